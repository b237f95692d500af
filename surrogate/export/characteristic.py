"""The steady characteristic of a fitted valve: Δp(q) on its up and down branches.

At a pilot pressure, back pressure and temperature held, the flow is ramped slowly up and then
down. Going up, the piston opens and friction holds it back, so the valve needs more pressure for
the same flow; coming down it closes and friction holds it open. The two steady branches are the
force balance solved on either side of the friction band (:mod:`surrogate.solver.steady`); this is
the curve users set beside catalogue data.
"""

from __future__ import annotations

import textwrap

from dataclasses import dataclass

import numpy as np
import pandas as pd

from ..model import ValveModel
from ..points import CLOSING, OPENING, OperatingPoints
from ..solver.steady import SteadyState, solve_steady, status_names
from ..core.units import from_si

BRANCHES = {"up": OPENING, "down": CLOSING}


@dataclass(frozen=True)
class Characteristic:
    """Both branches at one operating condition.

    Attributes
    ----------
    model : str
        The model's name.
    p_P, p_B : float
        Pilot and back pressure [Pa].
    temperature : float
        Oil temperature [K].
    branches : dict of str to SteadyState
        ``"up"`` (flow rising, the piston opening) and ``"down"``.
    """

    model: str
    p_P: float
    p_B: float
    temperature: float
    branches: dict[str, SteadyState]

    def to_frame(self) -> pd.DataFrame:
        """One row per flow and branch, in display units (L/min, mm, bar)."""
        parts = []
        for branch, state in self.branches.items():
            parts.append(pd.DataFrame({
                "branch": branch,
                "q_lpm": from_si(state.points.q, "L/min"),
                "u_mm": from_si(state.u, "mm"),
                "dp_bar": from_si(state.dp, "bar"),
                "p_L_bar": from_si(state.p_L, "bar"),
                "status": status_names(state.status)}))
        return pd.concat(parts, ignore_index=True)

    def to_json(self) -> dict:
        """The branches as lists in display units, with the condition they hold."""
        document = {"model": self.model,
                    "p_P_bar": float(from_si(self.p_P, "bar")),
                    "p_Pe_bar": float(from_si(self.p_P - self.p_B, "bar")),
                    "p_B_bar": float(from_si(self.p_B, "bar")),
                    "temperature_C": float(from_si(self.temperature, "degC")),
                    "branches": {}}
        for branch, state in self.branches.items():
            ok = state.ok

            def listed(values, unit):
                return [round(float(v), 6) if good else None
                        for v, good in zip(from_si(values, unit), ok)]
            document["branches"][branch] = {
                "q_lpm": listed(state.points.q, "L/min"),
                "u_mm": listed(state.u, "mm"), "dp_bar": listed(state.dp, "bar"),
                "status": status_names(state.status).tolist()}
        return document

    @property
    def failures(self) -> str:
        """The points of either branch that found no equilibrium, in words; empty if none."""
        return "; ".join(f"{branch} branch: {state.failure_summary()}"
                         for branch, state in self.branches.items() if state.failure_summary())

    def figure(self):
        """Δp against q on both branches (matplotlib Figure)."""
        from matplotlib.figure import Figure

        figure = Figure(figsize=(7.0, 4.5), layout="constrained")
        axes = figure.add_subplot()
        colours = {"up": "#c0392b", "down": "#2471a3"}
        for branch, state in self.branches.items():
            ok = state.ok
            axes.plot(from_si(state.points.q[ok], "L/min"), from_si(state.dp[ok], "bar"),
                      color=colours[branch], lw=2,
                      label=f"{branch} (flow {'rising' if branch == 'up' else 'falling'})")
        axes.set_xlabel("flow q [L/min]")
        axes.set_ylabel("pressure drop Δp = p_L − p_B [bar]")
        # the operating point on a line of its own, where a long model name cannot clip it
        p_P, p_B = from_si(self.p_P, "bar"), from_si(self.p_B, "bar")
        axes.set_title("\n".join([*textwrap.wrap(self.model, 80),
                                  f"steady characteristic at p_Pe = {p_P - p_B:.4g} bar "
                                  f"(p_P {p_P:.4g}, p_B {p_B:.4g} bar), "
                                  f"{from_si(self.temperature, 'degC'):.4g} °C"]), fontsize=10)
        axes.grid(alpha=0.3)
        axes.legend()
        return figure


def steady_characteristic(model: ValveModel, q: np.ndarray, p_P: float, p_B: float,
                          temperature: float) -> Characteristic:
    """The up and down branches of Δp(q).

    Parameters
    ----------
    model : ValveModel
        The valve (its sensor terms should be left out first, :mod:`.valve_only`).
    q : numpy.ndarray
        Flows [m^3/s], rising.
    p_P, p_B : float
        Pilot and back pressure [Pa].
    temperature : float
        Oil temperature [K].
    """
    q = np.asarray(q, float)
    branches = {}
    for branch, direction in BRANCHES.items():
        points = OperatingPoints.create(q, p_P, p_B, temperature, direction)
        branches[branch] = solve_steady(model, points)
    return Characteristic(model.name, float(p_P), float(p_B), float(temperature), branches)
