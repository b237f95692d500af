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


# What a model file may hold; anything else is refused rather than silently ignored.
_TOP_KEYS = {"model", "effects"}
_MODEL_KEYS = {"name", "description", "valve", "maps"}
_MAP_OPTIONS = {"orifice": {"discharge_coefficient"}, "grid": set(), "nn": set(), "gp": set()}
_EFFECT_KEYS = {"name", "title", "source", "parameters"}
_PARAMETER_KEYS = {"value", "unit", "min", "max", "vary", "stderr"}


def _unknown_keys(table: dict, allowed: set[str], where: str) -> None:
    unknown = sorted(set(table) - allowed)
    if unknown:
        raise InputError(f"{where}: unknown key(s) {', '.join(map(repr, unknown))}; allowed: "
                         f"{', '.join(sorted(allowed))}")


def _text(table: dict, key: str, where: str, default: str | None = None) -> str | None:
    value = table.get(key, default)
    if value is not None and not isinstance(value, str):
        raise InputError(f"{where}: {key} must be a string, got {value!r}")
    return value


def _number(value, what: str, where: str, *, allow_infinite: bool = False) -> float:
    """A TOML number (not a boolean, not text), finite unless ``allow_infinite``."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InputError(f"{where}: {what} must be a number, got {value!r}")
    value = float(value)
    if value != value or (not allow_infinite and value in (float("inf"), float("-inf"))):
        raise InputError(f"{where}: {what} must be a finite number, got {value!r}")
    return value


def model_from_dict(document: dict, source: str, folder: Path, valve_path: str | None = None,
                    cfd_samples=None) -> ValveModel:
    """Build a model from a parsed model file (``source`` names it in messages).

    The file is read strictly: unknown keys, wrong types, duplicated effects, non-boolean
    ``vary`` and empty bounds are errors that name the key, never ignored.
    """
    _unknown_keys(document, _TOP_KEYS, source)
    table = document.get("model")
    if not isinstance(table, dict) or "maps" not in table:
        raise InputError(f"{source}: needs a [model] table with maps = {{ kind = ... }}")
    _unknown_keys(table, _MODEL_KEYS, f"{source} [model]")
    kind, options = _maps_entry(table["maps"], f"{source} [model] maps", folder)
    _text(table, "description", f"{source} [model]")
    valve_spec = valve_path or _text(table, "valve", f"{source} [model]", "shipped")
    if valve_spec == "shipped":
        valve = load_valve()
    elif valve_path:
        valve = load_valve(valve_path)
    else:
        candidate = Path(valve_spec)
        try:
            valve = load_valve(candidate if candidate.is_absolute() else folder / candidate)
        except InputError as error:
            raise InputError(f"{source} [model] valve = {valve_spec!r}: {error}") from None
    entries = document.get("effects", [])
    if not isinstance(entries, list):
        raise InputError(f"{source}: effects must be an array of tables ([[effects]]), got "
                         f"{entries!r}")
    effects, seen = [], {}
    for index, entry in enumerate(entries, start=1):
        effect = _effect_from_entry(entry, source, index)
        if effect.name in seen:
            raise InputError(f"{source}, effect {index}: {effect.name!r} is already effect "
                             f"{seen[effect.name]}; list each effect once")
        seen[effect.name] = index
        effects.append(effect)
    name = _text(table, "name", f"{source} [model]", Path(source).stem)
    return build_model(MapsSource(kind, options), valve, effects, name, cfd_samples)


def _maps_entry(maps, where: str, folder: Path) -> tuple[str, dict]:
    """The map kind (or surrogate folder) and its options, checked against what the kind takes."""
    if isinstance(maps, str):
        maps = {"kind": maps}
    if not isinstance(maps, dict):
        raise InputError(f"{where}: expected a map kind (orifice, grid, nn, gp or the path of a "
                         f"surrogate folder) or a table {{ kind = ... }}, got {maps!r}")
    kind = maps.get("kind")
    if not isinstance(kind, str):
        raise InputError(f"{where}: needs a kind (orifice, grid, nn, gp or the path of a "
                         "surrogate folder)")
    options = {k: v for k, v in maps.items() if k != "kind"}
    allowed = _MAP_OPTIONS.get(kind, set())
    _unknown_keys(options, allowed, f"{where} (kind {kind!r})")
    if "discharge_coefficient" in options:
        value = _number(options["discharge_coefficient"], "discharge_coefficient", where)
        if not 0.0 < value <= 1.0:
            raise InputError(f"{where}: discharge_coefficient must lie in (0, 1], got {value:g} "
                             "(an orifice passes at most its ideal flow)")
        options["discharge_coefficient"] = value
    if kind not in _MAP_OPTIONS:
        kind = str((folder / kind).resolve()) if not Path(kind).is_absolute() else kind
    return kind, options


def _effect_from_entry(entry: dict, source: str, index: int) -> Effect:
    where = f"{source}, effect {index}"
    if not isinstance(entry, dict) or not isinstance(entry.get("name"), str):
        raise InputError(f"{where}: needs a name = \"...\" (a table under [[effects]])")
    _unknown_keys(entry, _EFFECT_KEYS, where)
    try:
        cls = effect_class(entry["name"])
    except InputError as error:
        hint = f" (its source was {entry['source']})" if "source" in entry else ""
        raise InputError(f"{where}: {error}{hint}") from None
    where = f"{where} ({cls.name})"
    specs = entry.get("parameters", {})
    if not isinstance(specs, dict):
        raise InputError(f"{where}: parameters must be a table of name = {{ value = ..., "
                         f"unit = ... }}, got {specs!r}")
    effect = cls.for_parameters(list(specs))
    for key, spec in specs.items():
        if key not in effect.params:
            raise InputError(f"{where}: unknown parameter {key!r}; it has "
                             f"{', '.join(effect.params) or 'none'}")
        _set_parameter(effect.params[key], spec, f"{where}, parameter {key!r}")
    return effect


def _set_parameter(parameter, spec, where: str) -> None:
    """Set value, bounds and vary from a parameter's table (display units)."""
    if not isinstance(spec, dict) or "value" not in spec:
        raise InputError(f"{where}: needs {{ value = ..., unit = ... }}, got {spec!r}")
    _unknown_keys(spec, _PARAMETER_KEYS, where)
    unit = spec.get("unit", parameter.unit)
    if unit != parameter.unit:
        raise InputError(f"{where}: is in {parameter.unit}, not {unit}")
    value = _number(spec["value"], "value", where)
    low = _number(spec.get("min", from_si(parameter.min, unit)), "min", where,
                  allow_infinite=True)
    high = _number(spec.get("max", from_si(parameter.max, unit)), "max", where,
                   allow_infinite=True)
    if "stderr" in spec and _number(spec["stderr"], "stderr", where) < 0:
        raise InputError(f"{where}: stderr must be >= 0, got {spec['stderr']!r}")
    vary = spec.get("vary", parameter.vary)
    if not isinstance(vary, bool):
        raise InputError(f"{where}: vary must be true or false, got {vary!r}")
    if not low < high:
        raise InputError(f"{where}: min = {low:g} must be below max = {high:g} (to hold the "
                         "parameter fixed, set vary = false and keep the bounds apart)")
    # the effect's own bounds are physics (friction >= 0, a scale > 0): a file may narrow them
    own_low, own_high = from_si(parameter.min, unit), from_si(parameter.max, unit)
    slack = 1e-9 * max(abs(own_low) if own_low > -float("inf") else 0.0,
                       abs(own_high) if own_high < float("inf") else 0.0, 1.0)
    if low < own_low - slack or high > own_high + slack:
        raise InputError(f"{where}: bounds [{low:g}, {high:g}] {unit} reach beyond the effect's "
                         f"own [{own_low:g}, {own_high:g}]; a model file may narrow them only")
    if not low <= value <= high:
        raise InputError(f"{where}: value {value:g} lies outside [min, max] = [{low:g}, "
                         f"{high:g}] {unit}")
    parameter.value, parameter.vary = to_si(value, unit), vary
    parameter.min = max(to_si(low, unit), parameter.min)  # no wider than its own by rounding
    parameter.max = min(to_si(high, unit), parameter.max)
    parameter.value = min(max(parameter.value, parameter.min), parameter.max)


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
