"""Force-map GP structures by the four-scheme cross-validation: which kernel parts carry the flow
force best between openings, across temperatures and at other back pressures.

    python eval/force_gp_structures.py [--restarts 3] [--flow] [--out results/force_gp_structures]

The shipped GP's force map (``surrogate/learn/training.py``: ``FORCE_GP_PARTS``) predicts
ln(−α), α = f_ff/(A_L·Δp), from (ln Re, ln u/U, ln σ, ln(Δp/p_atm)) with a Brownian-motion bridge
over the opening times an RBF of Re and the pressure level, an RBF of (Re, u) and an RBF of σ.
Here the same fit (scikit-learn, the project's kernels) is tried with other parts, among them the
three-feature structure shipped before, on the folds of :mod:`surrogate.maps.crossval`; the score
is the relative RMS error of the flow force at each left-out sample's pressure drop
(``force_error`` of :func:`~surrogate.maps.crossval.errors_on`, here exp(L̂ − L) − 1 of the latent
target). The shipped GP's own cross-validation (``training/train.py``) scores the structure it
ships within 0.01 % of its row here.

``--flow`` asks the same of the flow map's GP instead (``surrogate/learn/training.py``:
``FLOW_GP_PARTS``, ``FLOW_GP_TREND_DEGREE``: ln C_d from (ln Re_q, ln u/U, ln σ_q) as a trend, a
quadratic in the opening and linear in the rest, plus a Matérn 3/2 in the opening times an RBF
of Re, plus RBF(u, σ); or other parts, or the trend of another degree in the opening, 1 to 4,
or none), scored by the relative error of C_d at each left-out sample (the flow at its
pressure drop): whether another structure would carry q better between openings without losing
elsewhere. Leaving one opening out also asks what the trend does across the 0.20-0.63 mm gap,
where the Matérn reverts to it: the row prints each left-out opening's error too.

Prints one row per structure and writes ``structures.json``; about a minute on one core.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from surrogate import load_valve
from surrogate.data import load_cfd_samples
from surrogate.features import FeatureSpec, targets
from surrogate.learn.gaussian_process import fit_gp
from surrogate.learn.training import FLOW_GP_PARTS, FLOW_GP_TREND_DEGREE
from surrogate.maps.crossval import SCHEMES, folds
from surrogate.maps.gp import NumpyGP
from surrogate.core.outputs import atomic_directory
from surrogate.core.paths import SHIPPED_CFD_SAMPLES

#: input columns: 0 ln Re, 1 ln(u/U), 2 ln σ, 3 ln(Δp/p_atm)
STRUCTURES = {
    "three features: bridge(u; Re) + RBF(Re, u) + RBF(σ)":
        (("bridge", (1, 0)), ("rbf", (0, 1)), ("rbf", (2,))),
    "+ RBF(Δp, u)": (("bridge", (1, 0)), ("rbf", (0, 1)), ("rbf", (2,)), ("rbf", (3, 1))),
    "+ bridge(u; Δp)": (("bridge", (1, 0)), ("rbf", (0, 1)), ("rbf", (2,)), ("bridge", (1, 3))),
    "shipped: bridge(u; Re, Δp) + RBF(Re, u) + RBF(σ)":
        (("bridge", (1, 0, 3)), ("rbf", (0, 1)), ("rbf", (2,))),
}


#: input columns of the flow map: 0 ln Re_q, 1 ln(u/U), 2 ln σ_q; a structure's trend
#: (the degree of its polynomial in the opening) follows its parts where it has one
_MATERN_PAIR = FLOW_GP_PARTS  # Matérn(u)·RBF(Re) + RBF(u, σ)
_DEGREES = {1: "linear", 2: "quadratic", 3: "cubic", 4: "quartic"}
#: the trends in the opening, the shipped degree first
_TRENDS = sorted(_DEGREES, key=lambda degree: degree != FLOW_GP_TREND_DEGREE)
FLOW_STRUCTURES = {
    **{("shipped: " if degree == FLOW_GP_TREND_DEGREE else "")
       + f"{_DEGREES[degree]} trend + Matérn(u)·RBF(Re) + RBF(u, σ)": (_MATERN_PAIR, degree)
       for degree in _TRENDS},
    "RBF(Re, u) + RBF(u, σ)": (("rbf", (0, 1)), ("rbf", (1, 2))),
    "Matérn(u)·RBF(Re) + RBF(u, σ)": _MATERN_PAIR,
    "Matérn(u)·RBF(Re) + Matérn(u)·RBF(σ)": (("matern", (1, 0)), ("matern", (1, 2))),
    "Matérn(u)·RBF(Re) + RBF(u, σ) + RBF(σ)": (("matern", (1, 0)), ("rbf", (1, 2)),
                                              ("rbf", (2,))),
    "+ RBF(σ)": (("rbf", (0, 1)), ("rbf", (1, 2)), ("rbf", (2,))),
    "+ RBF(Re)": (("rbf", (0, 1)), ("rbf", (1, 2)), ("rbf", (0,))),
    "+ RBF(Re, u, σ)": (("rbf", (0, 1)), ("rbf", (1, 2)), ("rbf", (0, 1, 2))),
    "RBF(Re, u, σ) alone": (("rbf", (0, 1, 2)),),
    "bridge(u; Re) + RBF(u, σ)": (("bridge", (1, 0)), ("rbf", (1, 2))),
}


def scores(parts, inputs: np.ndarray, latent: np.ndarray, frame, restarts: int,
           trend: int = 0) -> tuple[dict, dict]:
    """Relative RMS error [%] of the target per scheme, each fold fitted on its training
    samples only (standardisation included), with a trend of degree ``trend`` in the opening
    (0: none) fitted first; and the same per left-out opening [mm]."""
    errors = {scheme: [] for scheme in SCHEMES}
    by_opening = {}
    for fold in folds(frame):
        arrays = fit_gp(inputs[fold.train], latent[fold.train], parts, linear_mean=trend > 0,
                        opening_degree=max(trend, 1), restarts=restarts)
        predicted = NumpyGP(arrays).predict(inputs[fold.test])
        error = np.exp(predicted - latent[fold.test]) - 1.0
        errors[fold.scheme].append(error)
        if fold.scheme == "leave one opening out":
            opening = float(np.unique(frame["u"].to_numpy()[fold.test])[0]) * 1e3
            by_opening[f"{opening:.2f}"] = 100.0 * float(np.sqrt(np.mean(error ** 2)))
    return ({scheme: 100.0 * float(np.sqrt(np.mean(np.concatenate(found) ** 2)))
             for scheme, found in errors.items() if found}, by_opening)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--restarts", type=int, default=3)
    parser.add_argument("--flow", action="store_true",
                        help="the flow map's GP (ln C_d) instead of the force map's")
    parser.add_argument("--out", default="results/force_gp_structures")
    args = parser.parse_args()
    valve = load_valve()
    frame = load_cfd_samples(SHIPPED_CFD_SAMPLES).frame
    data = targets(FeatureSpec.for_valve(valve), frame)
    if args.flow:
        latent, inputs, structures = data.log_discharge, data.flow_features, FLOW_STRUCTURES
    else:
        latent = np.log(-data.flow_force_fraction)
        inputs = data.force_features  # all four (surrogate.features.FORCE_FEATURE_NAMES)
        structures = STRUCTURES
    print(f"{'structure':52s} " + " ".join(f"{s[:14]:>14s}" for s in SCHEMES) + "    mean")
    results = {}
    for name, structure in structures.items():
        parts, trend = structure if isinstance(structure[-1], int) else (structure, 0)
        began = time.perf_counter()
        row, by_opening = scores(parts, inputs, latent, frame, args.restarts, trend)
        results[name] = {**row, "mean": float(np.mean(list(row.values()))),
                         "left-out opening [mm]: error %": by_opening,
                         "seconds": round(time.perf_counter() - began, 1)}
        print(f"{name:52s} " + " ".join(f"{row[s]:13.2f}%" for s in SCHEMES)
              + f"  {results[name]['mean']:5.2f}%", flush=True)
        print(f"{'':4s}each opening left out [mm: %]: "
              + ", ".join(f"{u} {e:.2f}" for u, e in by_opening.items()), flush=True)
    with atomic_directory(Path(args.out)) as staging:
        (staging / "structures.json").write_text(json.dumps(results, indent=2))


if __name__ == "__main__":
    main()
