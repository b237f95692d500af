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

from dataclasses import dataclass, field

import numpy as np

from .effects import BalanceState, Effect, FlowState, Parameter
from .fluid import FluidState
from .maps.base import FlowMap, ForceMap
from .points import OperatingPoints
from .valve import ValveParameters

_LEAKAGE_STEPS = 80  # safeguarded secant steps at most
# the leakage split ends when the power law's error in ln Δp is below 1e-9 for |f''| <= 20:
# the grid's sweeps have |f''| <= 1.4, an orifice 0, laminar flow 0
_SETTLED = 1e-10


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


@dataclass(frozen=True)
class MapsSource:
    """Where a model's maps come from, so it can be written to a file and rebuilt.

    ``kind`` is ``"orifice"`` (with ``discharge_coefficient``), ``"grid"``, ``"nn"``, ``"gp"`` or
    the path of a surrogate folder.
    """

    kind: str
    options: dict = field(default_factory=dict)


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
    maps_source : MapsSource, optional
        Where the maps come from (needed to save the model to a file).
    """

    def __init__(self, valve: ValveParameters, flow_map: FlowMap, force_map: ForceMap,
                 effects: tuple[Effect, ...] | list[Effect] = (), name: str = "model",
                 maps_source: MapsSource | None = None):
        self.valve = valve
        self.flow_map = flow_map
        self.force_map = force_map
        self.effects = list(effects)
        self.name = name
        self.maps_source = maps_source
        self._back_area = valve.A_s3 - valve.A_B

    def __repr__(self) -> str:
        effects = ", ".join(repr(e) for e in self.effects) or "no effects"
        return f"ValveModel({self.name!r}: {self.flow_map!r}, {self.force_map!r}; {effects})"

    def copy(self, name: str | None = None) -> "ValveModel":
        """A copy whose effects (and so parameters) can change without touching this one."""
        return ValveModel(self.valve, self.flow_map, self.force_map,
                          [effect.copy() for effect in self.effects], name or self.name,
                          self.maps_source)

    def with_effects(self, effects, name: str | None = None) -> "ValveModel":
        """A copy with other effects (copied) on the same maps."""
        return ValveModel(self.valve, self.flow_map, self.force_map,
                          [effect.copy() for effect in effects], name or self.name,
                          self.maps_source)

    def effect(self, name: str) -> Effect:
        """The effect registered as ``name``."""
        for effect in self.effects:
            if effect.name == name:
                return effect
        raise KeyError(f"model {self.name!r} has no effect {name!r}; it has "
                       f"{', '.join(e.name for e in self.effects) or 'none'}")

    def has_effect(self, name: str) -> bool:
        return any(effect.name == name for effect in self.effects)

    def parameters(self) -> list[tuple[Effect, Parameter]]:
        """All parameters with the effect they belong to."""
        return [(effect, p) for effect in self.effects for p in effect.params.values()]

    @property
    def has_friction(self) -> bool:
        return any(_uses(effect, "friction") for effect in self.effects)

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

    def pressure_drop(self, u, points: OperatingPoints, fluid: FluidState) -> np.ndarray:
        """Δp [Pa] across the valve at opening ``u`` [m] for the (true) points' flow."""
        state = FlowState(np.broadcast_to(u, points.q.shape), points.q, points.p_B, points.p_P,
                          points.temperature, fluid, self.valve)
        flow_effects = [e for e in self.effects if _uses(e, "restriction_flow")]
        leaks = [e for e in self.effects if _uses(e, "leakage")]

        def through_restriction(q, index=slice(None)):
            sub = state if isinstance(index, slice) else _subset(state, index)
            for effect in flow_effects:
                q = effect.restriction_flow(q, sub)
            return self.flow_map.pressure_drop(q, sub.p_B, sub.u, sub.fluid)

        dp = through_restriction(points.q)
        if not leaks:
            return dp

        # the leakage path and the restriction see the same Δp and share the flow q: find the
        # restriction's share q_r in [0, q] with g(q_r) = q_r + leak(Δp_r(q_r)) − q = 0, which
        # rises with q_r. Each step solves that equation with Δp_r(q_r) replaced by the power law
        # through the last two evaluations of the map (an orifice is close to one), kept inside
        # the bracket on q_r. The power law is the secant of ln Δp(ln q_r) through those two
        # evaluations, so at the step its error is ½·f''·ln(step/current)·ln(step/previous) with
        # f'' = d²ln Δp/d(ln q)²; once that product is below _SETTLED, the law's Δp at the step
        # stands in for the map's, which saves the map call that would only confirm it. On the
        # shipped log almost every sample settles after three map calls.
        def leak(x, sub):
            return sum(effect.leakage(x, sub) for effect in leaks)

        flowing = np.flatnonzero((points.q > 0) & np.isfinite(dp) & (dp > 0))
        q = points.q[flowing]
        g_full = leak(dp[flowing], _subset(state, flowing))  # g at q_r = q
        if not np.any(g_full > 0):
            return dp
        dp = dp.copy()
        low, high = np.zeros(flowing.size), q.copy()
        previous, previous_drop = q.copy(), dp[flowing]
        share = np.clip(q - g_full, 0.0, q)
        active = np.arange(flowing.size)  # points not converged yet: only these are iterated
        for _ in range(_LEAKAGE_STEPS):
            index = flowing[active]
            sub = _subset(state, index)
            current, wanted = share[active], q[active]
            drop = through_restriction(current, index)
            g = current + leak(drop, sub) - wanted
            lower = np.where(g < 0, current, low[active])
            upper = np.where(g >= 0, current, high[active])
            with np.errstate(divide="ignore", invalid="ignore"):
                secant = (np.log(drop / previous_drop[active])
                          / np.log(current / previous[active]))
            exponent = np.where(np.isfinite(secant), np.clip(secant, 0.5, 4.0), 2.0)
            step = _power_law_step(current, drop, exponent, wanted, lambda x: leak(x, sub))
            with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
                predicted = drop * (step / current) ** exponent
                # the secant's error at the step, in ln Δp: ½·f''·ln(step/current)·ln(step/prev)
                spread = np.abs(np.log(step / current) * np.log(step / previous[active]))
            settled = ((spread <= _SETTLED) & (exponent == secant) & (step > lower)
                       & (step < upper) & np.isfinite(predicted))
            dp[index] = np.where(settled, predicted, drop)
            # converged: the flows balance to 1e-9 of q (so the leak, and Δp, to ~1e-9), the
            # power law's next step is settled, or the bracket is down to rounding (the
            # restriction passes almost nothing)
            done = (np.abs(g) <= 1e-9 * wanted) | settled | (upper - lower <= 1e-12 * upper)
            low[active], high[active] = lower, upper
            previous[active], previous_drop[active] = current, drop
            share[active] = np.where((step > lower) & (step < upper), step,
                                     0.5 * (lower + upper))
            active = active[~done]
            if not active.size:
                break
        return dp

    def balance(self, u, points: OperatingPoints, fluid: FluidState) -> Balance:
        """The force balance with the piston at ``u`` [m] while the points' flow passes."""
        points = self.true_points(points)
        dp = self.pressure_drop(u, points, fluid)
        p_L = points.p_B + dp
        f_sim = self.force_map.force(p_L, points.p_B, u, fluid)
        flow_force = f_sim - p_L * self.valve.A_L - points.p_B * self._back_area
        return self._balance(u, points, fluid, p_L, dp, flow_force)

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
        points = self.true_points(points)
        state = FlowState(np.broadcast_to(u, points.q.shape), points.q, points.p_B, points.p_P,
                          points.temperature, fluid, self.valve)
        q = points.q
        for effect in self.effects:
            if _uses(effect, "restriction_flow"):
                q = effect.restriction_flow(q, state)
        return (self.flow_map.extrapolating_at_flow(q, points.p_B, u, fluid)
                | self.force_map.extrapolating(p_L, points.p_B, u, fluid))


def _power_law_step(share, drop, exponent, q, leak, newton_steps: int = 3) -> np.ndarray:
    """Root x of x + leak(Δp(x)) = q with Δp(x) = drop·(x/share)^exponent (no map call)."""
    x = share
    for _ in range(newton_steps):
        with np.errstate(divide="ignore", invalid="ignore"):
            pressure = drop * (x / share) ** exponent
            nudge = 1e-6 * pressure
            slope = (leak(pressure + nudge) - leak(pressure)) / nudge  # d leak / dΔp
            derivative = 1.0 + slope * exponent * pressure / x
            x = x - (x + leak(pressure) - q) / derivative
    return x


def _subset(state: FlowState, index) -> FlowState:
    return FlowState(state.u[index], state.q[index], state.p_B[index], state.p_P[index],
                     state.temperature[index], state.fluid[index], state.valve)
