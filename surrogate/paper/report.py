"""Writing the paper's comparison: tables as CSV and Markdown, figures as PNG, and paper.json."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd

from ..core.outputs import atomic_directory
from .comparison import TABLE5_P_PE_BAR, TEMPERATURES_C, PaperComparison
from .figures import all_figures


def table5_markdown(records: list[dict]) -> str:
    """Table 5 in the paper's layout: models as rows, p_Pe × temperature as columns."""
    frame = pd.DataFrame(records)
    header = ["model"] + [f"{p:g} bar, {t:g} °C" for p in TABLE5_P_PE_BAR for t in TEMPERATURES_C]
    rows = ["| " + " | ".join(header) + " | ", "|" + "---|" * len(header)]
    for model, group in frame.groupby("model", sort=False):
        cells = [model]
        for p in TABLE5_P_PE_BAR:
            for t in TEMPERATURES_C:
                record = group[(group["p_Pe_bar"] == p) & (group["temperature_C"] == t)].iloc[0]
                cells.append(f"{record['mean_abs_bar']:.1f} ({record['category']})")
        rows.append("| " + " | ".join(cells) + " |")
    means = frame.groupby("model", sort=False)["mean_abs_bar"].mean()
    rows.append("")
    rows.append("Mean over the nine cells: " + ", ".join(f"{m} {v:.1f} bar"
                                                        for m, v in means.items()) + ".")
    rows.append("Mean absolute distance from the median line [bar]; (++) < 5 bar, (+) 5–15 bar, "
                "(-) > 15 bar. Friction off.")
    return "\n".join(rows)


def table6_markdown(records: list[dict]) -> str:
    """Table 6: K1 and K2 per temperature for the two runs fitted to."""
    rows = ["| temperature | fitted on p_Pe | K1 [N] | K2 [10⁻² N/bar] | rms [bar] |",
            "|---|---|---|---|---|"]
    for r in records:
        k1 = f"{r['K1_N']:.2f}" + (f" ± {r['K1_stderr_N']:.2f}" if r["K1_stderr_N"] is not None
                                   else " (bound)")
        k2 = f"{100 * r['K2_N_per_bar']:.2f}" + (
            f" ± {100 * r['K2_stderr_N_per_bar']:.2f}" if r["K2_stderr_N_per_bar"] is not None
            else " (bound)")
        rows.append(f"| {r['temperature_C']:g} °C | {r['fitted_on_p_Pe_bar']:g} bar | {k1} | {k2} "
                    f"| {r['rms_bar']:.2f} |")
    return "\n".join(rows)


def write_report(comparison: PaperComparison, directory: str | Path, maps: str) -> list[Path]:
    """Write tables, figures and ``paper.json`` into ``directory`` (all or nothing)."""
    document = {"maps": maps, **comparison.to_json()}
    with atomic_directory(directory) as staging:
        pd.DataFrame(comparison.table5).to_csv(staging / "table5.csv", index=False)
        pd.DataFrame(comparison.table6).to_csv(staging / "table6.csv", index=False)
        (staging / "table5.md").write_text(table5_markdown(comparison.table5) + "\n")
        (staging / "table6.md").write_text(table6_markdown(comparison.table6) + "\n")
        (staging / "paper.json").write_text(json.dumps(document, indent=2) + "\n")
        for stem, figure in all_figures(comparison).items():
            figure.savefig(staging / f"{stem}.png", dpi=130)
        written = sorted(path.name for path in staging.iterdir())
    return [Path(directory) / name for name in written]
