"""Errors that describe a user's mistake (bad config, bad stimulus file) rather than a bug.

The command-line entry points print these as one line and exit with status 2; any other
exception keeps its traceback.
"""


class UserInputError(ValueError):
    """A configuration value, file or argument given by the user is wrong."""
