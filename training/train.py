"""Train every learned surrogate (NN and GP, flow and force maps) on CPU and save them.

    python training/train.py [--kinds nn gp grid] [--out surrogate/trained] [--cfd PATH]
                             [--workers 2] [--calibrate-only]

Each kind is trained on **every** CFD sample: a user's CFD runs are too expensive to hold any
back. How accurate the result is comes from cross-validation (``surrogate.maps.crossval``): the
same training repeated with sweeps, an opening, a temperature or the back-pressure set left out,
and asked about what it did not see. Those errors calibrate the maps' standard deviations, and go
into each folder: the summary per scheme in ``surrogate.json`` (with the SHA-256 of the sample
file, so a test can tell when the committed surrogates no longer match the shipped samples), the
errors per left-out sample in ``cross_validation.csv``.

``--calibrate-only`` fits the learned kinds' calibrations again from the errors their folders
keep, without training (seconds): for a change in how σ is fitted.

The grid maps are not trained, but their calibration (from their own cross-validation) and
that cross-validation's summary are stored for the shipped samples too (``--kinds grid``, a few
seconds), with the CFD's own Δp error that the mesh study and the samples give, pooled
(``surrogate/trained/cfd/cfd_error.json``, :func:`surrogate.maps.cfd_error.pooled_dp_error`).

Training the deployed maps takes under a minute on 2 cores (40 s on a quiet machine); the
cross-validation retrains each kind once per fold (14 folds on the shipped samples), about five
minutes with two worker processes.
"""

from __future__ import annotations

import argparse
import sys
import time
from functools import partial
from pathlib import Path

from surrogate import load_valve
from surrogate.data import load_cfd_samples
from surrogate.learn.reproducibility import environment
from surrogate.learn.training import (KINDS, kept_errors, learned_maps_on, recalibrate,
                                      train_surrogate)
from surrogate.maps.cfd_error import SHIPPED_CFD_ERROR, write_dp_error
from surrogate.maps.crossval import calibrate, cross_validate, summary
from surrogate.maps.grid import GridUncertainty
from surrogate.maps.grid_sigma import SHIPPED_GRID_CALIBRATION, write_calibrations
from surrogate.maps.package import file_hash
from surrogate.maps.registry import map_kind
from surrogate.core.errors import InputError
from surrogate.core.outputs import Output, check_outputs
from surrogate.core.paths import (PROJECT_ROOT, SHIPPED_BENCH_LOG, SHIPPED_CFD_SAMPLES,
                                  SHIPPED_SURROGATES)
from surrogate.core.progress import Progress


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--kinds", nargs="+", choices=[*KINDS, "grid"], default=[*KINDS, "grid"],
                        help="learned kinds to train; grid: only the grid maps' calibration "
                        "(surrogate.maps.grid_sigma)")
    parser.add_argument("--out", type=Path, default=SHIPPED_SURROGATES,
                        help="parent folder of the surrogates")
    parser.add_argument("--cfd", type=Path, default=SHIPPED_CFD_SAMPLES, help="CFD-sample file")
    parser.add_argument("--valve", help="valve file (default: the shipped valve)")
    parser.add_argument("--workers", type=int, default=2,
                        help="processes for the cross-validation (default 2)")
    parser.add_argument("--calibrate-only", action="store_true",
                        help="refit the learned kinds' calibrations from the cross-validated "
                        "errors their folders keep (cross_validation.csv); no training")
    args = parser.parse_args()
    try:  # before any training: no kind's folder may replace or hold what training reads
        check_outputs([Output("--out", args.out / kind, "folder") for kind in args.kinds],
                      [(args.cfd, "given by --cfd"), (args.valve, "given by --valve"),
                       (SHIPPED_CFD_SAMPLES.parent, "the shipped CFD samples"),
                       (SHIPPED_BENCH_LOG.parent, "the shipped measurements")])
    except InputError as error:
        parser.error(str(error))

    progress = Progress()
    import torch

    torch.set_num_threads(max(1, min(2, torch.get_num_threads())))
    valve = load_valve(args.valve)
    samples = load_cfd_samples(args.cfd)
    try:
        data_file = str(args.cfd.resolve().relative_to(PROJECT_ROOT))
    except ValueError:
        data_file = str(args.cfd)
    training = {
        "data_file": data_file,
        "data_sha256": file_hash(args.cfd),
        "samples": "all",
        # what decides the rounding: a retraining matches bit for bit only where this does
        "environment": environment(),
    }
    if not args.calibrate_only:
        progress(f"{len(samples)} CFD samples from {args.cfd}; training on all of them")
    for kind in args.kinds:
        if args.calibrate_only and kind != "grid":
            recalibrate(args.out / kind, samples)
            progress(f"{kind.upper()}: calibration refitted in {args.out / kind}")
            continue
        if kind == "grid":
            path = args.out / "grid" / SHIPPED_GRID_CALIBRATION.name
            uncertainty = GridUncertainty(samples, valve)
            calibrations = uncertainty.fitted_calibrations()
            accuracy = summary(uncertainty.errors, calibrations["flow"], calibrations["force"],
                               known=uncertainty.known_in_errors())
            write_calibrations(path, samples, valve, calibrations, accuracy)
            progress(f"GRID: calibration and cross-validation summary written to {path}")
            # the CFD's own Δp error pooled from these samples, which every map's σ carries
            # (read from the package's copy: the shipped samples')
            path = args.out / SHIPPED_CFD_ERROR.parent.name / SHIPPED_CFD_ERROR.name
            pooled = write_dp_error(path, samples.frame, training["data_sha256"])["dp"]
            progress(f"CFD error in Δp {100 * pooled['pooled']:.2f} % (mesh study and samples "
                     f"pooled) written to {path}")
            continue
        progress(f"training {kind.upper()} maps")
        trained = train_surrogate(kind, samples, valve, None, progress)
        progress(f"{kind.upper()}: trained in {trained.seconds:.1f} s; cross-validating with "
                 f"{args.workers} worker(s)")
        started = time.perf_counter()
        errors = kept_errors(cross_validate(samples, valve,
                                            partial(learned_maps_on, kind, samples, valve),
                                            progress=progress, workers=args.workers))
        powers = map_kind(kind).calibration_powers
        flow, force = calibrate(errors, use_spread=True, samples=samples, powers=(powers, powers))
        trained.calibrate(flow, force)
        metrics = {"cross_validation": summary(errors, flow, force, samples=samples),
                   "cross_validation_seconds": round(time.perf_counter() - started, 1)}
        folder = args.out / kind
        trained.save(folder, training, metrics, errors)
        for scheme, row in metrics["cross_validation"].items():
            progress(f"{kind.upper()} {scheme}: q {100 * row['q_rel_rmse']:.2f} %, flow force "
                     f"{100 * row['flow_force_rel_rmse']:.2f} %; ±2σ holds "
                     f"{100 * row['q_coverage_2sigma']:.0f} % / "
                     f"{100 * row['flow_force_coverage_2sigma']:.0f} %")
        progress(f"{kind.upper()} written to {folder}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
