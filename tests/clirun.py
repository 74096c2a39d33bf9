"""In-process calls of the ``gnssrx`` command line for tests."""
import os

from click.testing import CliRunner

from receiver.cli import main


def cli(args, cwd=None):
    """In-process CLI call: (exit code, stdout, stderr).  An uncaught exception is a test failure."""
    old = os.getcwd()
    try:
        if cwd:
            os.chdir(cwd)
        res = CliRunner().invoke(main, [str(a) for a in args])
    finally:
        os.chdir(old)
    if res.exception is not None and not isinstance(res.exception, SystemExit):
        raise res.exception
    return res.exit_code, res.stdout, res.stderr
