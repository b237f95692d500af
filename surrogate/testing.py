"""Contract checks every map must pass, shipped with the package (as GPyTorch ships its tests).

A user who writes a new :class:`~surrogate.maps.base.FlowMap` or
:class:`~surrogate.maps.base.ForceMap` runs the same checks as the built-in ones::

    from surrogate.testing import check_flow_map
    check_flow_map(MyFlowMap(...), oil)

Each check raises ``AssertionError`` with a message naming what broke.
"""

from __future__ import annotations

import numpy as np

from .fluid import FluidState, Oil
from .maps.base import FlowMap, ForceMap, MapResult
from .units import BAR, LPM, MM, ZERO_CELSIUS


def _query_points(seed: int, count: int, oil: Oil):
    rng = np.random.default_rng(seed)
    u = rng.uniform(0.03, 0.63, count) * MM
    q = rng.uniform(0.5, 14.0, count) * LPM
    p_B = rng.uniform(1.0, 8.0, count) * BAR
    fluid = oil.state(rng.uniform(15.0, 70.0, count) + ZERO_CELSIUS)
    return u, q, p_B, fluid


def check_flow_map(flow_map: FlowMap, oil: Oil, *, count: int = 200, seed: int = 0,
                   rtol: float = 1e-6) -> None:
    """Check the flow-map contract on random points in and around the valve's working range.

    * shapes broadcast and results are finite, with flow >= 0 and Δp >= 0;
    * :meth:`~FlowMap.flow` and :meth:`~FlowMap.pressure_drop` invert each other to ``rtol``;
    * flow is non-decreasing in p_L and zero at Δp = 0;
    * ``extrapolating`` and ``query`` return arrays of the query's shape.
    """
    u, q, p_B, fluid = _query_points(seed, count, oil)
    dp = flow_map.pressure_drop(q, p_B, u, fluid)
    assert dp.shape == q.shape, f"pressure_drop returned shape {dp.shape}, expected {q.shape}"
    assert np.all(np.isfinite(dp)) and np.all(dp > 0), "pressure_drop must be finite and > 0"
    back = flow_map.flow(p_B + dp, p_B, u, fluid)
    assert np.allclose(back, q, rtol=rtol, atol=0), (
        f"flow(pressure_drop(q)) differs from q by up to {np.max(np.abs(back / q - 1)):.2g}")
    for factor in (1.01, 1.5, 3.0):
        more = flow_map.flow(p_B + factor * dp, p_B, u, fluid)
        assert np.all(more >= back * (1 - 1e-12)), "flow must not fall as p_L rises"
    zero = flow_map.flow(p_B, p_B, u, fluid)
    assert np.allclose(zero, 0.0, atol=1e-12), "flow must vanish at Δp = 0"
    scalar = flow_map.pressure_drop(q[0], p_B[0], u, FluidState(fluid.nu[0], fluid.rho[0]))
    assert scalar.shape == u.shape, "scalar arguments must broadcast against arrays"
    flags = flow_map.extrapolating(p_B + dp, p_B, u, fluid)
    assert flags.shape == q.shape and flags.dtype == bool, "extrapolating must be a bool array"
    result = flow_map.query(p_B + dp, p_B, u, fluid)
    assert isinstance(result, MapResult) and result.value.shape == q.shape
    if result.std is not None:
        assert result.std.shape == q.shape and np.all(result.std >= 0), "std must be >= 0"


def check_force_map(force_map: ForceMap, flow_map: FlowMap, oil: Oil, *, count: int = 200,
                    seed: int = 1) -> None:
    """Check the force-map contract at points on the flow map's characteristic.

    * results are finite and of the query's shape;
    * f_sim is non-decreasing in p_L;
    * ``extrapolating`` and ``query`` return arrays of the query's shape.
    """
    u, q, p_B, fluid = _query_points(seed, count, oil)
    p_L = p_B + flow_map.pressure_drop(q, p_B, u, fluid)
    force = force_map.force(p_L, p_B, u, fluid)
    assert force.shape == q.shape and np.all(np.isfinite(force)), "force must be finite"
    for factor in (1.01, 1.5, 3.0):
        higher = force_map.force(p_B + factor * (p_L - p_B), p_B, u, fluid)
        assert np.all(higher >= force - 1e-9 * np.abs(force)), "f_sim must not fall as p_L rises"
    flags = force_map.extrapolating(p_L, p_B, u, fluid)
    assert flags.shape == q.shape and flags.dtype == bool, "extrapolating must be a bool array"
    result = force_map.query(p_L, p_B, u, fluid)
    assert isinstance(result, MapResult) and result.value.shape == q.shape
    if result.std is not None:
        assert result.std.shape == q.shape and np.all(result.std >= 0), "std must be >= 0"
