"""``suggest-cfd``: the CFD runs that would most reduce the maps' share of the Δp uncertainty."""

from __future__ import annotations

import json

from ..data import load_bench_log
from ..core.errors import InputError
from ..maps.crossval import most_accurate_kind
from ..maps.registry import MapChoice
from ..description.modelfile import PRESETS, load_spec
from ..core.outputs import Output, atomic_directory
from ..planning.cfd_runs import suggest_cfd, suggestion_figure
from .common import (add_command, add_data_options, bench_log_path, effect_library, guard_outputs,
                     model_option, positive_int, print_json, progress_for)

DEFAULT_RUNS = 8


def register(subparsers) -> None:
    parser = add_command(
        subparsers, "suggest-cfd",
        help="list the CFD runs that would most reduce the maps' Δp uncertainty over a log",
        description="Replay the model over the bench log, find how much of the computed Δp's "
                    "uncertainty comes from each map and where, and rank candidate CFD runs "
                    "(opening, flow, temperature, back pressure, where the bench operates) by the "
                    "variance they would remove, weighted by the log's samples (integrated "
                    "variance reduction, chosen greedily so that the runs complement each "
                    "other). Writes suggestions.csv for the CFD engineer and a figure of the "
                    "log's operating points over the sampled openings.")
    add_data_options(parser, model=False, out_help="write suggestions.csv, suggestions.png and "
                                                   "suggestions.json into this folder",
                     maps_help="the maps whose uncertainty to reduce (default: the kind whose "
                               "flow force is the most accurate by cross-validation)")
    parser.add_argument("--model", default="cfda", type=model_option,
                        help=f"the model replayed over the log: a preset ({', '.join(PRESETS)}) "
                             "or a model file (default cfda)")
    parser.add_argument("--cfd", help="CFD samples for grid maps (default: the shipped ones)")
    parser.add_argument("--runs", type=positive_int, default=DEFAULT_RUNS,
                        help=f"how many runs to suggest (default {DEFAULT_RUNS})")
    parser.set_defaults(func=run)


def run(args) -> int:
    guard_outputs(args, Output("--out", args.out, "folder"))
    progress = progress_for(args)
    data = bench_log_path(args, progress)
    library = effect_library(args, progress)
    log = load_bench_log(data, progress)
    spec = load_spec(args.model, args.valve)
    kind = args.maps
    if kind is None:
        kind = MapChoice.read(most_accurate_kind(spec.valve.parameters)[0])
    spec = spec.on_maps(kind, args.cfd)
    model = spec.build(library, args.model)
    if model.flow_map.calibration is None and model.force_map.calibration is None:
        raise InputError(f"--maps {kind}: these maps have no uncertainty to reduce; choose maps "
                         "built from CFD samples (grid, nn, gp or a trained surrogate's folder)")
    progress(f"replaying {model.name} and ranking candidate CFD runs")
    suggestion = suggest_cfd(model, log, args.runs)
    if args.out:
        # the figure draws with matplotlib, half a second of a start: only when it is written
        from ..reporting.report import figure_png

        with atomic_directory(args.out) as staging:
            suggestion.runs.to_csv(staging / "suggestions.csv", index=False, float_format="%.4g")
            (staging / "suggestions.json").write_text(
                json.dumps({"model": model.name, **suggestion.to_json()}, indent=2) + "\n")
            (staging / "suggestions.png").write_bytes(
                figure_png(suggestion_figure(suggestion, model)))
        progress(f"wrote {args.out}/suggestions.csv and suggestions.png")
    if args.json:
        print_json({"model": model.name, **suggestion.to_json()})
    else:
        print(suggestion.format_text())
    return 0
