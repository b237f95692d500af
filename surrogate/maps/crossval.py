"""Cross-validation of flow and force maps: how wrong a map kind is on CFD runs it did not see,
and the calibration of its uncertainty that follows.

Every kind is trained (or, for the grid, built) on part of the samples and asked about the rest,
in four schemes:

* **k-fold by sweep**: the sweeps (one temperature, opening and back pressure each) in five folds;
* **leave one opening out**: each interior opening of the main set in turn;
* **leave one temperature out**: each temperature in turn (two of them are extrapolations in ν);
* **back-pressure set out**: trained on the reference back pressure, asked about the others.

For each left-out sample the errors are the relative errors of C_d at the sample's flow (δln C_d,
which is δln q at its pressure drop up to the map's slope) and of the flow force at its pressure
drop, together with the kind's own spread and the distance to the training data there; a
:class:`~surrogate.maps.sigma.SigmaCalibration` fitted to all of them makes the kind's ±2σ bands
honest, and the coverage per scheme says whether they are.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np
import pandas as pd

from ..data.loaders import CfdSamples
from ..features import FeatureSpec
from ..fluid import FluidState
from ..valve import ValveParameters
from . import splits
from .sigma import SigmaCalibration, coverage_of
from .cfd_error import FORCE_CFD_ERROR, flow_cfd_error, mesh_bias_share
from .registry import MAP_KINDS, cross_validation_summary, map_kind

SCHEMES = ("k-fold by sweep", "leave one opening out", "leave one temperature out",
           "back-pressure set out")
K_FOLDS = 5
FOLD_SEED = 0


@dataclass(frozen=True)
class Fold:
    """One training set and the samples it is asked about."""

    scheme: str
    label: str
    train: np.ndarray
    test: np.ndarray


def folds(frame: pd.DataFrame, *, back_pressure_by_opening: bool = False) -> list[Fold]:
    """Every fold of the four schemes (:data:`SCHEMES`), deterministic.

    ``back_pressure_by_opening`` asks about the back-pressure set one opening at a time, the
    rest of the set in the training, instead of training on the reference back pressure alone:
    for a map that learns the back pressure's effect from the set itself (the grid's
    :class:`~.cavitation.CavitationLaw`), which without the set has nothing to be judged on.
    """
    keys = splits.sweep_keys(frame).to_numpy()
    order = np.random.default_rng(FOLD_SEED).permutation(np.unique(keys))
    result = []
    for index in range(K_FOLDS):
        test = np.isin(keys, order[index::K_FOLDS])
        result.append(Fold(SCHEMES[0], f"fold {index + 1}", ~test, test))
    result += [Fold(SCHEMES[1], label, train, test)
               for label, train, test in splits.leave_one_opening_out(frame)]
    result += [Fold(SCHEMES[2], label, train, test)
               for label, train, test in splits.leave_one_temperature_out(frame)]
    if back_pressure_by_opening:
        result += [Fold(SCHEMES[3], label, train, test)
                   for label, train, test in splits.back_pressure_set_by_opening(frame)]
    elif splits.back_pressure_set(frame).any():
        result.append(Fold(SCHEMES[3], "back-pressure set", splits.main_set(frame),
                           splits.back_pressure_set(frame)))
    return result


def errors_on(flow_map, force_map, frame: pd.DataFrame, valve: ValveParameters) -> pd.DataFrame:
    """The maps' errors at the samples of ``frame`` (one row each), with what their calibrated
    standard deviation is made of there (``calibration_inputs``: own spread, distances from the
    data as columns ``<map>_distance:<name>``)."""
    spec = FeatureSpec.for_valve(valve)
    fluid = FluidState(frame["nu"].to_numpy(), frame["rho"].to_numpy())
    q, p_L, p_B, u = (frame[name].to_numpy() for name in ("q", "p_L", "p_B", "u"))
    dp = flow_map.pressure_drop(q, p_B, u, fluid)
    flow_force = force_map.flow_force(p_L, p_B, u, fluid)
    flow_force_true = frame["f_sim"].to_numpy() - spec.uniform_force(p_L, p_B)
    columns = {
        "case": frame["case"].to_numpy(),
        # δln C_d at the sample's flow: Δp ∝ C_d^−2
        "discharge_error": 0.5 * np.log((p_L - p_B) / dp),
        "q_error": flow_map.flow(p_L, p_B, u, fluid) / q - 1.0,
        "force_error": flow_force / flow_force_true - 1.0,
    }
    for name, inputs in (("flow", flow_map.calibration_inputs(q, p_B, u, fluid)),
                         ("force", force_map.calibration_inputs(p_L, p_B, u, fluid))):
        spread, distances = inputs
        columns[f"{name}_spread"] = np.zeros(len(frame)) if spread is None else spread
        for key, distance in distances.items():
            columns[f"{name}_distance:{key}"] = distance
    return pd.DataFrame(columns)


def _distances(errors: pd.DataFrame, name: str) -> dict[str, np.ndarray]:
    prefix = f"{name}_distance:"
    return {column[len(prefix):]: errors[column].to_numpy() for column in errors
            if column.startswith(prefix)}


def cross_validate(samples: CfdSamples, valve: ValveParameters,
                   fit_maps: Callable[[np.ndarray], tuple], *,
                   progress: Callable[[str], None] = lambda message: None,
                   workers: int = 1, back_pressure_by_opening: bool = False) -> pd.DataFrame:
    """The errors of the maps ``fit_maps(train_mask)`` returns, on every fold's left-out
    samples: one row per (fold, sample), see :func:`errors_on`; ``back_pressure_by_opening``
    as :func:`folds`.

    ``workers`` > 1 runs folds in that many fresh processes of one thread each (the learned
    kinds' training holds the interpreter); ``fit_maps`` must then be picklable (a module-level
    function, or a :func:`functools.partial` of one).
    """
    every = folds(samples.frame, back_pressure_by_opening=back_pressure_by_opening)
    jobs = [(fit_maps, samples.frame, valve, fold) for fold in every]
    parts = [None] * len(jobs)

    def report(done: int, index: int) -> None:
        progress(f"cross-validation {done}/{len(every)} done: {every[index].scheme}, "
                 f"{every[index].label}")

    if workers > 1:
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor, as_completed

        # fresh interpreters: a forked copy of a process that already ran PyTorch's thread pool
        # can hang
        context = multiprocessing.get_context("spawn")
        with ProcessPoolExecutor(workers, mp_context=context,
                                 initializer=_one_thread) as pool:
            futures = {pool.submit(_run_fold, job): index for index, job in enumerate(jobs)}
            for done, future in enumerate(as_completed(futures), start=1):
                parts[futures[future]] = future.result()
                report(done, futures[future])
    else:
        for index, job in enumerate(jobs):
            parts[index] = _run_fold(job)
            report(index + 1, index)
    return pd.concat(parts, ignore_index=True)


def _one_thread() -> None:
    """Worker start-up: one math thread each, the workers being the parallelism (two workers
    with two BLAS threads each on two cores run four times slower than one)."""
    import os

    from threadpoolctl import threadpool_limits

    os.environ["OMP_NUM_THREADS"] = "1"  # read by PyTorch when a training imports it
    threadpool_limits(1)  # the BLAS NumPy already loaded


def _run_fold(job) -> pd.DataFrame:
    fit_maps, frame, valve, fold = job
    flow_map, force_map = fit_maps(fold.train)
    result = errors_on(flow_map, force_map, frame[fold.test], valve)
    return result.assign(scheme=fold.scheme, fold=fold.label)


def calibrate(errors: pd.DataFrame, *, use_spread: bool, samples: CfdSamples | None = None,
              powers: tuple[Mapping[str, float], Mapping[str, float]] = ({}, {}),
              known: tuple | None = None, each_power: tuple[bool, bool] = (False, False)
              ) -> tuple[SigmaCalibration, SigmaCalibration]:
    """The flow and force calibrations that make the cross-validated errors most likely, each
    scheme weighted alike, with ±2σ holding 90-98 % of every scheme's errors
    (:meth:`~surrogate.maps.sigma.SigmaCalibration.fit`). Given the CFD ``samples`` the errors
    were made on, the meshes' biases they carry are known variance, not the map's
    (:func:`meshes_in_errors`). ``powers``: the (flow, force) powers given per distance, not
    fitted (default none: a kind's :attr:`~.registry.MapKind.calibration_powers`).
    ``known``: the (flow, force) known variance per error [ln units², None: none], in place of
    :func:`meshes_in_errors`' (a grid's own account of the meshes it bridged); ``each_power``:
    (flow, force) True to fit each distance a power of its own."""
    weights = 1.0 / errors.groupby("scheme")["case"].transform("size").to_numpy()
    if known is None:
        known = (None, None) if samples is None else meshes_in_errors(errors, samples)
    return tuple(SigmaCalibration.fit(errors[error], errors[f"{name}_spread"],
                                 _distances(errors, name), weights=weights,
                                 use_spread=use_spread, groups=errors["scheme"].to_numpy(),
                                 known=variance, powers=given, each_power=each)
                 for (name, error), variance, given, each in zip(
                     (("flow", "discharge_error"), ("force", "force_error")), known, powers,
                     each_power))


def meshes_in_errors(errors: pd.DataFrame, samples: CfdSamples) -> tuple[np.ndarray, np.ndarray]:
    """The variance [ln units²] the CFD meshes' own biases put into each cross-validated error
    (flow, force): at an opening left out, its mesh's bias and the bridged neighbours'
    (σ_CFD²·(1 + share²), :func:`.cfd_error.mesh_bias_share` of the openings left in); 0 where
    the training kept the sample's mesh (a sweep, a temperature or the back-pressure set out).
    σ_CFD of the flow is what the samples estimate of their own meshes
    (:func:`.cfd_error.flow_cfd_error`)."""
    carried = meshes_carried(errors, samples, (errors["scheme"] == SCHEMES[1]).to_numpy())
    return flow_cfd_error(samples.frame) ** 2 * carried, FORCE_CFD_ERROR ** 2 * carried


def meshes_carried(errors: pd.DataFrame, samples: CfdSamples, without: np.ndarray
                   ) -> np.ndarray:
    """How many meshes' biases (in units of one's variance) each cross-validated error carries
    where its fold's map lacked the sample's opening (``without``, a mask over ``errors``): its
    own mesh's and the bridged neighbours', 1 + share² (:func:`.cfd_error.mesh_bias_share` of
    the openings left in); 0 elsewhere."""
    frame = samples.frame.set_index("case")
    u = frame.loc[errors["case"], "u"].to_numpy()
    openings = np.unique(frame["u"].round(12))
    carried = np.zeros(len(errors))
    for index in np.flatnonzero(without):
        kept = openings[~np.isclose(openings, u[index], rtol=0, atol=1e-12)]
        carried[index] = 1.0 + mesh_bias_share(kept, np.array([u[index]]))[0] ** 2
    return carried


def standard_deviations(errors: pd.DataFrame, flow: SigmaCalibration, force: SigmaCalibration):
    """The calibrated standard deviations (of ln C_d, of the flow force) at each row."""
    return tuple(np.asarray(calibration.std(errors[f"{name}_spread"], _distances(errors, name)))
                 for name, calibration in (("flow", flow), ("force", force)))


def summary(errors: pd.DataFrame, flow: SigmaCalibration, force: SigmaCalibration, *,
            samples: CfdSamples | None = None, known: tuple | None = None) -> dict:
    """Per scheme: relative RMS error of q and of the flow force, and the share of left-out
    samples inside the calibrated ±2σ bands (of ln C_d, i.e. of q at its Δp, and of the flow
    force); given the ``samples``, σ with the meshes' biases the errors carry
    (:func:`meshes_in_errors`), as the calibration was fitted, or with the (flow, force)
    ``known`` variance the calibration was given instead (None: none)."""
    flow_std, force_std = standard_deviations(errors, flow, force)
    if known is None and samples is not None:
        known = meshes_in_errors(errors, samples)
    if known is not None:
        flow_known, force_known = (np.zeros(len(errors)) if variance is None else variance
                                   for variance in known)
        flow_std, force_std = np.sqrt(flow_std ** 2 + flow_known), np.sqrt(force_std ** 2
                                                                            + force_known)
    result = {}
    for scheme in SCHEMES:
        at = (errors["scheme"] == scheme).to_numpy()
        if not at.any():
            continue
        part = errors[at]
        result[scheme] = {
            "samples": int(at.sum()),
            "q_rel_rmse": float(np.sqrt(np.mean(part["q_error"] ** 2))),
            "flow_force_rel_rmse": float(np.sqrt(np.mean(part["force_error"] ** 2))),
            "q_coverage_2sigma": coverage_of(part["discharge_error"], flow_std[at]),
            "flow_force_coverage_2sigma": coverage_of(part["force_error"], force_std[at]),
        }
    return result


def flow_force_score(summary_of_kind: dict | None) -> float:
    """One number to rank map kinds by: the flow-force relative RMS error averaged over the
    schemes (nan without a summary). The flow force decides the computed Δp (1 N moves it by
    about 1 bar on the shipped valve); the flow maps of every kind are within a few per cent of
    each other's accuracy, and a floating piston absorbs their error."""
    if not summary_of_kind:
        return float("nan")
    return float(np.mean([row["flow_force_rel_rmse"] for row in summary_of_kind.values()]))


def most_accurate_kind(valve: ValveParameters, kinds=None) -> tuple[str, dict[str, float]]:
    """The map kind built from the shipped CFD samples whose flow force is the most accurate by
    cross-validation (:func:`flow_force_score`), and every kind's score."""
    kinds = kinds or [name for name, kind in MAP_KINDS.items() if kind.accuracy is not None]
    scores = {kind: flow_force_score(cross_validation_summary(map_kind(kind).source(), valve))
              for kind in kinds}
    ranked = [kind for kind in kinds if np.isfinite(scores[kind])]
    if not ranked:
        raise ValueError("no map kind has a cross-validation summary")
    return min(ranked, key=scores.get), scores
