"""Train every learned surrogate (monotone NN and GP, flow and force maps) on CPU and save them.

    python training/train.py [--kinds nn gp] [--out surrogate/trained] [--cfd PATH]

The surrogates are trained on the CFD samples minus the fixed, stratified 20 % hold-out of
``surrogate.learn.splits.holdout_mask`` and checked on that hold-out; the metrics go into each
folder's ``surrogate.json`` together with the SHA-256 of the sample file, so a test can tell when
the committed surrogates no longer match the shipped samples. Takes about a minute on 2 cores.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from surrogate import load_valve
from surrogate.data import load_cfd_samples
from surrogate.learn.metrics import map_errors
from surrogate.learn.reproducibility import environment
from surrogate.learn.splits import HOLDOUT_FRACTION, HOLDOUT_SEED, holdout_mask
from surrogate.learn.training import KINDS, train_surrogate
from surrogate.maps.registry import file_hash
from surrogate.maps.registry import TRAINED
from surrogate.paths import PROJECT_ROOT, SHIPPED_CFD_SAMPLES
from surrogate.progress import Progress


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--kinds", nargs="+", choices=KINDS, default=list(KINDS))
    parser.add_argument("--out", type=Path, default=TRAINED, help="parent folder of the surrogates")
    parser.add_argument("--cfd", type=Path, default=SHIPPED_CFD_SAMPLES, help="CFD-sample file")
    parser.add_argument("--valve", help="valve file (default: the shipped valve)")
    args = parser.parse_args()

    progress = Progress()
    import torch

    torch.set_num_threads(max(1, min(2, torch.get_num_threads())))
    valve = load_valve(args.valve)
    samples = load_cfd_samples(args.cfd)
    held_out = holdout_mask(samples.frame)
    try:
        data_file = str(args.cfd.resolve().relative_to(PROJECT_ROOT))
    except ValueError:
        data_file = str(args.cfd)
    training = {
        "data_file": data_file,
        "data_sha256": file_hash(args.cfd),
        "split": {"holdout_fraction": HOLDOUT_FRACTION, "seed": HOLDOUT_SEED,
                  "held_out_cases": sorted(samples.frame.loc[held_out, "case"])},
        # what decides the rounding: a retraining matches bit for bit only where this does
        "environment": environment(),
    }
    progress(f"{len(samples)} CFD samples from {args.cfd}; training on {int((~held_out).sum())}, "
             f"holding out {int(held_out.sum())}")
    for kind in args.kinds:
        progress(f"training {kind.upper()} maps")
        trained = train_surrogate(kind, samples, valve, ~held_out, progress)
        metrics = {"holdout": map_errors(trained.flow_map, trained.force_map,
                                         samples.frame[held_out], valve)}
        folder = args.out / kind
        trained.save(folder, training, metrics)
        hold = metrics["holdout"]
        progress(f"{kind.upper()}: trained in {trained.seconds:.1f} s; hold-out q error "
                 f"{100 * hold['q_rel_rmse']:.2f} %, flow-force error "
                 f"{100 * hold['flow_force_rel_rmse']:.2f} %; written to {folder}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
