"""Hidden effects whose shapes the library does not name, for the off-library stress test.

A workbench that finds only what its library names has proved little about a real valve. These
effects are what real valves show, in shapes no library term has; a stress case draws one, with
its size, shape and position, and hides it in a virtual valve that also differs from its CFD
(:mod:`.mismatch`). The diagnosis must find a term of the right *kind* (a force, a friction, a
leakage) on the right *variable* (:attr:`OffLibraryEffect.variable`), shape-free or from the
library, and nothing else.

* :class:`DetentForce`: a closing force bump around one opening (a detent, a ball seat, a
  magnet): a force of u;
* :class:`KinkedSpring`: a spring whose rate grows beyond one opening (a second spring, a coil
  that touches): a force of u;
* :class:`ExtrusionFriction`: seal friction that sets in above a load pressure (a seal pressed
  into its gap): a friction of p_L;
* :class:`FlowFriction`: friction rising with the flow (a jet on a seal lip): a friction of q;
* :class:`ThresholdLeakage`: a leak that opens above a pressure drop (a clearance that deforms,
  a check ball lifting): a leakage of Δp.

Leaks follow other laws than the library's laminar one (:data:`LEAK_LAWS`, drawn by
:func:`off_library_suite` with ``leaks``): through an orifice (√Δp, :class:`TurbulentLeakage`),
opening above thresholds from low to high (:class:`ThresholdLeakage`, its threshold drawn over a
wider range there), growing with the opening (:class:`OpeningLeakage`) or with the temperature
beyond what the viscosity gives (:class:`WarmLeakage`), at sizes from barely visible to dominant.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ..effects import BalanceState, Effect, EffectLibrary, FlowState, Parameter
from ..effects.shapes import ShapeFreeEffect
from ..core.units import BAR, CST, LPM
from .visibility import RMS_RATIO, TWIN_RATIO, left_nothing_to_find, over_floor


class OffLibraryEffect(Effect):
    """Base class: an effect the generator hides; ``variable`` is what its shape depends on
    (a name of :data:`surrogate.effects.shapes.VARIABLES`, or ``"dp"``)."""

    category = "physics"
    variable: ClassVar[str] = ""

    @classmethod
    def draw(cls, rng: np.random.Generator) -> dict[str, float]:
        """Parameter values (display units) for one stress case."""
        raise NotImplementedError


class DetentForce(OffLibraryEffect):
    """A closing force A·exp(−½((u − u₀)/w)²) around the opening u₀."""

    name = "detent_force"
    kind = "force"
    title = "a detent: a closing force bump around one opening"
    variable = "u"
    parameter_specs = (Parameter("A", 0.0, "N", min=0.0, max=50.0),
                       Parameter("u0", 0.15e-3, "mm", min=0.0, max=1e-3, vary=False),
                       Parameter("w", 0.04e-3, "mm", min=1e-6, max=1e-3, vary=False))

    def force(self, state: BalanceState) -> np.ndarray:
        return -self["A"] * np.exp(-0.5 * ((state.u - self["u0"]) / self["w"]) ** 2)

    @classmethod
    def draw(cls, rng):
        return {"A": rng.uniform(6.0, 12.0), "u0": rng.uniform(0.08, 0.30),
                "w": rng.uniform(0.03, 0.07)}


class KinkedSpring(OffLibraryEffect):
    """An extra spring rate k beyond the opening u_k: a closing force k·max(u − u_k, 0)."""

    name = "kinked_spring"
    kind = "force"
    title = "a spring whose rate grows beyond one opening"
    variable = "u"
    parameter_specs = (Parameter("k", 0.0, "N/m", min=0.0, max=500e3),
                       Parameter("u_k", 0.2e-3, "mm", min=0.0, max=1e-3, vary=False))

    def force(self, state: BalanceState) -> np.ndarray:
        return -self["k"] * np.maximum(state.u - self["u_k"], 0.0)

    @classmethod
    def draw(cls, rng):
        knee = rng.uniform(0.10, 0.30)  # and 20-40 N more at the full stroke, 0.63 mm
        return {"k": rng.uniform(20.0, 40.0) / ((0.63 - knee) * 1e-3), "u_k": knee}


class ExtrusionFriction(OffLibraryEffect):
    """Friction K·max(p_L − p₀, 0)/(100 bar) that sets in above the load pressure p₀."""

    name = "extrusion_friction"
    kind = "friction"
    title = "seal friction setting in above a load pressure"
    variable = "p_L"
    parameter_specs = (Parameter("K", 0.0, "N", min=0.0, max=100.0),
                       Parameter("p0", 80 * BAR, "bar", min=0.0, max=400 * BAR, vary=False))

    def friction(self, state: BalanceState) -> np.ndarray:
        return self["K"] * np.maximum(state.p_L - self["p0"], 0.0) / (100.0 * BAR)

    @classmethod
    def draw(cls, rng):
        return {"K": rng.uniform(12.0, 24.0), "p0": rng.uniform(50.0, 100.0)}


class FlowFriction(OffLibraryEffect):
    """Friction K·(q/10 L/min)^n rising with the flow."""

    name = "flow_friction"
    kind = "friction"
    title = "friction rising with the flow"
    variable = "q"
    parameter_specs = (Parameter("K", 0.0, "N", min=0.0, max=100.0),
                       Parameter("n", 1.5, "1", min=0.5, max=4.0, vary=False))

    def friction(self, state: BalanceState) -> np.ndarray:
        return self["K"] * (np.maximum(state.q, 0.0) / (10.0 * LPM)) ** self["n"]

    @classmethod
    def draw(cls, rng):
        return {"K": rng.uniform(3.0, 7.0), "n": rng.uniform(1.0, 2.5)}


#: a leak's size G, about its flow at 100 bar (each leak's docstring says where exactly) [m³/s]
LEAK_SIZE = Parameter("G", 0.0, "L/min", min=0.0, max=20 * LPM)


class ThresholdLeakage(OffLibraryEffect):
    """A laminar leak G·max(Δp − p₀, 0)·ν_ref/ν that opens above the pressure drop p₀ (G per
    100 bar above it, at 46 cSt)."""

    name = "threshold_leakage"
    kind = "leakage"
    title = "a leak opening above a pressure drop"
    variable = "dp"
    parameter_specs = (LEAK_SIZE,
                       Parameter("p0", 80 * BAR, "bar", min=0.0, max=400 * BAR, vary=False))

    def leakage(self, dp: np.ndarray, state: FlowState) -> np.ndarray:
        return (self["G"] * np.maximum(dp - self["p0"], 0.0) / (100.0 * BAR)
                * (46.0 * CST / state.fluid.nu))

    @classmethod
    def draw(cls, rng):
        return {"G": rng.uniform(0.3, 0.6), "p0": rng.uniform(40.0, 90.0)}


class TurbulentLeakage(OffLibraryEffect):
    """A leak through an orifice, G·√(Δp/100 bar): turbulent, so the viscosity does not enter."""

    name = "turbulent_leakage"
    kind = "leakage"
    title = "a leak through an orifice, rising with the square root of the pressure drop"
    variable = "dp"
    parameter_specs = (LEAK_SIZE,)

    def leakage(self, dp: np.ndarray, state: FlowState) -> np.ndarray:
        return self["G"] * np.sqrt(np.maximum(dp, 0.0) / (100.0 * BAR))

    @classmethod
    def draw(cls, rng):
        return {"G": leak_size(rng)}


class OpeningLeakage(OffLibraryEffect):
    """A laminar leak that grows with the opening, G·(u/0.63 mm)·(Δp/100 bar)·ν_ref/ν (a seal
    lifted off its land as the piston moves)."""

    name = "opening_leakage"
    kind = "leakage"
    title = "a leak growing with the opening"
    variable = "dp"
    parameter_specs = (LEAK_SIZE,)

    def leakage(self, dp: np.ndarray, state: FlowState) -> np.ndarray:
        return (self["G"] * np.maximum(state.u, 0.0) / 0.63e-3
                * np.maximum(dp, 0.0) / (100.0 * BAR) * (46.0 * CST / state.fluid.nu))

    @classmethod
    def draw(cls, rng):
        return {"G": leak_size(rng)}


class WarmLeakage(OffLibraryEffect):
    """A leak whose clearance opens as the valve warms: G·(Δp/100 bar)·exp(b·(T − 60 °C)/20 K),
    with no viscosity in it (a gap between parts of unlike expansion); G is its size at the
    bench's warmest, 60 °C."""

    name = "warm_leakage"
    kind = "leakage"
    title = "a leak growing with the temperature"
    variable = "dp"
    parameter_specs = (LEAK_SIZE,
                       Parameter("b", 1.0, "1", min=0.0, max=3.0, vary=False))

    def leakage(self, dp: np.ndarray, state: FlowState) -> np.ndarray:
        warmer = (np.asarray(state.temperature, float) - 333.15) / 20.0
        return (self["G"] * np.maximum(dp, 0.0) / (100.0 * BAR)
                * np.exp(self["b"] * warmer))

    @classmethod
    def draw(cls, rng):
        return {"G": leak_size(rng), "b": rng.uniform(0.5, 1.5)}


#: a leak's flow at 100 bar [L/min]: from barely visible (about the flow meter's noise) to
#: dominant (the bench's smallest flows; a larger leak leaves runs no equilibrium at all)
LEAK_SIZES_LPM = (0.05, 1.0)


def leak_size(rng: np.random.Generator) -> float:
    """A leak's flow at 100 bar [L/min], log-uniform over :data:`LEAK_SIZES_LPM`."""
    return float(np.exp(rng.uniform(*np.log(LEAK_SIZES_LPM))))


OFF_LIBRARY = EffectLibrary([DetentForce, KinkedSpring, ExtrusionFriction, FlowFriction,
                             ThresholdLeakage, TurbulentLeakage, OpeningLeakage, WarmLeakage])
#: the leaks of other laws than the laminar one, drawn in turn by ``off_library_suite(leaks=...)``
LEAK_LAWS = ("turbulent_leakage", "threshold_leakage", "opening_leakage", "warm_leakage")
#: the range of a threshold leak's threshold among the leak laws [bar]: low to high
LEAK_THRESHOLDS_BAR = (20.0, 150.0)

#: the kind and variable of every library effect that a diagnosis may add for an off-library
#: one (a term of the right kind on the right variable counts as found)
LIBRARY_SHAPES = {
    "spring_preload_offset": ("force", "u"), "progressive_spring": ("force", "u"),
    "friction_load_pressure": ("friction", "p_L"),
    "friction_seal_pressure": ("friction", "p_LP"), "friction_pilot_pressure": ("friction", "p_P"),
    "friction_pilot_differential": ("friction", "p_P"), "friction_viscous": ("friction", "nu"),
    "laminar_leakage": ("leakage", "dp"),
}


@dataclass(frozen=True)
class OffLibraryCase:
    """One log of the off-library stress test: the hidden effect (None: nothing) and its values
    (display units), and the seed of its noise and map mismatch."""

    hidden: str | None
    values: dict[str, float] | None
    seed: int


#: the effects ``cases`` cycle through (the leak laws are drawn by ``leaks``)
SHAPES = ("detent_force", "kinked_spring", "extrusion_friction", "flow_friction",
          "threshold_leakage")


def off_library_suite(cases: int = 20, controls: int = 10, seed: int = 4242, leaks: int = 0
                      ) -> list[OffLibraryCase]:
    """``cases`` logs with one off-library effect each (:data:`SHAPES` in turn, sizes, shapes
    and positions drawn), ``leaks`` with a leak of another law than the laminar one
    (:data:`LEAK_LAWS` in turn, sizes stratified in ln G over :data:`LEAK_SIZES_LPM`), and
    ``controls`` with nothing hidden; every log has its own seed."""
    rng = np.random.default_rng(seed)
    suite = [OffLibraryCase(SHAPES[i % len(SHAPES)], OFF_LIBRARY[SHAPES[i % len(SHAPES)]].draw(rng),
                            seed + 1 + i) for i in range(cases)]
    leak_rng = np.random.default_rng([seed, 1])  # its own stream: the cases above keep theirs
    # sizes stratified in ln G, the strata shuffled: every suite spans barely visible to
    # dominant, whatever its length, and each law meets small and large sizes
    strata = leak_rng.permutation(leaks)
    low, high = np.log(LEAK_SIZES_LPM)
    for i in range(leaks):
        name = LEAK_LAWS[i % len(LEAK_LAWS)]
        values = OFF_LIBRARY[name].draw(leak_rng)
        if name == "threshold_leakage":  # thresholds from low to high
            values["p0"] = float(leak_rng.uniform(*LEAK_THRESHOLDS_BAR))
        share = (strata[i] + leak_rng.uniform()) / leaks
        values["G"] = float(np.exp(low + share * (high - low)))
        suite.append(OffLibraryCase(name, values, seed + 301 + i))
    return suite + [OffLibraryCase(None, None, seed + 501 + i) for i in range(controls)]


def term_shape(name: str, model) -> tuple[str, str] | None:
    """The (kind, variable) of valve physics ``name`` in ``model``: a library effect's from
    :data:`LIBRARY_SHAPES`, a shape-free term's its own; None for a map correction, a sensor,
    or a term of no single variable."""
    if name in LIBRARY_SHAPES:
        return LIBRARY_SHAPES[name]
    effect = model.effect(name) if model.has_effect(name) else None
    if isinstance(effect, ShapeFreeEffect) and effect.category == "physics":
        return effect.kind, effect.variable.name
    return None


@dataclass(frozen=True)
class OffLibraryOutcome:
    """How a workflow did on one off-library case.

    ``twin_over_floor`` is what the same virtual valve with nothing hidden (the same map
    mismatch and noise) ends at, over its noise floor: under map mismatch even a log with
    nothing hidden can stay above 1.3x the floor (1.27-1.81x on grid maps), since the maps'
    error is not noise and no term may absorb it."""

    hidden: str | None
    added: tuple[str, ...]  # every term the diagnosed steps added
    matching: tuple[str, ...]  # of those, physics of the hidden effect's kind and variable
    invented: tuple[str, ...]  # physics or sensor terms beyond those (map corrections allowed)
    rms_over_floor: float
    twin_over_floor: float = float("nan")
    #: the physics claims the loop named and withheld for their look-alikes of other kinds
    withheld: tuple[str, ...] = ()

    @property
    def right_term(self) -> bool:
        """A term of the hidden effect's kind on its variable added, nothing invented (with
        nothing hidden: nothing invented)."""
        if self.hidden is None:
            return not self.invented
        return bool(self.matching) and not self.invented

    @property
    def within_floor(self) -> bool:
        """The final RMS within :data:`RMS_RATIO` of the noise floor."""
        return self.rms_over_floor <= RMS_RATIO

    @property
    def as_twin(self) -> bool:
        """The final RMS within :data:`TWIN_RATIO` of the nothing-hidden twin's (or of the
        floor's :data:`RMS_RATIO`, whichever is larger): all the effect's error is gone."""
        twin = self.twin_over_floor if np.isfinite(self.twin_over_floor) else RMS_RATIO
        return self.rms_over_floor <= max(RMS_RATIO, TWIN_RATIO * twin)

    @property
    def invisible(self) -> bool:
        """Nothing added, nothing withheld and nothing left to find
        (:func:`.visibility.left_nothing_to_find`): the hidden effect (a leak of 0.05 L/min,
        say) moved nothing the bench can see."""
        return (self.hidden is not None and not self.added and not self.withheld
                and left_nothing_to_find(self.rms_over_floor, self.twin_over_floor))

    @property
    def clean(self) -> bool:
        """Nothing invented, and the hidden effect found or invisible on this log."""
        return self.found or (self.invisible and not self.invented)

    @property
    def found(self) -> bool:
        """The right term, nothing invented, and the final RMS within 1.3x the noise floor (the
        issue's criterion; with nothing hidden: nothing invented)."""
        return self.right_term and (self.hidden is None or self.within_floor)

    def to_json(self) -> dict:
        return {"hidden": self.hidden, "added": list(self.added), "matching": list(self.matching),
                "invented": list(self.invented), "rms_over_floor": round(self.rms_over_floor, 3),
                "twin_over_floor": (round(self.twin_over_floor, 3)
                                    if np.isfinite(self.twin_over_floor) else None),
                "right_term": self.right_term, "within_floor": self.within_floor,
                "as_twin": self.as_twin, "found": self.found, "invisible": self.invisible,
                "clean": self.clean}


def off_library_outcome(workflow, hidden: str | None, twin=None) -> OffLibraryOutcome:
    """Judge a workflow run on a log with off-library effect ``hidden`` (None: nothing hidden);
    ``twin`` is the workflow on the same virtual valve with nothing hidden, if run."""
    model = workflow.final.model
    target = None if hidden is None else (OFF_LIBRARY[hidden].kind, OFF_LIBRARY[hidden].variable)
    added, matching, invented = [], [], []
    for step in workflow.steps[1:]:
        if step.diagnosis is None:  # a paper step
            continue
        for name in step.added:
            added.append(name)
            # the term, or a look-alike the log cannot tell from it, named beside it
            shapes = {term_shape(name, model)} | explanation_shapes(step.diagnosis, name)
            if target is not None and target in shapes:
                matching.append(name)
            elif _category(name, model) != "map correction":
                invented.append(name)
    twin_ratio = float("nan") if twin is None else over_floor(twin)
    return OffLibraryOutcome(hidden, tuple(added), tuple(matching), tuple(invented),
                             over_floor(workflow), twin_ratio,
                             tuple(declined.claim.name for declined in workflow.declined))


def explanation_shapes(diagnosis, name: str) -> set[tuple[str, str]]:
    """The (kind, variable) of the physics among the explanations of ``diagnosis``' finding,
    when ``name`` is that finding (empty otherwise): a library term and the shape of free shape
    the log cannot tell from it are one finding (:func:`surrogate.diagnosis.lookalikes.
    alike_shapes`)."""
    best = diagnosis.best
    if best is None or best.name != name:
        return set()
    found = set()
    for candidate in diagnosis.explanations:
        if candidate.name in LIBRARY_SHAPES:
            found.add(LIBRARY_SHAPES[candidate.name])
        elif candidate.shape_free and candidate.category == "physics":
            found.add((candidate.kind, candidate.curve.variable))
    return found


def _category(name: str, model) -> str:
    """The category of the model's effect ``name`` (physics, map correction, sensor)."""
    return model.effect(name).category if model.has_effect(name) else "physics"
