"""How far can a retraining move the learned maps without anything being wrong, and how far does
a broken training move them? The evidence behind ``surrogate.learn.reproducibility.TOLERANCES``.

    python eval/retraining.py [--out results/retraining] [--seeds 3]

Retrains the committed NN and GP maps (every sample, same seeds and settings as
``training/train.py``)
under three kinds of change and compares each with the committed maps at the CFD states:

* nothing (twice): is training deterministic in this environment?
* float-level: the training data moved by one unit in the last place (random sign per value),
  or the math library on one thread: what another platform's rounding does;
* broken trainings, each a plausible bug: stopped early, the flow network's second stage
  skipped, one ensemble member, no GP optimiser restarts, one sweep lost from the data, the
  density off by 1 %.

Prints a table (RMS and largest relative difference in Δp and in the flow force) with each
row's verdict against the tolerance, and writes it as ``retraining.json`` and ``retraining.md``.
Takes about 12 minutes on 2 cores.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import time
from pathlib import Path

import numpy as np
import torch
from threadpoolctl import threadpool_limits

from surrogate import load_valve
from surrogate.data import load_cfd_samples
from surrogate.data.loaders import CfdSamples
from surrogate.learn import training
from surrogate.learn.reproducibility import (TOLERANCES, environment, nudged_by_one_ulp,
                                             prediction_difference)
from surrogate.maps import splits
from surrogate.maps.registry import build_maps
from surrogate.core.outputs import atomic_directory
from surrogate.core.paths import SHIPPED_CFD_SAMPLES


def scaled_density(samples: CfdSamples, factor: float) -> CfdSamples:
    frame = samples.frame.copy()
    frame["rho"] = frame["rho"] * factor
    return CfdSamples(frame, samples.source)


@contextlib.contextmanager
def patched(**settings):
    """Training constants changed for the duration (a mutation of ``surrogate.learn.training``)."""
    saved = {name: getattr(training, name) for name in settings}
    for name, value in settings.items():
        setattr(training, name, value)
    try:
        yield
    finally:
        for name, value in saved.items():
            setattr(training, name, value)


def variants(samples: CfdSamples, seeds: int):
    """(group, label, kinds, samples, training mask, context) of every retraining."""
    train = np.ones(len(samples), bool)  # the committed maps use every sample
    keys = splits.sweep_keys(samples.frame)
    one_sweep_lost = (keys != keys.iloc[len(keys) // 2]).to_numpy()
    none = contextlib.nullcontext
    rows = [("unchanged", "as committed", ("nn", "gp"), samples, train, none),
            ("unchanged", "as committed, again", ("nn", "gp"), samples, train, none)]
    rows += [("float-level", f"data moved by 1 ulp (seed {seed})", ("nn", "gp"),
              nudged_by_one_ulp(samples, seed), train, none) for seed in range(1, seeds + 1)]
    rows += [("float-level", "math libraries on one thread", ("nn", "gp"), samples, train,
              lambda: _one_thread())]
    rows += [
        ("broken", "stopped early (epochs / 5)", ("nn",), samples, train,
         lambda: patched(NN_EPOCHS=training.NN_EPOCHS // 5)),
        ("broken", "flow network in one stage", ("nn",), samples, train,
         lambda: patched(FLOW_PHYSICS_GROUPS=None)),
        ("broken", "one ensemble member", ("nn",), samples, train,
         lambda: patched(NN_MEMBERS=1)),
        ("broken", "no optimiser restarts", ("gp",), samples, train,
         lambda: patched(GP_RESTARTS=0)),
        ("broken", "one sweep lost from the data", ("nn", "gp"), samples, one_sweep_lost, none),
        ("broken", "density 1 % high", ("nn", "gp"), scaled_density(samples, 1.01), train, none),
    ]
    return rows


@contextlib.contextmanager
def _one_thread():
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        with threadpool_limits(1):
            yield
    finally:
        torch.set_num_threads(threads)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("results/retraining"))
    parser.add_argument("--seeds", type=int, default=3, help="ulp perturbations to try")
    args = parser.parse_args()
    torch.set_num_threads(max(1, min(2, torch.get_num_threads())))
    started = time.perf_counter()
    valve = load_valve()
    samples = load_cfd_samples(SHIPPED_CFD_SAMPLES)
    committed = {kind: build_maps(kind, valve) for kind in ("nn", "gp")}
    results = []
    for group, label, kinds, data, train, context in variants(samples, args.seeds):
        for kind in kinds:
            with context():
                fresh = training.train_surrogate(kind, data, valve, train)
            difference = prediction_difference(fresh.flow_map, fresh.force_map,
                                               *committed[kind], samples.frame, valve)
            row = {"group": group, "variant": label, "kind": kind, **difference,
                   "within_tolerance": TOLERANCES[kind].admits(difference)}
            results.append(row)
            print(f"[{time.perf_counter() - started:6.0f} s] {kind} {label:<34} "
                  f"dp rms {difference['dp_rms']:.2e} max {difference['dp_max']:.2e}  "
                  f"flow force rms {difference['flow_force_rms']:.2e} "
                  f"max {difference['flow_force_max']:.2e}  "
                  f"{'within' if row['within_tolerance'] else 'beyond'} tolerance", flush=True)
    lines = ["| kind | change | Δp RMS | Δp max | flow force RMS | flow force max | verdict |",
             "|---|---|---|---|---|---|---|"]
    for row in sorted(results, key=lambda r: (r["kind"], r["group"] != "unchanged",
                                              r["group"] != "float-level")):
        lines.append(f"| {row['kind']} | {row['group']}: {row['variant']} | "
                     f"{row['dp_rms']:.1e} | {row['dp_max']:.1e} | {row['flow_force_rms']:.1e} | "
                     f"{row['flow_force_max']:.1e} | "
                     f"{'within' if row['within_tolerance'] else 'beyond'} |")
    table = "\n".join(lines)
    print(table)
    document = {"environment": environment(),
                "tolerances": {k: vars(v) for k, v in TOLERANCES.items()}, "results": results,
                "seconds": round(time.perf_counter() - started, 1)}
    with atomic_directory(args.out) as staging:
        (staging / "retraining.json").write_text(json.dumps(document, indent=2) + "\n")
        (staging / "retraining.md").write_text(table + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
