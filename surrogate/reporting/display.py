"""How the reporting layer shows a pressure: in bar, the display unit of every pressure it reports
(residuals, RMS figures, noise floors), by the factor :mod:`surrogate.core.units` defines.

One helper beside the modules that word and draw the numbers, instead of a conversion by unit
name at each number; the same bits as ``from_si(value, "bar")``.
"""

from __future__ import annotations

import numpy as np

from ..core.units import BAR


def in_bar(value):
    """A pressure [Pa] in bar: a float for a number, an array for an array."""
    if np.isscalar(value):
        return float(value) / BAR
    return np.asarray(value, dtype=float) / BAR
