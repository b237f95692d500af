"""One self-contained HTML report (figures embedded as PNG data) and the workbench's own figures.

The report is meant for an engineer who never ran the tool: every section says in a sentence what
it shows, numbers carry units, and the figures sit next to the tables they illustrate.
"""

from __future__ import annotations

import base64
import html
import re
import textwrap
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from .display import in_bar
from .naming import WITHIN, library_matches
from ..diagnosis.result import Diagnosis
from ..diagnosis.rule import (BIC_THRESHOLD, GAIN_FRACTION, HELDOUT_GAIN, INCLUSION_MIN,
                              NOISE_MARGIN, OTHER_KIND_GAIN)
from ..core.outputs import atomic_file
from ..core.units import label
from ..workbench.compare import TEXT_RUNS, Comparison
from .figures import BELOW, all_figures, caption, extents, place_panels, png_bytes
from .prose import next_steps, sensor_check_text, summarise, workflow_summary
from ..planning.cfd_runs import operating_points_figure
from .staircase import staircase_figure, staircases_figure, step_label
from .kinds import compare_kinds, comparison_sentences
from .verdict import verdict
from .views import residual_views, run_loops

_STYLE = """
body { font-family: system-ui, sans-serif; max-width: 1200px; margin: 2em auto; color: #222;
       line-height: 1.45; padding: 0 1em; }
h1 { font-size: 1.6em; } h2 { font-size: 1.25em; margin-top: 2em; border-bottom: 1px solid #ccc; }
.scroll { overflow-x: auto; max-width: 100%; }
table { border-collapse: collapse; margin: 0.8em 0; font-size: 0.9em; }
th, td { border: 1px solid #ddd; padding: 0.25em 0.6em; text-align: right; vertical-align: top; }
th { background: #f3f3f3; } td.text, th.text { text-align: left; }
td.text { max-width: 32em; overflow-wrap: break-word; }
figure { margin: 1em 0; } figcaption { color: #555; font-size: 0.9em; max-width: 60em; }
img { max-width: 100%; }
details { margin: 0.3em 0; } summary { cursor: pointer; }
.summary { background: #f5f8ff; border-left: 4px solid #4a7bd0; padding: 0.6em 1em; }
.verdict { background: #fff8e8; border-left: 4px solid #c98a00; padding: 0.3em 1em; }
.verdict p { margin: 0.4em 0; }
.yes { color: #0a7a2a; font-weight: 600; } .no { color: #888; }
nav.contents { background: #fafafa; border: 1px solid #ddd; padding: 0.5em 1em; display: inline-block; }
nav.contents ol { margin: 0.3em 0; padding-left: 1.5em; }
"""

#: longest text in a table cell [characters]: longer lists are summarised (see
#: :func:`parameter_summary`) so that every table fits a 1,400-pixel page
CELL_LENGTH = 120


def _prose(text: str) -> str:
    """Text of the diagnosis' prose as HTML: escaped, its `code` spans (commands, options) set
    as code rather than shown with their backticks."""
    return re.sub(r"`([^`]+)`", r"<code>\1</code>", html.escape(text))


def figure_png(figure: Figure) -> bytes:
    """The figure as PNG bytes (:func:`.figures.png_bytes`)."""
    return png_bytes(figure)


def figure_html(png: bytes, alt: str, caption: str) -> str:
    """An embedded PNG with its caption (which carries what the short title leaves out)."""
    data = base64.b64encode(png).decode("ascii")
    return (f'<figure><img alt="{html.escape(alt)}" src="data:image/png;base64,{data}">'
            f"<figcaption>{html.escape(caption)}</figcaption></figure>")


def parameter_summary(parameters, limit: int = CELL_LENGTH) -> str:
    """The fitted parameters in one line of at most ``limit`` characters.

    Parameters of one run each (``delta_R01``, ``delta_R02``, ...) are shown as their range; what
    does not fit is counted, not cut mid-word (every value is in the model file and the JSON).
    """
    parameters = [p for p in parameters if p.vary]
    per_run = [p for p in parameters if p.scope is not None]
    texts = [str(p) for p in parameters if p.scope is None]
    if per_run:
        values = [p.display_value for p in per_run]
        template = per_run[0].name.rsplit("_", 1)[0]
        texts.append(f"{template} per run: {min(values):+.3g} to {max(values):+.3g} "
                     f"{label(per_run[0].unit)} ({len(per_run)} runs)")
    shown: list[str] = []
    for index, text in enumerate(texts):
        remaining = len(texts) - index  # this one and those after it
        room_for_tail = len(f"; … {remaining - 1} more") if remaining > 1 else 0
        if len("; ".join([*shown, text])) + room_for_tail > limit:
            shown.append(f"… {remaining} more")
            break
        shown.append(text)
    return "; ".join(shown)


def table_html(frame: pd.DataFrame, text_columns: tuple[str, ...] = (),
               formats: dict[str, str] | None = None) -> str:
    """An HTML table; numbers as ``formats[column]`` (a format spec such as ``".3f"``) or with
    four significant digits."""
    formats = formats or {}
    head = "".join(f'<th class="{"text" if c in text_columns else ""}">{html.escape(str(c))}</th>'
                   for c in frame.columns)
    rows = []
    for row in frame.itertuples(index=False):
        cells = []
        for column, value in zip(frame.columns, row):
            if isinstance(value, (bool, np.bool_)):
                text = "yes" if value else "no"
            elif isinstance(value, (float, np.floating)) and not np.isfinite(value):
                # a run without both ramps has no hysteresis width: say so, not "nan"
                text = "not measured" if "hysteresis" in str(column) else ""
            elif isinstance(value, (float, np.floating)):
                text = format(value, formats.get(column, ".4g"))
            else:  # long effect names may wrap after their underscores
                text = html.escape(str(value)).replace("_", "_<wbr>")
            cells.append(f'<td class="{"text" if column in text_columns else ""}">{text}</td>')
        rows.append("<tr>" + "".join(cells) + "</tr>")
    # a table wider than the page scrolls inside its box, the page itself never does
    return (f'<div class="scroll"><table><thead><tr>{head}</tr></thead>'
            f"<tbody>{''.join(rows)}</tbody></table></div>")


def readable(name: str) -> str:
    """A model name that can wrap: ``cfda+friction_viscous`` as ``cfda + friction_viscous``."""
    return name.replace("+", " + ")


def figure_pngs(comparison: Comparison) -> dict[str, bytes]:
    """Every figure of a comparison rendered as PNG, by name (:func:`.figures.all_figures`)."""
    return {name: figure_png(figure) for name, figure in all_figures(comparison).items()}


def comparison_section(comparison: Comparison, heading: str,
                       pngs: dict[str, bytes] | None = None) -> str:
    """Headline, per-run table, p_Pe × temperature table, worst regions and the figures
    (``pngs``: the figures already rendered, by name; else they are drawn here)."""
    rms, floor = in_bar(comparison.rms), in_bar(comparison.noise_floor)
    runs = comparison.runs.assign(extrapolating=100 * comparison.runs["extrapolating_fraction"])
    shown_runs = ""
    if len(runs) > TEXT_RUNS:  # a big log: its worst runs here, every run in runs.csv
        runs = runs.sort_values("rms_bar", ascending=False, kind="stable").head(TEXT_RUNS)
        shown_runs = (f" The {TEXT_RUNS} runs of largest RMS are shown, of "
                      f"{len(comparison.runs)}; runs.csv holds every run.")
    runs = runs[["run", "temperature_C", "p_Pe_bar", "samples", "failed", "rms_bar", "bias_bar",
                 "hysteresis_measured_bar", "hysteresis_model_bar", "hysteresis_error_bar",
                 "extrapolating"]]
    runs.columns = ["run", "T [°C]", "p_Pe [bar]", "samples", "not solved", "RMS [bar]",
                    "bias [bar]", "hysteresis measured [bar]", "hysteresis model [bar]",
                    "hysteresis error [bar]", "maps extrapolate [%]"]
    pivot = comparison.pivot.reset_index()
    pivot.columns = ["p_Pe [bar]"] + [f"{c:g} °C" for c in comparison.pivot.columns]
    regions = comparison.regions.head(10).assign(
        extrapolating=lambda r: 100 * r["extrapolating_fraction"])
    regions = regions[["q_low_lpm", "q_high_lpm", "temperature_C", "p_Pe_bar", "samples",
                       "rms_bar", "bias_bar", "extrapolating"]]
    regions.columns = ["q from [L/min]", "q to [L/min]", "T [°C]", "p_Pe [bar]", "samples",
                       "RMS [bar]", "bias [bar]", "maps extrapolate [%]"]
    bar = {column: ".2f" for column in [*runs.columns, *regions.columns, *pivot.columns[1:]]
           if "[bar]" in column or "°C" in column or "L/min" in column}
    bar.update({"T [°C]": ".1f", "p_Pe [bar]": "g", "maps extrapolate [%]": ".0f",
                "q from [L/min]": ".1f", "q to [L/min]": ".1f"})
    parts = [
        f"<h2>{html.escape(heading)}</h2>",
        f"<p>Model <b>{html.escape(readable(comparison.model))}</b> replayed over every run "
        f"(friction as a play). Residual = model − measured Δp. RMS <b>{rms:.3f} bar</b>; noise "
        f"floor estimated from the data's sample-to-sample scatter <b>{floor:.3f} bar</b> "
        f"({comparison.rms_over_noise:.2f}×). The maps extrapolate at "
        f"{100 * comparison.extrapolating_fraction:.0f} % of the samples.</p>",
        "<h3>Per run</h3><p>Bias is the mean residual; hysteresis width is Δp on the ramp up minus "
        "Δp on the ramp down at equal flow; <i>maps extrapolate</i> is the share of samples where "
        f"the model leaves its maps' data.{shown_runs}</p>", table_html(runs, ("run",), bar),
        "<h3>RMS by pilot set point and temperature [bar]</h3>", table_html(pivot, (), bar),
        "<h3>Worst operating regions</h3><p>Flow band × temperature × set point, worst first.</p>",
        table_html(regions, (), bar),
    ]
    headings = {"dp_vs_q": "Δp over q",
                "residuals": "Residual against the operating variables",
                "hysteresis": "Hysteresis width against the pilot set point"}
    captions = {"dp_vs_q": "Measured samples are light dots, the model a dark line, both in the "
                           "colour of the run's pilot set point.",
                "residuals": "The grey band is ± the noise floor; structure outside it is what "
                             "the model misses.",
                "hysteresis": "Filled circles: measured; open squares: the model; the line "
                              "between them is the model's error."}
    if pngs is None:
        pngs = figure_pngs(comparison)
    for name, png in pngs.items():
        parts.append(f"<h3>{headings.get(name, name)}</h3>"
                     + figure_html(png, name, f"{caption(comparison)} {captions.get(name, '')}"))
    return "\n".join(parts)


#: the diagnosis table's columns shown as one in the report (the CSV keeps each): {shown
#: heading: the columns, in bar}
_JOINED_COLUMNS = {
    "held out: runs / T / p_P [bar]": ("held out [bar]", "T left out [bar]",
                                       "p_P left out [bar]"),
    "median line / half-width [bar]": ("median line [bar]", "half-width [bar]"),
}


def _joined(table: pd.DataFrame, columns: tuple[str, ...]) -> list[str]:
    """Each row's ``columns`` as one text, "1.23 / 0.98" ("–" where a value is missing: a
    per-run candidate's held-out RMS, or a condition the log does not vary)."""
    return ["\u202f/\u202f".join(  # narrow no-break spaces: one line per cell
            "–" if not np.isfinite(v) else f"{v:.2f}" for v in row)
            for row in table[list(columns)].itertuples(index=False)]


def _diagnosis_shown(table: pd.DataFrame) -> pd.DataFrame:
    """The diagnosis table as the report shows it, narrow enough for a 1,000-pixel window:
    each effect as its title with its name after it, and the held-out columns and the two
    hysteresis views each as one column (:data:`_JOINED_COLUMNS`)."""
    shown = table.copy()
    shown["effect"] = [f"{title} ({name})" for title, name in zip(table["what"],
                                                                    table["effect"])]
    shown = shown.drop(columns="what")
    for heading, columns in _JOINED_COLUMNS.items():
        at = shown.columns.get_loc(columns[0])
        texts = _joined(table, columns)
        shown = shown.drop(columns=list(columns))
        shown.insert(at, heading, texts)
    return shown


def diagnosis_table(diagnosis: Diagnosis) -> pd.DataFrame:
    """One row per candidate, best first (display units)."""
    rows = []
    withheld = None if diagnosis.declined is None else diagnosis.declined.claim.name
    for c in diagnosis.candidates:
        rows.append({"effect": c.name, "what": c.title, "category": c.category,
                     "rms after [bar]": in_bar(c.rms_after),
                     "held out [bar]": in_bar(c.heldout_rms),
                     "T left out [bar]": in_bar(c.heldout.get("temperature", np.nan)),
                     "p_P left out [bar]": in_bar(c.heldout.get("pilot pressure", np.nan)),
                     "median line [bar]": in_bar(c.median_rms),
                     "half-width [bar]": in_bar(c.half_width_rms), "ΔBIC": c.delta_bic,
                     "chosen in [%]": 100.0 * c.inclusion,
                     "significant": ("sensor check" if c.per_run
                                     else "yes" if c.significant
                                     else "withheld: a look-alike of another kind"
                                     if c.name == withheld else "no"),
                     "parameters": parameter_summary(c.params),
                     "same as": ", ".join(n for n in c.group if n != c.name)})
    return pd.DataFrame(rows)


def diagnosis_figure(diagnosis: Diagnosis) -> Figure:
    """RMS after adding each candidate: a line from the current RMS down to the candidate's, on
    an axis zoomed to the candidates' range so that close ones can be told apart."""
    table = diagnosis_table(diagnosis)
    figure = Figure(figsize=(8, 0.35 * len(table) + 1.6))
    axes = figure.subplots()
    before = float(in_bar(diagnosis.rms_before))
    floor = float(in_bar(diagnosis.noise_floor))
    after = table["rms after [bar]"].to_numpy(float)
    colours = ["tab:green" if s == "yes" else "tab:gray" for s in table["significant"]]
    positions = np.arange(len(table))[::-1]
    axes.hlines(positions, after, before, color=colours, linewidth=2.0)
    axes.scatter(after, positions, color=colours, zorder=3)
    for x, y in zip(after, positions):
        # on the side away from the current RMS's line: a candidate that made it worse to the
        # right, so that its value never sits across the line
        worse = x > before
        axes.annotate(f"{x:.3f}", (x, y), textcoords="offset points",
                      xytext=(4 if worse else -4, 0), ha="left" if worse else "right",
                      va="center", fontsize=7)
    axes.set_yticks(positions, table["effect"])
    axes.axvline(before, color="k", label=f"current model {before:.3f} bar")
    # zoomed to the candidates and the current RMS (not from 0), so that close candidates stay
    # apart; the noise floor joins the range only when it is near, else it is named at the edge
    values = np.concatenate([after[np.isfinite(after)], [before]])
    span = max(float(values.max() - values.min()), 0.01 * before)
    if values.min() - floor <= 0.5 * span:
        values = np.append(values, floor)
        span = float(values.max() - values.min())
    low = values.min() - 0.15 * span
    high = values.max() + (0.15 if np.any(after > before) else 0.05) * span
    axes.set_xlim(low, high)
    if floor >= low:
        axes.axvline(floor, color="tab:red", linestyle="--", label=f"noise floor {floor:.3f} bar")
    else:
        axes.plot([], [], color="tab:red", linestyle="--",
                  label=f"noise floor {floor:.3f} bar (off the axis, to the left)")
    axes.set_xlabel("residual RMS after adding the candidate [bar] (axis zoomed)")
    axes.set_title("Diagnosis: RMS after each candidate (green: significant)")
    legend = figure.legend(loc="lower center", ncols=2, fontsize=8)  # clear of every line
    # placed by the legend's and the effect names' extents, measured once, instead of the
    # constrained layout, which measured every label over again at each save (as the
    # staircase's figure): the names left of the panel, the legend under its axis' label
    (_, legend_height), *names = extents(figure, legend, *axes.get_yticklabels())
    place_panels(figure, above=0.4, left=max((width for width, _ in names), default=0.0) + 0.2,
                 right=0.25, below=legend_height + BELOW, across=0.0, down=0.0)
    return figure


def shape_figure(candidate) -> Figure:
    """A shape-free find against its variable with its one-σ band, and the closest library
    terms of its kind fitted to it (:mod:`surrogate.reporting.naming`)."""
    curve = candidate.curve
    figure = Figure(figsize=(7.5, 4.0), layout="constrained")
    axes = figure.subplots()
    axes.fill_between(curve.x, curve.value - WITHIN * curve.band,
                      curve.value + WITHIN * curve.band, color="tab:blue", alpha=0.15,
                      label=f"±{WITHIN:g}σ band")
    axes.plot(curve.x, curve.value, color="tab:blue", linewidth=2.0,
              label=f"found: {candidate.name}")
    for match, style in zip(library_matches(candidate.name, curve)[:2], ("--", ":")):
        verdict = "fits" if match.fits else f"departs by {match.worst:.1f}σ"
        axes.plot(curve.x, match.fitted, color="tab:orange", linestyle=style,
                  label=f"closest library term: {match.name} ({verdict})")
    axes.axhline(0.0, color="k", linewidth=0.5)
    axes.set_xlabel(f"{curve.label} [{label(curve.unit)}]")
    axes.set_ylabel(f"{candidate.effect.quantity} [{label(curve.value_unit)}]")
    axes.set_title(f"The shape the log drew: {candidate.effect.quantity} of {curve.variable}")
    axes.legend(fontsize=8)
    return figure


def diagnosis_section(diagnosis: Diagnosis, heading: str = "Diagnosis") -> str:
    rule = (f"A candidate is significant when it explains more than the maps' own error could "
            f"(ΔBIC &lt; {BIC_THRESHOLD:g} once smooth map-discrepancy terms of the maps' "
            f"calibrated size, refitted with the parameters, have explained what they can, "
            f"counted with the "
            f"{diagnosis.effective_samples:.0f} effectively independent samples), lowers the "
            f"RMS on held-out runs (now {in_bar(diagnosis.heldout_before):.3f} bar, each "
            f"run predicted by a refit to the others) by more than {100 * HELDOUT_GAIN:g} %, "
            "and so the RMS with one temperature or one pilot pressure left out (<i>held out: "
            "runs / T / p_P</i>), the residual before exceeds "
            f"{NOISE_MARGIN:g}× the noise floor, it removes more than {GAIN_FRACTION:g}× the "
            "noise floor of RMS, and it "
            "narrows the view of the hysteresis its physics acts on (a friction term the "
            "half-width, any other term the median line). "
            "<i>chosen in</i>: the share of bootstrap resamples over runs in which it would be "
            f"the one added; a discovery (with its look-alikes) must be chosen in at least "
            f"{100 * INCLUSION_MIN:.0f} % of them. A claim of valve physics must also predict "
            f"the runs, or a temperature or pilot pressure, left out {100 * OTHER_KIND_GAIN:g} % "
            "better than every shape-free term of another kind and the maps' own error, each "
            "fitted with the maps' error beside it; otherwise it is <i>withheld</i> and the "
            "summary names them. A parameter per run cannot predict another "
            "run: such candidates are "
            "sensor checks, never part of the model. <i>median line</i> and <i>half-width</i>: "
            "the RMS of the runs' residual split into the mean of the up and down ramps at "
            f"equal flow (now {in_bar(diagnosis.median_before):.3f} bar) and half "
            f"their difference (now {in_bar(diagnosis.half_width_before):.3f} bar); "
            "map error moves the first, friction the second.")
    correlations = pd.DataFrame(
        [{"variable": k.split("~")[1], "what": k.split("~")[0], "correlation": v}
         for k, v in diagnosis.correlations.items()])
    return "\n".join([
        f"<h2>{html.escape(heading)}</h2>",
        f'<p class="summary">{_prose(summarise(diagnosis))}</p>',
        f"<p>Each candidate effect was refitted together with the model's free parameters. "
        f"{rule}</p>",
        table_html(_diagnosis_shown(diagnosis_table(diagnosis)),
                   ("effect", "category", "significant", "parameters", "same as"),
                   {"rms after [bar]": ".3f", "ΔBIC": ".1f", "chosen in [%]": ".0f"}),
        figure_html(figure_png(diagnosis_figure(diagnosis)), "diagnosis",
                    f"Diagnosis of {readable(diagnosis.model.name)}: each candidate's line runs "
                    "from the current RMS to the RMS after refitting with it."),
        *([figure_html(figure_png(shape_figure(diagnosis.best)), "shape",
                       f"The shape-free term {diagnosis.best.name} as fitted, with its band "
                       f"({WITHIN:g} standard deviations from the fit's covariance), and the "
                       "library terms of its kind fitted to it: one inside the band says the same "
                       "with a name.")]
              if diagnosis.best is not None and diagnosis.best.shape_free else []),
        "<h3>Correlation of the residual with candidate variables</h3><p><i>residual</i>: the "
        "residual itself; <i>hysteresis</i>: the residual signed by the ramp direction (a misfit "
        "of the hysteresis width).</p>",
        table_html(correlations, ("variable", "what"), {"correlation": "+.3f"}),
    ])


def staircase_table(steps) -> pd.DataFrame:
    """One row per step: what was added and the RMS after it; every fitted parameter too (the
    CSV keeps them all; the report shows them per step, folded)."""
    rows = []
    for number, step in enumerate(steps, start=1):
        parameters = "; ".join(str(p) for p in step.model.parameters().values() if p.vary)
        rows.append({"step": number, "added": ", ".join(step.added) or step.model.name,
                     "category": (step.category or "—")
                     + (", free shape" if getattr(step, "shape_free", False) else ""),
                     "rms [bar]": in_bar(step.rms),
                     "held out [bar]": in_bar(step.heldout_rms),
                     "parameters": parameters})
    return pd.DataFrame(rows)


def _step_parameters(number: int, step) -> str:
    """A folded table of one step's fitted parameters."""
    rows = [{"parameter": key, "value": p.display_value,
             "± stderr": p.display_stderr if p.display_stderr is not None else float("nan"),
             "unit": label(p.unit), "note": "at bound" if p.at_bound else ""}
            for key, p in step.model.parameters().items() if p.vary]
    what = ", ".join(step.added) or step.model.name
    if not rows:
        return f"<details><summary>Step {number} ({html.escape(what)}): no fitted parameters" \
               "</summary></details>"
    return (f"<details><summary>Step {number} ({html.escape(what)}): {len(rows)} fitted "
            f"parameter(s)</summary>{table_html(pd.DataFrame(rows), ('parameter', 'unit', 'note'))}"
            "</details>")


def staircase_section(workflow, png: bytes | None = None) -> str:
    """The staircase's table, each step's parameters and its figure (``png``: the figure
    already rendered, as for staircase.png; else it is drawn here)."""
    if png is None:
        png = figure_png(staircase_figure(workflow.steps, workflow.noise_floor))
    floor = in_bar(workflow.noise_floor)
    final = in_bar(workflow.final.rms)
    return "\n".join([
        "<h2>Error staircase</h2>",
        f'<p class="summary">From the paper\'s basic model to the final one, the residual RMS '
        f"fell from {in_bar(workflow.steps[0].rms):.2f} to {final:.2f} bar "
        f"({final / floor:.2f}× the noise floor of {floor:.2f} bar). "
        f"{_prose(workflow_summary(workflow))}</p>",
        "<p>Steps 1–4 are the paper's models (BMBE, BMBEBF, CFD maps, CFDA); later steps add the "
        "effect the diagnosis found most likely. Every step refits all free parameters on every "
        "sample. <i>held out</i> is the RMS on runs the step's fit did not see (each run "
        "predicted by a refit to the others): an added effect must lower it, and the RMS with "
        "one temperature or one pilot pressure left out too. "
        "<i>category</i> says what the step added: valve physics, a correction of the CFD maps, "
        "or a sensor error; <i>free shape</i> marks a term whose shape the data drew, which "
        "no library effect has (its effects file, found_*.py, is in the output folder).</p>",
        _category_story(workflow),
        table_html(staircase_table(workflow.steps).drop(columns="parameters").assign(
                **{"× noise floor": [step.rms / workflow.noise_floor for step in workflow.steps]}),
                ("added", "category"), {"rms [bar]": ".3f", "held out [bar]": ".3f",
                                        "× noise floor": ".2f"}),
        "<p>The parameters fitted at each step (all of them are in <i>staircase.csv</i> and the "
        "final model file):</p>",
        *(_step_parameters(number, step) for number, step in enumerate(workflow.steps, 1)),
        figure_html(png, "staircase",
                    f"Residual RMS after each step on {workflow.log.source}; the final model is "
                    f"{readable(workflow.final.model.name)}."),
    ])


def _sized(model, name: str) -> str:
    """An effect of ``model`` with its fitted values: ``pilot_transducer_offset (delta =
    4.8494 ± 0.076 bar)``; a per-run effect as its range (:func:`parameter_summary`)."""
    if not model.has_effect(name):
        return name
    return f"{name} ({parameter_summary(model.effect(name).params.values(), 80)})"


def _category_story(workflow) -> str:
    """The added effects grouped by category, in plain words."""
    found: dict[str, list[str]] = {}
    for step in workflow.steps[4:] if workflow.maps else workflow.steps[1:]:
        found.setdefault(step.category, []).extend(step.added)
    lines = []
    if found.get("physics"):
        lines.append(f"<b>Valve physics the data contain</b>: {', '.join(found['physics'])}.")
    if found.get("map correction"):
        lines.append(f"<b>Corrections of the CFD maps</b>: {', '.join(found['map correction'])}"
                     ": they patch where the maps are wrong (new CFD runs there would replace "
                     "them; see the diagnosis' map limits and <code>suggest-cfd</code>).")
    if found.get("sensor"):
        sized = [_sized(workflow.final.model, name) for name in found["sensor"]]
        lines.append(f"<b>Sensor errors</b>: {html.escape('; '.join(sized))}: check the bench.")
    for category, names in found.items():
        if " or " in category:  # look-alikes: one finding, explanations of different kinds
            sized = "; ".join(_sized(workflow.final.model, name) for name in names)
            lines.append(f"<b>One finding, {html.escape(category)}</b>: {html.escape(sized)} "
                         "stands for look-alikes this log cannot tell apart (see its step's "
                         "reason); check the cheaper explanation.")
    lines += _identifiability_lines(workflow)
    if workflow.dropped:
        lines.append(f"<b>Refused step</b>: {html.escape(workflow.dropped)}.")
    checks = workflow.final_diagnosis.sensor_checks
    if checks:
        lines.append("<b>Sensor checks</b> (per-run readings, never part of the model): "
                     + html.escape("; ".join(map(sensor_check_text, checks))) + ".")
    if not lines:
        lines.append("The diagnosis added nothing beyond the paper's steps.")
    return "<p>" + "<br>".join(lines) + "</p>"


def _identifiability_lines(workflow) -> list[str]:
    """What the steps pushed to a bound, and which of the final model's parameters the log
    cannot separate (:mod:`surrogate.fitting.identifiability`)."""
    lines = []
    for number, step in enumerate(workflow.steps, start=1):
        for moved in step.pushed:
            lines.append(f"<b>Driven to a bound</b> at step {number}: "
                         f"{html.escape(moved.parameter)} went from {moved.before:.4g} to {moved.after:.4g} "
                         f"{html.escape(label(moved.unit))} when "
                         f"{html.escape(', '.join(moved.by))} was added: that term took over "
                         "what it carried, and the bound, not the data, now holds it.")
    for pair in workflow.final.entangled:
        lines.append(f"<b>Not separable on this log</b>: {html.escape(pair.first)} and "
                     f"{html.escape(pair.second)} (their estimates correlate at "
                     f"{pair.correlation:+.2f}): the log fixes their combination, not each.")
    return lines


#: runs above which a report draws no loop per run (a big log's loops are in compare's figures)
LOOP_RUNS = 24


def misfit_figures(workflow) -> dict[str, bytes]:
    """The workflow's misfit at the scale of a bar, as PNG by name: the residual's median line
    and half-width against the state before and after each added effect (from CFDA on, or from
    the starting model), and each run's loop with the first and the final model."""
    steps = workflow.steps[3:] if workflow.maps else workflow.steps
    # legend entries wrapped so that three fit side by side on a figure 14 inches wide
    models = [("\n".join(textwrap.wrap(f"{workflow.steps.index(step) + 1}. "
                                       + step_label(step, 200).replace("\n", " "), 44)),
               step.log_replay) for step in steps]
    pngs = {}
    views = residual_views(workflow.log, models)
    if views is not None:
        pngs["residual_views"] = figure_png(views)
    if len(workflow.log.run_ids) <= LOOP_RUNS:
        pngs["run_loops"] = figure_png(run_loops(workflow.log, [models[0], models[-1]]))
    if workflow.final.model.flow_map.coverage is not None:
        pngs["operating_points"] = figure_png(operating_points_figure(workflow.final.log_replay,
                                                                      workflow.final.model))
    return pngs


def next_steps_section(workflow) -> str:
    """What to do next, each line from a finding of the workflow (:func:`.prose.next_steps`)."""
    items = "".join(f"<li>{_prose(step)}</li>" for step in next_steps(workflow))
    return f"<h2>What to do next</h2><ul>{items}</ul>"


def misfit_section(workflow, pngs: dict[str, bytes]) -> str:
    """Where the misfit lies, before and after each added effect (:func:`misfit_figures`)."""
    parts = ["<h2>Where the misfit lies</h2>",
             "<p>Each run's residual, model minus measured, split bin by bin along the flow into "
             "its <i>median line</i> (the mean of the up and down ramps: a map error moves it) "
             "and its <i>half-width</i> (half their difference: friction changes it), against the "
             "flow, the opening, the pilot pressure and the temperature: one line per model, "
             "before and after each added effect. A term that helps brings its line to zero "
             "where it acts.</p>"]
    if "residual_views" in pngs:
        parts.append(figure_html(pngs["residual_views"], "residual views",
                                 "The residual's median line (top) and half-width (bottom), per "
                                 "run and flow bin (dots: the last model), against the state; "
                                 "lines: the bins' median for each model."))
    if "run_loops" in pngs:
        parts.append(figure_html(pngs["run_loops"], "every run's loop",
                                 "Every run's Δp(q), each on its own scale: measured ramps against "
                                 "the first and the final model."))
    if "operating_points" in pngs:
        parts.append(figure_html(pngs["operating_points"], "where the bench operates",
                                 "The log's openings and flows in the final model, shaded by the "
                                 "Δp standard deviation its maps imply, over the CFD's sampled "
                                 "openings (dashed): a misfit between them, where no CFD run lies, "
                                 "may be the maps'. suggest-cfd ranks the CFD runs that would "
                                 "settle it."))
    return "\n".join(parts)


def staircases_section(workflows: dict, main: str, scores: dict | None = None) -> str:
    """The staircases of every map kind side by side, and why ``main`` is the report's."""
    rows = []
    for kind, workflow in workflows.items():
        # the kinds' cross-validation scores where they chose the main kind; chosen with --maps,
        # none were computed and the column is left out rather than shown empty
        scored = ({"flow-force CV error [%]": 100 * scores[kind] if kind in scores
                   else float("nan")} if scores else {})
        rows.append({"maps": kind + (" (main)" if kind == main else ""), **scored,
                     "steps": len(workflow.steps),
                     "added by diagnosis": ", ".join(
                         name for step in workflow.steps[4:] for name in step.added) or "—",
                     "final rms [bar]": in_bar(workflow.final.rms),
                     "× noise floor": workflow.final.rms / workflow.noise_floor})
    why = ("chosen with --maps" if not scores else
           "the kind whose flow force is the most accurate by cross-validation (mean relative "
           "RMS error over the four schemes, table's second column)")
    return "\n".join([
        "<h2>The staircase on every kind of map</h2>",
        f"<p>The same loop run on grid, neural-network and Gaussian-process maps, on the kinds "
        f"beside the main one with the library's effects only (a term of free shape there "
        f"would mostly take up that kind's own map error). The rest of "
        f"this report follows the <b>{html.escape(main)}</b> maps: {why}. Each kind's maps err "
        f"in their own way, and its loop adds what makes up for that error beside what the "
        f"valve holds: below, the effects the loops added, grouped by the physics they stand "
        f"for, and which to trust.</p>",
        table_html(pd.DataFrame(rows), ("maps", "added by diagnosis"),
                   {"flow-force CV error [%]": ".1f", "final rms [bar]": ".3f",
                    "× noise floor": ".2f"}),
        "<h3>Where the kinds agree, where they differ, and what to trust</h3><ul>"
        + "".join(f"<li>{html.escape(sentence)}</li>"
                  for sentence in comparison_sentences(compare_kinds(workflows, main)))
        + "</ul>",
        # the main kind's staircase is drawn above: only the others here, on its RMS axis
        figure_html(figure_png(staircases_figure(
            {kind: workflow for kind, workflow in workflows.items() if kind != main})),
            "staircases of the comparison kinds",
            f"Residual RMS after each step on the other kinds of map (the {html.escape(main)} "
            "maps' staircase is the first figure of this report)."),
    ])


def verdict_html(workflow) -> str:
    """The workflow's three-line verdict (:func:`.verdict.verdict`), to open its report."""
    found = verdict(workflow)
    lines = "".join(f"<p><b>{label}</b>: {_prose(text)}</p>" for label, text in
                    (("Lacks", found.lacks), ("Where", found.where), ("Next", found.next)))
    return f'<div class="verdict">{lines}</div>'


def write_html(path: str | Path, title: str, sections: list[str], note: str = "",
               opening: str = "") -> Path:
    """Write the report (to a temporary name first, then renamed into place): ``opening``
    (HTML) under its title, then ``note``, and its sections' headings linked from a list of
    contents where there are several."""
    path = Path(path)
    body, contents = with_contents("\n".join(sections))
    document = (f"<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\">"
                f"<title>{html.escape(title)}</title><style>{_STYLE}</style></head><body>"
                f"<h1>{html.escape(title)}</h1>{opening}<p>{html.escape(note)}</p>{contents}"
                f"{body}</body></html>")
    with atomic_file(path) as stream:
        stream.write(document)
    return path


def with_contents(body: str) -> tuple[str, str]:
    """``body`` with an id on each ``<h2>``, and the list of contents linking them ("" for a
    page of fewer than three sections)."""
    headings = []

    def anchored(match) -> str:
        headings.append(match.group(1))
        return f'<h2 id="section-{len(headings)}">{match.group(1)}</h2>'

    body = re.sub(r"<h2>(.*?)</h2>", anchored, body)
    if len(headings) < 3:
        return body, ""
    items = "".join(f'<li><a href="#section-{number}">{heading}</a></li>'
                    for number, heading in enumerate(headings, start=1))
    return body, f'<nav class="contents"><b>Contents</b><ol>{items}</ol></nav>'
