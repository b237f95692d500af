"""Exceptions that mean "the input is wrong", as opposed to a bug in the package.

The command line turns an :class:`InputError` into a message and exit code 2. Names the user
types (presets, map kinds) are matched with :func:`named` and missed with :func:`did_you_mean`.
"""

import difflib


class InputError(ValueError):
    """Input the user can fix: a file, a parameter or a query the package cannot accept."""


def named(text: str, choices) -> str | None:
    """The one of ``choices`` that ``text`` names, in any case (``"CFDA"`` names ``"cfda"``:
    reports write names in capitals), or None."""
    if not isinstance(text, str):
        return None
    if text in choices:
        return text
    return next((choice for choice in choices if choice.lower() == text.lower()), None)


def did_you_mean(text: str, choices) -> str:
    """``" (did you mean 'gp'?)"`` for a near miss of one of ``choices``, else ``""``."""
    by_lower = {choice.lower(): choice for choice in choices}
    close = difflib.get_close_matches(str(text).lower(), list(by_lower), n=1, cutoff=0.6)
    return f" (did you mean {by_lower[close[0]]!r}?)" if close else ""
