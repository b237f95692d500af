"""A valve model: the valve's parameters, a flow map, a force map and a list of effects.

The model knows the physics; the solver (:mod:`surrogate.solver`) only asks it for the force
balance at candidate piston positions. For measured inputs and an opening u the model

1. corrects the inputs for sensor errors (effects' ``correct_inputs``);
2. finds the pressure drop from the flow map, for the flow the main restriction carries
   (effects' ``restriction_flow``; with ``leakage`` effects, the split between restriction and
   leakage paths is solved so that both see the same Δp);
3. computes the fluid force from the force map (paper eq. 7),

       f_fl = f_sim(p_L, p_B, u) − p_B·A_s3 + p_P·A_P = p_L·A_L + p_P·A_P − p_B·A_B + f_ff,

   the spring force F_cr + K_f·u (eq. 3), and adds the effects' forces;
4. sums the effects' friction into the half-width of the Coulomb friction band.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .effects import BalanceState, Effect, FlowState
from .fluid import FluidState
from .leakage import shared_pressure_drop
from .maps.base import FlowMap, ForceMap
from .parameters import Parameters
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
    state : BalanceState
        What the effects' force and friction hooks saw (the true points, Δp, the flow force):
        the replay's sensitivities evaluate one effect's hooks on it alone
        (:mod:`surrogate.solver.sensitivities`).
    """

    p_L: np.ndarray
    dp: np.ndarray
    net_force: np.ndarray
    friction: np.ndarray
    state: BalanceState


def _uses(effect: Effect, hook: str) -> bool:
    return getattr(type(effect), hook) is not getattr(Effect, hook)


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
        Extra terms (sensor corrections, flow, leakage, forces, friction).
    name : str
        Display name, e.g. ``"CFDA"``.
    origin : (ValveSource, MapsSpec), optional
        Where the valve and the maps come from, for a model built from a
        :class:`~surrogate.description.spec.ModelSpec` (the way the package builds its models); it
        lets the model be described as a spec again
        (:meth:`~surrogate.description.spec.ModelSpec.of`), to be saved and rebuilt.
    """

    def __init__(self, valve: ValveParameters, flow_map: FlowMap, force_map: ForceMap,
                 effects: tuple[Effect, ...] | list[Effect] = (), name: str = "model",
                 origin: tuple | None = None):
        self.valve = valve
        self.flow_map = flow_map
        self.force_map = force_map
        self.effects = list(effects)
        self.name = name
        self.origin = origin
        self._back_area = valve.A_s3 - valve.A_B

    def __repr__(self) -> str:
        effects = ", ".join(repr(e) for e in self.effects) or "no effects"
        return f"ValveModel({self.name!r}: {self.flow_map!r}, {self.force_map!r}; {effects})"

    def copy(self, name: str | None = None) -> "ValveModel":
        """A copy whose effects (and so parameters) can change without touching this one."""
        return ValveModel(self.valve, self.flow_map, self.force_map,
                          [effect.copy() for effect in self.effects], name or self.name,
                          self.origin)

    def with_effects(self, effects, name: str | None = None) -> "ValveModel":
        """A copy with other effects (copied) on the same maps."""
        return ValveModel(self.valve, self.flow_map, self.force_map,
                          [effect.copy() for effect in effects], name or self.name,
                          self.origin)

    def effect(self, name: str) -> Effect:
        """The effect registered as ``name``."""
        for effect in self.effects:
            if effect.name == name:
                return effect
        raise KeyError(f"model {self.name!r} has no effect {name!r}; it has "
                       f"{', '.join(e.name for e in self.effects) or 'none'}")

    def has_effect(self, name: str) -> bool:
        return any(effect.name == name for effect in self.effects)

    def parameters(self) -> Parameters:
        """All parameters, keyed ``"effect.parameter"`` (the model's own objects: setting a value
        there sets it in the model)."""
        return Parameters((f"{effect.name}.{p.name}", p) for effect in self.effects
                          for p in effect.params.values())

    def penalty(self, keys, samples: int) -> tuple[np.ndarray, np.ndarray] | None:
        """The effects' penalties (:meth:`~surrogate.effects.Effect.penalty`) on a fit of the
        parameters ``keys`` (``"effect.parameter"``) over ``samples`` residuals: (L, b), the
        penalty's residual L·v + b [Pa] for the SI values v of ``keys``, b holding what the
        parameters outside ``keys`` contribute at their values; None when no effect has one."""
        index = {key: column for column, key in enumerate(keys)}
        matrices, offsets = [], []
        for effect in self.effects:
            matrix = effect.penalty(samples)
            if matrix is None:
                continue
            rows = np.zeros((matrix.shape[0], len(index)))
            offset = np.zeros(matrix.shape[0])
            for column, parameter in zip(matrix.T, effect.params.values()):
                key = f"{effect.name}.{parameter.name}"
                if key in index:
                    rows[:, index[key]] = column
                else:
                    offset += column * parameter.value
            matrices.append(rows)
            offsets.append(offset)
        if not matrices:
            return None
        return np.vstack(matrices), np.concatenate(offsets)

    @property
    def has_friction(self) -> bool:
        return any(_uses(effect, "friction") for effect in self.effects)

    @property
    def has_leakage(self) -> bool:
        """Whether an effect adds a leakage path beside the restriction."""
        return any(_uses(effect, "leakage") for effect in self.effects)

    def fluid(self, points: OperatingPoints) -> FluidState:
        """The oil's ν and ρ at each point's temperature."""
        return self.valve.oil.state(points.temperature)

    def true_points(self, points: OperatingPoints) -> OperatingPoints:
        """The operating points corrected for the sensor effects."""
        for effect in self.effects:
            corrected = effect.correct_inputs(points)
            if corrected is not None:
                points = corrected
        return points

    def pressure_drop(self, u, points: OperatingPoints, fluid: FluidState, maps=None
                      ) -> np.ndarray:
        """Δp [Pa] across the valve at opening ``u`` [m] for the (true) points' flow.

        With leakage effects the flow splits between the restriction and the leakage paths at
        a common Δp (:func:`surrogate.leakage.shared_pressure_drop`). ``maps``: the maps' values
        at these points and openings, when a fit reads them from its tables
        (:class:`surrogate.solver.map_tables.TabulatedMaps`) instead of asking the maps."""
        state = FlowState(np.broadcast_to(u, points.q.shape), points.q, points.p_B, points.p_P,
                          points.temperature, fluid, self.valve)
        flow_effects = [e for e in self.effects if _uses(e, "restriction_flow")]
        leaks = [e for e in self.effects if _uses(e, "leakage")]
        # a leak's split asks the restriction about these openings at many flows
        restriction = (self.flow_map.at_openings(state.p_B, state.u, fluid)
                       if leaks and maps is None else None)

        def through_restriction(q, index=slice(None)):
            sub = state if isinstance(index, slice) else state.subset(index)
            for effect in flow_effects:
                q = effect.restriction_flow(q, sub)
            if maps is not None:
                return maps.pressure_drop(q, index)
            if restriction is not None:
                return restriction(q, index)
            return self.flow_map.pressure_drop(q, sub.p_B, sub.u, sub.fluid)

        dp = through_restriction(points.q)
        if not leaks:
            return dp

        def leak_at(index):
            sub = state.subset(index)
            return lambda drop: sum(effect.leakage(drop, sub) for effect in leaks)

        return shared_pressure_drop(points.q, dp, through_restriction, leak_at)

    def balance(self, u, points: OperatingPoints, fluid: FluidState, maps=None) -> Balance:
        """The force balance with the piston at ``u`` [m] while the points' flow passes
        (``maps``: as :meth:`pressure_drop`'s)."""
        points = self.true_points(points)
        return self.balance_at(u, self.pressure_drop(u, points, fluid, maps), points, fluid,
                               maps)

    @property
    def may_change_the_flow(self) -> bool:
        """Whether an effect may ask the maps about another flow than the measured one: one
        that changes the flow through the restriction, adds a leak, or corrects the inputs (a
        flowmeter's gain; whatever its parameters' values)."""
        return any(_uses(effect, hook) for effect in self.effects
                   for hook in ("restriction_flow", "leakage", "correct_inputs"))

    def map_part(self, u, points: OperatingPoints, fluid: FluidState
                 ) -> tuple[np.ndarray, np.ndarray]:
        """What the maps contribute to :meth:`balance` at ``u`` [m] for the (true) points:
        the pressure drop Δp [Pa] and the flow force f_ff [N] at that Δp."""
        dp = self.pressure_drop(u, points, fluid)
        return dp, self.flow_force(u, dp, points, fluid)

    def balance_at(self, u, dp, points: OperatingPoints, fluid: FluidState, maps=None
                   ) -> Balance:
        """The force balance at ``u`` [m] with the pressure drop ``dp`` [Pa] imposed on the
        (true, i.e. already corrected) points, whatever the flow map says: the flow force at
        that load pressure. Its slopes in u and Δp carry map errors through the balance
        (:mod:`surrogate.solver.uncertainty`). ``maps``: as :meth:`pressure_drop`'s."""
        return self._balance(u, points, fluid, points.p_B + dp, dp,
                             self.flow_force(u, dp, points, fluid, maps))

    def flow_force(self, u, dp, points: OperatingPoints, fluid: FluidState, maps=None
                   ) -> np.ndarray:
        """f_ff [N]: what the force map gives at ``u`` [m] and Δp [Pa] beyond the uniform
        pressures (``maps``: as :meth:`pressure_drop`'s)."""
        if maps is not None:
            return maps.flow_force(dp)
        p_L = points.p_B + dp
        f_sim = self.force_map.force(p_L, points.p_B, u, fluid)
        return f_sim - p_L * self.valve.A_L - points.p_B * self._back_area

    def balance_without_flow(self, u, p_L, points: OperatingPoints,
                             fluid: FluidState) -> Balance:
        """The force balance at ``u`` [m] and load pressure ``p_L`` [Pa] with no flow (so no flow
        force): the closed valve, or one held open by its pilot alone."""
        points = self.true_points(points.replace(q=np.zeros(len(points))))
        p_L = np.broadcast_to(p_L, points.q.shape)
        return self._balance(u, points, fluid, p_L, p_L - points.p_B, np.zeros(points.q.shape))

    def _balance(self, u, points, fluid, p_L, dp, flow_force) -> Balance:
        valve = self.valve
        u = np.broadcast_to(u, points.q.shape)
        fluid_force = p_L * valve.A_L + points.p_P * valve.A_P - points.p_B * valve.A_B + flow_force
        net = fluid_force - (valve.F_cr + valve.K_f * u)
        friction = np.zeros(points.q.shape)
        state = BalanceState(u, points.q, p_L, points.p_B, points.p_P, points.temperature, fluid,
                             flow_force, valve)
        for effect in self.effects:
            extra = effect.force(state)
            if extra is not None:
                net = net + extra
            band = effect.friction(state)
            if band is not None:
                friction = friction + band
        return Balance(p_L, dp, net, friction, state)

    def restriction_flow(self, u, points: OperatingPoints, fluid: FluidState) -> np.ndarray:
        """The flow [m^3/s] through the main restriction at opening ``u`` [m] for the (true)
        points, as the flow effects divert it (leakage paths aside)."""
        state = FlowState(np.broadcast_to(u, points.q.shape), points.q, points.p_B, points.p_P,
                          points.temperature, fluid, self.valve)
        q = points.q
        for effect in self.effects:
            if _uses(effect, "restriction_flow"):
                q = effect.restriction_flow(q, state)
        return q

    def extrapolation_reasons(self, u, p_L, points: OperatingPoints,
                              fluid: FluidState) -> np.ndarray:
        """Why either map is queried outside its data with the points' flow passing at opening
        ``u`` [m] and load pressure ``p_L`` [Pa]: bit flags of :mod:`surrogate.maps.coverage`
        (0 inside)."""
        points = self.true_points(points)
        q = self.restriction_flow(u, points, fluid)
        return (self.flow_map.reasons_at_flow(q, points.p_B, u, fluid)
                | self.force_map.extrapolation_reasons(p_L, points.p_B, u, fluid))

    def extrapolating(self, u, p_L, points: OperatingPoints, fluid: FluidState) -> np.ndarray:
        """True where either map is queried outside its data (:meth:`extrapolation_reasons`)."""
        return self.extrapolation_reasons(u, p_L, points, fluid) != 0
