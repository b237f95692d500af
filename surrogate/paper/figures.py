"""Figures in the style of the paper's Figures 16–21: Δp over q, data against models.

Figures are built with :class:`matplotlib.figure.Figure` directly (no pyplot state), so they can be
made from any thread or process without a display.
"""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from ..fitting.residuals import measured_dp
from ..points import OperatingPoints
from ..solver import replay, solve_steady
from ..core.units import from_si
from .comparison import TABLE5_P_PE_BAR, TEMPERATURES_C, PaperComparison
from .median import median_points

TEMPERATURE_COLOURS = {20.0: "tab:blue", 40.0: "tab:green", 60.0: "tab:red"}
MODEL_STYLES = {
    "BMBE": {"color": "tab:red", "linestyle": "-"},
    "BMBEBF": {"color": "tab:orange", "linestyle": "-"},
    "CFDA": {"color": "tab:blue", "linestyle": "-", "linewidth": 2.0},
    "CFDAForce": {"color": "tab:purple", "linestyle": "--"},
    "CFDARes": {"color": "tab:brown", "linestyle": ":"},
}


def _axes(title: str):
    figure = Figure(figsize=(7.5, 5.2), layout="constrained")
    axes = figure.add_subplot()
    axes.set_xlabel("q [L/min]")
    axes.set_ylabel("Δp = p_L − p_B [bar]")
    axes.set_title(title)
    axes.grid(alpha=0.3)
    return figure, axes


def _data(axes, run, colour, label=None, alpha=0.25):
    axes.plot(from_si(run.frame["q"], "L/min"), from_si(measured_dp(run), "bar"), ".",
              markersize=1.5, color=colour, alpha=alpha, label=label, rasterized=True)


def _median(axes, line, label=None):
    axes.plot(from_si(line["q"], "L/min"), from_si(line["dp"], "bar"), "k--", linewidth=1.0,
              label=label)


def _model_curve(axes, model, line, name, label=True):
    solution = solve_steady(model, median_points(line), friction=False)
    q = from_si(line["q"].to_numpy(), "L/min")
    dp = np.where(solution.ok, from_si(solution.dp, "bar"), np.nan)
    axes.plot(q, dp, label=name if label else None, **MODEL_STYLES.get(name, {}))


def figure16(comparison: PaperComparison) -> Figure:
    """All runs, coloured by temperature, with the 40 °C median lines."""
    figure, axes = _axes("Bench data: Δp(q) at p_Pe = 50, 65, 80, 120 bar (Figure 16)")
    for (p_Pe, temperature), run in sorted(comparison.runs.items()):
        label = f"{temperature:g} °C" if p_Pe == TABLE5_P_PE_BAR[0] else None
        _data(axes, run, TEMPERATURE_COLOURS[temperature], label, alpha=0.35)
    for p_Pe in TABLE5_P_PE_BAR:
        run = comparison.runs[(p_Pe, 40.0)]
        _median(axes, comparison.lines[run.run], "median line, 40 °C" if p_Pe == 50.0 else None)
    axes.legend(markerscale=6)
    return figure


def models_at(comparison: PaperComparison, temperature: float, number: int) -> Figure:
    """Figures 17–19: BMBE, BMBEBF and CFDA against the data at one temperature."""
    figure, axes = _axes(f"Models vs data at {temperature:g} °C (Figure {number}), friction off")
    models = comparison.models.table5_models()
    for index, p_Pe in enumerate(sorted(p for p, t in comparison.runs if t == temperature)):
        run = comparison.runs[(p_Pe, temperature)]
        line = comparison.lines[run.run]
        _data(axes, run, "0.55", "data" if index == 0 else None)
        _median(axes, line, "median line" if index == 0 else None)
        for name, model in models.items():
            _model_curve(axes, model, line, name, label=index == 0)
        axes.annotate(f"{p_Pe:g} bar", (from_si(line["q"].iloc[-1], "L/min"),
                                        from_si(line["dp"].iloc[-1], "bar")),
                      textcoords="offset points", xytext=(4, 0), fontsize=8)
    axes.legend(markerscale=6)
    return figure


def figure20(comparison: PaperComparison) -> Figure:
    """The ablations at 40 °C: which map contributes what."""
    figure, axes = _axes("CFDA and its ablations at 40 °C (Figure 20), friction off")
    models = comparison.models.ablation_models()
    for index, p_Pe in enumerate(TABLE5_P_PE_BAR):
        run = comparison.runs[(p_Pe, 40.0)]
        line = comparison.lines[run.run]
        _data(axes, run, "0.55", "data" if index == 0 else None)
        _median(axes, line, "median line" if index == 0 else None)
        for name, model in models.items():
            _model_curve(axes, model, line, name, label=index == 0)
    axes.legend(markerscale=6)
    return figure


def figure21(comparison: PaperComparison) -> Figure:
    """CFDA with and without friction at 40 °C against the raw data, friction fitted at 65 bar."""
    figure, axes = _axes("CFDA with friction (fit to 65 bar) vs data at 40 °C (Figure 21)")
    with_friction = comparison.friction_models[(65.0, 40.0)]
    for index, p_Pe in enumerate(TABLE5_P_PE_BAR):
        run = comparison.runs[(p_Pe, 40.0)]
        frame = run.frame
        up = (frame["direction"] == "up").to_numpy()
        q = from_si(frame["q"].to_numpy(), "L/min")
        dp = from_si(measured_dp(run), "bar")
        axes.plot(q[up], dp[up], ".", color="tab:orange", markersize=1.5, alpha=0.3,
                  label="data, ramp up" if index == 0 else None, rasterized=True)
        axes.plot(q[~up], dp[~up], ".", color="tab:cyan", markersize=1.5, alpha=0.3,
                  label="data, ramp down" if index == 0 else None, rasterized=True)
        solver_replay = replay(with_friction, OperatingPoints.from_bench(frame))
        predicted = np.where(solver_replay.ok, from_si(solver_replay.dp, "bar"), np.nan)
        axes.plot(q[up], predicted[up], color="tab:red", linewidth=1.2,
                  label="CFDA with friction" if index == 0 else None)
        axes.plot(q[~up], predicted[~up], color="tab:blue", linewidth=1.2)
        _model_curve(axes, comparison.models.cfda, comparison.lines[run.run], "CFDA",
                     label=False)
    axes.plot([], [], **MODEL_STYLES["CFDA"], label="CFDA without friction")
    axes.legend(markerscale=6)
    return figure


def all_figures(comparison: PaperComparison) -> dict[str, Figure]:
    """File stem -> figure, for every figure of the comparison."""
    figures = {"fig16_bench_data": figure16(comparison)}
    for number, temperature in zip((17, 18, 19), TEMPERATURES_C):
        figures[f"fig{number}_models_{temperature:g}C"] = models_at(comparison, temperature, number)
    figures["fig20_ablations_40C"] = figure20(comparison)
    figures["fig21_friction_40C"] = figure21(comparison)
    return figures
