"""``simulate``: a synthetic bench log with a known hidden effect, to test the workbench on."""

from __future__ import annotations

from ..data import load_bench_log
from ..errors import InputError
from ..paths import SHIPPED_BENCH_LOG, shipped
from ..data.writer import write_bench_log
from ..workbench.simulate import (REALISTIC_MAGNITUDES, SensorNoise, hidden_effect_case,
                                  reference_model, noise_free_sequence)
from .workbench_options import Progress, load_effects


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "simulate", help="write a synthetic bench log with a hidden effect switched on",
        description="Replay a reference valve (CFDA on grid maps with the shipped bench's fitted "
                    "values) with one effect switched on over the shipped test sequence, add "
                    "sensor noise like the shipped bench's, and write the log as CSV. "
                    f"Built-in effects default to a realistic magnitude: "
                    + ", ".join(f"{name} {values}" for name, values in
                                REALISTIC_MAGNITUDES.items()))
    parser.add_argument("--hidden", help="effect to switch on (none: the reference as is)")
    parser.add_argument("--set", action="append", default=[], metavar="PARAM=VALUE",
                        help="a parameter of the hidden effect, in its display unit")
    parser.add_argument("--effects-file", action="append", default=[], metavar="FILE",
                        help="Python file defining custom effects")
    parser.add_argument("--seed", type=int, default=0, help="noise seed (default 0)")
    parser.add_argument("--noise-scale", type=float, default=1.0,
                        help="sensor noise relative to the shipped bench's (default 1)")
    parser.add_argument("--every", type=int, default=1,
                        help="keep every n-th sample of the sequence (default 1: all)")
    parser.add_argument("--sequence", help="bench log whose test sequence to use "
                                           "(default: the shipped one)")
    parser.add_argument("--out", required=True, help="CSV file to write")
    parser.set_defaults(func=run)


def run(args) -> int:
    progress = Progress()
    load_effects(args)
    values = {}
    for item in args.set:
        key, _, value = item.partition("=")
        try:
            values[key.strip()] = float(value)
        except ValueError:
            raise InputError(f"--set {item!r}: expected PARAM=NUMBER") from None
    source = load_bench_log(args.sequence or shipped(SHIPPED_BENCH_LOG))
    sequence = noise_free_sequence(source, every=args.every)
    case = hidden_effect_case(args.hidden, values or None, sequence=sequence, seed=args.seed,
                              reference=reference_model(),
                              noise=SensorNoise().scaled(args.noise_scale))
    write_bench_log(case.log, args.out)
    progress(f"wrote {len(case.log)} samples to {args.out} (truth: {case.truth!r})")
    return 0
