"""Big bench logs: rows per second and peak memory of check-data and compare, 10^4 to 2·10^6 rows.

A bench that logs at 1 kHz for an afternoon writes millions of rows. This script makes logs of
10^4, 10^5, 10^6 and 2·10^6 rows from the shipped one (its runs repeated under new run ids, each
copy's times shifted), runs ``check-data`` and ``compare`` on each as a separate process, and
prints wall time, rows per second and peak resident memory, with each size's time per row and
memory as ratios to those of 10^4 rows measured in the same run (time per row near 1: linear).

    python eval/big_logs.py                      # all four sizes
    python eval/big_logs.py --sizes 10000 100000 --commands check-data

Targets (issue 25): peak memory <= 1 GB at 2·10^6 rows, time linear in the rows.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from surrogate.core.paths import SHIPPED_BENCH_LOG  # noqa: E402

SIZES = (10_000, 100_000, 1_000_000, 2_000_000)
COMMANDS = ("check-data", "compare")


def write_big_log(path: Path, rows: int) -> None:
    """The shipped log's runs repeated under new run ids (``R01`` -> ``R01-c0007``) with their
    times shifted, cut at ``rows`` data rows."""
    lines = SHIPPED_BENCH_LOG.read_text().splitlines()
    header, body = lines[0], [line.split(",", 2) for line in lines[1:]]
    columns = header.split(",")
    assert columns[:2] == ["run", "time_s"], columns
    written = 0
    with path.open("w") as stream:
        stream.write(header + "\n")
        copy = 0
        while written < rows:
            shift = 1000.0 * copy
            for run, time_s, rest in body:
                if written == rows:
                    break
                stream.write(f"{run}-c{copy:04d},{float(time_s) + shift:.3f},{rest}\n")
                written += 1
            copy += 1


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=list(SIZES))
    parser.add_argument("--commands", nargs="+", choices=COMMANDS, default=list(COMMANDS))
    args = parser.parse_args(argv)
    results = []
    with tempfile.TemporaryDirectory() as folder:
        for rows in sorted(args.sizes):
            log = Path(folder) / f"log_{rows}.csv"
            write_big_log(log, rows)
            megabytes = log.stat().st_size / 1e6
            for name in args.commands:
                command = [sys.executable, "-m", "surrogate", name, str(log)] if name == \
                    "check-data" else [sys.executable, "-m", "surrogate", "compare", "--model",
                                       "cfda", "--data", str(log), "--out",
                                       str(Path(folder) / f"out_{rows}")]
                seconds, peak, code = measure_isolated(command)
                results.append((name, rows, megabytes, seconds, peak, code))
                print(f"{name:<11}{rows:>10,} rows ({megabytes:6.1f} MB): {seconds:8.1f} s, "
                      f"{rows / seconds:>10,.0f} rows/s, peak {peak:7.0f} MB, exit {code}",
                      flush=True)
    print("\nratios to the smallest size, measured in this run (time per row falls while the "
          "start-up of a few seconds weighs less;\nthe marginal time per row, between one size "
          "and the next, is what stays level when the time is linear in the rows):")
    print(f"{'command':<11}{'rows':>10}{'time/row':>10}{'marginal µs/row':>17}{'peak':>8}"
          f"{'peak MB':>9}")
    for name in args.commands:
        mine = [r for r in results if r[0] == name]
        base = mine[0]
        previous = None
        for _, rows, _, seconds, peak, _ in mine:
            per_row = (seconds / rows) / (base[3] / base[1])
            marginal = ("" if previous is None else
                        f"{1e6 * (seconds - previous[1]) / (rows - previous[0]):.1f}")
            print(f"{name:<11}{rows:>10,}{per_row:>10.2f}{marginal:>17}{peak / base[4]:>8.2f}"
                  f"{peak:>9.0f}")
            previous = (rows, seconds)
    return 0 if all(r[5] == 0 for r in results) else 1


def measure_isolated(command: list[str]) -> tuple[float, float, int]:
    """(wall time [s], peak RSS [MB], exit code): the command run under a fresh intermediate
    process, so that its peak memory is its own and not the largest of every child so far."""
    probe = ("import resource, subprocess, sys, time, json\n"
             "t = time.perf_counter()\n"
             "done = subprocess.run(sys.argv[1:], stdout=subprocess.DEVNULL, "
             "stderr=subprocess.PIPE, text=True)\n"
             "elapsed = time.perf_counter() - t\n"
             "peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024.0\n"
             "sys.stderr.write(done.stderr[-2000:] if done.returncode else '')\n"
             "print(json.dumps([elapsed, peak, done.returncode]))\n")
    done = subprocess.run([sys.executable, "-c", probe, *command], cwd=ROOT, text=True,
                          capture_output=True, env={**os.environ, "PYTHONPATH": str(ROOT)})
    if done.stderr:
        print(done.stderr, file=sys.stderr)
    seconds, peak, code = json.loads(done.stdout)
    return seconds, peak, code


if __name__ == "__main__":
    raise SystemExit(main())
