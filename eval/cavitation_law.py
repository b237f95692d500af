"""What the grid's cavitation law buys: the back-pressure set predicted, and the paper's models.

The paper's maps leave the back pressure out (its eq. 19 eliminates it); the package's grid
reads the CFD's back-pressure set through one law of the cavitation number
(:mod:`surrogate.maps.cavitation`). This script measures it twice:

1. **On the CFD.** Each opening of the back-pressure set in turn is left out of the law's fit and
   predicted from the other openings' law and its own run at the reference back pressure; the
   error |ln α| is printed beside that of ignoring the back pressure.
2. **On the bench.** ``paper --json`` with the shipped samples (the grid with its law) and with
   the samples at the reference back pressure only (the grid has no law to fit: the paper's
   maps), the same log: CFDA's fitted flow-force scale, Table 5's mean distances and Table 6's
   friction fits.

    python eval/cavitation_law.py

Seconds (two ``paper`` runs of about 10 s each). Writes results/cavitation_law.json.
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from surrogate.data.loaders import load_cfd_samples  # noqa: E402
from surrogate.maps.cavitation import left_out_opening_errors  # noqa: E402
from surrogate.maps.splits import reference_back_pressure  # noqa: E402
from surrogate.core.paths import SHIPPED_CFD_SAMPLES  # noqa: E402
from surrogate.core.units import from_si  # noqa: E402
from surrogate.valve import load_valve  # noqa: E402


def paper_runs() -> dict:
    """``paper --json`` with the shipped samples and with those at the reference back pressure
    only."""
    frame = pd.read_csv(SHIPPED_CFD_SAMPLES)
    reference_bar = reference_back_pressure(frame.assign(p_B=frame["p_B_bar"] * 1e5)) / 1e5
    results = {}
    with tempfile.TemporaryDirectory() as scratch:
        only_reference = Path(scratch) / "cfd_at_reference.csv"
        frame[np.isclose(frame["p_B_bar"], reference_bar)].to_csv(only_reference, index=False)
        for name, extra in (("with the law", []), ("paper's maps (no law)",
                                                   ["--cfd", str(only_reference)])):
            output = subprocess.run([sys.executable, "-m", "surrogate", "paper", "--json", *extra],
                                    cwd=ROOT, capture_output=True, text=True, check=True).stdout
            results[name] = json.loads(output)
    return results


def main() -> int:
    valve = load_valve()
    samples = load_cfd_samples(SHIPPED_CFD_SAMPLES)
    errors = left_out_opening_errors(samples.frame, valve)
    table = pd.DataFrame({"u_mm": from_si(errors["u"], "mm").round(3),
                          "q_lpm": from_si(errors["q"], "L/min").round(2),
                          "p_B_bar": from_si(errors["p_B"], "bar").round(2),
                          "sigma": errors["sigma"].round(4),
                          "error_with_law": errors["with_law"].round(4),
                          "error_ignoring_p_B": errors["ignoring_p_B"].round(4)})
    rows = table.to_dict("records")
    print("The back-pressure set, each opening predicted by the law of the others [ln α]:")
    print(table.to_string(index=False))
    with_law, ignoring = (np.abs(errors[column]) for column in ("with_law", "ignoring_p_B"))
    print(f"  with the law: rms {np.sqrt(np.mean(with_law ** 2)):.3f}, worst {with_law.max():.3f}; "
          f"ignoring p_B: rms {np.sqrt(np.mean(ignoring ** 2)):.3f}, worst {ignoring.max():.3f}")
    papers = paper_runs()
    print("\nThe paper's comparison on the shipped log (python -m surrogate paper):")
    print(f"{'maps':<24}{'CFDA scale':>11}{'Table 5 CFDA mean [bar]':>25}   Table 6 rms [bar]")
    summary = {}
    for name, result in papers.items():
        scale = result["fitted"]["CFDA_flow_force_scale"]
        cells = [row["mean_abs_bar"] for row in result["table5"] if row["model"] == "CFDA"]
        rms = [row["rms_bar"] for row in result["table6"]]
        summary[name] = {"CFDA_flow_force_scale": scale, "table5_CFDA_mean_bar": np.mean(cells),
                         "table6_rms_bar": rms, "table6": result["table6"]}
        print(f"{name:<24}{scale:>11.3f}{np.mean(cells):>25.2f}   "
              f"{', '.join(f'{value:.2f}' for value in rms)}")
    out = ROOT / "results" / "cavitation_law.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"back_pressure_set": rows, "paper": summary}, indent=2) + "\n")
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
