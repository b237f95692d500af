"""Where the loop's time goes: a profile of diagnose, the workflow or one off-library log.

Issue 43 asks to measure before cutting. This runs one job under :mod:`cProfile` and counts
what the cost is made of, so that a change can be judged by what it removes:

* **balance points**: how many (sample, parameter set) force balances were evaluated
  (:meth:`surrogate.model.ValveModel.balance_at`, which every solve, replay and map-error gain
  goes through), and in how many calls;
* **map queries**: points asked of the flow map (Δp at a flow) and of the force map;
* **replays**: replays of a log or part of one (:func:`surrogate.fitting.residuals.replay_log`)
  and their samples;
* the functions with the most time of their own and the most cumulative time.

    python eval/profile_loop.py diagnose                 # diagnose --model cfda, shipped log
    python eval/profile_loop.py workflow --maps gp       # the main job's GP staircase
    python eval/profile_loop.py offlibrary --case 4245   # one shape-heavy off-library log

Writes results/profile/<job>.json (the counts and the top functions) and <job>.pstats (for
``snakeviz`` or ``python -m pstats``). CPU seconds throughout: the machine may be shared. The
job runs on one thread, since the profiler sees only the thread it runs in.
"""

from __future__ import annotations

import argparse
import cProfile
import io
import json
import pstats
import sys
import time
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from surrogate.core import parallel  # noqa: E402
from surrogate.data import load_bench_log  # noqa: E402
from surrogate.core.paths import SHIPPED_BENCH_LOG  # noqa: E402

TOP = 25


class Counts:
    """Counts of the expensive calls, by wrapping them in place for the run."""

    def __init__(self):
        self.calls, self.points = Counter(), Counter()
        self._undo = []

    def wrap(self, owner, name: str, label: str, size) -> None:
        original = getattr(owner, name)

        def counted(*args, **kwargs):
            self.calls[label] += 1
            self.points[label] += size(*args, **kwargs)
            return original(*args, **kwargs)

        setattr(owner, name, counted)
        self._undo.append((owner, name, original))

    def restore(self) -> None:
        for owner, name, original in reversed(self._undo):
            setattr(owner, name, original)

    def as_dict(self) -> dict:
        return {label: {"calls": self.calls[label], "points": self.points[label]}
                for label in sorted(self.calls)}


def instrument() -> Counts:
    import numpy as np

    import surrogate.fitting.residuals as residuals
    from surrogate.maps.base import FlowMap, ForceMap
    from surrogate.maps.grid import _FlowAtOpenings
    from surrogate.model import ValveModel

    counts = Counts()
    counts.wrap(ValveModel, "balance_at", "balance", lambda self, u, dp, *rest: np.size(dp))
    # every replay of a log goes through replay_log, which calls the solver's replay
    counts.wrap(residuals, "replay", "replay", lambda model, points, *rest, **kw: len(points))
    for cls in FlowMap.__subclasses__():
        if "pressure_drop" in vars(cls):
            counts.wrap(cls, "pressure_drop", "flow map", lambda self, q, *rest: np.size(q))
    # a grid prepared at fixed openings (a leak's split) answers its flows itself
    counts.wrap(_FlowAtOpenings, "__call__", "flow map", lambda self, q, *rest: np.size(q))
    for cls in ForceMap.__subclasses__():
        if "force" in vars(cls):
            counts.wrap(cls, "force", "force map", lambda self, p_L, *rest: np.size(p_L))
    return counts


def job(name: str, args) -> callable:
    """The work to profile, ready to run (inputs loaded outside the profile)."""
    if name == "diagnose":
        from surrogate.diagnosis.diagnose import diagnose
        from surrogate.fitting.logfit import fit_to_log
        from surrogate.description.modelfile import load_model

        log = load_bench_log(SHIPPED_BENCH_LOG)
        model = load_model("cfda")
        return lambda: diagnose(fit_to_log(model, log).model, log)
    if name == "workflow":
        from surrogate.description.presets import maps
        from surrogate.workbench.workflow import run_workflow

        log = load_bench_log(SHIPPED_BENCH_LOG)
        return lambda: run_workflow(log, maps_spec=maps(args.maps))
    from surrogate.effects import LIBRARY
    from surrogate.description.presets import maps
    from surrogate.synthetic.mismatch import MapMismatch
    from surrogate.synthetic.offlibrary import OFF_LIBRARY, off_library_suite
    from surrogate.synthetic.simulate import hidden_effect_case, noise_free_sequence
    from surrogate.workbench.workflow import run_workflow

    sequence = noise_free_sequence(load_bench_log(SHIPPED_BENCH_LOG), every=8)
    suite = {case.seed: case for case in off_library_suite(20, 10, 4242, 8)}
    case = suite[args.case]
    made = hidden_effect_case(case.hidden, case.values, sequence=sequence, seed=case.seed,
                              library=LIBRARY + OFF_LIBRARY, mismatch=MapMismatch(),
                              maps_under_test=maps(args.maps))
    return lambda: run_workflow(made.log, start=made.start, max_additions=3)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("job", choices=("diagnose", "workflow", "offlibrary"))
    parser.add_argument("--maps", default="gp", help="map kind of the workflow and the "
                                                      "off-library log (default gp)")
    parser.add_argument("--case", type=int, default=4245,
                        help="seed of the off-library case (default 4245, an extrusion friction)")
    parser.add_argument("--out", default=str(ROOT / "results" / "profile"))
    args = parser.parse_args(argv)
    work = job(args.job, args)
    # one thread: cProfile sees the thread it runs in only, and the counts are the same
    parallel.THREAD_LIMIT = 1
    counts = instrument()
    profile = cProfile.Profile()
    began = time.process_time()
    try:
        profile.runcall(work)
    finally:
        counts.restore()
    cpu = time.process_time() - began
    stats = pstats.Stats(profile)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    name = args.job if args.job == "diagnose" else f"{args.job}-{args.maps}" + (
        f"-{args.case}" if args.job == "offlibrary" else "")
    stats.dump_stats(out / f"{name}.pstats")

    def top(key: str) -> list[dict]:
        stats.sort_stats(key)
        rows = []
        for function in stats.fcn_list[:TOP]:
            calls, _, own_seconds, cumulative, _ = stats.stats[function]
            file, line, func = function
            rows.append({"function": f"{Path(file).name}:{line}({func})", "calls": calls,
                         "own s": round(own_seconds, 2), "cumulative s": round(cumulative, 2)})
        return rows

    report = {"job": name, "cpu seconds": round(cpu, 1), "counts": counts.as_dict(),
              "by own time": top("tottime"), "by cumulative time": top("cumulative")}
    (out / f"{name}.json").write_text(json.dumps(report, indent=2) + "\n")
    print(f"{name}: {cpu:.0f} s CPU (under the profiler, which slows it)")
    for label, entry in report["counts"].items():
        print(f"  {label:10s} {entry['calls']:>10,} calls {entry['points']:>14,} points")
    buffer = io.StringIO()
    stats.stream = buffer
    stats.sort_stats("tottime").print_stats(TOP)
    print(buffer.getvalue().split("\n", 6)[-1][:6000])
    print(f"wrote {out / (name + '.json')} and {name}.pstats")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
