"""The fit's map tables (surrogate.solver.map_tables) against the maps they stand for, and the
play's prefix scan against the loop it replaced."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from surrogate.description import presets
from surrogate.effects import LIBRARY
from surrogate.fitting.residuals import replay_log
from surrogate.description.modelfile import load_model
from surrogate.points import OperatingPoints
from surrogate.solver.map_tables import FINE, MapTables, _Locator
from surrogate.solver.replay import (FROM_START, OWN_HIGH, OWN_LOW, STATE_LOW, play,
                                     play_bounds)
from surrogate.core.units import BAR


@pytest.fixture(scope="module")
def setting(cfda_on_runs):
    return cfda_on_runs(6)


def test_a_grid_maps_pressure_drop_is_tabulated_exactly_and_its_flow_force_closely(setting):
    """Between the grid's sampled openings (nodes of the table) ln Δp is linear in ln u: the
    table holds it to the rounding of its single-precision slopes. The flow force bends along
    u; its cubic is third order."""
    log, model, log_replay = setting
    points = OperatingPoints.from_bench(log.frame)
    tables = MapTables(model)
    tables.tabulate(model, points, log_replay.replay.band)
    view = tables.view(points)
    held = np.flatnonzero(view.row >= 0)
    assert held.size > 0.9 * np.count_nonzero(points.q > 0)
    level = view.levels[FINE]
    rows = view.row[held]
    start = level.first[rows]
    low, high = level.nodes[start], level.nodes[start + level.count[rows] - 1]
    u = np.exp(low + (high - low) * np.random.default_rng(3).random(held.size))
    dp, flow_force, inside = view[held].lookup(u)
    assert inside.all()
    sub = points[held]
    dp_maps, force_maps = model.map_part(u, sub, model.fluid(sub))
    # exact but for the slopes' single precision (they multiply a hundredth in ln u)
    np.testing.assert_allclose(dp, dp_maps, rtol=1e-9)
    force_error = np.abs(flow_force - force_maps) / model.valve.A_L
    assert np.median(force_error) < 1e-5 * BAR
    assert np.quantile(force_error, 0.99) < 5e-3 * BAR


def test_on_the_stop_the_tables_give_the_maps_own_answers(setting):
    """No window holds the stroke itself: there a tabulated balance gives the maps' answers,
    kept per row when tabulated (Δp at the measured flow, the flow force at that Δp), to the
    bit; at another flow or Δp, and at another opening outside the windows, it asks the maps."""
    from surrogate.solver.map_tables import TabulatedMaps

    log, model, log_replay = setting
    points = OperatingPoints.from_bench(log.frame)
    tables = MapTables(model)
    tables.tabulate(model, points, log_replay.replay.band)
    view = tables.view(points)
    fluid = model.fluid(points)
    rng = np.random.default_rng(5)
    stroke = model.valve.U_max
    u = np.where(rng.random(len(points)) < 0.7, stroke, stroke * rng.uniform(1e-6, 1.0,
                                                                             len(points)))
    kept = TabulatedMaps(model, view, points, fluid, u)
    asked = TabulatedMaps(model, view, points, fluid, u)
    asked.at_stroke = None  # every point outside the windows asks the maps
    assert kept.at_stroke is not None and not kept.inside[u == stroke].any()
    q = points.q * np.where(rng.random(len(points)) < 0.8, 1.0, 1.01)  # some at another flow
    dp = kept.pressure_drop(q)
    np.testing.assert_array_equal(dp, asked.pressure_drop(q))
    np.testing.assert_array_equal(kept.pressure_drop(points.q), asked.pressure_drop(points.q))
    for drops in (dp, dp * np.where(rng.random(len(points)) < 0.8, 1.0, 1.01)):
        np.testing.assert_array_equal(kept.flow_force(drops), asked.flow_force(drops))
    on_stop = (u == stroke) & (view.row >= 0) & (points.q > 0)
    np.testing.assert_array_equal(kept.pressure_drop(points.q)[on_stop],
                                  model.flow_map.pressure_drop(points.q, points.p_B, u,
                                                               fluid)[on_stop])


def test_outside_its_window_a_sample_is_not_in_the_table(setting):
    log, model, log_replay = setting
    points = OperatingPoints.from_bench(log.frame)
    tables = MapTables(model)
    tables.tabulate(model, points, log_replay.replay.band)
    view = tables.view(points)
    flowing = np.flatnonzero(view.row >= 0)[:50]
    far = log_replay.replay.band[0, flowing] * 10.0
    *_, inside = view[flowing].lookup(far)
    assert not inside.any()
    *_, inside = view[flowing].lookup(log_replay.replay.band[0, flowing])
    assert inside.all()


def test_a_replay_from_the_tables_matches_one_from_the_maps(setting):
    """A fit's inner loop (a guess, no diagnostics) reads the tables; what it replays is the
    maps' replay to well under the noise of a bench log (tenths of a bar)."""
    log, model, log_replay = setting
    tabulated = replay_log(model, log, guess=log_replay, diagnostics=False)
    assert tabulated.replay.tables is not None
    assert log_replay.replay.tables is None
    both = np.isfinite(tabulated.replay.dp) & np.isfinite(log_replay.replay.dp)
    assert both.mean() > 0.9
    difference = tabulated.replay.dp[both] - log_replay.replay.dp[both]
    assert np.sqrt(np.mean(difference ** 2)) < 5e-3 * BAR
    assert np.array_equal(tabulated.replay.moving, log_replay.replay.moving)


FLOW_CHANGING = ["flowmeter_gain", "laminar_leakage", "discharge_scale"]


def _with(model, name):
    effect = LIBRARY[name]()
    for parameter in effect.params.values():
        parameter.value = parameter.value + 0.05 * (parameter.max - parameter.min)
    return model.with_effects([*model.effects, effect])


@pytest.fixture(scope="module")
def gp_model():
    return presets.cfda(maps_spec=presets.maps("gp")).build()


@pytest.mark.parametrize("name", FLOW_CHANGING)
def test_effects_that_change_the_flow_read_smooth_maps_expansions(setting, gp_model, name):
    """A flowmeter's gain moves the flow the maps are asked about, a leak or a discharge
    correction the flow through the restriction (one of each hook); on smooth maps the tables'
    expansions about the measured flow answer as the maps do."""
    log, _, _ = setting
    # two runs: a GP map asked over a whole replay is the test's cost
    log = log.take(np.flatnonzero(log.frame["run"].isin(log.frame["run"].unique()[:2])
                                  .to_numpy()))
    changed = _with(gp_model, name)
    start = replay_log(changed, log, diagnostics=False)
    tabulated = replay_log(changed, log, guess=start, diagnostics=False)
    asked = replay_log(changed, log, guess=start, diagnostics=True)
    assert tabulated.replay.tables is not None and asked.replay.tables is None
    both = np.isfinite(tabulated.replay.dp) & np.isfinite(asked.replay.dp)
    assert both.mean() > 0.9
    difference = np.abs(tabulated.replay.dp[both] - asked.replay.dp[both])
    # a sample can still flip between sticking and sliding on a hair's difference; the
    # expansions, made at every fourth node and linear between, are good to tens of pascals
    # (a wrong one is off by the whole change of the flow: kilopascals)
    assert np.mean(difference > 1e-2 * BAR) < 0.02, name
    assert np.median(difference) < 5e-4 * BAR, name


@pytest.mark.parametrize("name", FLOW_CHANGING)
def test_effects_that_change_the_flow_ask_a_grid_map(setting, name):
    """A grid's sweeps have kinks in the flow and Δp that no polynomial follows."""
    log, model, log_replay = setting
    again = replay_log(_with(model, name), log, guess=log_replay, diagnostics=False)
    assert again.replay.tables is None


def _looped_play(u_open, u_close, status_open, status_close, starts, u_start, smoothing):
    """The play as the loop it was: a reference for the prefix scan."""
    count = len(u_open)
    u = np.empty(count)
    moving = np.zeros(count, dtype=bool)
    source = np.full((2, count), -1, dtype=np.int64)
    status, low, high, state_low, state_high, high_kind = play_bounds(
        u_open, u_close, status_open, status_close, starts, smoothing)
    solved = status >= 0
    previous, state_from = u_start, (FROM_START, -1)
    for k in range(count):
        if starts[k]:
            previous, state_from = u_start, (FROM_START, -1)
        if solved[k]:
            state = min(max(previous, state_low[k]), state_high[k])
            if state != previous:
                moving[k] = True
                opened = state > previous
                u[k] = low[k] if opened else high[k]
                source[:, k] = (OWN_LOW if opened else OWN_HIGH), k
                state_from = (STATE_LOW if opened else high_kind[k], k)
            else:
                u[k] = state
                source[:, k] = state_from
            previous = state
        else:
            u[k] = previous
            source[:, k] = state_from
    return u, moving, status, source


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31), count=st.integers(1, 300),
       smoothing=st.sampled_from([1, 5, 7]), u_start=st.sampled_from([0.0, 1.0]))
def test_the_plays_prefix_scan_is_the_loop_to_the_bit(seed, count, smoothing, u_start):
    rng = np.random.default_rng(seed)
    centre = 1.0 + 0.01 * np.cumsum(rng.normal(size=count))
    half = np.abs(rng.normal(0.0, 0.05, count))
    u_open, u_close = centre - half, centre + half
    swap = rng.random(count) < 0.1  # where an effect turns the band over
    u_open, u_close = np.where(swap, u_close, u_open), np.where(swap, u_open, u_close)
    status_open = np.where(rng.random(count) < 0.05, -2, 0)
    status_close = np.where(rng.random(count) < 0.05, -3, 0)
    u_open[status_open < 0], u_close[status_close < 0] = np.nan, np.nan
    starts = rng.random(count) < 0.03
    starts[0] = True
    expected = _looped_play(u_open, u_close, status_open, status_close, starts, u_start,
                            smoothing)
    found = play(u_open, u_close, status_open, status_close, starts, u_start, smoothing)
    for wanted, got in zip(expected, found):
        np.testing.assert_array_equal(got, wanted)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31), close=st.integers(0, 4))
def test_the_bucket_locator_finds_the_segment_a_binary_search_finds(seed, close):
    """Uniform nodes with kinks among them, some closer to each other than a bucket is wide."""
    rng = np.random.default_rng(seed)
    kinks = rng.uniform(-10.0, -5.0, 6)
    kinks = np.concatenate([kinks, kinks[0] + 1e-4 * np.arange(1, close + 1)])
    nodes = np.unique(np.concatenate([np.arange(-20.0, 1.0, 0.01), kinks]))
    locate = _Locator(nodes, 0.00125)
    x = np.concatenate([rng.uniform(-21.0, 2.0, 2000), nodes, np.nextafter(nodes, np.inf),
                        np.nextafter(nodes, -np.inf)])
    np.testing.assert_array_equal(locate(x), np.searchsorted(nodes, x, "right") - 1)


def test_a_full_store_keeps_each_samples_latest_row(setting, monkeypatch):
    """Renewed rows leave old ones behind; a store that would outgrow its bound keeps only the
    latest row of each sample (its older views then find none, and the maps answer)."""
    log, model, log_replay = setting
    points = OperatingPoints.from_bench(log.frame)
    tables = MapTables(model)
    tables.tabulate(model, points, log_replay.replay.band)
    monkeypatch.setattr("surrogate.solver.map_tables.MAX_NODES", int(1.5 * tables.size))
    before = tables.view(points)
    moved = log_replay.replay.band * 1.3
    tables.tabulate(model, points, moved)
    assert tables.generation == 1 and tables.size < 1.5 * len(before.row) * 60
    assert not before.lookup(log_replay.replay.band[0])[2].any()
    view = tables.view(points)
    held = np.flatnonzero(view.row >= 0)
    u = moved[0, held]
    dp, _, inside = view[held].lookup(u)
    assert inside.all()
    dp_maps, _ = model.map_part(u, points[held], model.fluid(points[held]))
    np.testing.assert_allclose(dp, dp_maps, rtol=1e-9)
