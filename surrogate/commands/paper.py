"""``paper``: reproduce the paper's model comparison (Tables 5 and 6, Figures 16–21)."""

from __future__ import annotations

import json

from ..data import load_bench_log
from ..core.outputs import Output
from ..paper.comparison import reproduce
from ..description.spec import ValveSource
from .common import (add_command, bench_log_path, guard_outputs, maps_help_text,
                     maps_option, progress_for)

DEFAULT_OUT = "results/paper"


def register(subparsers) -> None:
    parser = add_command(
        subparsers, "paper", help="reproduce the paper's comparison of BMBE, BMBEBF and CFDA",
        description="Fit BMBEBF and CFDA to the 40 °C, p_Pe = 65 bar median line, compare all "
                    "models with the median lines (Table 5), fit friction per temperature "
                    "(Table 6) and draw Figures 16–21.")
    parser.add_argument("--maps", default="grid", type=maps_option,
                        help=f"{maps_help_text()} (default grid)")
    parser.add_argument("--out", help=f"output folder (default {DEFAULT_OUT}, none with --json)")
    parser.add_argument("--data", help="bench log (default: the shipped one, said so in the first "
                                       "progress line)")
    parser.add_argument("--cfd", help="CFD samples for grid maps (default: the shipped ones)")
    parser.add_argument("--valve", help="valve file (default: the shipped valve)")
    parser.set_defaults(func=run)


def run(args) -> int:
    out = args.out or (None if args.json else DEFAULT_OUT)
    guard_outputs(args, Output("--out", out, "folder"))
    progress = progress_for(args)
    valve = ValveSource.read(args.valve)
    log = load_bench_log(bench_log_path(args, progress), progress)
    comparison = reproduce(valve, args.maps.spec(args.cfd), log, progress)
    if out:
        # the figures draw with matplotlib, half a second of a start: only when written
        from ..paper.report import write_report

        progress(f"writing tables and figures to {out}")
        written = write_report(comparison, out, str(args.maps))
        progress(f"wrote {len(written)} files")
    if args.json:
        print(json.dumps({"maps": str(args.maps), **comparison.to_json()}, indent=2))
    return 0
