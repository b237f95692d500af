"""The package's one minimiser (surrogate/fitting/leastsquares.py) on problems with known answers: a
linear fit against the normal equations, a bound that binds, the Gauss–Newton refinement with
Broyden updates against the trust-region fit, and a penalty minimised with the sum of squares."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import lsq_linear

from surrogate.effects import Effect, Parameter
from surrogate.fitting.leastsquares import (FunctionProblem, Minimizer, bounded_linear_fit,
                                            compress, covariance, fit)
from surrogate.model import ValveModel

X = np.linspace(0.0, 1.0, 40)


class Line(Effect):
    """Two plain parameters, a·x + b, for problems whose answer is known."""

    name, kind, category, title = "line", "force", "physics", "a line"
    parameter_specs = (Parameter("a", 0.0, "1", min=-10.0, max=10.0),
                       Parameter("b", 0.0, "1", min=-10.0, max=10.0))


@pytest.fixture
def line_model(valve, grid_maps):
    return ValveModel(valve, *grid_maps, [Line()])


def _residuals(y):
    def residuals(model):
        line = model.effect("line")
        return line["a"] * X + line["b"] - y
    return residuals


def test_a_linear_fit_is_the_least_squares_solution_with_its_standard_errors(line_model):
    rng = np.random.default_rng(0)
    y = 2.0 * X - 0.5 + rng.normal(0.0, 0.05, X.size)
    result = fit(line_model, _residuals(y))
    design = np.column_stack([X, np.ones_like(X)])
    solution, rss, *_ = np.linalg.lstsq(design, y, rcond=None)
    fitted = [p.value for p in result.parameters]
    assert np.allclose(fitted, solution, atol=1e-6)
    errors = np.sqrt(np.diag(rss[0] / (X.size - 2) * np.linalg.inv(design.T @ design)))
    assert np.allclose([p.stderr for p in result.parameters], errors, rtol=1e-3)
    assert result.rms == pytest.approx(np.sqrt(rss[0] / X.size), rel=1e-6)


def test_a_bound_that_binds_holds_the_parameter_and_reports_no_standard_error(line_model):
    line_model.effect("line").params["b"].min = 0.0
    y = 1.0 * X - 2.0  # the free optimum has b = -2
    result = fit(line_model, _residuals(y))
    b = result.model.effect("line").params["b"]
    assert b.value == pytest.approx(0.0, abs=1e-9) and b.at_bound and b.stderr is None


def test_the_refinement_polishes_to_the_trust_region_fits_optimum(line_model):
    """Gauss–Newton with Broyden updates from a forward-difference linearisation near the
    optimum (where a diagnosis starts it), each step one evaluation, on a problem nonlinear in
    its parameters; a step that gains nothing ends it."""
    y = np.exp(1.3 * X) - 0.4

    def residuals(model):
        line = model.effect("line")
        return np.exp(line["a"] * X) + line["b"] - y

    line_model.effect("line").params["a"].value = 1.15
    line_model.effect("line").params["b"].value = -0.3
    problem = FunctionProblem(residuals)
    minimizer = Minimizer(line_model, problem)
    start = problem.evaluate(minimizer.model)
    step = 0.05  # a forward difference: its curvature error is what the updates correct
    changes = [np.exp((1.15 + step) * X) - np.exp(1.15 * X), np.full(X.size, step)]
    minimizer.linearise(changes, [step, step], start).refine(10)
    _, rss = minimizer.refined
    reference = fit(line_model, residuals)
    assert rss < 1e-6 * float(np.sum(start.residual ** 2))
    assert [p.value for p in minimizer.parameters] == pytest.approx(
        [p.value for p in reference.parameters], abs=1e-3)


def test_a_penalty_in_the_covariance_narrows_what_the_data_leave_free():
    """σ²·(JᵀJ + LᵀL)⁺: a parameter the data do not feel is as uncertain as its penalty lets
    it be, no more."""
    jacobian = np.column_stack([X, np.zeros_like(X)])
    residuals = np.full(X.size, 0.1)
    free = covariance(jacobian, residuals)
    penalised = covariance(jacobian, residuals, penalty=np.array([[0.0, 10.0]]))
    assert free[1, 1] == 0.0  # pinv: the unfelt direction is dropped, not infinite
    variance = float(residuals @ residuals) / (X.size - 2)
    assert penalised[1, 1] == pytest.approx(variance / 100.0)
    assert penalised[0, 0] == pytest.approx(free[0, 0])


@pytest.mark.parametrize("seed", range(3))
def test_a_bounded_linear_fit_on_the_triangular_factor_is_the_tall_fit(seed):
    """bounded_linear_fit solves a tall problem (samples by a few columns, a penalty's rows
    beside) on its QR factor: the same minimiser as lsq_linear on all the rows, bounds active
    or not."""
    rng = np.random.default_rng(seed)
    tall, target = rng.standard_normal((3000, 5)), rng.standard_normal(3000)
    rows, row_target = 0.3 * rng.standard_normal((2, 5)), rng.standard_normal(2)
    unbounded = lsq_linear(np.vstack([tall, rows]), np.r_[target, row_target]).x
    bounds = (np.full(5, -np.inf), np.r_[np.inf, np.inf, 0.5 * unbounded[2], np.inf, np.inf])
    expected = lsq_linear(np.vstack([tall, rows]), np.r_[target, row_target], bounds=bounds,
                          tol=1e-12).x
    got = bounded_linear_fit(tall, target, bounds, rows, row_target)
    assert got[2] == pytest.approx(bounds[1][2]) or unbounded[2] < 0
    np.testing.assert_allclose(got, expected, atol=1e-8)
    np.testing.assert_allclose(
        bounded_linear_fit(tall, target, bounds, rows, row_target, compress(tall, target)), got)
