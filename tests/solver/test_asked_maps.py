"""What the maps are asked replay after replay: a grid's reading at each sample's flow
(GridFlowMap.at_flows) and a solver's balance that blends it (surrogate.solver.asked_maps) give
the maps' own values, to the bit."""

from __future__ import annotations

import numpy as np
import pytest

from surrogate.effects import LIBRARY
from surrogate.fluid import FluidState
from surrogate.description.modelfile import load_model
from surrogate.points import OperatingPoints
from surrogate.solver import asked_maps
from surrogate.solver.asked_maps import AskedBalance, asked_balance, kept_flows


@pytest.fixture(scope="module")
def setting(cfda_on_runs):
    return cfda_on_runs(4)


def same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    return np.array_equal(a, b, equal_nan=True) and np.array_equal(np.signbit(a), np.signbit(b))


def test_a_grids_reading_at_the_flows_blends_to_its_pressure_drop_to_the_bit():
    """Flows at, between and beyond the sweeps' (none and NaN too), openings on, between and
    beyond the sampled ones (closed and NaN too), viscosities on and beyond the fluid levels,
    points asked more than once."""
    grid = load_model("cfda").flow_map
    rng = np.random.default_rng(7)
    count = 3000
    levels = np.array([level.nu for level in grid.levels])
    nu = np.exp(rng.uniform(np.log(levels[0]) - 0.3, np.log(levels[-1]) + 0.3, count))
    nu[:30] = levels[rng.integers(0, len(levels), 30)]
    fluid = FluidState(nu, np.full(count, 870.0))
    q = np.exp(rng.uniform(np.log(1e-7), np.log(5e-3), count))
    q[:5], q[5:8] = 0.0, np.nan
    reading = grid.at_flows(q, np.zeros(count), fluid)
    for trial in range(6):
        repeated = trial % 2 == 0
        index = rng.choice(count, rng.integers(1, 2 * count if repeated else count),
                           replace=repeated)
        u = np.exp(rng.uniform(np.log(1e-7), np.log(5e-3), len(index)))
        u[:4], u[4:6] = 0.0, np.nan
        u[6:40] = np.exp(grid._shared_log_u[rng.integers(0, len(grid._shared_log_u), 34)])
        assert same_bits(reading(u, index),
                         grid.pressure_drop(q[index], np.zeros(len(index)), u, fluid[index]))


@pytest.mark.parametrize("name", ["pilot_transducer_offset", "discharge_scale",
                                  "flowmeter_gain"])
def test_a_solvers_balance_with_the_kept_reading_is_the_maps_own(setting, name):
    """A model whose flow is the measured one (a pilot transducer's offset) reads the kept
    sweeps; one that changes the flow (a discharge correction, a flowmeter's gain) asks the
    grid: both give the balance the maps give."""
    log, model, log_replay = setting
    trial = model.copy()
    trial.effects.append(LIBRARY[name].for_runs(log.run_ids))
    for parameter in trial.effect(name).params.values():
        if parameter.vary:
            parameter.value = parameter.min + 0.3 * (parameter.max - parameter.min)
    points = OperatingPoints.from_bench(log.frame)
    flowing = np.flatnonzero(points.q > 0)
    points = points[flowing]
    fluid = trial.fluid(points)
    balance = asked_balance(trial, points, fluid, keep=True)
    assert isinstance(balance, AskedBalance)
    rng = np.random.default_rng(5)
    u = log_replay.replay.u[flowing]
    for _ in range(3):
        index = np.sort(rng.choice(len(points), len(points) // 2, replace=False))
        at = np.where(np.isfinite(u[index]), u[index], 1e-4) * rng.uniform(0.9, 1.1, len(index))
        kept, asked = balance(at, index), trial.balance(at, points[index], fluid[index])
        for field in ("dp", "net_force", "friction"):
            assert same_bits(getattr(kept, field), getattr(asked, field))


def test_a_model_with_a_leak_or_a_single_balance_asks_the_maps_as_ever(setting):
    log, model, _ = setting
    points = OperatingPoints.from_bench(log.frame)
    leaky = model.copy()
    leaky.effects.append(LIBRARY["laminar_leakage"]())
    assert not isinstance(asked_balance(leaky, points, leaky.fluid(points), keep=True),
                          AskedBalance)
    assert not isinstance(asked_balance(model, points, model.fluid(points)), AskedBalance)


def test_the_reading_is_made_once_per_set_of_points_and_the_oldest_let_go(setting, monkeypatch):
    log, model, _ = setting
    points = OperatingPoints.from_bench(log.frame)
    fluid = model.fluid(points)
    first = kept_flows(model.flow_map, points, fluid)
    assert kept_flows(model.flow_map, points, fluid) is first
    monkeypatch.setattr(asked_maps, "KEPT_POINTS", len(points) + 10)
    half = points[np.arange(20)]
    kept_flows(model.flow_map, half, model.fluid(half))  # the first set is let go
    assert kept_flows(model.flow_map, points, fluid) is not first
