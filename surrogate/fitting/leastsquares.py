"""Least-squares fitting of a model's parameters: the package's one minimiser, in the manner of
lmfit.

A :class:`FitProblem` says what to minimise: it owns the residual, the Jacobian's columns and
whatever warm starts make them cheap, as lmfit's user function and ``Dfun`` do. A
:class:`Minimizer` varies the free parameters of a copy of a model within their bounds:

* :meth:`Minimizer.least_squares`: trust-region reflective least squares
  (:func:`scipy.optimize.least_squares`), the Jacobian by forward differences whose columns are
  evaluated side by side on threads;
* :meth:`Minimizer.linearise` and :meth:`Minimizer.refine`: bounded Gauss–Newton from a given
  Jacobian, each step one real evaluation with Broyden's update of the Jacobian instead of a new
  one, resumable (the diagnosis refits many candidates a step at a time this way).

Standard errors come from one :func:`covariance`, widened for residuals that are correlated (in
time, for bench logs) by the problem's effective number of independent samples. Every fit of the
package (a model to a bench log, the diagnosis' candidates, the paper's models) goes through here.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.optimize import least_squares, lsq_linear

from ..core.errors import InputError
from ..model import ValveModel
from ..core.parallel import map_threads
from ..parameters import Parameter
from ..core.units import from_si, to_si

#: residual of a solver failure, so that a fit is steered away from it [Pa]
FAILURE_RESIDUAL = 1000e5
#: finite-difference step of the Jacobian, relative to max(1, |parameter in display units|)
DIFF_STEP = 1e-4
#: a refinement step that lowers the RSS by less than this share of it ends the refinement: the
#: RMS is then settled to 5e-5 of itself
SETTLED_GAIN = 1e-4


@dataclass(frozen=True)
class Evaluation:
    """The residuals at one set of parameters, and what the problem made them from (a replay of
    a bench log, say), for the caller."""

    residual: np.ndarray
    payload: object = None

    def finite(self) -> "Evaluation":
        """The same with its residuals made finite (:func:`_finite`)."""
        return replace(self, residual=_finite(self.residual))


class FitProblem:
    """What a fit minimises: the sum of squares of :meth:`evaluate`'s residuals.

    Subclasses implement :meth:`evaluate`; they may also evaluate a Jacobian column more cheaply
    (:meth:`column`) and say how many independent samples the residuals are worth
    (:meth:`effective_samples`).
    """

    #: where the residuals come from (a bench log's file), named by the messages about them
    source: str = ""

    def evaluate(self, model: ValveModel, fit_step: bool = True) -> Evaluation:
        """The residuals of ``model``. ``fit_step`` is False for the Jacobian's columns, which run
        on threads: a problem that keeps a warm start moves it on its own steps only, so that the
        result never depends on timing."""
        raise NotImplementedError

    def column(self, model: ValveModel, parameter: Parameter) -> tuple[np.ndarray | None,
                                                                         np.ndarray]:
        """The residuals a step of ``parameter`` can change, for its Jacobian column: (rows,
        values), rows None for all of them. Default: all of them."""
        return None, self.evaluate(model, fit_step=False).residual

    def effective_samples(self, evaluation: Evaluation) -> float:
        """How many independent samples the residuals are worth (default: all of them)."""
        return float(len(evaluation.residual))

    def changes(self, model: ValveModel, trials: Sequence[ValveModel],
                evaluation: Evaluation) -> np.ndarray | None:
        """The residuals' change from ``evaluation`` (``model``'s) to each of ``trials``
        (``model`` with one parameter stepped), (n, len(trials)), if the problem can tell
        without evaluating each (its sensitivities); None to have the Jacobian's columns
        evaluated one by one (:meth:`column`). Default: None."""
        return None


class FunctionProblem(FitProblem):
    """A problem given as a plain function ``residuals(model) -> array``."""

    def __init__(self, residuals):
        self.residuals = residuals

    def evaluate(self, model: ValveModel, fit_step: bool = True) -> Evaluation:
        return Evaluation(np.asarray(self.residuals(model), float))


def covariance(jacobian: np.ndarray, residuals: np.ndarray, n_eff: float | None = None,
               penalty: np.ndarray | None = None) -> np.ndarray:
    """Covariance of the fitted coordinates: σ²·(JᵀJ + LᵀL)⁺ with σ² = RSS/(n − k), widened by
    n/n_eff when the n residuals are worth only n_eff independent samples.

    Parameters
    ----------
    jacobian : numpy.ndarray
        ∂residual/∂coordinate at the optimum, shape (n, k).
    residuals : numpy.ndarray
        The residuals there, shape (n,).
    n_eff : float, optional
        Effective number of independent samples (default n: independent residuals).
    penalty : numpy.ndarray, optional
        L, ∂(penalty residual)/∂coordinate (a shape's roughness; default none).
    """
    count, parameters = jacobian.shape
    dof = max(count - parameters, 1)
    variance = float(np.sum(residuals**2)) / dof
    if n_eff is not None:
        variance *= count / max(n_eff, 1.0)
    information = jacobian.T @ jacobian
    if penalty is not None:
        information = information + penalty.T @ penalty
    try:
        return np.linalg.pinv(information) * variance
    except np.linalg.LinAlgError:
        return np.full((parameters, parameters), np.nan)


@dataclass(frozen=True)
class FitResult:
    """The outcome of a fit.

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
    correlation : numpy.ndarray
        Correlation matrix of the fitted parameters.
    success : bool
    message : str
    evaluations : int
    parameters : list of Parameter
        The fitted parameters (the model's own objects).
    evaluation : Evaluation or None
        The problem's evaluation at the optimum (its payload: a replay, say).
    jacobian : numpy.ndarray or None
        ∂residual/∂parameter at the optimum, per display unit of each parameter (None when
        nothing was fitted); what a linearised refit on part of the data starts from.
    """

    model: ValveModel
    names: list[str]
    rms: float
    count: int
    correlation: np.ndarray
    success: bool
    message: str
    evaluations: int
    parameters: list[Parameter] = field(default_factory=list)
    evaluation: Evaluation | None = None
    jacobian: np.ndarray | None = None

    @property
    def aic(self) -> float:
        """Akaike's information criterion, n·ln(RSS/n) + 2k."""
        return information_criteria(self.rms, self.count, len(self.names))[0]

    @property
    def bic(self) -> float:
        """The Bayesian information criterion, n·ln(RSS/n) + k·ln n."""
        return information_criteria(self.rms, self.count, len(self.names))[1]

    def report(self) -> str:
        """A readable summary, like lmfit's ``fit_report``."""
        state = "converged" if self.success else "NOT converged"
        lines = [f"fit of {self.model.name}: {len(self.names)} parameter(s), {self.count} "
                 f"residuals, {self.evaluations} evaluations, {state}",
                 f"  rms {from_si(self.rms, 'bar'):.4g} bar, AIC {self.aic:.1f}, "
                 f"BIC {self.bic:.1f}"]
        lines += [f"  {name:<32} {parameter}" for name, parameter in
                  zip(self.names, self.parameters)]
        for i in range(len(self.names)):
            for j in range(i + 1, len(self.names)):
                if abs(self.correlation[i, j]) > 0.5:
                    lines.append(f"  correlation({self.names[i]}, {self.names[j]}) = "
                                 f"{self.correlation[i, j]:+.3f}")
        return "\n".join(lines)


def information_criteria(rms: float, count: int, parameter_count: int) -> tuple[float, float]:
    """(AIC, BIC) of a least-squares fit with Gaussian errors of unknown variance, from the RMS
    of its ``count`` residuals."""
    base = count * np.log(max(rms**2, 1e-300 / max(count, 1)))
    return base + 2 * parameter_count, base + parameter_count * np.log(count)


def free_parameters(model: ValveModel, names: Sequence[str] | None = None
                    ) -> list[tuple[str, Parameter]]:
    """The parameters a fit varies: ``names`` (``"effect.parameter"``) or all with vary=True."""
    available = model.parameters()
    if names is None:
        return [(name, available[name]) for name in available.free()]
    missing = [name for name in names if name not in available]
    if missing:
        raise InputError(f"model {model.name!r} has no parameter(s) {', '.join(missing)}; it has "
                         f"{', '.join(available) or 'none'}")
    return [(name, available[name]) for name in names]


def split_key(key: str) -> tuple[str, str]:
    """``"effect.parameter"`` -> (effect, parameter)."""
    effect, _, parameter = key.partition(".")
    return effect, parameter


def _finite(values: np.ndarray) -> np.ndarray:
    """Residuals with failed points (NaN) counted as :data:`FAILURE_RESIDUAL`."""
    values = np.asarray(values, float)
    return np.where(np.isfinite(values), values, FAILURE_RESIDUAL)


class Minimizer:
    """Fits the free parameters (or ``names``) of a copy of ``model`` to ``problem``.

    The coordinates are the parameters in their display units, where they are of order one;
    values are clipped to the parameters' bounds.
    """

    def __init__(self, model: ValveModel, problem: FitProblem,
                 names: Sequence[str] | None = None):
        self.model = model.copy()
        self.problem = problem
        chosen = free_parameters(self.model, names)
        self.names = [name for name, _ in chosen]
        self.parameters = [parameter for _, parameter in chosen]
        self.units = [p.unit for p in self.parameters]
        self.lower = np.array([from_si(p.min, p.unit) if np.isfinite(p.min) else -np.inf
                               for p in self.parameters])
        self.upper = np.array([from_si(p.max, p.unit) if np.isfinite(p.max) else np.inf
                               for p in self.parameters])
        self._scales = np.array([to_si(1.0, unit) - to_si(0.0, unit) for unit in self.units])
        self.evaluations = 0
        self._refinement: _Refinement | None = None
        self._penalties: dict[int, tuple | None] = {}

    # --- coordinates ------------------------------------------------------------------------------

    @property
    def x(self) -> np.ndarray:
        """The parameters' current values in display units."""
        return np.array([p.display_value for p in self.parameters])

    def assign(self, x, parameters: list[Parameter] | None = None) -> None:
        for parameter, unit, value in zip(parameters or self.parameters, self.units, x):
            parameter.value = float(to_si(value, unit))

    def _evaluate(self, x, fit_step: bool = True) -> Evaluation:
        self.assign(x)
        evaluation = self.problem.evaluate(self.model, fit_step).finite()
        if fit_step:
            self.evaluations += 1
        if len(evaluation.residual) <= len(self.parameters):
            # as many unknowns as equations: the fit would pass through every point and report
            # standard errors computed from nothing
            where = f"{self.problem.source}: " if self.problem.source else ""
            raise InputError(f"{where}fitting {len(self.parameters)} free parameter(s) of "
                             f"{self.model.name!r} needs more than {len(self.parameters)} "
                             f"samples; there are {len(evaluation.residual)}")
        return evaluation

    def penalty(self, samples: int) -> tuple[np.ndarray, np.ndarray] | None:
        """The model's penalty on this fit's parameters over ``samples`` residuals, (L, b) with
        its residual L·v + b [Pa] at their SI values v (:meth:`ValveModel.penalty`); None
        without one."""
        if samples not in self._penalties:
            self._penalties[samples] = self.model.penalty(self.names, samples)
        return self._penalties[samples]

    def _penalty_residual(self, penalty) -> np.ndarray:
        """The penalty's residual [Pa] at the current parameters."""
        matrix, offset = penalty
        return matrix @ np.array([p.value for p in self.parameters]) + offset

    # --- trust-region least squares -----------------------------------------------------------------

    def least_squares(self, *, max_evaluations: int = 200, tolerance: float = 1e-8,
                      progress=None) -> FitResult:
        """Minimise the sum of squares (trust-region reflective, within the bounds).

        ``tolerance``: the relative change of the sum of squares, and of the parameters, below
        which the fit stops. The Jacobian's columns are evaluated side by side on threads, each
        with its own copy of the model. A penalty of the model's (:meth:`penalty`) is minimised
        with the sum of squares. ``progress``: called as ``progress(evaluations, rss)`` after
        each of the fit's own evaluations (not the Jacobian's columns).
        """
        if not self.parameters:
            evaluation = self.problem.evaluate(self.model).finite()
            return self._result(evaluation, None, True, "nothing to fit")
        last: dict = {"x": None, "evaluation": None}

        def objective(x):
            evaluation = self._evaluate(x)
            last["x"], last["evaluation"] = np.array(x), evaluation
            if progress is not None:
                progress(self.evaluations, float(np.sum(evaluation.residual ** 2)))
            penalty = self.penalty(len(evaluation.residual))
            if penalty is None:
                return evaluation.residual
            return np.r_[evaluation.residual, self._penalty_residual(penalty)]

        def jacobian(x):
            if not np.array_equal(last["x"], x):
                objective(x)
            at_x = last["evaluation"]
            columns = self.jacobian(np.asarray(x, float), at_x)
            penalty = self.penalty(len(at_x.residual))
            return (columns if penalty is None
                    else np.vstack([columns, penalty[0] * self._scales]))

        start = np.clip(self.x, self.lower, self.upper)
        result = least_squares(objective, start, jac=jacobian, bounds=(self.lower, self.upper),
                               x_scale="jac", max_nfev=max_evaluations, ftol=tolerance,
                               xtol=tolerance)
        # the optimum is usually the point least_squares evaluated last: reuse its residuals then
        evaluation = (last["evaluation"] if np.array_equal(last["x"], result.x)
                      else self._evaluate(result.x))
        self.assign(result.x)
        return self._result(evaluation, result.jac[:len(evaluation.residual)],
                            bool(result.success), str(result.message), int(result.nfev))

    def jacobian(self, x: np.ndarray, at_x: Evaluation) -> np.ndarray:
        """∂residual/∂x at ``at_x`` (the evaluation at x) by forward differences (scipy's
        '2-point' rule): from the problem's sensitivities where it has them
        (:meth:`FitProblem.changes`), else one evaluation per column, side by side on
        threads."""
        steps = _forward_steps(x, self.upper)
        trials = [self._stepped(x, j, steps[j]) for j in range(len(x))]
        changes = self.problem.changes(self.model, trials, at_x)
        if changes is not None:
            return np.where(np.isfinite(changes), changes, 0.0) / steps
        residual = at_x.residual

        def column(j: int) -> np.ndarray:
            trial = trials[j]
            rows, values = self.problem.column(trial, trial.parameters()[self.names[j]])
            values = _finite(values)
            if rows is None:
                return (values - residual) / steps[j]
            change = np.zeros_like(residual)
            change[rows] = (values - residual[rows]) / steps[j]
            return change

        return np.column_stack(list(map_threads(column, range(len(x)))))

    def _stepped(self, x: np.ndarray, j: int, step: float) -> ValveModel:
        """A copy of the model at ``x`` with parameter ``j`` stepped by ``step``."""
        trial = self.model.copy()
        shifted = np.array(x, float)
        shifted[j] += step
        self.assign(shifted, [p for _, p in free_parameters(trial, self.names)])
        return trial

    # --- Gauss–Newton refinement with Broyden updates -----------------------------------------------

    def linearise(self, changes: Sequence[np.ndarray], steps: Sequence[float],
                  evaluation: Evaluation, penalty: np.ndarray | None = None) -> "Minimizer":
        """Start a refinement at the current parameters, whose evaluation is ``evaluation``:
        ``changes[j]`` is how the residual changes when parameter j moves by ``steps[j]`` [SI]
        (a forward-difference Jacobian the caller already has). Without parameters (none the data
        feel) the refinement stays where it starts.

        ``penalty``: a matrix L over the parameters' SI values v; the refinement then minimises
        the sum of squares plus ‖L·v‖² (a prior on a calibration's values), and the model's own
        penalty (:meth:`penalty`: a shape's roughness) besides."""
        jacobian = (np.column_stack(changes) if len(changes)
                    else np.zeros((len(evaluation.residual), 0)))
        penalties = [(penalty, np.zeros(len(penalty)))] if penalty is not None else []
        own_penalty = self.penalty(len(evaluation.residual))
        penalties += [own_penalty] if own_penalty is not None else []
        combined = None if not penalties else (np.vstack([m for m, _ in penalties]),
                                               np.concatenate([b for _, b in penalties]))
        self._refinement = _Refinement(self, jacobian, np.asarray(steps, float), evaluation,
                                       combined)
        if not len(changes):
            self._refinement.settled = True
        return self

    def refine(self, steps: int) -> "Minimizer":
        """Up to ``steps`` more Gauss–Newton steps from :meth:`linearise`, each one real
        evaluation; ends early once a step gains less than :data:`SETTLED_GAIN` of the sum of
        squares. Resumable: call again for more."""
        self._refinement.advance(steps)
        return self

    @property
    def refined(self) -> tuple[Evaluation, float]:
        """The best evaluation of the refinement so far and its sum of squares, the penalty
        left out (the parameters are set to it)."""
        refinement = self._refinement
        refinement.assign(refinement.best_z)
        return refinement.best, refinement.best_rss - refinement._penalty_at(refinement.best_z)

    @property
    def refined_jacobian(self) -> np.ndarray:
        """The refinement's Jacobian (Broyden-updated) at its best point, per step of each
        parameter."""
        return self._refinement.jacobian

    @property
    def refined_steps(self) -> np.ndarray:
        """The step [SI] of each parameter that a column of :attr:`refined_jacobian` is for."""
        return self._refinement.scale

    @property
    def refined_penalty(self) -> tuple[np.ndarray, np.ndarray] | None:
        """The refinement's penalty (:meth:`linearise`) per step of each parameter, as the
        Jacobian's columns, and its residual [Pa] at the best point; None without one."""
        refinement = self._refinement
        if refinement.penalty is None:
            return None
        matrix, offset = refinement.penalty
        return matrix, matrix @ refinement.best_z + offset

    def refinement_errors(self) -> None:
        """Standard errors of the refinement's best point, set on the parameters."""
        refinement = self._refinement
        refinement.assign(refinement.best_z)
        z_covariance = covariance(refinement.jacobian, refinement.best.residual,
                                  self.problem.effective_samples(refinement.best))
        errors = np.sqrt(np.clip(np.diag(z_covariance), 0.0, None)) * np.abs(refinement.scale)
        for parameter, error in zip(self.parameters, errors):
            usable = np.isfinite(error) and not parameter.at_bound
            parameter.stderr = float(error) if usable else None

    # --- results ----------------------------------------------------------------------------------

    def _result(self, evaluation: Evaluation, jacobian: np.ndarray | None, success: bool,
                message: str, evaluations: int = 1) -> FitResult:
        residual = evaluation.residual
        k = len(self.parameters)
        penalty = self.penalty(len(residual)) if k else None
        if k:  # the penalty per display unit, as the Jacobian
            matrix = covariance(jacobian, residual, self.problem.effective_samples(evaluation),
                                None if penalty is None else penalty[0] * self._scales)
            errors = np.sqrt(np.clip(np.diag(matrix), 0, None))
            for parameter, error, scale in zip(self.parameters, errors, self._scales):
                # on a bound the curvature says nothing about the uncertainty: report none
                usable = np.isfinite(error) and not parameter.at_bound
                parameter.stderr = float(error * scale) if usable else None
            with np.errstate(invalid="ignore", divide="ignore"):
                correlation = matrix / np.outer(errors, errors)
        else:
            correlation = np.zeros((0, 0))
        rms = float(np.sqrt(np.mean(residual**2))) if len(residual) else 0.0
        return FitResult(self.model, list(self.names), rms, len(residual), correlation, success,
                         message, evaluations, list(self.parameters), evaluation,
                         None if jacobian is None else np.asarray(jacobian))


def fit(model: ValveModel, problem: FitProblem | object, names: Sequence[str] | None = None, *,
        max_evaluations: int = 200, tolerance: float = 1e-8) -> FitResult:
    """Fit the free parameters (or ``names``) of ``model`` to ``problem`` (a :class:`FitProblem`,
    or a function ``residuals(model) -> array``) by :meth:`Minimizer.least_squares`.

    NaN residuals (failed points) count as :data:`FAILURE_RESIDUAL`. ``model`` is not modified;
    the result holds a fitted copy.
    """
    if not isinstance(problem, FitProblem):
        problem = FunctionProblem(problem)
    return Minimizer(model, problem, names).least_squares(max_evaluations=max_evaluations,
                                                          tolerance=tolerance)


def bounded_linear_fit(tall: np.ndarray, target: np.ndarray, bounds: tuple,
                       rows: np.ndarray | None = None, row_target: np.ndarray | None = None,
                       compressed: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """x minimising ‖tall·x − target‖² + ‖rows·x − row_target‖² within ``bounds``.

    ``tall`` (a residual's Jacobian: thousands of samples by a few columns) is first reduced to
    its triangular factor R of ``tall = Q·R``, whose least squares differ from the tall one's
    by a constant (‖tall·x − target‖² = ‖R·x − Qᵀ·target‖² + ‖(1 − QQᵀ)·target‖²), so that
    the bounded solver iterates on a few rows instead of thousands. ``compressed``: (R, Qᵀ·target)
    from :func:`compress` when one tall problem is solved with several sets of ``rows``.
    """
    factor, projected = compress(tall, target) if compressed is None else compressed
    if rows is not None and len(rows):
        factor, projected = np.vstack([factor, rows]), np.r_[projected, row_target]
    return lsq_linear(factor, projected, bounds=bounds).x


def compress(tall: np.ndarray, target: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(R, Qᵀ·target) of ``tall = Q·R`` (economic QR): the few rows that carry all of a tall
    linear least-squares problem's dependence on x (:func:`bounded_linear_fit`)."""
    q, r = np.linalg.qr(tall)
    return r, q.T @ target


def _forward_steps(x: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """Finite-difference steps: :data:`DIFF_STEP` relative to max(1, |x|), away from the upper
    bound when a step up would cross it (scipy's rule for '2-point' with bounds)."""
    steps = DIFF_STEP * np.where(x >= 0, 1.0, -1.0) * np.maximum(1.0, np.abs(x))
    steps = np.where(x + steps > upper, -np.abs(steps), steps)
    return (x + steps) - x  # exactly representable differences


class _Refinement:
    """Bounded Gauss–Newton with Broyden updates in z = (parameter − start)/step [SI], where the
    Jacobian's columns are of comparable size."""

    def __init__(self, minimizer: Minimizer, jacobian: np.ndarray, steps: np.ndarray,
                 evaluation: Evaluation, penalty: tuple[np.ndarray, np.ndarray] | None = None):
        self.minimizer = minimizer
        parameters = minimizer.parameters
        self.start = np.array([p.value for p in parameters])
        self.scale = steps
        lower = np.array([(p.min - p.value) / s for p, s in zip(parameters, steps)])
        upper = np.array([(p.max - p.value) / s for p, s in zip(parameters, steps)])
        self.lower, self.upper = np.minimum(lower, upper), np.maximum(lower, upper)
        self.jacobian = jacobian
        # the penalty ‖L·v + b‖² in z, v = start + scale·z: ‖L_z·z + offset‖²
        self.penalty = (None if penalty is None else
                        (penalty[0] * steps, penalty[0] @ self.start + penalty[1]))
        self.best_z = np.zeros(len(parameters))
        self.best = evaluation
        self.best_rss = float(np.sum(evaluation.residual**2)) + self._penalty_at(self.best_z)
        self.z, self.r = self.best_z, evaluation.residual
        self.replays = 0
        self.settled = False

    def assign(self, z) -> None:
        parameters = self.minimizer.parameters
        values = np.clip(self.start + self.scale * z, [p.min for p in parameters],
                         [p.max for p in parameters])
        for parameter, value in zip(parameters, values):
            parameter.value = float(value)

    def advance(self, steps: int) -> None:
        for _ in range(steps):
            if self.settled:
                break
            self._step()

    def _penalty_at(self, z: np.ndarray) -> float:
        """‖L·v‖² at ``z`` (0 without a penalty)."""
        if self.penalty is None:
            return 0.0
        matrix, offset = self.penalty
        return float(np.sum((matrix @ z + offset) ** 2))

    def _step(self) -> None:
        rows, row_target = (None, None) if self.penalty is None else (self.penalty[0],
                                                                     -self.penalty[1])
        target = bounded_linear_fit(self.jacobian, -self.r + self.jacobian @ self.z,
                                    (self.lower, self.upper), rows, row_target)
        if np.allclose(target, self.z, rtol=0, atol=1e-4):
            self.settled = True
            return
        self.assign(target)
        evaluation = self.minimizer.problem.evaluate(self.minimizer.model).finite()
        self.minimizer.evaluations += 1
        self.replays += 1
        new = evaluation.residual
        # Broyden: make the Jacobian reproduce the change just observed
        dz = target - self.z
        self.jacobian = self.jacobian + np.outer((new - self.r) - self.jacobian @ dz,
                                                 dz) / float(dz @ dz)
        rss = float(np.sum(new**2)) + self._penalty_at(target)
        # the first replay is the linear solution, judged against the starting point; after
        # that, a step that gains (almost) nothing means the refinement is done
        if self.replays > 1 and rss > (1.0 - SETTLED_GAIN) * self.best_rss:
            self.settled = True
        if rss < self.best_rss:
            self.best_z, self.best, self.best_rss = target, evaluation, rss
            self.z, self.r = target, new
        else:  # the updated Jacobian proposes a new step from the best point so far
            self.z, self.r = self.best_z, self.best.residual
