"""Benchmark: exporting the workflow's final model in every format, and what the tables cost.

Times ``python -m surrogate export`` of the final model as FMU + tables (one tabulation serves
both) and as ONNX, each as its own process (what a user waits for), against one replay of the
shipped log measured in the same run (the baseline: the machine's speed today). Reports the
tables' resolution error on the shipped log (what the export itself measures: the tables' replay
against the solver's), the FMU's own error in FMPy against the solver's replay, on the log and on
smooth flow ramps across the valve's envelope that no log holds, and the ONNX
graphs' largest relative difference from the package on 10,000 random states.

The final model is ``results/workflow/final_model.toml`` when the workflow has been run
(``python -m surrogate workflow ...``), else the effects the workflow adds on the shipped log on
GP maps (README: the viscous and seal frictions and the back-pressure flow force, on CFDA) at
plausible values, said so in the output.

    python eval/export.py [--model FILE] [--out results/export] [--json]

Writes ``<out>/benchmark.json``; about 3 minutes on 2 cores.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from surrogate.data import load_bench_log
from surrogate.description.modelfile import load_model
from surrogate.core.paths import PROJECT_ROOT, SHIPPED_BENCH_LOG
from surrogate.points import OperatingPoints
from surrogate.solver.replay import replay
from surrogate.core.units import from_si

WORKFLOW_FINAL = PROJECT_ROOT / "results" / "workflow" / "final_model.toml"
TARGET_SECONDS = 120.0


def representative_model(folder: Path) -> Path:
    """A model file with the effects the workflow adds on GP maps (README), for when no
    workflow has been run."""
    from surrogate.effects import LIBRARY
    from surrogate.description.presets import preset
    from surrogate.description.spec import EffectSpec

    spec = preset("cfda-gp")
    for name, values in (("friction_viscous", {"K_nu": 2.7}),
                         ("friction_seal_pressure", {"K_LP": 0.05}),
                         ("back_pressure_flow_force", {"gamma": 0.01})):
        spec = spec.adding(EffectSpec.start(LIBRARY[name], **values),
                           name=f"{spec.name}+{name}")
    path = folder / "final_like.toml"
    spec.write(path, "the effects the workflow adds on the shipped log on GP maps, at plausible "
                     "values (eval/export.py)")
    return path


def timed_export(model: Path, formats: list[str], out: Path) -> tuple[float, dict]:
    """Wall time of one export process [s] and its export.json."""
    command = [sys.executable, "-m", "surrogate", "export", "--model", str(model), "--out",
               str(out), "--quiet"] + [a for f in formats for a in ("--format", f)]
    started = time.perf_counter()
    done = subprocess.run(command, capture_output=True, text=True)
    seconds = time.perf_counter() - started
    if done.returncode != 0:
        raise SystemExit(f"export failed ({done.returncode}): {done.stderr.strip()}")
    return seconds, json.loads((out / "export.json").read_text())


def fmu_error(fmu: Path, model, points: OperatingPoints, runs: np.ndarray) -> dict:
    """The FMU's Δp in FMPy against the solver's replay (classic play) [bar]."""
    from surrogate.export.fmu import simulate_log  # one simulation per run, from rest
    from surrogate.export.valve_only import valve_physics

    physics = valve_physics(model).model
    reference = replay(physics, points, runs, diagnostics=False)
    dp = simulate_log(str(fmu), points, runs)
    error = from_si(dp - reference.dp, "bar")
    ok = np.isfinite(error)
    return {"rms": round(float(np.sqrt(np.mean(error[ok] ** 2))), 4),
            "max": round(float(np.max(np.abs(error[ok]))), 4), "samples": int(ok.sum())}


def envelope_probe(model, points: OperatingPoints) -> tuple[OperatingPoints, np.ndarray]:
    """Smooth flow ramps at four corners of the valve's envelope, the export's default ranges
    (:func:`surrogate.export.envelope.probe_runs`): runs no log holds."""
    from surrogate.export.envelope import probe_runs, valve_envelope
    from surrogate.export.valve_only import valve_physics

    return probe_runs(valve_envelope(valve_physics(model).model, points))


def onnx_parity(kind: str) -> dict:
    """Largest relative difference of the ONNX graphs from the package on 10,000 states."""
    from surrogate.export.onnx_maps import parity, random_states
    from surrogate.maps.learned import load_learned_maps, trained_folder

    flow, force = load_learned_maps(trained_folder(kind))
    compared = parity(flow, force, random_states(flow.coverage))
    return {name: float(np.max(np.abs(found - value) / np.abs(value)))
            for name, (found, value) in compared.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--model", help="model file (default: the workflow's final model)")
    parser.add_argument("--out", default="results/export")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    scratch = Path(tempfile.mkdtemp(prefix="cbv-export-eval-"))
    if args.model:
        model_path, which = Path(args.model), args.model
    elif WORKFLOW_FINAL.is_file():
        model_path, which = WORKFLOW_FINAL, str(WORKFLOW_FINAL)
    else:
        model_path = representative_model(scratch)
        which = ("no results/workflow/final_model.toml: the effects the workflow adds on GP "
                 "maps at plausible values")
    print(f"model: {which}", file=sys.stderr)
    model = load_model(str(model_path))
    log = load_bench_log(SHIPPED_BENCH_LOG)
    points, runs = OperatingPoints.from_bench(log.frame), log.frame["run"].to_numpy()

    started = time.perf_counter()
    replay(model, points, runs, diagnostics=False)
    baseline = time.perf_counter() - started
    print(f"baseline, one replay of the shipped log: {baseline:.2f} s", file=sys.stderr)

    tables_seconds, tables = timed_export(model_path, ["fmu", "tables"], scratch / "fmu")
    print(f"export fmu + tables: {tables_seconds:.1f} s", file=sys.stderr)
    onnx_seconds = onnx = None
    kind = getattr(model.flow_map, "kind", "")
    if kind in ("nn", "gp"):
        onnx_seconds, onnx = timed_export(model_path, ["onnx"], scratch / "onnx")
        print(f"export onnx: {onnx_seconds:.1f} s", file=sys.stderr)
    (fmu,) = (scratch / "fmu").glob("*.fmu")
    result = {
        "model": which, "model_name": model.name, "cpus": os.cpu_count(),
        "baseline_replay_seconds": round(baseline, 3),
        "export_fmu_and_tables_seconds": round(tables_seconds, 2),
        "export_onnx_seconds": None if onnx_seconds is None else round(onnx_seconds, 2),
        "total_seconds": round(tables_seconds + (onnx_seconds or 0.0), 2),
        "total_in_replays": round((tables_seconds + (onnx_seconds or 0.0)) / baseline, 1),
        "target_seconds": TARGET_SECONDS,
        "table_nodes": tables["table_nodes"],
        "resolution_error_bar": tables["resolution_error_bar"],
        "envelope_error_bar": tables["envelope_error_bar"],
        "refinement": tables["refinement"],
        "fmu_against_replay_bar": fmu_error(fmu, model, points, runs),
        "fmu_on_runs_across_the_envelope_bar": fmu_error(fmu, model, *envelope_probe(model,
                                                                                     points)),
        "fmu_binary": tables["fmu"]["binary"],
        "onnx_largest_relative_difference": None if onnx is None else onnx_parity(kind),
    }
    (out / "benchmark.json").write_text(json.dumps(result, indent=2) + "\n")
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        print(f"exporting {model.name}: fmu + tables {tables_seconds:.1f} s, onnx "
              f"{onnx_seconds or 0:.1f} s; {result['total_seconds']:.1f} s in all = "
              f"{result['total_in_replays']:.1f} replays of the log ({baseline:.2f} s each); "
              f"target < {TARGET_SECONDS:.0f} s")
        error = result["resolution_error_bar"]
        print(f"table resolution error on the shipped log: {error['rms']:.3f} bar RMS, "
              f"{error['max']:.3f} bar at most ({error['rms_linear']:.3f} / "
              f"{error['max_linear']:.3f} bar interpolated linearly), {result['table_nodes']:,} "
              "nodes")
        fmu_found = result["fmu_against_replay_bar"]
        print(f"FMU (FMPy) against the replay: {fmu_found['rms']:.3f} bar RMS, "
              f"{fmu_found['max']:.3f} bar at most")
        across = result["fmu_on_runs_across_the_envelope_bar"]
        print(f"FMU (FMPy) against the solver on flow ramps across the valve's envelope: "
              f"{across['rms']:.3f} bar RMS, {across['max']:.3f} bar at most")
        print(f"refinement: {result['refinement']}")
        if onnx is not None:
            print("ONNX against the package, largest relative difference: "
                  + ", ".join(f"{k} {v:.1e}" for k, v in result[
                      "onnx_largest_relative_difference"].items()))
        print(f"wrote {out / 'benchmark.json'}")


if __name__ == "__main__":
    main()
