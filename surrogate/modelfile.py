"""Valve models as data: presets and readable TOML files.

A model file names its maps and valve and lists its effects with their parameters (in display
units, with bounds and whether a fit may vary them)::

    [model]
    name = "cfda"
    description = "grid maps, fitted flow-force scale, Coulomb friction K1 + K2*p_L"
    valve = "shipped"                    # or the path of a valve file
    maps = { kind = "grid" }             # orifice (with discharge_coefficient), grid, nn, gp,
                                         # or the path of a trained surrogate folder
    [[effects]]
    name = "flow_force_scale"
    [effects.parameters]
    scale = { value = 0.885, unit = "1", min = 0.0, max = 3.0, vary = true }

Loading never runs code: a custom effect in a model file must be supplied again with
``--effects-file`` (its ``source`` is recorded as a hint).

Presets
-------
* ``bmbe``: the paper's basic model, orifice equation with C_d = 0.4 and a uniform pressure.
* ``cfda``: grid maps, a flow-force scale, and Coulomb friction K1 + K2·p_L with one K1 and
  one K2 for all temperatures (starting from the paper's 0.9, 6.5 N and 0.05 N/bar).
* ``cfda-nn``, ``cfda-gp``: the same on the learned maps.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

from .effects import ConstantFriction, Effect, FlowForceScale, LoadPressureFriction, effect_class
from .errors import InputError
from .maps.orifice import OrificeFlowMap, UniformPressureForceMap
from .maps.registry import build_maps
from .model import MapsSource, ValveModel
from .outputs import atomic_file
from .tomlio import dumps
from .units import from_si, to_si
from .valve import ValveParameters, load_valve

BASIC_DISCHARGE_COEFFICIENT = 0.4
_PRESET_DESCRIPTIONS = {
    "bmbe": "the paper's basic model: orifice equation with C_d = 0.4, uniform pressure",
    "cfda": "grid maps, flow-force scale, Coulomb friction K1 + K2*p_L (one pair for all "
            "temperatures)",
    "cfda-nn": "as cfda on the monotone neural-network maps",
    "cfda-gp": "as cfda on the Gaussian-process maps",
}
PRESETS = tuple(_PRESET_DESCRIPTIONS)


def build_model(source: MapsSource, valve: ValveParameters, effects: list[Effect], name: str,
                cfd_samples=None) -> ValveModel:
    """A model from where its maps come from, the valve and its effects."""
    if source.kind == "orifice":
        coefficient = source.options.get("discharge_coefficient", BASIC_DISCHARGE_COEFFICIENT)
        maps = (OrificeFlowMap(float(coefficient), valve.w), UniformPressureForceMap(valve))
    else:
        maps = build_maps(source.kind, valve, cfd_samples)
    return ValveModel(valve, *maps, effects, name, source)


def cfda_effects() -> list[Effect]:
    """The CFDA model's effects at their starting values (the paper's 0.9, 6.5 N, 0.05 N/bar)."""
    return [FlowForceScale(scale=0.9), ConstantFriction(K1=6.5),
            LoadPressureFriction(K2=to_si(0.05, "N/bar"))]


def preset(name: str, valve: ValveParameters | None = None, cfd_samples=None) -> ValveModel:
    """A preset model (see the module docstring)."""
    valve = valve or load_valve()
    if name == "bmbe":
        source = MapsSource("orifice", {"discharge_coefficient": BASIC_DISCHARGE_COEFFICIENT})
        return build_model(source, valve, [], name)
    if name in ("cfda", "cfda-nn", "cfda-gp"):
        kind = {"cfda": "grid", "cfda-nn": "nn", "cfda-gp": "gp"}[name]
        return build_model(MapsSource(kind), valve, cfda_effects(), name, cfd_samples)
    raise InputError(f"unknown preset {name!r}; presets: {', '.join(PRESETS)}")


def load_model(spec: str, valve_path: str | None = None, cfd_samples=None) -> ValveModel:
    """A preset by name, or a model file by path.

    ``valve_path`` replaces the model's valve (for presets, the shipped valve otherwise).
    """
    if spec in PRESETS:
        return preset(spec, load_valve(valve_path) if valve_path else None, cfd_samples)
    path = Path(spec)
    if not path.is_file():
        raise InputError(f"unknown model {spec!r}: give a preset ({', '.join(PRESETS)}) or the "
                         "path of a model file")
    try:
        document = tomllib.loads(path.read_text("utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as error:
        raise InputError(f"{path}: not a valid TOML model file ({error})") from None
    return model_from_dict(document, f"{path}", path.parent, valve_path, cfd_samples)


def model_from_dict(document: dict, source: str, folder: Path, valve_path: str | None = None,
                    cfd_samples=None) -> ValveModel:
    """Build a model from a parsed model file (``source`` names it in messages)."""
    table = document.get("model")
    if not isinstance(table, dict) or "maps" not in table:
        raise InputError(f"{source}: needs a [model] table with maps = {{ kind = ... }}")
    maps = table["maps"]
    if isinstance(maps, str):
        maps = {"kind": maps}
    kind = maps.get("kind")
    if not isinstance(kind, str):
        raise InputError(f"{source}: [model] maps needs a kind (orifice, grid, nn, gp or a path)")
    if kind not in ("orifice", "grid", "nn", "gp"):
        kind = str((folder / kind).resolve()) if not Path(kind).is_absolute() else kind
    options = {k: v for k, v in maps.items() if k != "kind"}
    valve_spec = valve_path or table.get("valve", "shipped")
    if valve_spec == "shipped":
        valve = load_valve()
    else:
        candidate = Path(valve_spec)
        valve = load_valve(candidate if candidate.is_absolute() or valve_path
                           else folder / candidate)
    effects = [_effect_from_entry(entry, source, index)
               for index, entry in enumerate(document.get("effects", []), start=1)]
    return build_model(MapsSource(kind, options), valve, effects,
                       str(table.get("name", Path(source).stem)), cfd_samples)


def _effect_from_entry(entry: dict, source: str, index: int) -> Effect:
    where = f"{source}, effect {index}"
    if not isinstance(entry, dict) or "name" not in entry:
        raise InputError(f"{where}: needs a name")
    try:
        cls = effect_class(entry["name"])
    except InputError as error:
        hint = f" (its source was {entry['source']})" if "source" in entry else ""
        raise InputError(f"{where}: {error}{hint}") from None
    effect = cls.for_parameters(list(entry.get("parameters", {})))
    for key, spec in entry.get("parameters", {}).items():
        if key not in effect.params:
            raise InputError(f"{where} ({cls.name}): unknown parameter {key!r}; it has "
                             f"{', '.join(effect.params)}")
        parameter = effect.params[key]
        if not isinstance(spec, dict) or "value" not in spec:
            raise InputError(f"{where} ({cls.name}): parameter {key!r} needs "
                             "{ value = ..., unit = ... }")
        unit = spec.get("unit", parameter.unit)
        if unit != parameter.unit:
            raise InputError(f"{where} ({cls.name}): parameter {key!r} is in {parameter.unit}, "
                             f"not {unit}")
        try:
            parameter.value = to_si(float(spec["value"]), unit)
            if "min" in spec:
                parameter.min = to_si(float(spec["min"]), unit)
            if "max" in spec:
                parameter.max = to_si(float(spec["max"]), unit)
        except (TypeError, ValueError):
            raise InputError(f"{where} ({cls.name}): parameter {key!r} needs numbers") from None
        parameter.vary = bool(spec.get("vary", parameter.vary))
        if not parameter.min <= parameter.value <= parameter.max:
            raise InputError(f"{where} ({cls.name}): {key} = {spec['value']} lies outside "
                             f"[{from_si(parameter.min, unit):g}, {from_si(parameter.max, unit):g}]")
    return effect


def model_to_dict(model: ValveModel, valve_reference: str = "shipped") -> dict:
    """The model file's content (display units)."""
    if model.maps_source is None:
        raise InputError(f"model {model.name!r} does not record where its maps come from")
    maps = {"kind": model.maps_source.kind, **model.maps_source.options}
    effects = []
    for effect in model.effects:
        parameters = {}
        for parameter in effect.params.values():
            entry = {"value": parameter.display_value, "unit": parameter.unit,
                     "min": float(from_si(parameter.min, parameter.unit)),
                     "max": float(from_si(parameter.max, parameter.unit)),
                     "vary": parameter.vary}
            if parameter.display_stderr is not None:
                entry["stderr"] = parameter.display_stderr
            parameters[parameter.name] = entry
        item = {"name": effect.name, "title": effect.title, "parameters": parameters}
        if getattr(type(effect), "custom", False):
            item["source"] = getattr(type(effect).function, "__module__", "custom")
        effects.append(item)
    return {"model": {"name": model.name, "valve": valve_reference, "maps": maps},
            "effects": effects}


def save_model(model: ValveModel, path: str | Path, note: str = "",
               valve_reference: str = "shipped") -> None:
    """Write a model file (see the module docstring); ``stderr`` entries are informative."""
    header = "Valve model written by cbv-surrogate" + (f"\n{note}" if note else "")
    text = dumps(model_to_dict(model, valve_reference), header)
    with atomic_file(path) as stream:
        stream.write(text)
