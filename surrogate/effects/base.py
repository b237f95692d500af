"""Physical effects: terms of the valve's flow equation and force balance, with named parameters.

The valve model (:mod:`surrogate.model`) turns measured inputs into a force balance in five stages,
and an effect may take part in any of them through a hook (each returns None to stay out):

1. :meth:`Effect.correct_inputs` — **sensors**: measured operating points to true ones
   (a pilot-transducer offset, a flowmeter gain error).
2. :meth:`Effect.restriction_flow` — **flow**: the flow the main restriction's map sees, given the
   flow through it (a discharge-coefficient scale).
3. :meth:`Effect.leakage` — **leakage**: flow that bypasses the restriction at a pressure drop
   (laminar leakage past the piston); the model solves for the split.
4. :meth:`Effect.force` — **force**: an extra force on the piston, positive in the opening
   direction (a spring preload offset, a scaled flow force).
5. :meth:`Effect.friction` — **friction**: an extra half-width of the Coulomb friction band, >= 0;
   the solver makes it oppose the piston's motion (a play).

The solver never sees effects; a new effect is one new class with a ``name``, registered in
:mod:`surrogate.effects` or loaded from a user's file (:mod:`.custom`).

Parameters (:mod:`surrogate.parameters`) are stored in SI units and cross the boundary in the
unit each carries: an effect is made with display-unit values, ``LoadPressureFriction(K2=0.05)``
for 0.05 N/bar.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ..fluid import FluidState
from ..parameters import Parameter
from ..valve import ValveParameters

KINDS = ("sensor", "flow", "leakage", "force", "friction")

#: what an effect says about the valve, as a diagnosis reports it: **physics** of the valve itself
#: (friction, springs, leakage); a **map correction**, which patches the CFD maps where they are
#: wrong (a flow-force or discharge scale, a near-seat or back-pressure flow force); or a
#: **sensor** error of the bench. Only the first is news about the valve; the second says where
#: the CFD needs another look, the third where the bench does.
CATEGORIES = ("physics", "map correction", "sensor")


#: what an effect may hold for :meth:`Effect.copy` to copy it without deepcopy
_COPIED_CHEAPLY = frozenset({"params", "_cached", "_lines_cached"})
#: the types of a parameter's fields that no one changes in place
_IMMUTABLE = (float, int, str, bool, type(None), np.floating, np.integer, np.bool_)


def _plain(parameter: Parameter) -> bool:
    """Whether every field of ``parameter`` is of an immutable type (a shallow copy is then a
    deep one)."""
    return all(isinstance(value, _IMMUTABLE) for value in parameter.__dict__.values())


@dataclass(frozen=True)
class FlowState:
    """What a flow or leakage hook may use (SI units): the piston position and the inputs."""

    u: np.ndarray
    q: np.ndarray
    p_B: np.ndarray
    p_P: np.ndarray
    temperature: np.ndarray
    fluid: FluidState
    valve: ValveParameters

    def subset(self, index) -> "FlowState":
        """The state at some of its points (numpy indexing)."""
        return FlowState(self.u[index], self.q[index], self.p_B[index], self.p_P[index],
                         self.temperature[index], self.fluid[index], self.valve)


@dataclass(frozen=True)
class BalanceState:
    """Everything a force or friction hook may use at a batch of piston positions (SI units).

    ``q`` is the flow through the valve, ``flow_force`` f_ff from the force map (zero for a
    uniform-pressure map).
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
        Registry key, e.g. ``"friction_pilot_pressure"``.
    kind : str
        One of :data:`KINDS`: which stage of the model it acts in.
    category : str
        One of :data:`CATEGORIES`: valve physics, a map correction or a sensor error.
    title : str
        What it is, in words an engineer recognises.
    parameter_specs : tuple of Parameter
        Parameters with their default values ("effect off"), units, bounds and descriptions.
    validity : str
        Where the term holds and where it does not.
    custom, source : bool, str or None
        Whether it is a user's effect, and the file that defined it.
    """

    name: ClassVar[str] = ""
    kind: ClassVar[str] = ""
    category: ClassVar[str] = ""
    title: ClassVar[str] = ""
    parameter_specs: ClassVar[tuple[Parameter, ...]] = ()
    validity: ClassVar[str] = ""
    #: whether a diagnosis tries it among the library's candidates by default (the maps'
    #: calibration per opening is fitted once, last, under its prior: :mod:`.per_opening`)
    candidate: ClassVar[bool] = True
    #: a user's effect (from an effects file), and the file it came from: model files record it
    #: as a hint, since they never run code
    custom: ClassVar[bool] = False
    source: ClassVar[str | None] = None

    def __init__(self, **values: float):
        """Parameters take their default values unless given here, in their display units
        (``K2=0.05`` for 0.05 N/bar)."""
        self.params: dict[str, Parameter] = {spec.name: copy.copy(spec)
                                             for spec in self.parameter_specs}
        unknown = set(values) - set(self.params)
        if unknown:
            raise TypeError(f"{type(self).__name__} has no parameter(s) "
                            f"{', '.join(sorted(unknown))}; it has "
                            f"{', '.join(self.params) or 'none'}")
        for key, value in values.items():
            self.params[key].set_display(value)

    def __getitem__(self, key: str) -> float:
        """A parameter's SI value (what the hooks compute with)."""
        return self.params[key].value

    def __repr__(self) -> str:
        inside = ", ".join(str(p) for p in self.params.values())
        return f"{type(self).__name__}({inside})"

    @classmethod
    def describe(cls) -> str:
        """The docstring's first paragraph: the physics in a sentence or two."""
        doc = (cls.__doc__ or cls.title).strip().split("\n\n")[0]
        return " ".join(doc.split())

    def copy(self) -> "Effect":
        """A copy whose parameters can change without touching this one: what
        ``copy.deepcopy`` makes, made cheaper where the effect holds only its parameters (and a
        shape's cache of its spline or lines, :class:`.shapes.ShapeFreeEffect`,
        :mod:`.per_opening`): a parameter's fields are numbers, text and flags, so a shallow
        copy of each is a deep one, and a cache is never changed in place (a new parameter
        value builds a new one), so the copy may share it. A model is
        copied for every probe and trial of a fit, and deepcopy walked every parameter's fields
        (a third of a second of an off-library workflow). Anything else deepcopy copies."""
        state = getattr(self, "__dict__", None)
        if (state is None or not state.keys() <= _COPIED_CHEAPLY
                or not isinstance(state.get("params"), dict)
                or getattr(type(self), "__deepcopy__", None) is not None or not all(
                    type(p) is Parameter and _plain(p) for p in state["params"].values())):
            return copy.deepcopy(self)
        cls = type(self)
        new = cls.__new__(cls)
        new.__dict__.update(state)
        new.params = {key: copy.copy(p) for key, p in state["params"].items()}
        return new

    @classmethod
    def for_runs(cls, runs: list[str]) -> "Effect":
        """The effect, off, ready to be fitted to a log with these runs (the same for every
        effect but those with a parameter per run, :mod:`.per_run`)."""
        return cls()

    @classmethod
    def for_parameters(cls, names: list[str]) -> "Effect":
        """The effect, off, with parameters of these names (as a model file lists them)."""
        return cls()

    def check_parameters(self, where: str) -> None:
        """Refuse (InputError, naming ``where``) parameter values a model file may hold one by
        one but not together; the parameters are set. None here."""

    # hooks: return None to contribute nothing
    def correct_inputs(self, points):
        """True operating points from measured ones (an ``OperatingPoints``), or None."""
        return None

    def restriction_flow(self, q: np.ndarray, state: FlowState) -> np.ndarray | None:
        """The flow the main restriction's map should see when ``q`` [m^3/s] passes it."""
        return None

    def leakage(self, dp: np.ndarray, state: FlowState) -> np.ndarray | None:
        """Flow bypassing the main restriction at pressure drop ``dp`` [Pa], in [m^3/s]."""
        return None

    def force(self, state: BalanceState) -> np.ndarray | None:
        """Extra force on the piston [N], positive in the opening direction."""
        return None

    def friction(self, state: BalanceState) -> np.ndarray | None:
        """Extra half-width of the Coulomb friction band [N], >= 0."""
        return None

    def penalty(self, samples: int) -> np.ndarray | None:
        """A quadratic penalty that every fit of this effect adds to its sum of squares: L with
        ‖L·v‖² [Pa²] for the SI values v of :attr:`params` in their order, when the fit has
        ``samples`` residuals; None for none (the default). A shape-free term's roughness
        (:mod:`.shapes`) is one: without it a refit of its spline would follow the noise."""
        return None
