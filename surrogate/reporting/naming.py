"""Naming a shape: which library term, if any, has the shape a shape-free term found.

A shape-free term that fits is a hypothesis without a name. Each library term of the same kind
on the same variable has a shape of its own, with free size (a constant preload, a spring rising
with u², a friction proportional to p_L ...). Fitted to the found shape, weighted by its band
(one standard deviation at each point), a library shape that stays within two standard
deviations everywhere *fits the shape*: the library term says what the shape-free one says, with
one parameter and a name. One that does not leaves the shape unnamed, and the largest departure
says what distinguishes it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..effects.shapes import SHAPE_FREE, VARIABLES
from ..diagnosis.result import ShapeCurve

#: a library shape fits a found one when it stays within this many of its standard deviations
WITHIN = 2.0

#: per shape-free effect: the library terms of its kind on its variable, each as the functions
#: of the variable (in display units) whose free combination it can take
LIBRARY_SHAPES: dict[str, tuple[tuple[str, tuple], ...]] = {
    "shape_force_of_opening": (
        ("spring_preload_offset", (np.ones_like,)),
        ("progressive_spring", (np.square,)),
        ("spring_preload_offset + progressive_spring", (np.ones_like, np.square)),
    ),
    "shape_friction_of_p_L": (("friction_load_pressure", (lambda x: x - x[0],)),),
    "shape_friction_of_p_P": (("friction_pilot_pressure", (lambda x: x - x[0],)),),
    "shape_friction_of_p_LP": (("friction_seal_pressure", (lambda x: x - x[0],)),),
    "shape_friction_of_nu": (("friction_viscous", (lambda x: x - x[0],)),),
    "shape_leakage": (("laminar_leakage", (lambda x: x,)),),
    "shape_flow_force_of_opening": (("flow_force_scale", (np.ones_like,)),),
    "shape_discharge_of_opening": (("discharge_scale", (np.ones_like,)),),
}


#: library terms no shape-free term generalises, by the variable they change with: a flow force
#: fading near the seat changes with the opening; a pilot-differential friction is the
#: pilot-pressure one where the back pressure is small (its validity)
OTHER_VARIABLES = {"seat_flow_force": "u", "back_pressure_flow_force": "p_B",
                   "friction_pilot_differential": "p_P"}
#: what an effect of each kind (:data:`surrogate.effects.KINDS`) is, in words, and how it
#: changes with its variable (frictions and leakages of free shape only rise)
KIND_WORDS = {"friction": ("a friction", "growing with"),
              "leakage": ("a leakage", "growing with"),
              "force": ("a force on the piston", "changing with"),
              "flow": ("a discharge coefficient", "changing with"),
              "sensor": ("a sensor error", "changing with")}


@dataclass(frozen=True)
class Family:
    """The physics an effect stands for, whatever its shape: its kind (where in the model it
    acts) and the state variable it changes with. A library friction growing with viscosity and
    a friction of free shape rising with it are one family; an effect that changes with no
    variable (a constant friction, a sensor's gain) is a family of its own, named by its title.
    """

    kind: str
    variable: str  # the variable's label ("the oil's viscosity ν"), "" for none
    title: str = ""  # the effect's own title, for a family without a variable

    @property
    def words(self) -> str:
        """The family in words: "a friction growing with the oil's viscosity ν"."""
        if not self.variable:
            return self.title
        noun, how = KIND_WORDS.get(self.kind, (f"a {self.kind} term", "changing with"))
        return f"{noun} {how} {self.variable}"


def _shape_variables() -> dict[str, str]:
    """{effect name: the name of the variable it changes with} for the shape-free terms, the
    library terms each generalises (:data:`LIBRARY_SHAPES`) and :data:`OTHER_VARIABLES`."""
    found = {}
    for cls in SHAPE_FREE:
        variable = cls.variable.name
        found[cls.name] = variable
        for names, _ in LIBRARY_SHAPES.get(cls.name, ()):
            for name in names.split(" + "):
                found.setdefault(name, variable)
    return {**found, **OTHER_VARIABLES}


_VARIABLE_OF = _shape_variables()
_LABELS = {**{name: variable.label for name, variable in VARIABLES.items()},
           **{cls.variable.name: cls.variable.label for cls in SHAPE_FREE}}


def family(effect) -> Family:
    """The :class:`Family` of an effect, an effect class or a diagnosis candidate (anything
    with a ``name``, a ``kind`` and a ``title``)."""
    variable = _VARIABLE_OF.get(effect.name)
    if variable is None:
        return Family(effect.kind, "", effect.title)
    return Family(effect.kind, _LABELS[variable])


@dataclass(frozen=True)
class ShapeMatch:
    """A library term fitted to a found shape.

    ``fitted`` holds its values on the curve's grid (display units); ``worst`` is its largest
    departure from the shape in standard deviations, at ``worst_at`` (the variable's display
    units).
    """

    name: str
    fitted: np.ndarray
    worst: float
    worst_at: float

    @property
    def fits(self) -> bool:
        """Whether it stays within :data:`WITHIN` standard deviations of the shape."""
        return self.worst <= WITHIN


def library_matches(shape_name: str, curve: ShapeCurve) -> list[ShapeMatch]:
    """Every library term of the shape's kind and variable fitted to it, closest first."""
    x, value = np.asarray(curve.x, float), np.asarray(curve.value, float)
    sigma = np.maximum(np.asarray(curve.band, float), 1e-9 * max(np.ptp(value), 1e-12))
    matches = []
    for name, functions in LIBRARY_SHAPES.get(shape_name, ()):
        basis = np.column_stack([function(x) for function in functions])
        coefficients = np.linalg.lstsq(basis / sigma[:, None], value / sigma, rcond=None)[0]
        fitted = basis @ coefficients
        departure = np.abs(fitted - value) / sigma
        worst = int(np.argmax(departure))
        matches.append(ShapeMatch(name, fitted, float(departure[worst]), float(x[worst])))
    return sorted(matches, key=lambda match: match.worst)


@dataclass(frozen=True)
class ShapeFeatures:
    """What a found shape does, in numbers: its range, and the point where it departs most
    from the straight line between its ends (a bump or a dip, or a bend)."""

    low: float  # its smallest value and where [display units]
    low_at: float
    high: float  # its largest value and where
    high_at: float
    rising: bool  # monotone, within its band
    falling: bool
    bend: float  # the largest departure from the line through its ends, signed
    bend_at: float
    steepest_at: float  # where it changes fastest with the variable


def shape_features(curve: ShapeCurve) -> ShapeFeatures:
    """The features of :class:`ShapeFeatures` of a curve."""
    x, value = np.asarray(curve.x, float), np.asarray(curve.value, float)
    band = np.asarray(curve.band, float)
    steps = np.diff(value)
    slack = np.minimum(band[1:], band[:-1])
    line = value[0] + (value[-1] - value[0]) * (x - x[0]) / max(x[-1] - x[0], 1e-300)
    bend = int(np.argmax(np.abs(value - line)))
    steepest = int(np.argmax(np.abs(steps) / np.maximum(np.diff(x), 1e-300)))
    return ShapeFeatures(float(value.min()), float(x[np.argmin(value)]), float(value.max()),
                         float(x[np.argmax(value)]), bool(np.all(steps >= -slack)),
                         bool(np.all(steps <= slack)), float(value[bend] - line[bend]),
                         float(x[bend]), float(0.5 * (x[steepest] + x[steepest + 1])))
