"""Speed of diagnose and the workflow against an earlier version of the package, in one run.

Issue 26 (shape-free terms beside the library) must keep diagnose and the workflow within 1.5x
of the version before it, on 2 cores, for the shipped log's 11,000 samples. This script checks
that version out into a temporary folder (``git worktree``), then runs each command as its own
process from the current checkout (A) and from the baseline (B) in turn — A B A B ... — so that
a machine whose speed drifts moves both alike, and reports the median of the pairwise ratios
A/B with the medians of each, in CPU seconds (user + system of the command's process and its
threads: a machine that other work shares cannot hide or fake a gain in them), wall time
beside. Both processes read the same shipped files.

Run: ``python eval/speed_vs_baseline.py [--baseline 42ba9e0] [--runs 3] [--commands diagnose
workflow]`` (the workflow takes a few minutes a run: about 40 minutes for three pairs of each).
Writes results/speed_vs_baseline.json.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: the last commit before issue 26's work: seals merged, no shape-free terms
BASELINE = "42ba9e0"

COMMANDS = {
    "diagnose": ["diagnose", "--model", "cfda", "--data", "measurements/bench_measurements.csv",
                 "--json"],
    "workflow": ["workflow", "--data", "measurements/bench_measurements.csv", "--maps", "gp",
                 "--out", "{out}"],
}


def timed_run(checkout: Path, arguments: list[str], scratch: Path) -> tuple[float, float]:
    """CPU seconds and wall seconds of one ``python -m surrogate ARGUMENTS`` run from
    ``checkout`` (its package first on the path, whatever is installed)."""
    out = scratch / f"out-{time.monotonic_ns()}"
    command = [sys.executable, "-c", "import sys, runpy; sys.path.insert(0, sys.argv.pop(1)); "
               "runpy.run_module('surrogate', run_name='__main__')", str(checkout),
               *[argument.format(out=out) for argument in arguments]]
    environment = {**os.environ, "PYTHONDONTWRITEBYTECODE": "1"}
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    began = time.perf_counter()
    done = subprocess.run(command, cwd=ROOT, env=environment, stdout=subprocess.DEVNULL,
                          stderr=subprocess.PIPE, text=True)
    seconds = time.perf_counter() - began
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(arguments)} from {checkout} failed:\n{done.stderr[-2000:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return cpu, seconds


def which_package(checkout: Path) -> str:
    """Where ``surrogate`` is imported from when ``checkout`` is put first (a check that the
    baseline really runs its own code)."""
    code = ("import sys; sys.path.insert(0, sys.argv[1]); import surrogate; "
            "print(surrogate.__file__)")
    return subprocess.run([sys.executable, "-c", code, str(checkout)], capture_output=True,
                          text=True, check=True).stdout.strip()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--baseline", default=BASELINE, help="git revision to compare against")
    parser.add_argument("--runs", type=int, default=3, help="pairs of runs per command")
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
            record = {"baseline": args.baseline, "cores": os.cpu_count(), "commands": {}}
            for name in args.commands:
                pairs = []
                for number in range(args.runs):
                    now = timed_run(ROOT, COMMANDS[name], scratch)
                    then = timed_run(baseline, COMMANDS[name], scratch)
                    pairs.append((now, then))
                    print(f"  {name} pair {number + 1}: now {now[0]:.1f} s CPU ({now[1]:.1f} s "
                          f"wall), baseline {then[0]:.1f} s CPU ({then[1]:.1f} s wall) "
                          f"(x{now[0] / then[0]:.2f} CPU)", flush=True)
                ratio = statistics.median(now[0] / then[0] for now, then in pairs)
                record["commands"][name] = {
                    "now_cpu_s": round(statistics.median(p[0][0] for p in pairs), 1),
                    "baseline_cpu_s": round(statistics.median(p[1][0] for p in pairs), 1),
                    "now_wall_s": round(statistics.median(p[0][1] for p in pairs), 1),
                    "baseline_wall_s": round(statistics.median(p[1][1] for p in pairs), 1),
                    "cpu_ratio": round(ratio, 3),
                    "wall_ratio": round(statistics.median(now[1] / then[1]
                                                          for now, then in pairs), 3),
                    "pairs_cpu_wall_s": pairs}
                print(f"{name}: x{ratio:.2f} the baseline's CPU time (median of {len(pairs)} "
                      "pairs)")
        finally:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force",
                            str(baseline)], check=False, capture_output=True)
    path = Path(args.out)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(record, indent=2) + "\n")


if __name__ == "__main__":
    main()
