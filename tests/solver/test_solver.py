"""The steady solver and the replay: analytic cases, invariants, edge cases and failure flags."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from surrogate.effects import (
    ConstantFriction,
    LaminarLeakage,
    LoadPressureFriction,
    custom_effect,
)
from surrogate.maps import OrificeFlowMap, UniformPressureForceMap
from surrogate.maps.base import FlowMap
from surrogate.model import ValveModel
from surrogate.points import OperatingPoints
from surrogate.solver import Status, replay, solve_steady, steady
from surrogate.core.units import BAR, LPM


def basic_model(valve, discharge_coefficient=0.4, effects=()):
    return ValveModel(valve, OrificeFlowMap(discharge_coefficient, valve.w),
                      UniformPressureForceMap(valve), list(effects), name="BM")


def eq15_flow(valve, dp, p_L, p_P, p_B, rho, discharge_coefficient=0.4, crack_force=None):
    """Paper eq. 15: q = C_V/K_δ·sqrt(Δp)·(p_L + α_P·p_P − (α_P + 1)·p_B − P_cr)."""
    crack_force = valve.F_cr if crack_force is None else crack_force
    c_v = discharge_coefficient * valve.w * valve.U_max * np.sqrt(2.0 / rho)  # eq. 13
    k_delta = valve.K_f * valve.U_max / valve.A_L  # eq. 14
    return c_v / k_delta * np.sqrt(dp) * (p_L + valve.alpha_P * p_P - (valve.alpha_P + 1) * p_B
                                          - crack_force / valve.A_L)


def eq15_pressure_drop(valve, q, p_Pe, rho, crack_force, discharge_coefficient=0.4):
    """Eq. 15 solved for Δp: x³ + (α_P·p_Pe − F/A_L)·x − q·K_δ/C_V = 0 with x = sqrt(Δp)."""
    c_v = discharge_coefficient * valve.w * valve.U_max * np.sqrt(2.0 / rho)
    k_delta = valve.K_f * valve.U_max / valve.A_L
    out = []
    for flow, pe in np.broadcast(q, p_Pe):
        roots = np.roots([1.0, 0.0, valve.alpha_P * pe - crack_force / valve.A_L,
                          -flow * k_delta / c_v])
        real = roots[(abs(roots.imag) < 1e-9 * abs(roots).max()) & (roots.real > 0)].real
        out.append(real.max() ** 2)
    return np.array(out)


def test_basic_model_reproduces_eq15_including_stop_and_near_closing(valve):
    grid = np.array(np.meshgrid([0.001, 0.05, 0.2, 1, 3, 6, 9, 12, 20],  # q [L/min]
                                [20, 35, 50, 65, 80, 100, 120, 150],  # p_Pe [bar]
                                [1.0, 5.0], [20.0, 60.0])).reshape(4, -1)  # p_B [bar], T [°C]
    q, p_Pe, p_B, temperature = grid
    points = OperatingPoints.from_display(q, p_Pe + p_B, p_B, temperature)
    solution = solve_steady(basic_model(valve), points)
    status = solution.status
    assert set(np.unique(status)) == {Status.OK, Status.AT_STOP}
    rho = valve.oil.density(points.temperature)
    inside = status == Status.OK
    q_eq15 = eq15_flow(valve, solution.dp, solution.p_L, points.p_P, points.p_B, rho)
    np.testing.assert_allclose(q_eq15[inside], points.q[inside], rtol=1e-9)
    assert np.min(solution.u[inside]) < 1e-4 * valve.U_max  # points near closing are covered
    # on the stop: the orifice at full stroke passes the flow, and the net force still opens
    stop = status == Status.AT_STOP
    q_stop = 0.4 * valve.w * valve.U_max * np.sqrt(2 * solution.dp[stop] / rho[stop])
    np.testing.assert_allclose(q_stop, points.q[stop], rtol=1e-9)  # Δp = p_L − p_B of ~1e-4 Pa
    assert np.all(solution.u[stop] == valve.U_max)


def test_play_gives_the_hand_computed_hysteresis_loop(valve):
    """Linear spring, constant friction K1: the up-ramp is the basic model with crack force
    F_cr + K1, the down-ramp the one with F_cr − K1, joined by a stretch where the piston sticks."""
    K1 = 12.0
    model = basic_model(valve, effects=[ConstantFriction(K1=K1)])
    q = np.concatenate([np.linspace(1, 12, 300), np.linspace(12, 1, 300)]) * LPM
    p_B, p_Pe = 3 * BAR, 50 * BAR
    points = OperatingPoints.create(q, p_Pe + p_B, p_B, 313.15)
    solver_replay = replay(model, points)
    assert solver_replay.ok.all()
    rho = valve.oil.density(313.15)
    up = eq15_pressure_drop(valve, q, p_Pe, rho, valve.F_cr + K1)
    down = eq15_pressure_drop(valve, q, p_Pe, rho, valve.F_cr - K1)
    rising = slice(0, 300)
    np.testing.assert_allclose(solver_replay.dp[rising], up[rising], rtol=1e-9)
    falling = np.arange(300, 600)
    stuck = falling[~solver_replay.moving[falling]]
    sliding = falling[solver_replay.moving[falling]]
    assert 5 < len(stuck) < 295 and stuck.max() < sliding.min()  # stick first, then slide
    np.testing.assert_allclose(solver_replay.u[stuck], solver_replay.u[299])
    np.testing.assert_allclose(solver_replay.dp[sliding], down[sliding], rtol=1e-9)
    # loop width at low flow tends to the friction band 2·K1/A_L
    tiny = OperatingPoints.create(np.full(2, 1e-4 * LPM), p_Pe + p_B, p_B, 313.15, [1, -1])
    width = np.diff(solve_steady(model, tiny).dp[::-1])[0]
    assert width == pytest.approx(2 * K1 / valve.A_L, rel=1e-3)


def test_smoothed_state_does_not_ratchet_on_pilot_noise(valve):
    """Sensor noise on p_P: the classic play's piston follows the running maximum of the noise
    while it slides open, so its pressure drop runs low on the up-ramp, and it keeps a lead where
    friction holds it after the turn. The play on smoothed edges (7 samples, as the workbench's
    replay of a 25 Hz log) removes most of both."""
    model = basic_model(valve, effects=[ConstantFriction(K1=12.0)])
    q = np.concatenate([np.linspace(1, 12, 500), np.linspace(12, 1, 500)]) * LPM
    p_B, p_Pe = 3 * BAR, 50 * BAR
    truth = replay(model, OperatingPoints.create(q, p_Pe + p_B, p_B, 313.15))
    held = np.flatnonzero(~truth.moving[500:]) + 500  # after the turn, before sliding back
    rising = np.arange(50, 450)
    assert len(held) > 20
    bias, lead = {}, {}
    for window in (1, 7):
        ramp_errors, leads = [], []
        for seed in range(3):
            noise = 0.3 * BAR * np.random.default_rng(seed).standard_normal(len(q))
            noisy = OperatingPoints.create(q, p_Pe + p_B + noise, p_B, 313.15)
            solver_replay = replay(model, noisy, smoothing=window)
            ramp_errors.append(np.mean(solver_replay.dp[rising] - truth.dp[rising]))
            leads.append(np.median(solver_replay.u[held] - truth.u[held]))
        bias[window], lead[window] = np.mean(ramp_errors), np.mean(leads)
    assert bias[1] < -0.1 * BAR and lead[1] > 0  # the classic play ratchets
    assert abs(bias[7]) < 0.3 * abs(bias[1])
    assert abs(lead[7]) < 0.6 * lead[1]


def test_smoothing_of_noise_free_ramps_keeps_the_hand_computed_loop(valve):
    """On noise-free straight ramps the smoothed state is the classic play's: the filter follows
    ramps exactly and rounds only the turn, by much less than the friction band."""
    model = basic_model(valve, effects=[ConstantFriction(K1=12.0)])
    q = np.concatenate([np.linspace(1, 12, 300), np.linspace(12, 1, 300)]) * LPM
    points = OperatingPoints.create(q, 53 * BAR, 3 * BAR, 313.15)
    classic, smoothed = replay(model, points), replay(model, points, smoothing=7)
    np.testing.assert_allclose(smoothed.dp[:296], classic.dp[:296], rtol=1e-9)
    band = 2 * 12.0 / valve.A_L  # the friction band in pressure drop, 22 bar
    assert np.max(np.abs(smoothed.dp - classic.dp)) < 0.01 * band


def test_replay_without_friction_is_the_steady_solution(valve, grid_maps):
    flow_map, force_map = grid_maps
    model = ValveModel(valve, flow_map, force_map)
    points = OperatingPoints.from_display(np.linspace(1, 12, 50), 68.0, 3.0, 40.0)
    solver_replay = replay(model, points)
    steady = solve_steady(model, points)
    np.testing.assert_allclose(solver_replay.dp, steady.dp, rtol=1e-12)


def cfda_model(valve, grid_maps, K1=0.0, K2=0.0):
    flow_map, force_map = grid_maps
    return ValveModel(valve, flow_map, force_map,
                      [ConstantFriction(K1=K1), LoadPressureFriction(K2=K2)])


@settings(max_examples=40, deadline=None)
@given(q=st.lists(st.floats(0.2, 15.0), min_size=1, max_size=30),
       p_Pe=st.floats(20.0, 150.0), p_B=st.floats(1.0, 8.0), temperature=st.floats(10.0, 70.0),
       direction=st.sampled_from([-1, 0, 1]))
def test_solutions_stay_within_the_stroke(valve, grid_maps, q, p_Pe, p_B, temperature,
                                          direction):
    model = cfda_model(valve, grid_maps, K1=8.0, K2=0.05)  # K2 in N/bar
    points = OperatingPoints.from_display(q, p_Pe + p_B, p_B, temperature, direction)
    solution = solve_steady(model, points)
    assert solution.ok.all(), solution.failure_summary()
    assert np.all((solution.u >= 0) & (solution.u <= valve.U_max))


@settings(max_examples=40, deadline=None)
@given(q=st.lists(st.floats(0.2, 15.0), min_size=1, max_size=30),
       p_Pe=st.floats(20.0, 150.0), temperature=st.floats(10.0, 70.0),
       direction=st.sampled_from([-1, 0, 1]),
       factor=st.one_of(st.floats(0.97, 1.03), st.floats(0.3, 3.0)))
def test_a_guess_changes_how_fast_not_what(valve, grid_maps, q, p_Pe, temperature, direction,
                                           factor):
    # guesses within the first ±2 % bracket, within the wider ones, and beyond all of them
    model = cfda_model(valve, grid_maps, K1=8.0, K2=0.05)  # K2 in N/bar
    points = OperatingPoints.from_display(q, p_Pe + 5.0, 5.0, temperature, direction)
    cold = solve_steady(model, points)
    warm = solve_steady(model, points, guess=cold.u * factor)
    np.testing.assert_array_equal(warm.status, cold.status)
    np.testing.assert_allclose(warm.u, cold.u, rtol=1e-12)
    np.testing.assert_allclose(warm.dp, cold.dp, rtol=1e-9)


@settings(max_examples=40, deadline=None)
@given(p_Pe=st.floats(20.0, 150.0), p_B=st.floats(1.0, 8.0), temperature=st.floats(10.0, 70.0))
def test_pressure_drop_rises_with_flow_without_friction(valve, grid_maps, p_Pe, p_B,
                                                        temperature):
    points = OperatingPoints.from_display(np.linspace(0.5, 14.0, 60), p_Pe + p_B, p_B,
                                          temperature)
    solution = solve_steady(cfda_model(valve, grid_maps), points)
    assert solution.ok.all()
    assert np.all(np.diff(solution.dp) > 0)


def test_closed_valve_holds_up_to_its_crack_pressure(valve):
    p_P, p_B = 40 * BAR, 4 * BAR
    points = OperatingPoints.create(0.0, p_P, p_B, 313.15)
    solution = solve_steady(basic_model(valve), points)
    assert solution.status[0] == Status.CLOSED and solution.u[0] == 0.0
    crack = (valve.F_cr - p_P * valve.A_P + p_B * valve.A_B) / valve.A_L
    assert solution.p_L[0] == pytest.approx(crack, rel=1e-9)


def test_pilot_alone_can_hold_the_valve_open_without_flow(valve):
    p_B = 2 * BAR
    points = OperatingPoints.create(0.0, [p_B + 82 * BAR, p_B + 150 * BAR], p_B, 313.15)
    solution = solve_steady(basic_model(valve), points)
    assert list(solution.status) == [Status.OK, Status.AT_STOP]
    np.testing.assert_allclose(solution.p_L, p_B)
    opening = (points.p_P[0] * valve.A_P + p_B * valve.A_L - p_B * valve.A_B - valve.F_cr)
    assert solution.u[0] == pytest.approx(opening / valve.K_f, rel=1e-9)


class _BrokenFlowMap(FlowMap):
    """Returns NaN beyond half the stroke, like a surrogate that failed to load."""

    def __init__(self, valve):
        self.inner = OrificeFlowMap(0.4, valve.w)
        self.half = valve.U_max / 2

    def pressure_drop(self, q, p_B, u, fluid):
        dp = self.inner.pressure_drop(q, p_B, u, fluid)
        return np.where(np.asarray(u) > self.half, np.nan, dp)


class _LeakyFlowMap(FlowMap):
    """Almost no pressure drop at any opening: the valve can never build up its crack force."""

    def pressure_drop(self, q, p_B, u, fluid):
        return np.broadcast_to(1.0, np.broadcast(q, u).shape).astype(float)


def test_failures_are_flagged_with_a_reason_never_silent(valve):
    points = OperatingPoints.from_display([np.nan, -1.0, 6.0, 6.0], 60.0, 3.0,
                                          [40.0, 40.0, np.nan, 40.0])
    solution = solve_steady(basic_model(valve), points)
    assert list(solution.status[:3]) == [Status.INVALID_INPUT] * 3
    assert solution.status[3] == Status.OK

    broken = ValveModel(valve, _BrokenFlowMap(valve), UniformPressureForceMap(valve))
    solution = solve_steady(broken, OperatingPoints.from_display([3.0, 3.0], [60, 150], 3, 40))
    assert solution.status[1] == Status.MAP_FAILURE

    leaky = ValveModel(valve, _LeakyFlowMap(), UniformPressureForceMap(valve))
    solution = solve_steady(leaky, OperatingPoints.from_display(6.0, 40.0, 3.0, 40.0))
    assert solution.status[0] == Status.NO_EQUILIBRIUM
    assert "no equilibrium" in solution.reasons()[0]
    assert "1 point(s): no equilibrium" in solution.failure_summary()


@settings(max_examples=30, deadline=None)
@given(q=st.lists(st.one_of(st.floats(-5, 20), st.just(float("nan")), st.just(0.0)),
                  min_size=1, max_size=20),
       p_Pe=st.floats(0.0, 200.0), temperature=st.floats(-30.0, 150.0))
def test_no_silent_nan(valve, grid_maps, q, p_Pe, temperature):
    solution = solve_steady(cfda_model(valve, grid_maps, K1=5.0),
                            OperatingPoints.from_display(q, p_Pe + 3.0, 3.0, temperature, 1))
    nan = np.isnan(solution.u) | np.isnan(solution.p_L)
    assert np.array_equal(nan, solution.status < 0)


def test_extrapolating_solutions_are_reported(valve, grid_maps):
    model = cfda_model(valve, grid_maps)
    points = OperatingPoints.from_display([6.0, 6.0, 1.0], [65 + 5, 65 + 5, 20 + 5], 5.0,
                                          [40.0, 95.0, 40.0])
    solution = solve_steady(model, points)
    assert list(solution.extrapolating) == [False, True, True]  # inside; too hot; u < 0.05 mm
    assert solution.u[2] < 0.05e-3


@custom_effect("force", units={"f": "N", "u0": "mm", "w": "1"})
def force_bump(state, f=0.0, u0=0.1, w=0.3):
    """A force f [N] (negative: closing) around the opening u0, over a width w in ln u: a
    made-up term that bends the balance so that it rises with u somewhere."""
    return f * np.exp(-(np.log(state.u / u0) / w) ** 2)


def dip_model(valve):
    """A laminar leak keeps Δp, and h, bounded at small openings (about 120 bar at 6 L/min);
    a closing force of 60 N around 0.01 mm pulls h below zero there: three equilibria per side
    at 6 L/min and a pilot pressure of 50 bar, about 0.006, 0.02 and 0.05 mm (the check's
    sample, a factor 3 from the outer ones, falls between the inner two)."""
    return basic_model(valve, effects=[LaminarLeakage(G=0.05), ConstantFriction(K1=5.0),
                                       force_bump(f=-60.0, u0=0.01, w=0.7)])


def stop_model(valve):
    """An opening force of 200 N near the stop: at 8 L/min and a pilot pressure of 53 bar h falls
    through zero at ~0.19 mm,
    rises through it again at ~0.52 mm and is positive on the stop."""
    return basic_model(valve, effects=[ConstantFriction(K1=5.0),
                                       force_bump(f=200.0, u0=0.63, w=0.25)])


def every_root(model, points):
    """Each point's roots of h [m], from its sign changes on 20,000 openings, refined."""
    from scipy.optimize import brentq

    stroke = model.valve.U_max
    grid = np.geomspace(1e-7 * stroke, stroke, 20_000)
    roots = []
    for k in range(len(points)):
        point, sign = points[np.full(grid.size, k)], float(points.direction[k])

        def h(u, k=k, sign=sign):
            one = points[[k]]
            balance = model.balance(np.atleast_1d(u), one, model.fluid(one))
            return float((balance.net_force - sign * balance.friction)[0])

        balance = model.balance(grid, point, model.fluid(point))
        values = balance.net_force - sign * balance.friction
        changes = np.flatnonzero(np.sign(values[1:]) != np.sign(values[:-1]))
        roots.append([brentq(h, grid[i], grid[i + 1], xtol=1e-30, rtol=1e-14)
                      for i in changes])
    return roots


DIRECTIONS = [1, 0, -1]  # opening, no friction, closing


@pytest.mark.parametrize("guess_at", [None, 0, 1, 2, "far above", "far below"])
def test_of_three_equilibria_the_solver_takes_the_rules_whatever_the_guess(valve, guess_at):
    """Opening (and without friction) the smallest stable equilibrium, the one a piston opening
    from closed meets; closing the largest, the one a piston closing from the stop meets. A
    guess near any of the three roots (the middle one unstable), or none, changes nothing."""
    model = dip_model(valve)
    points = OperatingPoints.from_display(np.full(3, 6.0), 53.0, 3.0, 40.0, DIRECTIONS)
    roots = every_root(model, points)
    assert [len(r) for r in roots] == [3, 3, 3]  # the model does what it is made for
    expected = np.array([r[0] if d >= 0 else r[2] for r, d in zip(roots, DIRECTIONS)])
    if guess_at is None:
        guess = None
    elif guess_at == "far above":
        guess = np.array([r[2] * 3.0 for r in roots])
    elif guess_at == "far below":
        guess = np.array([r[0] / 3.0 for r in roots])
    else:  # inside the first bracket around that root
        guess = np.array([r[guess_at] * 1.01 for r in roots])
    solution = solve_steady(model, points, guess=guess)
    assert list(solution.status) == [Status.OK] * 3
    np.testing.assert_allclose(solution.u, expected, rtol=1e-10)


@pytest.mark.parametrize("guess_at", [None, 0, 1])
def test_a_piston_closing_from_the_stop_stays_on_it_one_opening_stops_below(valve, guess_at):
    """h >= 0 on the stop with an equilibrium inside the stroke: opening, the piston meets the
    equilibrium first; closing from the stop, it never leaves the stop."""
    model = stop_model(valve)
    points = OperatingPoints.from_display(np.full(3, 8.0), 56.0, 3.0, 40.0, DIRECTIONS)
    roots = every_root(model, points)
    assert [len(r) for r in roots] == [2, 2, 2]  # down through zero, then up again
    guess = None if guess_at is None else np.array([r[guess_at] * 1.01 for r in roots])
    solution = solve_steady(model, points, guess=guess)
    assert list(solution.status) == [Status.OK, Status.OK, Status.AT_STOP]
    np.testing.assert_allclose(solution.u[:2], [roots[0][0], roots[1][0]], rtol=1e-10)
    assert solution.u[2] == valve.U_max


@pytest.mark.parametrize("guess_at", [None, 0, 1])
def test_a_piston_coming_down_from_the_stop_stops_where_h_turns_positive(valve, guess_at):
    """A leak too weak to hold the valve open at 3 L/min (h < 0 at a vanishing opening and on
    the stop) and an opening force around 0.003 mm that lifts h above zero between about 0.0016
    and 0.005 mm: closing from the stop, the piston stops where h turns positive; opening from
    closed, it never leaves the seat."""
    model = basic_model(valve, effects=[LaminarLeakage(G=0.05), ConstantFriction(K1=5.0),
                                        force_bump(f=40.0, u0=0.003, w=0.6)])
    points = OperatingPoints.from_display(np.full(3, 3.0), 53.0, 3.0, 40.0, DIRECTIONS)
    roots = every_root(model, points)
    assert [len(r) for r in roots] == [2, 2, 2]  # up through zero, then down again
    guess = None if guess_at is None else np.array([r[guess_at] * 1.01 for r in roots])
    solution = solve_steady(model, points, guess=guess)
    assert list(solution.status) == [Status.NO_EQUILIBRIUM] * 2 + [Status.OK]
    assert solution.u[2] == pytest.approx(roots[2][1], rel=1e-10)


def test_without_the_rule_a_guess_would_pick_the_equilibrium(valve, monkeypatch):
    """The models above need the rule: without its check the root follows the guess."""
    model = dip_model(valve)
    points = OperatingPoints.from_display(np.full(3, 6.0), 53.0, 3.0, 40.0, DIRECTIONS)
    roots = every_root(model, points)
    monkeypatch.setattr(steady, "_first_met", lambda h: None)
    for k in (0, 2):
        guess = np.array([r[k] * 1.01 for r in roots])
        np.testing.assert_allclose(solve_steady(model, points, guess=guess).u,
                                   [r[k] for r in roots], rtol=1e-10)


def test_a_replay_with_several_equilibria_does_not_depend_on_its_guess(valve):
    """Up and down a flow ramp through the three equilibria, started from a replay of a model
    with a weaker dip (whose band sits on the upper branch): the same replay as from cold."""
    q = np.concatenate([np.linspace(5.8, 6.0, 40), np.linspace(6.0, 5.8, 40)])
    points = OperatingPoints.from_display(q, 53.0, 3.0, 40.0)
    model = dip_model(valve)
    other = basic_model(valve, effects=[LaminarLeakage(G=0.05), ConstantFriction(K1=5.0),
                                        force_bump(f=-20.0, u0=0.01, w=0.7)])
    cold = replay(model, points)
    warm = replay(model, points, guess=replay(other, points))
    assert np.all(cold.band[1] > 5 * cold.band[0])  # the band's edges on different branches
    np.testing.assert_array_equal(warm.status, cold.status)
    np.testing.assert_allclose(warm.u, cold.u, rtol=1e-10)
    np.testing.assert_allclose(warm.dp, cold.dp, rtol=1e-9)


@pytest.mark.parametrize("shape", [(918,), (918, 2), (9,), (57, 3)])
def test_the_band_edges_smoothing_forms_the_run_ends_as_tensordot_does(shape):
    """The run ends' products are np.tensordot's own (a dot of the same reshapes), to the bit."""
    from numpy.lib.stride_tricks import sliding_window_view

    from surrogate.solver.replay import _savgol, _savgol_operators

    x = np.random.default_rng(len(shape) + shape[0]).normal(size=shape)
    for size in (5, 7, 9):
        if len(x) < size:
            continue
        weights, first, last = _savgol_operators(size)
        half, length = size // 2, len(x)
        expected = np.empty_like(x)
        expected[half:length - half] = sliding_window_view(x, size, axis=0) @ weights
        expected[:half] = np.tensordot(first, x[:size], axes=(1, 0))
        expected[length - half:] = np.tensordot(last, x[length - size:], axes=(1, 0))
        assert np.array_equal(_savgol(x, size), expected)
