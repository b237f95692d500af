"""How closely a fit's map tables reproduce the maps they stand for (:mod:`surrogate.solver.map_tables`).

For each map kind, CFDA on those maps replays the shipped bench log once; every sample's map part
is tabulated around its friction band, as a fit tabulates it, and then compared with the maps
asked directly at random openings inside each sample's table: the pressure drop Δp and the flow
force f_ff, relative, and what an error of f_ff means for Δp through the balance (f_ff / A_L, in
bar). Also the CPU time of tabulating against one replay.

Then what a fit sees: the whole log replayed from the tables (a guess, no diagnostics) against
the same replay asking the maps, for CFDA and for CFDA with an effect that changes the flow the
maps are asked about (a flowmeter gain of 3 %, a laminar leak; read from the tables' expansions
on smooth maps, from the maps on a grid's): the RMS and the largest difference of Δp, and the
share of samples more than 10 mbar apart (mostly samples that flip between sticking and sliding
on a hair's difference).

    python eval/map_tables_accuracy.py              # grid, nn and gp
    python eval/map_tables_accuracy.py --kinds grid
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from surrogate.description import presets  # noqa: E402
from surrogate.data import load_bench_log  # noqa: E402
from surrogate.fitting.residuals import replay_log  # noqa: E402
from surrogate.core.paths import SHIPPED_BENCH_LOG  # noqa: E402
from surrogate.points import OperatingPoints  # noqa: E402
from surrogate.solver.map_tables import MapTables  # noqa: E402
from surrogate.core.units import BAR  # noqa: E402


def accuracy(kind: str, level: int = 0, seed: int = 0) -> dict:
    model = presets.cfda(maps_spec=presets.maps(kind)).build()
    log = load_bench_log(SHIPPED_BENCH_LOG)
    start = time.process_time()
    log_replay = replay_log(model, log, diagnostics=False)
    replay_cpu = time.process_time() - start
    points = model.true_points(OperatingPoints.from_bench(log.frame))
    tables = MapTables(model)
    start = time.process_time()
    tables.tabulate(model, points, log_replay.replay.band)
    tabulate_cpu = time.process_time() - start
    view = tables.view(points)
    held = np.flatnonzero(view.row >= 0)
    rng = np.random.default_rng(seed)
    # a random opening in each sample's window of the level asked for
    snapshot = view.levels[level]
    start = snapshot.first[view.row[held]]
    low = snapshot.nodes[start]
    high = snapshot.nodes[start + snapshot.count[view.row[held]] - 1]
    u = np.exp(low + (high - low) * rng.random(held.size))
    dp, flow_force, inside = view[held].lookup(u, coarsest=level)
    sub = points[held]
    dp_maps, force_maps = model.map_part(u, sub, model.fluid(sub))
    dp_error = np.abs(dp / dp_maps - 1)
    force_error = np.abs(flow_force - force_maps)
    relative_force = force_error / np.maximum(np.abs(force_maps), 1e-3)
    return {"kind": kind, "level": level, "samples": held.size, "nodes": tables.size,
            "inside": float(inside.mean()), "replay_cpu": replay_cpu,
            "tabulate_cpu": tabulate_cpu,
            "dp_median": float(np.median(dp_error)), "dp_max": float(dp_error.max()),
            "force_median": float(np.median(relative_force)),
            "force_p99": float(np.quantile(relative_force, 0.99)),
            "force_as_dp_max_bar": float(force_error.max() / model.valve.A_L / BAR),
            "beyond_mbar": float(np.mean(np.maximum(np.abs(dp - dp_maps), force_error
                                                    / model.valve.A_L) > 1e-3 * BAR))}


def replays(kind: str) -> list[dict]:
    """Tabulated against asked replays of the shipped log, with and without flow effects."""
    from surrogate.effects import LIBRARY
    base = presets.cfda(maps_spec=presets.maps(kind)).build()
    log = load_bench_log(SHIPPED_BENCH_LOG)
    found = []
    for name, values in ((None, {}), ("flowmeter_gain", {"g": 0.03}),
                         ("laminar_leakage", {"G": None})):
        model = base
        if name is not None:
            effect = LIBRARY[name]()
            for key, value in values.items():
                parameter = effect.params[key]
                parameter.value = (value if value is not None
                                   else parameter.min + 0.1 * (parameter.max - parameter.min))
            model = base.with_effects([*base.effects, effect])
        start = replay_log(model, log, diagnostics=False)
        tabulated = replay_log(model, log, guess=start, diagnostics=False)
        asked = replay_log(model, log, guess=start, diagnostics=True)
        both = np.isfinite(tabulated.replay.dp) & np.isfinite(asked.replay.dp)
        difference = np.abs(tabulated.replay.dp[both] - asked.replay.dp[both]) / BAR
        found.append({"kind": kind, "effect": name or "(CFDA)",
                      "read": "tables" if tabulated.replay.tables is not None else "maps",
                      "rms_mbar": 1e3 * float(np.sqrt(np.mean(difference ** 2))),
                      "max_mbar": 1e3 * float(difference.max()),
                      "beyond_10_mbar": float(np.mean(difference > 1e-2))})
    return found


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--kinds", nargs="+", default=["grid", "nn", "gp"])
    parser.add_argument("--levels", nargs="+", type=int, default=[0, 1],
                        help="table levels to check (0 fine, 1 coarse)")
    args = parser.parse_args(argv)
    print(f"{'kind':5} {'level':>5} {'samples':>7} {'nodes':>8} {'tabulate/replay':>15} "
          f"{'Δp rel. med':>11} {'max':>8} {'f_ff rel. med':>13} {'p99':>8} "
          f"{'f_ff max as Δp':>15} {'> 1 mbar':>9}")
    for kind in args.kinds:
        for level in args.levels:
            r = accuracy(kind, level)
            print(f"{r['kind']:5} {r['level']:5d} {r['samples']:7d} {r['nodes']:8d} "
                  f"{r['tabulate_cpu'] / r['replay_cpu']:14.1f}× "
                  f"{r['dp_median']:11.1e} {r['dp_max']:8.1e} {r['force_median']:13.1e} "
                  f"{r['force_p99']:8.1e} {r['force_as_dp_max_bar']:11.1e} bar "
                  f"{r['beyond_mbar']:8.2%}")
    print()
    print(f"{'kind':5} {'effect':17} {'read':6} {'Δp RMS':>9} {'max':>9} {'> 10 mbar':>9}")
    for kind in args.kinds:
        for r in replays(kind):
            print(f"{r['kind']:5} {r['effect']:17} {r['read']:6} {r['rms_mbar']:6.2f} mbar "
                  f"{r['max_mbar']:6.0f} mbar {r['beyond_10_mbar']:9.2%}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
