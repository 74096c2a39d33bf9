"""The one exception type for bad user input (config, files, formats).

The CLI turns it into a one-line message and exit code 2, without traceback.
"""
import logging


class UserError(Exception):
    """Bad input from the user: config key/value, file format, missing file."""


def warn(msg: str):
    """One warning (input that is accepted but probably not what the user meant), logged to
    ``receiver.warnings``; the CLI shows it as one line ``gnssrx: warning: ...`` on stderr."""
    logging.getLogger("receiver.warnings").warning(msg)
