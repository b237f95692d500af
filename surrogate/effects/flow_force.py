"""Corrections to the flow force that the force map predicts."""

from __future__ import annotations

import numpy as np

from ..core.units import BAR
from .base import BalanceState, Effect, Parameter


class FlowForceScale(Effect):
    """The map's flow force made stronger (scale > 1) or weaker (scale < 1): f_ff → scale·f_ff.

    The flow force f_ff is the part of the fluid force a uniform pressure would not give (paper
    eq. 10). The paper's CFD-assisted model needed it reduced by 10 % (scale 0.9) to fit its
    bench data.
    """

    name = "flow_force_scale"
    kind = "force"
    category = "map correction"
    title = "flow-force scale"
    parameter_specs = (
        Parameter("scale", 1.0, "1", min=0.0, max=3.0,
                  description="factor on the map's flow force"),
    )
    validity = "Acts only on what the force map calls flow force; zero with a uniform-pressure map."

    def force(self, state: BalanceState) -> np.ndarray:
        return (self["scale"] - 1.0) * state.flow_force


class BackPressureFlowForce(Effect):
    """A flow force that depends on the back pressure: f_ff → f_ff·(1 + γ·(p_B − p_ref)).

    A higher back pressure suppresses cavitation in the jet leaving the restriction, which changes
    the pressure distribution on the piston and hence the flow force. A map built from CFD at one
    back pressure (p_ref) misses that dependence.
    """

    name = "back_pressure_flow_force"
    kind = "force"
    category = "map correction"
    title = "flow force depending on back pressure"
    parameter_specs = (
        Parameter("gamma", 0.0, "1/bar", min=-0.5 / BAR, max=0.5 / BAR,
                  description="relative change of the flow force per bar of back pressure"),
        Parameter("p_ref", 5.0 * BAR, "bar", min=0.0, max=50.0 * BAR, vary=False,
                  description="back pressure of the CFD samples the map was built from"),
    )
    validity = "Linear in p_B around p_ref; zero with a uniform-pressure map."

    def force(self, state: BalanceState) -> np.ndarray:
        return self["gamma"] * (state.p_B - self["p_ref"]) * state.flow_force


class NearSeatFlowForce(Effect):
    """The flow force fading as the piston nears its seat: f_ff → f_ff·min(1, (u/u_ref)^k).

    Below the smallest CFD opening u_ref the grid maps hold the flow-force fraction
    α = f_ff/(A_L·Δp) at its value there, but the CFD samples themselves show |α| shrinking
    toward the seat (in the shipped samples by about a fifth between 0.08 and 0.05 mm at equal
    Δp): as the gap closes, the jet's momentum falls with the discharge area and the pressure over
    the seat land approaches the uniform closed-valve value. The power law continues that trend;
    k = 0 is the maps' own rule, k = 1 a flow force proportional to the opening.
    """

    name = "seat_flow_force"
    kind = "force"
    category = "map correction"
    title = "flow force fading near the seat"
    parameter_specs = (
        Parameter("k", 0.0, "1", min=0.0, max=3.0,
                  description="exponent of the fade below u_ref"),
        Parameter("u_ref", 0.05e-3, "mm", min=1e-6, max=1e-3, vary=False,
                  description="smallest opening the force map was built from"),
    )
    validity = ("Acts only below u_ref, on the flow force of the force map; set u_ref to the "
                "smallest CFD opening of your maps.")

    def force(self, state: BalanceState) -> np.ndarray:
        closeness = np.clip(state.u / self["u_ref"], 1e-12, 1.0)
        return (closeness ** self["k"] - 1.0) * state.flow_force
