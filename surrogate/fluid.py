"""Hydraulic oil: viscosity by Walther / ASTM D341 and density by linear thermal expansion.

Maps never see a temperature, only a :class:`FluidState` (kinematic viscosity and density). That is
what lets a map trained on one oil answer for another: give it the other oil's ν(T) and ρ(T).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .core.errors import InputError
from .limits import DENSITY, Range
from .core.tomlio import require_keys
from .core.units import CST, ZERO_CELSIUS, from_si, to_si

_WALTHER_SHIFT = 0.7  # [cSt] the constant of ASTM D341, valid for ν >= 2 cSt
_T40 = 40.0 + ZERO_CELSIUS  # [K]
_T100 = 100.0 + ZERO_CELSIUS  # [K]
_T15 = 15.0 + ZERO_CELSIUS  # [K]
# datasheet viscosities of hydraulic and lubricating oils: ISO VG 2 to VG 1500 and beyond
_NU40 = Range(1.0, 1e4, "cSt")
_NU100 = Range(0.5, 1e3, "cSt")


@dataclass(frozen=True)
class FluidState:
    """The fluid properties a map needs at each query point.

    Attributes
    ----------
    nu : numpy.ndarray
        Kinematic viscosity [m^2/s].
    rho : numpy.ndarray
        Density [kg/m^3].
    """

    nu: np.ndarray
    rho: np.ndarray

    def __post_init__(self):
        nu, rho = np.broadcast_arrays(np.asarray(self.nu, float), np.asarray(self.rho, float))
        if np.any(~(nu > 0)) or np.any(~(rho > 0)):
            raise InputError("fluid state needs nu > 0 [m^2/s] and rho > 0 [kg/m^3] everywhere")
        object.__setattr__(self, "nu", nu)
        object.__setattr__(self, "rho", rho)

    def __getitem__(self, index) -> "FluidState":
        """The fluid state at a subset of points (same indexing as numpy)."""
        if isinstance(index, np.ndarray) and index.dtype.kind in "iu" and self.nu.ndim == 1:
            nu, rho = self.nu.take(index), self.rho.take(index)  # positions: as the solver asks
        else:
            nu, rho = self.nu[index], self.rho[index]
        if np.ndim(nu) == 0:  # one point: 0-d arrays, as the constructor makes them
            return FluidState(nu, rho)
        # a subset of checked states needs no check: the solver takes subsets at every step
        subset = object.__new__(FluidState)
        object.__setattr__(subset, "nu", nu)
        object.__setattr__(subset, "rho", rho)
        return subset

    def ravel(self) -> "FluidState":
        """The same states as flat arrays."""
        return FluidState(self.nu.ravel(), self.rho.ravel())


def broadcast(*arrays) -> tuple[np.ndarray, ...]:
    """Float arrays of one common shape."""
    return np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in arrays))


def broadcast_query(a, b, u, fluid: FluidState):
    """(a, b, u, fluid) broadcast to one shape, fluid included: the arguments of a map query
    (:mod:`surrogate.maps.base`) or of its features (:mod:`surrogate.features`)."""
    a, b, u, nu, rho = broadcast(a, b, u, fluid.nu, fluid.rho)
    if nu.shape == np.shape(fluid.nu):
        # a state is checked when made (a subset of one needs none): already the query's
        # shape, it needs no second check at every map query of a solver
        return a, b, u, fluid
    return a, b, u, FluidState(nu, rho)


@dataclass(frozen=True)
class Oil:
    """A mineral hydraulic oil described by its datasheet values.

    Parameters
    ----------
    name : str
        Display name, e.g. ``"ISO VG46 HV"``.
    nu40 : float
        Kinematic viscosity at 40 °C [m^2/s].
    nu100 : float
        Kinematic viscosity at 100 °C [m^2/s].
    rho15 : float
        Density at 15 °C [kg/m^3].
    expansion : float
        Relative density decrease per kelvin [1/K]: ρ(T) = ρ15·(1 − expansion·(T − 15 °C)).

    Notes
    -----
    Viscosity follows Walther's equation as standardised in ASTM D341,
    ``log10(log10(ν + 0.7)) = A − B·log10(T)`` with ν in cSt and T in K, through the two datasheet
    points. It is accurate for ν >= 2 cSt, which covers mineral oils from −40 to well above
    100 °C.
    """

    name: str
    nu40: float
    nu100: float
    rho15: float
    expansion: float

    def __post_init__(self):
        for key, value, plausible in (("nu40_cSt", self.nu40, _NU40), ("nu100_cSt", self.nu100,
                                                                       _NU100)):
            value = from_si(value, "cSt")
            if not plausible.contains(value):
                raise InputError(f"oil {self.name!r}: {key} = {value:g} is not plausible "
                                 f"(expected {plausible.describe()}{plausible.unit_hint(value)})")
        if not (self.nu40 > self.nu100 > 0):
            raise InputError(f"oil {self.name!r}: need nu40 > nu100 > 0, got "
                             f"{from_si(self.nu40, 'cSt')} and {from_si(self.nu100, 'cSt')} cSt")
        if not DENSITY.contains(self.rho15):
            raise InputError(f"oil {self.name!r}: rho15 = {self.rho15} kg/m^3 is outside 600-1200")
        if not (0 <= self.expansion < 0.01):  # also refuses NaN
            raise InputError(f"oil {self.name!r}: expansion = {self.expansion} 1/K is implausible "
                             "(mineral oils: about 6e-4 to 9e-4)")

    @property
    def _walther(self) -> tuple[float, float]:
        z40 = np.log10(np.log10(self.nu40 / CST + _WALTHER_SHIFT))
        z100 = np.log10(np.log10(self.nu100 / CST + _WALTHER_SHIFT))
        slope = (z40 - z100) / (np.log10(_T100) - np.log10(_T40))
        return z40 + slope * np.log10(_T40), slope

    def viscosity(self, temperature):
        """Kinematic viscosity [m^2/s] at ``temperature`` [K]."""
        intercept, slope = self._walther
        z = intercept - slope * np.log10(np.asarray(temperature, float))
        return (10.0 ** (10.0 ** z) - _WALTHER_SHIFT) * CST

    def temperature(self, nu):
        """The temperature [K] at which the oil has kinematic viscosity ``nu`` [m^2/s]: the
        inverse of :meth:`viscosity`."""
        intercept, slope = self._walther
        z = np.log10(np.log10(np.asarray(nu, float) / CST + _WALTHER_SHIFT))
        return 10.0 ** ((intercept - z) / slope)

    def density(self, temperature):
        """Density [kg/m^3] at ``temperature`` [K]."""
        return self.rho15 * (1.0 - self.expansion * (np.asarray(temperature, float) - _T15))

    def state(self, temperature) -> FluidState:
        """The :class:`FluidState` at ``temperature`` [K] (scalar or array)."""
        return FluidState(self.viscosity(temperature), self.density(temperature))

    @classmethod
    def from_dict(cls, table: dict, *, source: str = "oil table") -> "Oil":
        """Build from the ``[oil]`` table of a valve file (file units: cSt, kg/m^3, 1/K)."""
        keys = {"name", "nu40_cSt", "nu100_cSt", "rho15_kg_m3", "expansion_per_K"}
        require_keys(table, keys, source)
        for key in sorted(keys - {"name"}):
            value = table[key]
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise InputError(f"{source}: {key} must be a number, got {value!r}")
        try:
            return cls(name=str(table["name"]),
                       nu40=to_si(table["nu40_cSt"], "cSt"),
                       nu100=to_si(table["nu100_cSt"], "cSt"),
                       rho15=float(table["rho15_kg_m3"]),
                       expansion=float(table["expansion_per_K"]))
        except InputError as error:
            raise InputError(f"{source}: {error}") from None

    def to_dict(self) -> dict:
        """The ``[oil]`` table in file units; the inverse of :meth:`from_dict`."""
        return {"name": self.name, "nu40_cSt": from_si(self.nu40, "cSt"),
                "nu100_cSt": from_si(self.nu100, "cSt"), "rho15_kg_m3": self.rho15,
                "expansion_per_K": self.expansion}

