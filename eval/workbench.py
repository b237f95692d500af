"""Benchmark of the measurement workbench on the shipped bench log, and its hidden-effect record.

Measures, in one run on this machine:

* one diagnose over the whole library on the full shipped log (12 runs, 11,000 samples),
  against the cost of one replay of the log measured in the same run, and against the same
  diagnose with the BLAS left free to start threads of its own beside the replays' threads
  (:data:`surrogate.core.parallel.BLAS_THREADS_IN_POOL`);
* the full workflow (paper's steps, then diagnose → add until nothing significant is left);
* the identification rate over randomised hidden-effect cases on the shipped test sequence;
* on a synthetic log with nothing hidden, the true model's RMS over the noise floor with the
  classic friction play and with the replay's smoothed friction state;
* under map mismatch (a virtual valve that differs from its CFD, :mod:`surrogate.workbench.
  mismatch`; the model under test on the shipped maps): the share of randomised hidden-effect
  cases the workflow finds cleanly (the hidden effect or its group, no other physics or sensor
  effect), or that leave nothing to find (nothing added or withheld, and the log ends as its
  twin with nothing hidden does, :mod:`surrogate.synthetic.visibility`; counted apart), and the
  physics or sensor effects it adds where nothing is hidden, over the stress
  suite of :func:`surrogate.synthetic.simulate.stress_suite` (``--mismatch-cases`` cases and
  ``--controls`` controls for each of its two settings seeds), with weak leakages (at most
  1.2x their realistic size, the suite's usual misses) counted apart.

Writes results/workbench/benchmark.json and prints a summary. Run:
``python eval/workbench.py [--cases 20] [--every 4] [--mismatch-cases 20] [--controls 5]
[--maps gp] [--mismatch-maps grid] [--mismatch-settings 2026 2027] [--only-mismatch]
[--gap FORCE DP] [--per-opening DP FORCE] [--only-weak-leakages] [--mismatch-folder DIR]``
(about 20 minutes on 2 cores).
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from surrogate.core import parallel
from surrogate.data import load_bench_log
from surrogate.diagnosis.diagnose import diagnose
from surrogate.diagnosis.result import Diagnosis
from surrogate.fitting.logfit import fit_to_log
from surrogate.fitting.residuals import (measured_dp, noise_floor, replay_log,
                                         state_smoothing_samples)
from surrogate.core.paths import SHIPPED_BENCH_LOG
from surrogate.points import OperatingPoints
from surrogate.description.presets import cfda, maps
from surrogate.reporting.documents import workflow_document
from surrogate.reporting.prose import summarise
from surrogate.solver import replay
from surrogate.synthetic.mismatch import MapMismatch
from surrogate.synthetic.simulate import (STRESS_SETTINGS, WEAK_LEAKAGE, hidden_effect_case,
                                          identified, noise_free_sequence, random_settings,
                                          run_stress_case, stress_suite, withheld_claims)
from surrogate.synthetic.visibility import over_floor
from surrogate.core.units import from_si
from surrogate.workbench.workflow import run_workflow


def timed(function, *args, **kwargs):
    start = time.perf_counter()
    value = function(*args, **kwargs)
    return value, time.perf_counter() - start


def diagnose_with_free_blas(model, log, base) -> tuple[Diagnosis, float]:
    """One diagnose with the BLAS's threads left as they are (the baseline of the pools' one
    BLAS thread each), and its seconds."""
    kept = parallel.BLAS_THREADS_IN_POOL
    parallel.BLAS_THREADS_IN_POOL = None
    try:
        return timed(diagnose, model, log, base=base)
    finally:
        parallel.BLAS_THREADS_IN_POOL = kept


def same_candidates(one: Diagnosis, other: Diagnosis) -> bool:
    """Whether two diagnoses rank the same candidates with bit-identical ΔBIC and RMS."""
    return [(c.name, c.delta_bic, c.rms_after) for c in one.candidates] == [
        (c.name, c.delta_bic, c.rms_after) for c in other.candidates]


def replay_noise_control(log, seed: int = 1) -> dict:
    """The true model on a synthetic log with nothing hidden (full test sequence): its residual
    RMS over the noise floor with the classic play and with the workbench's smoothed state."""
    case = hidden_effect_case(None, sequence=noise_free_sequence(log), seed=seed)
    points = OperatingPoints.from_bench(case.log.frame)
    runs = case.log.frame["run"].to_numpy()
    measured = measured_dp(case.log)
    result = {}
    for label, window in (("classic play", 1),
                          ("smoothed state", state_smoothing_samples(case.log))):
        solver_replay = replay(case.truth, points, runs, smoothing=window)
        residual = np.where(solver_replay.ok, solver_replay.dp - measured, np.nan)
        rms = float(np.sqrt(np.nanmean(residual**2)))
        floor = noise_floor(residual, runs)
        result[label] = {"window_samples": window, "rms_bar": round(float(from_si(rms, "bar")), 3),
                         "noise_floor_bar": round(float(from_si(floor, "bar")), 3),
                         "rms_over_noise": round(rms / floor, 3)}
    return result


def mismatch_record(log, cases: int, controls: int, kind: str, every: int,
                    settings: tuple[int, ...] = STRESS_SETTINGS,
                    mismatch: MapMismatch = MapMismatch(), only_weak: bool = False,
                    folder: str | None = None) -> dict:
    """The workflow on virtual-valve logs (the same settings and seeds as
    tests/synthetic/test_mismatch.py with its defaults): clean identifications over randomised
    cases, and the physics or sensor effects added where nothing is hidden. ``only_weak``: the
    weak leakages' cases alone; ``folder``: a learned kind's trained surrogate other than the
    committed one (an earlier version's, say)."""
    sequence = noise_free_sequence(log, every=every)
    under = maps(kind) if folder is None else maps(kind, folder=folder)
    record = {"maps": kind, "folder": folder, "every": every, "settings": list(settings),
              "cases": [],
              "controls": [], "mismatch": {name: getattr(mismatch, name)
                                           for name in mismatch.__dataclass_fields__}}

    for case in stress_suite(cases, controls, settings):
        if only_weak and not case.weak_leakage:
            continue
        outcome = run_stress_case(case, sequence, under, mismatch=mismatch)
        workflow, added = outcome.workflow, outcome.added
        # the share of resamples over runs that chose each added effect or its look-alikes
        chosen_in = [round(step.diagnosis.group_inclusion(step.diagnosis.best), 2)
                     for step in workflow.steps[1:] if step.diagnosis is not None]
        if case.hidden is None:
            record["controls"].append({"seed": case.seed, "added": added,
                                       "invented": outcome.invented, "chosen_in": chosen_in,
                                       "final_summary": summarise(workflow.final_diagnosis),
                                       "seconds": round(outcome.seconds, 1)})
            print(f"  nothing hidden, seed {case.seed}: added {', '.join(added) or 'nothing'}"
                  f" {chosen_in or ''}")
            continue
        ok = outcome.clean
        ratio = over_floor(workflow)
        twin = None if outcome.twin is None else round(over_floor(outcome.twin), 3)
        record["cases"].append({"hidden": case.hidden, "factor": round(case.factor, 2),
                                "seed": case.seed, "added": added, "chosen_in": chosen_in,
                                "shapes_beside_library": outcome.shapes_beside_library,
                                "withheld": withheld_claims(workflow),
                                "final_summary": summarise(workflow.final_diagnosis),
                                "rms_over_floor": round(ratio, 3),
                                "twin_over_floor": twin, "found": outcome.found,
                                "invisible": outcome.invisible,
                                "clean": ok, "seconds": round(outcome.seconds, 1)})
        verdict = ("clean" if outcome.found else "invisible" if outcome.invisible
                   else "NOT CLEAN")
        line = (f"  mismatch case {case.seed}: {case.hidden:<28} x{case.factor:.2f} -> "
                f"{', '.join(added) or 'nothing':<50} {verdict} "
                f"{chosen_in or ''}").rstrip()
        if twin is not None:
            line += (f"; {ratio:.2f}x the floor, its twin (nothing hidden) "
                     f"{twin:.2f}x")
        print(line + "".join(f"; withheld {claim}" for claim in record["cases"][-1]["withheld"]))
    record["clean_rate"] = (float(np.mean([c["clean"] for c in record["cases"]]))
                            if record["cases"] else None)
    # clean for having nothing to find: nothing added or withheld, the log ends as its twin
    record["invisible"] = sum(c["invisible"] for c in record["cases"])
    record["false_additions"] = sum(len(c["invented"]) for c in record["controls"])
    # shape-free terms added after the hidden library effect already explained the log
    record["shapes_beside_library"] = sum(len(c["shapes_beside_library"])
                                          for c in record["cases"])
    record["by_group"] = by_group(record["cases"])
    # misses that named the hidden effect but withheld it: a look-alike predicted as well
    record["withheld_hidden"] = sum(
        1 for c in record["cases"] if not c["clean"]
        and any(claim.split(" ")[0] == c["hidden"] for claim in c["withheld"]))
    rate = "" if record["clean_rate"] is None else f"{record['clean_rate']:.0%} of "
    print(f"under map mismatch ({kind} maps): {rate}{len(record['cases'])} cases clean "
          f"(found, or nothing added where the effect left nothing to find: "
          f"{record['invisible']}); {record['false_additions']} physics or sensor effects "
          f"added over {len(record['controls'])} nothing-hidden logs; "
          f"{record['shapes_beside_library']} shape-free term(s) added beside a library effect "
          "that already explained its log")
    for group, (clean, total) in record["by_group"].items():
        print(f"  {group}: {clean} of {total} clean")
    print(f"  not clean, the hidden effect named but withheld for a look-alike: "
          f"{record['withheld_hidden']}")
    return record


def by_group(cases: list[dict]) -> dict[str, list[int]]:
    """[clean, total] of the mismatch cases: weak leakages (the laminar leakage at most
    :data:`WEAK_LEAKAGE` times its realistic size), stronger leakages, and every other effect."""
    groups = {f"weak leakages (<= {WEAK_LEAKAGE}x)": [0, 0], "stronger leakages": [0, 0],
              "other effects": [0, 0]}
    for case in cases:
        if case["hidden"] == "laminar_leakage":
            group = (f"weak leakages (<= {WEAK_LEAKAGE}x)" if case["factor"] <= WEAK_LEAKAGE
                     else "stronger leakages")
        else:
            group = "other effects"
        groups[group][0] += int(case["clean"])
        groups[group][1] += 1
    return groups


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cases", type=int, default=20)
    parser.add_argument("--every", type=int, default=4, help="decimation of the sequence")
    parser.add_argument("--out", default="results/workbench")
    parser.add_argument("--mismatch-cases", type=int, default=20)
    parser.add_argument("--controls", type=int, default=5)
    parser.add_argument("--maps", default="gp",
                        help="maps of the timed diagnose and workflow (default: the workflow "
                             "command's default kind)")
    parser.add_argument("--mismatch-maps", default="grid",
                        help="maps of the model under test on the virtual valve")
    parser.add_argument("--mismatch-every", type=int, default=8)
    parser.add_argument("--mismatch-settings", type=int, nargs="+", default=list(STRESS_SETTINGS),
                        help="settings seeds of the stress suite (default: both)")
    parser.add_argument("--only-mismatch", action="store_true",
                        help="only the map-mismatch record (written to mismatch.json)")
    parser.add_argument("--gap", type=float, nargs=2, metavar=("FORCE", "DP"),
                        help="the virtual valve's departure from the maps across the unsampled "
                             "gaps, relative (default: MapMismatch's 0.05 0.03, the grid's "
                             "between-openings error; the GP's measured one is about 0.034 "
                             "0.009)")
    parser.add_argument("--per-opening", type=float, nargs=2, metavar=("DP", "FORCE"),
                        help="the virtual valve's error at each sampled opening, relative "
                             "(default: MapMismatch's 0.015 0.025, the CFD's mesh error; 0 0 "
                             "asks what the CFD's own error hides)")
    parser.add_argument("--only-weak-leakages", action="store_true",
                        help="of the mismatch suite, only the weak leakages' cases (no controls)")
    parser.add_argument("--mismatch-folder",
                        help="a trained surrogate's folder for --mismatch-maps nn|gp instead of "
                             "the committed one (an earlier version's, to compare)")
    args = parser.parse_args()
    log = load_bench_log(SHIPPED_BENCH_LOG)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    # how far the virtual valve strays from its CFD: the defaults, or as the options set
    strays = MapMismatch()
    if args.gap is not None:
        strays = replace(strays, gap_force=args.gap[0], gap_dp=args.gap[1])
    if args.per_opening is not None:
        strays = replace(strays, dp_per_opening=args.per_opening[0],
                         force_per_opening=args.per_opening[1])
    mismatch = mismatch_record(log, args.mismatch_cases,
                               0 if args.only_weak_leakages else args.controls,
                               args.mismatch_maps, args.mismatch_every,
                               tuple(args.mismatch_settings), strays, args.only_weak_leakages,
                               args.mismatch_folder)
    if args.only_mismatch or args.only_weak_leakages:
        path = out / f"mismatch_{args.mismatch_maps}.json"
        path.write_text(json.dumps(mismatch, indent=2) + "\n")
        print(f"wrote {path}")
        return

    fitted = fit_to_log(cfda(maps_spec=maps(args.maps)).build(), log).model
    base, replay_seconds = timed(replay_log, fitted, log)
    diagnosis, diagnose_seconds = timed(diagnose, fitted, log, base=base)
    print(f"diagnose of CFDA on {args.maps} maps over {len(diagnosis.candidates)} candidates on "
          f"{len(log)} samples (held-out checks included): {diagnose_seconds:.1f} s = "
          f"{diagnose_seconds / replay_seconds:.0f} replays ({replay_seconds:.2f} s each)")
    blas_free, blas_free_seconds = diagnose_with_free_blas(fitted, log, base)
    same = same_candidates(diagnosis, blas_free)
    print(f"the same diagnose with BLAS threads beside the replays' threads: "
          f"{blas_free_seconds:.1f} s = {blas_free_seconds / diagnose_seconds:.2f}x, "
          f"{'the same' if same else 'DIFFERENT'} results bit for bit")

    workflow, workflow_seconds = timed(run_workflow, log, maps_spec=maps(args.maps),
                                       progress=print)
    print(f"workflow: {workflow_seconds:.1f} s, {len(workflow.steps)} steps, final rms "
          f"{from_si(workflow.final.rms, 'bar'):.3f} bar, noise floor "
          f"{from_si(workflow.noise_floor, 'bar'):.3f} bar")

    control = replay_noise_control(log)
    for label, entry in control.items():
        print(f"control (nothing hidden), true model, {label}: rms {entry['rms_bar']:.3f} bar = "
              f"{entry['rms_over_noise']:.2f}x the noise floor")

    sequence = noise_free_sequence(log, every=args.every)
    cases = []
    for number, (hidden, factor, values) in enumerate(random_settings(args.cases, seed=7)):
        case = hidden_effect_case(hidden, values, sequence=sequence, seed=1000 + number)
        found = diagnose(fit_to_log(case.start, case.log).model, case.log)
        ok = identified(found, hidden)
        cases.append({"hidden": hidden, "factor": round(factor, 2), "identified": ok,
                      "best": found.candidates[0].name,
                      "rms_after_over_noise": round(found.candidates[0].rms_after
                                                    / found.noise_floor, 3)})
        print(f"  case {number + 1:2d}: {hidden:<28} x{factor:.2f} -> {cases[-1]['best']:<28} "
              f"{'found' if ok else 'MISSED'}")
    rate = float(np.mean([c["identified"] for c in cases]))
    print(f"identification rate: {rate:.0%} over {len(cases)} cases")

    document = {
        "samples": len(log), "maps": args.maps, "replay_seconds": round(replay_seconds, 3),
        "diagnose_seconds": round(diagnose_seconds, 1),
        "diagnose_in_replays": round(diagnose_seconds / replay_seconds, 1),
        "diagnose_free_blas_seconds": round(blas_free_seconds, 1),
        "free_blas_over_one_thread": round(blas_free_seconds / diagnose_seconds, 2),
        "free_blas_same_results": same,
        "workflow_seconds": round(workflow_seconds, 1),
        "workflow": workflow_document(workflow),
        "control_true_model": control,
        "identification_rate": rate, "cases": cases, "every": args.every,
        "mismatch": mismatch,
    }
    (out / "benchmark.json").write_text(json.dumps(document, indent=2) + "\n")
    print(f"wrote {out / 'benchmark.json'}")


if __name__ == "__main__":
    main()
