"""A model replayed over a whole bench log, with its residuals, and the noise they carry.

The residual of a sample is the model's pressure drop minus the measured one, p_L − p_B, with the
model fed the measured flow, pilot and back pressures and temperature, and friction acting as a
play along each run's time series.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from ..data.loaders import BenchLog
from ..core.errors import InputError
from ..maps.coverage import describe_all
from ..core.memory import release_freed
from ..model import ValveModel
from ..points import OperatingPoints
from ..solver import Replay, replay
from ..solver.steady import Status


@dataclass(frozen=True)
class LogReplay:
    """A model replayed over every run of a bench log.

    Attributes
    ----------
    log : BenchLog
    replay : Replay
    measured : numpy.ndarray
        Measured Δp = p_L − p_B [Pa].
    residual : numpy.ndarray
        Model minus measured Δp [Pa]; NaN where the solver failed (see ``replay.status``).
    """

    log: BenchLog
    replay: Replay
    measured: np.ndarray
    residual: np.ndarray

    @property
    def ok(self) -> np.ndarray:
        return np.isfinite(self.residual)

    @property
    def runs(self) -> np.ndarray:
        return self.log.frame["run"].to_numpy()

    def require_solved(self, model: str) -> "LogReplay":
        """This replay, if the model solved any sample; else an InputError that says why not."""
        if not self.ok.any():
            statuses = pd.Series([Status(code).name.lower() for code in self.replay.status]
                                 ).value_counts()
            raise InputError(f"model {model!r} solves none of the {len(self.residual)} samples "
                             f"of {self.log.source} ("
                             + ", ".join(f"{n} {status}" for status, n in statuses.items())
                             + "); check its valve and effects")
        return self

    def rms(self) -> float:
        """Root-mean-square residual over the solved samples [Pa]."""
        return float(np.sqrt(np.mean(self.residual[self.ok] ** 2)))

    def take(self, rows) -> "LogReplay":
        """The replay of these rows (positions) alone, e.g. one run's."""
        return LogReplay(self.log.take(rows), self.replay.take(rows), self.measured[rows],
                         self.residual[rows])

    def frame(self) -> pd.DataFrame:
        """One row per sample (SI): the log's columns, predicted and measured Δp, residual, the
        predicted Δp's standard deviation from the maps (NaN for maps without one), whether and
        why the maps extrapolate there, and whether the piston moved."""
        frame = self.log.frame.copy()
        frame["dp_measured"] = self.measured
        frame["dp_predicted"] = self.replay.dp
        frame["residual"] = self.residual
        frame["dp_std"] = (np.full(len(frame), np.nan) if self.replay.dp_std is None
                           else self.replay.dp_std)
        frame["extrapolating"] = self.replay.extrapolating
        frame["outside_samples"] = describe_all(self.replay.reasons_outside)
        frame["moving"] = self.replay.moving
        frame["status"] = self.replay.status
        return frame


def run_groups_of(runs: np.ndarray) -> list[np.ndarray]:
    """The positions of each run's samples, runs in order of first appearance, samples in their
    order: one pass over the labels, however many runs a log holds."""
    codes, labels = pd.factorize(np.asarray(runs), sort=False)
    order = np.argsort(codes, kind="stable")
    return np.split(order, np.cumsum(np.bincount(codes, minlength=len(labels)))[:-1])


def run_rows(log: BenchLog, run: str) -> np.ndarray:
    """Positions of one run's samples in the log."""
    return np.flatnonzero(log.frame["run"].astype(str).to_numpy() == str(run))


def measured_dp(log) -> np.ndarray:
    """Measured Δp = p_L − p_B of every sample of a log (or of one run) [Pa]."""
    return (log.frame["p_L"] - log.frame["p_B"]).to_numpy()


#: time over which the friction state ignores the inputs' sample-to-sample noise [s] (see
#: :mod:`surrogate.solver.replay`): 7 samples at 25 Hz. On a noisy ramp that already removes the
#: ratchet's bias; longer windows round the turns of the ramps, and the state then turns short
#: of the real piston (tests/solver/test_solver.py::test_smoothed_state_does_not_ratchet_on_pilot_noise)
STATE_SMOOTHING = 0.28


def state_smoothing_samples(log: BenchLog, seconds: float = STATE_SMOOTHING) -> int:
    """The odd number of samples spanning ``seconds`` [s] at the log's median sampling interval
    (:attr:`~surrogate.data.loaders.BenchLog.sampling_interval`, found once per log)."""
    interval = log.sampling_interval
    if not np.isfinite(interval) or interval <= 0:
        return 1
    return int(round(seconds / interval)) // 2 * 2 + 1


def replay_log(model: ValveModel, log: BenchLog, *, guess: LogReplay | None = None,
               diagnostics: bool = True, progress=None) -> LogReplay:
    """Replay every run of ``log`` with ``model`` (friction as a play within each run, its state
    blind to the inputs' sample-to-sample noise over :data:`STATE_SMOOTHING`).

    ``guess``: a replay of the same log with nearby parameters, to start the solver from.
    ``diagnostics=False`` skips the maps' extrapolation reasons and Δp standard deviation
    (:func:`surrogate.solver.replay.replay`), for the inner loop of a fit. ``progress``
    (a :class:`~surrogate.core.progress.Progress`) hears how far the replay of a big log got.
    """
    # a guess of this very log brings its inputs and measured Δp, read from the log once (a
    # diagnosis replays its log from the model's own replay some eighty times)
    same = guess is not None and guess.log is log
    points = guess.replay.points if same else OperatingPoints.from_bench(log.frame)
    # the points' run labels, as fixed-width text: the log's column is made of objects,
    # slower to read out and to compare
    solver_replay = replay(model, points, points.run,
                           guess=None if guess is None else guess.replay, diagnostics=diagnostics,
                           smoothing=state_smoothing_samples(log), progress=progress)
    measured = guess.measured if same else measured_dp(log)
    residual = np.where(solver_replay.ok, solver_replay.dp - measured, np.nan)
    release_freed(len(log))
    return LogReplay(log, solver_replay, measured, residual)


#: solved samples a run needs for its second differences to say anything about the noise
NOISE_SAMPLES = 5


def noise_floor(residual: np.ndarray, runs: np.ndarray, *, required: bool = True,
                source: str | None = None) -> float:
    """The residual's white-noise level [same units], from its sample-to-sample scatter.

    Within each run the residual's second differences r[k+1] − 2·r[k] + r[k−1] cancel anything
    smooth in time (the model's misfit) and keep the noise: for white noise of standard deviation
    σ their variance is 6σ². A robust scale (1.4826 × median absolute deviation) ignores the
    occasional jump where the piston breaks away. Runs are pooled by their sample counts. The
    result is the lowest RMS any model fed these noisy inputs could reach.

    Raises
    ------
    InputError
        If no run has :data:`NOISE_SAMPLES` solved samples (with ``required``; otherwise the
        result is NaN): the log is too short to tell noise from misfit.
    """
    weights, variances = [], []
    finite = np.isfinite(residual)
    for rows in run_groups_of(runs):
        r = residual[rows[finite[rows]]]
        if len(r) < NOISE_SAMPLES:
            continue
        second = r[2:] - 2.0 * r[1:-1] + r[:-2]
        scale = 1.4826 * np.median(np.abs(second - np.median(second))) / np.sqrt(6.0)
        weights.append(len(r))
        variances.append(scale**2)
    if not weights:
        if not required:
            return float("nan")
        longest = max((int(np.sum(finite[rows])) for rows in run_groups_of(runs)), default=0)
        where = f"{source}: " if source else ""
        raise InputError(f"{where}the noise floor needs a run with at least {NOISE_SAMPLES} "
                         f"solved samples; the longest run here has {longest}")
    return float(np.sqrt(np.average(variances, weights=weights)))


def effective_samples(residual: np.ndarray, runs: np.ndarray) -> float:
    """How many independent samples the residuals are worth, n·(1 − ρ)/(1 + ρ) per run.

    ρ is the run's lag-1 autocorrelation (clipped to [0, 0.99]): a model that misses something
    leaves residuals correlated in time, and counting every sample as independent would make any
    extra term look significant.
    """
    total = 0.0
    finite = np.isfinite(residual)
    for rows in run_groups_of(runs):
        r = residual[rows[finite[rows]]]
        if len(r) < 3:
            total += len(r)
            continue
        r = r - r.mean()
        denominator = float(np.sum(r * r))
        rho = float(np.sum(r[1:] * r[:-1]) / denominator) if denominator > 0 else 0.0
        rho = min(max(rho, 0.0), 0.99)
        total += len(r) * (1.0 - rho) / (1.0 + rho)
    return max(total, 1.0)
