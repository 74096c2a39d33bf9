"""The one exception type for bad user input (config, files, formats).

The CLI turns it into a one-line message and exit code 2, without traceback.
"""
import sys


class UserError(Exception):
    """Bad input from the user: config key/value, file format, missing file."""


def warn(msg: str):
    """One warning line on stderr (for input that is accepted but probably not what the user meant)."""
    print(f"gnssrx: warning: {msg}", file=sys.stderr, flush=True)
