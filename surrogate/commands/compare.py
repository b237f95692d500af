"""``compare``: replay a model over a bench log and show how much, and where, they disagree."""

from __future__ import annotations

import json

from ..core.outputs import Output, atomic_directory
from ..workbench.compare import compare
from .common import (add_command, add_data_options, guard_outputs, load_inputs, print_json,
                     progress_for)


def register(subparsers) -> None:
    parser = add_command(
        subparsers, "compare",
        help="compare a model with bench data: residuals per run, region and figure",
        description="Replay every run of the bench log with the model (friction as a play) and "
                    "summarise the residual: RMS, bias and hysteresis-width error per run, a "
                    "p_Pe x temperature table, the noise floor of the data, and operating regions "
                    "ranked by error with flags where the maps extrapolate. The model is used as "
                    "given (no fit; see `fit`).")
    add_data_options(parser, out_help="write compare.json, runs.csv, regions.csv, samples.csv "
                                      "(every sample: measured and model Δp, its standard "
                                      "deviation from the maps, why it lies outside the CFD "
                                      "samples), figures and report.html into this folder")
    parser.set_defaults(func=run)


def run(args) -> int:
    guard_outputs(args, Output("--out", args.out, "folder"))
    progress = progress_for(args)
    model, log, _ = load_inputs(args, progress)
    progress(f"replaying {model.name}")
    comparison = compare(model, log, progress=progress)
    if args.out:
        progress(f"writing {args.out}")
        write_comparison(comparison, args.out)
        progress(f"wrote {args.out}/report.html")
    if args.json:
        print_json(comparison.to_json())
    else:
        print(comparison.format_text())
    return 0


def write_comparison(comparison, out) -> None:
    """All files of a comparison, all or none."""
    # the report draws with matplotlib, half a second of a start: only when it is written
    from ..reporting.report import comparison_section, figure_pngs, write_html

    with atomic_directory(out) as staging:
        (staging / "compare.json").write_text(json.dumps(comparison.to_json(), indent=2) + "\n")
        comparison.runs.to_csv(staging / "runs.csv", index=False)
        comparison.regions.to_csv(staging / "regions.csv", index=False)
        comparison.worst.to_csv(staging / "worst_samples.csv", index=False)
        comparison.write_samples(staging / "samples.csv")
        pngs = figure_pngs(comparison)  # drawn once, for the files and the report
        for name, png in pngs.items():
            (staging / f"{name}.png").write_bytes(png)
        write_html(staging / "report.html", f"Comparison: {comparison.model}",
                   [comparison_section(comparison, "Model against measurements", pngs)])
