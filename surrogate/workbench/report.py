"""One self-contained HTML report (figures embedded as PNG data) and the workbench's own figures.

The report is meant for an engineer who never ran the tool: every section says in a sentence what
it shows, numbers carry units, and the figures sit next to the tables they illustrate.
"""

from __future__ import annotations

import base64
import html
import io
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from ..outputs import atomic_file
from ..units import from_si
from .compare import Comparison
from .diagnose import BIC_THRESHOLD, GAIN_FRACTION, NOISE_MARGIN, Diagnosis
from .figures import DPI, all_figures

_STYLE = """
body { font-family: system-ui, sans-serif; max-width: 1200px; margin: 2em auto; color: #222;
       line-height: 1.45; padding: 0 1em; }
h1 { font-size: 1.6em; } h2 { font-size: 1.25em; margin-top: 2em; border-bottom: 1px solid #ccc; }
table { border-collapse: collapse; margin: 0.8em 0; font-size: 0.9em; }
th, td { border: 1px solid #ddd; padding: 0.25em 0.6em; text-align: right; }
th { background: #f3f3f3; } td.text, th.text { text-align: left; }
img { max-width: 100%; margin: 0.5em 0; }
.summary { background: #f5f8ff; border-left: 4px solid #4a7bd0; padding: 0.6em 1em; }
.yes { color: #0a7a2a; font-weight: 600; } .no { color: #888; }
"""


def figure_png(figure: Figure) -> bytes:
    """The figure as PNG bytes."""
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=DPI)
    return buffer.getvalue()


def _image(png: bytes, alt: str) -> str:
    data = base64.b64encode(png).decode("ascii")
    return f'<img alt="{html.escape(alt)}" src="data:image/png;base64,{data}">'


def _table(frame: pd.DataFrame, text_columns: tuple[str, ...] = ()) -> str:
    head = "".join(f'<th class="{"text" if c in text_columns else ""}">{html.escape(str(c))}</th>'
                   for c in frame.columns)
    rows = []
    for row in frame.itertuples(index=False):
        cells = []
        for column, value in zip(frame.columns, row):
            if isinstance(value, (float, np.floating)):
                text = "" if not np.isfinite(value) else f"{value:.4g}"
            else:
                text = html.escape(str(value))
            cells.append(f'<td class="{"text" if column in text_columns else ""}">{text}</td>')
        rows.append("<tr>" + "".join(cells) + "</tr>")
    return f"<table><thead><tr>{head}</tr></thead><tbody>{''.join(rows)}</tbody></table>"


def comparison_section(comparison: Comparison, heading: str) -> str:
    """Headline, per-run table, p_Pe × temperature table, worst regions and the figures."""
    rms, floor = from_si(comparison.rms, "bar"), from_si(comparison.noise_floor, "bar")
    runs = comparison.runs[["run", "temperature_C", "p_Pe_bar", "samples", "rms_bar", "bias_bar",
                            "hysteresis_measured_bar", "hysteresis_model_bar",
                            "hysteresis_error_bar", "extrapolating_fraction"]]
    pivot = comparison.pivot.reset_index()
    pivot.columns = ["p_Pe [bar]"] + [f"{c:g} °C" for c in comparison.pivot.columns]
    regions = comparison.regions.head(10)
    parts = [
        f"<h2>{html.escape(heading)}</h2>",
        f"<p>Model <b>{html.escape(comparison.model)}</b> replayed over every run "
        f"(friction as a play). Residual = model − measured Δp. RMS <b>{rms:.3f} bar</b>; noise "
        f"floor estimated from the data's sample-to-sample scatter <b>{floor:.3f} bar</b> "
        f"({comparison.rms_over_noise:.2f}×). The maps extrapolate at "
        f"{100 * comparison.extrapolating_fraction:.0f} % of the samples.</p>",
        "<h3>Per run</h3><p>Bias is the mean residual; hysteresis width is Δp on the ramp up minus "
        "Δp on the ramp down at equal flow [bar].</p>", _table(runs, ("run",)),
        "<h3>RMS by pilot set point and temperature [bar]</h3>", _table(pivot),
        "<h3>Worst operating regions</h3><p>Flow band × temperature × set point, worst first; "
        "<i>extrapolating_fraction</i> is the share of samples where the model leaves its "
        "maps' data.</p>", _table(regions),
    ]
    captions = {"dp_vs_q": "Δp over q, measured (solid) against the model (dashed)",
                "residuals": "Residual against the operating variables",
                "hysteresis": "Hysteresis width against the pilot set point"}
    for name, figure in all_figures(comparison).items():
        parts.append(f"<h3>{captions.get(name, name)}</h3>" + _image(figure_png(figure), name))
    return "\n".join(parts)


def diagnosis_table(diagnosis: Diagnosis) -> pd.DataFrame:
    """One row per candidate, best first (display units)."""
    rows = []
    for c in diagnosis.candidates:
        rows.append({"effect": c.name, "what": c.title,
                     "rms after [bar]": from_si(c.rms_after, "bar"), "ΔBIC": c.delta_bic,
                     "significant": "yes" if c.significant else "no",
                     "parameters": "; ".join(str(p) for p in c.params if p.vary),
                     "same as": ", ".join(n for n in c.group if n != c.name)})
    return pd.DataFrame(rows)


def diagnosis_figure(diagnosis: Diagnosis) -> Figure:
    """RMS after adding each candidate, against the current RMS and the noise floor."""
    table = diagnosis_table(diagnosis)
    figure = Figure(figsize=(8, 0.35 * len(table) + 1.6), layout="constrained")
    axes = figure.subplots()
    colours = ["tab:green" if s == "yes" else "tab:gray" for s in table["significant"]]
    positions = np.arange(len(table))[::-1]
    axes.barh(positions, table["rms after [bar]"], color=colours)
    axes.set_yticks(positions, table["effect"])
    axes.axvline(from_si(diagnosis.rms_before, "bar"), color="k", label="current model")
    axes.axvline(from_si(diagnosis.noise_floor, "bar"), color="tab:red", linestyle="--",
                 label="noise floor")
    axes.set_xlabel("residual RMS after adding the candidate [bar]")
    axes.set_title(f"Diagnosis of {diagnosis.model.name} (green: significant)")
    axes.legend(loc="lower right")
    return figure


def diagnosis_section(diagnosis: Diagnosis, heading: str = "Diagnosis") -> str:
    rule = (f"A candidate is significant when ΔBIC &lt; {BIC_THRESHOLD:g} (counted with the "
            f"{diagnosis.effective_samples:.0f} effectively independent samples), the residual "
            f"before exceeds {NOISE_MARGIN:g}× the noise floor, and it removes more than "
            f"{GAIN_FRACTION:g}× the noise floor of RMS.")
    correlations = pd.DataFrame(
        [{"variable": k.split("~")[1], "what": k.split("~")[0], "correlation": v}
         for k, v in diagnosis.correlations.items()])
    return "\n".join([
        f"<h2>{html.escape(heading)}</h2>",
        f'<p class="summary">{html.escape(diagnosis.summary)}</p>',
        f"<p>Each candidate effect was refitted together with the model's free parameters. "
        f"{rule}</p>",
        _table(diagnosis_table(diagnosis), ("effect", "what", "significant", "parameters",
                                            "same as")),
        _image(figure_png(diagnosis_figure(diagnosis)), "diagnosis"),
        "<h3>Correlation of the residual with candidate variables</h3><p><i>residual</i>: the "
        "residual itself; <i>hysteresis</i>: the residual signed by the ramp direction (a misfit "
        "of the hysteresis width).</p>",
        _table(correlations, ("variable", "what")),
    ])


def staircase_table(steps) -> pd.DataFrame:
    rows = []
    for number, step in enumerate(steps, start=1):
        parameters = "; ".join(str(p) for _, p in step.model.parameters() if p.vary)
        rows.append({"step": number, "model": step.model.name,
                     "added": ", ".join(step.added) or "—",
                     "rms [bar]": from_si(step.rms, "bar"), "parameters": parameters})
    return pd.DataFrame(rows)


def staircase_figure(steps, noise_floor: float) -> Figure:
    """The error staircase: RMS after each step, with the noise floor."""
    figure = Figure(figsize=(9, 4.2), layout="constrained")
    axes = figure.subplots()
    rms = [from_si(step.rms, "bar") for step in steps]
    labels = [", ".join(step.added) or step.model.name for step in steps]
    positions = np.arange(len(steps))
    axes.step(positions, rms, where="mid", color="tab:blue")
    axes.plot(positions, rms, "o", color="tab:blue")
    for x, y in zip(positions, rms):
        axes.annotate(f"{y:.2f}", (x, y), textcoords="offset points", xytext=(0, 6),
                      ha="center", fontsize=8)
    floor = from_si(noise_floor, "bar")
    axes.axhline(floor, color="tab:red", linestyle="--", label=f"noise floor {floor:.2f} bar")
    axes.axhline(1.3 * floor, color="tab:red", linestyle=":", label="1.3 × noise floor")
    axes.set_xticks(positions, [f"{i + 1}. {text}" for i, text in enumerate(labels)],
                    rotation=30, ha="right", fontsize=8)
    axes.set_yscale("log")
    axes.set_ylabel("residual RMS [bar]")
    axes.set_title("Error staircase: RMS after each step")
    axes.legend()
    return figure


def staircase_section(workflow) -> str:
    floor = from_si(workflow.noise_floor, "bar")
    final = from_si(workflow.final.rms, "bar")
    return "\n".join([
        "<h2>Error staircase</h2>",
        f'<p class="summary">From the paper\'s basic model to the final one, the residual RMS '
        f"fell from {from_si(workflow.steps[0].rms, 'bar'):.2f} to {final:.2f} bar "
        f"({final / floor:.2f}× the noise floor of {floor:.2f} bar). "
        f"{html.escape(workflow.final_diagnosis.summary)}</p>",
        "<p>Steps 1–4 are the paper's models (BMBE, BMBEBF, CFD maps, CFDA); later steps add the "
        "effect the diagnosis found most likely. Every step refits all free parameters on every "
        "sample.</p>",
        _table(staircase_table(workflow.steps), ("model", "added", "parameters")),
        _image(figure_png(staircase_figure(workflow.steps, workflow.noise_floor)), "staircase"),
    ])


def write_html(path: str | Path, title: str, sections: list[str], note: str = "") -> Path:
    """Write the report (to a temporary name first, then renamed into place)."""
    path = Path(path)
    body = "\n".join(sections)
    document = (f"<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\">"
                f"<title>{html.escape(title)}</title><style>{_STYLE}</style></head><body>"
                f"<h1>{html.escape(title)}</h1><p>{html.escape(note)}</p>{body}</body></html>")
    with atomic_file(path) as stream:
        stream.write(document)
    return path
