"""The fleet's HTML report: how the valves scatter, which stand out and why, and what the outliers'
steady Δp(q) looks like beside the fleet's median valve.

Self-contained, like the workbench's reports (:mod:`surrogate.reporting.report`): the figures are
embedded PNGs. Everything here is drawn from the per-valve results and the model; no log is read
again.
"""

from __future__ import annotations

import html
from dataclasses import dataclass

import numpy as np
import pandas as pd
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator

from ..export.characteristic import steady_characteristic
from ..export.valve_only import valve_physics
from ..model import ValveModel
from ..reporting.report import figure_html, figure_png, table_html, write_html
from ..core.units import from_si, to_si
from .population import OutlierAnalysis

#: outliers whose Δp(q) is drawn (the table lists every one)
CURVES_SHOWN = 8
#: parameters in the pair plot (the histograms show every figure)
PAIR_PARAMETERS = 4
#: flows per branch of a drawn Δp(q), from the largest flow / RANGE to the largest
CURVE_POINTS, CURVE_RANGE = 60, 30.0
OUTLIER_COLOUR, FLEET_COLOUR = "tab:red", "tab:blue"
#: legend text [pt]: 10 px or more once a page 1,000 px wide shrinks the widest figure to fit
LEGEND_SIZE = 13
#: a fleet smaller than this shows each valve by its serial (a dot per valve, named) instead of
#: a histogram, which says nothing of three values
NAMED_VALVES = 20


@dataclass(frozen=True)
class FleetSummary:
    """What the report shows.

    Attributes
    ----------
    table : pandas.DataFrame
        valves.csv: one row per fitted valve.
    figures : list of str
        The columns the population statistics are taken over (parameters, then the RMS).
    parameters : dict of str to str
        Column of each free parameter -> its ``"effect.parameter"`` key.
    population : dict
        population.json's ``figures`` (median, spreads, range per figure).
    correlations : pandas.DataFrame
    analysis : OutlierAnalysis
    failed : pandas.DataFrame
        failed.csv.
    model_label : str
    diagnosed : bool
    """

    table: pd.DataFrame
    figures: list[str]
    parameters: dict[str, str]
    population: dict
    correlations: pd.DataFrame
    analysis: OutlierAnalysis
    failed: pd.DataFrame
    model_label: str
    diagnosed: bool


def histograms_figure(table: pd.DataFrame, columns: list[str], flagged: set[str]) -> Figure:
    """One histogram per figure, the outliers' values marked below the axis; for a fleet of
    fewer than :data:`NAMED_VALVES` valves, a dot per valve against its serial instead."""
    count = len(columns)
    across = min(3, count)
    down = int(np.ceil(count / across))
    named = len(table) < NAMED_VALVES
    height = max(3.0, 0.28 * len(table) + 1.2) if named else 3.0
    figure = Figure(figsize=(4.2 * across, height * down), layout="constrained")
    axes = figure.subplots(down, across, squeeze=False).ravel()
    outlier = table["serial"].isin(flagged).to_numpy()
    serials = table["serial"].astype(str).to_numpy()
    for ax, column in zip(axes, columns):
        values = pd.to_numeric(table[column], errors="coerce").to_numpy(float)
        finite = np.isfinite(values)
        if named:
            _named_dots(ax, values, serials, outlier, fontsize=8)
            ax.grid(axis="x", alpha=0.3)
        else:
            ax.hist(values[finite & ~outlier],
                    bins=min(30, max(5, int(finite.sum() ** 0.5) + 1)), color=FLEET_COLOUR,
                    alpha=0.75)
            if np.any(finite & outlier):
                ax.plot(values[finite & outlier], np.zeros(int(np.sum(finite & outlier))), "|",
                        color=OUTLIER_COLOUR, markersize=18, markeredgewidth=2,
                        label="the outliers' values", clip_on=False)
            ax.set_ylabel("valves")
        ax.xaxis.set_major_locator(MaxNLocator(5))
        ax.set_xlabel(column, fontsize=9)
    for ax in axes[count:]:
        ax.set_visible(False)
    # one legend for the figure, large enough to read once the page shrinks the image
    handles, labels = axes[0].get_legend_handles_labels()
    if handles:
        figure.legend(handles[:1], labels[:1], loc="outside upper right", fontsize=LEGEND_SIZE)
    return figure


def _named_dots(ax, values: np.ndarray, serials: np.ndarray, outlier: np.ndarray,
                fontsize: float) -> None:
    """Each valve's value as a dot on a row of its own, labelled by its serial, the outliers
    in red (a fleet too small for a histogram)."""
    rows = np.arange(len(values))
    finite = np.isfinite(values)
    ax.plot(values[finite & ~outlier], rows[finite & ~outlier], "o", color=FLEET_COLOUR)
    if np.any(finite & outlier):
        ax.plot(values[finite & outlier], rows[finite & outlier], "o", color=OUTLIER_COLOUR,
                label="the outliers")
    ax.set_yticks(rows, serials, fontsize=fontsize)
    ax.set_ylim(len(values) - 0.5, -0.5)


def pair_figure(table: pd.DataFrame, columns: list[str], flagged: set[str]) -> Figure:
    """Every pair of ``columns`` against each other, the outliers in red."""
    count = len(columns)
    figure = Figure(figsize=(2.6 * count + 0.6, 2.6 * count + 0.4), layout="constrained")
    axes = figure.subplots(count, count, squeeze=False)
    outlier = table["serial"].isin(flagged).to_numpy()
    values = {c: pd.to_numeric(table[c], errors="coerce").to_numpy(float) for c in columns}
    for i, row in enumerate(columns):
        for j, column in enumerate(columns):
            ax = axes[i, j]
            if i == j and len(table) < NAMED_VALVES:  # a small fleet: each valve, named
                _named_dots(ax, values[column], table["serial"].astype(str).to_numpy(),
                            outlier, fontsize=6)
            elif i == j:
                finite = np.isfinite(values[column])
                ax.hist(values[column][finite], bins=20, color=FLEET_COLOUR, alpha=0.75)
            else:
                ax.plot(values[column][~outlier], values[row][~outlier], ".",
                        color=FLEET_COLOUR, markersize=3, alpha=0.6)
                ax.plot(values[column][outlier], values[row][outlier], "o",
                        color=OUTLIER_COLOUR, markersize=5)
                # the outliers by name, and every valve in a small fleet
                named = np.ones(len(table), bool) if len(table) < NAMED_VALVES else outlier
                for k in np.flatnonzero(named & np.isfinite(values[column])
                                        & np.isfinite(values[row])):
                    ax.annotate(str(table["serial"].iloc[k]), (values[column][k],
                                                               values[row][k]),
                                fontsize=6, xytext=(3, 2), textcoords="offset points")
            ax.tick_params(labelsize=7)
            # few ticks: long values (K2 in N/bar) overlapped at the default count
            ax.xaxis.set_major_locator(MaxNLocator(3))
            if i != j or len(table) >= NAMED_VALVES:
                ax.yaxis.set_major_locator(MaxNLocator(4))
            if i == count - 1:
                ax.set_xlabel(column, fontsize=8)
            if j == 0:
                ax.set_ylabel(row, fontsize=8)
    return figure


def valve_with(model: ValveModel, parameters: dict[str, float], name: str) -> ValveModel:
    """``model`` (the valve's physics: no sensor or per-run terms) with the parameters
    ``{"effect.parameter": display value}`` it has."""
    valve = model.copy(name=name)
    valve_parameters = valve.parameters()
    for key, value in parameters.items():
        if key in valve_parameters and np.isfinite(value):
            valve_parameters[key].set_display(value)
    return valve_physics(valve, name).model


def curves_figure(model: ValveModel, median: dict[str, float],
                  outliers: list[tuple[str, dict[str, float]]], condition: dict) -> Figure:
    """Each outlier's steady Δp(q), up and down branches, beside the fleet's median valve (every
    free parameter at the fleet's median), at the fleet's typical condition."""
    q_max = to_si(condition["q_max_lpm"], "L/min")
    q = np.geomspace(q_max / CURVE_RANGE, q_max, CURVE_POINTS)
    p_B = to_si(condition["p_B_bar"], "bar")
    p_P = p_B + to_si(condition["p_Pe_bar"], "bar")
    temperature = to_si(condition["temperature_C"], "degC")

    def branches(valve: ValveModel):
        curve = steady_characteristic(valve, q, p_P, p_B, temperature)
        return {name: from_si(state.dp, "bar") for name, state in curve.branches.items()}

    reference = branches(valve_with(model, median, "fleet median"))
    count = len(outliers)
    across = min(4, count)
    down = int(np.ceil(count / across))
    figure = Figure(figsize=(3.6 * across, 3.0 * down), layout="constrained")
    axes = figure.subplots(down, across, squeeze=False).ravel()
    flow = from_si(q, "L/min")
    for ax, (serial, values) in zip(axes, outliers):
        outlier_branches = branches(valve_with(model, values, serial))
        for branch, style in (("up", "-"), ("down", "--")):
            ax.plot(flow, reference[branch], style, color="0.45",
                    label=f"the fleet's median valve, {branch}")
            ax.plot(flow, outlier_branches[branch], style, color=OUTLIER_COLOUR,
                    label=f"the valve named above, {branch}")
        ax.set_title(serial, fontsize=10)
        ax.set_xlabel("q [L/min]")
        ax.set_ylabel("Δp [bar]")
    for ax in axes[count:]:
        ax.set_visible(False)
    if count:
        figure.legend(*axes[0].get_legend_handles_labels(), loc="outside upper center",
                      ncols=2, fontsize=LEGEND_SIZE)
    return figure


def typical_condition(records: list[dict]) -> dict | None:
    """The fleet's typical bench condition: the median of the valves' own (:func:`.valve.
    conditions`)."""
    found = [r["conditions"] for r in records if r.get("status") == "ok" and r.get("conditions")]
    if not found:
        return None
    return {key: float(np.median([c[key] for c in found if c.get(key) is not None]))
            for key in found[0]}


def write_fleet_report(path, summary: FleetSummary, model: ValveModel | None,
                       records: list[dict]) -> None:
    """Write report.html (see the module docstring); ``model``: the fleet's model, to draw the
    outliers' Δp(q) with (None: not drawn)."""
    table, analysis = summary.table, summary.analysis
    flagged = analysis.flagged()
    fitted, failed = len(table), len(summary.failed)
    parts = [f"<p class=\"summary\">{fitted} valve(s) fitted with model "
             f"<b>{html.escape(summary.model_label)}</b>"
             + (f", {failed} failed (listed at the end)" if failed else "")
             + f"; {len(flagged)} stand out from the fleet"
             + (f" by robust distance ({html.escape(analysis.method)}, cutoff "
                f"{analysis.cutoff:.2f})" if analysis.method != "none"
                else " (too few valves to tell)") + ".</p>"]
    if fitted:
        parts += _valves_section(summary)
        parts += _population_section(summary)
        parts += _outlier_section(summary, model, records)
        if summary.diagnosed:
            parts += _diagnosis_section(table)
    if failed:
        parts += [("<h2>Failed valves</h2><p>Each with the error that stopped it; a refused log "
                  "names its file, line and column. The other valves are not affected.</p>"),
                  table_html(summary.failed, ("serial", "log", "kind", "message"))]
    write_html(path, f"Fleet: {fitted + failed} valves", parts)


def _valves_section(summary: FleetSummary) -> list[str]:
    """Every valve by serial: whether it stands out, its robust distance, its RMS and, when
    diagnosed, its finding (folded away for a large fleet)."""
    table, analysis = summary.table, summary.analysis
    flagged = analysis.flagged()
    rows = pd.DataFrame({"serial": table["serial"].astype(str)})
    rows["stands out"] = np.where(rows["serial"].isin(flagged), "yes", "")
    distances = analysis.distances.reindex(rows["serial"]).to_numpy(float) \
        if len(analysis.distances) else np.full(len(rows), np.nan)
    rows["robust distance"] = distances
    for column in [c for c in table.columns if c.startswith("rms")] + (
            ["finding"] if "finding" in table.columns else []):
        rows[column] = table[column].to_numpy()
    rows = rows.sort_values(["stands out", "robust distance"], ascending=[False, False],
                            kind="stable")
    shown = table_html(rows, ("serial", "stands out", "finding"))
    if len(rows) > NAMED_VALVES:
        shown = f"<details><summary>all {len(rows)} valves</summary>{shown}</details>"
    return ["<h2>Valves</h2><p>Each valve by serial, those that stand out first (farthest "
            "first).</p>", shown]


def _population_section(summary: FleetSummary) -> list[str]:
    rows = [{"figure": column, "valves": stats["valves"], "median": stats["median"],
             "robust spread": stats["robust_spread"],
             "typical stderr": stats.get("typical_stderr") or np.nan,
             "min": stats["min"], "max": stats["max"]}
            for column, stats in summary.population.items()]
    flagged = summary.analysis.flagged()
    parts = [("<h2>Population</h2><p>Median and robust spread (1.4826 × the median absolute "
             "deviation: the standard deviation of a Gaussian population, unmoved by a few "
             "outliers) of each fitted parameter and of the fit's RMS; the typical standard "
             "error is the median of the valves' own. Correlations are Spearman's.</p>"),
             table_html(pd.DataFrame(rows), ("figure",)),
             figure_html(figure_png(histograms_figure(summary.table, summary.figures, flagged)),
                         "histograms",
                         ("Each valve's figures by serial" if len(summary.table) < NAMED_VALVES
                          else "How each figure scatters across the fleet")
                         + ("; the outliers in red." if flagged else "."))]
    main = [c for c in summary.parameters if summary.table[c].nunique() > 1][:PAIR_PARAMETERS]
    if len(main) >= 2:
        parts.append(figure_html(figure_png(pair_figure(summary.table, main, flagged)),
                                 "pair plot", "The main parameters against each other; "
                                 "outliers in red."))
    if not summary.correlations.empty:
        shown = summary.correlations.reset_index().rename(columns={"index": "figure"})
        parts.append(table_html(shown, ("figure",), {c: ".2f" for c in shown.columns}))
    return parts


def _outlier_section(summary: FleetSummary, model: ValveModel | None,
                     records: list[dict]) -> list[str]:
    analysis = summary.analysis
    parts = ["<h2>Valves that stand out</h2>"]
    if not analysis.outliers:
        parts.append("<p>None: every valve lies within the cutoff of the fleet's robust "
                     "distance.</p>" if analysis.method != "none" else
                     "<p>Too few valves to estimate the fleet's spread.</p>")
        return parts
    shown = analysis.table()[["serial", "robust distance", "cutoff", "stands out by",
                              "z-scores"]]
    parts += [(f"<p>Robust distance from the fleet ({html.escape(analysis.method)}), beyond "
              f"{analysis.cutoff:.2f}; <i>stands out by</i> names the figures without which the "
              "valve would be within the cutoff, with their robust z-scores "
              "((value − median) / robust spread).</p>"),
              table_html(shown, ("serial", "stands out by", "z-scores"),
                         {"robust distance": ".2f", "cutoff": ".2f"})]
    condition = typical_condition(records)
    if model is None or condition is None:
        return parts
    by_serial = {r["serial"]: r for r in records if r.get("status") == "ok"}
    median = {key: summary.population[column]["median"]
              for column, key in summary.parameters.items() if column in summary.population}
    chosen = [(o.serial, {key: p["value"] for key, p in
                          by_serial[o.serial]["parameters"].items()})
              for o in analysis.outliers[:CURVES_SHOWN] if o.serial in by_serial]
    figure = curves_figure(model, median, chosen, condition)
    parts.append(figure_html(figure_png(figure), "outliers' steady characteristics",
                             f"Steady Δp(q), up (solid) and down (dashed) branches, at "
                             f"p_Pe = {condition['p_Pe_bar']:.0f} bar, "
                             f"p_B = {condition['p_B_bar']:.1f} bar and "
                             f"{condition['temperature_C']:.0f} °C (the fleet's typical "
                             "bench condition): each outlier (red) against the fleet's median "
                             "valve (grey, every parameter at the fleet's median)"
                             + (f"; the {CURVES_SHOWN} farthest of "
                                f"{len(analysis.outliers)}" if len(analysis.outliers)
                                > CURVES_SHOWN else "") + "."))
    return parts


def _diagnosis_section(table: pd.DataFrame) -> list[str]:
    if "finding" not in table:
        return []
    found = table[table["finding"].notna()]
    counts = (found.groupby(["finding", "finding category"]).size().rename("valves")
              .reset_index().sort_values("valves", ascending=False))
    parts = ["<h2>Diagnosis per valve</h2>",
             (f"<p>{len(found)} of {len(table)} valves have a significant finding: an effect "
             "the model lacks that explains that valve's log (the diagnosis of "
             "<code>diagnose</code>, per valve).</p>")]
    if len(found):
        parts += [table_html(counts, ("finding", "finding category")),
                  table_html(found[["serial", "finding", "finding category", "top ΔBIC",
                                    "top summary"]],
                             ("serial", "finding", "finding category", "top summary"),
                             {"top ΔBIC": ".1f"})]
    return parts
