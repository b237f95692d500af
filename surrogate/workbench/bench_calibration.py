"""The workflow's last step: the CFD maps calibrated to the bench, within their own uncertainty.

Every diagnosis judges a candidate against the maps' discrepancy, nuisance terms as large as the
maps' error can be (:mod:`surrogate.fitting.discrepancy`). When no physics is left to find, the
residual still holds that error: a real valve is never its CFD. This step fits it, once, as two
map corrections of the opening (:mod:`surrogate.effects.per_opening`): the flow force and the
discharge coefficient, each scaled by a value per knot of the discrepancy.

The values are fitted with the discrepancy's own prior: each N(0, σ_b²), σ_b the maps' relative
error near knot b (their calibrated σ and the CFD's own error in quadrature, over the samples
near it), weighed against the residual with s² = σ_noise²·n/n_eff, the noise of one effective
sample, as the diagnosis weighs its nuisance terms. So the maps move where the bench says they
are wrong, and by no more than their uncertainty allows: a physical effect the diagnosis missed
is not soaked up beyond that.

The columns come from two probe replays (:func:`surrogate.diagnosis.shapes.sensitivity`), as a
shape-free term's do; Gauss–Newton steps with real replays then settle the values, which the
model keeps fixed: the workflow refits the model's own parameters beside them, and judges the
step on held-out runs with the calibration refitted without each run under the same prior
(:meth:`BenchCalibration.heldout_rms`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..data.loaders import BenchLog
from ..diagnosis.refit import DiagnosisProblem
from ..diagnosis.shapes import (probe_of, sensitivity, shape_columns, state_at_samples)
from ..effects.per_opening import CALIBRATIONS, hat_basis
from ..fitting.discrepancy import knots
from ..fitting.heldout import HEADLINE, Prior, replayed_heldout_rms
from ..fitting.residuals import LogReplay
from ..fitting.leastsquares import FitResult, Minimizer
from ..model import ValveModel
from ..core.parallel import map_threads

#: Gauss–Newton steps (one replay each) after the linear solution
STEPS = 3
#: the row of :attr:`~surrogate.solver.replay.Replay.map_std` of each calibration's map
MAP_ROW = {"calibrated_flow_force": 1, "calibrated_discharge": 0}


@dataclass(frozen=True)
class BenchCalibration:
    """The calibrated model and what judging it on held-out runs needs.

    Attributes
    ----------
    model : ValveModel
        The model with the calibration's effects, their values fitted and fixed.
    replay : LogReplay
        Its replay of the log.
    names : list of str
        The calibration's effects.
    columns : numpy.ndarray
        (n, k) [Pa]: Δp's change at every sample of the log for a unit step of each value (0 where
        the model before had no solution).
    prior : numpy.ndarray
        (k, k) [Pa]: the prior as a penalty ‖prior·v‖² over the values v.
    values : numpy.ndarray
        (k,) [1]: the fitted values.
    sigma : numpy.ndarray
        (k,) [1]: each value's prior σ.
    """

    model: ValveModel
    replay: LogReplay
    names: list[str]
    columns: np.ndarray
    prior: np.ndarray
    values: np.ndarray
    sigma: np.ndarray

    def heldout_rms(self, fitted: FitResult | None, log_replay: LogReplay,
                    schemes: dict[str, dict[str, list[str]]], columns=None) -> float:
        """RMS on held-out runs [Pa] of the calibrated model refitted to the others and
        replayed (:func:`~surrogate.fitting.heldout.replayed_heldout_rms`): its own free
        parameters (``fitted``'s, replayed as ``log_replay``) and the calibration's values together,
        these under their prior; ``columns``: the free parameters' probe columns, if made."""
        model = self.model if fitted is None else fitted.model
        keys = [f"{name}.{coefficient}" for name in self.names
                for coefficient in model.effect(name).coefficient_names()]
        prior = Prior(keys, self.columns[log_replay.ok], self.prior)
        keys = ([] if fitted is None else list(fitted.names) if columns is None
                else [column.key for column in columns])
        return replayed_heldout_rms(model, keys, log_replay, schemes[HEADLINE], prior,
                                    columns=columns)

    def describe(self) -> str:
        """The calibration in words: how far each map moved, and where most."""
        parts = []
        for effect in self.model.effects:
            if effect.name not in self.names:
                continue
            values = effect.coefficients
            where = effect.knots[int(np.argmax(np.abs(values)))]
            parts.append(f"{effect.quantity.split()[0]} {100 * values.min():+.1f} to "
                         f"{100 * values.max():+.1f} % (most near {where * 1e3:.3g} mm)")
        return ("the CFD maps calibrated to the bench per opening, within their own "
                "uncertainty: " + "; ".join(parts))


def prior_sigma(name: str, replay, ok: np.ndarray, at: np.ndarray) -> np.ndarray:
    """Each knot's prior σ [1] for calibration ``name``: the map's relative σ against the valve
    (the calibrated one and the CFD's own error in quadrature), averaged over the solved samples
    ``ok`` by their hat weights (the log's average where no sample lies near a knot), and no
    wider than the values' bounds (a grid's σ beyond its smallest opening can reach them)."""
    spread = np.full(int(ok.sum()), 0.0)
    if replay.map_std is not None:
        spread = np.nan_to_num(replay.map_std[MAP_ROW[name], ok])
    variance = spread**2
    weights = hat_basis(at, np.nan_to_num(replay.u[ok], nan=at[0]))
    total = weights.sum(axis=0)
    knot_variance = weights.T @ variance / np.where(total > 0, total, 1.0)
    limit = next(cls.value_limit for cls in CALIBRATIONS if cls.name == name)
    return np.minimum(np.sqrt(np.where(total > 1e-9, knot_variance, float(np.mean(variance)))),
                      limit)


def calibrate_maps(model: ValveModel, log: BenchLog, log_replay: LogReplay, *,
                   workers: int | None = None) -> BenchCalibration | None:
    """The maps of ``model`` (fitted to ``log``, replayed as ``log_replay`` with diagnostics)
    calibrated per opening (module docstring); None for maps without samples or uncertainty
    (an orifice equation), or when the model already has a calibration."""
    at = knots(model)
    if (log_replay.replay.map_gain is None or at.size < 2
            or any(model.has_effect(cls.name) for cls in CALIBRATIONS)):
        return None
    problem = DiagnosisProblem(log, log_replay)
    ok = problem.ok
    state = state_at_samples(model, log_replay)
    probes = [probe_of(cls) for cls in CALIBRATIONS]
    found = list(map_threads(lambda probe: sensitivity(model, probe, log_replay), probes,
                             workers=workers))
    trial = model.copy()
    columns, sigma, names = [], [], []
    for cls, sensitivities in zip(CALIBRATIONS, found):
        effect = cls.on_knots(at)
        shaped = shape_columns(cls, state, sensitivities, ok, log_replay.replay.moving,
                               log_replay.runs, effect=effect)
        trial.effects.append(effect)
        columns.append(shaped.columns / shaped.steps)  # per unit value
        sigma.append(prior_sigma(cls.name, log_replay.replay, ok, at))
        names += [f"{cls.name}.{name}" for name in effect.coefficient_names()]
    columns, sigma = np.hstack(columns), np.concatenate(sigma)
    prior = np.diag(np.sqrt(problem.noise_floor**2 * ok.sum() / problem.n_eff) / sigma)
    minimizer = Minimizer(trial, problem, names)
    minimizer.linearise(list(columns.T), np.ones(len(names)), problem.base_evaluation,
                        penalty=prior).refine(1 + STEPS)
    evaluation, _ = minimizer.refined
    calibrated = minimizer.model.copy()
    for cls in CALIBRATIONS:
        for parameter in calibrated.effect(cls.name).params.values():
            parameter.vary = False
    values = np.concatenate([calibrated.effect(cls.name).coefficients for cls in CALIBRATIONS])
    everywhere = np.zeros((len(ok), len(names)))
    everywhere[ok] = columns
    return BenchCalibration(calibrated, evaluation.payload, [cls.name for cls in CALIBRATIONS],
                       everywhere, prior, values, sigma)
