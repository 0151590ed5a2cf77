"""The one exception type that the command line turns into a one-line message and exit code 2."""


class UsageError(ValueError):
    """Bad input from the user: names the file or option, what was wrong and what was expected. A ValueError, so
    that the Python API raises what Python code expects for a bad argument."""
