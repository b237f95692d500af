"""Departures of the flow through the valve from what the flow map predicts."""

from __future__ import annotations

import numpy as np

from ..core.units import BAR, LPM
from .base import Effect, FlowState, Parameter


class DischargeScale(Effect):
    """A discharge coefficient scaled by c at every opening: the map's flow at a Δp times c.

    Manufacturing tolerances of the metering edge (its radius, a chamfer) change C_d; the map then
    sees the flow q/c.
    """

    name = "discharge_scale"
    kind = "flow"
    category = "map correction"
    title = "discharge-coefficient scale"
    parameter_specs = (Parameter("c", 1.0, "1", min=0.2, max=3.0,
                                 description="factor on the discharge coefficient"),)
    validity = "Uniform over openings and flows; indistinguishable from a flowmeter gain error."

    def restriction_flow(self, q: np.ndarray, state: FlowState) -> np.ndarray:
        return q / self["c"]


class LaminarLeakage(Effect):
    """Laminar leakage G·Δp past the piston, from the load to the back port, around the restriction.

    The clearance between piston and bore passes a flow proportional to the pressure drop; the
    main restriction then carries less than the measured flow, most noticeably at small flows.
    """

    name = "laminar_leakage"
    kind = "leakage"
    category = "physics"
    title = "laminar leakage past the piston"
    parameter_specs = (Parameter("G", 0.0, "L/min/bar", min=0.0, max=0.05 * LPM / BAR,
                                 description="leakage flow per bar of pressure drop"),)
    validity = "Laminar (viscosity dependence not modelled); small next to the main flow."

    def leakage(self, dp: np.ndarray, state: FlowState) -> np.ndarray:
        return self["G"] * np.maximum(dp, 0.0)
