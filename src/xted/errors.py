"""Exceptions and warnings shared by the library and the CLI.

The CLI maps ``InputError`` to exit code 2 (bad input or usage) and any other
exception to exit code 1 (internal error); a ``DataWarning`` is printed as
``xted: warning: ...`` and the command goes on.
"""

import warnings


class InputError(ValueError):
    """Bad user input: a malformed file, an inconsistent array, an unknown name."""


class DataWarning(UserWarning):
    """Something in the user's data that xted works around and the user should know of."""


def warn_data(message: str) -> None:
    warnings.warn(message, DataWarning, stacklevel=3)
