"""Figures of a model-against-log comparison (:mod:`~surrogate.workbench.compare`), written as
PNG files.

* ``dp_vs_q``: Δp over q, measured against the model, one panel per temperature;
* ``residuals``: the residual against q, p_L, p_P, p_B, temperature and ramp direction;
* ``hysteresis``: hysteresis width against the pilot set point, measured against the model.

Figures are built with :class:`matplotlib.figure.Figure` directly (no pyplot state), as in
:mod:`surrogate.paper.figures`, so they need no display and leave nothing open.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib import colormaps
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import PolyCollection
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch
from matplotlib.ticker import AutoLocator, Locator, ScalarFormatter

from ..core.outputs import atomic_directory
from ..core.units import from_si, label
from ..workbench.compare import Comparison
from .png import png_from_rgba

DPI = 110
# the paper's colours for 20, 40 and 60 °C, then more for logs with more temperatures
TEMPERATURE_COLOURS = ("tab:blue", "tab:green", "tab:red", "tab:purple", "tab:orange",
                       "tab:brown", "tab:cyan", "tab:olive")
BAR, LPM, DEGC = label("bar"), label("L/min"), label("degC")


#: room left of a grid of panels (a y label and its tick labels), right of it, and below it (x
#: tick labels and an x label) [inches], where a figure places its panels itself
LEFT, RIGHT, BELOW = 0.75, 0.15, 0.6


def place_panels(figure: Figure, *, above: float, left: float = LEFT, right: float = RIGHT,
                 below: float = BELOW, across: float, down: float) -> None:
    """Place ``figure``'s grid of panels by its margins and the gaps between panels across and
    down [inches].

    The report's figures of several panels do so instead of using matplotlib's constrained
    layout, which measures every tick label about ten times over: it was a third to a half of
    their drawing. Their grids and labels keep their shape from log to log; what varies, a
    legend or a title, the caller measures (:func:`extents`).
    """
    width, height = figure.get_size_inches()
    rows, columns = figure.axes[0].get_subplotspec().get_gridspec().get_geometry()
    panel_width = (width - left - right - (columns - 1) * across) / columns
    panel_height = (height - above - below - (rows - 1) * down) / rows
    figure.subplots_adjust(left=left / width, right=1.0 - right / width, bottom=below / height,
                           top=1.0 - above / height, wspace=across / panel_width,
                           hspace=down / panel_height)


def png_bytes(figure: Figure) -> bytes:
    """The figure drawn at :data:`DPI` as PNG bytes, the pixels ``savefig`` draws, but cheaper:

    * an opaque figure (every report figure) is written as RGB, without the alpha channel
      that is 255 everywhere, and deflated without Pillow's per-row filters
      (:func:`.png.png_from_rgba`);
    * the figure is laid out once, not measured again at every draw (:func:`settled_layout`).
    """
    settled_layout(figure)
    dpi = figure.dpi
    figure.dpi = DPI  # as savefig(dpi=DPI) does while it draws
    try:
        canvas = FigureCanvasAgg(figure)
        canvas.draw()
        return png_from_rgba(np.asarray(canvas.buffer_rgba()), DPI)
    finally:
        figure.dpi = dpi


def settled_layout(figure: Figure) -> None:
    """Spare the draw two measurements whose answer these figures already know (matplotlib
    makes them at every draw, and they were a sixth of drawing the report's figures):

    * a panel's title is moved above its top tick labels or its y axis' offset text where
      they would overlap: the panels here have their ticks at the bottom, and their y axes
      show plain numbers, without an offset (one such as "+1.5e2" reads worse anyway), so the
      title stays where it is, at the top of its panel;
    * an axis label is placed beside the tick labels of its axis and of those aligned with
      it, found again at every draw, also where the label is empty: an empty label is placed
      once, on its axis (it draws nothing, and takes no room).

    Only for a figure that places its panels itself (no layout engine, which would measure
    the empty labels' place)."""
    if figure.get_layout_engine() is not None:
        return
    for ax in figure.axes:
        if ax.get_title() and not ax.get_title("left") and not ax.get_title("right") \
                and ax.xaxis.get_ticks_position() == "bottom" \
                and ax.xaxis.get_label_position() == "bottom":
            formatter = ax.yaxis.get_major_formatter()
            if type(formatter) is ScalarFormatter:
                formatter.set_useOffset(False)
                ax.title.set_y(1.0)
                ax._autotitlepos = False
        for axis, place in ((ax.xaxis, (0.5, 0.0)), (ax.yaxis, (0.0, 0.5))):
            if not axis.label.get_text():
                axis.set_label_coords(*place)
            if type(axis.get_major_locator()) is AutoLocator and axis.get_scale() == "linear":
                axis.set_major_locator(InView(axis.get_major_locator()))


class InView(Locator):
    """A locator's ticks inside the axis' view only. Matplotlib's default one also names a tick
    or two beyond each end, which the axis makes (each tick its lines and labels, a third of
    the ticks made on the report's panels) and then leaves undrawn; their labels are the
    same, since the tick format and offset are found from the ticks in view."""

    def __init__(self, locator: Locator):
        self.locator = locator

    def set_axis(self, axis) -> None:
        super().set_axis(axis)
        self.locator.set_axis(axis)

    def __call__(self):
        locations = np.asarray(self.locator())
        low, high = sorted(self.axis.get_view_interval())
        # as the axis decides which ticks to draw (matplotlib.transforms._interval_contains_close)
        room = 1e-10 * (high - low)
        return locations[(locations >= low - room) & (locations <= high + room)]

    def tick_values(self, vmin, vmax):
        return self.locator.tick_values(vmin, vmax)

    def view_limits(self, vmin, vmax):
        return self.locator.view_limits(vmin, vmax)

    def nonsingular(self, v0, v1):
        return self.locator.nonsingular(v0, v1)


def extents(figure: Figure, *artists) -> list[tuple[float, float]]:
    """(width, height) [inches] of each of ``artists`` (a legend, a title) as ``figure`` draws
    them."""
    renderer = FigureCanvasAgg(figure).get_renderer()
    boxes = [artist.get_window_extent(renderer) for artist in artists]
    return [(box.width / figure.dpi, box.height / figure.dpi) for box in boxes]


def write_figures(comparison: Comparison, folder: str | Path) -> dict[str, Path]:
    """Write every figure of ``comparison`` as ``folder/<name>.png`` (all or none), the same
    pixels as the report's (:func:`png_bytes`).

    Returns
    -------
    dict
        Figure name (``dp_vs_q``, ``residuals``, ``hysteresis``) -> path of its PNG.
    """
    figures = all_figures(comparison)
    with atomic_directory(folder) as staging:
        for name, figure in figures.items():
            (staging / f"{name}.png").write_bytes(png_bytes(figure))
    return {name: Path(folder) / f"{name}.png" for name in figures}


def all_figures(comparison: Comparison) -> dict[str, Figure]:
    """Figure name -> figure, for every figure of the comparison."""
    runs, points = decimated(comparison)
    samples = _samples(comparison, runs)
    return {"dp_vs_q": _noted(dp_against_flow(comparison, samples), runs),
            "residuals": _noted(residual_panels(
                comparison, samples if points is runs else _samples(comparison, points)),
                points),
            "hysteresis": hysteresis_against_set_point(comparison)}


#: samples above which the figures draw a thinned view (a figure then costs the same for a
#: log of 10^5 samples and one of 10^7, and its dots still show the density)
FIGURE_SAMPLES = 60_000
#: runs drawn per condition (nominal temperature and set point) in a thinned Δp(q) figure:
#: a big log repeats its runs, and a hundred loops on top of each other show no more than four
RUNS_PER_CONDITION = 4


@dataclass(frozen=True)
class View:
    """The samples a figure draws (positions in the log), and what was left out, in words."""

    rows: np.ndarray | slice
    note: str = ""


def decimated(comparison: Comparison) -> tuple[View, View]:
    """The views the figures draw: (the runs of the Δp(q) figure, the points of the residual
    scatters). A log of at most :data:`FIGURE_SAMPLES` samples is drawn whole; a bigger one
    draws the first :data:`RUNS_PER_CONDITION` runs of each condition, and every k-th sample
    of the scatters (k the smallest that keeps :data:`FIGURE_SAMPLES`)."""
    runs = comparison.log_replay.runs
    count = len(runs)
    if count <= FIGURE_SAMPLES:
        whole = View(slice(None))
        return whole, whole
    table = comparison.runs
    rank = table.groupby(["temperature_nominal_C", "p_Pe_bar"], sort=False).cumcount()
    kept = table.loc[rank.to_numpy() < RUNS_PER_CONDITION, "run"]
    step = -(-count // FIGURE_SAMPLES)
    return (View(np.flatnonzero(np.isin(runs, kept.to_numpy())),
                 f"{len(kept)} of {len(table)} runs shown (the first {RUNS_PER_CONDITION} of "
                 "each condition)"),
            View(slice(None, None, step), f"every {step}th of {count:,} samples shown"))


def _noted(figure: Figure, view: View) -> Figure:
    """The figure, saying what its thinned view left out."""
    if view.note:
        figure.text(0.995, 0.005, view.note, ha="right", va="bottom", fontsize=7, color="0.35")
    return figure


def _samples(comparison: Comparison, view: View) -> pd.DataFrame:
    """Per-sample data of a view for plotting, in display units: the comparison's sample table,
    with each run's nominal temperature and set point, the measured p_L and the ramp up as a
    flag."""
    table = comparison.sample_table(view.rows)
    log = comparison.log_replay.log.frame
    nominal = dict(zip(comparison.runs["run"], comparison.runs["temperature_nominal_C"]))
    return table.assign(temperature_nominal_C=table["run"].map(nominal).to_numpy(),
                        p_Pe_bar=from_si(log["p_Pe_nominal"].to_numpy()[view.rows], "bar"),
                        p_L_bar=from_si(log["p_L"].to_numpy()[view.rows], "bar"),
                        up=(table["direction"] == "up").to_numpy())


def _temperature_colours(comparison: Comparison) -> dict[float, str]:
    levels = sorted(set(comparison.runs["temperature_nominal_C"]))
    return {level: TEMPERATURE_COLOURS[index % len(TEMPERATURE_COLOURS)]
            for index, level in enumerate(levels)}


#: longest figure title [characters]: titles fit their figure; the model's full name, which can be
#: long after a workflow, goes into the caption (:func:`caption`)
TITLE_LENGTH = 60


def _title(comparison: Comparison, what: str) -> str:
    return (f"{what}: RMS {from_si(comparison.rms, 'bar'):.2f} {BAR}, "
            f"noise floor {from_si(comparison.noise_floor, 'bar'):.2f} {BAR}")


def caption(comparison: Comparison) -> str:
    """What every figure of the comparison shows, in full: the model and the data."""
    model = comparison.model.replace("+", " + ")  # so that a long name can wrap
    return f"Model {model} against {Path(comparison.log_replay.log.source).name}."


def _tint(colour, amount: float):
    """``colour`` mixed with white: 0 keeps it, 1 is white."""
    from matplotlib.colors import to_rgb

    return tuple(c + (1.0 - c) * amount for c in to_rgb(colour))


def _shade(colour, amount: float):
    """``colour`` mixed with black: 0 keeps it, 1 is black."""
    from matplotlib.colors import to_rgb

    return tuple(c * (1.0 - amount) for c in to_rgb(colour))


def dp_against_flow(comparison: Comparison, samples: pd.DataFrame) -> Figure:
    """Δp(q) of every run, one panel per temperature: measured as light dots, the model as a
    dark line, both in the set point's hue, so the two differ in marker and in colour; around
    the model, a shaded ±2σ band of the Δp uncertainty its maps imply (where they have one)."""
    levels = sorted(set(samples["temperature_nominal_C"]))
    set_points = sorted(set(samples["p_Pe_bar"]))
    palette = colormaps["viridis"].resampled(max(len(set_points), 2))
    colour = {p: palette(0.85 * index / max(len(set_points) - 1, 1))
              for index, p in enumerate(set_points)}
    figure = Figure(figsize=(4.2 * len(levels) + 2.0, 4.6))
    axes = figure.subplots(1, len(levels), sharex=True, sharey=True, squeeze=False)[0]
    for ax, level in zip(axes, levels):
        bands, tints = [], []
        for run, group in samples[samples["temperature_nominal_C"] == level].groupby(
                "run", sort=False):
            c = colour[group["p_Pe_bar"].iloc[0]]
            ax.plot(group["q_lpm"], group["dp_measured_bar"], "o", color=_tint(c, 0.55),
                    markersize=1.6, markeredgewidth=0, rasterized=True)
            polygons = _band(group)
            bands += polygons
            tints += [_tint(c, 0.3)] * len(polygons)
            # time order, so each run draws its loop: up the ramp and back down
            ax.plot(group["q_lpm"], group["dp_model_bar"], "-", color=_shade(c, 0.35),
                    linewidth=1.3)
        if bands:
            # the panel's bands as one artist: a patch each cost more to add (its limits traced
            # along its outline) and to draw than their polygons; patches and collections are
            # drawn under the lines alike
            ax.add_collection(PolyCollection(bands, facecolors=tints, alpha=0.35,
                                             linewidths=0, rasterized=True))
        ax.set_title(f"{level:g} {DEGC}")
        ax.set_xlabel(f"q [{LPM}]")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel(f"Δp = p_L − p_B [{BAR}]")
    handles = [Line2D([], [], color=colour[p], linewidth=2.0, label=f"p_Pe {p:g} {BAR}")
               for p in set_points]
    handles += [Line2D([], [], color=_tint("0.2", 0.55), marker="o", linestyle="",
                       markersize=4, label="measured (dots, light)"),
                Line2D([], [], color="0.2", linewidth=1.3, label="model (line, dark)")]
    if samples["dp_std_bar"].notna().any():
        handles.append(Patch(color=_tint("0.2", 0.75), label="model ± 2σ of its maps"))
    legend = figure.legend(handles=handles, fontsize=11, loc="upper right")
    title = figure.suptitle(_title(comparison, "Δp over q"))
    _beside_legend(figure, legend, title, titled=True, across=0.25, down=0.0)
    return figure


def _beside_legend(figure: Figure, legend, title, titled: bool, across: float,
                   down: float) -> None:
    """Place the panels under ``title`` (with room for their own titles where ``titled``) and
    left of ``legend`` (in the upper right corner)."""
    (legend_width, _), (_, title_height) = extents(figure, legend, title)
    place_panels(figure, above=title_height + (0.55 if titled else 0.3),
                 right=legend_width + 0.2, across=across, down=down)


def _band(run: pd.DataFrame) -> list[np.ndarray]:
    """The model's ±2σ band over one run as polygons, (points, 2) arrays of q and Δp, one per
    ramp (each ramp's flow runs one way, so its upper edge and its lower edge reversed close a
    polygon). σ is drawn as a running median over a twentieth of the ramp: it jumps between
    samples where friction holds the piston (the flow map's error alone) and where it slides
    (the force map's too), which would hide the band's course; samples.csv keeps every
    sample's own. In NumPy on the run's columns (a DataFrame and a rolling window per ramp
    cost more than drawing the bands)."""
    polygons = []
    std_all = run["dp_std_bar"].to_numpy(float)
    if np.isnan(std_all).all():
        return polygons
    model_all = run["dp_model_bar"].to_numpy(float)
    q_all = run["q_lpm"].to_numpy()
    up = run["up"].to_numpy()
    # the ramps: where the direction changes
    bounds = [0, *(np.flatnonzero(up[1:] != up[:-1]) + 1).tolist(), len(up)]
    for begin, end in zip(bounds[:-1], bounds[1:]):
        std, model = std_all[begin:end], model_all[begin:end]
        kept = ~np.isnan(std) & ~np.isnan(model)
        if kept.sum() < 2:
            continue
        q, std, model = q_all[begin:end][kept], std[kept], model[kept]
        std = centred_median(std, max(5, len(std) // 20))
        upper, lower = model + 2 * std, model - 2 * std
        polygons.append(np.column_stack([np.concatenate([q, q[::-1]]),
                                         np.concatenate([upper, lower[::-1]])]))
    return polygons


def centred_median(values: np.ndarray, window: int) -> np.ndarray:
    """The running median of ``values`` over ``window`` samples, as pandas'
    ``Series.rolling(window, center=True, min_periods=1).median()`` finds it (the window
    shortened at the ends; for an even window, one more sample before than after)."""
    count = len(values)
    stop = np.arange(1, count + 1) + (window - 1) // 2
    start, stop = np.maximum(stop - window, 0), np.minimum(stop, count)
    result = np.empty(count)
    full = stop - start == window
    if full.any():
        result[full] = np.median(
            np.lib.stride_tricks.sliding_window_view(values, window)[start[full]], axis=1)
    for row in np.flatnonzero(~full):
        result[row] = np.median(values[start[row]:stop[row]])
    return result


RESIDUAL_PANELS = (("q_lpm", f"q [{LPM}]"), ("p_L_bar", f"p_L [{BAR}]"),
                   ("p_P_bar", f"p_P [{BAR}]"), ("p_B_bar", f"p_B [{BAR}]"),
                   ("temperature_C", f"temperature [{DEGC}]"))


def residual_panels(comparison: Comparison, samples: pd.DataFrame) -> Figure:
    """The residual against each input and the ramp direction, coloured by temperature, with
    the noise floor as a grey band: structure outside the band is what the model misses."""
    colours = _temperature_colours(comparison)
    solved = samples[np.isfinite(samples["residual_bar"])]
    point_colours = solved["temperature_nominal_C"].map(colours).to_numpy()
    floor = from_si(comparison.noise_floor, "bar")
    figure = Figure(figsize=(13.0, 7.2))
    axes = figure.subplots(2, 3, sharey=True).ravel()
    for ax, (column, axis_label) in zip(axes, RESIDUAL_PANELS):
        ax.scatter(solved[column], solved["residual_bar"], s=1.5, c=point_colours, alpha=0.35,
                   linewidths=0, rasterized=True)
        ax.set_xlabel(axis_label)

    # direction: a strip per ramp direction, jittered so that the density shows, with mean ± σ
    ax = axes[-1]
    position = np.where(solved["up"], 0.0, 1.0)
    jitter = np.random.default_rng(0).uniform(-0.3, 0.3, len(solved))  # fixed: same image twice
    ax.scatter(position + jitter, solved["residual_bar"], s=1.5, c=point_colours, alpha=0.35,
               linewidths=0, rasterized=True)
    for x, up in ((0.0, True), (1.0, False)):
        values = solved.loc[solved["up"] == up, "residual_bar"]
        if len(values):
            ax.errorbar(x, values.mean(), yerr=values.std(), fmt="o", color="black",
                        capsize=6, markersize=5, zorder=3)
    ax.set_xticks([0.0, 1.0], ["up", "down"])
    ax.set_xlim(-0.6, 1.6)
    ax.set_xlabel("ramp direction (mean ± σ in black)")

    for ax in axes:
        ax.axhspan(-floor, floor, color="0.6", alpha=0.25, linewidth=0)
        ax.axhline(0.0, color="black", linewidth=0.6)
        ax.grid(alpha=0.3)
    for ax in axes[::3]:
        ax.set_ylabel(f"residual = model − measured Δp [{BAR}]")
    handles = [Line2D([], [], marker="o", linestyle="", color=c, label=f"{t:g} {DEGC}")
               for t, c in colours.items()]
    handles.append(Line2D([], [], color="0.6", alpha=0.5, linewidth=6, label="± noise floor"))
    legend = figure.legend(handles=handles, fontsize=10, loc="upper right")
    title = figure.suptitle(_title(comparison, "residuals"))
    # the panels share their y axis: tick labels on the first column only; an x label on each
    _beside_legend(figure, legend, title, titled=False, across=0.25, down=0.75)
    return figure


def hysteresis_against_set_point(comparison: Comparison) -> Figure:
    """Hysteresis width of each run against its set point: measured (filled) and model (open),
    joined by a line whose length is the model's error."""
    colours = _temperature_colours(comparison)
    runs = comparison.runs
    levels = list(colours)
    # spread the temperatures a little sideways so that runs at one set point do not overlap
    spacing = 0.012 * max(float(np.ptp(runs["p_Pe_bar"])), 10.0)
    figure = Figure(figsize=(7.0, 4.8))
    ax = figure.add_subplot()
    for index, level in enumerate(levels):
        group = runs[runs["temperature_nominal_C"] == level]
        x = group["p_Pe_bar"] + (index - (len(levels) - 1) / 2) * spacing
        ax.vlines(x, group["hysteresis_measured_bar"], group["hysteresis_model_bar"],
                  color=colours[level], linewidth=1.0, alpha=0.7)
        ax.plot(x, group["hysteresis_measured_bar"], "o", color=colours[level], markersize=7,
                label=f"{level:g} {DEGC}")
        ax.plot(x, group["hysteresis_model_bar"], "s", markerfacecolor="white",
                markeredgecolor=colours[level], markeredgewidth=1.5, markersize=7)
    set_points = sorted(set(runs["p_Pe_bar"]))
    ax.set_xticks(set_points, [f"{p:g}" for p in set_points])
    ax.axhline(0.0, color="black", linewidth=0.6)
    ax.set_xlabel(f"p_Pe set point [{BAR}]")
    ax.set_ylabel(f"hysteresis width: Δp up − down at equal q [{BAR}]")
    ax.grid(alpha=0.3)
    handles, _ = ax.get_legend_handles_labels()
    handles += [Line2D([], [], marker="o", linestyle="", color="0.3", label="measured"),
                Line2D([], [], marker="s", linestyle="", markerfacecolor="white",
                       markeredgecolor="0.3", markeredgewidth=1.5, label="model")]
    ax.legend(handles=handles, fontsize=10, loc="best")
    ax.set_title("Hysteresis width per run")
    # its labels keep their size: fixed margins, not the constrained layout's measuring
    place_panels(figure, above=0.35, left=0.8, across=0.0, down=0.0)
    return figure
