"""The README's figure: the error staircase of the main job on the shipped bench log, and one
run's Δp(q) loop with the paper's CFDA and the workflow's final model.

Runs the workflow as the quickstart's first command does on its main kind of map (GP maps,
without the comparison kinds; about 5 minutes on 2 cores) and writes
``docs/figures/workflow.png``. Run: ``python docs/figures.py [--run R06]``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from surrogate.data import load_bench_log
from surrogate.core.paths import SHIPPED_BENCH_LOG
from surrogate.description.presets import maps
from surrogate.reporting.staircase import plot_staircase
from surrogate.core.units import from_si
from surrogate.workbench.workflow import run_workflow

HERE = Path(__file__).resolve().parent
#: the paper's last step, CFDA (BMBE, BMBEBF, CFD maps, CFDA)
CFDA_STEP = 3


def draw(workflow, run: str) -> Figure:
    """Two panels: the staircase, and run ``run``'s measured Δp(q) against CFDA and the final
    model, each ramp in its own shade."""
    figure = Figure(figsize=(14, 5.6), layout="constrained")
    left, right = figure.subplots(1, 2, width_ratios=[1.35, 1])
    plot_staircase(left, workflow.steps, workflow.noise_floor, fontsize=9, width=30,
                   lines=2)
    left.set_title(f"From the paper's basic model to {from_si(workflow.final.rms, 'bar'):.2f} "
                   "bar: the error staircase on the shipped log", fontsize=11)
    frame = workflow.log.frame
    rows = np.flatnonzero(frame["run"].astype(str).to_numpy() == run)
    q = from_si(frame["q"].to_numpy()[rows], "L/min")
    measured = from_si((frame["p_L"] - frame["p_B"]).to_numpy()[rows], "bar")
    up = frame["direction"].to_numpy()[rows] == "up"
    for mask, shade, ramp in ((up, "tab:orange", "up"), (~up, "tab:purple", "down")):
        right.plot(q[mask][::3], measured[mask][::3], ".", color=shade, markersize=3,
                   alpha=0.5, label=f"measured, ramp {ramp}")
    for step, style, name in ((workflow.steps[CFDA_STEP], "--", "CFDA (the paper)"),
                              (workflow.final, "-", "final model")):
        predicted = from_si(step.log_replay.replay.dp[rows], "bar")
        for mask, shade in ((up, "tab:orange"), (~up, "tab:purple")):
            order = np.argsort(q[mask])
            right.plot(q[mask][order], _smooth(predicted[mask][order]), style, color=shade,
                       linewidth=1.6, label=f"{name}" if shade == "tab:orange" else None)
    temperature = from_si(frame["temperature"].to_numpy()[rows].mean(), "degC")
    pilot = from_si((frame["p_P"] - frame["p_B"]).to_numpy()[rows].mean(), "bar")
    right.set_title(f"Run {run}: {temperature:.0f} °C, p_Pe {pilot:.0f} bar — the hysteresis "
                    "loop", fontsize=11)
    right.set_xlabel("flow q [L/min]", fontsize=10)
    right.set_ylabel("pressure drop Δp [bar]", fontsize=10)
    right.legend(fontsize=9, loc="upper left", markerscale=3)
    right.grid(alpha=0.3)
    return figure


def _smooth(values: np.ndarray, window: int = 9) -> np.ndarray:
    """A running median: the replay follows the measured inputs' noise sample by sample."""
    padded = np.pad(values, window // 2, mode="edge")
    return np.array([np.median(padded[i:i + window]) for i in range(len(values))])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--run", default="R06", help="the run whose loop is drawn")
    parser.add_argument("--out", default=str(HERE / "figures" / "workflow.png"))
    args = parser.parse_args()
    log = load_bench_log(SHIPPED_BENCH_LOG)
    workflow = run_workflow(log, maps_spec=maps("gp"), progress=print)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    draw(workflow, args.run).savefig(out, dpi=110)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
