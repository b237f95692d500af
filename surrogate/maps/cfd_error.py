"""The CFD's own error: what no map fitted to the samples can see, and every map's σ carries.

A CFD result is a simulator's output, not the valve (Kennedy and O'Hagan's discrepancy). With one
mesh per opening, each opening's samples share a bias of their own: the paper's mesh study
(Table 4) moved Δp by −1.84 to +1.86 % when the cells at 0.10 mm were refined from 1.7 to 3.1
million, and its choice between two cavitation models moved f_sim by 1.06 %, a few per cent of
the flow-force part of f_sim. A map fitted to the samples reproduces that bias exactly, and
cross-validation, which scores a map against samples it did not see, cannot see it: a GP then
called its flow certain to 0.05 % where it was 0.3 % off a virtual valve
(``eval/valve_coverage.py``).

How large a mesh's bias is, two things say: the mesh study, and how the shipped samples'
openings (one mesh each) scatter about a smooth trend in ln u, which no map's interpolation
error and no flow physics would bend opening by opening. Each is an estimate of one variance on
its own degrees of freedom; σ_CFD of Δp pools them (:func:`pooled_dp_error`: 1.3 %, where the
mesh study alone said 1.6 % and the samples alone 0.5 %), computed from the shipped samples and
kept in the package (:data:`SHIPPED_CFD_ERROR`).

So every map built from CFD samples reports σ² = σ_interpolation² + σ_CFD²: the first from its
calibration (:mod:`.sigma`, fitted on cross-validation), the second from here, as
:attr:`~.base.FlowMap.cfd_error` and :attr:`~.base.ForceMap.cfd_error` in the calibrations' ln
units. σ at a sampled opening is then never smaller than the CFD's own error there. The
workbench's allowance for the maps' error (:mod:`surrogate.fitting.discrepancy`) reads the same σ.

σ_CFD of the flow is the samples' own: a user's CFD of another valve, or of this one on other
meshes, scatters as its own meshes do. Grid maps compute it from the samples they interpolate
(:func:`flow_cfd_error`, :attr:`.grid.GridUncertainty.flow_cfd_error`); a learned kind's training
computes it from the samples it learns and records it in the surrogate's manifest
(``flow.cfd_error``), where its calibration took the meshes' biases out of its errors with it
(:func:`.crossval.meshes_in_errors`). A map without a record of its own (the committed
surrogates, written before the manifest kept it, were trained on the shipped samples) uses the
shipped samples' (:data:`FLOW_CFD_ERROR`). The flow force's has no estimate from the samples
and is the same for every map.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd

from ..core.paths import SHIPPED_CFD_SAMPLES, SHIPPED_SURROGATES
from ..core.units import P_ATM
from .coverage import Coverage

#: Δp's change with mesh refinement at u = 0.10 mm, q = 1, 3, 6, 9, 12 L/min [%] (Table 4)
MESH_STUDY_DP_CHANGE = (1.53, 1.86, -0.88, -1.64, -1.84)

#: parameters of the smooth trend of ln Δp in ln u (a quadratic) about which the openings' meshes
#: scatter (:func:`opening_scatter`)
TREND_DEGREE = 2


def mesh_study_variance() -> tuple[float, int]:
    """(s², ν): the variance of the relative Δp error of a mesh [1²] that the paper's mesh study
    (:data:`MESH_STUDY_DP_CHANGE`) estimates, the mean square of its changes (about zero, not
    about their mean: the refined mesh is the reference, no mean is fitted), on one degree of
    freedom per change. The five are one opening's at five flows, not five meshes' biases;
    counted as five, the study weighs in the pool as much as it can, on the wide side."""
    change = np.asarray(MESH_STUDY_DP_CHANGE) / 100.0
    return float(np.mean(change ** 2)), len(change)


def opening_scatter(frame: pd.DataFrame) -> tuple[float, int]:
    """(s², ν): the variance of each opening's mesh bias in ln Δp [1²] that CFD ``samples``
    estimate by how their openings scatter about a smooth trend, and its degrees of freedom.

    ``frame`` in SI (:class:`~surrogate.data.CfdSamples`' frame). At the most sampled back
    pressure, every (temperature, flow) is a slice; within each run of openings not parted by an
    unsampled gap (:meth:`.coverage.Coverage.gaps`), ln Δp of a slice with more openings than
    the trend has parameters is fitted by a quadratic in ln u, and each opening's mesh bias is
    its mean residual over its slices (one mesh serves all its temperatures and flows; on the
    shipped samples its residuals differ by 0.24 % RMS between temperatures, against 0.73 %
    between openings and flows). A quadratic takes up three of the openings' biases, so
    s² = Σ mean residual² / (openings − 3), on openings − 3 degrees of freedom per run. The
    flow-dependent scatter left in the means (about 0.6 %/√7) is kept: it errs on the wide side.
    (0.0, 0) where no run has enough openings."""
    frame = frame[frame["q"] > 0]
    back = frame["p_B"].round(-2).mode().iloc[0]
    frame = frame[np.isclose(frame["p_B"], back, rtol=0, atol=50.0)].assign(
        log_dp=lambda f: np.log(f["p_L"] - f["p_B"]), log_u=lambda f: np.log(f["u"]))
    openings = np.unique(frame["u"].round(12))
    edges = [high for _, high in Coverage.of_samples(frame).gaps()]
    runs = np.split(openings, np.searchsorted(openings, edges))
    squares, freedom = 0.0, 0
    for run in (run for run in runs if len(run) > TREND_DEGREE + 1):
        part = frame[np.isin(frame["u"].round(12), run)]
        residuals = []
        for _, sweep in part.groupby(["temperature", "q"]):
            if sweep["u"].nunique() > TREND_DEGREE + 1:
                trend = np.polyfit(sweep["log_u"], sweep["log_dp"], TREND_DEGREE)
                residuals.append(sweep["log_dp"] - np.polyval(trend, sweep["log_u"]))
        biases = pd.concat(residuals).groupby(part["u"].round(12)).mean()
        squares += float(np.sum(biases ** 2))
        freedom += len(biases) - (TREND_DEGREE + 1)
    return (squares / freedom, freedom) if freedom > 0 else (0.0, 0)


def flow_cfd_error(frame: pd.DataFrame) -> float:
    """σ_CFD of ln C_d that CFD samples ``frame`` (SI) estimate for their own meshes [1]: half
    the pooled relative Δp error (:func:`pooled_dp_error`), as ln C_d = −ln Δp / 2 at a given
    flow. For the shipped samples, :data:`FLOW_CFD_ERROR` to the bit."""
    return pooled_dp_error(frame) / 2.0


def dp_error_estimates(frame: pd.DataFrame) -> dict:
    """Both estimates of one mesh's relative Δp error, {"mesh study": …, "samples": …}, each
    {"sigma": s [1], "freedom": ν}, and {"pooled": σ [1]} (:func:`pooled_dp_error`)."""
    estimates = {"mesh study": mesh_study_variance(), "samples": opening_scatter(frame)}
    record = {name: {"sigma": float(np.sqrt(s2)), "freedom": int(nu)}
              for name, (s2, nu) in estimates.items()}
    return {**record, "pooled": _pooled(estimates.values())}


def pooled_dp_error(frame: pd.DataFrame) -> float:
    """One σ of the relative Δp error each opening's mesh puts on the samples [1]: the mesh
    study's estimate (:func:`mesh_study_variance`) and the samples' own
    (:func:`opening_scatter`) pooled by their degrees of freedom,
    √((ν₁s₁² + ν₂s₂²)/(ν₁ + ν₂)). Two views of one bias: refining one opening's mesh, and how
    the meshes of many openings scatter about a trend no mesh bias would bend (the samples
    cannot see a bias that all meshes share, nor can a virtual valve or any map)."""
    return _pooled([mesh_study_variance(), opening_scatter(frame)])


def _pooled(estimates) -> float:
    """√(Σν·s² / Σν) of (s², ν) estimates of one variance."""
    estimates = list(estimates)
    freedom = sum(nu for _, nu in estimates)
    return float(np.sqrt(sum(nu * s2 for s2, nu in estimates) / freedom))


#: where the Δp error pooled from the shipped samples is kept: inside the package, which a wheel
#: carries without the samples (``python training/train.py --kinds grid`` writes it; a test
#: recomputes it from the samples and compares)
SHIPPED_CFD_ERROR = SHIPPED_SURROGATES / "cfd" / "cfd_error.json"


def write_dp_error(path: str | Path, frame: pd.DataFrame, samples_sha256: str) -> dict:
    """Write :func:`dp_error_estimates` of the CFD samples ``frame`` (SI) to ``path`` (JSON),
    with the SHA-256 of their file; returns what was written."""
    record = {"cfd_sha256": samples_sha256, "dp": dp_error_estimates(frame)}
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    Path(path).write_text(json.dumps(record, indent=2) + "\n")
    return record


def shipped_dp_error(path: str | Path = SHIPPED_CFD_ERROR) -> float:
    """The pooled relative Δp error of the shipped samples [1], as :func:`write_dp_error` kept
    it at ``path``; without that file (a checkout before ``train.py`` first wrote it), computed
    from the shipped samples."""
    try:
        return float(json.loads(Path(path).read_text())["dp"]["pooled"])
    except (OSError, ValueError, KeyError):
        from ..data.loaders import load_cfd_samples  # a checkout's samples; a wheel has none

        return pooled_dp_error(load_cfd_samples(SHIPPED_CFD_SAMPLES).frame)


#: one σ of the relative error each opening's mesh puts on Δp at a given flow and on the flow
#: force [1]. For Δp, the mesh study and the shipped samples pooled (:func:`pooled_dp_error`:
#: 1.59 % on 5 degrees of freedom and 0.53 % on 3, 1.30 %); the virtual valves'
#: (:class:`surrogate.synthetic.mismatch.MapMismatch`) stay the mesh study's. For the flow
#: force, the cavitation model's 1.06 % of f_sim is 1.4 to 4.5 % of the flow force at 0.10 mm,
#: 40 °C (no mesh study of it to pool with)
CFD_ERROR = {"dp": shipped_dp_error(), "flow force": 0.025}

#: the same in the calibrations' units: ln C_d (= −ln Δp / 2 at a given flow) and the relative
#: flow force; a map built from other samples carries its samples' own of the flow
#: (:func:`flow_cfd_error`)
FLOW_CFD_ERROR = CFD_ERROR["dp"] / 2.0
FORCE_CFD_ERROR = CFD_ERROR["flow force"]

#: one σ of ln C_d at the middle of an unsampled gap between openings (no CFD run there) [1]:
#: how far the valve may stray from a smooth bridge where no mesh says anything, and which
#: smooth bridge. The first is the virtual valves' own prior for the gap (a bump of 3 % in Δp,
#: :attr:`surrogate.synthetic.mismatch.MapMismatch.gap_dp`: 1.5 % in ln C_d); the second how
#: far the smooth bridges through the samples differ at the shipped 0.20–0.63 mm gap's middle:
#: the NN's and the GP's by 2.0–2.4 %, two draws of a σ of 2.2/√2 = 1.6 %. In quadrature,
#: 2.2 %. The grid's bridge (a power law, 6–7 % below both there) is an interpolation rule whose
#: error its own calibration measures and carries: its σ grows with the span it bridges. How it
#: joins a map's σ, :func:`valve_sigma` says; it was 3 % while the GP's bridge lay 3.5 % below
#: the NN's (docs/maps.md)
GAP_FLOW_ERROR = 0.022

#: one σ of the relative flow-force error at the middle of an unsampled gap [1], as the flow's
#: (:data:`GAP_FLOW_ERROR`): what the valve's flow force may do where no mesh ran, the virtual
#: valves' own prior for the gap (a bump of 5 %, :attr:`surrogate.synthetic.mismatch.
#: MapMismatch.gap_force`), and which smooth bridge is the valve's: the NN's and the GP's flow
#: forces differ by 5.2 % (median; 7.6 % at the 90th percentile) at the shipped gap's middle, two
#: draws of a σ of 3.7 %. In quadrature, 6.2 %. With 5 % alone the GP's ±2σ held 82 % of the
#: virtual valves' flow force there and the NN's 88 % (over 60 valves; ``eval/valve_coverage.py``)
GAP_FORCE_ERROR = float(np.hypot(0.05, 0.052 / np.sqrt(2.0)))

#: one σ per unit of ln(u₀/u) of the exponent k by which the valve's Δp at a flow, and its
#: flow-force fraction, may change as (u/u₀)^k below the smallest sampled opening u₀ [1]. No mesh
#: says how the characteristic goes on toward the seat, where a bench log spends much of its
#: time, and every kind continues it by a rule of its own (the grid holds C_d and follows the
#: flow-force fraction's power of u; a GP's kernel and the networks' features do what they do).
#: The same prior as the virtual valves'
#: (:attr:`surrogate.synthetic.mismatch.MapMismatch.seat_exponent`). A floor of σ, not a term
#: beside it: the grid's calibrated σ grows beyond its openings by itself
SEAT_EXPONENT_ERROR = 0.1

#: the same in the calibrations' units per unit of ln(u₀/u): ln C_d (half of ln Δp at a given
#: flow) and the relative flow force. The flow's also holds which continuation toward the seat
#: is the valve's: the kinds' go on by rules of their own, and the learned kinds' ln C_d differ
#: by about 5 % per unit below the shipped samples' smallest opening (the GP's and the NN's at
#: 0.015 mm, 6-8.5 % at 20-200 bar), two draws of a σ of 3.5 %; in quadrature with the valves'
#: own 5 %, 6.1 % (issue 42, eighth round: with 5 % alone the NN's ±2σ held 77 % of the virtual
#: valves' q there, the GP's 84 %; ``eval/valve_coverage.py``)
SEAT_FLOW_ERROR = float(np.hypot(SEAT_EXPONENT_ERROR / 2.0, 0.035))
SEAT_FORCE_ERROR = SEAT_EXPONENT_ERROR

#: one σ of the relative flow-force error the CFD's cavitation model adds per unit of
#: |ln(absolute back pressure / the samples' central one)| [1]. Cavitation at the throttling edge
#: changes the pressure on the piston, more the lower the back pressure; the paper's choice
#: between two cavitation models moved f_sim by 1.06 % at one back pressure, and nothing in the
#: samples says the model errs alike at the others. A map fitted to samples at a few back
#: pressures inherits the model's error at each, growing away from the central one
#: (:class:`surrogate.synthetic.mismatch.CavitationFlowForce` is the virtual valve's version)
CAVITATION_FORCE_ERROR = 0.03


def valve_sigma(calibrated, meshes, gap, *, gap_is_floor: bool = False) -> np.ndarray:
    """σ of a map against the valve [ln units] from its ``calibrated`` σ (its error against the
    CFD), the CFD meshes' own error as the map carries them (``meshes``) and what no mesh says
    across an unsampled gap (``gap``, :func:`gap_error`), all in ln units.

    The meshes' error and the calibrated σ are independent and add in quadrature. Across a gap,
    the map's error against the valve is how far the valve strays from the map's bridge where no
    mesh ran. For a map whose calibration never bridged a span that wide (the learned kinds',
    whose distances are to the nearest sample in their features), the gap's prior says it: a
    term beside the calibrated σ, never less than the meshes' own. A map whose calibration was
    measured across such spans (``gap_is_floor``: the grid's, fitted to openings left out of its
    bridge, √((x − a)(b − x)) up to 0.89 in ln u where the gap's middle is 0.57) already holds an
    estimate of that, its own: the prior is then a
    floor under it, not a second count of one error (in quadrature, the grid's ±2σ held 99 % of
    the virtual valves' flow force across the gap; ``eval/valve_coverage.py``)."""
    if gap_is_floor:
        return np.maximum(np.hypot(calibrated, meshes), gap)
    return np.hypot(calibrated, np.maximum(meshes, gap))


def gap_error(gaps: list[tuple[float, float]], u, size: float = GAP_FLOW_ERROR) -> np.ndarray:
    """σ [ln units] that an unsampled gap adds at openings ``u`` [m]: ``size``·sin(π·t), t the
    position across the gap in ln u (0 at the openings that bound it), 0 outside every gap."""
    log_u = _log_opening(u)
    return sum((size * np.sin(np.pi * _position(log_u, low, high)) for low, high in gaps),
               np.zeros(log_u.shape))


def seat_error(openings, u, size: float = SEAT_FLOW_ERROR) -> np.ndarray:
    """σ [ln units] below the smallest of the sampled ``openings`` u₀ [m] at openings ``u`` [m]:
    ``size``·ln(u₀/u), 0 from u₀ up."""
    smallest = np.log(np.min(openings)) if len(openings) else -np.inf
    return size * np.maximum(smallest - _log_opening(u), 0.0)


def mesh_bias_share(openings, u) -> np.ndarray:
    """How much of one mesh's bias a map carries at openings ``u`` [m] [1]: 1 at a sampled
    opening and beyond the end ones; between two, the map bridges both meshes' biases, which
    are independent, (1 − t)·b₁ + t·b₂ with t the position in ln u, so √((1 − t)² + t²) of one
    (1/√2 halfway)."""
    log_u = _log_opening(u)
    openings = np.sort(np.asarray(openings, float))
    share = np.ones(log_u.shape)
    for low, high in zip(openings, openings[1:]):  # 0 outside the pair: t is 0 or 1 there
        t = _position(log_u, low, high)
        share += np.sqrt((1.0 - t) ** 2 + t ** 2) - 1.0
    return share


def _log_opening(u) -> np.ndarray:
    with np.errstate(divide="ignore"):
        return np.log(np.asarray(u, float))


def _position(log_u: np.ndarray, low: float, high: float) -> np.ndarray:
    """Where ln u lies between the openings ``low`` and ``high`` [m], clipped to [0, 1] (the
    ONNX export computes the same, :func:`surrogate.export.onnx_maps._position`)."""
    return np.clip((log_u - np.log(low)) / np.log(high / low), 0.0, 1.0)


def cavitation_error(central_back_pressure: float | None, p_B,
                     size: float = CAVITATION_FORCE_ERROR) -> np.ndarray:
    """Relative σ of the flow force [1] that the cavitation model adds at back pressures ``p_B``
    [Pa]: ``size``·|ln((p_B + p_atm)/(p_c + p_atm))|, p_c the samples' central back pressure
    [Pa] (0 everywhere when there is none)."""
    p_B = np.asarray(p_B, float)
    if central_back_pressure is None:
        return np.zeros(p_B.shape)
    return size * np.abs(np.log((np.maximum(p_B, 0.0) + P_ATM)
                                / (central_back_pressure + P_ATM)))


__all__ = ["CAVITATION_FORCE_ERROR", "CFD_ERROR", "FLOW_CFD_ERROR", "FORCE_CFD_ERROR",
           "GAP_FLOW_ERROR", "MESH_STUDY_DP_CHANGE", "SEAT_EXPONENT_ERROR", "SEAT_FLOW_ERROR",
           "SEAT_FORCE_ERROR", "SHIPPED_CFD_ERROR", "TREND_DEGREE", "cavitation_error",
           "dp_error_estimates", "flow_cfd_error", "gap_error", "mesh_bias_share",
           "mesh_study_variance", "opening_scatter", "pooled_dp_error", "seat_error",
           "shipped_dp_error", "valve_sigma", "write_dp_error"]
