"""``paper``: reproduce the paper's model comparison (Tables 5 and 6, Figures 16–21)."""

from __future__ import annotations

import json
import sys
import time

from ..data import load_bench_log
from ..maps.registry import MAP_KINDS, build_maps
from ..paper.comparison import reproduce
from ..paper.report import write_report
from ..paths import SHIPPED_BENCH_LOG, shipped
from ..valve import load_valve

DEFAULT_OUT = "results/paper"


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "paper", help="reproduce the paper's comparison of BMBE, BMBEBF and CFDA",
        description="Fit BMBEBF and CFDA to the 40 °C, p_Pe = 65 bar median line, compare all "
                    "models with the median lines (Table 5), fit friction per temperature "
                    "(Table 6) and draw Figures 16–21.")
    parser.add_argument("--maps", default="grid", help=f"map kind: {', '.join(MAP_KINDS)}")
    parser.add_argument("--out", help=f"output folder (default {DEFAULT_OUT}, none with --json)")
    parser.add_argument("--json", action="store_true", help="print paper.json to stdout")
    parser.add_argument("--data", help="bench log (default: the shipped one)")
    parser.add_argument("--cfd", help="CFD samples for grid maps (default: the shipped ones)")
    parser.add_argument("--valve", help="valve file (default: the shipped valve)")
    parser.set_defaults(func=run)


def run(args) -> int:
    started = time.perf_counter()

    def progress(message: str) -> None:
        print(f"[{time.perf_counter() - started:5.1f} s] {message}", file=sys.stderr)

    valve = load_valve(args.valve)
    log = load_bench_log(args.data or shipped(SHIPPED_BENCH_LOG))
    flow_map, force_map = build_maps(args.maps, valve, args.cfd)
    comparison = reproduce(valve, flow_map, force_map, log, progress)
    out = args.out or (None if args.json else DEFAULT_OUT)
    if out:
        progress(f"writing tables and figures to {out}")
        written = write_report(comparison, out, args.maps)
        progress(f"wrote {len(written)} files")
    if args.json:
        print(json.dumps({"maps": args.maps, **comparison.to_json()}, indent=2))
    return 0
