"""``export``: the fitted valve for system simulators: an FMU, lookup tables, ONNX maps."""

from __future__ import annotations

import dataclasses
import json
import time

import numpy as np

from ..core.errors import InputError
from ..export.envelope import probe_runs, valve_envelope
from ..export.fmu import model_identifier, write_fmu
from ..export.refinement import Refinement, refined_grid
from ..export.tables import TableGrid, ValveTables, resolution_error, write_tables
from ..export.tabulable import refuse_untabulable
from ..export.valve_only import valve_physics
from ..core.outputs import Output, atomic_directory
from ..points import OperatingPoints
from ..core.units import from_si, to_si
from .common import (add_command, add_data_options, guard_outputs, load_inputs, print_json,
                     progress_for, required)

FORMATS = ("fmu", "tables", "onnx")
#: the accuracy asked of the tables by default [bar]: the issue's for the FMU
DEFAULT_TOLERANCE_BAR = 0.1
RANGES = (("q", "--q-lpm", "L/min", "flow"), ("p_B", "--p-B-bar", "bar", "back pressure"),
          ("p_P", "--p-P-bar", "bar", "pilot pressure"),
          ("temperature", "--temperature-C", "degC", "temperature"))


def register(subparsers) -> None:
    parser = add_command(
        subparsers, "export",
        help="export a fitted valve: an FMU (FMI 2.0 co-simulation), lookup tables, ONNX maps",
        description="Take the model's valve physics (its sensor and per-run terms are left out, "
                    "and the manifest says which) out of the workbench. fmu: a standalone FMI "
                    "2.0 co-simulation FMU with inputs q, p_B, p_P, T and outputs p_L, dp, u "
                    "(SI), the tables interpolated in C with the friction play as internal "
                    "state, compiled with the system's C compiler (source-only, and said so, "
                    "without one). tables: the same tables as CSV and MATLAB .mat with a JSON "
                    "manifest. onnx: the learned flow and force maps (nn, gp) as ONNX graphs. "
                    "The tables span the valve's envelope (flow from nearly zero to beyond the "
                    "largest the CFD or the bench saw, back and pilot pressures from zero, the "
                    "temperatures of the CFD and the log widened by 10 K); nodes are inserted "
                    "where the valve changes quickly until the tables meet --tolerance; their "
                    "resolution error, the tables' replay of the log (--data, default the "
                    "shipped log) against the solver's, is measured and reported.")
    add_data_options(parser, out_help="output folder (always a folder)", out_required=True)
    required(parser).add_argument("--format", action="append", required=True, choices=FORMATS,
                                  help="what to write (repeatable): fmu, tables or onnx")
    parser.add_argument("--grid-scale", type=float, default=1.0, metavar="S",
                        help="refine (>1) or coarsen (<1) the tables' node spacing, 0.25 to 8 "
                             "(default 1)")
    parser.add_argument("--tolerance", type=float, default=None, metavar="BAR",
                        help="the tables' largest RMS error against the solver [bar], between "
                             "nodes over the ranges and on the log's replay (default "
                             f"{DEFAULT_TOLERANCE_BAR}: reported when not met; given: refused "
                             "when not met)")
    parser.add_argument("--ranges", choices=("valve", "log"), default="valve",
                        help="the tables' ranges: the valve's envelope (default) or the log's "
                             "with a margin")
    for _, option, unit, what in RANGES:
        parser.add_argument(option, nargs=2, type=float, metavar=("LOW", "HIGH"),
                            help=f"the tables' {what} range [{unit}] (default: as --ranges "
                                 "says)")
    parser.add_argument("--no-compile", action="store_true",
                        help="write a source-only FMU (no binary)")
    parser.set_defaults(func=run)


#: what each format writes into --out under a fixed name (the FMU's name is the model's)
FORMAT_FILES = {"onnx": ("flow.onnx", "force.onnx", "onnx.json"),
                "tables": ("valve_tables.mat", "manifest.json"), "fmu": ()}


def run(args) -> int:
    formats = list(dict.fromkeys(args.format))
    entries = ("export.json", *(name for form in formats for name in FORMAT_FILES.get(form, ())))
    guard_outputs(args, Output("--out", args.out, "folder", entries))
    if not (np.isfinite(args.grid_scale) and 0.25 <= args.grid_scale <= 8):
        raise InputError(f"--grid-scale {args.grid_scale:g}: expected a number in [0.25, 8]")
    strict = args.tolerance is not None
    tolerance = args.tolerance if strict else DEFAULT_TOLERANCE_BAR
    if not (np.isfinite(tolerance) and tolerance > 0):
        raise InputError(f"--tolerance {tolerance}: expected a number of bar > 0")
    progress = progress_for(args)
    started = time.perf_counter()
    model, log, _ = load_inputs(args, progress)
    source = args.model
    physics = valve_physics(model, source)
    for name, why in physics.left_out.items():
        progress(f"left out {name}: {why}")
    summary = {"model": model.name, "source": source, "formats": formats,
               "left_out": physics.left_out, "files": {}}
    onnx_maps = None
    if "onnx" in formats:
        from ..export.onnx_maps import learned_maps_of

        onnx_maps = learned_maps_of(model, source)  # refused before any long work
    tables = grid = None
    if "fmu" in formats or "tables" in formats:
        tables, grid, found = _tabulated(args, physics, log, tolerance, strict, progress)
        summary |= found
    extra = {"source": source,
             "resolution_error_bar": summary.get("resolution_error_bar"),
             "generated_by": "cbv-surrogate export"}
    with atomic_directory(args.out) as staging:
        if "tables" in formats:
            for path in write_tables(tables, grid, staging, extra):
                summary["files"][path.name] = "tables"
        if "fmu" in formats:
            name = f"{model_identifier(tables.model)}.fmu"
            result = write_fmu(tables, grid, staging / name, extra,
                               compiler=None if args.no_compile else "auto", progress=progress)
            summary["files"][name] = "fmu"
            summary["fmu"] = {"binary": result.compiled, "compiler": result.compiler}
            if not result.compiled:
                progress(f"the FMU is source-only: {result.compiler}; an importer compiles "
                         "sources/fmu_valve.c itself (FMPy: fmpy.util.compile_platform_binary)")
        if onnx_maps is not None:
            from ..export.onnx_maps import write_onnx

            for path in write_onnx(onnx_maps, staging, progress):
                summary["files"][path.name] = "onnx"
        summary["seconds"] = round(time.perf_counter() - started, 2)
        (staging / "export.json").write_text(json.dumps(summary, indent=2, allow_nan=False)
                                             + "\n")
    progress(f"wrote {', '.join(summary['files'])} to {args.out}")
    if args.json:
        print_json(summary)
    else:
        _print_summary(summary, model.name, formats, args.out)
    return 0


def _tabulated(args, physics, log, tolerance: float, strict: bool, progress
               ) -> tuple[ValveTables, TableGrid, dict]:
    """The valve's tables on a grid refined to ``tolerance`` [bar], and what the summary says of
    them: the refinement, the resolution error on the log and across the ranges. A tolerance
    given (``strict``) and not met is refused."""
    points = OperatingPoints.from_bench(log.frame)
    grid = _grid(args, points, physics.model)
    refuse_untabulable(physics.model, grid, args.model)
    refined = refined_grid(physics.model, grid, float(to_si(tolerance, "bar")), progress)
    grid = refined.grid
    tables = dataclasses.replace(refined.tables, left_out=physics.left_out)
    progress(f"{tables.node_count():,} table nodes; measuring their resolution error on "
             f"{log.source}")
    error = resolution_error(tables, physics.model, points, log.frame["run"].to_numpy())
    shown = {key: round(float(from_si(value, "bar")), 4) if key != "points" else value
             for key, value in error.items()}
    progress(f"resolution error: {shown['rms']:.3f} bar RMS, {shown['max']:.3f} bar at most "
             f"({shown['rms_linear']:.3f} and {shown['max_linear']:.3f} bar with linear "
             "interpolation)")
    across = resolution_error(tables, physics.model, *probe_runs(grid))
    found = {"refinement": _refinement_summary(refined), "envelope_error_bar": {
        "rms": round(float(from_si(across["rms"], "bar")), 4),
        "max": round(float(from_si(across["max"], "bar")), 4), "samples": across["points"],
        "against": "the solver's replay of smooth flow ramps at four corners of the ranges "
                   "(surrogate.export.envelope.probe_runs)"}}
    progress(f"across the ranges (flow ramps at four of their corners): "
             f"{found['envelope_error_bar']['rms']:.3f} bar RMS, "
             f"{found['envelope_error_bar']['max']:.3f} bar at most")
    missed = _missed(refined, shown["rms"], found["envelope_error_bar"]["rms"], tolerance,
                     log.source)
    if missed and strict:
        raise InputError(f"--tolerance {tolerance:g} bar is not met by a grid starting at "
                         f"--grid-scale {args.grid_scale:g}, refined as far as allowed: "
                         f"{missed}; start finer (--grid-scale "
                         f"{min(8.0, 1.5 * args.grid_scale):g}), narrow the ranges "
                         "(--q-lpm LOW HIGH, ...) or loosen --tolerance")
    if missed:
        progress(f"warning: the tolerance of {tolerance:g} bar is not met everywhere: {missed}")
        found["tolerance_not_met"] = missed
    found["tolerance_bar"] = tolerance
    found["resolution_error_bar"] = {
        "rms": shown["rms"], "max": shown["max"], "rms_linear": shown["rms_linear"],
        "max_linear": shown["max_linear"], "samples": shown["points"],
        "against": f"the solver's replay (classic play) of {log.source}"}
    found["table_nodes"] = tables.node_count()
    return tables, grid, found


def _print_summary(summary: dict, name: str, formats: list[str], out) -> None:
    """What the export wrote and how well its tables follow the solver, on stdout."""
    print(f"exported {name} ({', '.join(formats)}) to {out}")
    if summary["left_out"]:
        print(f"  left out: {', '.join(summary['left_out'])}")
    if "resolution_error_bar" in summary:
        found = summary["resolution_error_bar"]
        print(f"  resolution error on the log: {found['rms']:.3f} bar RMS, "
              f"{found['max']:.3f} bar at most")
        across = summary["envelope_error_bar"]
        print(f"  across the ranges (flow ramps at four corners): {across['rms']:.3f} bar "
              f"RMS, {across['max']:.3f} bar at most")
        worst = summary["refinement"]["worst_cell_rms_bar"]
        print(f"  between nodes over the ranges: at most {max(worst.values()):.3f} bar RMS "
              f"in a cell's middle (most along {max(worst, key=worst.get)})")
    if "tolerance_not_met" in summary:
        print(f"  tolerance {summary['tolerance_bar']:g} bar not met: "
              f"{summary['tolerance_not_met']}")
    if "fmu" in summary and not summary["fmu"]["binary"]:
        print(f"  FMU without binary: {summary['fmu']['compiler']}")


def _refinement_summary(refined: Refinement) -> dict:
    return {"rounds": refined.rounds, "met": refined.met,
            "inserted_nodes": refined.grid.inserted_count,
            "worst_cell_rms_bar": {axis: round(float(from_si(miss, "bar")), 4)
                                   for axis, miss in refined.worst.items()}}


def _missed(refined: Refinement, log_rms: float, across_rms: float, tolerance: float,
            source: str) -> str:
    """Where the tables miss ``tolerance`` [bar], in words; empty when they meet it."""
    misses = []
    if log_rms > tolerance:
        misses.append(f"the tables replay {source} within {log_rms:.3f} bar RMS of the solver")
    if across_rms > tolerance:
        misses.append(f"flow ramps across the ranges within {across_rms:.3f} bar RMS")
    if not refined.met:
        worst = {axis: float(from_si(miss, "bar")) for axis, miss in refined.worst.items()}
        axis = max(worst, key=worst.get)
        why = {"budget": "the node budget is spent",
               "rounds": f"after {refined.rounds} rounds of refinement"}[refined.stopped_by]
        misses.append(f"between nodes they miss it by up to {worst[axis]:.3f} bar RMS in a "
                      f"cell's middle along {axis} ({why})")
    return "; ".join(misses)


def _grid(args, points: OperatingPoints, model) -> TableGrid:
    """The tables' grid: the valve's envelope or the log's range with a margin, or the ranges
    given."""
    around = (valve_envelope(model, points, args.grid_scale) if args.ranges == "valve"
              else TableGrid.around(points, args.grid_scale))
    ranges = {}
    for name, option, unit, _ in RANGES:
        given = getattr(args, option[2:].replace("-", "_"))
        if given is None:
            ranges[name] = getattr(around, name)
            continue
        low, high = given
        if not (np.isfinite(low) and np.isfinite(high) and low < high):
            raise InputError(f"{option} {low:g} {high:g}: expected LOW < HIGH [{unit}]")
        ranges[name] = (float(to_si(low, unit)), float(to_si(high, unit)))
    try:
        return TableGrid(**ranges, scale=args.grid_scale)
    except InputError as error:
        raise InputError(f"--grid-scale / ranges: {error}") from None
