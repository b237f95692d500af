"""How the reporting layer shows a pressure: in bar, the display unit of every pressure it reports
(residuals, RMS figures, noise floors), by the factor :mod:`surrogate.core.units` defines.

One name beside the modules that word and draw the numbers, instead of a unit name spelled at
each number; the conversion itself stays :func:`surrogate.core.units.from_si`'s.
"""

from __future__ import annotations

from ..core.units import from_si


def in_bar(value):
    """A pressure [Pa] in bar: a float for a number, an array for an array."""
    return from_si(value, "bar")
