"""Unit conversions: the one place where file and display units meet SI.

Everything inside the package is SI: pressures in [Pa], lengths in [m], areas in [m^2], flows in
[m^3/s], kinematic viscosity in [m^2/s], density in [kg/m^3], forces in [N] and temperatures in
[K]. Files and printed output use the units engineers read: bar, mm, L/min, cSt and degC (a bench log
may also come in psi, kPa, MPa, US gpm and degF, converted here as it is read). Any
conversion between the two goes through :func:`to_si` and :func:`from_si` (or the named constants
below, which are the same factors), so a unit is defined exactly once.

Pressures are gauge throughout, as in the data files; :data:`P_ATM` converts to absolute where a
physical law needs it (gas release, cavitation).
"""

from __future__ import annotations

import numpy as np

# Multiplicative factors to SI. Named so that physics code reads like the equations it implements.
BAR = 1e5  # [Pa]
MM = 1e-3  # [m]
MM2 = 1e-6  # [m^2]
LPM = 1e-3 / 60.0  # [m^3/s] per L/min
CST = 1e-6  # [m^2/s] per cSt (= mm^2/s)
ZERO_CELSIUS = 273.15  # [K]
P_ATM = 1.013 * BAR  # [Pa] atmospheric pressure, to turn gauge into absolute pressure
PSI = 6894.757293168  # [Pa] per pound-force per square inch (0.45359237 kgf / 0.0254² m²)
US_GALLON = 3.785411784e-3  # [m^3] (231 cubic inches, exact)

# unit -> (scale, offset) with  si = value * scale + offset
_UNITS: dict[str, tuple[float, float]] = {
    # pressure
    "Pa": (1.0, 0.0),
    "bar": (BAR, 0.0),
    "kPa": (1e3, 0.0),
    "MPa": (1e6, 0.0),
    "psi": (PSI, 0.0),
    # length and area
    "m": (1.0, 0.0),
    "mm": (MM, 0.0),
    "m^2": (1.0, 0.0),
    "mm^2": (MM2, 0.0),
    # flow
    "m^3/s": (1.0, 0.0),
    "L/min": (LPM, 0.0),
    "gpm": (US_GALLON / 60.0, 0.0),  # US gallons per minute, as US benches log flow
    # viscosity and density
    "m^2/s": (1.0, 0.0),
    "cSt": (CST, 0.0),
    "mm^2/s": (CST, 0.0),
    "kg/m^3": (1.0, 0.0),
    # temperature
    "K": (1.0, 0.0),
    "degC": (1.0, ZERO_CELSIUS),
    "degF": (5.0 / 9.0, ZERO_CELSIUS - 32.0 * 5.0 / 9.0),
    # quantities whose file unit already is SI
    "N": (1.0, 0.0),
    "N/m": (1.0, 0.0),
    "N/bar": (1.0 / BAR, 0.0),
    "1/bar": (1.0 / BAR, 0.0),
    "L/min/bar": (LPM / BAR, 0.0),
    "s": (1.0, 0.0),
    "1/K": (1.0, 0.0),
    "1": (1.0, 0.0),
}

#: Display spelling of each unit, for messages and axis labels.
UNIT_LABELS = {"degC": "°C", "degF": "°F", "gpm": "US gpm", "m^2": "m²", "mm^2": "mm²", "m^3/s": "m³/s", "m^2/s": "m²/s",
               "mm^2/s": "mm²/s", "kg/m^3": "kg/m³"}


def known_units() -> tuple[str, ...]:
    """The unit spellings :func:`to_si` and :func:`from_si` accept."""
    return tuple(_UNITS)


def _factors(unit: str) -> tuple[float, float]:
    try:
        return _UNITS[unit]
    except KeyError:
        raise ValueError(f"unknown unit {unit!r}; known units: {', '.join(_UNITS)}") from None


def to_si(value, unit: str):
    """Convert ``value`` given in ``unit`` to SI.

    Parameters
    ----------
    value : float or array_like
        Quantity in ``unit``.
    unit : str
        One of :func:`known_units`, e.g. ``"bar"``, ``"L/min"``, ``"degC"``.

    Returns
    -------
    float or numpy.ndarray
        The quantity in SI units ([Pa], [m^3/s], [K], ...).
    """
    scale, offset = _factors(unit)
    if np.isscalar(value):
        return float(value) * scale + offset
    return np.asarray(value, dtype=float) * scale + offset


def from_si(value, unit: str):
    """Convert an SI ``value`` to ``unit``; the inverse of :func:`to_si`."""
    scale, offset = _factors(unit)
    if np.isscalar(value):
        return (float(value) - offset) / scale
    return (np.asarray(value, dtype=float) - offset) / scale


def label(unit: str) -> str:
    """How ``unit`` is printed: ``"degC"`` becomes ``"°C"``, ``"mm^2"`` becomes ``"mm²"``."""
    return UNIT_LABELS.get(unit, unit)
