"""How often the steady solver returns the rule's equilibrium whatever its guess, on made-up
models whose force balance has several (:mod:`surrogate.solver.steady`, "Several equilibria").

Each model is the basic valve (orifice flow map, uniform-pressure force map) with constant
friction, a force bump f·exp(−(ln(u/u0)/w)²) of random size, place and width, and in half of them
a laminar leak (which keeps Δp, and h, bounded at small openings). At random flows, each side
(opening, no friction, closing) is sampled at 4,000 openings; where h changes sign more than once
the rule's equilibrium is read off the samples (opening and no friction: the first downward
crossing from a positive h at the floor, else none; closing: the stop where h >= 0 there, else
the last downward crossing). The point counts as right where the solver returns it (to 1 %)
from no guess and from a guess at each downward crossing. Run for the shipped check and for
others: ``python eval/equilibria.py [--models 120] [--factors 3 2,6 2,5,12 ""]``.
"""

from __future__ import annotations

import argparse

import numpy as np

from surrogate import load_valve
from surrogate.effects import ConstantFriction, LaminarLeakage, custom_effect
from surrogate.maps import OrificeFlowMap, UniformPressureForceMap
from surrogate.model import ValveModel
from surrogate.points import OperatingPoints
from surrogate.solver import solve_steady, steady


@custom_effect("force", units={"f": "N", "u0": "mm", "w": "1"})
def force_bump(state, f=0.0, u0=0.1, w=0.3):
    """A force f [N] around the opening u0, over a width w in ln u."""
    return f * np.exp(-(np.log(state.u / u0) / w) ** 2)


def share_right(models: int, seed: int = 1) -> tuple[int, int]:
    """(points with several equilibria, of them returned as the rule's whatever the guess)."""
    valve = load_valve()
    rng = np.random.default_rng(seed)
    stroke = valve.U_max
    grid = np.geomspace(1e-7 * stroke, stroke, 4000)
    several = right = 0
    for _ in range(models):
        leak = rng.random() < 0.5
        u0 = float(np.exp(rng.uniform(np.log(0.003), np.log(0.6))))
        w, f = float(rng.uniform(0.15, 0.8)), float(rng.uniform(-150, 150))
        effects = [ConstantFriction(K1=5.0), force_bump(f=f, u0=u0, w=w)]
        model = ValveModel(valve, OrificeFlowMap(0.4, valve.w), UniformPressureForceMap(valve),
                           effects + ([LaminarLeakage(G=0.05)] if leak else []))
        q = rng.uniform(1, 12, 8)
        points = OperatingPoints.from_display(np.repeat(q, 3), 53.0, 3.0, 40.0,
                                              np.tile([1, 0, -1], 8))
        n = len(points)
        sampled = points[np.repeat(np.arange(n), grid.size)]
        balance = model.balance(np.tile(grid, n), sampled, model.fluid(sampled))
        h = (balance.net_force - sampled.direction * balance.friction).reshape(n, grid.size)
        down = (h[:, :-1] > 0) & (h[:, 1:] <= 0)
        multi = np.flatnonzero((np.diff(np.sign(h), axis=1) != 0).sum(axis=1) > 1)
        if not multi.size:
            continue
        expected = np.full(n, np.nan)
        guesses = np.full((3, n), np.nan)
        for k in multi:
            crossings = grid[np.flatnonzero(down[k])]
            if points.direction[k] >= 0:
                expected[k] = crossings[0] if h[k, 0] > 0 and crossings.size else np.nan
            else:
                expected[k] = stroke if h[k, -1] >= 0 else (
                    crossings[-1] if crossings.size else np.nan)
            for i in range(3):
                if crossings.size:
                    guesses[i, k] = crossings[min(i, crossings.size - 1)]
        answers = np.array([solve_steady(model, points).u]
                           + [solve_steady(model, points, guess=g).u for g in guesses])
        for k in multi:
            several += 1
            right += bool(np.all(np.isclose(answers[:, k], expected[k], rtol=0.01)
                                 | (np.isnan(answers[:, k]) & np.isnan(expected[k]))))
    return several, right


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--models", type=int, default=120)
    parser.add_argument("--factors", nargs="*", default=["3", "2,6", ""],
                        help="the check's factors to try, comma-separated ('' for no check)")
    args = parser.parse_args()
    shipped = steady._RULE_FACTORS
    print("| check's factors | points with several equilibria | the rule's whatever the guess |")
    print("|---|---|---|")
    try:
        for factors in args.factors:
            steady._RULE_FACTORS = tuple(float(f) for f in factors.split(",") if f)
            several, right = share_right(args.models)
            label = factors or "none"
            if steady._RULE_FACTORS == shipped:
                label += " (shipped)"
            print(f"| {label} | {several} | {right} ({right / several:.0%}) |", flush=True)
    finally:
        steady._RULE_FACTORS = shipped


if __name__ == "__main__":
    main()
