"""Benchmark: the batch steady solver against a per-point brentq loop, and the bench-run replay.

Both solvers use the same CFDA model on the grid maps and the same tolerance on u, and are timed in
the same run on the same 10,000 random operating points spanning the bench tests (q 1–12 L/min,
p_Pe 40–130 bar, p_B 1–8 bar, 20–60 °C). The ratio of their rates is the speed-up; the two answers
are compared as well, so the speed is not bought with accuracy.

It also times the replay of the whole bench log with and without what the maps say about
themselves (the Δp standard deviation their uncertainty implies, and why samples lie outside
the CFD samples), on each kind of map: the ratio is the uncertainty's cost.

    python eval/bench_solver.py [--points 10000] [--loop-points 10000] [--repeats 3] [--json]
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np
from scipy.optimize import brentq

from surrogate import load_valve
from surrogate.data import load_bench_log
from surrogate.effects import FlowForceScale
from surrogate.model import ValveModel
from surrogate.core.paths import SHIPPED_BENCH_LOG
from surrogate.points import OperatingPoints
from surrogate.solver import Status, replay, solve_steady
from surrogate.description.presets import CFDA_START, cfda, maps
from surrogate.solver.steady import _OPENING_FLOOR, _U_RTOL
from surrogate.description.spec import EffectSpec, ModelSpec


def random_points(count: int, seed: int = 0) -> OperatingPoints:
    rng = np.random.default_rng(seed)
    p_B = rng.uniform(1.0, 8.0, count)
    return OperatingPoints.from_display(rng.uniform(1.0, 12.0, count),
                                        rng.uniform(40.0, 130.0, count) + p_B, p_B,
                                        rng.uniform(20.0, 60.0, count))


def solve_one_by_one(model: ValveModel, points: OperatingPoints) -> np.ndarray:
    """The baseline: scipy.optimize.brentq point by point on the same force balance."""
    fluid = model.fluid(points)
    stroke = model.valve.U_max
    floor = stroke * _OPENING_FLOOR
    u = np.full(len(points), np.nan)
    for i in range(len(points)):
        point, state = points[i:i + 1], fluid[i:i + 1]

        def net_force(x):
            return model.balance(np.array([x]), point, state).net_force[0]

        if net_force(stroke) >= 0:
            u[i] = stroke
        elif net_force(floor) > 0:
            u[i] = brentq(net_force, floor, stroke, xtol=stroke * 1e-30, rtol=_U_RTOL)
    return u


def best_time(function, repeats: int):
    times, result = [], None
    for _ in range(repeats):
        started = time.perf_counter()
        result = function()
        times.append(time.perf_counter() - started)
    return min(times), result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=10_000)
    parser.add_argument("--loop-points", type=int, default=10_000,
                        help="points for the (slow) brentq loop; its rate is compared")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--json", action="store_true", help="print the figures as JSON")
    args = parser.parse_args()

    valve = load_valve()
    with_friction = cfda().build()  # the paper's CFDA at its start values (CFDA_START)
    model = ModelSpec("CFDA", maps=ModelSpec.of(with_friction).maps,
                      effects=(EffectSpec.start(FlowForceScale, scale=CFDA_START["scale"]),)
                      ).build()
    points = random_points(args.points)

    batch_time, batch = best_time(lambda: solve_steady(model, points), args.repeats)
    loop_points = points[: args.loop_points]
    loop_time, loop_u = best_time(lambda: solve_one_by_one(model, loop_points), 1)
    batch_rate = args.points / batch_time
    loop_rate = args.loop_points / loop_time
    agreement = np.nanmax(np.abs(batch.u[: args.loop_points] - loop_u)) / valve.U_max

    log = load_bench_log(SHIPPED_BENCH_LOG)
    run = log.run("R06")
    run_points = OperatingPoints.from_bench(run.frame)
    run_time, _ = best_time(lambda: replay(with_friction, run_points), args.repeats)
    all_points = OperatingPoints.from_bench(log.frame)
    log_time, _ = best_time(lambda: replay(with_friction, all_points, log.frame["run"],
                                           diagnostics=False), args.repeats)
    # the cost of the Δp standard deviation (and extrapolation reasons) on every kind of map
    uncertainty = {}
    for kind in ("grid", "nn", "gp"):
        on_kind = cfda(maps_spec=maps(kind)).build()
        replay(on_kind, all_points, log.frame["run"])  # first use: the grid's calibration
        plain, _ = best_time(lambda: replay(on_kind, all_points, log.frame["run"],
                                            diagnostics=False), args.repeats)
        full, _ = best_time(lambda: replay(on_kind, all_points, log.frame["run"]),
                            args.repeats)
        uncertainty[kind] = {"plain_seconds": plain, "with_uncertainty_seconds": full,
                             "ratio": full / plain}

    figures = {
        "points": args.points,
        "batch_seconds": batch_time,
        "batch_points_per_second": batch_rate,
        "loop_points": args.loop_points,
        "loop_seconds": loop_time,
        "loop_points_per_second": loop_rate,
        "speedup": batch_rate / loop_rate,
        "max_u_difference_fraction_of_stroke": float(agreement),
        "batch_failures": int(np.sum(batch.status < 0)),
        "at_stop": int(np.sum(batch.status == Status.AT_STOP)),
        "replay_run_samples": len(run_points),
        "replay_run_seconds": run_time,
        "replay_log_samples": len(all_points),
        "replay_log_seconds": log_time,
        "replay_with_uncertainty": uncertainty,
    }
    if args.json:
        print(json.dumps(figures, indent=2))
        return
    print(f"steady solve, CFDA on grid maps, {args.points} points "
          f"({figures['at_stop']} at the stop, {figures['batch_failures']} failed)")
    print("| solver | points | time [s] | points/s |")
    print("|---|---|---|---|")
    print(f"| batch (this package) | {args.points} | {batch_time:.3f} | {batch_rate:,.0f} |")
    print(f"| per-point brentq loop | {args.loop_points} | {loop_time:.2f} | {loop_rate:,.0f} |")
    print(f"speed-up: {batch_rate / loop_rate:.0f}x (target >= 20x); "
          f"largest difference in u: {agreement:.1e} of the stroke")
    print(f"replay with friction: one run ({len(run_points)} samples) {run_time * 1e3:.0f} ms; "
          f"whole log ({len(all_points)} samples, 12 runs) {log_time:.2f} s")
    print("replay of the whole log with the Δp standard deviation and extrapolation reasons, "
          "against without (target <= 2x):")
    print("| maps | without [s] | with [s] | ratio |")
    print("|---|---|---|---|")
    for kind, row in uncertainty.items():
        print(f"| {kind} | {row['plain_seconds']:.2f} | {row['with_uncertainty_seconds']:.2f} | "
              f"{row['ratio']:.2f} |")


if __name__ == "__main__":
    main()
