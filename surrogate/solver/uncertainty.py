"""The pressure drop's standard deviation that the maps' uncertainty implies, through the balance.

Each map reports a calibrated standard deviation (:mod:`surrogate.maps.sigma`): σ_C of
ln C_d, which moves the flow map's pressure drop at a given flow and opening by
δΔp_map = 2·Δp·σ_C, and σ_f of the flow force. Neither moves the computed Δp one for one: the
piston answers. Linearised about a solution (u, Δp) of the balance N(u, Δp) = 0, where N is the
net force less the friction on the side it acts (:class:`~surrogate.model.ValveModel.balance_at`)
and Δp(u) the flow map's pressure drop at the point's flow,

    δu  = −(N_Δp·δΔp_map + δf) / H,          H = N_u + N_Δp·Δp_u  (dN/du along Δp(u)),
    δΔp = δΔp_map + Δp_u·δu
        = (1 − Δp_u·N_Δp/H)·δΔp_map − (Δp_u/H)·δf.

A counterbalance valve regulates: where the piston floats, a flow-map error mostly moves the
piston, not the pressure, and the flow-force error is what shows in Δp. Where the piston cannot
move (held by friction, on its stop) Δp moves with the flow map alone. The two maps' errors are
taken as independent, and the partial derivatives by forward differences (three more balance
evaluations and one more pressure drop per point, next to the dozens a solve takes).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..model import ValveModel
from ..points import OperatingPoints

_STEP = 1e-5  # relative step of the forward differences


@dataclass(frozen=True)
class Sensitivity:
    """How the computed Δp of flowing points answers each map's error.

    δΔp = flow_gain·δln C_d + force_gain·δ(relative flow-force error), so that
    Var Δp = (flow_gain·σ_C)² + (force_gain·σ_f)² with σ_C and σ_f the maps' standard deviations
    against the valve in ln units (calibrated, with the CFD's own error).

    Attributes
    ----------
    index : numpy.ndarray of int
        The points (of those given) that carry flow and a solution.
    flow_gain, force_gain : numpy.ndarray
        [Pa] per unit ln C_d (lower) and per unit relative flow-force error (stronger); signed.
    flow_query : tuple
        (q through the restriction [m^3/s], p_B [Pa], u [m], fluid) at which the flow map is
        asked, per point of ``index``.
    force_query : tuple
        (p_L, p_B, u, fluid) at which the force map is asked.
    """

    index: np.ndarray
    flow_gain: np.ndarray
    force_gain: np.ndarray
    flow_query: tuple
    force_query: tuple


def sensitivity(model: ValveModel, points: OperatingPoints, u: np.ndarray, dp: np.ndarray,
                side: np.ndarray, held: np.ndarray) -> Sensitivity:
    """The gains of :class:`Sensitivity` at a solution (arguments as
    :func:`pressure_drop_std`), linearised as the module docstring says."""
    u, dp = np.asarray(u, float), np.asarray(dp, float)
    side, held = np.asarray(side, float), np.asarray(held, bool)
    true = model.true_points(points)
    flowing = np.flatnonzero(np.isfinite(dp) & np.isfinite(u) & (true.q > 0) & (u > 0))
    fluid = model.fluid(points)[flowing]
    sub, u_f, dp_f = true[flowing], u[flowing], dp[flowing]
    q = model.restriction_flow(u_f, sub, fluid)
    flow_gain = 2.0 * dp_f  # at a fixed opening, Δp ∝ C_d^−2
    force_gain = np.zeros(len(flowing))
    free = np.flatnonzero(~held[flowing])
    if free.size:
        part, at_u, at_dp, part_fluid = sub[free], u_f[free], dp_f[free], fluid[free]
        sign = side[flowing][free]

        def net(trial_u, trial_dp):
            balance = model.balance_at(trial_u, trial_dp, part, part_fluid)
            return balance.net_force - sign * balance.friction

        du, ddp = _STEP * at_u, _STEP * np.maximum(at_dp, 1.0)
        here = net(at_u, at_dp)
        n_u = (net(at_u + du, at_dp) - here) / du
        n_dp = (net(at_u, at_dp + ddp) - here) / ddp
        dp_u = (model.pressure_drop(at_u + du, part, part_fluid) - at_dp) / du
        total = n_u + n_dp * dp_u  # < 0: the net force falls as the piston opens
        flow_force = model.force_map.flow_force(part.p_B + at_dp, part.p_B, at_u, part_fluid) \
            if model.force_map.calibration is not None else np.zeros(free.size)
        with np.errstate(divide="ignore", invalid="ignore"):
            flow_gain[free] *= 1.0 - dp_u * n_dp / total
            force_gain[free] = -dp_u / total * flow_force
    return Sensitivity(flowing, flow_gain, force_gain, (q, sub.p_B, u_f, fluid),
                       (sub.p_B + dp_f, sub.p_B, u_f, fluid))


def pressure_drop_std(model: ValveModel, points: OperatingPoints, u: np.ndarray,
                      dp: np.ndarray, side: np.ndarray, held: np.ndarray) -> np.ndarray | None:
    """Standard deviation of the computed Δp [Pa] at each point, from the maps' uncertainty
    (arguments and result as :func:`map_error_effects`, the two maps' parts combined)."""
    parts = map_error_effects(model, points, u, dp, side, held)
    return None if parts is None else np.hypot(parts[0], parts[1])


def map_error_effects(model: ValveModel, points: OperatingPoints, u: np.ndarray,
                      dp: np.ndarray, side: np.ndarray, held: np.ndarray) -> np.ndarray | None:
    """How much the computed Δp [Pa] moves at each point when a map errs by one of its
    standard deviations: row 0 for the flow map (its Δp at the point's flow and opening too
    high by 2·σ_C in ln), row 1 for the force map (its flow force too strong by σ_f). Signed,
    so that one map error shared by many points moves them consistently (the workbench's map
    discrepancy, :mod:`surrogate.fitting.discrepancy`); their root-sum-square is σ_Δp.

    Parameters
    ----------
    model : ValveModel
    points : OperatingPoints
        The measured points (the model corrects them as it does in a solve).
    u, dp : numpy.ndarray
        The solution: opening [m] and pressure drop [Pa] (NaN where there is none).
    side : numpy.ndarray
        Friction's side at each point: +1 while the piston opens, −1 while it closes, 0 none.
    held : numpy.ndarray of bool
        True where the piston stays put whatever the maps say (friction holds it, or it rests
        on its stop): there Δp moves with the flow map's error alone.

    Returns
    -------
    numpy.ndarray or None
        (2, n) [Pa]: 0 without flow (no map involved), NaN where there is no solution; None
        when neither map has an uncertainty (the orifice equation).
    """
    found = map_error_gains(model, points, u, dp, side, held)
    return None if found is None else found[0] * found[1]


def map_error_gains(model: ValveModel, points: OperatingPoints, u: np.ndarray,
                    dp: np.ndarray, side: np.ndarray, held: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray] | None:
    """The two factors of :func:`map_error_effects` (same arguments): the gains, (2, n) [Pa]
    per unit ln C_d error of the flow map and per unit relative flow-force error of the force
    map, and the maps' standard deviations against the valve (2, n) [1] of those errors; None when
    neither map has an uncertainty."""
    flow_map, force_map = model.flow_map, model.force_map
    if flow_map.calibration is None and force_map.calibration is None:
        return None
    solved = np.isfinite(np.asarray(dp, float)) & np.isfinite(np.asarray(u, float))
    gain = np.where(solved, 0.0, np.nan) * np.ones((2, 1))
    std = np.zeros(gain.shape)
    gains = sensitivity(model, points, u, dp, side, held)
    if gains.index.size:
        log_cd_std = flow_map.log_discharge_std(*gains.flow_query)
        gain[0, gains.index], gain[1, gains.index] = gains.flow_gain, gains.force_gain
        std[0, gains.index] = 0.0 if log_cd_std is None else log_cd_std
        relative = force_map.relative_force_std(*gains.force_query)
        std[1, gains.index] = 0.0 if relative is None else np.ravel(relative)
    return gain, std
