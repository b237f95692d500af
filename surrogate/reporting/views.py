"""Where a model misses, at the scale of a bar: the residual's two hysteresis views against the
state, and every run's Δp(q) loop on its own axes.

A Δp(q) figure of the whole log spans 0–175 bar; a misfit of 1 bar, the size of the effects the
workbench looks for, vanishes in it, and 11,000 raw residual dots hide a trend of that size in
their scatter. So:

* :func:`residual_views`: each run's residual split into its median line and its half-width
  (:mod:`surrogate.fitting.hysteresis`: a map error moves the median line, friction the
  half-width), bin by bin, against the flow q, the opening u, the pilot pressure p_P and the
  temperature T, one line per model: before and after each added effect;
* :func:`run_loops`: small multiples, one panel per run, each on its own Δp range, measured
  ramps against the models.
"""

from __future__ import annotations

import numpy as np
from matplotlib import colormaps
from matplotlib.figure import Figure

from ..fitting.hysteresis import hysteresis_split
from ..core.units import from_si, label
from .figures import extents, place_panels

#: the state variables the views are drawn against: (column, what, display unit, the step of
#: the levels a bench holds it at, 0 for a variable a run sweeps)
VARIABLES = (("q", "flow q", "L/min", 0.0), ("u", "opening u", "mm", 0.0),
             ("p_P", "pilot pressure p_P", "bar", 10.0),
             ("temperature", "temperature T", "degC", 5.0))
#: points of a binned line along a variable (quantiles of the bins' values)
LINE_POINTS = 10
#: a binned line breaks where no sample lies over this share of its variable's range
GAP_SHARE = 0.1
#: tick text [pt]; legends and labels one more: at least 10 px on a 1,000-pixel page, where a
#: 14-inch figure at 110 dpi shows at about 0.63 of its size
FONT = 10


def model_colours(count: int) -> list:
    """One colour per model, hues that tell apart (shades of one map did not, for five
    models), the last model, the final one, in black."""
    cycle = colormaps["tab10"].colors
    return [cycle[i % len(cycle)] for i in range(count - 1)] + ["black"][:count]


def _binned_line(x: np.ndarray, y: np.ndarray, level: float = 0.0
                 ) -> tuple[np.ndarray, np.ndarray]:
    """The median of ``y`` in :data:`LINE_POINTS` bins of ``x`` of equal count, or, for a
    variable the bench holds at levels ``level`` apart (a pilot set point, a temperature), at
    each level."""
    finite = np.isfinite(x) & np.isfinite(y)
    x, y = x[finite], y[finite]
    if level > 0:
        levels = np.round(x / level) * level
        held = np.unique(levels)
        return (np.array([np.median(x[levels == v]) for v in held]),
                np.array([np.median(y[levels == v]) for v in held]))
    if len(x) < 2 * LINE_POINTS:
        order = np.argsort(x)
        return x[order], y[order]
    edges = np.unique(np.quantile(x, np.linspace(0.0, 1.0, LINE_POINTS + 1)))
    which = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, len(edges) - 2)
    used = [b for b in range(len(edges) - 1) if np.any(which == b)]
    centres = np.array([np.median(x[which == b]) for b in used])
    medians = np.array([np.median(y[which == b]) for b in used])
    # no line across a stretch without data (the openings between 0.3 and 0.63 mm): a break
    # between two bins' centres wherever the samples between them leave a wide gap
    ordered = np.sort(x)
    widest = []
    for low, high in zip(centres[:-1], centres[1:]):
        inside = ordered[(ordered >= low) & (ordered <= high)]
        widest.append(np.max(np.diff(np.r_[low, inside, high])))
    gaps = np.flatnonzero(np.array(widest) > GAP_SHARE * (x.max() - x.min())) + 1
    return np.insert(centres, gaps, np.nan), np.insert(medians, gaps, np.nan)


def residual_views(log, models: list[tuple[str, object]]) -> Figure | None:
    """The residual's median line (top row) and half-width (bottom row), binned per run along
    the flow, against q, u, p_P and T: dots for the bins of the last model, a line of the bins'
    medians for each model. ``models``: (label, LogReplay) in order. None for a log without
    runs that go both ways."""
    frame = log.frame
    split = hysteresis_split(frame)
    if not split.bins:
        return None
    weights = np.abs(split.median)  # each bin's mean of a variable over its samples
    last = models[-1][1]
    state = {"q": frame["q"].to_numpy(float), "p_P": frame["p_P"].to_numpy(float),
             "temperature": frame["temperature"].to_numpy(float),
             "u": np.nan_to_num(last.replay.u, nan=0.0)}
    at_bins = {name: weights @ values for name, values in state.items()}
    figure = Figure(figsize=(14, 6.4))
    axes = figure.subplots(2, len(VARIABLES), sharey="row")
    colours = model_colours(len(models))
    for row, (view, what) in enumerate(((split.median, "median line"),
                                        (split.half, "half-width"))):
        for column, (name, words, unit, level) in enumerate(VARIABLES):
            ax = axes[row, column]
            x = from_si(at_bins[name], unit)
            for (title, log_replay), shade in zip(models, colours):
                residual = np.nan_to_num(log_replay.residual, nan=0.0)
                values = from_si(view @ residual, "bar") - from_si(0.0, "bar")
                if log_replay is last:
                    ax.plot(x, values, ".", color=shade, markersize=3, alpha=0.35)
                centres, medians = _binned_line(x, values, level)
                # a variable held at levels (set points, temperatures): its levels' medians as
                # points on a thin line, which says nothing between them
                ax.plot(centres, medians, "o:" if level else "-", color=shade,
                        linewidth=0.8 if level else 1.8, markersize=5,
                        label=title if row == 0 and column == 0 else None)
            ax.axhline(0.0, color="black", linewidth=0.8)
            ax.grid(alpha=0.3)
            ax.tick_params(labelsize=FONT)
            if row == 1:
                ax.set_xlabel(f"{words} [{label(unit)}]", fontsize=FONT + 1)
            if column == 0:
                ax.set_ylabel(f"residual's {what} [bar]", fontsize=FONT + 1)
    legend = figure.legend(loc="upper center", ncols=min(len(models), 3), fontsize=FONT + 1,
                           title="model − measured, per run and flow bin; lines: the bins' "
                           "median", title_fontsize=FONT + 1)
    # under the legend; the rows share their y axis: tick labels on the first column only
    place_panels(figure, above=extents(figure, legend)[0][1] + 0.3, across=0.25, down=0.45)
    return figure


def run_loops(log, models: list[tuple[str, object]], columns: int = 4,
              smooth: int = 9) -> Figure:
    """One panel per run: the measured Δp(q) of each ramp (dots) against each model's (lines,
    a running median over ``smooth`` samples: a replay follows its inputs' noise), each panel on
    the run's own Δp range."""
    frame = log.frame
    runs = list(dict.fromkeys(frame["run"].astype(str)))
    rows = int(np.ceil(len(runs) / columns))
    figure = Figure(figsize=(3.5 * columns, 2.7 * rows + 0.8))
    axes = np.atleast_1d(figure.subplots(rows, columns, squeeze=False)).ravel()
    colours = model_colours(len(models))
    measured = from_si((frame["p_L"] - frame["p_B"]).to_numpy(float), "bar")
    q = from_si(frame["q"].to_numpy(float), "L/min")
    up = frame["direction"].to_numpy() == "up"
    names = frame["run"].astype(str).to_numpy()
    for ax, run in zip(axes, runs):
        inside = names == run
        for ramp, marker, tint in ((up, ".", "0.35"), (~up, "x", "0.6")):
            rows_ = inside & ramp
            step = max(1, int(rows_.sum() // 150))
            ax.plot(q[rows_][::step], measured[rows_][::step], marker, color=tint,
                    markersize=2.5, alpha=0.6)
        for (title, log_replay), shade in zip(models, colours):
            predicted = from_si(log_replay.replay.dp, "bar")
            # both ramps as one line, broken between them: one artist instead of two
            x, y = [], []
            for ramp in (up, ~up):
                rows_ = np.flatnonzero(inside & ramp)
                order = rows_[np.argsort(q[rows_], kind="stable")]
                x += [q[order], [np.nan]]
                y += [_running_median(predicted[order], smooth), [np.nan]]
            ax.plot(np.concatenate(x[:-1]), np.concatenate(y[:-1]), "-", color=shade,
                    linewidth=1.3)
        temperature = from_si(frame["temperature"].to_numpy(float)[inside].mean(), "degC")
        pilot = from_si((frame["p_P"] - frame["p_B"]).to_numpy(float)[inside].mean(), "bar")
        ax.set_title(f"{run}: {temperature:.0f} °C, p_Pe {pilot:.0f} bar", fontsize=FONT + 1)
        ax.tick_params(labelsize=FONT)
        ax.grid(alpha=0.3)
    for ax in axes[len(runs):]:
        ax.set_visible(False)
    for ax in axes[::columns]:
        ax.set_ylabel(f"Δp [{label('bar')}]", fontsize=FONT)
    handles = [axes[0].plot([], [], ".", color="0.35")[0], axes[0].plot([], [], "x",
                                                                        color="0.6")[0]]
    handles += [axes[0].plot([], [], "-", color=shade)[0] for shade in colours]
    legend = figure.legend(handles, ["measured, ramp up", "measured, ramp down"]
                           + [title for title, _ in models], loc="upper center",
                           ncols=min(len(handles), 3), fontsize=FONT + 1)
    figure.supxlabel(f"flow q [{label('L/min')}]", fontsize=FONT + 1)
    # under the legend, each panel with its own y tick labels and title
    place_panels(figure, above=extents(figure, legend)[0][1] + 0.3, across=0.45, down=0.6)
    return figure


def _running_median(values: np.ndarray, window: int) -> np.ndarray:
    if window < 2 or len(values) < window:
        return values
    padded = np.pad(values, window // 2, mode="edge")
    windows = np.lib.stride_tricks.sliding_window_view(padded, window)[:len(values)]
    # NumPy's nanmedian of short rows goes through masked arrays, many times the plain
    # median's cost, which gives the same where no value is missing
    return (np.median(windows, axis=1) if not np.isnan(values).any()
            else np.nanmedian(windows, axis=1))


__all__ = ["residual_views", "run_loops"]
