"""``steady``: the steady characteristic of a model, Δp(q) on its up and down branches."""

from __future__ import annotations

import json

import numpy as np

from ..core.errors import InputError
from ..export.characteristic import steady_characteristic
from ..export.valve_only import valve_physics
from ..limits import FLOW, PRESSURE, PRESSURE_DIFFERENCE, TEMPERATURE
from ..core.outputs import Output, atomic_directory
from ..core.units import from_si, to_si
from .common import (add_command, effect_library, guard_outputs, maps_help_text, maps_option,
                     model_option, print_json, progress_for, required)


def register(subparsers) -> None:
    parser = add_command(
        subparsers, "steady",
        help="the steady characteristic of a model: up and down branches of dp(q)",
        description="Solve the model's force balance at rising flow (piston opening, friction "
                    "holding it back: the up branch) and falling flow (the down branch) at a "
                    "pilot set point (or pilot pressure), back pressure and temperature held, "
                    "the curve a catalogue shows. The model's sensor and per-run terms are left "
                    "out (they belong to the bench). Writes steady.csv, steady.json and "
                    "steady.png into --out.")
    options = required(parser)
    options.add_argument("--model", required=True, type=model_option,
                         help="a preset or a model file (TOML)")
    pilot = options.add_mutually_exclusive_group(required=True)
    pilot.add_argument("--p-Pe-bar", type=float,
                       help="pilot set point p_Pe = p_P − p_B [bar], as bench logs give it")
    pilot.add_argument("--p-P-bar", type=float, help="pilot pressure p_P (gauge) [bar]")
    options.add_argument("--out", required=True, help="output folder")
    parser.add_argument("--p-B-bar", type=float, default=5.0,
                        help="back pressure [bar] (default 5)")
    parser.add_argument("--temperature-C", type=float, default=40.0,
                        help="oil temperature [°C] (default 40)")
    parser.add_argument("--q-lpm", nargs=2, type=float, default=(0.5, 12.0),
                        metavar=("LOW", "HIGH"), help="flow range [L/min] (default 0.5 12)")
    parser.add_argument("--points", type=int, default=60, help="flows per branch (default 60)")
    parser.add_argument("--maps", metavar="KIND", type=maps_option,
                        help=f"replace the model's maps: {maps_help_text()}")
    parser.add_argument("--effects-file", action="append", default=[], metavar="FILE",
                        help="Python file defining custom effects (repeatable)")
    parser.add_argument("--valve", help="valve file (default: the model's, or the shipped one)")
    parser.set_defaults(func=run)


def run(args) -> int:
    guard_outputs(args, Output("--out", args.out, "folder"))
    low, high = args.q_lpm
    if not (np.isfinite(low) and np.isfinite(high) and 0 < low < high):
        raise InputError(f"--q-lpm {low:g} {high:g}: expected 0 < LOW < HIGH [L/min]")
    if not 2 <= args.points <= 10_000:
        raise InputError(f"--points {args.points}: expected 2 to 10000 flows per branch")
    if args.p_P_bar is None:  # the set point: the pilot pressure is p_Pe above the back port
        PRESSURE_DIFFERENCE.check_option("--p-Pe-bar", args.p_Pe_bar)
        args.p_P_bar = args.p_Pe_bar + args.p_B_bar
    for option, value, plausible in (("--p-P-bar", args.p_P_bar, PRESSURE),
                                     ("--p-B-bar", args.p_B_bar, PRESSURE),
                                     ("--temperature-C", args.temperature_C, TEMPERATURE),
                                     ("--q-lpm", high, FLOW)):
        plausible.check_option(option, value)
    progress = progress_for(args)
    from ..description.modelfile import PRESETS, load_spec

    spec = load_spec(args.model, args.valve)
    if args.maps:
        spec = spec.on_maps(args.maps)
    where = args.model if args.model not in PRESETS else f"preset {args.model!r}"
    model = spec.build(effect_library(args, progress), where)
    physics = valve_physics(model, args.model)
    q = np.geomspace(*to_si(np.array([low, high]), "L/min"), args.points)
    progress(f"solving {physics.model.name}'s steady branches at {args.points} flows")
    curve = steady_characteristic(physics.model, q, to_si(args.p_P_bar, "bar"),
                                  to_si(args.p_B_bar, "bar"), to_si(args.temperature_C, "degC"))
    check_result(curve, where)
    document = curve.to_json() | {"left_out": physics.left_out, "failures": curve.failures}
    # matplotlib, half a second of a start, for this command's figure only
    from ..reporting.report import figure_png

    with atomic_directory(args.out) as staging:
        curve.to_frame().to_csv(staging / "steady.csv", index=False, float_format="%.6g")
        (staging / "steady.json").write_text(json.dumps(document, indent=2, allow_nan=False)
                                             + "\n")
        (staging / "steady.png").write_bytes(figure_png(curve.figure()))
    if curve.failures:
        progress(f"no equilibrium at some flows: {curve.failures}")
    progress(f"wrote steady.csv, steady.json and steady.png to {args.out}")
    if args.json:
        print_json(document)
    else:
        frame = curve.to_frame()
        for branch in ("up", "down"):
            rows = frame[frame.branch == branch]
            print(f"{branch:>4}: dp {rows.dp_bar.min():.1f} to {rows.dp_bar.max():.1f} bar over "
                  f"{from_si(q[0], 'L/min'):.2f} to {from_si(q[-1], 'L/min'):.2f} L/min")
    return 0


def check_result(curve, where: str) -> None:
    """Refuse a characteristic whose pressure drop no valve has (beyond its plausible range):
    the model's maps or parameters are damaged, and the numbers must not be written as a
    result."""
    dp = curve.to_frame().dp_bar.to_numpy()
    bad = [value for value in dp if np.isfinite(value) and not PRESSURE_DIFFERENCE.contains(value)]
    if bad:
        raise InputError(f"{where}: the model gives a pressure drop of {bad[0]:.4g} bar, "
                         f"outside {PRESSURE_DIFFERENCE.describe()}; its maps or parameters are "
                         "damaged (check its surrogate folder or refit it)")
