"""What the workbench commands (compare, diagnose, fit, workflow, simulate) share: their common
options, loading the model and the log, progress lines and JSON output."""

from __future__ import annotations

import json
import sys
import time

from ..data import load_bench_log
from ..effects import load_effects_file
from ..model import ValveModel
from ..modelfile import PRESETS, load_model
from ..paths import SHIPPED_BENCH_LOG, shipped


def add_data_options(parser, *, model: bool = True, out_help: str = "output folder") -> None:
    if model:
        parser.add_argument("--model", required=True,
                            help=f"a preset ({', '.join(PRESETS)}) or a model file (TOML)")
    parser.add_argument("--data", help="bench log CSV (default: the shipped one)")
    parser.add_argument("--effects-file", action="append", default=[], metavar="FILE",
                        help="Python file defining custom effects (repeatable)")
    parser.add_argument("--valve", help="valve file (default: the model's, or the shipped valve)")
    parser.add_argument("--out", help=out_help)
    parser.add_argument("--json", action="store_true",
                        help="print the machine-readable result to stdout")


class Progress:
    """Progress lines with elapsed time, on stderr so that --json output stays clean."""

    def __init__(self):
        self.started = time.perf_counter()

    def __call__(self, message: str) -> None:
        print(f"[{self.elapsed:6.1f} s] {message}", file=sys.stderr, flush=True)

    @property
    def elapsed(self) -> float:
        return time.perf_counter() - self.started


def load_effects(args) -> list[str]:
    """Import the --effects-file files (before a model file that names their effects loads)."""
    names = []
    for path in args.effects_file:
        names += load_effects_file(path)
    return names


def load_inputs(args, progress: Progress) -> tuple[ValveModel | None, object]:
    custom = load_effects(args)
    if custom:
        progress(f"custom effects: {', '.join(custom)}")
    model = load_model(args.model, args.valve) if getattr(args, "model", None) else None
    log = load_bench_log(args.data or shipped(SHIPPED_BENCH_LOG))
    progress(f"{len(log)} samples in {len(log.run_ids)} runs from {log.source}")
    return model, log


def print_json(document: dict) -> None:
    print(json.dumps(document, indent=2, allow_nan=False))
