"""``effects``: list the effects a model may add, or those an effects file defines."""

from __future__ import annotations

import math

from ..effects import CALIBRATION, LIBRARY, SHAPES
from ..effects.base import Effect, Parameter
from ..effects.per_run import PerRunEffect
from ..effects.shapes import ShapeFreeEffect
from ..core.units import label
from .common import add_command, effect_library, print_json, progress_for

#: the groups of the built-in effects, in the order they are listed, with what each is for
GROUPS = (
    ("library", LIBRARY, "the candidates a diagnosis tries and `fit --add NAME` adds"),
    ("shape-free", SHAPES, "terms whose shape the data choose; a diagnosis tries them beside "
                           "the library and `diagnose --out` writes what it finds as an "
                           "effects file"),
    ("calibration", CALIBRATION, "the maps calibrated to the bench per opening, the "
                                 "workflow's last step"),
)


def register(subparsers) -> None:
    parser = add_command(
        subparsers, "effects", help="list the effects: name, title, parameters and units",
        description="List the built-in effects (the library a diagnosis tries, the shape-free "
                    "terms and the maps' calibration) with their category, the model stage "
                    "they act in (kind), their parameters with units and bounds, and what each "
                    "one is. With --effects-file, list the effects that file defines instead, "
                    "after checking them as fit and diagnose would.",
        json_help="print the effects as JSON on stdout")
    parser.add_argument("--effects-file", action="append", default=[], metavar="FILE",
                        help="Python file defining custom effects (repeatable): list its "
                             "effects")
    parser.set_defaults(func=run)


def run(args) -> int:
    if args.effects_file:
        library = effect_library(args, progress_for(args))  # loaded and checked as fit does
        groups = [("custom", [cls for cls in library.values() if cls.custom],
                   f"defined in {', '.join(args.effects_file)}")]
    else:
        groups = [(name, list(effects.values()), purpose) for name, effects, purpose in GROUPS]
    if args.json:
        print_json({"groups": [{"group": name, "purpose": purpose,
                                "effects": [effect_record(cls) for cls in classes]}
                               for name, classes, purpose in groups]})
        return 0
    for name, classes, purpose in groups:
        print(f"{name} ({len(classes)}): {purpose}")
        for cls in classes:
            print(format_effect(effect_record(cls)))
        print()
    return 0


def effect_record(cls: type[Effect]) -> dict:
    """An effect as plain data: name, title, category, kind, description, where it holds, the
    file of a custom one, and its parameters (value when off, unit, bounds, in display units)."""
    record = {"name": cls.name, "title": cls.title, "category": cls.category, "kind": cls.kind,
              "description": cls.describe(), "validity": " ".join(cls.validity.split())}
    if cls.custom:
        record["source"] = cls.source
    if issubclass(cls, PerRunEffect):
        record["parameters"] = [_parameter(cls.template, per_run=True)]
    elif issubclass(cls, ShapeFreeEffect):
        # its knots and coefficients are made where the data are: their number and place too
        record["parameters"] = []
        unit = "dimensionless" if cls.value_unit == "1" else f"in {label(cls.value_unit)}"
        record["parameters_note"] = (f"knots along {cls.variable.label} and coefficients "
                                     f"({unit}), placed when it is fitted")
    else:
        record["parameters"] = [_parameter(spec) for spec in cls.parameter_specs]
    return record


def _parameter(spec: Parameter, per_run: bool = False) -> dict:
    low, high = spec.display_bounds
    return {"name": f"{spec.name}_<run>" if per_run else spec.name, "unit": spec.unit,
            "off": _finite(spec.display_value), "min": _finite(low), "max": _finite(high),
            "description": spec.description, "per_run": per_run}


def _finite(value: float) -> float | None:
    """JSON has no infinity: an open bound is null."""
    return round(value, 12) if math.isfinite(value) else None


def format_effect(record: dict) -> str:
    """An effect's record as a few lines for a terminal."""
    lines = [f"  {record['name']}: {record['title']}",
             f"      {record['category']}, acts on the {record['kind']}"
             + (f"; from {record['source']}" if record.get("source") else "")]
    for p in record["parameters"]:
        bounds = " to ".join("∞" if b is None else f"{b:g}" for b in (p["min"], p["max"]))
        bounds = bounds.replace("∞ to", "-∞ to", 1) if p["min"] is None else bounds
        lines.append(f"      {p['name']} [{label(p['unit'])}]: {bounds}, off at {p['off']:g}"
                     + (" (one per run)" if p["per_run"] else "")
                     + (f"; {p['description']}" if p["description"] else ""))
    if record.get("parameters_note"):
        lines.append(f"      parameters: {record['parameters_note']}")
    lines.append(f"      {record['description']}")
    return "\n".join(lines)
