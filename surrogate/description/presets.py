"""The package's own models as specs: the presets, the paper's models and their starting values.

* ``bmbe``: the paper's basic model, orifice equation with C_d = 0.4 and a uniform pressure.
* ``bmbebf``: the same with its discharge coefficient scaled (the paper's best fit of it).
* ``cfd-maps``: the grid maps replace the orifice and the uniform pressure, with a flow-force
  scale and no friction. These two and ``cfda`` are the workflow's steps 2-4, by their names.
* ``cfda``: CFD maps (grid by default), a flow-force scale, and Coulomb friction K1 + K2·p_L with
  one K1 and one K2 for all temperatures, starting from the paper's 0.9, 6.5 N and 0.05 N/bar.
* ``cfda-<kind>``: the same on the maps of another kind (``cfda-nn``, ``cfda-gp``).

Everything here returns a :class:`~.spec.ModelSpec`; build it with ``.build()``.
"""

from __future__ import annotations

from pathlib import Path

from ..effects import ConstantFriction, DischargeScale, FlowForceScale, LoadPressureFriction
from ..core.errors import InputError, did_you_mean, named
from ..maps.orifice import BASIC_DISCHARGE_COEFFICIENT
from ..maps.registry import MAP_KINDS, MapsSpec
from .spec import EffectSpec, ModelSpec, ValveSource

#: the paper's CFDA starting values: flow-force scale, K1 [N], K2 [N/bar]; every model that adds
#: CFDA's effects starts from these
CFDA_START = {"scale": 0.9, "K1": 6.5, "K2": 0.05}
#: where the paper's comparison starts its friction fits per temperature (Table 6): about the
#: values of the paper's Table 6, K1 [N], K2 [N/bar], not CFDA's start
TABLE6_FRICTION_START = {"K1": 8.0, "K2": 0.05}


def maps(kind: str = "grid", cfd: str | Path | None = None, **options) -> MapsSpec:
    """Both maps of ``kind``, with its ``options`` (a learned kind's ``folder``, say); maps built
    from CFD samples record the file (default: the shipped one) and its SHA-256, so that a model
    built on them names the data it needs."""
    return MapsSpec.of_kind(kind, cfd, **options)


def basic_maps(discharge_coefficient: float = BASIC_DISCHARGE_COEFFICIENT) -> MapsSpec:
    """The basic model's maps: the orifice equation and a uniform pressure."""
    return MapsSpec.both("orifice", discharge_coefficient=discharge_coefficient)


#: what the paper's basic model is, in words
BMBE_DESCRIPTION = (f"the paper's basic model: orifice equation with "
                    f"C_d = {BASIC_DISCHARGE_COEFFICIENT:g}, uniform pressure")


def bmbe(valve: ValveSource | None = None) -> ModelSpec:
    """The paper's basic model BMBE."""
    return ModelSpec("bmbe", valve or ValveSource.shipped(), basic_maps(), (), BMBE_DESCRIPTION)


def cfda_effects(scale: float = CFDA_START["scale"], K1: float = CFDA_START["K1"],
                 K2: float = CFDA_START["K2"]) -> tuple[EffectSpec, ...]:
    """CFDA's effects: flow-force scale [-], K1 [N], K2 [N/bar]."""
    return (EffectSpec.start(FlowForceScale, scale=scale), *cfda_friction(K1, K2))


def cfda_friction(K1: float = CFDA_START["K1"], K2: float = CFDA_START["K2"]
                  ) -> tuple[EffectSpec, ...]:
    """CFDA's Coulomb friction s·(K1 + K2·p_L): K1 [N], K2 [N/bar]."""
    return (EffectSpec.start(ConstantFriction, K1=K1),
            EffectSpec.start(LoadPressureFriction, K2=K2))


def cfda(valve: ValveSource | None = None, maps_spec: MapsSpec | None = None,
         name: str = "cfda") -> ModelSpec:
    """The paper's CFDA on ``maps_spec`` (default: the grid maps of the shipped samples)."""
    maps_spec = maps_spec or maps("grid")
    return ModelSpec(name, valve or ValveSource.shipped(), maps_spec, cfda_effects(),
                     f"{maps_kind_name(maps_spec)} maps, flow-force scale, Coulomb friction "
                     "K1 + K2*p_L (one pair for all temperatures)")


def maps_kind_name(spec: MapsSpec) -> str:
    return spec.flow.kind if spec.flow == spec.force else f"{spec.flow.kind}/{spec.force.kind}"


def bmbebf_step(previous: ModelSpec) -> ModelSpec:
    """The paper's best-fit basic model: the orifice's discharge coefficient scaled (fitted)."""
    return previous.adding(EffectSpec.start(DischargeScale), name="bmbebf")


def cfd_maps_step(previous: ModelSpec, maps_spec: MapsSpec) -> ModelSpec:
    """CFD maps replace the orifice equation and the uniform pressure, with a flow-force scale."""
    return ModelSpec("cfd-maps", previous.valve, maps_spec,
                     (EffectSpec.start(FlowForceScale, scale=CFDA_START["scale"]),))


def cfda_step(previous: ModelSpec) -> ModelSpec:
    """Coulomb friction K1 + K2·p_L added, one pair for all temperatures."""
    return previous.adding(*cfda_friction(), name="cfda")


PRESET_DESCRIPTIONS = {
    "bmbe": BMBE_DESCRIPTION,
    "bmbebf": "bmbe with its discharge coefficient scaled (the workflow's step 2)",
    "cfd-maps": "grid maps, flow-force scale, no friction (the workflow's step 3)",
    "cfda": "grid maps, flow-force scale, Coulomb friction K1 + K2*p_L",
    **{f"cfda-{name}": f"as cfda on the {name} maps" for name, kind in MAP_KINDS.items()
       if kind.learned},
}
PRESETS = tuple(PRESET_DESCRIPTIONS)


def preset_named(text: str) -> str | None:
    """The preset ``text`` names, in any case (``"CFDA"`` is cfda, as reports write it), or
    None."""
    return named(text, PRESETS)


def preset(name: str, valve: ValveSource | None = None) -> ModelSpec:
    """A preset by name, in any case (see the module docstring)."""
    name = preset_named(name) or name
    if name == "bmbe":
        return bmbe(valve)
    if name == "bmbebf":
        return bmbebf_step(bmbe(valve))
    if name == "cfd-maps":
        return cfd_maps_step(bmbe(valve), maps("grid"))
    if name == "cfda":
        return cfda(valve)
    if name in PRESET_DESCRIPTIONS and name.startswith("cfda-"):
        kind = name.removeprefix("cfda-")
        return cfda(valve, maps(kind), name)
    raise InputError(f"unknown preset {name!r}{did_you_mean(name, PRESETS)}; presets: "
                     f"{', '.join(PRESETS)}")
