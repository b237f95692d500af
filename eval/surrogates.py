"""Evaluation: grid interpolation against the monotone NN and the GP maps.

    python eval/surrogates.py [--out results/surrogates] [--workers 2]

Four tests, each training the maps on one part of the CFD samples and predicting the rest:

(a) the fixed, stratified 20 % hold-out (the committed surrogates are trained this way);
(b) leave one opening out, each interior u in turn;
(c) leave one temperature out, each of 20, 40, 60 °C in turn (trained on the other two);
(d) the back-pressure set (trained on the 5-bar main set).

Metrics: relative RMSE of q predicted from (p_L, p_B, u, fluid), relative RMSE of the flow-force
part of f_sim (f_sim − p_L·A_L − p_B·(A_s3 − A_B)), monotonicity violations on 100,000 random states
(half inside, half far outside the sampled ranges), evaluation throughput and training time. An
unconstrained copy of the network (same architecture, no sign or slope constraints) is evaluated
alongside to show what the constraints buy. Writes a Markdown table, ``surrogates.json`` and the
figures into ``--out``; takes about 5 minutes on 2 cores.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from surrogate import load_valve
from surrogate.data import load_cfd_samples
from surrogate.features import FeatureSpec, targets
from surrogate.fluid import FluidState
from surrogate.learn import splits
from surrogate.learn.metrics import map_errors
from surrogate.learn.monotonicity import random_states, violations
from surrogate.learn.training import train_surrogate
from surrogate.maps.grid import GridFlowMap, GridForceMap
from surrogate.maps.registry import build_maps
from surrogate.outputs import atomic_directory
from surrogate.paths import SHIPPED_CFD_SAMPLES
from surrogate.units import BAR, LPM, ZERO_CELSIUS, from_si

KINDS = ("grid", "nn", "gp")
LABELS = {"grid": "grid", "nn": "NN", "gp": "GP", "nn-free": "NN, unconstrained"}


def experiments(frame) -> list[tuple[str, str, np.ndarray, np.ndarray]]:
    """(experiment, label, training mask, test mask) of every test."""
    held_out = splits.holdout_mask(frame)
    cases = [("a", "20 % hold-out", ~held_out, held_out)]
    cases += [("b", label, train, test) for label, train, test in
              splits.leave_one_opening_out(frame)]
    cases += [("c", label, train, test) for label, train, test in
              splits.leave_one_temperature_out(frame)]
    cases.append(("d", "back-pressure set", splits.main_set(frame),
                  splits.back_pressure_set(frame)))
    return cases


def fit(kind: str, samples, valve, train):
    """(flow map, force map, seconds) of a kind trained on the ``train`` samples."""
    started = time.perf_counter()
    if kind == "grid":
        subset = samples.subset(train)
        maps = GridFlowMap.from_samples(subset), GridForceMap.from_samples(subset, valve)
        return (*maps, time.perf_counter() - started)
    trained = train_surrogate(kind.removesuffix("-free"), samples, valve, train,
                              constrained=not kind.endswith("-free"))
    return trained.flow_map, trained.force_map, trained.seconds


def run_case(case) -> dict:
    """Every map kind on one test (runs in a worker process)."""
    import torch

    torch.set_num_threads(1)
    experiment, label, train, test = case
    valve = load_valve()
    samples = load_cfd_samples(SHIPPED_CFD_SAMPLES)
    result = {"experiment": experiment, "label": label, "test_samples": int(test.sum())}
    for kind in KINDS:
        flow_map, force_map, seconds = fit(kind, samples, valve, train)
        result[kind] = {**map_errors(flow_map, force_map, samples.frame[test], valve),
                        "training_seconds": round(seconds, 2)}
    print(f"  ({experiment}) {label}: " + ", ".join(
        f"{LABELS[k]} q {100 * result[k]['q_rel_rmse']:.2f} %" for k in KINDS), flush=True)
    return result


def throughput(flow_map, force_map, states, repeats: int = 3) -> dict:
    """Points per second of the pressure drop (the solver's query) and of the force."""
    q = np.full(len(states.u), 6 * LPM)
    rates = {}
    for name, call in (("pressure_drop", lambda: flow_map.pressure_drop(q, states.p_B, states.u,
                                                                        states.fluid)),
                       ("force", lambda: force_map.force(states.p_L, states.p_B, states.u,
                                                         states.fluid))):
        best = min(_timed(call) for _ in range(repeats))
        rates[name] = len(q) / best
    return rates


def _timed(call) -> float:
    started = time.perf_counter()
    call()
    return time.perf_counter() - started


def summary_table(results: list[dict], monotonicity: dict, speed: dict,
                  training: dict) -> str:
    """The Markdown table the README quotes."""
    def cell(records, kind, key):
        values = [r[kind][key] for r in records]
        text = f"{100 * np.mean(values):.2f}"
        return text + (f" (max {100 * max(values):.2f})" if len(values) > 1 else "")

    groups = [("(a) 20 % hold-out", [r for r in results if r["experiment"] == "a"]),
              ("(b) leave one opening out, mean of 5", [r for r in results if r["experiment"] == "b"])]
    groups += [(f"(c) leave {r['label']} out", [r]) for r in results if r["experiment"] == "c"]
    groups += [("(d) back-pressure set", [r for r in results if r["experiment"] == "d"])]
    header = ("| test | q error, grid [%] | q error, NN [%] | q error, GP [%] "
              "| flow-force error, grid [%] | NN [%] | GP [%] |")
    lines = [header, "|---|---|---|---|---|---|---|"]
    for name, records in groups:
        lines.append(f"| {name} | " + " | ".join(cell(records, k, "q_rel_rmse") for k in KINDS)
                     + " | " + " | ".join(cell(records, k, "flow_force_rel_rmse") for k in KINDS)
                     + " |")
    lines += ["", "| map | monotonicity violations (100,000 states) | pressure drops per s "
                  "| forces per s | training time [s] |", "|---|---|---|---|---|"]
    for kind in (*KINDS, "nn-free"):
        m = monotonicity[kind]
        in_range = sum(v["in_range"] for k, v in m.items() if isinstance(v, dict))
        outside = sum(v["outside"] for k, v in m.items() if isinstance(v, dict))
        rates = speed.get(kind)
        rate_cells = (f"{rates['pressure_drop']:,.0f} | {rates['force']:,.0f}" if rates
                      else "– | –")
        lines.append(f"| {LABELS[kind]} | {m['total']} ({in_range} in range, {outside} outside) "
                     f"| {rate_cells} | {training[kind]:.1f} |")
    return "\n".join(lines)


def figures(samples, valve, maps: dict) -> dict[str, Figure]:
    """C_d(Re, u) and flow-force maps with the samples over them, per map kind."""
    frame = samples.frame[splits.main_set(samples.frame)]
    spec = FeatureSpec.for_valve(valve)
    data = targets(spec, frame)
    openings = np.unique(frame["u"].round(9))
    colours = dict(zip(openings, ("C0", "C1", "C2", "C3", "C4", "C5", "C6")))
    result = {}

    cd, axes_cd = _panels("Discharge coefficient C_d(Re_q, u) at p_B = 5 bar: maps (lines) "
                          "and CFD samples (dots)")
    ff, axes_ff = _panels("Flow-force fraction α = f_ff/(A_L·Δp) at p_B = 5 bar: maps (lines) "
                          "and CFD samples (dots)")
    q = np.geomspace(0.3, 14.0, 120) * LPM
    for (kind, (flow_map, force_map)), ax_cd, ax_ff in zip(maps.items(), axes_cd, axes_ff):
        for u in openings:
            for temperature, style in ((20.0, ":"), (40.0, "-"), (60.0, "--")):
                fluid = valve.oil.state(np.full(q.shape, temperature + ZERO_CELSIUS))
                dp = flow_map.pressure_drop(q, 5 * BAR, u, fluid)
                discharge = np.sqrt(spec.orifice_pressure_drop(q, u, fluid.rho) / dp)
                reynolds = 2 * q / (valve.w * fluid.nu)
                ax_cd.plot(reynolds, discharge, style, color=colours[u], linewidth=1)
                alpha = (force_map.force(5 * BAR + dp, 5 * BAR, u, fluid)
                         - spec.uniform_force(5 * BAR + dp, 5 * BAR)) / (valve.A_L * dp)
                ax_ff.plot(from_si(q, "L/min"), alpha, style, color=colours[u], linewidth=1)
        for u in openings:
            at = np.isclose(frame["u"], u)
            ax_cd.plot(np.exp(data.flow_features[at, 0]), np.exp(data.log_discharge[at]), "o",
                       color=colours[u], markersize=3, label=f"u = {from_si(u, 'mm'):g} mm")
            ax_ff.plot(from_si(frame["q"][at], "L/min"), data.flow_force_fraction[at], "o",
                       color=colours[u], markersize=3, label=f"u = {from_si(u, 'mm'):g} mm")
        ax_cd.set(xscale="log", xlabel="Re_q = 2q/(w·ν)", ylabel="C_d", title=LABELS[kind])
        ax_ff.set(xlabel="q [L/min]", ylabel="α", title=LABELS[kind])
    axes_cd[0].legend(fontsize=7, title="20 °C dotted, 40 solid, 60 dashed", title_fontsize=7)
    axes_ff[0].legend(fontsize=7)
    result["cd_maps"], result["flow_force_maps"] = cd, ff
    return result


def parity_figure(samples, valve, holdout_maps: dict) -> Figure:
    """Predicted against CFD on the 20 % hold-out, for q and for the flow force."""
    frame = samples.frame[splits.holdout_mask(samples.frame)]
    fluid = FluidState(frame["nu"].to_numpy(), frame["rho"].to_numpy())
    state = (frame["p_L"].to_numpy(), frame["p_B"].to_numpy(), frame["u"].to_numpy(), fluid)
    uniform = state[0] * valve.A_L + state[1] * (valve.A_s3 - valve.A_B)
    figure = Figure(figsize=(10, 4.5), layout="constrained")
    ax_q, ax_f = figure.subplots(1, 2)
    for kind, (flow_map, force_map), marker in zip(holdout_maps, holdout_maps.values(), "so^"):
        ax_q.plot(from_si(frame["q"], "L/min"), from_si(flow_map.flow(*state), "L/min"), marker,
                  fillstyle="none", label=LABELS[kind])
        ax_f.plot(frame["f_sim"] - uniform, force_map.force(*state) - uniform, marker,
                  fillstyle="none", label=LABELS[kind])
    for axes, name in ((ax_q, "q [L/min]"), (ax_f, "flow force f_ff [N]")):
        low, high = axes.get_xlim()
        axes.plot([low, high], [low, high], "k-", linewidth=0.8)
        axes.set(xlabel=f"CFD {name}", ylabel=f"predicted {name}")
        axes.legend()
        axes.grid(alpha=0.3)
    figure.suptitle("Parity on the 20 % hold-out (a)")
    return figure


def _panels(title: str):
    figure = Figure(figsize=(15, 4.8), layout="constrained")
    axes = figure.subplots(1, 3, sharey=True)
    for ax in axes:
        ax.grid(alpha=0.3)
    figure.suptitle(title)
    return figure, axes


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("results/surrogates"))
    parser.add_argument("--workers", type=int, default=min(2, os.cpu_count() or 1))
    parser.add_argument("--states", type=int, default=100_000)
    args = parser.parse_args()

    valve = load_valve()
    samples = load_cfd_samples(SHIPPED_CFD_SAMPLES)
    cases = experiments(samples.frame)
    print(f"{len(cases)} tests × {len(KINDS)} map kinds, {args.workers} worker(s)", flush=True)
    with ProcessPoolExecutor(args.workers) as pool:
        results = list(pool.map(run_case, cases))

    print("monotonicity and throughput on the committed maps", flush=True)
    states = random_states(args.states)
    committed = {kind: build_maps(kind, valve) for kind in KINDS}
    train = ~splits.holdout_mask(samples.frame)
    free_flow, free_force, free_seconds = fit("nn-free", samples, valve, train)
    monotonicity = {kind: violations(*maps, states) for kind, maps in committed.items()}
    monotonicity["nn-free"] = violations(free_flow, free_force, states)
    speed = {kind: throughput(*maps, states) for kind, maps in committed.items()}
    holdout = next(r for r in results if r["experiment"] == "a")
    training = {kind: holdout[kind]["training_seconds"] for kind in KINDS}
    training["nn-free"] = free_seconds

    table = summary_table(results, monotonicity, speed, training)
    document = {"tests": results, "monotonicity": monotonicity, "throughput": speed,
                "training_seconds": training}
    with atomic_directory(args.out) as staging:
        (staging / "surrogates.md").write_text(table + "\n")
        (staging / "surrogates.json").write_text(json.dumps(document, indent=2) + "\n")
        for stem, figure in figures(samples, valve, committed).items():
            figure.savefig(staging / f"{stem}.png", dpi=120)
        grid_flow, grid_force, _ = fit("grid", samples, valve, train)  # without the hold-out
        holdout_maps = {"grid": (grid_flow, grid_force), "nn": committed["nn"],
                        "gp": committed["gp"]}
        parity_figure(samples, valve, holdout_maps).savefig(staging / "parity_holdout.png",
                                                            dpi=120)
    print(table)
    print(f"written to {args.out}")


if __name__ == "__main__":
    main()
