"""Linearised refits of a model on parts of a log: held-out runs, bootstrap resamples, and the
maps' discrepancy as a penalised nuisance.

Refitting a model for every held-out fold and every resample would cost hundreds of replays. A
fit is already linearised at its optimum (its residual r and Jacobian J over every sample), and
a refit on part of the data moves the parameters little. So:

* **held out**: the parameters refitted without a group of runs move by
  δ_g = θ(without g) − θ(all), both from the linear problem min Σ_runs w_run·‖r + J·θ‖²; the
  held-out residual is r_g + J_g·δ_g. Taking the difference of two linear solves, not the solve
  itself, keeps a Jacobian that is only roughly right from promising gains the real refit did
  not find (the classic approximate cross-validation);
* **against the maps' error**: the sum of squares left once the discrepancy (:mod:`.discrepancy`,
  columns N, coefficients a with the prior N(0, 1)) has explained what it can, refitted together
  with the model's parameters, min over θ and a of Σ_runs w_run·‖r + J·θ + N·a‖² + s²·‖a‖²,
  with s² the variance of one effective sample; w_run is a run's multiplicity in a bootstrap
  resample (1 for the log itself). The parameters move with the discrepancy because the fit
  that set them knew nothing of the maps' error: where a parameter bent to absorb some of it
  (a viscous friction coefficient taking up a flow map's error across an unsampled gap, say),
  the discrepancy must be able to take that error back and let the parameter return. Fitted
  after them instead, it leaves the bend in the model, and a candidate that undoes it looks
  like a discovery (a virtual valve's log, seed 2 of eval/virtual_bench.py: a degressive
  spring).

Sums of squares and cross products are kept per run, so every refit costs a small solve, not a
pass over the samples.

Held-out schemes (:func:`run_groups`): leave one run out, leave one temperature out, leave one
pilot pressure out. A parameter the training runs do not determine (one run's own, with that run
left out) keeps its value in the linear refit, so a per-run parameter would carry what it learnt
from a run to that run's held-out prediction: per-run candidates are not judged on held-out runs
at all (:func:`~surrogate.diagnosis.diagnose.diagnose`), since by construction they cannot predict
another run.

The held-out RMS quoted for a model (a workflow step, a candidate) is that of every run predicted
by a fit to the others (:data:`HEADLINE`). A candidate must also predict a whole condition left
out better, one temperature or one pilot pressure
(:meth:`surrogate.diagnosis.rule.SignificanceRule.gains_on_unseen`), not both: leaving
out the only runs that reach some part of the valve's range (the largest openings, say, which a
test sequence reaches at one pilot pressure only) leaves a parameter acting there undetermined,
so that condition cannot judge an effect that acts there, true or not.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass

import numpy as np

from ..data.loaders import BenchLog
from ..model import ValveModel
from ..core.parallel import map_threads
from ..core.units import from_si
from .discrepancy import Discrepancy
from .logfit import probe_columns
from .residuals import LogReplay, replay_log

#: temperature [°C] and pilot pressure [bar] within which two runs count as the same condition
SAME_TEMPERATURE_C = 5.0
SAME_PILOT_BAR = 5.0
#: the scheme of the held-out RMS quoted for a model: each run predicted by a fit to the others
HEADLINE = "run"
#: schemes that leave a whole operating condition out; a candidate must predict one of them better
CONDITIONS = ("temperature", "pilot pressure")
#: the RMS over every scheme's held-out runs together (runs, temperatures, pilot pressures)
POOLED = "pooled"


def run_groups(log: BenchLog) -> dict[str, dict[str, list[str]]]:
    """The held-out schemes: scheme -> {group label -> runs}, runs as in the log.

    ``run``: every run alone; ``temperature``: runs at one oil temperature; ``pilot pressure``:
    runs at one pilot set point p_P − p_B (schemes with a single group are left out: nothing
    would remain to fit)."""
    frame = log.frame
    runs = list(dict.fromkeys(frame["run"].astype(str)))
    per_run = frame.assign(run=frame["run"].astype(str), p_Pe=frame["p_P"] - frame["p_B"]
                           ).groupby("run", sort=False)[["temperature", "p_Pe"]].median()
    schemes = {"run": {run: [run] for run in runs}}
    for scheme, column, step, unit, shown in (
            ("temperature", "temperature", SAME_TEMPERATURE_C, "degC", "°C"),
            ("pilot pressure", "p_Pe", SAME_PILOT_BAR, "bar", "bar")):
        # levels rounded in display units, so that the labels read as the set points do
        levels = np.round(from_si(per_run[column].to_numpy(), unit) / step) * step
        groups: dict[str, list[str]] = {}
        for run, level in zip(per_run.index, levels):
            groups.setdefault(f"{level:.0f} {shown}", []).append(run)
        if len(groups) > 1:
            schemes[scheme] = groups
    return schemes


def held_at_bounds(jacobian: np.ndarray, parameters: list) -> np.ndarray:
    """``jacobian`` with the columns of parameters that sit on a bound set to zero: the linear
    refits of the judgement (:class:`RunBlocks`) know no bounds, and a viscous friction fitted to
    zero would otherwise turn negative there, crediting its candidate with a gain no valve can
    have. Held where the fit left them, such parameters take no part in those refits."""
    pinned = np.array([parameter.at_bound for parameter in parameters], bool)
    return np.where(pinned, 0.0, jacobian) if pinned.any() else jacobian


@dataclass(frozen=True)
class Linearised:
    """A fitted model's residual r [Pa] and Jacobian J (any column scaling) at its optimum, over
    the solved samples of a log, and the fit's penalty (a shape's roughness), if any: (L, p),
    its Jacobian in the same column scaling and its residual [Pa] at the optimum."""

    residual: np.ndarray
    jacobian: np.ndarray
    roughness: tuple[np.ndarray, np.ndarray] | None = None

    def held(self, parameters: list) -> "Linearised":
        """The same with the parameters that sit on a bound held where they are
        (:func:`held_at_bounds`), in the penalty too: their value is in its residual."""
        roughness = self.roughness
        if roughness is not None:
            roughness = (held_at_bounds(roughness[0], parameters), roughness[1])
        return Linearised(self.residual, held_at_bounds(self.jacobian, parameters), roughness)

    def moved(self, step: np.ndarray) -> "Linearised":
        """The same linearisation about the point ``step`` away (in the columns' scaling): its
        residual and its penalty's residual there. Held-out refits about a point that is no
        optimum would otherwise credit the whole log's step to no group."""
        roughness = self.roughness
        if roughness is not None:
            roughness = (roughness[0], roughness[0] @ step + roughness[1])
        return Linearised(self.residual + self.jacobian @ step, self.jacobian, roughness)

    def beside(self, columns: np.ndarray, penalty: np.ndarray, values: np.ndarray
               ) -> "Linearised":
        """The same with more parameters beside: their ``columns`` and a penalty ‖L·v‖² over
        their values v, at ``values``."""
        p, k = self.jacobian.shape[1], columns.shape[1]
        rows = np.hstack([np.zeros((len(penalty), p)), penalty])
        offset = penalty @ values
        if self.roughness is not None:
            kept = np.hstack([self.roughness[0], np.zeros((len(self.roughness[0]), k))])
            rows, offset = np.vstack([kept, rows]), np.r_[self.roughness[1], offset]
        return Linearised(self.residual, np.column_stack([self.jacobian, columns]),
                          (rows, offset))


def weighted_sum(weights: np.ndarray, blocks: np.ndarray) -> np.ndarray:
    """Σ_k weights[k]·blocks[k]: ``np.tensordot(weights, blocks, axes=1)``'s own product, to
    the bit, without its handling of general axes, which cost more than the product for the
    few runs of a log (held-out refits and bootstrap resamples ask it thousands of times)."""
    weights = np.asarray(weights)
    return np.dot(weights.reshape(1, -1), blocks.reshape(len(weights), -1)
                  ).reshape(blocks.shape[1:])


@dataclass(frozen=True)
class RunIndex:
    """The samples of each run, the runs in the order they first appear: what
    :class:`RunBlocks` sums over, made once for the many refits a diagnosis makes on one log's
    samples (comparing labels costs more than the sums).

    Attributes
    ----------
    labels : list of str
    rows : list of numpy.ndarray
        Each run's samples, as a mask.
    positions : list of numpy.ndarray
        Each run's samples, as their positions.
    """

    labels: list[str]
    rows: list[np.ndarray]
    positions: list[np.ndarray]

    @classmethod
    def of(cls, runs: np.ndarray) -> "RunIndex":
        """The index of each sample's run label ``runs``."""
        runs = np.asarray(runs).astype(str)
        labels = list(dict.fromkeys(runs.tolist()))  # a list iterates faster than NumPy
        rows = [runs == run for run in labels]
        return cls(labels, rows, [np.flatnonzero(m) for m in rows])


class RunBlocks:
    """Per-run sums of squares and cross products of [J, N] and r, for fast refits.

    Parameters
    ----------
    fit : Linearised
    discrepancy : Discrepancy or None
        The maps' nuisance columns at the same samples (None: no nuisance).
    runs : numpy.ndarray or RunIndex
        Each sample's run, or their index (:meth:`RunIndex.of`).
    penalty : float
        s² [Pa²]: the prior's weight on the nuisance coefficients.
    roughness : tuple of numpy.ndarray, optional
        (L, b): a penalty ‖L·θ + b‖² on the parameters' step θ (in the Jacobian's column
        scaling), the roughness of a shape-free term (:mod:`surrogate.effects.shapes`): refits
        keep the shape as smooth as its fit did. It shapes the refits but is not counted in
        :meth:`objective`; :meth:`effective_parameters` says what it leaves free. Default: the
        fit's own (:attr:`Linearised.roughness`).
    """

    def __init__(self, fit: Linearised, discrepancy: Discrepancy | None,
                 runs: np.ndarray | RunIndex, penalty: float,
                 roughness: tuple[np.ndarray, np.ndarray] | None = None):
        jacobian = fit.jacobian
        self.p = jacobian.shape[1]
        index = runs if isinstance(runs, RunIndex) else RunIndex.of(runs)
        self.labels = index.labels
        r = fit.residual
        # [J, N]ᵀ[J, N] per run, its nuisance block shared with every other refit on the same
        # discrepancy (Discrepancy.run_grams), and so are the runs' rows of N
        k = 0 if discrepancy is None else discrepancy.size
        nuisance = ([None] * len(index.labels) if discrepancy is None
                    else discrepancy.run_columns(index.labels, index.positions))
        self.gram = np.empty((len(index.labels), self.p + k, self.p + k))
        self.cross = np.empty((len(index.labels), self.p + k))
        squares = []
        for number, (rows, run_nuisance) in enumerate(zip(index.positions, nuisance)):
            # the run's positions: the rows its mask selects, without finding them again
            run_jacobian, run_residual = jacobian[rows], r[rows]
            part = np.empty((len(run_residual), self.p + k))  # the run's [J, N]
            part[:, :self.p] = run_jacobian
            if k:
                part[:, self.p:] = run_nuisance
            self.gram[number, :self.p, :] = run_jacobian.T @ part
            self.gram[number, self.p:, :self.p] = self.gram[number, :self.p, self.p:].T
            self.cross[number] = part.T @ run_residual
            squares.append(float(run_residual @ run_residual))
        if k:
            self.gram[:, self.p:, self.p:] = discrepancy.run_grams(index.labels, index.rows)
        self.squares = np.array(squares)
        self.counts = np.array([len(rows) for rows in index.positions])
        self.penalty = penalty * np.eye(k)
        # a parameter the data do not feel has a zero column: a whisper of ridge keeps the solve
        # defined without moving anything the data determine
        diagonal = np.einsum("kii->i", self.gram)[:self.p]
        self.ridge = np.diag(1e-10 * max(float(diagonal.mean()) if self.p else 1.0, 1e-300)
                             * np.ones(self.p))
        self.rough = None
        self._regular_matrix = None  # :meth:`_regular`, once asked
        roughness = fit.roughness if roughness is None else roughness
        if roughness is not None:
            matrix, offset = roughness
            self.rough = (matrix.T @ matrix, matrix.T @ offset)

    def moved(self, theta: np.ndarray) -> "RunBlocks":
        """The same blocks about the point ``theta`` away (a parameter step, in the columns'
        scaling): the residual r + J·θ and the roughness penalty's about L·θ + b, from the
        products already formed (the fit's :meth:`Linearised.moved`, without forming
        [J, N]ᵀ[J, N] again, which is most of the cost)."""
        p, moved = self.p, copy.copy(self)
        moved.cross = self.cross + self.gram[:, :, :p] @ theta
        moved.squares = (self.squares + 2.0 * self.cross[:, :p] @ theta
                         + np.einsum("i,kij,j->k", theta, self.gram[:, :p, :p], theta))
        if self.rough is not None:
            moved.rough = (self.rough[0], self.rough[1] + self.rough[0] @ theta)
        return moved

    def step(self, weights: np.ndarray) -> np.ndarray:
        """The linear refit's parameter step θ with each run weighted by ``weights``."""
        p = self.p
        gram = weighted_sum(weights, self.gram[:, :p, :p]) + self.ridge
        cross = weighted_sum(weights, self.cross[:, :p])
        if self.rough is not None:
            gram, cross = gram + self.rough[0], cross + self.rough[1]
        return -np.linalg.solve(gram, cross)

    def objective(self, weights: np.ndarray) -> float:
        """min over θ and a of the weighted sum of squares of r + J·θ + N·a plus s²·‖a‖² [Pa²]
        (the parameters refitted with the discrepancy; without one, the sum of squares). With a
        roughness penalty, θ and a minimise it too, and the value is that of the sum of squares
        and s²·‖a‖² at them."""
        squares = float(weights @ self.squares)
        cross = weighted_sum(weights, self.cross)
        if self.rough is not None:
            gram = weighted_sum(weights, self.gram)
            x = self._joint_step(weights, cross, gram)
            a = x[self.p:]
            return (squares + 2.0 * float(cross @ x) + float(x @ gram @ x)
                    + float(a @ self.penalty @ a))
        if not self.penalty.size:
            return squares
        return squares + float(cross @ self._joint_step(weights, cross))

    def effective_parameters(self, columns: np.ndarray) -> float:
        """How many parameters the columns ``columns`` (indices into θ) are worth, refitted with
        the rest and the discrepancy on the whole log: the trace of their block of the hat
        matrix (their count without a roughness penalty, less with one)."""
        ones = np.ones(len(self.labels))
        gram = weighted_sum(ones, self.gram)
        influence = np.linalg.solve(gram + self._regular(), gram)
        return float(np.trace(influence[np.ix_(columns, columns)]))

    def nuisance(self) -> np.ndarray:
        """The discrepancy's coefficients a fitted to the whole log, with the parameters."""
        ones = np.ones(len(self.labels))
        return self._joint_step(ones, weighted_sum(ones, self.cross))[self.p:]

    def _regular(self) -> np.ndarray:
        """What the solves add to the Gram matrix: the ridge, the roughness, the prior on a
        (made once: every resample's solve adds the same; :meth:`moved` keeps the roughness's
        matrix, and so this)."""
        if self._regular_matrix is None:
            p = self.p
            regular = np.zeros_like(self.gram[0])
            regular[:p, :p] = self.ridge + (0.0 if self.rough is None else self.rough[0])
            regular[p:, p:] = self.penalty
            self._regular_matrix = regular
        return self._regular_matrix

    def _joint_step(self, weights: np.ndarray, cross: np.ndarray,
                    gram: np.ndarray | None = None) -> np.ndarray:
        """(θ, a) minimising the weighted objective, whose cross products are ``cross`` (and
        Gram matrix ``gram``, when the caller has formed it)."""
        if self.rough is not None:
            cross = cross.copy()
            cross[:self.p] += self.rough[1]
        if gram is None:
            gram = weighted_sum(weights, self.gram)
        return -np.linalg.solve(gram + self._regular(), cross)

    def _squares_at(self, theta: np.ndarray, run: int) -> float:
        """‖r + J·θ‖² over run ``run``'s samples."""
        p = self.p
        return float(self.squares[run] + 2.0 * self.cross[run, :p] @ theta
                     + theta @ self.gram[run, :p, :p] @ theta)

    def shifts(self, groups: dict[str, list[str]]) -> dict[str, tuple[list[int], np.ndarray]]:
        """For each group of runs that can be left out (some runs remain): the indices of its
        runs in :attr:`labels` and δ_g, the parameters' step when the fit leaves it out."""
        index = {run: i for i, run in enumerate(self.labels)}
        whole = self.step(np.ones(len(self.labels)))
        result = {}
        for label, runs in groups.items():
            held = [index[run] for run in runs if run in index]
            if not held or len(held) == len(self.labels):
                continue
            weights = np.ones(len(self.labels))
            weights[held] = 0.0
            result[label] = (held, self.step(weights) - whole)
        return result

    def heldout_rms(self, schemes: dict[str, dict[str, list[str]]]) -> dict[str, float]:
        """RMS of the residual on held-out runs [Pa], per scheme and :data:`POOLED` over all:
        refitted without each group, judged on it."""
        result, total, count = {}, 0.0, 0
        for scheme, groups in schemes.items():
            squares, samples = 0.0, 0
            for held, shift in self.shifts(groups).values():
                squares += sum(self._squares_at(shift, i) for i in held)
                samples += int(self.counts[held].sum())
            if samples:
                result[scheme] = float(np.sqrt(max(squares, 0.0) / samples))
                total, count = total + squares, count + samples
        result[POOLED] = float(np.sqrt(max(total, 0.0) / count)) if count else float("nan")
        return result


@dataclass(frozen=True)
class Prior:
    """Parameters a held-out refit moves beside a model's free ones under a prior, though no
    fit varies them (a calibration's values, fitted once under it): their keys, their columns
    (the Δp change [Pa] per SI unit at the solved samples) and the prior as a penalty
    ‖L·v‖² [Pa²] over their SI values v."""

    keys: list[str]
    columns: np.ndarray
    penalty: np.ndarray


def replayed_heldout_rms(model: ValveModel, keys: list[str], log_replay: LogReplay,
                         groups: dict[str, list[str]], prior: Prior | None = None,
                         columns: list | None = None) -> float:
    """RMS [Pa] of ``model``'s residual on each group of runs predicted by a fit to the others.

    The parameters ``keys`` (and ``prior``'s) are refitted without the group by the linear
    refit of :meth:`RunBlocks.shifts` about ``log_replay``, the model's replay of the log: the
    parameters' ``columns`` (:func:`~surrogate.fitting.logfit.probe_columns` of ``keys``, probed
    here unless given), parameters on a bound held, the model's penalty kept (a shape stays as
    smooth as its fit made it). The group's runs are then *replayed* at the refitted values.

    The linear refit tells well how the parameters move without a group; its prediction of the
    group, J·δ, does not when Δp answers a parameter far from linearly: a leak 0.03 L/min larger
    at the smallest flows of the hottest run, linearised, predicted that run 120 bar off (stress
    case 4252 of eval/offlibrary.py), where the replay moves it by a fraction of a bar. The
    replays cost one replay of the log per scheme, the columns one per parameter (none when
    given: a workflow's step probes them once, for this check and the next diagnosis)."""
    ok = log_replay.ok
    parameters = model.parameters()
    columns = probe_columns(model, keys, log_replay) if columns is None else columns
    nothing = np.zeros(int(ok.sum()))
    jacobian = np.column_stack([c.change if c.felt else nothing for c in columns]
                               or [np.zeros((len(nothing), 0))])
    steps = np.array([c.step for c in columns])
    values = np.array([parameters[key].value for key in keys])
    penalty = model.penalty(keys, int(ok.sum()))
    roughness = (None if penalty is None else
                 (penalty[0] * steps, penalty[0] @ values + penalty[1]))
    fit = Linearised(log_replay.residual[ok], jacobian, roughness).held([parameters[key]
                                                                         for key in keys])
    if prior is not None:
        fit = fit.beside(prior.columns, prior.penalty,
                         np.array([parameters[key].value for key in prior.keys]))
        keys = keys + prior.keys
        steps = np.r_[steps, np.ones(len(prior.keys))]
        values = np.r_[values, [parameters[key].value for key in prior.keys]]
    blocks = RunBlocks(fit, None, log_replay.runs[ok], 0.0)

    def predict(entry) -> np.ndarray:
        held, shift = entry
        trial = model.copy()
        moved = trial.parameters()
        for key, value in zip(keys, values + shift * steps):
            parameter = moved[key]
            parameter.value = float(np.clip(value, parameter.min, parameter.max))
        rows = np.flatnonzero(np.isin(log_replay.runs.astype(str),
                                      [blocks.labels[i] for i in held]))
        again = replay_log(trial, log_replay.log.take(rows), guess=log_replay.take(rows),
                           diagnostics=False)
        # a sample the refitted model leaves unsolved keeps the residual it had before
        return np.where(np.isfinite(again.residual), again.residual, log_replay.residual[rows])

    residuals = [r[np.isfinite(r)]
                 for r in map_threads(predict, list(blocks.shifts(groups).values()))]
    count = sum(len(r) for r in residuals)
    return float(np.sqrt(sum(float(r @ r) for r in residuals) / count)) if count else float("nan")


def bootstrap_weights(runs: int, resamples: int, seed: int = 0) -> np.ndarray:
    """(resamples, runs) multiplicities of runs drawn with replacement."""
    rng = np.random.default_rng(seed)
    draws = rng.integers(0, runs, size=(resamples, runs))
    return np.stack([np.bincount(row, minlength=runs) for row in draws]).astype(float)
