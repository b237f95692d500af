"""Held-out refits (surrogate/fitting/heldout.py): the schemes, the linearised refits against
explicit ones, and the judgement against the maps' discrepancy refitted with the parameters (what
a candidate must do on runs it was not fitted to is the rule's: tests/diagnosis/test_rule.py)."""

from __future__ import annotations

import numpy as np
import pytest

from surrogate.fitting.discrepancy import Discrepancy
from surrogate.fitting.heldout import (HEADLINE, Linearised, RunBlocks, bootstrap_weights,
                                       held_at_bounds, run_groups)
from surrogate.parameters import Parameter


def test_the_shipped_logs_schemes(bench_log):
    schemes = run_groups(bench_log)
    assert len(schemes["run"]) == 12
    assert sorted(schemes["temperature"]) == ["20 °C", "40 °C", "60 °C"]
    assert sorted(schemes["pilot pressure"], key=lambda g: float(g.split()[0])) == [
        "50 bar", "65 bar", "80 bar", "120 bar"]
    assert all(len(runs) == 4 for runs in schemes["temperature"].values())


def _at_optimum(raw: np.ndarray, jacobian: np.ndarray) -> Linearised:
    """The residual r + J·θ at the least-squares optimum θ, as a fit hands it over."""
    theta = np.linalg.lstsq(jacobian, -raw, rcond=None)[0]
    return Linearised(raw + jacobian @ theta, jacobian)


def _linear_problem(seed=0, runs=6, per_run=40, parameters=2):
    """Run labels, the raw residual (at θ = 0) and the Jacobian of a linear problem whose runs
    differ by a run-to-run offset."""
    rng = np.random.default_rng(seed)
    labels = np.repeat([f"R{i}" for i in range(runs)], per_run)
    jacobian = rng.standard_normal((len(labels), parameters))
    raw = (jacobian @ rng.standard_normal(parameters) + 0.3 * rng.standard_normal(len(labels))
           + np.repeat(0.5 * rng.standard_normal(runs), per_run))
    return labels, raw, jacobian


def test_a_held_out_run_is_predicted_as_an_explicit_refit_without_it_would():
    """For a linear problem the linearised refit is exact: fit θ without run g by least squares
    on r + J·θ, predict run g, and the RMS over all runs left out in turn must agree."""
    labels, raw, jacobian = _linear_problem()
    schemes = {"run": {run: [run] for run in dict.fromkeys(labels)}}
    got = RunBlocks(_at_optimum(raw, jacobian), None, labels, 0.0).heldout_rms(schemes)["run"]
    squares = 0.0
    for run in dict.fromkeys(labels):
        train = labels != run
        theta = np.linalg.lstsq(jacobian[train], -raw[train], rcond=None)[0]
        held = raw[~train] + jacobian[~train] @ theta
        squares += float(held @ held)
    assert got == pytest.approx(np.sqrt(squares / len(labels)), rel=1e-9)


@pytest.mark.parametrize("rough", [False, True])
def test_blocks_moved_to_a_point_are_the_blocks_formed_there(rough):
    """RunBlocks.moved forms the blocks about another point from the products it has: they must
    be what forming them about the moved linearisation gives (refits, objective, held-out)."""
    labels, raw, jacobian = _linear_problem(seed=3, parameters=3)
    roughness = (np.array([[1.0, -2.0, 1.0]]), np.array([0.4])) if rough else None
    fit = Linearised(raw, jacobian, roughness)
    theta = np.array([0.3, -1.2, 0.7])
    schemes = {"run": {run: [run] for run in dict.fromkeys(labels)}}
    moved = RunBlocks(fit, None, labels, 0.0).moved(theta)
    formed = RunBlocks(fit.moved(theta), None, labels, 0.0)
    ones = np.ones(len(formed.labels))
    assert moved.step(ones) == pytest.approx(formed.step(ones), rel=1e-10, abs=1e-12)
    assert moved.objective(ones) == pytest.approx(formed.objective(ones), rel=1e-10)
    assert moved.heldout_rms(schemes) == pytest.approx(formed.heldout_rms(schemes), rel=1e-10)


def test_the_discrepancy_is_refitted_with_the_parameters_so_undoing_a_bend_gains_nothing():
    """A model fitted without the discrepancy bends its parameters to absorb map error. Against
    the discrepancy refitted together with those parameters, a candidate that only undoes the
    bend (its column lies in the span of the parameters' and the discrepancy's) gains nothing;
    a candidate with a shape of its own still does."""
    rng = np.random.default_rng(4)
    labels = np.repeat([f"R{i}" for i in range(4)], 50)
    n = len(labels)
    x = np.linspace(0.0, 1.0, n)
    nuisance = np.column_stack([np.sin(np.pi * k * x) for k in (1, 2, 3)])
    own_column = (x + 0.3 * rng.standard_normal(n))[:, None]  # a parameter that can bend toward N
    step = (x > 0.5).astype(float)  # an effect of a shape the discrepancy does not have
    observed = (nuisance @ np.array([2.0, -1.0, 0.5]) + 0.3 * step
                + 0.05 * rng.standard_normal(n))
    discrepancy = Discrepancy(nuisance, ["a", "b", "c"])
    penalty = 1e-3

    def objective(columns: np.ndarray) -> float:
        fit = _at_optimum(-observed, columns)  # fitted without the discrepancy
        return RunBlocks(fit, discrepancy, labels, penalty).objective(np.ones(4))

    before = objective(own_column)
    undoing = own_column + nuisance @ np.array([0.7, 0.2, -0.4])[:, None]
    # fitted after the parameters instead, the discrepancy would leave the bend, and undoing
    # it would lower this sum of squares by a fifth
    assert objective(np.column_stack([own_column, undoing])) == pytest.approx(before, rel=0.01)
    shaped = step[:, None] + 0.02 * rng.standard_normal((n, 1))
    assert objective(np.column_stack([own_column, shaped])) < 0.5 * before


def test_a_parameter_on_its_bound_is_held_there_in_the_linear_refits():
    """The linear refits know no bounds: a parameter a fit left on its bound (a friction of
    zero) would turn negative in them, so its column is zeroed; the others are kept."""
    pinned = Parameter("K_nu", 0.0, min=0.0, max=50.0)
    free = Parameter("K1", 3.0, min=0.0, max=50.0)
    top = Parameter("beta", 3.0, min=-0.9, max=3.0)
    jacobian = np.arange(1.0, 13.0).reshape(4, 3)
    held = held_at_bounds(jacobian, [pinned, free, top])
    assert np.all(held[:, [0, 2]] == 0.0)
    assert np.array_equal(held[:, 1], jacobian[:, 1])
    assert held_at_bounds(jacobian, [free, free, free]) is jacobian


def test_a_held_parameter_is_held_in_the_penalty_too_and_its_value_stays_in_its_residual():
    """A shape's coefficient on its bound: its Jacobian column and its penalty column are zeroed,
    the penalty's residual (which its value is part of) kept."""
    pinned, free = Parameter("c_1", 0.0, min=0.0, max=5.0), Parameter("c_2", 2.0, min=0.0, max=5.0)
    rough = (np.array([[1.0, -1.0]]), np.array([-2.0]))
    fit = Linearised(np.ones(4), np.arange(1.0, 9.0).reshape(4, 2), rough).held([pinned, free])
    assert np.all(fit.jacobian[:, 0] == 0) and np.all(fit.roughness[0][:, 0] == 0)
    assert np.array_equal(fit.roughness[0][:, 1], [-1.0])
    assert np.array_equal(fit.roughness[1], [-2.0])


def test_each_group_left_out_has_the_refit_that_its_held_out_rms_is_made_of():
    """RunBlocks.shifts are the steps heldout_rms judges by; a group that would leave nothing to
    fit has none."""
    rng = np.random.default_rng(4)
    runs = np.repeat(["R1", "R2", "R3"], 30)
    jacobian = rng.normal(size=(90, 2))
    residual = jacobian @ [0.3, -0.2] + rng.normal(0.0, 0.1, 90)
    blocks = RunBlocks(Linearised(residual, jacobian), None, runs, 0.0)
    groups = {"R1": ["R1"], "R2": ["R2"], "all": ["R1", "R2", "R3"]}
    shifts = blocks.shifts(groups)
    assert set(shifts) == {"R1", "R2"}
    held, shift = shifts["R1"]
    keep = runs != "R1"
    explicit = np.linalg.lstsq(jacobian[keep], -residual[keep], rcond=None)[0]
    whole = np.linalg.lstsq(jacobian, -residual, rcond=None)[0]
    assert held == [0] and np.allclose(shift, explicit - whole, atol=1e-6)


def test_run_blocks_sum_and_index_the_runs_as_before():
    """The runs' weighted sums are tensordot's own product, and blocks made from an index of
    the runs (as a diagnosis makes them once) are those made from the labels, to the bit."""
    from surrogate.fitting.heldout import RunIndex, weighted_sum

    rng = np.random.default_rng(7)
    for shape in [(12, 9, 9), (12, 9), (5, 3, 4)]:
        blocks = rng.normal(size=shape)
        weights = rng.integers(0, 4, shape[0]).astype(float)
        for part in (blocks, blocks[:, :2]):
            np.testing.assert_array_equal(weighted_sum(weights, part),
                                          np.tensordot(weights, part, axes=1))
    runs = np.repeat(np.array([f"R{i:02d}" for i in range(6)], dtype=object), 40)
    jacobian = rng.normal(size=(len(runs), 3))
    fit = _at_optimum(rng.normal(size=len(runs)), jacobian)
    discrepancy = Discrepancy(rng.normal(size=(len(runs), 4)), ["a", "b", "c", "d"])
    for nuisance in (None, discrepancy):
        by_labels = RunBlocks(fit, nuisance, runs, 2.0)
        by_index = RunBlocks(fit, nuisance, RunIndex.of(runs), 2.0)
        for name in ("gram", "cross", "squares", "counts", "penalty", "ridge"):
            np.testing.assert_array_equal(getattr(by_labels, name), getattr(by_index, name))
        ones = np.ones(len(by_index.labels))
        assert by_labels.objective(ones) == by_index.objective(ones)
        # each run's blocks as [J, N] over the whole log gave them
        stacked = jacobian if nuisance is None else np.column_stack([jacobian,
                                                                     nuisance.columns])
        for k, label in enumerate(by_index.labels):
            rows = runs == label
            np.testing.assert_array_equal(by_index.gram[k, :3], jacobian[rows].T
                                          @ stacked[rows])
            np.testing.assert_array_equal(by_index.cross[k], stacked[rows].T
                                          @ fit.residual[rows])


def test_bootstrap_resamples_draw_every_run_alike_and_the_same_every_time():
    """The diagnosis' bootstrap over runs (its last test, the majority of resamples): each
    resample is as many runs as the log has, drawn with replacement, the same for the same seed,
    and no run favoured."""
    weights = bootstrap_weights(12, 4000, seed=0)
    assert weights.shape == (4000, 12)
    assert np.all(weights.sum(axis=1) == 12) and np.all(weights >= 0)
    assert np.array_equal(weights, bootstrap_weights(12, 4000, seed=0))
    assert not np.array_equal(weights, bootstrap_weights(12, 4000, seed=1))
    # each run is drawn once per resample on average; left out in about (11/12)^12 of them
    assert weights.mean(axis=0) == pytest.approx(np.ones(12), abs=0.05)
    assert np.mean(weights == 0) == pytest.approx((11 / 12) ** 12, abs=0.02)
