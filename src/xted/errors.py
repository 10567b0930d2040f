"""Exceptions shared by the library and the CLI.

The CLI maps ``InputError`` to exit code 2 (bad input or usage) and any other
exception to exit code 1 (internal error).
"""


class InputError(ValueError):
    """Bad user input: a malformed file, an inconsistent array, an unknown name."""
