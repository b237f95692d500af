"""Plausibility limits: values that parse as numbers but that no valve, oil or test bench has.

A file can be valid syntax and still wrong: a pressure of 1e30 bar, a load pressure logged in psi
under a ``_bar`` name, an area written in m² under an ``_mm2`` key. Such values do not fail loudly
downstream; they shift a map or make a fit "converge" on nonsense. So every quantity read from a
file is checked against a range that spans real hydraulics with a wide margin, and a value outside
it is refused with the likely cause: when the value lies in range once read in a unit people
commonly confuse with the expected one, the message says so.

The limits live here, once, and the file schemas and the valve file use them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from .core.errors import InputError
from .core.units import P_ATM, from_si, label

#: [bar] the highest pressure accepted anywhere: above any mobile or industrial hydraulics
#: (components are rated to 700 bar at most), so a larger value is a unit or typing mistake
PRESSURE_MAX_BAR = 1000.0
#: [bar] flow runs from the load to the back port, so p_L >= p_B; measured values may undershoot
#: by sensor noise: 5σ of the difference of a ±0.3 bar and a ±0.05 bar transducer (1σ)
PRESSURE_NOISE_BAR = 1.5

# Units that are commonly written where another was meant, with the factor (and offset) that turn
# a number in the mistaken unit into the expected one: expected = mistaken * factor + offset.
_MISTAKES: dict[str, tuple[tuple, ...]] = {
    "degC": (("K", 1.0, -273.15), ("°F", 5.0 / 9.0, -160.0 / 9.0)),
    "bar": (("psi", 1.0 / 14.5038), ("kPa", 0.01), ("MPa", 10.0), ("Pa", 1e-5)),
    "mm": (("µm", 1e-3), ("m", 1e3), ("inch", 25.4)),
    "mm^2": (("m²", 1e6), ("cm²", 100.0), ("µm²", 1e-6)),
    "cSt": (("m²/s", 1e6),),
    "kg/m^3": (("g/cm³", 1000.0),),
    "L/min": (("L/s", 60.0), ("m³/s", 6e4), ("US gpm", 3.78541)),
    "N": (("kN", 1e3), ("mN", 1e-3)),
    "N/m": (("N/mm", 1e3), ("kN/m", 1e3)),
}


@dataclass(frozen=True)
class Range:
    """The plausible values of a quantity in its file unit: ``low <= value <= high``."""

    low: float
    high: float
    unit: str

    def contains(self, value: float) -> bool:
        """Whether ``value`` is finite and within the range (NaN and ±inf never are)."""
        return math.isfinite(value) and self.low <= value <= self.high

    def check_option(self, option: str, value: float) -> float:
        """``value`` of a command-line ``option`` when plausible, else InputError saying the
        range (and the unit it may have been given in)."""
        if not self.contains(value):
            raise InputError(f"{option} {value:g}: expected {self.describe()}"
                             f"{self.unit_hint(value)}")
        return value

    def describe(self) -> str:
        """``"0 to 1000 bar"``."""
        return f"{self.low:g} to {self.high:g} {label(self.unit)}"

    def unit_hint(self, value: float) -> str:
        """Why ``value`` (outside the range) may be there: the units it would be plausible in,
        e.g. ``"; in psi? 1450 psi = 100 bar"``; empty when no common mix-up explains it."""
        if not (math.isfinite(value) and (value > self.high or 0 < value < self.low)):
            return ""  # a sign error or a value below vacuum is no unit mix-up
        guesses = []
        for mistaken, factor, *offset in _MISTAKES.get(self.unit, ()):
            converted = value * factor + (offset[0] if offset else 0.0)
            if self.contains(converted):
                guesses.append((mistaken, converted))
        guesses = guesses[:2]  # the likeliest two: enough to see the mistake
        if not guesses:
            return ""
        units = " or ".join(mistaken for mistaken, _ in guesses)
        worked = "; ".join(f"{value:g} {mistaken} = {converted:.4g} {label(self.unit)}"
                           for mistaken, converted in guesses)
        return f"; is it in {units}? ({worked})"


PRESSURE = Range(-from_si(P_ATM, "bar"), PRESSURE_MAX_BAR, "bar")  # gauge: not below vacuum
PRESSURE_DIFFERENCE = Range(0.0, PRESSURE_MAX_BAR, "bar")
TEMPERATURE = Range(-40.0, 200.0, "degC")  # mineral oils: pour point to well above any bench
VISCOSITY = Range(0.1, 1e5, "cSt")  # hot water 0.3 cSt; cold gear oil 1e4 cSt
DENSITY = Range(600.0, 1200.0, "kg/m^3")
TIME = Range(-1e6, 1e7, "s")  # a run's clock: minutes to hours, a year at most, may start < 0
OPENING = Range(0.0, 100.0, "mm")  # a piston position; valve strokes are millimetres
FLOW = Range(0.0, 5000.0, "L/min")  # the largest cartridge valves pass ~1000 L/min
FORCE = Range(-1e6, 1e6, "N")
