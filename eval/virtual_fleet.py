"""A virtual fleet through the `fleet` command: parameters recovered, faults flagged, throughput.

The fleet (:mod:`surrogate.synthetic.batch`): ``--valves`` virtual valves of one design, each with
its own draws of Coulomb friction K1 and K2, spring preload F_cr, spring rate K_f and flow-force
scale, all on the design's CFD-size map mismatch (one draw for the whole fleet: the CFD errs for
the design), each bench run with its own sensor noise, on the shipped test sequence subsampled
(``--every``). About 5 % of the valves carry a fault the others lack: a seal friction growing with
|p_L − p_P| or a laminar leakage, 0.6 to 1.5 times its realistic size.

The model fitted to every valve is CFDA (flow-force scale, K1, K2) with a spring-preload offset
and a laminar leakage: each valve's friction, preload and leakage, as a valve maker asks. It is
run as a user runs it: ``python -m surrogate fleet`` in its own process, fit-only and (with
``--diagnose``) diagnosed.

Reported:

* recovered against drawn parameters, K1 and preload (F_cr + the fitted offset): Pearson
  correlation and bias (mean recovered − drawn), over the valves without a fault;
* faults flagged (share of the faulty valves) and false flags (share of the others): flagged is
  an outlier of the fit-only fleet, or, with ``--diagnose``, also a significant finding of the
  fault's kind (friction, leakage) by the valve's diagnosis;
* throughput of the fit-only fleet on ``--throughput-valves`` of the valves, in valves per
  minute: local pool with 1 and with 2 workers, and a ``distributed.LocalCluster`` of 2 worker
  processes of 1 thread, as Dask starts them and with the workers' glibc trim threshold raised
  (docs/fleet.md), as ratios to the 1-worker pool, from the same run. Each is timed from the
  command's start to its end (worker start-up included; the cluster itself is started before,
  as a user's cluster is), with the cores the run kept busy.

Targets (issue 30): K1 and preload correlation >= 0.9; >= 90 % of the faults flagged with <= 2 %
false flags; >= 1.7x from 1 to 2 workers.

Writes OUT/logs/ (the virtual logs), OUT/fit/ and OUT/diagnose/ (the command's outputs),
OUT/throughput/ and OUT/fleet_eval.json. Run:
``python eval/virtual_fleet.py [--valves 200] [--every 8] [--diagnose] [--throughput-valves 60]``
(200 valves: about 6 minutes fit-only, 20 with --diagnose, on 2 cores).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

from surrogate.data import load_bench_log, load_cfd_samples
from surrogate.data.writer import write_bench_log
from surrogate.effects import LIBRARY
from surrogate.core.paths import SHIPPED_BENCH_LOG, SHIPPED_CFD_SAMPLES
from surrogate.description.presets import preset
from surrogate.description.spec import EffectSpec
from surrogate.synthetic.batch import draw_fleet, virtual_log
from surrogate.synthetic.simulate import noise_free_sequence, reference_spec

#: the model every valve is fitted with: CFDA, a spring-preload offset and a laminar leakage
MODEL_EFFECTS = ("spring_preload_offset", "laminar_leakage")
#: [bytes] the glibc trim threshold the tuned LocalCluster's workers get (docs/fleet.md)
WORKER_TRIM_THRESHOLD = 1 << 27
#: the kind of finding that flags each fault
FAULT_KINDS = {"friction_seal_pressure": "friction", "laminar_leakage": "leakage"}


def write_fleet(out: Path, valves: int, every: int, seed: int) -> tuple[list, Path]:
    """The virtual logs in OUT/logs (made anew) and the model file; returns the valves and the
    model file's path."""
    logs = out / "logs"
    shutil.rmtree(logs, ignore_errors=True)
    logs.mkdir(parents=True)
    sequence = noise_free_sequence(load_bench_log(SHIPPED_BENCH_LOG), every=every)
    samples = load_cfd_samples(SHIPPED_CFD_SAMPLES)
    fleet = draw_fleet(valves, seed=seed)
    began = time.perf_counter()
    for valve in fleet:
        write_bench_log(virtual_log(valve, sequence, samples, mismatch_seed=seed),
                        logs / f"{valve.serial}.csv")
    print(f"{valves} virtual logs of {len(sequence)} samples written in "
          f"{time.perf_counter() - began:.0f} s; faults: "
          + ", ".join(f"{v.serial} {v.fault}" for v in fleet if v.fault), flush=True)
    # the preset's start values, not the reference valve's: the fit must find each valve's own
    model = preset("cfda").adding(*(EffectSpec.start(LIBRARY.effect(name))
                                    for name in MODEL_EFFECTS), name="fleet model")
    path = out / "fleet_model.toml"
    model.write(path, "the model eval/virtual_fleet.py fits to every virtual valve")
    return fleet, path


def run_fleet(logs: Path | str, model: Path, out: Path, *extra: str) -> tuple[float, dict]:
    """``python -m surrogate fleet`` in its own process, into a fresh ``out``; (wall time [s],
    its JSON)."""
    shutil.rmtree(out, ignore_errors=True)
    command = [sys.executable, "-m", "surrogate", "fleet", "--data", str(logs), "--model",
               str(model), "--out", str(out), "--json", *extra]
    began = time.perf_counter()
    done = subprocess.run(command, check=False, capture_output=True, text=True,
                          env={**os.environ, "OMP_NUM_THREADS": "1"})
    seconds = time.perf_counter() - began
    if done.returncode not in (0, 3):
        raise SystemExit(f"{' '.join(command)} failed ({done.returncode}):\n{done.stderr[-3000:]}")
    return seconds, json.loads(done.stdout)


def recovery(fleet, table: pd.DataFrame, preload_model: float) -> dict:
    """Correlation and bias of the recovered K1 and preload against the drawn ones, over the
    valves without a fault."""
    drawn = pd.DataFrame([{"serial": v.serial, "K1": v.K1, "preload": v.preload,
                           "fault": v.fault} for v in fleet])
    merged = drawn.merge(table, on="serial")
    healthy = merged[merged["fault"].isna()]
    recovered = {"K1": healthy["friction_constant.K1 [N]"],
                 "preload": preload_model + healthy["spring_preload_offset.delta_F [N]"]}
    result = {}
    for name, values in recovered.items():
        truth = healthy[name]
        result[name] = {"correlation": round(float(np.corrcoef(truth, values)[0, 1]), 4),
                        "bias": round(float(np.mean(values - truth)), 4),
                        "rms_error": round(float(np.sqrt(np.mean((values - truth) ** 2))), 4),
                        "drawn_spread": round(float(np.std(truth)), 4), "valves": len(truth)}
    return result


def flags(fleet, outliers: set[str], table: pd.DataFrame | None) -> dict:
    """Shares of the faulty valves flagged and of the others falsely flagged: an outlier, or a
    finding of the fault's kind (with a diagnosis table)."""
    findings = {}
    if table is not None and "finding" in table:
        findings = {row.serial: row._asdict().get("finding_kind")
                    for row in table.rename(columns={"finding kind": "finding_kind"})
                    .itertuples() if isinstance(row.finding, str)}

    def flagged(valve) -> bool:
        if valve.serial in outliers:
            return True
        kinds = {FAULT_KINDS[valve.fault]} if valve.fault else set(FAULT_KINDS.values())
        return findings.get(valve.serial) in kinds

    faulty = [v for v in fleet if v.fault]
    healthy = [v for v in fleet if not v.fault]
    return {"faults": len(faulty), "faults_flagged": sum(map(flagged, faulty)),
            "faults_flagged_share": round(sum(map(flagged, faulty)) / max(len(faulty), 1), 4),
            "false_flags": sum(map(flagged, healthy)),
            "false_flag_share": round(sum(map(flagged, healthy)) / max(len(healthy), 1), 4),
            "missed": [f"{v.serial} {v.fault} {v.fault_values}" for v in faulty
                       if not flagged(v)],
            "false": [v.serial for v in healthy if flagged(v)]}


def _children_cpu() -> float:
    """CPU seconds [s] of this process's finished children and their own children."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def _say_throughput(rates: dict) -> None:
    print(f"throughput, fit-only, {rates['valves']} valves: {rates['valves_per_minute']} "
          f"valves/min; 2 workers / 1: {rates['ratio_2_to_1_workers']:.2f}x, LocalCluster(2) / "
          f"1 worker: {rates['ratio_cluster_to_1_worker']:.2f}x (with workers' "
          f"MALLOC_TRIM_THRESHOLD_ 128 MiB: {rates['ratio_tuned_cluster_to_1_worker']:.2f}x); "
          f"cores busy "
          f"{rates['cores_busy']}", flush=True)


def throughput(logs: Path, model: Path, out: Path, count: int) -> dict:
    """Valves per minute of the fit-only fleet on the first ``count`` logs: local pool with 1
    and 2 workers, and a LocalCluster of 2 single-threaded worker processes."""
    subset = out / "subset"
    shutil.rmtree(subset, ignore_errors=True)
    subset.mkdir(parents=True)
    for path in sorted(logs.glob("*.csv"))[:count]:
        shutil.copyfile(path, subset / path.name)
    seconds, cores = {}, {}
    for workers in (1, 2):
        name = f"local_{workers}"
        used = _children_cpu()
        seconds[name], _ = run_fleet(subset, model, out / name, "--workers", str(workers),
                                     "--quiet")
        cores[name] = (_children_cpu() - used) / seconds[name]
        print(f"  {count} valves on {workers} local worker(s): {seconds[name]:.1f} s, "
              f"{cores[name]:.2f} cores busy", flush=True)
    from distributed import LocalCluster

    # Dask's nanny starts its workers with MALLOC_TRIM_THRESHOLD_=65536 (unless the environment
    # sets it), so that they hand freed memory back at once; a fit's many mid-sized arrays then
    # cost page faults again and again (about 1.4x the time per valve, measured): the cluster
    # as Dask sets it up, and as docs/fleet.md advises starting the workers
    for name, trim in (("cluster_2", None), ("cluster_2_trim_128MiB", WORKER_TRIM_THRESHOLD)):
        kept = dict(os.environ)  # the nanny writes its workers' variables into ours
        if trim is not None:
            os.environ["MALLOC_TRIM_THRESHOLD_"] = str(trim)
        used, began = _children_cpu(), time.perf_counter()
        try:
            with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                              dashboard_address=None) as cluster:
                seconds[name], _ = run_fleet(subset, model, out / name, "--scheduler",
                                             cluster.scheduler_address, "--quiet")
        finally:
            os.environ.clear()
            os.environ.update(kept)
        # the cluster's workers are reaped when it closes: their CPU over its lifetime
        cores[name] = (_children_cpu() - used) / (time.perf_counter() - began)
        print(f"  {count} valves on a LocalCluster of 2 workers (MALLOC_TRIM_THRESHOLD_ "
              f"{trim or 'as Dask sets it'}): {seconds[name]:.1f} s, {cores[name]:.2f} cores "
              "busy", flush=True)
    rates = {name: 60.0 * count / value for name, value in seconds.items()}
    return {"valves": count, "seconds": {k: round(v, 1) for k, v in seconds.items()},
            # CPU the runs got per second of wall time: on a machine shared with other work the
            # scheduler may give a run fewer cores than it has workers (Linux's autogroups share
            # the CPU between sessions, not processes), and the ratios then say so
            "cores_busy": {k: round(v, 2) for k, v in cores.items()},
            "valves_per_minute": {k: round(v, 2) for k, v in rates.items()},
            "ratio_2_to_1_workers": round(rates["local_2"] / rates["local_1"], 3),
            "ratio_cluster_to_1_worker": round(rates["cluster_2"] / rates["local_1"], 3),
            "ratio_tuned_cluster_to_1_worker": round(rates["cluster_2_trim_128MiB"]
                                                     / rates["local_1"], 3),
            "ratio_cluster_to_2_workers": round(rates["cluster_2"] / rates["local_2"], 3)}


def draw(fleet, table: pd.DataFrame, cutoff: float, method: str, preload_model: float,
         path: Path) -> None:
    """The README's fleet figure: recovered against drawn K1 and preload, and every valve's
    robust distance against the cutoff, the faulty valves marked by their fault."""
    from matplotlib.figure import Figure

    drawn = pd.DataFrame([{"serial": v.serial, "K1": v.K1, "preload": v.preload,
                           "fault": v.fault or ""} for v in fleet]).merge(table, on="serial")
    styles = {"": ("tab:blue", ".", "no fault"),
              "friction_seal_pressure": ("tab:red", "s", "seal friction"),
              "laminar_leakage": ("tab:orange", "^", "leakage")}
    figure = Figure(figsize=(14, 4.4), layout="constrained")
    axes = figure.subplots(1, 3, width_ratios=[1, 1, 1.6])
    recovered = {"K1": ("friction_constant.K1 [N]", 0.0, "K1 [N]"),
                 "preload": ("spring_preload_offset.delta_F [N]", preload_model,
                             "preload F_cr [N]")}
    for ax, (name, (column, offset, unit)) in zip(axes[:2], recovered.items()):
        for fault, (colour, marker, text) in styles.items():
            rows = drawn[drawn["fault"] == fault]
            ax.plot(rows[name], offset + rows[column], marker, color=colour, label=text,
                    markersize=4 if fault == "" else 6)
        low, high = drawn[name].min(), drawn[name].max()
        ax.plot([low, high], [low, high], "-", color="0.5", linewidth=0.8)
        healthy = drawn[drawn["fault"] == ""]
        r = np.corrcoef(healthy[name], offset + healthy[column])[0, 1]
        ax.set_title(f"{name}: recovered against drawn (r = {r:.3f})", fontsize=10)
        ax.set_xlabel(f"drawn {unit}")
        ax.set_ylabel(f"fitted {unit}")
    axes[0].legend(fontsize=8)
    ax = axes[2]
    position = np.arange(len(drawn))
    for fault, (colour, marker, text) in styles.items():
        rows = drawn["fault"] == fault
        ax.plot(position[rows], drawn["robust distance"][rows], marker, color=colour,
                label=text, markersize=4 if fault == "" else 6)
    ax.axhline(cutoff, color="k", linestyle="--", linewidth=0.8, label="outlier cutoff")
    ax.set_yscale("log")
    ax.set_xlabel("valve")
    ax.set_ylabel("robust distance from the fleet")
    short = {"minimum covariance determinant": "MCD"}.get(method, method)
    ax.set_title(f"Robust distance of each of {len(drawn)} valves from the fleet ({short})",
                 fontsize=10)
    ax.legend(fontsize=8)
    figure.savefig(path, dpi=110)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--valves", type=int, default=200)
    parser.add_argument("--every", type=int, default=8, help="keep every n-th sample")
    parser.add_argument("--seed", type=int, default=2030, help="the fleet's draws")
    parser.add_argument("--diagnose", action="store_true", help="run the diagnosed fleet too")
    parser.add_argument("--throughput-valves", type=int, default=60,
                        help="valves timed three ways (0: skip)")
    parser.add_argument("--workers", type=int, default=2, help="for the main runs")
    parser.add_argument("--out", default="results/fleet")
    parser.add_argument("--throughput-only", action="store_true",
                        help="only the throughput (the fleet's logs made anew)")
    parser.add_argument("--figure", help="write the README's fleet figure here "
                                         "(docs/figures/fleet.png)")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    fleet, model = write_fleet(out, args.valves, args.every, args.seed)
    preload_model = reference_spec().valve.parameters.F_cr
    if args.throughput_only:
        rates = throughput(out / "logs", model, out / "throughput", args.throughput_valves)
        _say_throughput(rates)
        (out / "throughput.json").write_text(json.dumps(rates, indent=2) + "\n")
        return
    seconds, fitted = run_fleet(out / "logs", model, out / "fit", "--workers",
                                str(args.workers), "--quiet")
    table = pd.read_csv(out / "fit" / "valves.csv")
    outliers = {o["serial"] for o in fitted["outliers"]}
    summary = {"valves": args.valves, "every": args.every, "seed": args.seed,
               "samples_per_log": int(table["samples"].median()),
               "fit_seconds": round(seconds, 1), "failed": fitted["failed"],
               "recovery": recovery(fleet, table, preload_model),
               "flags_fit_only": flags(fleet, outliers, None),
               "outliers": fitted["outliers"]}
    print(f"fit-only fleet of {args.valves} valves on {args.workers} workers: {seconds:.0f} s; "
          + "; ".join(f"{name}: correlation {r['correlation']:.3f}, bias {r['bias']:+.3f} "
                      f"(drawn spread {r['drawn_spread']:.2f})"
                      for name, r in summary["recovery"].items()), flush=True)
    result = summary["flags_fit_only"]
    print(f"  fit-only: {result['faults_flagged']} of {result['faults']} faults flagged "
          f"({result['faults_flagged_share']:.0%}), {result['false_flags']} false flags "
          f"({result['false_flag_share']:.1%}); missed {result['missed']}", flush=True)
    if args.diagnose:
        seconds, diagnosed = run_fleet(out / "logs", model, out / "diagnose", "--diagnose",
                                       "--workers", str(args.workers), "--quiet")
        diagnosed_table = pd.read_csv(out / "diagnose" / "valves.csv")
        summary["diagnose_seconds"] = round(seconds, 1)
        summary["flags_diagnosed"] = result = flags(
            fleet, {o["serial"] for o in diagnosed["outliers"]}, diagnosed_table)
        summary["findings"] = diagnosed["population"].get("findings", {})
        print(f"  with --diagnose ({seconds:.0f} s): {result['faults_flagged']} of "
              f"{result['faults']} faults flagged ({result['faults_flagged_share']:.0%}), "
              f"{result['false_flags']} false flags ({result['false_flag_share']:.1%}); "
              f"findings {summary['findings']}; missed {result['missed']}", flush=True)
    if args.throughput_valves:
        summary["throughput"] = rates = throughput(out / "logs", model, out / "throughput",
                                                   args.throughput_valves)
        _say_throughput(rates)
    if args.figure:
        judged = fitted["population"]["outliers"]
        draw(fleet, table, judged["cutoff"], judged["method"], preload_model, Path(args.figure))
    (out / "fleet_eval.json").write_text(json.dumps(summary, indent=2) + "\n")


if __name__ == "__main__":
    main()
