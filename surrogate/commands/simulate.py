"""``simulate``: a synthetic bench log with a known hidden effect, to test the workbench on."""

from __future__ import annotations

import math

from ..data import load_bench_log
from ..data.writer import write_bench_log
from ..core.errors import InputError
from ..core.outputs import atomic_directory
from ..synthetic.mismatch import MapMismatch
from ..synthetic.simulate import (REALISTIC_MAGNITUDES, SensorNoise, hidden_effect_case,
                                  noise_free_sequence, reference_spec)
from .common import (add_command, bench_log_path, effect_library, guard_outputs, maps_help_text,
                     maps_option, non_negative_int, output_file, positive_int,
                     print_json, progress_for, required)

#: largest --mismatch: ten times the CFD's own error is already far beyond any real valve's
MISMATCH_MAX = 10.0


def register(subparsers) -> None:
    parser = add_command(
        subparsers, "simulate", help="write a synthetic bench log with a hidden effect switched "
                                     "on",
        description="Replay a reference valve (CFDA with the shipped bench's fitted values, on "
                    "grid maps unless --maps says otherwise) with one effect switched on over "
                    "the shipped test sequence, add sensor noise like the shipped bench's, and "
                    "write the log as CSV. With --mismatch the valve differs from its CFD as a "
                    "real valve does, so that diagnosing the log on the same maps tests what "
                    "a diagnosis can tell from the maps' own error. "
                    "Built-in effects default to a realistic magnitude: "
                    + ", ".join(f"{name} {values}" for name, values in
                                REALISTIC_MAGNITUDES.items()))
    parser.add_argument("--hidden", help="effect to switch on (none: the reference as is)")
    parser.add_argument("--set", action="append", default=[], metavar="PARAM=VALUE",
                        help="a parameter of the hidden effect, in its display unit")
    parser.add_argument("--effects-file", action="append", default=[], metavar="FILE",
                        help="Python file defining custom effects")
    parser.add_argument("--seed", type=non_negative_int, default=0,
                        help="noise seed (default 0)")
    parser.add_argument("--noise-scale", type=float, default=1.0,
                        help="sensor noise relative to the shipped bench's, 0 to 100 (default 1)")
    parser.add_argument("--every", type=positive_int, default=1,
                        help="keep every n-th sample of the sequence (default 1: all)")
    parser.add_argument("--sequence", help="bench log whose test sequence to use "
                                           "(default: the shipped one)")
    parser.add_argument("--maps", metavar="KIND", type=maps_option,
                        help=f"maps the valve runs on: {maps_help_text()} (default: grid maps "
                             "of the shipped CFD samples); use the kind you will diagnose with")
    parser.add_argument("--mismatch", type=float, metavar="SCALE",
                        help="make the valve differ from its CFD as a real one does, SCALE times "
                             "the CFD's own error (1: per-opening errors of 1.5 %% in Δp and "
                             "2.5 %% in the flow force, its own curve where the CFD has no "
                             "opening, a cavitation-driven back-pressure dependence; 0 to "
                             f"{MISMATCH_MAX:g}; default: none, the valve is its maps)")
    required(parser).add_argument("--out", required=True,
                                  help="output folder: the log is written as FOLDER/log.csv")
    parser.set_defaults(func=run)


def run(args) -> int:
    output, path = output_file(args, "log.csv", ".csv")
    guard_outputs(args, output)
    if not (math.isfinite(args.noise_scale) and 0 <= args.noise_scale <= 100):
        raise InputError(f"--noise-scale {args.noise_scale:g}: expected 0 to 100 (times the "
                         "shipped bench's sensor noise)")
    if args.mismatch is not None and not (math.isfinite(args.mismatch)
                                          and 0 <= args.mismatch <= MISMATCH_MAX):
        raise InputError(f"--mismatch {args.mismatch:g}: expected 0 to {MISMATCH_MAX:g} (times "
                         "the CFD's own error)")
    maps_spec = args.maps.spec() if args.maps else None
    progress = progress_for(args)
    library = effect_library(args, progress)
    hidden = None if args.hidden in (None, "none") else args.hidden
    if hidden:
        library.effect(hidden)  # an unknown name is an error before any work
    elif args.set:
        raise InputError("--set needs --hidden NAME: the parameters are the hidden effect's")
    values = {}
    for item in args.set:
        key, _, value = item.partition("=")
        try:
            number = float(value)
        except ValueError:
            number = math.nan
        if not key.strip() or not math.isfinite(number):
            raise InputError(f"--set {item!r}: expected PARAM=NUMBER with a finite number")
        values[key.strip()] = number
    source = load_bench_log(bench_log_path(args, progress, "sequence"), progress)
    sequence = noise_free_sequence(source, every=args.every)
    mismatch = None if args.mismatch is None else MapMismatch().scaled(args.mismatch)
    if mismatch is not None:
        progress(f"building a virtual valve {args.mismatch:g}x the CFD's own error away from "
                 f"its {args.maps or 'grid'} maps (draws of seed {args.seed})")
    # without a mismatch the valve runs on the maps themselves; with one it is built around them
    # from the grid reference (mismatch.py: a valve wrapping other maps with the case's draws)
    case = hidden_effect_case(hidden, values or None, sequence=sequence, seed=args.seed,
                              reference=reference_spec(None if mismatch else maps_spec),
                              library=library, noise=SensorNoise().scaled(args.noise_scale),
                              mismatch=mismatch, maps_under_test=maps_spec)
    if output.kind == "folder":
        with atomic_directory(output.path) as staging:
            write_bench_log(case.log, staging / path.name)
    else:
        write_bench_log(case.log, path)
    progress(f"wrote {len(case.log)} samples to {path} (truth: {case.truth.name})")
    if args.json:
        print_json({"file": str(path), "samples": len(case.log),
                    "runs": len(case.log.run_ids), "truth": case.truth.name,
                    "maps": str(args.maps or "grid"), "mismatch": args.mismatch})
    return 0
