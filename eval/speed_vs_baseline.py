"""Speed of diagnose and the workflow against an earlier version of the package, in one run.

Issue 43 asks for the main job and ``diagnose --model cfda`` on the shipped log's 11,000 samples
at least 5x less CPU than before it, the default workflow on the off-library suite's logs 8x
(median over the logs), peak memory no higher (issue 26 before it: within 1.5x). This script checks
that version out into a temporary folder (``git worktree``), then runs each command as its own
process from the current checkout (A) and from the baseline (B) in turn — A B A B ... — so that
a machine whose speed drifts moves both alike, and reports the median of the pairwise ratios
A/B with the medians of each, in CPU seconds (user + system of the command's process and its
threads: a machine that other work shares cannot hide or fake a gain in them), wall time and
peak resident memory beside. Both packages are byte-compiled first, as an installed one is after
its first command. Both processes read the same files: the shipped log, or for
``offlibrary`` the first ``--logs`` logs of ``eval/offlibrary.py``'s suite written as bench-log
files (``workflow --kinds`` on each, its main kind alone).

Run: ``python eval/speed_vs_baseline.py [--baseline 6de8049] [--runs 3] [--commands diagnose
workflow offlibrary] [--logs 5]`` (the workflow takes minutes a run at the baseline).
Writes results/speed_vs_baseline.json.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: main when issue 43 (speed) was filed, before any of its work
BASELINE = "6de8049"

COMMANDS = {
    "diagnose": ["diagnose", "--model", "cfda", "--data", "measurements/bench_measurements.csv",
                 "--json"],
    "workflow": ["workflow", "--data", "measurements/bench_measurements.csv", "--maps", "gp",
                 "--out", "{out}"],
    # the default workflow on its main kind alone (GP), on each of the off-library logs
    "offlibrary": ["workflow", "--data", "{log}", "--kinds", "--out", "{out}"],
}


def timed_run(checkout: Path, arguments: list[str], scratch: Path, log: Path | None = None
              ) -> tuple[float, float, float]:
    """CPU seconds, wall seconds and peak memory [MB] of one ``python -m surrogate ARGUMENTS``
    run from ``checkout`` (its package first on the path, whatever is installed); ``{log}`` in
    the arguments stands for ``log``."""
    out = scratch / f"out-{time.monotonic_ns()}"
    command = [sys.executable, "-c", "import sys, runpy; sys.path.insert(0, sys.argv.pop(1)); "
               "runpy.run_module('surrogate', run_name='__main__')", str(checkout),
               *[argument.format(out=out, log=log) for argument in arguments]]
    environment = {**os.environ, "PYTHONDONTWRITEBYTECODE": "1"}
    errors = scratch / f"stderr-{time.monotonic_ns()}"
    began = time.perf_counter()
    with errors.open("w") as stderr:
        process = subprocess.Popen(command, cwd=ROOT, env=environment,
                                   stdout=subprocess.DEVNULL, stderr=stderr)
        # this process's own resource use (its threads' CPU time, its peak resident memory)
        _, status, usage = os.wait4(process.pid, 0)
    seconds = time.perf_counter() - began
    if os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit(f"{' '.join(arguments)} from {checkout} failed:\n"
                         f"{errors.read_text()[-2000:]}")
    return usage.ru_utime + usage.ru_stime, seconds, usage.ru_maxrss / 1024.0


def off_library_logs(count: int, scratch: Path, every: int = 8) -> list[Path]:
    """The first ``count`` logs of the off-library suite (``eval/offlibrary.py``: one hidden
    effect per case, in the suite's order, every ``every``-th sample of the shipped sequence as
    the suite keeps, the virtual valve's CFD erring as a real one's), written as bench-log files
    that either checkout reads."""
    sys.path.insert(0, str(ROOT))  # the logs are made by the current checkout
    from surrogate.data import load_bench_log
    from surrogate.data.writer import write_bench_log
    from surrogate.effects import LIBRARY
    from surrogate.core.paths import SHIPPED_BENCH_LOG
    from surrogate.description.presets import maps
    from surrogate.synthetic.mismatch import MapMismatch
    from surrogate.synthetic.offlibrary import OFF_LIBRARY, off_library_suite
    from surrogate.synthetic.simulate import hidden_effect_case, noise_free_sequence

    sequence = noise_free_sequence(load_bench_log(SHIPPED_BENCH_LOG), every=every)
    paths = []
    for case in off_library_suite(count, 0, 4242)[:count]:
        made = hidden_effect_case(case.hidden, case.values, sequence=sequence, seed=case.seed,
                                  library=LIBRARY + OFF_LIBRARY, mismatch=MapMismatch(),
                                  maps_under_test=maps("gp"))
        paths.append(write_bench_log(made.log, scratch / f"{case.hidden}-{case.seed}.csv"))
    return paths


def which_package(checkout: Path) -> str:
    """Where ``surrogate`` is imported from when ``checkout`` is put first (a check that the
    baseline really runs its own code)."""
    code = ("import sys; sys.path.insert(0, sys.argv[1]); import surrogate; "
            "print(surrogate.__file__)")
    return subprocess.run([sys.executable, "-c", code, str(checkout)], capture_output=True,
                          text=True, check=True).stdout.strip()


def compile_package(checkout: Path) -> None:
    """Byte-compile ``checkout``'s package before any run is timed, as a user's installation is
    after its first command: otherwise a fresh checkout (the baseline's always, the current one
    when new) compiles every module again in every run, which no user pays, and only where its
    cache is missing."""
    subprocess.run([sys.executable, "-m", "compileall", "-q", str(checkout / "surrogate")],
                   check=True, capture_output=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--baseline", default=BASELINE, help="git revision to compare against")
    parser.add_argument("--runs", type=int, default=3, help="pairs of runs per command")
    parser.add_argument("--logs", type=int, default=5,
                        help="off-library logs for the offlibrary command (the suite's first)")
    parser.add_argument("--every", type=int, default=8,
                        help="keep every n-th sample of the off-library logs (the suite's 8; 1: "
                        "the shipped log's length)")
    parser.add_argument("--commands", nargs="+", default=list(COMMANDS), choices=list(COMMANDS))
    parser.add_argument("--out", default="results/speed_vs_baseline.json")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        scratch = Path(folder)
        baseline = scratch / "baseline"
        subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", str(baseline),
                        args.baseline], check=True, capture_output=True)
        try:
            for checkout in (ROOT, baseline):
                where = which_package(checkout)
                if not where.startswith(str(checkout)):
                    raise SystemExit(f"{checkout} imports surrogate from {where}")
                compile_package(checkout)
            record = {"baseline": args.baseline, "cores": os.cpu_count(), "commands": {}}
            for name in args.commands:
                pairs = []
                logs = (off_library_logs(args.logs, scratch, args.every)
                        if name == "offlibrary" else [None])
                for number in range(args.runs):
                    for log in logs:
                        now = timed_run(ROOT, COMMANDS[name], scratch, log)
                        then = timed_run(baseline, COMMANDS[name], scratch, log)
                        pairs.append((now, then))
                        print(f"  {name}{'' if log is None else ' ' + log.stem} run "
                              f"{number + 1}: now {now[0]:.1f} s CPU ({now[1]:.1f} s wall, "
                              f"{now[2]:.0f} MB), baseline {then[0]:.1f} s CPU ({then[1]:.1f} "
                              f"s wall, {then[2]:.0f} MB) (x{now[0] / then[0]:.2f} CPU)",
                              flush=True)
                ratio = statistics.median(now[0] / then[0] for now, then in pairs)
                record["commands"][name] = {
                    "now_cpu_s": round(statistics.median(p[0][0] for p in pairs), 1),
                    "baseline_cpu_s": round(statistics.median(p[1][0] for p in pairs), 1),
                    "now_wall_s": round(statistics.median(p[0][1] for p in pairs), 1),
                    "baseline_wall_s": round(statistics.median(p[1][1] for p in pairs), 1),
                    "cpu_ratio": round(ratio, 3),
                    "wall_ratio": round(statistics.median(now[1] / then[1]
                                                          for now, then in pairs), 3),
                    "now_peak_mb": round(max(p[0][2] for p in pairs)),
                    "baseline_peak_mb": round(max(p[1][2] for p in pairs)),
                    "pairs_cpu_wall_s": pairs}
                print(f"{name}: x{ratio:.2f} the baseline's CPU time (median of {len(pairs)} "
                      f"pairs); peak memory {record['commands'][name]['now_peak_mb']} MB "
                      f"against {record['commands'][name]['baseline_peak_mb']} MB")
        finally:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force",
                            str(baseline)], check=False, capture_output=True)
    path = Path(args.out)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(record, indent=2) + "\n")


if __name__ == "__main__":
    main()
