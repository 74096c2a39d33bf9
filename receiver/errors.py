"""The one exception type for bad user input (config, files, formats).

The CLI turns it into a one-line message and exit code 2, without traceback.
"""


class UserError(Exception):
    """Bad input from the user: config key/value, file format, missing file."""
