"""Unit checks of individual library effects against their stated physics."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from surrogate import load_valve
from surrogate.effects import (BUILT_IN, BalanceState, LaminarLeakage, NearSeatFlowForce,
                               load_effects_file)
from surrogate.fluid import FluidState
from surrogate.model import ValveModel
from surrogate.points import OperatingPoints
from surrogate.testing import check_effect
from surrogate.core.units import to_si


def balance_state(u, flow_force):
    u = np.asarray(u, float)
    ones = np.ones_like(u)
    return BalanceState(u, 1e-4 * ones, 100e5 * ones, 5e5 * ones, 60e5 * ones, 313.15 * ones,
                        FluidState(46e-6 * ones, 860.0 * ones), flow_force * ones,
                        load_valve())


def test_near_seat_flow_force_acts_only_below_the_reference_opening():
    effect = NearSeatFlowForce(k=1.0, u_ref=0.05)  # u_ref in mm
    u = np.array([0.0125e-3, 0.025e-3, 0.05e-3, 0.2e-3])
    extra = effect.force(balance_state(u, -40.0))
    # k = 1: the flow force scales with u/u_ref below u_ref, so the extra force cancels
    # (1 − u/u_ref) of the (closing, negative) flow force and opens the valve
    assert extra == pytest.approx([30.0, 20.0, 0.0, 0.0])


def test_near_seat_flow_force_is_the_maps_rule_at_k_zero():
    effect = NearSeatFlowForce(k=0.0)
    assert np.all(effect.force(balance_state([1e-6, 1e-5, 1e-4], -40.0)) == 0.0)


@given(q_lpm=st.floats(1.0, 12.0), u_mm=st.floats(0.03, 0.6),
       leak_lpm_per_bar=st.floats(1e-4, 0.05), temperature_C=st.floats(20.0, 60.0))
@settings(max_examples=40, deadline=None)
def test_laminar_leakage_splits_the_flow_between_restriction_and_clearance(
        valve, grid_maps, q_lpm, u_mm, leak_lpm_per_bar, temperature_C):
    flow_map, force_map = grid_maps
    model = ValveModel(valve, flow_map, force_map,
                       [LaminarLeakage(G=leak_lpm_per_bar)])
    points = OperatingPoints.from_display(np.array([q_lpm]), np.array([60.0]), np.array([5.0]),
                                          np.array([temperature_C]))
    fluid = model.fluid(points)
    u = to_si(u_mm, "mm")
    dp = model.pressure_drop(u, points, fluid)
    # the restriction passes what the clearance does not, and at that flow the map gives the
    # same pressure drop
    through_restriction = points.q - model.effect("laminar_leakage").leakage(dp, None)
    assert 0.0 < through_restriction[0] <= points.q[0]
    expected = flow_map.pressure_drop(through_restriction, points.p_B, np.array([u]), fluid)
    assert dp == pytest.approx(expected, rel=1e-7)


#: a leakage table [bar] -> [L/min] like the one a diagnosis handed over in stress case 4262 of
#: eval/offlibrary.py: flat, then steep up to its last row, and held beyond it
_TABLE_DP_BAR = np.array([0.0, 20.0, 40.0, 60.0, 80.0, 100.0, 120.0, 140.0, 152.0])
_TABLE_LEAK_LPM = np.array([0.0, 0.029, 0.034, 0.043, 0.086, 0.157, 0.243, 0.343, 0.459])


@pytest.mark.parametrize("q_lpm", [0.6, 1.12, 1.5, 2.0])
@pytest.mark.parametrize("scale", [0.7, 1.0, 1.5])
def test_a_leakage_table_splits_the_flow_at_every_opening(valve, grid_maps, q_lpm, scale):
    """At small openings the restriction alone would need far more Δp than the table's last row,
    where the leak's slope drops to 0: Newton's power-law step can cycle there, and a step that
    is no root must not stand in for the map (it gave Δp 40 % off at some openings, and a force
    balance that zig-zagged in u)."""
    from surrogate.effects import FlowState, custom_effect

    @custom_effect("leakage", units={"scale": "1"})
    def table_leak(dp, state, scale=0.0):
        """A leakage from a table, held beyond its rows."""
        return scale * np.interp(np.maximum(dp, 0.0) / 1e5, _TABLE_DP_BAR, _TABLE_LEAK_LPM) / 6e4

    flow_map, force_map = grid_maps
    leak = table_leak(scale=scale)
    model = ValveModel(valve, flow_map, force_map, [leak])
    u = to_si(np.linspace(0.002, 0.03, 57), "mm")
    points = OperatingPoints.from_display(np.full(u.size, q_lpm), 56.0, 5.0, 60.0)
    fluid = model.fluid(points)
    dp = model.pressure_drop(u, points, fluid)
    state = FlowState(u, points.q, points.p_B, points.p_P, points.temperature, fluid, valve)
    through_restriction = points.q - leak.leakage(dp, state)
    expected = flow_map.pressure_drop(through_restriction, points.p_B, u, fluid)
    np.testing.assert_allclose(dp, expected, rtol=1e-7)
    assert np.all(np.diff(dp) < 0)  # a wider opening passes the same flow at less Δp


@pytest.mark.parametrize("cls", BUILT_IN, ids=[cls.name for cls in BUILT_IN])
def test_every_built_in_effect_meets_the_effect_contract(cls):
    check_effect(cls)


def test_the_custom_effect_example_meets_the_effect_contract():
    from surrogate.core.paths import PROJECT_ROOT

    for cls in load_effects_file(PROJECT_ROOT / "examples" / "seat_force.py").values():
        check_effect(cls)


def test_the_effect_contract_catches_a_broken_effect():
    """An effect that is on at its defaults, or whose friction turns negative, fails the check."""
    from surrogate.effects import Effect, Parameter

    class AlwaysOn(Effect):
        name, kind, category = "always_on", "force", "physics"
        title = "a force that never switches off"
        parameter_specs = (Parameter("f", 5.0, "N", min=0.0, max=10.0),)

        def force(self, state):
            return np.full(state.u.shape, self["f"])

    class NegativeFriction(Effect):
        name, kind, category = "negative_friction", "friction", "physics"
        title = "friction below zero"
        parameter_specs = (Parameter("k", 0.0, "N", min=-5.0, max=5.0),)

        def friction(self, state):
            return np.full(state.u.shape, self["k"])

    with pytest.raises(AssertionError, match="switch the effect off"):
        check_effect(AlwaysOn)
    with pytest.raises(AssertionError, match="negative friction"):
        check_effect(NegativeFriction)


def test_a_custom_effect_is_not_blamed_for_a_state_the_solver_has_no_value_for():
    """A pressure drop the flow split has not settled (NaN) gives a NaN leak: that is no fault
    of the user's function; a NaN from finite inputs is, and says so."""
    from surrogate.effects import FlowState, custom_effect
    from surrogate.core.errors import InputError

    @custom_effect("leakage", units={"G": "L/min"})
    def leak(dp, state, G=0.1):
        return G * np.sqrt(np.maximum(dp, 0.0)) / 1e3

    @custom_effect("leakage", units={"G": "L/min"})
    def broken(dp, state, G=0.1):
        return G * np.sqrt(dp - 50e5) / 1e3  # NaN below 50 bar

    valve = load_valve()
    fluid = FluidState(np.full(3, 46e-6), np.full(3, 870.0))
    state = FlowState(np.full(3, 1e-4), np.full(3, 1e-4), np.zeros(3), np.zeros(3),
                      np.full(3, 313.0), fluid, valve)
    flows = leak().leakage(np.array([100e5, np.nan, 20e5]), state)
    assert np.isnan(flows[1]) and np.all(np.isfinite(flows[[0, 2]]))
    with pytest.raises(InputError, match="1 non-finite value.*from finite inputs"), \
            np.errstate(invalid="ignore"):
        broken().leakage(np.array([100e5, np.nan, 20e5]), state)


def test_a_custom_effects_penalty_pulls_its_parameter_towards_zero_in_every_fit():
    """``penalties={"k": w}`` [bar per unit]: every fit over n residuals adds n·(w·k)², with k in
    its display unit; a parameter without one has no row; a negative weight or an unknown
    parameter is refused by name."""
    from surrogate.effects import custom_effect
    from surrogate.core.errors import InputError

    @custom_effect("friction", units={"k": "N", "m": "N/bar"}, penalties={"k": 0.5})
    def pulled(state, k=1.0, m=0.0):
        return k + m * state.p_L

    rows = pulled().penalty(100)
    assert rows.shape == (1, 2)
    k_display = 3.0
    assert np.linalg.norm(rows @ [k_display, 0.0]) ** 2 == pytest.approx(100 * (0.5e5 * 3.0) ** 2)
    assert np.all(rows[:, 1] == 0.0)
    model = ValveModel(load_valve(), None, None, [pulled()])
    assert model.penalty(["pulled.k"], 100)[0].shape == (1, 1)

    with pytest.raises(InputError, match="penalty of 'k' is -1.0"):
        custom_effect("friction", penalties={"k": -1.0})
    with pytest.raises(InputError, match="unknown parameter.*nope"):
        custom_effect("friction", penalties={"nope": 1.0})(lambda state, k=1.0: k)
