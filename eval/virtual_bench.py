"""The main job on whole virtual-valve logs, as a user would run it: `simulate --mismatch`, then
`workflow`.

The stress suite (tests/synthetic/test_mismatch.py, `eval/workbench.py --only-mismatch`) runs on every 8th
sample of the test sequence and starts from the reference valve's CFDA. A user's log is the
whole sequence, and the main job starts from the paper's basic model. This script does what a
user would: for each case it writes the log that
`python -m surrogate simulate --hidden NAME --mismatch 1 --maps KIND --seed SEED` writes (the
whole shipped test sequence, 11,000 samples, the shipped sensor noise, a virtual valve that
differs from its CFD by the CFD's own error), runs the workflow on it from BMBE on the same kind
of maps (`python -m surrogate workflow --data LOG --maps KIND`), and reports what was added, in
which category, and whether it is clean: the hidden effect (or one the data cannot tell from it)
and no other physics or sensor effect; map corrections are allowed and labelled as such.

Writes results/virtual_bench/virtual_bench.json. Run:
``python eval/virtual_bench.py [--maps gp] [--seeds 1 2] [--hidden NAME ...]``
(about 2 minutes per log on 2 cores).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from surrogate.data import load_bench_log
from surrogate.core.paths import SHIPPED_BENCH_LOG
from surrogate.description.presets import maps
from surrogate.reporting.prose import sensor_check_text
from surrogate.synthetic.mismatch import MapMismatch
from surrogate.synthetic.simulate import (cleanly_identified, hidden_effect_case,
                                          noise_free_sequence, reference_spec,
                                          unexplained_additions)
from surrogate.core.units import from_si
from surrogate.workbench.workflow import run_workflow

#: one effect of each kind the library holds (friction, spring, leakage, flow force, sensor),
#: at its realistic magnitude, and the control with nothing hidden
DEFAULT_HIDDEN = ("none", "friction_viscous", "friction_seal_pressure", "progressive_spring",
                  "laminar_leakage", "back_pressure_flow_force", "pilot_transducer_offset")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--maps", default="gp", help="kind of map (default: the workflow's)")
    parser.add_argument("--hidden", nargs="+", default=list(DEFAULT_HIDDEN),
                        help="effects to hide, one log each ('none': nothing hidden)")
    parser.add_argument("--seeds", type=int, nargs="+", default=[1],
                        help="noise and mismatch seeds (each effect is run with each)")
    parser.add_argument("--out", default="results/virtual_bench")
    args = parser.parse_args()
    sequence = noise_free_sequence(load_bench_log(SHIPPED_BENCH_LOG))
    records = []
    for seed in args.seeds:
        for name in args.hidden:
            hidden = None if name == "none" else name
            case = hidden_effect_case(hidden, sequence=sequence, seed=seed,
                                      reference=reference_spec(), mismatch=MapMismatch(),
                                      maps_under_test=maps(args.maps))
            began = time.perf_counter()
            workflow = run_workflow(case.log, maps_spec=maps(args.maps))
            seconds = time.perf_counter() - began
            added = [{"added": step.added, "category": step.category,
                      "rms_bar": round(float(from_si(step.rms, "bar")), 3),
                      "heldout_rms_bar": round(float(from_si(step.heldout_rms, "bar")), 3)}
                     for step in workflow.steps[4:]]  # after the paper's four steps
            clean = cleanly_identified(workflow, hidden)
            records.append({
                "hidden": name, "seed": seed, "clean": clean, "added": added,
                "invented": unexplained_additions(workflow, hidden),
                "sensor_checks": [sensor_check_text(c)
                                  for c in workflow.final_diagnosis.sensor_checks],
                "final_rms_bar": round(float(from_si(workflow.final.rms, "bar")), 3),
                "noise_floor_bar": round(float(from_si(workflow.noise_floor, "bar")), 3),
                "seconds": round(seconds, 1)})
            steps = "; ".join(f"{', '.join(a['added'])} ({a['category']})" for a in added)
            print(f"seed {seed} {name:<26} -> {steps or 'nothing':<70} "
                  f"{'clean' if clean else 'NOT CLEAN'} ({seconds:.0f} s)", flush=True)
    hidden = [r for r in records if r["hidden"] != "none"]
    controls = [r for r in records if r["hidden"] == "none"]
    summary = {"maps": args.maps, "samples": len(sequence),
               "clean": sum(r["clean"] for r in hidden), "cases": len(hidden),
               "controls_clean": sum(r["clean"] for r in controls), "controls": len(controls),
               "records": records}
    print(f"{args.maps} maps, whole logs: {summary['clean']} of {summary['cases']} hidden effects "
          f"found cleanly; {summary['controls_clean']} of {summary['controls']} nothing-hidden "
          "logs clean")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "virtual_bench.json").write_text(json.dumps(summary, indent=2) + "\n")
    print(f"wrote {out / 'virtual_bench.json'}")


if __name__ == "__main__":
    main()
