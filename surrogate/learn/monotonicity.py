"""Counting monotonicity violations of flow and force maps at random states.

Half the states are drawn log-uniformly inside the CFD samples' ranges, half over a box far wider
(openings from 0.005 to 1.2 mm, pressure drops from 0.01 to 800 bar, viscosities from 3 to 500 cSt,
back pressures up to 20 bar), so both interpolation and extrapolation are tested. Each state is
compared with a neighbour 0.1 % higher in p_L (q and f_sim must not fall) and 0.1 % wider in u
(q must not fall); the pressure drop for the state's flow is checked the same way (it must rise
with q and fall with u).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..fluid import FluidState
from ..maps.base import FlowMap, ForceMap
from ..core.units import BAR, CST, MM

# the CFD samples' ranges: inside them a state counts as "in range"
_SAMPLED = {"u": (0.05 * MM, 0.63 * MM), "dp": (0.2 * BAR, 400 * BAR),
            "nu": (22 * CST, 118 * CST), "p_B": (1.5 * BAR, 10 * BAR)}
_STEP = 1e-3
_TOLERANCE = 1e-9  # relative; below this a decrease is numerical noise of the inversion


@dataclass(frozen=True)
class States:
    u: np.ndarray
    p_L: np.ndarray
    p_B: np.ndarray
    fluid: FluidState

    @property
    def in_range(self) -> np.ndarray:
        """True where every quantity lies inside the CFD samples' ranges."""
        dp = self.p_L - self.p_B
        checks = [(self.u, "u"), (dp, "dp"), (self.fluid.nu, "nu"), (self.p_B, "p_B")]
        return np.all([(v >= _SAMPLED[k][0]) & (v <= _SAMPLED[k][1]) for v, k in checks], axis=0)


def random_states(count: int, seed: int = 0) -> States:
    """``count`` states: half inside the sampled ranges, half over the wide box."""
    rng = np.random.default_rng(seed)
    inside = np.arange(count) < count // 2

    def log_uniform(wide, sampled):
        low = np.where(inside, sampled[0], wide[0])
        high = np.where(inside, sampled[1], wide[1])
        return np.exp(rng.uniform(np.log(low), np.log(high)))

    p_B = log_uniform((1e-3 * BAR, 20.0 * BAR), _SAMPLED["p_B"])
    dp = log_uniform((0.01 * BAR, 800.0 * BAR), _SAMPLED["dp"])
    return States(log_uniform((0.005 * MM, 1.2 * MM), _SAMPLED["u"]), p_B + dp, p_B,
                  FluidState(log_uniform((3.0 * CST, 500.0 * CST), _SAMPLED["nu"]),
                             rng.uniform(750.0, 1000.0, count)))


def violations(flow_map: FlowMap, force_map: ForceMap, states: States) -> dict:
    """Where q falls as p_L or u rises, or f_sim falls as p_L rises: counts in and out of range."""
    s = states
    higher = s.p_B + (1.0 + _STEP) * (s.p_L - s.p_B)
    q = flow_map.flow(s.p_L, s.p_B, s.u, s.fluid)
    q_pressure = flow_map.flow(higher, s.p_B, s.u, s.fluid) < q * (1.0 - _TOLERANCE)
    q_opening = flow_map.flow(s.p_L, s.p_B, s.u * (1.0 + _STEP), s.fluid) < q * (1.0 - _TOLERANCE)
    dp = flow_map.pressure_drop(q, s.p_B, s.u, s.fluid)
    dp_flow = flow_map.pressure_drop(q * (1.0 + _STEP), s.p_B, s.u, s.fluid) < dp * (1 - _TOLERANCE)
    dp_opening = (flow_map.pressure_drop(q, s.p_B, s.u * (1.0 + _STEP), s.fluid)
                  > dp * (1 + _TOLERANCE))
    force = force_map.force(s.p_L, s.p_B, s.u, s.fluid)
    f_pressure = (force_map.force(higher, s.p_B, s.u, s.fluid)
                  < force - _TOLERANCE * np.abs(force))
    inside = s.in_range
    result = {"states": int(len(s.u)), "in_range": int(inside.sum())}
    checks = (("q_vs_p_L", q_pressure), ("q_vs_u", q_opening), ("dp_vs_q", dp_flow),
              ("dp_vs_u", dp_opening), ("f_sim_vs_p_L", f_pressure))
    for name, bad in checks:
        result[name] = {"in_range": int(np.sum(bad & inside)), "outside": int(np.sum(bad & ~inside))}
    result["total"] = int(np.sum(np.any([bad for _, bad in checks], axis=0)))
    return result
