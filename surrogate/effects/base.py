"""Physical effects: terms added to the valve's force balance, each with named parameters.

The valve model (:mod:`surrogate.model`) computes the force balance of the piston from its maps,

    net force = f_fl − f_spr = p_L·A_L + p_P·A_P − p_B·A_B + f_ff − (F_cr + K_f·u),

and then asks each effect for its contribution. An effect may add an opening force
(:meth:`Effect.force`) or widen the friction band (:meth:`Effect.friction`, a non-negative
half-width; the solver turns it into Coulomb friction that opposes the piston's motion). The
solver never sees effects, so a new effect is one new class, registered by its ``name``.

Parameters are stored in SI units; each carries the unit it is shown and written in.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ..fluid import FluidState
from ..units import from_si, label, to_si
from ..valve import ValveParameters


@dataclass
class Parameter:
    """A named model parameter, in the manner of ``lmfit.Parameter``.

    Attributes
    ----------
    name : str
        Name, unique within its effect.
    value : float
        Value in SI units.
    unit : str
        Unit it is displayed and written in (a key of :mod:`surrogate.units`).
    min, max : float
        Bounds in SI units.
    vary : bool
        Whether fitting may change it.
    description : str
        What it means, in words.
    stderr : float or None
        Standard error from the last fit [SI], if any.
    """

    name: str
    value: float
    unit: str = "1"
    min: float = -np.inf
    max: float = np.inf
    vary: bool = True
    description: str = ""
    stderr: float | None = None

    @property
    def display_value(self) -> float:
        """The value in :attr:`unit`."""
        return float(from_si(self.value, self.unit))

    @property
    def display_stderr(self) -> float | None:
        if self.stderr is None:
            return None
        return float(abs(from_si(self.stderr, self.unit) - from_si(0.0, self.unit)))

    @property
    def at_bound(self) -> bool:
        """True when the value sits on a bound, within a millionth of the allowed range (a fit
        pushed it there, and its curvature then says nothing about the uncertainty)."""
        span = self.max - self.min
        slack = 1e-6 * span if np.isfinite(span) else 1e-12 * max(abs(self.value), 1.0)
        return self.value <= self.min + slack or self.value >= self.max - slack

    def set_display(self, value: float) -> None:
        """Set the value from :attr:`unit`."""
        self.value = float(to_si(value, self.unit))

    def __str__(self) -> str:
        text = f"{self.name} = {self.display_value:.5g}"
        if self.stderr is not None:
            text += f" ± {self.display_stderr:.2g}"
        text = f"{text} {label(self.unit)}".rstrip()
        return text + " (at bound)" if self.at_bound else text


@dataclass(frozen=True)
class BalanceState:
    """Everything an effect may use at a batch of candidate piston positions (SI units).

    ``flow_force`` is f_ff from the force map (zero for a uniform-pressure map), ``q`` the flow
    through the main restriction.
    """

    u: np.ndarray
    q: np.ndarray
    p_L: np.ndarray
    p_B: np.ndarray
    p_P: np.ndarray
    temperature: np.ndarray
    fluid: FluidState
    flow_force: np.ndarray
    valve: ValveParameters

    @property
    def dp(self) -> np.ndarray:
        """Pressure drop p_L − p_B [Pa]."""
        return self.p_L - self.p_B


class Effect:
    """Base class of the effects. Subclasses set the class attributes and override hooks.

    Class attributes
    ----------------
    name : str
        Registry key, e.g. ``"coulomb_friction"``.
    title : str
        What it is, in words an engineer recognises.
    parameter_specs : tuple of Parameter
        Parameters with their default values, units, bounds and descriptions.
    validity : str
        Where the term holds and where it does not.
    """

    name: ClassVar[str] = ""
    title: ClassVar[str] = ""
    parameter_specs: ClassVar[tuple[Parameter, ...]] = ()
    validity: ClassVar[str] = ""

    def __init__(self, **values: float):
        """Parameters take their default values unless given here, in SI units."""
        self.params: dict[str, Parameter] = {spec.name: copy.copy(spec)
                                             for spec in self.parameter_specs}
        unknown = set(values) - set(self.params)
        if unknown:
            raise TypeError(f"{type(self).__name__} has no parameter(s) {', '.join(sorted(unknown))}; "
                            f"it has {', '.join(self.params) or 'none'}")
        for key, value in values.items():
            self.params[key].value = float(value)

    def __getitem__(self, key: str) -> float:
        """A parameter's SI value."""
        return self.params[key].value

    def __repr__(self) -> str:
        inside = ", ".join(str(p) for p in self.params.values())
        return f"{type(self).__name__}({inside})"

    def copy(self) -> "Effect":
        return copy.deepcopy(self)

    # hooks: return None to contribute nothing
    def force(self, state: BalanceState) -> np.ndarray | None:
        """Extra force on the piston [N], positive in the opening direction."""
        return None

    def friction(self, state: BalanceState) -> np.ndarray | None:
        """Extra half-width of the Coulomb friction band [N], >= 0."""
        return None
