"""Exceptions that mean "the input is wrong", as opposed to a bug in the package.

The command line turns an :class:`InputError` into a message and exit code 2.
"""


class InputError(ValueError):
    """Input the user can fix: a file, a parameter or a query the package cannot accept."""
