"""The one exception type that the command line turns into a one-line message and exit code 2."""


class UsageError(Exception):
    """Bad input from the user: names the file or option, what was wrong and what was expected."""
