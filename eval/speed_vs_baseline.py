"""Speed of diagnose and the workflow against an earlier version of the package, in one run.

Issue 26 (shape-free terms beside the library) must keep diagnose and the workflow within 1.5x
of the version before it, on 2 cores, for the shipped log's 11,000 samples. This script checks
that version out into a temporary folder (``git worktree``), then runs each command as its own
process from the current checkout (A) and from the baseline (B) in turn — A B A B ... — so that
a machine whose speed drifts moves both alike, and reports the median of the pairwise ratios
A/B with the medians of each. Both processes read the same shipped files.

Run: ``python eval/speed_vs_baseline.py [--baseline 42ba9e0] [--runs 3] [--commands diagnose
workflow]`` (the workflow takes a few minutes a run: about 40 minutes for three pairs of each).
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
#: the last commit before issue 26's work: seals merged, no shape-free terms
BASELINE = "42ba9e0"

COMMANDS = {
    "diagnose": ["diagnose", "--model", "cfda", "--data", "measurements/bench_measurements.csv",
                 "--json"],
    "workflow": ["workflow", "--data", "measurements/bench_measurements.csv", "--maps", "gp",
                 "--out", "{out}"],
}


def timed_run(checkout: Path, arguments: list[str], scratch: Path) -> float:
    """Seconds of one ``python -m surrogate ARGUMENTS`` run from ``checkout`` (its package
    first on the path, whatever is installed)."""
    out = scratch / f"out-{time.monotonic_ns()}"
    command = [sys.executable, "-c", "import sys, runpy; sys.path.insert(0, sys.argv.pop(1)); "
               "runpy.run_module('surrogate', run_name='__main__')", str(checkout),
               *[argument.format(out=out) for argument in arguments]]
    environment = {**os.environ, "PYTHONDONTWRITEBYTECODE": "1"}
    began = time.perf_counter()
    done = subprocess.run(command, cwd=ROOT, env=environment, stdout=subprocess.DEVNULL,
                          stderr=subprocess.PIPE, text=True)
    seconds = time.perf_counter() - began
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(arguments)} from {checkout} failed:\n{done.stderr[-2000:]}")
    return seconds


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
                    print(f"  {name} pair {number + 1}: now {now:.1f} s, baseline {then:.1f} s "
                          f"(x{now / then:.2f})", flush=True)
                ratio = statistics.median(now / then for now, then in pairs)
                record["commands"][name] = {
                    "now_s": round(statistics.median(p[0] for p in pairs), 1),
                    "baseline_s": round(statistics.median(p[1] for p in pairs), 1),
                    "ratio": round(ratio, 3), "pairs": pairs}
                print(f"{name}: x{ratio:.2f} the baseline's time (median of {len(pairs)} "
                      "pairs; target <= 1.5)")
        finally:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force",
                            str(baseline)], check=False, capture_output=True)
    path = Path(args.out)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(record, indent=2) + "\n")


if __name__ == "__main__":
    main()
