"""Least-squares fitting of a valve model's free parameters, in the manner of lmfit.

Any residual works: a model's pressure drop against a median line, or a replay against every
sample of a bench log. The fit varies the free parameters of the model's effects within their
bounds (:class:`scipy.optimize.least_squares`, trust-region reflective) and reports the values with
standard errors, their correlations, χ², AIC and BIC.

Standard errors assume independent residuals. Bench samples are correlated in time, so they are
optimistic; compare models by BIC or by held-out error, not by these alone.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares

from .effects import Effect, Parameter
from .errors import InputError
from .model import ValveModel
from .parallel import map_threads
from .units import from_si, to_si

#: residual of a solver failure, so that a fit is steered away from it [Pa]
FAILURE_RESIDUAL = 1000e5
#: finite-difference step of the Jacobian, relative to max(1, |parameter in display units|)
DIFF_STEP = 1e-4


@dataclass
class FitResult:
    """The outcome of :func:`fit`.

    Attributes
    ----------
    model : ValveModel
        A copy of the model with the fitted values (and their standard errors) set.
    names : list of str
        ``"effect.parameter"`` for each fitted parameter.
    rms : float
        Root-mean-square residual at the optimum [residual units, Pa for pressures].
    count : int
        Number of residuals.
    aic, bic : float
        Akaike and Bayesian information criteria, n·ln(RSS/n) + 2k and n·ln(RSS/n) + k·ln n.
    correlation : numpy.ndarray
        Correlation matrix of the fitted parameters.
    success : bool
    message : str
    evaluations : int
    """

    model: ValveModel
    names: list[str]
    rms: float
    count: int
    aic: float
    bic: float
    correlation: np.ndarray
    success: bool
    message: str
    evaluations: int
    parameters: list[Parameter] = field(default_factory=list)

    def report(self) -> str:
        """A readable summary, like lmfit's ``fit_report``."""
        lines = [f"fit of {self.model.name}: {len(self.names)} parameter(s), {self.count} residuals,"
                 f" {self.evaluations} evaluations, {'converged' if self.success else 'NOT converged'}",
                 f"  rms {from_si(self.rms, 'bar'):.4g} bar, AIC {self.aic:.1f}, BIC {self.bic:.1f}"]
        lines += [f"  {name:<32} {parameter}" for name, parameter in
                  zip(self.names, self.parameters)]
        for i in range(len(self.names)):
            for j in range(i + 1, len(self.names)):
                if abs(self.correlation[i, j]) > 0.5:
                    lines.append(f"  correlation({self.names[i]}, {self.names[j]}) = "
                                 f"{self.correlation[i, j]:+.3f}")
        return "\n".join(lines)


def information_criteria(residuals: np.ndarray, parameter_count: int) -> tuple[float, float]:
    """(AIC, BIC) of a least-squares fit with Gaussian errors of unknown variance."""
    count = len(residuals)
    rss = max(float(np.sum(residuals**2)), 1e-300)
    base = count * np.log(rss / count)
    return base + 2 * parameter_count, base + parameter_count * np.log(count)


def free_parameters(model: ValveModel, names: Sequence[str] | None = None
                    ) -> list[tuple[str, Effect, Parameter]]:
    """The parameters a fit varies: ``names`` (``"effect.parameter"``) or all with vary=True."""
    available = {f"{effect.name}.{p.name}": (effect, p) for effect, p in model.parameters()}
    if names is None:
        return [(name, e, p) for name, (e, p) in available.items() if p.vary]
    missing = [name for name in names if name not in available]
    if missing:
        raise InputError(f"model {model.name!r} has no parameter(s) {', '.join(missing)}; it has "
                         f"{', '.join(available) or 'none'}")
    return [(name, *available[name]) for name in names]


def fit(model: ValveModel, residuals: Callable[[ValveModel], np.ndarray],
        names: Sequence[str] | None = None, *, max_evaluations: int = 200,
        tolerance: float = 1e-8,
        scoped: Callable[[ValveModel, str], tuple[np.ndarray, np.ndarray]] | None = None
        ) -> FitResult:
    """Fit the free parameters of ``model`` to minimise the sum of squared ``residuals``.

    Parameters
    ----------
    model : ValveModel
        Not modified; the result holds a fitted copy.
    residuals : callable
        ``residuals(model)`` returns an array of residuals; NaN entries (failed points) count as
        :data:`FAILURE_RESIDUAL`. The Jacobian's columns are evaluated on threads
        (:mod:`.parallel`), each with its own copy of the model, so ``residuals`` must not change
        state that other calls read.
    names : sequence of str, optional
        ``"effect.parameter"`` names to fit; default every parameter with ``vary=True``.
    max_evaluations : int
        Limit on residual evaluations (not counting those for the Jacobian).
    tolerance : float
        Relative change in the sum of squares, and in the parameters, below which the fit stops.
    scoped : callable, optional
        ``scoped(model, scope)`` returns ``(rows, values)``: the positions of the residuals a
        parameter with that ``scope`` (a run) can change, and their values for ``model``. The
        Jacobian's column of such a parameter then costs only those residuals; without it, every
        column evaluates them all.
    """
    fitted = model.copy()
    chosen = free_parameters(fitted, names)

    def evaluate(candidate: ValveModel) -> np.ndarray:
        values = np.asarray(residuals(candidate), float)
        return np.where(np.isfinite(values), values, FAILURE_RESIDUAL)

    if not chosen:
        values = evaluate(fitted)
        aic, bic = information_criteria(values, 0)
        return FitResult(fitted, [], _rms(values), len(values), aic, bic, np.zeros((0, 0)), True,
                         "nothing to fit", 1, [])

    # optimise in display units, where the parameters are of order one
    units = [p.unit for _, _, p in chosen]
    start = np.array([p.display_value for _, _, p in chosen])
    lower = np.array([from_si(p.min, p.unit) if np.isfinite(p.min) else -np.inf
                      for _, _, p in chosen])
    upper = np.array([from_si(p.max, p.unit) if np.isfinite(p.max) else np.inf
                      for _, _, p in chosen])
    start = np.clip(start, lower, upper)

    names = [name for name, _, _ in chosen]
    parameters = [p for _, _, p in chosen]

    def assign(parameters: list[Parameter], x):
        for parameter, unit, value in zip(parameters, units, x):
            parameter.value = float(to_si(value, unit))

    last: dict = {"x": None, "values": None}

    def objective(x):
        assign(parameters, x)
        values = evaluate(fitted)
        if len(values) <= len(chosen):
            # as many unknowns as equations: the fit would pass through every point and report
            # standard errors computed from nothing
            raise InputError(f"fitting {len(chosen)} free parameter(s) of {model.name!r} needs "
                             f"more than {len(chosen)} samples; there are {len(values)}")
        last["x"], last["values"] = np.array(x), values
        return values

    def jacobian(x):
        """Forward differences, as scipy's '2-point', with the columns evaluated side by side."""
        at_x = last["values"] if np.array_equal(last["x"], x) else objective(x)
        steps = _forward_steps(np.asarray(x, float), upper)

        def column(j: int) -> np.ndarray:
            trial = fitted.copy()
            shifted = np.array(x, float)
            shifted[j] += steps[j]
            assign([p for _, _, p in free_parameters(trial, names)], shifted)
            scope = parameters[j].scope
            if scope is None or scoped is None:
                return (evaluate(trial) - at_x) / steps[j]
            rows, values = scoped(trial, scope)
            values = np.where(np.isfinite(values), values, FAILURE_RESIDUAL)
            change = np.zeros_like(at_x)
            change[rows] = (values - at_x[rows]) / steps[j]
            return change

        return np.column_stack(list(map_threads(column, range(len(x)))))

    result = least_squares(objective, start, jac=jacobian, bounds=(lower, upper),
                           x_scale="jac", max_nfev=max_evaluations, ftol=tolerance,
                           xtol=tolerance)
    assign(parameters, result.x)
    # the optimum is usually the point least_squares evaluated last: reuse its residuals then
    final = last["values"] if np.array_equal(last["x"], result.x) else evaluate(fitted)
    covariance = _covariance(result.jac, final, len(chosen))
    scales = np.array([to_si(1.0, unit) - to_si(0.0, unit) for unit in units])
    errors = np.sqrt(np.clip(np.diag(covariance), 0, None))
    for (_, _, parameter), error, scale in zip(chosen, errors, scales):
        # on a bound the curvature says nothing about the uncertainty: report none
        usable = np.isfinite(error) and not parameter.at_bound
        parameter.stderr = float(error * scale) if usable else None
    with np.errstate(invalid="ignore", divide="ignore"):
        correlation = covariance / np.outer(errors, errors)
    aic, bic = information_criteria(final, len(chosen))
    return FitResult(fitted, names, _rms(final), len(final), aic, bic,
                     correlation, bool(result.success), str(result.message), int(result.nfev),
                     parameters)


def _forward_steps(x: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """Finite-difference steps: :data:`DIFF_STEP` relative to max(1, |x|), away from the upper
    bound when a step up would cross it (scipy's rule for '2-point' with bounds)."""
    steps = DIFF_STEP * np.where(x >= 0, 1.0, -1.0) * np.maximum(1.0, np.abs(x))
    steps = np.where(x + steps > upper, -np.abs(steps), steps)
    return (x + steps) - x  # exactly representable differences


def _rms(values: np.ndarray) -> float:
    return float(np.sqrt(np.mean(values**2))) if len(values) else 0.0


def _covariance(jacobian: np.ndarray, residuals: np.ndarray, parameter_count: int) -> np.ndarray:
    dof = max(len(residuals) - parameter_count, 1)
    variance = float(np.sum(residuals**2)) / dof
    try:
        return np.linalg.pinv(jacobian.T @ jacobian) * variance
    except np.linalg.LinAlgError:
        return np.full((parameter_count, parameter_count), np.nan)
