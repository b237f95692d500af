"""A valve model: the valve's parameters, a flow map, a force map and a list of effects.

The model knows the physics; the solver (:mod:`surrogate.solver`) only asks it for the force
balance at candidate piston positions. For a flow q at opening u the model finds the pressure
drop from the flow map, the fluid force from the force map (paper eq. 7),

    f_fl = f_sim(p_L, p_B, u) − p_B·A_s3 + p_P·A_P
         = p_L·A_L + p_P·A_P − p_B·A_B + f_ff,

the spring force f_spr = F_cr + K_f·u (eq. 3), and adds what its effects contribute: extra forces,
and the half-width of the Coulomb friction band.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .effects import BalanceState, Effect, Parameter
from .fluid import FluidState
from .maps.base import FlowMap, ForceMap
from .points import OperatingPoints
from .valve import ValveParameters


@dataclass(frozen=True)
class Balance:
    """The force balance at a batch of piston positions.

    Attributes
    ----------
    p_L : numpy.ndarray
        Load pressure [Pa].
    dp : numpy.ndarray
        Pressure drop p_L − p_B [Pa], kept separately because it can be far smaller than p_L.
    net_force : numpy.ndarray
        Fluid force minus spring force plus effect forces [N]; positive opens the valve.
    friction : numpy.ndarray
        Half-width of the Coulomb friction band [N], >= 0.
    """

    p_L: np.ndarray
    dp: np.ndarray
    net_force: np.ndarray
    friction: np.ndarray


class ValveModel:
    """Maps plus effects for one valve.

    Parameters
    ----------
    valve : ValveParameters
        Geometry, spring, stroke and oil.
    flow_map : FlowMap
        q(p_L, p_B, u, fluid) and its inverse.
    force_map : ForceMap
        f_sim(p_L, p_B, u, fluid).
    effects : sequence of Effect
        Extra terms of the force balance.
    name : str
        Display name, e.g. ``"CFDA"``.
    """

    def __init__(self, valve: ValveParameters, flow_map: FlowMap, force_map: ForceMap,
                 effects: tuple[Effect, ...] | list[Effect] = (), name: str = "model"):
        self.valve = valve
        self.flow_map = flow_map
        self.force_map = force_map
        self.effects = list(effects)
        self.name = name
        self._back_area = valve.A_s3 - valve.A_B

    def __repr__(self) -> str:
        effects = ", ".join(repr(e) for e in self.effects) or "no effects"
        return f"ValveModel({self.name!r}: {self.flow_map!r}, {self.force_map!r}; {effects})"

    def copy(self, name: str | None = None) -> "ValveModel":
        """A copy whose effects (and so parameters) can change without touching this one."""
        return ValveModel(self.valve, self.flow_map, self.force_map,
                          [effect.copy() for effect in self.effects], name or self.name)

    def effect(self, name: str) -> Effect:
        """The effect registered as ``name``."""
        for effect in self.effects:
            if effect.name == name:
                return effect
        raise KeyError(f"model {self.name!r} has no effect {name!r}; it has "
                       f"{', '.join(e.name for e in self.effects) or 'none'}")

    def parameters(self) -> list[tuple[Effect, Parameter]]:
        """All parameters with the effect they belong to."""
        return [(effect, p) for effect in self.effects for p in effect.params.values()]

    @property
    def has_friction(self) -> bool:
        return any(type(e).friction is not Effect.friction for e in self.effects)

    def fluid(self, points: OperatingPoints) -> FluidState:
        """The oil's ν and ρ at each point's temperature."""
        return self.valve.oil.state(points.temperature)

    def balance(self, u, points: OperatingPoints, fluid: FluidState) -> Balance:
        """The force balance with the piston at ``u`` [m] while the points' flow passes."""
        dp = self.flow_map.pressure_drop(points.q, points.p_B, u, fluid)
        p_L = points.p_B + dp
        f_sim = self.force_map.force(p_L, points.p_B, u, fluid)
        flow_force = f_sim - p_L * self.valve.A_L - points.p_B * self._back_area
        return self._balance(u, points, fluid, p_L, dp, flow_force)

    def balance_without_flow(self, u, p_L, points: OperatingPoints,
                             fluid: FluidState) -> Balance:
        """The force balance at ``u`` [m] and load pressure ``p_L`` [Pa] with no flow (so no flow
        force): the closed valve, or one held open by its pilot alone."""
        p_L = np.broadcast_to(p_L, points.q.shape)
        return self._balance(u, points.replace(q=np.zeros(len(points))), fluid, p_L,
                             p_L - points.p_B, np.zeros(points.q.shape))

    def _balance(self, u, points, fluid, p_L, dp, flow_force) -> Balance:
        valve = self.valve
        u = np.broadcast_to(u, points.q.shape)
        fluid_force = p_L * valve.A_L + points.p_P * valve.A_P - points.p_B * valve.A_B + flow_force
        net = fluid_force - (valve.F_cr + valve.K_f * u)
        friction = np.zeros(points.q.shape)
        if self.effects:
            state = BalanceState(u, points.q, p_L, points.p_B, points.p_P, points.temperature,
                                 fluid, flow_force, valve)
            for effect in self.effects:
                extra = effect.force(state)
                if extra is not None:
                    net = net + extra
                band = effect.friction(state)
                if band is not None:
                    friction = friction + band
        return Balance(p_L, dp, net, friction)

    def extrapolating(self, u, p_L, points: OperatingPoints, fluid: FluidState) -> np.ndarray:
        """True where either map is queried outside its data with the points' flow passing at
        opening ``u`` [m] and load pressure ``p_L`` [Pa]."""
        return (self.flow_map.extrapolating_at_flow(points.q, points.p_B, u, fluid)
                | self.force_map.extrapolating(p_L, points.p_B, u, fluid))
