"""The basic model's maps: the orifice equation and a uniform pressure distribution.

These are the paper's BM components (Table 2, eqs. 4, 6 and 9): a constant discharge coefficient
with a discharge area growing linearly with the opening, and a fluid force with no flow force.
They need no data, so they never extrapolate. The kind ``orifice`` (:mod:`.registry`) builds them.
"""

from __future__ import annotations

import numpy as np

from ..fluid import FluidState, broadcast_query
from ..valve import ValveParameters
from .base import FlowMap, ForceMap
from .registry import MapKind, Option, number_in, register

BASIC_DISCHARGE_COEFFICIENT = 0.4  # the paper's BMBE choice, from C_d at u = 0.63 mm


class OrificeFlowMap(FlowMap):
    """q = C_d·w·u·sqrt(2Δp/ρ) (paper eqs. 4 and 9).

    Parameters
    ----------
    discharge_coefficient : float
        C_d [-], constant.
    w : float
        Discharge-area coefficient [m]: the discharge area is a_d = w·u.
    """

    smooth = True  # an orifice and a uniform pressure are analytic

    kind = "orifice"

    def __init__(self, discharge_coefficient: float, w: float):
        if not (discharge_coefficient > 0 and w > 0):
            raise ValueError("orifice map needs C_d > 0 and w > 0")
        self.discharge_coefficient = float(discharge_coefficient)
        self.w = float(w)

    def __repr__(self) -> str:
        return f"OrificeFlowMap(C_d={self.discharge_coefficient:g}, w={self.w:g} m)"

    def flow(self, p_L, p_B, u, fluid: FluidState) -> np.ndarray:
        p_L, p_B, u, fluid = broadcast_query(p_L, p_B, u, fluid)
        dp = np.maximum(p_L - p_B, 0.0)
        return self.discharge_coefficient * self.w * np.maximum(u, 0.0) * np.sqrt(
            2.0 * dp / fluid.rho)

    def pressure_drop(self, q, p_B, u, fluid: FluidState) -> np.ndarray:
        q, p_B, u, fluid = broadcast_query(q, p_B, u, fluid)
        with np.errstate(divide="ignore", invalid="ignore"):  # u = 0: no flow passes, or needs
            # an infinite pressure drop
            velocity = np.maximum(q, 0.0) / (self.discharge_coefficient * self.w * u)
        return np.where(q > 0, 0.5 * fluid.rho * velocity**2, 0.0)


class UniformPressureForceMap(ForceMap):
    """f_sim with a uniform pressure on every surface and no flow force.

    With p_L on the load-side surfaces and p_B on the outlet-side ones, the force inside the CFD
    domain is f_sim = p_L·A_L + p_B·(A_s3 − A_B), so that the total fluid force
    f_sim − p_B·A_s3 + p_P·A_P equals the basic model's p_L·A_L + p_P·A_P − p_B·A_B (eq. 6).
    """

    smooth = True  # an orifice and a uniform pressure are analytic

    kind = "uniform pressure"

    def __init__(self, valve: ValveParameters):
        self.A_L = valve.A_L
        self.back_area = valve.A_s3 - valve.A_B

    def __repr__(self) -> str:
        return "UniformPressureForceMap()"

    def force(self, p_L, p_B, u, fluid: FluidState) -> np.ndarray:
        p_L, p_B, _, _ = broadcast_query(p_L, p_B, u, fluid)
        return p_L * self.A_L + p_B * self.back_area


def _build_orifice(options, valve, base):
    return (OrificeFlowMap(options.get("discharge_coefficient", BASIC_DISCHARGE_COEFFICIENT),
                           valve.w), UniformPressureForceMap(valve))


register(MapKind(
    "orifice", "the paper's basic model: the orifice equation (eq. 4) with a constant discharge "
               "coefficient, and a uniform pressure on the piston (eq. 6, no flow force)",
    _build_orifice,
    (Option("discharge_coefficient", "C_d [-], constant",
            number_in(0.0, 1.0, "an orifice passes at most its ideal flow"),
            BASIC_DISCHARGE_COEFFICIENT),)))
