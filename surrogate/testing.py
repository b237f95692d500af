"""Contract checks every map and every effect must pass, shipped with the package (as GPyTorch
ships its tests and scikit-learn its ``check_estimator``).

A user who writes a new :class:`~surrogate.maps.base.FlowMap`, :class:`~surrogate.maps.base.ForceMap`
or effect runs the same checks as the built-in ones::

    from surrogate.testing import check_effect, check_flow_map
    check_flow_map(MyFlowMap(...), oil)
    check_effect(MyEffect)

Each check raises ``AssertionError`` with a message naming what broke. The command line runs
:func:`check_effect` on every effect of an ``--effects-file`` as it loads it.
"""

from __future__ import annotations

import numpy as np

from .effects.base import CATEGORIES, KINDS, BalanceState, Effect, FlowState
from .effects.library import EffectLibrary
from .fluid import FluidState, Oil
from .maps.base import FlowMap, ForceMap, MapResult
from .points import OperatingPoints
from .core.units import BAR, LPM, MM, ZERO_CELSIUS
from .valve import ValveParameters, load_valve


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


_HOOKS = {"sensor": "correct_inputs", "flow": "restriction_flow", "leakage": "leakage",
          "force": "force", "friction": "friction"}
_RUNS = ("R01", "R02", "R03")


def _effect_states(seed: int, count: int, valve: ValveParameters):
    """A grid of states in and around a valve's working range: the points (with run labels),
    the flow state and the balance state at them."""
    rng = np.random.default_rng(seed)
    u = rng.uniform(0.0, 1.0, count) * valve.U_max
    q = rng.uniform(0.5, 14.0, count) * LPM
    p_B = rng.uniform(1.0, 8.0, count) * BAR
    p_P = rng.uniform(0.0, 150.0, count) * BAR
    p_L = p_B + rng.uniform(0.5, 300.0, count) * BAR
    temperature = rng.uniform(15.0, 70.0, count) + ZERO_CELSIUS
    fluid = valve.oil.state(temperature)
    flow_force = -rng.uniform(0.0, 0.4, count) * valve.A_L * (p_L - p_B)
    points = OperatingPoints(q, p_P, p_B, temperature, rng.choice([-1, 1], count),
                             rng.choice(_RUNS, count))
    return (points, FlowState(u, q, p_B, p_P, temperature, fluid, valve),
            BalanceState(u, q, p_L, p_B, p_P, temperature, fluid, flow_force, valve),
            p_L - p_B)


def _trial_values(effect: Effect) -> list[dict[str, float]]:
    """Parameter values (display units) to try: the defaults, and points inside the bounds of
    the parameters a fit varies (the others are the effect's structure, such as a shape's knots,
    which must rise: all at one fraction of their bounds they would coincide)."""
    settings = [{}]
    for fraction in (0.25, 0.75):
        values = {}
        for name, parameter in effect.params.items():
            if not parameter.vary:
                continue
            low, high = parameter.display_bounds
            if np.isfinite(low) and np.isfinite(high):
                values[name] = low + fraction * (high - low)
            else:
                values[name] = parameter.display_value + (1.0 if fraction > 0.5 else -1.0)
        settings.append(values)
    return settings


def _call(effect: Effect, states) -> object:
    points, flow_state, balance_state, dp = states
    if effect.kind == "sensor":
        return effect.correct_inputs(points)
    if effect.kind == "flow":
        return effect.restriction_flow(points.q, flow_state)
    if effect.kind == "leakage":
        return effect.leakage(dp, flow_state)
    return getattr(effect, _HOOKS[effect.kind])(balance_state)


def check_effect(cls: type[Effect], valve: ValveParameters | None = None, *, count: int = 60,
                 seed: int = 0) -> None:
    """Check the effect contract on a grid of states and parameter values.

    * a name, a kind and a category, and the kind's hook (and no other) overridden;
    * the default values switch the effect off: the inputs, the restriction's flow, the leakage,
      the force and the friction stay what they are without it;
    * at the defaults and at values inside the bounds, the hook returns finite values of the
      states' shape (sensors: operating points of the same number), friction >= 0 and leakage
      >= 0;
    * it survives a model-file round trip: the parameters come back as they were.
    """
    valve = valve or load_valve()
    name = getattr(cls, "name", "") or cls.__name__
    assert cls.name and cls.kind in KINDS, f"{name}: needs a name and a kind in {KINDS}"
    assert cls.category in CATEGORIES, (f"{name}: needs a category in {CATEGORIES} (what a "
                                        "diagnosis that picks it says about the valve)")
    overridden = [kind for kind, hook in _HOOKS.items()
                  if getattr(cls, hook) is not getattr(Effect, hook)]
    assert overridden == [cls.kind], (f"{name}: a {cls.kind} effect must override "
                                      f"{_HOOKS[cls.kind]}() and no other hook; it overrides "
                                      f"{', '.join(_HOOKS[k] + '()' for k in overridden) or 'none'}")
    states = _effect_states(seed, count, valve)
    points, _, _, dp = states
    off = cls.for_runs(list(_RUNS))
    result = _call(off, states)
    if cls.kind == "sensor":
        for field in ("q", "p_P", "p_B", "temperature"):
            assert np.allclose(getattr(result, field), getattr(points, field), rtol=1e-12), (
                f"{name}: at its default values it changes the {field} readings; the defaults "
                "are where a fit starts: they must switch the effect off")
    else:
        neutral = points.q if cls.kind == "flow" else np.zeros(count)
        assert np.allclose(np.broadcast_to(result, (count,)), neutral, rtol=1e-12,
                           atol=1e-12 * float(np.max(np.abs(neutral), initial=1.0))), (
            f"{name}: at its default values its {_HOOKS[cls.kind]}() is not neutral; the "
            "defaults are where a fit starts: they must switch the effect off")
    for values in _trial_values(off):
        effect = cls.for_runs(list(_RUNS))
        for key, value in values.items():
            effect.params[key].set_display(value)
        result = _call(effect, states)
        if cls.kind == "sensor":
            assert isinstance(result, OperatingPoints) and len(result) == count, (
                f"{name}: correct_inputs() must return OperatingPoints of the points given")
            continue
        array = np.broadcast_to(np.asarray(result, float), (count,))
        assert np.all(np.isfinite(array)), f"{name}: non-finite output at {values}"
        if cls.kind in ("friction", "leakage"):
            assert np.all(array >= 0), f"{name}: negative {cls.kind} at {values}"
    _check_round_trip(cls, _trial_values(off)[-1], valve)


def _check_round_trip(cls: type[Effect], values: dict[str, float],
                      valve: ValveParameters) -> None:
    from .description.presets import basic_maps
    from .description.spec import EffectSpec, ModelSpec, ValveSource

    effect = cls.for_runs(list(_RUNS))
    for key, value in values.items():
        effect.params[key].set_display(value)
    spec = ModelSpec("check", ValveSource("shipped", valve), basic_maps(),
                     (EffectSpec.of(effect),))
    again = ModelSpec.from_toml(spec.to_toml())
    assert again == spec, f"{cls.name}: its model-file entry does not read back as written"
    rebuilt = again.build(EffectLibrary([cls])).effect(cls.name)
    for key, parameter in effect.params.items():
        back = rebuilt.params[key]
        assert np.isclose(back.value, parameter.value, rtol=1e-12, atol=0) and (
            back.vary == parameter.vary and back.scope == parameter.scope), (
            f"{cls.name}: parameter {key} does not survive a model-file round trip")
