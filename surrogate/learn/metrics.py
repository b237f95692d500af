"""Accuracy of flow and force maps on CFD samples, the way the evaluation reports it."""

from __future__ import annotations

import numpy as np

from ..fluid import FluidState
from ..maps.base import FlowMap, ForceMap
from ..valve import ValveParameters


def relative_rmse(predicted, true) -> float:
    """Root-mean-square of the relative errors, sqrt(mean((predicted/true − 1)²)) [-]."""
    predicted, true = np.asarray(predicted, float), np.asarray(true, float)
    return float(np.sqrt(np.mean((predicted / true - 1.0) ** 2))) if len(true) else float("nan")


def map_errors(flow_map: FlowMap, force_map: ForceMap, frame, valve: ValveParameters) -> dict:
    """Relative RMSE of q (predicted from p_L) and of the flow-force part of f_sim.

    The flow-force part is f_sim − p_L·A_L − p_B·(A_s3 − A_B): the part a uniform pressure would
    not give, which is what a force map has to learn.
    """
    fluid = FluidState(frame["nu"].to_numpy(), frame["rho"].to_numpy())
    p_L, p_B, u = (frame[name].to_numpy() for name in ("p_L", "p_B", "u"))
    q = flow_map.flow(p_L, p_B, u, fluid)
    uniform = p_L * valve.A_L + p_B * (valve.A_s3 - valve.A_B)
    flow_force = force_map.force(p_L, p_B, u, fluid) - uniform
    true_flow_force = frame["f_sim"].to_numpy() - uniform
    return {"samples": int(len(frame)),
            "q_rel_rmse": relative_rmse(q, frame["q"]),
            "flow_force_rel_rmse": relative_rmse(flow_force, true_flow_force),
            "q_max_rel_error": float(np.max(np.abs(q / frame["q"] - 1))) if len(frame) else None}
