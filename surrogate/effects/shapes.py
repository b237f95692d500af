"""Shape-free effects: a term of one physical kind whose shape along one variable the data choose.

The library's effects each have a shape an engineer named (a constant preload, a friction
proportional to the load pressure). A real valve's missing physics rarely has one of those
shapes. A shape-free effect keeps the *physics* of its kind and lets the log choose the *shape*:

=============================  ========  ===============================  ====================
effect                         hook      shape                            built in
=============================  ========  ===============================  ====================
force of the opening f(u)      force     cubic spline in u                nothing: any sign
friction g(x), x one state     friction  rising spline in x, 0 at the     g >= 0, rising
variable (p_L, p_P, p_B,                 smallest x of the log
p_L − p_P, ν, q)
leakage h(Δp, ν)               leakage   rising spline in Δp, 0 at Δp = 0,  h >= 0, rising in Δp,
                                         times ν_ref/ν                    laminar in ν
flow-force factor m(u)         force     f_ff·m(u), spline in u           a map correction
discharge factor d(u)          flow      q/(1 + d(u)), spline in u        a map correction
=============================  ========  ===============================  ====================

A shape is Σ_k c_k·b_k(x) over a small basis: cubic B-splines on knots placed at quantiles of
the variable over the log (where the data lie), or, for a rising shape, their cumulative sums
from the right, which rise from 0 to 1, so that coefficients c_k >= 0 make the shape rise and
stay non-negative. Beyond the end knots the shape is held. The knots are parameters that never
vary (a model file records them, so the shape reads back exactly); the coefficients are the
parameters a fit varies. Every coefficient 0 is the effect off.

A roughness penalty (differences of neighbouring coefficients, :meth:`ShapeFreeEffect.roughness`)
keeps the shape smooth; its weight is chosen by the held-out runs
(:mod:`surrogate.diagnosis.shapes`) and kept in the parameter ``smoothing``, so that every later
fit of the shape (a workflow's next step, ``fit`` with a model file) keeps it as smooth
(:meth:`ShapeFreeEffect.penalty`). Such a term has more freedom than a library term: a
diagnosis tries it only beside the library and prefers a library term that fits as well.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from scipy.interpolate import BSpline

from ..core.errors import InputError
from ..parameters import Parameter
from .. import limits
from ..core.units import BAR, CST, LPM, from_si, to_si
from .base import BalanceState, Effect, FlowState

#: knots of a shape (the basis then has KNOTS + 2 cubic B-splines)
KNOTS = 6
#: the most knots a model file may give a shape (a calibration has one per sampled opening)
MAX_KNOTS = 64
DEGREE = 3
#: knots sit this far toward the data's quantiles from an even spread over their range
QUANTILE_SHARE = 0.8
#: the end knots leave out this share of the data at either end: a few samples cannot determine
#: a shape, which is held beyond its end knots. The 120-bar runs' jumps to the stop put the
#: largest moving opening at 0.63 mm where 99 % of the moving samples lie below 0.29 mm, and a
#: force of free shape then rose to +183 N there, unchecked by the data
TAIL = 0.005
#: viscosity at which a shape-free leakage is quoted [m^2/s] (ISO VG46 at 40 °C)
NU_REFERENCE = 46.0 * CST


@dataclass(frozen=True)
class Variable:
    """A state variable a shape may depend on.

    Attributes
    ----------
    name : str
        Short name, as effect names carry it (``"p_L"``).
    label : str
        What it is, in words.
    unit : str
        Display unit (:mod:`surrogate.core.units`).
    of : callable
        ``of(state)`` -> its values [SI] in a :class:`BalanceState` or :class:`FlowState`.
    source : str
        The same as Python source, for the effect file a shape is handed over as
        (:mod:`.handover`).
    limits : tuple of float
        The values it can take [SI] (:mod:`surrogate.limits`): a knot's bounds.
    """

    name: str
    label: str
    unit: str
    of: Callable[[object], np.ndarray]
    source: str
    limits: tuple[float, float]


_PRESSURES = (-limits.PRESSURE_MAX_BAR * BAR, limits.PRESSURE_MAX_BAR * BAR)
VARIABLES = {variable.name: variable for variable in (
    Variable("u", "the opening u", "mm", lambda state: state.u, "state.u",
             (0.0, limits.OPENING.high * 1e-3)),
    Variable("p_L", "the load pressure p_L", "bar", lambda state: state.p_L, "state.p_L",
             _PRESSURES),
    Variable("p_P", "the pilot pressure p_P", "bar", lambda state: state.p_P, "state.p_P",
             _PRESSURES),
    Variable("p_B", "the back pressure p_B", "bar", lambda state: state.p_B, "state.p_B",
             _PRESSURES),
    Variable("p_LP", "the pressure across the pilot seal, p_L − p_P", "bar",
             lambda state: state.p_L - state.p_P, "(state.p_L - state.p_P)", _PRESSURES),
    Variable("nu", "the oil's viscosity ν", "cSt", lambda state: state.fluid.nu,
             "state.fluid.nu", (limits.VISCOSITY.low * CST, limits.VISCOSITY.high * CST)),
    Variable("q", "the flow q", "L/min", lambda state: state.q, "state.q",
             (0.0, limits.FLOW.high * LPM)),
)}
#: the pressure drop, the variable of a leakage (given to the hook, not part of its state)
PRESSURE_DROP = Variable("dp", "the pressure drop Δp", "bar", lambda state: state.dp,
                         "np.maximum(dp, 0.0)", (0.0, limits.PRESSURE_MAX_BAR * BAR))


def spline_basis(knots: np.ndarray, x: np.ndarray) -> np.ndarray:
    """(n, len(knots) + 2) cubic B-splines on ``knots`` (clamped at the ends) at ``x``, held
    beyond the end knots; each row sums to one."""
    knots = np.asarray(knots, float)
    padded = np.r_[[knots[0]] * DEGREE, knots, [knots[-1]] * DEGREE]
    count = len(padded) - DEGREE - 1
    inside = np.clip(np.asarray(x, float), knots[0], knots[-1])
    return BSpline(padded, np.eye(count), DEGREE, extrapolate=False)(inside).reshape(
        inside.size, count)


def rising_basis(knots: np.ndarray, x: np.ndarray) -> np.ndarray:
    """(n, len(knots) + 1) functions that rise from 0 at the first knot to 1 at the last: the
    B-splines summed from the right (without the constant). Non-negative coefficients make a
    rising, non-negative shape, zero at the first knot."""
    splines = spline_basis(knots, x)
    return np.cumsum(splines[:, ::-1], axis=1)[:, ::-1][:, 1:]


def quantile_knots(x: np.ndarray, count: int = KNOTS, *, start: float | None = None
                   ) -> np.ndarray:
    """``count`` knots between the :data:`TAIL` and 1 − :data:`TAIL` quantiles of the finite
    values of ``x`` [SI] (or from ``start``, a physical zero such as Δp = 0): each
    :data:`QUANTILE_SHARE` of the way from the evenly spaced point of that range to the evenly
    spaced quantile of the data, so that knots gather where the data lie but never collapse onto
    a value many samples share (a back pressure the bench holds)."""
    x = np.asarray(x, float)
    x = x[np.isfinite(x)]
    low = float(np.quantile(x, TAIL)) if start is None else float(start)
    high = max(float(np.quantile(x, 1.0 - TAIL)), low + 1e-12 * max(abs(low), 1.0))
    levels = np.linspace(0.0, 1.0, count)
    knots = (QUANTILE_SHARE * np.quantile(np.clip(x, low, high), levels)
             + (1.0 - QUANTILE_SHARE) * (low + levels * (high - low)))
    knots[0] = low
    return knots


class ShapeFreeEffect(Effect):
    """Base class: a term whose shape along :attr:`variable` is Σ_k c_k·b_k(x).

    Subclasses set the kind, the variable, whether the shape must rise (``rising``), the unit of
    the shape's values (``value_unit``) and the hook that applies it. Parameters: ``knot_1`` ...
    (the variable's unit, never varied), ``c_1`` ... (``value_unit``; >= 0 for a rising shape)
    and ``smoothing`` (bar, never varied): the roughness penalty's weight, what a difference of
    one display unit between the roughness's neighbouring coefficients costs, as RMS of the
    residual (:meth:`penalty`; 0: none).
    """

    shape_free: ClassVar[bool] = True
    variable: ClassVar[Variable]
    rising: ClassVar[bool] = False
    value_unit: ClassVar[str] = "N"
    #: how large a coefficient may be, in ``value_unit``
    value_limit: ClassVar[float] = 200.0
    #: what the shape is in words ("force", "friction" ...), for titles and reports
    quantity: ClassVar[str] = ""
    #: the hook's output as Python source, ``{shape}`` standing for the shape's values [SI]
    #: (the effect file of :mod:`.handover` writes it)
    formula: ClassVar[str] = "{shape}"
    #: whether the shape carries its roughness penalty's weight (``smoothing``) into every fit
    smoothed: ClassVar[bool] = True

    def __init__(self, knots=None, **values: float):
        """The effect off on ``knots`` [SI] (default: evenly over the variable's plausible range,
        to be replaced by :meth:`on_knots`); ``values`` in display units by parameter name."""
        knots = self._even_knots(KNOTS) if knots is None else np.asarray(knots, float)
        self.params = {}
        unit = self.variable.unit
        for index, knot in enumerate(knots, start=1):
            self.params[f"knot_{index}"] = Parameter(
                f"knot_{index}", float(knot), unit, *self.variable.limits, vary=False,
                description=f"knot {index} of the shape in {self.variable.label}")
        high = float(to_si(self.value_limit, self.value_unit))
        low = 0.0 if self.rising else -high
        for index in range(1, self.basis_size(len(knots)) + 1):
            self.params[f"c_{index}"] = Parameter(
                f"c_{index}", 0.0, self.value_unit, min=low, max=high,
                description=f"coefficient {index} of the shape")
        if self.smoothed:
            self.params["smoothing"] = Parameter(
                "smoothing", 0.0, "bar", min=0.0, max=1e4 * BAR, vary=False,
                description="weight of the roughness penalty: the residual RMS a difference of "
                            "one unit between neighbouring coefficients costs")
        unknown = set(values) - set(self.params)
        if unknown:
            raise TypeError(f"{type(self).__name__} has no parameter(s) "
                            f"{', '.join(sorted(unknown))}")
        for key, value in values.items():
            self.params[key].set_display(value)

    @classmethod
    def basis_size(cls, knots: int) -> int:
        return knots + 2 if not cls.rising else knots + 1

    @classmethod
    def on_knots(cls, knots) -> "ShapeFreeEffect":
        """The effect, off, on these knots [SI]."""
        return cls(knots)

    @classmethod
    def knots_for(cls, x: np.ndarray) -> np.ndarray:
        """Knots where the data ``x`` [SI] of :attr:`variable` lie."""
        return quantile_knots(x)

    @classmethod
    def for_parameters(cls, names: list[str]) -> "ShapeFreeEffect":
        count = sum(1 for name in names if name.startswith("knot_"))
        if count and not 2 <= count <= MAX_KNOTS:
            raise InputError(f"{cls.name}: {count} knots; a shape has 2 to {MAX_KNOTS}")
        return cls(cls._even_knots(count or KNOTS))

    @classmethod
    def _even_knots(cls, count: int) -> np.ndarray:
        """``count`` knots [SI] evenly over the variable's plausible range: rising, and each
        within its parameter's bounds, so that the effect reads back from a model file."""
        return np.linspace(*cls.variable.limits, count)

    def check_parameters(self, where: str) -> None:
        """The knots a model file gives must rise strictly: the shape is a spline between them."""
        knots = [(name, p.value) for name, p in self.params.items() if name.startswith("knot_")]
        for (before, low), (name, high) in zip(knots, knots[1:]):
            if not high > low:
                raise InputError(f"{where}: {name} = {from_si(high, self.variable.unit):g} "
                                 f"{self.variable.unit} does not lie above {before} = "
                                 f"{from_si(low, self.variable.unit):g}; a shape's knots rise "
                                 "strictly")

    @property
    def knots(self) -> np.ndarray:
        """The knots [SI], increasing (a file's knots that are not, or coincide, are spread by
        a hair so that the basis stays defined)."""
        knots = np.sort([p.value for name, p in self.params.items() if name.startswith("knot_")])
        hair = 1e-9 * max(float(np.max(np.abs(knots))), 1e-12)
        return knots + hair * np.arange(len(knots)) * (np.diff(knots, prepend=-np.inf) <= 0)

    @property
    def coefficients(self) -> np.ndarray:
        return np.array([p.value for name, p in self.params.items() if name.startswith("c_")])

    def coefficient_names(self) -> list[str]:
        return [name for name in self.params if name.startswith("c_")]

    def basis(self, x: np.ndarray) -> np.ndarray:
        """(n, coefficients): the basis functions at ``x`` [SI]."""
        return (rising_basis if self.rising else spline_basis)(self.knots, x)

    def shape(self, x: np.ndarray) -> np.ndarray:
        """The shape's values at ``x`` [SI of the variable] in SI units of ``value_unit``."""
        x = np.asarray(x, float)
        spline, low, high = self._spline()
        return spline(np.clip(x, low, high))

    def _spline(self) -> tuple[BSpline, float, float]:
        """The shape as one scalar cubic spline with its end knots, built again only when a
        parameter has changed. A solver evaluates the shape thousands of times per fit (a
        leakage at every step of the flow split), and building the basis each time cost more
        than the maps."""
        values = tuple(parameter.value for parameter in self.params.values())
        if getattr(self, "_cached", (None,))[0] != values:
            knots = self.knots
            coefficients = self.coefficients
            if self.rising:
                # Σ_k c_k·R_k with R_k = Σ_{j>k} B_j is Σ_j B_j·(c_1 + … + c_j), B_0's weight 0
                coefficients = np.r_[0.0, np.cumsum(coefficients)]
            padded = np.r_[[knots[0]] * DEGREE, knots, [knots[-1]] * DEGREE]
            spline = BSpline(padded, coefficients, DEGREE, extrapolate=False)
            self._cached = (values, (spline, float(knots[0]), float(knots[-1])))
        return self._cached[1]

    def roughness(self) -> np.ndarray:
        """Differences of neighbouring coefficients whose squares the penalty sums: second
        differences for a free shape (a straight line costs nothing), first differences of a
        rising shape's slopes (an evenly rising one costs nothing)."""
        size = len(self.coefficients)
        return np.diff(np.eye(size), 1 if self.rising else 2, axis=0)

    def penalty(self, samples: int) -> np.ndarray | None:
        """The roughness penalty over :attr:`params` for a fit of ``samples`` residuals:
        √samples·smoothing·(differences of the coefficients in display units), so that it weighs
        as much against the sum of squares whatever the log's length (None when ``smoothing``
        is 0)."""
        weight = self.params["smoothing"].value if self.smoothed else 0.0
        if weight <= 0.0:
            return None
        step = float(to_si(1.0, self.value_unit) - to_si(0.0, self.value_unit))
        matrix = np.zeros((self.roughness().shape[0], len(self.params)))
        names = list(self.params)
        columns = [names.index(name) for name in self.coefficient_names()]
        matrix[:, columns] = np.sqrt(samples) * weight * self.roughness() / step
        return matrix

    def table(self, points: int = 25) -> tuple[np.ndarray, np.ndarray]:
        """(x, shape) on an even grid between the end knots, in display units."""
        x = np.linspace(self.knots[0], self.knots[-1], points)
        return (from_si(x, self.variable.unit), from_si(self.shape(x), self.value_unit))


class OpeningForce(ShapeFreeEffect):
    """A force on the piston that depends on the opening alone, f(u), of a shape the data choose:
    a spring whose characteristic is not straight, a stop, a detent, a magnet.

    It depends on neither the pressures nor the temperature, which is what tells it from an
    error of the force map: that error scales with the flow force, hence with Δp, at each opening.
    """

    name = "shape_force_of_opening"
    kind = "force"
    category = "physics"
    title = "a force of the opening f(u), of free shape"
    quantity = "force"
    variable = VARIABLES["u"]
    value_unit = "N"
    validity = "Within the openings the log reaches; held beyond them."

    def force(self, state: BalanceState) -> np.ndarray:
        return self.shape(state.u)


class _RisingFriction(ShapeFreeEffect):
    rising = True
    kind = "friction"
    category = "physics"
    quantity = "friction"
    value_unit = "N"
    value_limit = 100.0
    validity = "Rising with its variable, zero at the smallest value the log holds."

    def friction(self, state: BalanceState) -> np.ndarray:
        return self.shape(self.variable.of(state))


def _friction_of(variable: Variable) -> type[ShapeFreeEffect]:
    """The shape-free friction rising with ``variable``."""
    return type(f"FrictionOf_{variable.name}", (_RisingFriction,), {
        "__doc__": (f"A Coulomb friction that rises with {variable.label}, g(x) >= 0, of a "
                    "shape the data choose: a seal energised by a pressure, a friction growing "
                    "as the oil thickens or the flow rises."),
        "__module__": __name__,
        "name": f"shape_friction_of_{variable.name}",
        "title": f"a friction rising with {variable.label}, of free shape",
        "variable": variable})


FRICTIONS = tuple(_friction_of(variable) for name, variable in VARIABLES.items() if name != "u")


class Leakage(ShapeFreeEffect):
    """A leakage past the restriction that rises with the pressure drop, h(Δp)·ν_ref/ν, of a
    shape the data choose: a clearance that opens under pressure, a leak that starts above a
    threshold. Laminar in the viscosity (ν_ref = 46 cSt)."""

    name = "shape_leakage"
    kind = "leakage"
    category = "physics"
    title = "a leakage rising with Δp, of free shape"
    quantity = "leakage"
    variable = PRESSURE_DROP
    rising = True
    value_unit = "L/min"
    value_limit = 20.0
    validity = "Rising with Δp from zero at Δp = 0; laminar in ν."

    @classmethod
    def knots_for(cls, x: np.ndarray) -> np.ndarray:
        return quantile_knots(x, start=0.0)

    formula = "{shape} * (%r / state.fluid.nu)" % NU_REFERENCE

    def leakage(self, dp: np.ndarray, state: FlowState) -> np.ndarray:
        return self.shape(np.maximum(dp, 0.0)) * (NU_REFERENCE / state.fluid.nu)


class FlowForceFactor(ShapeFreeEffect):
    """The map's flow force times 1 + m(u), m of a shape the data choose: the force map wrong
    by a share that changes with the opening."""

    name = "shape_flow_force_of_opening"
    kind = "force"
    category = "map correction"
    title = "the flow force scaled by a factor of the opening, of free shape"
    quantity = "flow-force change"
    variable = VARIABLES["u"]
    value_unit = "1"
    value_limit = 0.5
    validity = "Acts on the force map's flow force; zero with a uniform-pressure map."

    formula = "{shape} * state.flow_force"

    def force(self, state: BalanceState) -> np.ndarray:
        return self.shape(state.u) * state.flow_force


class DischargeFactor(ShapeFreeEffect):
    """The discharge coefficient times 1 + d(u), d of a shape the data choose: the flow map wrong
    by a share that changes with the opening."""

    name = "shape_discharge_of_opening"
    kind = "flow"
    category = "map correction"
    title = "the discharge coefficient scaled by a factor of the opening, of free shape"
    quantity = "discharge change"
    variable = VARIABLES["u"]
    value_unit = "1"
    value_limit = 0.5
    validity = "Acts on the flow map's discharge coefficient."

    formula = "q / (1.0 + {shape})"

    def restriction_flow(self, q: np.ndarray, state: FlowState) -> np.ndarray:
        return q / (1.0 + self.shape(state.u))


#: every shape-free effect, in the order a diagnosis tries them
SHAPE_FREE = (OpeningForce, *FRICTIONS, Leakage, FlowForceFactor, DischargeFactor)

__all__ = ["SHAPE_FREE", "VARIABLES", "ShapeFreeEffect", "OpeningForce", "Leakage",
           "FlowForceFactor", "DischargeFactor", "FRICTIONS", "spline_basis", "rising_basis",
           "quantile_knots"]
