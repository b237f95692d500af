"""The off-library stress test: physics the library does not name, hidden in virtual valves.

Each case hides one effect of :mod:`surrogate.synthetic.offlibrary` (a detent, a kinked spring,
seal extrusion friction, friction rising with flow, a leak opening above a pressure drop; size,
shape and position drawn per case) in a virtual valve whose CFD differs from the shipped one like
a real valve's (:mod:`surrogate.synthetic.mismatch`), on the shipped test sequence with the
bench's sensor noise; the controls hide nothing. The workflow starts from the CFDA model on the
chosen maps, never sees the virtual valve, and adds what the diagnosis finds (library terms
first, shape-free terms behind them).

A case is judged three ways (:func:`surrogate.synthetic.offlibrary.off_library_outcome`):

* *right term*: the workflow adds a physics term of the hidden effect's kind on its variable
  (shape-free or from the library) and invents no other physics or sensor term (map corrections
  are allowed and labelled);
* *found*: the right term, and the final RMS within 1.3x the noise floor (issue 26's criterion);
* *as twin*: the right term, and the final RMS within 1.1x what the same virtual valve with
  nothing hidden ends at (its *twin*, the same map mismatch and noise, run too): under map
  mismatch a log with nothing hidden itself ends above 1.3x the floor on some seeds;
* *invisible*: nothing added, and the log ends within 1.3x the floor and as its twin: the effect
  (a barely visible leak) left nothing to find; *clean* is found or invisible, nothing invented.

A control passes when nothing physical or sensor is added, and so does a twin (counted as
*twins clean*); a case with a physics or sensor term beyond the hidden effect's kind and
variable is counted too. Targets (issue 26): >= 80 % of the
cases found on grid and on GP maps, every control clean.

Every shape-free term a workflow adds is handed over as an effects file (what ``workflow --out``
writes), added to the step before it with one parameter ``scale`` and fitted: the file must
lower the held-out RMS by at least 90 % of what the shape-free term did (*kept*, per find).

Writes results/offlibrary/<maps>.json and prints one line per case. Run:
``python eval/offlibrary.py [--maps grid gp] [--cases 20] [--leaks 8] [--controls 10]
[--every 8] [--no-twins] [--only EFFECT ...]``
(about 10 minutes per map kind for 30 logs on grid maps on 2 cores; GP maps take longer).
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np

from surrogate.data import load_bench_log
from surrogate.effects import LIBRARY, load_effects_file
from surrogate.effects.handover import write_effect_file
from surrogate.core.errors import InputError
from surrogate.fitting.heldout import run_groups
from surrogate.fitting.logfit import fit_to_log
from surrogate.fitting.residuals import replay_log
from surrogate.core.paths import SHIPPED_BENCH_LOG
from surrogate.description.presets import maps
from surrogate.reporting.prose import summarise
from surrogate.synthetic.mismatch import MapMismatch
from surrogate.synthetic.offlibrary import (OFF_LIBRARY, RMS_RATIO, off_library_outcome,
                                            off_library_suite)
from surrogate.synthetic.simulate import (hidden_effect_case, noise_free_sequence,
                                          withheld_claims)
from surrogate.workbench.workflow import heldout_rms, run_workflow

#: effects the loop may add per case: the hidden one, a map correction or two
ADDITIONS = 3
#: a handed-over file must keep this share of its shape-free term's gain in held-out RMS
KEPT_GAIN = 0.9


def handed_over(workflow) -> dict[str, float]:
    """For each shape-free step: its shape written as an effects file, added to the step before
    it and fitted (its ``scale`` from 0); the share of the step's gain in held-out RMS (each run
    predicted by a refit to the others, replayed) that the file keeps."""
    kept = {}
    schemes = run_groups(workflow.log)
    for before, step in zip(workflow.steps, workflow.steps[1:]):
        if not step.shape_free:
            continue
        name = step.added[0]
        with tempfile.TemporaryDirectory() as folder:
            path = write_effect_file(step.model.effect(name), Path(folder) / "found_shape.py")
            effect = load_effects_file(path)["found_shape"]()
        fitted = fit_to_log(before.model.with_effects([*before.model.effects, effect]),
                            workflow.log, start=before.log_replay)
        log_replay = replay_log(fitted.model, workflow.log, guess=fitted.evaluation.payload)
        gain = before.heldout_check - step.heldout_check
        kept[name] = float((before.heldout_check - heldout_rms(fitted, log_replay, schemes))
                           / gain) if gain > 0 else float("nan")
    return kept


def run(kind: str, cases: int, controls: int, every: int, seed: int, twins: bool = True,
        leaks: int = 0, only: list[str] | None = None) -> dict:
    sequence = noise_free_sequence(load_bench_log(SHIPPED_BENCH_LOG), every=every)
    records = []
    for case in off_library_suite(cases, controls, seed, leaks):
        if only and (case.hidden or "nothing") not in only:
            continue
        began = time.perf_counter()
        try:
            log_case = hidden_effect_case(case.hidden, case.values, sequence=sequence,
                                          seed=case.seed, library=LIBRARY + OFF_LIBRARY,
                                          mismatch=MapMismatch(), maps_under_test=maps(kind))
        except InputError as error:  # an effect too large for the valve to have a log at all
            print(f"  {kind} {case.seed}: {case.hidden:<20} -> no log: {error}", flush=True)
            records.append({"hidden": case.hidden, "seed": case.seed, "values": case.values,
                            "skipped": str(error)})
            continue
        workflow = run_workflow(log_case.log, start=log_case.start, max_additions=ADDITIONS)
        twin = None
        if case.hidden is not None and twins:
            twin_case = hidden_effect_case(None, sequence=sequence, seed=case.seed,
                                           mismatch=MapMismatch(), maps_under_test=maps(kind))
            twin = run_workflow(twin_case.log, start=twin_case.start, max_additions=ADDITIONS)
        outcome = off_library_outcome(workflow, case.hidden, twin)
        # the twin hides nothing: whatever physics or sensor term it gets is invented
        twin_invented = [] if twin is None else list(off_library_outcome(twin, None).invented)
        seconds = time.perf_counter() - began
        kept = handed_over(workflow)
        records.append({**outcome.to_json(), "seed": case.seed, "twin_invented": twin_invented,
                        "withheld": withheld_claims(workflow),
                        "twin_withheld": [] if twin is None else withheld_claims(twin),
                        "values": case.values, "seconds": round(seconds, 1),
                        "handed_over_kept": {k: round(v, 3) for k, v in kept.items()},
                        "final_summary": summarise(workflow.final_diagnosis)})
        verdict = ("found" if outcome.found else "as twin" if outcome.right_term
                   and outcome.as_twin else "right term" if outcome.right_term
                   else "invisible" if outcome.invisible else "MISSED")
        print(f"  {kind} {case.seed}: {case.hidden or 'nothing hidden':<20} -> "
              f"{', '.join(outcome.added) or 'nothing':<55} {outcome.rms_over_floor:5.2f}x "
              f"floor (twin {outcome.twin_over_floor:4.2f}x)  {verdict}  ({seconds:.0f} s)"
              + "".join(f"; file keeps {share:.0%} of {name}'s held-out gain"
                        for name, share in kept.items())
              + (f"; TWIN got {', '.join(twin_invented)}" if twin_invented else "")
              + "".join(f"; withheld {claim}" for claim in records[-1]["withheld"])
              + "".join(f"; twin withheld {claim}" for claim in records[-1]["twin_withheld"]),
              flush=True)
    skipped = [r for r in records if "skipped" in r]
    records = [r for r in records if "skipped" not in r]
    hidden = [r for r in records if r["hidden"] is not None]
    clean = [r for r in records if r["hidden"] is None]

    def share(key: str) -> float | None:
        return float(np.mean([r[key] for r in hidden])) if hidden else None

    summary = {"maps": kind, "cases": len(hidden), "controls": len(clean),
               "found_share": share("found"), "right_term_share": share("right_term"),
               "clean_share": share("clean"), "invisible": sum(r["invisible"] for r in hidden),
               "as_twin_share": float(np.mean([r["right_term"] and r["as_twin"]
                                                for r in hidden])) if hidden else None,
               "controls_clean": sum(r["found"] for r in clean),
               "skipped": skipped,
               "twins_clean": f"{sum(not r['twin_invented'] for r in hidden)} of "
                              f"{sum(r['twin_over_floor'] is not None for r in hidden)}",
               # physics or sensor terms beyond the hidden effect's kind and variable
               "with_other_terms": sum(bool(r["invented"]) for r in hidden),
               "handed_over": [share for r in records
                               for share in r["handed_over_kept"].values()],
               "rms_ratio": RMS_RATIO, "by_effect": {
                   name: f"{sum(r['found'] for r in hidden if r['hidden'] == name)} of "
                         f"{sum(r['hidden'] == name for r in hidden)}"
                   for name in OFF_LIBRARY},
               "records": records}
    if not hidden:  # controls only
        print(f"{kind} maps: {summary['controls_clean']} of {len(clean)} controls clean")
        return summary
    print(f"{kind} maps, {len(hidden)} off-library cases: clean (found, or nothing added where "
          f"the effect left nothing to find) {summary['clean_share']:.0%} "
          f"({summary['invisible']} invisible), right term "
          f"{summary['right_term_share']:.0%}, found (and within {RMS_RATIO}x the floor) "
          f"{summary['found_share']:.0%}, right term "
          f"and as its twin {summary['as_twin_share']:.0%} (found by effect: "
          f"{summary['by_effect']}); {summary['controls_clean']} of {len(clean)} controls clean, "
          f"twins clean {summary['twins_clean']}, {summary['with_other_terms']} case(s) with a "
          "physics or sensor term of another kind; "
          f"{sum(share >= KEPT_GAIN for share in summary['handed_over'])} of "
          f"{len(summary['handed_over'])} handed-over files keep >= {KEPT_GAIN:.0%} of their "
          f"shape's held-out gain")
    return summary


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--maps", nargs="+", default=["grid", "gp"])
    parser.add_argument("--cases", type=int, default=20)
    parser.add_argument("--controls", type=int, default=10)
    parser.add_argument("--leaks", type=int, default=8,
                        help="cases with a leak of another law than the laminar one (orifice, "
                             "thresholds low to high, growing with the opening or the "
                             "temperature; sizes from barely visible to dominant)")
    parser.add_argument("--every", type=int, default=8, help="keep every n-th sample")
    parser.add_argument("--seed", type=int, default=4242, help="the suite's seed")
    parser.add_argument("--no-twins", action="store_true",
                        help="skip the nothing-hidden twin of each case (half the time)")
    parser.add_argument("--only", nargs="+", metavar="EFFECT",
                        help="only the cases hiding these effects ('nothing': the controls)")
    parser.add_argument("--out", default="results/offlibrary")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for kind in args.maps:
        summary = run(kind, args.cases, args.controls, args.every, args.seed,
                      twins=not args.no_twins, leaks=args.leaks, only=args.only)
        (out / f"{kind}.json").write_text(json.dumps(summary, indent=2) + "\n")


if __name__ == "__main__":
    main()
