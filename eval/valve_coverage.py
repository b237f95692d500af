"""Does a map's ±2σ cover the valve, not only the CFD? Coverage against virtual valves.

Cross-validation scores a map against CFD samples it did not see, so it cannot see the CFD's own
error: each opening's mesh has a bias of its own (the paper's Table 4 moves Δp by up to 1.9 %
with refinement), which a map fitted to the samples reproduces and may call certain. This script
judges every shipped kind's σ where the truth is known: in virtual valves whose CFD errs as a
real one does (:func:`surrogate.synthetic.mismatch.mismatched_samples`: each sampled opening's Δp
and flow force off by a draw of its own, the valve's own curve across the unsampled gap and below
the smallest opening, and a cavitation term in the flow force that maps built at few back
pressures miss); what its maps are made of, ``--truth`` below says.

For each valve (one seed) and region, the states are operating points (opening, flow, oil state,
back pressure); the valve's own Δp gives the load pressure; the map under test is asked its flow
at that load pressure and its flow force there, with σ. Reported per kind and region: the
median and the 90th percentile of |ln(map / valve)| and the share of states within ±2σ (the
target is 85-98 %, the issue's band) with its 90 % interval when whole valves are resampled
(a valve's states share its draws, so they fall inside or outside together). Regions:

* sampled: the CFD samples' own states (every opening, temperature and back pressure sampled);
* between: halfway in ln u between neighbouring openings, outside the wide gap;
* gap: a quarter, half and three quarters across the unsampled 0.20-0.63 mm gap;
* below: 0.3, 0.5 and 0.7 of the smallest sampled opening, toward the seat, at its flows scaled
  alike (so that Δp stays in the samples' range);
* temperatures: 30 and 50 °C (the samples hold 20, 40 and 60 °C), at the sampled openings;
* oils: viscosities 0.7 and 1.5 times the oil's at 40 °C, at the sampled openings;
* back pressures: 2.5, 7.5 and 15 bar (the samples hold 1.5, 5 and 10 bar).

    python eval/valve_coverage.py                        # grid, NN and GP; valves 1-60
    python eval/valve_coverage.py --truth samples        # valves that bridge the grid's way
    python eval/valve_coverage.py --truth own            # each kind's maps, wrong by the draws
    python eval/valve_coverage.py --constant-cfd-error   # σ without the region terms
    python eval/valve_coverage.py --kinds gp --seeds 1 2 3 4 5 6 7 8 --mismatch 0.5

The valve's maps (``--truth``) decide what "between the samples" means, since each kind bridges
openings, oils and back pressures its own way. By default each kind is judged against valves
made of the other kinds' maps, wrong by the draws and averaged by their precision where they are
asked (a map that knows it cannot tell counts little): a valve that bridges as the kind under
test does not. Grid maps of the perturbed samples (``samples``) bridge as the grid does (a
learned map's bridge then counts as its error, fairly or not, and that valve ignores its own
CFD's back-pressure set); a kind's own maps wrong by the draws (``own``) leave only the CFD's
error (the mesh bias, the gap's bump, the cavitation) to cover; one kind's maps judge every
kind's bridge against that one.

Writes results/valve_coverage/coverage.json and coverage.png (the table as a picture). About a
minute.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import Rectangle

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from surrogate.data.loaders import load_cfd_samples  # noqa: E402
from surrogate.maps.registry import build_maps  # noqa: E402
from surrogate.core.paths import SHIPPED_CFD_SAMPLES  # noqa: E402
from surrogate.reporting.report import figure_png  # noqa: E402
from surrogate.synthetic.mismatch import MapMismatch  # noqa: E402
from surrogate.synthetic.valve_coverage import (BAND, REGIONS, regions,  # noqa: E402
                                                score, summarise, valve_truth)
from surrogate.valve import load_valve  # noqa: E402

KINDS = ("grid", "nn", "gp")
#: the virtual valves: a valve's states share its draws, so the valve is the unit of chance, and
#: with 5 valves one unlucky draw moved a share by up to 18 points (the GP's flow force across
#: the gap: 82 % over valves 1-5, 86 % over 1-20). Twenty still left the gap's cells 20 points
#: wide (90 % intervals 72-96 %) and over valves 21-60 the grid's q there was 97 % against 86 %
#: over 1-20, the GP's flow force 80 % against 86 %: sixty, about a minute of CPU
SEEDS = tuple(range(1, 61))

def constant_cfd_error() -> None:
    """Take the region terms of the CFD's error out of every map's σ in this process
    (:mod:`surrogate.maps.cfd_error`: one mesh's whole bias everywhere, no gap term, no
    cavitation term)."""
    import surrogate.maps.base as base

    base.mesh_bias_share = lambda openings, u: np.ones(np.shape(u))
    base.gap_error = lambda gaps, u, size=None: np.zeros(np.shape(u))
    base.cavitation_error = lambda central, p_B: np.zeros(np.shape(p_B))


def truth_maps(truth: str, kind: str, maps, valve) -> list:
    """The (flow, force) maps the virtual valves of ``truth`` are made of for ``kind`` under
    test (its own ``maps`` already built); none for grid maps of the perturbed samples."""
    if truth == "samples":
        return []
    if truth == "own":
        return [maps]
    names = [other for other in KINDS if other != kind] if truth == "others" else [truth]
    return [maps if name == kind else build_maps(name, valve) for name in names]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--kinds", nargs="+", default=list(KINDS), choices=KINDS)
    parser.add_argument("--seeds", type=int, nargs="+", default=list(SEEDS))
    parser.add_argument("--mismatch", type=float, default=1.0,
                        help="scale of the valve's departure from its CFD (1: the defaults of "
                             "MapMismatch, the paper's mesh study)")
    parser.add_argument("--truth", default="others", choices=("others", "samples", "own", *KINDS),
                        help="what the valve's maps are: the other kinds' maps wrong by the "
                             "draws, averaged (default: a valve that bridges as the kind under "
                             "test does not), grid maps of its perturbed samples ('samples': "
                             "a valve that bridges the grid's way), each kind's own maps wrong "
                             "by the draws ('own': the CFD's error alone), or one kind's maps "
                             "wrong by the draws for every kind")
    parser.add_argument("--constant-cfd-error", action="store_true",
                        help="σ as before the CFD's error grew region by region: the calibrated "
                             "σ and the CFD's constant error only (no bridged meshes, no gap "
                             "floor, no cavitation term), to see what those terms do")
    parser.add_argument("--out", default=str(ROOT / "results" / "valve_coverage"))
    args = parser.parse_args(argv)
    if args.constant_cfd_error:
        constant_cfd_error()
    began = time.process_time()
    valve = load_valve()
    samples = load_cfd_samples(SHIPPED_CFD_SAMPLES)
    states = regions(samples, valve)
    mismatch = MapMismatch().scaled(args.mismatch)
    results = {}
    for kind in args.kinds:
        maps = build_maps(kind, valve)
        on = truth_maps(args.truth, kind, maps, valve)
        truths = {seed: valve_truth(samples, valve, seed, mismatch, on) for seed in args.seeds}
        results[kind] = {region: summarise([score(maps, truths[seed], states[region])
                                            for seed in args.seeds]) for region in REGIONS}
    print(f"{len(args.seeds)} virtual valves (seeds {_seeds(args.seeds)}) on "
          f"{args.truth} maps, mismatch x{args.mismatch:g}; share of states within ±2σ (target {BAND[0]:.0%}-"
          f"{BAND[1]:.0%}) with its 90 % interval over the valves, median |error| [%] and median "
          "σ [%]:")
    header = f"{'kind':<6}{'region':<16}{'states':>7}  " + "".join(
        f"{name + ' ±2σ':>24}{'err':>7}{'σ':>7}" for name in ("q", "flow force"))
    print(header)
    for kind, by_region in results.items():
        for region, summary in by_region.items():
            cells = ""
            for name in ("q", "flow force"):
                entry = summary[name]
                share = entry.get("within 2 sigma")
                mark = "" if share is None or BAND[0] <= share <= BAND[1] else " *"
                text = "-" if share is None else f"{share:.0%} ({_interval(entry)}){mark}"
                cells += (f"{text:>24}"
                          f"{entry['median error %']:>7.2f}"
                          f"{entry.get('median sigma %', float('nan')):>7.2f}")
            print(f"{kind:<6}{region:<16}{summary['states']:>7}  {cells}")
    print(f"(* outside the band; {time.process_time() - began:.0f} s CPU)")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    document = {"seeds": args.seeds, "mismatch": args.mismatch, "truth": args.truth,
                "band": BAND,
                "results": results}
    (out / "coverage.json").write_text(json.dumps(document, indent=2) + "\n")
    (out / "coverage.png").write_bytes(figure_png(coverage_figure(results, args.truth)))
    print(f"wrote {out / 'coverage.json'} and coverage.png")
    return 0


def _seeds(seeds: list[int]) -> str:
    """Seeds as a range where they are one ("1-20"), else listed."""
    if len(seeds) > 2 and list(seeds) == list(range(seeds[0], seeds[0] + len(seeds))):
        return f"{seeds[0]}-{seeds[-1]}"
    return ", ".join(map(str, seeds))


def _interval(entry: dict) -> str:
    """A share's 90 % interval over the valves, in percent ("78-93")."""
    low, high = entry["within 2 sigma, 90 % interval"]
    return f"{low:.0%}-{high:.0%}".replace("%-", "-")


def coverage_figure(results: dict, truth: str) -> Figure:
    """±2σ's share per region (rows) and kind and quantity (columns), green inside the band,
    orange above it (σ too wide), red below (σ too narrow), with the median error and σ [%]."""
    columns = [(kind, name) for kind in results for name in ("q", "flow force")]
    figure = Figure(figsize=(1.6 * len(columns) + 1.6, 0.62 * len(REGIONS) + 1.3),
                    layout="constrained")
    ax = figure.subplots()
    for row, region in enumerate(REGIONS):
        for column, (kind, name) in enumerate(columns):
            entry = results[kind][region][name]
            share = entry.get("within 2 sigma")
            colour = ("0.85" if share is None else "#8fd19e" if BAND[0] <= share <= BAND[1]
                      else "#f5c27a" if share > BAND[1] else "#f08080")
            ax.add_patch(Rectangle((column, row), 1, 1, facecolor=colour, edgecolor="white"))
            text = "-" if share is None else f"{share:.0%}"
            ax.text(column + 0.5, row + 0.35, text, ha="center", va="center", fontsize=11)
            if share is not None:
                ax.text(column + 0.5, row + 0.58, f"({_interval(entry)})", ha="center",
                        va="center", fontsize=7)
            ax.text(column + 0.5, row + 0.8, f"err {entry['median error %']:.1f} / "
                    f"σ {entry.get('median sigma %', float('nan')):.1f} %",
                    ha="center", va="center", fontsize=7, color="0.3")
    ax.set_xlim(0, len(columns))
    ax.set_ylim(len(REGIONS), 0)
    ax.set_xticks(np.arange(len(columns)) + 0.5,
                  [f"{kind}\n{name}" for kind, name in columns])
    ax.set_yticks(np.arange(len(REGIONS)) + 0.5, REGIONS)
    ax.tick_params(length=0)
    for side in ax.spines.values():
        side.set_visible(False)
    valves = {"others": "the other kinds' maps", "samples": "grid maps of perturbed samples",
              "own": "each kind's own maps"}.get(truth, f"{truth} maps")
    ax.set_title(f"±2σ's share of the virtual valves' truth (valves of {valves}), with its 90 % "
                 f"interval over the valves; green {BAND[0]:.0%}-{BAND[1]:.0%}, orange wider, "
                 "red narrower", fontsize=9)
    return figure


if __name__ == "__main__":
    raise SystemExit(main())
