"""``export``: the fitted valve for system simulators: an FMU, lookup tables, ONNX maps."""

from __future__ import annotations

import dataclasses
import json
import time

import numpy as np

from ..errors import InputError
from ..export.fmu import model_identifier, write_fmu
from ..export.tables import TableGrid, resolution_error, tabulate, write_tables
from ..export.tabulable import refuse_untabulable
from ..export.valve_only import valve_physics
from ..outputs import Output, atomic_directory
from ..points import OperatingPoints
from ..units import from_si, to_si
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
                    "The tables span the bench log's operating range (--data, default the "
                    "shipped log) with a margin; their resolution error, the tables' replay of "
                    "the log against the solver's, must lie within --tolerance.")
    add_data_options(parser, out_help="output folder (always a folder)", out_required=True)
    required(parser).add_argument("--format", action="append", required=True, choices=FORMATS,
                                  help="what to write (repeatable): fmu, tables or onnx")
    parser.add_argument("--grid-scale", type=float, default=1.0, metavar="S",
                        help="refine (>1) or coarsen (<1) the tables' node spacing, 0.25 to 8 "
                             "(default 1)")
    parser.add_argument("--tolerance", type=float, default=DEFAULT_TOLERANCE_BAR, metavar="BAR",
                        help="largest RMS resolution error of the tables on the log [bar] "
                             f"(default {DEFAULT_TOLERANCE_BAR}); a coarser grid is refused")
    for _, option, unit, what in RANGES:
        parser.add_argument(option, nargs=2, type=float, metavar=("LOW", "HIGH"),
                            help=f"the tables' {what} range [{unit}] (default: the log's, with "
                                 "a margin)")
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
    if not (np.isfinite(args.tolerance) and args.tolerance > 0):
        raise InputError(f"--tolerance {args.tolerance}: expected a number of bar > 0")
    progress = progress_for(args)
    started = time.perf_counter()
    model, log, _ = load_inputs(args, progress)
    source = args.model
    physics = valve_physics(model, source)
    for name, why in physics.left_out.items():
        progress(f"left out {name}: {why}")
    summary = {"model": model.name, "source": source, "formats": formats,
               "left_out": physics.left_out, "files": {}}
    points = OperatingPoints.from_bench(log.frame)
    runs = log.frame["run"].to_numpy()
    onnx_maps = None
    if "onnx" in formats:
        from ..export.onnx_maps import learned_maps_of

        onnx_maps = learned_maps_of(model, source)  # refused before any long work
    tables = grid = None
    if "fmu" in formats or "tables" in formats:
        grid = _grid(args, points)
        refuse_untabulable(physics.model, grid, source)
        tables = tabulate(physics.model, grid, progress)
        tables = dataclasses.replace(tables, left_out=physics.left_out)
        progress(f"{tables.node_count():,} table nodes; measuring their resolution error on "
                 f"{log.source}")
        error = resolution_error(tables, physics.model, points, runs)
        shown = {key: round(float(from_si(value, "bar")), 4) if key != "points" else value
                 for key, value in error.items()}
        progress(f"resolution error: {shown['rms']:.3f} bar RMS, {shown['max']:.3f} bar at most "
                 f"({shown['rms_linear']:.3f} and {shown['max_linear']:.3f} bar with linear "
                 "interpolation)")
        if shown["rms"] > args.tolerance:
            raise InputError(
                f"--grid-scale {args.grid_scale:g}: the grid is too coarse for --tolerance "
                f"{args.tolerance:g} bar: the tables replay {log.source} within "
                f"{shown['rms']:.3f} bar RMS of the solver ({shown['max']:.3f} bar at most); "
                "raise --grid-scale (the error falls roughly with its square) or loosen "
                "--tolerance")
        summary["resolution_error_bar"] = {
            "rms": shown["rms"], "max": shown["max"], "rms_linear": shown["rms_linear"],
            "max_linear": shown["max_linear"], "samples": shown["points"],
            "against": f"the solver's replay (classic play) of {log.source}"}
        summary["table_nodes"] = tables.node_count()
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
        print(f"exported {model.name} ({', '.join(formats)}) to {args.out}")
        if physics.left_out:
            print(f"  left out: {', '.join(physics.left_out)}")
        if "resolution_error_bar" in summary:
            found = summary["resolution_error_bar"]
            print(f"  resolution error on the log: {found['rms']:.3f} bar RMS, "
                  f"{found['max']:.3f} bar at most")
        if "fmu" in summary and not summary["fmu"]["binary"]:
            print(f"  FMU without binary: {summary['fmu']['compiler']}")
    return 0


def _grid(args, points: OperatingPoints) -> TableGrid:
    """The tables' grid: the log's range with a margin, or the ranges given."""
    around = TableGrid.around(points, args.grid_scale)
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
