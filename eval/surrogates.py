"""Evaluation: grid interpolation, the NN ensembles and the Gaussian processes, side by side.

    python eval/surrogates.py [--out results/surrogates] [--train]

* **Accuracy by cross-validation**, per kind and scheme (:mod:`surrogate.maps.crossval`: k-fold by
  sweep, leave one opening out, leave one temperature out, back-pressure set out): relative RMS
  error of q (predicted from p_L) and of the flow force, and the share of left-out samples inside
  the calibrated ±2σ bands. The grid's cross-validation runs here (a second); the learned kinds'
  is what ``training/train.py`` ran while training the committed maps and recorded in their
  ``surrogate.json`` (it retrains each kind once per fold: about five minutes).
* **Monotonicity**: violations on 20,000 random states, half inside the sampled ranges and half
  far outside.
* **Speed**: map evaluations per second (Δp at a flow, f_sim at a load pressure, and each one's
  standard deviation) on 100,000 random states, as ratios to the grid's measured in the same
  run; with ``--train``, the time to train the NN and GP maps on every sample against the
  2-minute budget.

Writes ``surrogates.md`` (the tables), ``surrogates.json`` and ``calibration.png`` (the
cross-validated errors against their ±2σ bands) into ``--out``.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.figure import Figure
from matplotlib.ticker import FormatStrFormatter, LogLocator, NullFormatter

from surrogate import load_valve
from surrogate.data import load_cfd_samples
from surrogate.learn.monotonicity import random_states, violations
from surrogate.maps.sigma import SigmaCalibration
from surrogate.maps.crossval import SCHEMES, standard_deviations
from surrogate.maps.learned import trained_folder
from surrogate.maps.package import read_manifest
from surrogate.maps.registry import build_maps, cross_validation_summary, learned_kinds, map_kind
from surrogate.core.outputs import atomic_directory
from surrogate.core.paths import SHIPPED_CFD_SAMPLES
from surrogate.reporting.report import figure_png

KINDS = ("grid", "nn", "gp")
LABELS = {"grid": "grid", "nn": "NN", "gp": "GP"}
TRAINING_BUDGET = 120.0  # [s] for every learned kind, on 2 cores
THROUGHPUT_TARGET = 200_000  # map evaluations per second, each kind


def errors_of(kind: str, valve) -> tuple[pd.DataFrame, SigmaCalibration, SigmaCalibration]:
    """The cross-validated errors of a kind and its calibrations."""
    flow_map, force_map = build_maps(kind, valve)
    if kind == "grid":
        calibrations = flow_map.uncertainty.calibrations
        return flow_map.uncertainty.errors, calibrations["flow"], calibrations["force"]
    from surrogate.learn.training import CROSS_VALIDATION_FILE

    frame = pd.read_csv(trained_folder(kind) / CROSS_VALIDATION_FILE)
    return frame, flow_map.calibration, force_map.calibration


def accuracy_table(summaries: dict) -> str:
    lines = ["| scheme | samples | q error: " + " / ".join(LABELS[k] for k in KINDS)
             + " | flow-force error: " + " / ".join(LABELS[k] for k in KINDS)
             + " | ±2σ holds q: " + " / ".join(LABELS[k] for k in KINDS)
             + " | ±2σ holds flow force: " + " / ".join(LABELS[k] for k in KINDS) + " |",
             "|---|---|---|---|---|---|"]
    for scheme in SCHEMES:
        rows = [summaries[kind][scheme] for kind in KINDS]

        def cells(key, scale=100, digits=1):
            return " / ".join(f"{scale * row[key]:.{digits}f}" for row in rows)

        lines.append(f"| {scheme} | {rows[0]['samples']} | {cells('q_rel_rmse', digits=2)} % | "
                     f"{cells('flow_force_rel_rmse')} % | {cells('q_coverage_2sigma', digits=0)} "
                     f"% | {cells('flow_force_coverage_2sigma', digits=0)} % |")
    return "\n".join(lines)


def throughput(valve, count: int = 100_000, repeats: int = 3) -> dict:
    """Map evaluations per second of every kind at random states."""
    rng = np.random.default_rng(0)
    q = rng.uniform(1, 12, count) / 6e4
    p_B = rng.uniform(2e5, 8e5, count)
    u = rng.uniform(0.05, 0.63, count) * 1e-3
    fluid = valve.oil.state(rng.uniform(293.15, 333.15, count))
    result = {}
    for kind in KINDS:
        flow_map, force_map = build_maps(kind, valve)
        p_L = p_B + flow_map.pressure_drop(q, p_B, u, fluid)
        force_map.force_std(p_L, p_B, u, fluid)  # first use: the grid's calibration
        calls = {"Δp(q)": lambda: flow_map.pressure_drop(q, p_B, u, fluid),
                 "f_sim(p_L)": lambda: force_map.force(p_L, p_B, u, fluid),
                 "σ of C_d": lambda: flow_map.log_discharge_std(q, p_B, u, fluid),
                 "σ of f_sim": lambda: force_map.force_std(p_L, p_B, u, fluid)}
        result[kind] = {}
        for name, call in calls.items():
            seconds = min(_timed(call) for _ in range(repeats))
            result[kind][name] = count / seconds
    return result


def _timed(call) -> float:
    started = time.perf_counter()
    call()
    return time.perf_counter() - started


def training_seconds(valve) -> dict:
    """Seconds to train each learned kind on every sample, as ``training/train.py`` does."""
    import torch

    from surrogate.learn.training import train_surrogate

    torch.set_num_threads(max(1, min(2, torch.get_num_threads())))
    samples = load_cfd_samples(SHIPPED_CFD_SAMPLES)
    return {kind: train_surrogate(kind, samples, valve).seconds for kind in ("nn", "gp")}


def calibration_figure(errors: dict) -> Figure:
    """Cross-validated error over its calibrated σ, per kind and map: a calibrated kind has
    about 95 % of the points inside ±2."""
    figure = Figure(figsize=(12, 6.4), layout="constrained")
    axes = figure.subplots(2, len(KINDS), sharey="row", squeeze=False)
    colours = dict(zip(SCHEMES, ("tab:blue", "tab:orange", "tab:green", "tab:red")))
    for column, kind in enumerate(KINDS):
        frame, flow, force = errors[kind]
        stds = standard_deviations(frame, flow, force)
        for row, (name, error, std) in enumerate((("C_d (q at its Δp)", "discharge_error",
                                                   stds[0]),
                                                  ("flow force", "force_error", stds[1]))):
            ax = axes[row, column]
            z = frame[error].to_numpy() / std
            for scheme in SCHEMES:
                at = (frame["scheme"] == scheme).to_numpy()
                ax.plot(std[at] * 100, z[at], "o", markersize=2.5, alpha=0.7,
                        color=colours[scheme], label=scheme)
            ax.axhspan(-2, 2, color="0.9", zorder=0)
            ax.set_xscale("log")
            # plain numbers at a few ticks: a narrow log axis otherwise labels its minor ticks
            # as 2×10⁰, 3×10⁰, ... on top of each other
            ax.xaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
            ax.xaxis.set_major_formatter(FormatStrFormatter("%g"))
            ax.xaxis.set_minor_formatter(NullFormatter())
            ax.set_ylim(-6, 6)
            ax.set_title(f"{LABELS[kind]}: {name}", fontsize=10)
            ax.set_xlabel("calibrated σ [%]")
            ax.grid(alpha=0.3)
    for row in range(2):
        axes[row, 0].set_ylabel("error / σ")
    axes[0, -1].legend(fontsize=7, loc="upper right")
    figure.suptitle("Cross-validated errors against their calibrated σ (shaded: ±2σ)")
    return figure


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("results/surrogates"))
    parser.add_argument("--train", action="store_true",
                        help="also time the training of the learned kinds (about 90 s)")
    args = parser.parse_args()
    valve = load_valve()

    summaries = {kind: cross_validation_summary(map_kind(kind).source(), valve) for kind in KINDS}
    errors = {kind: errors_of(kind, valve) for kind in KINDS}
    states = random_states(20_000, seed=7)
    monotonicity = {kind: violations(*build_maps(kind, valve), states)["total"]
                    for kind in KINDS}
    speed = throughput(valve)
    trained = training_seconds(valve) if args.train else {
        kind: read_manifest(trained_folder(kind), learned_kinds())["training"]["seconds"]
        for kind in ("nn", "gp")}

    lines = ["Accuracy by cross-validation (relative RMS error; ±2σ: share of the left-out "
             "samples inside the calibrated band):", "", accuracy_table(summaries), "",
             f"Monotonicity violations on {len(states.u):,} random states: "
             + ", ".join(f"{LABELS[k]} {monotonicity[k]}" for k in KINDS), "",
             "Map evaluations per second (100,000 random states; in brackets, the ratio to the "
             "grid's in the same run):", "",
             "| kind | " + " | ".join(speed["grid"]) + " |",
             "|---|" + "---|" * len(speed["grid"])]
    for kind in KINDS:
        lines.append(f"| {LABELS[kind]} | " + " | ".join(
            f"{rate / 1e3:,.0f} k ({rate / speed['grid'][name]:.2f})"
            for name, rate in speed[kind].items()) + " |")
    lines += ["", "Training on every sample, 2 cores" + (" (measured now)" if args.train else
                                                          " (as recorded by training/train.py)")
              + ": " + ", ".join(f"{LABELS[k]} {s:.0f} s" for k, s in trained.items())
              + f"; together {sum(trained.values()):.0f} s, "
              f"{sum(trained.values()) / TRAINING_BUDGET:.2f} of the {TRAINING_BUDGET:.0f} s "
              "budget"]
    table = "\n".join(lines)
    print(table)
    slowest = min(min(rates.values()) for rates in speed.values())
    print(f"\nslowest map evaluation: {slowest:,.0f} points/s "
          f"({slowest / THROUGHPUT_TARGET:.2f} of the {THROUGHPUT_TARGET:,} target)")
    document = {"cross_validation": summaries, "monotonicity_violations": monotonicity,
                "evaluations_per_second": speed, "training_seconds": trained}
    with atomic_directory(args.out) as staging:
        (staging / "surrogates.md").write_text(table + "\n")
        (staging / "surrogates.json").write_text(json.dumps(document, indent=2) + "\n")
        (staging / "calibration.png").write_bytes(figure_png(calibration_figure(errors)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
