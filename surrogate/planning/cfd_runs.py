"""Where to run CFD next: the runs that would most reduce the maps' share of the Δp uncertainty
over a bench log.

The design criterion is integrated variance reduction (Emukit's IVR, BoTorch's qNIPV), weighted
by where the bench actually operates:

1. The model is replayed over the log. Each solved sample x says where the maps are asked (the
   flow map at its flow, the force map at its load pressure) and how the computed Δp answers
   their errors: Var Δp(x) = (g_C(x)·σ_C(x))² + (g_f(x)·σ_f(x))², with σ_C and σ_f the maps'
   calibrated standard deviations (ln C_d; relative flow force) and g the gains of
   :func:`surrogate.solver.uncertainty.sensitivity`.
2. Each map's error is treated as a Gaussian process over its dimensionless features z
   (:mod:`surrogate.features`, standardised over the log's states): cov(x, c) =
   s(x)·s(c)·exp(−|z_x − z_c|²/(2ℓ²)), with ℓ = :data:`CORRELATION_LENGTH` and s² = σ² − floor²
   the part of the calibrated variance more CFD runs can remove: the calibration's floor is the
   error that remains next to the samples (:mod:`surrogate.maps.sigma`), which no run
   removes.
3. A CFD run at c observes both maps there, up to the CFD's own scatter τ (the calibration's
   floor, at least :data:`CFD_SCATTER`). It lowers the error variance at x by
   cov(x, c)²/(σ(c)² + τ²), so the weighted gain of c is Σ_x g(x)²·cov(x, c)²/(σ(c)² + τ²),
   summed over both maps.
4. Runs are chosen greedily: the best candidate, then the best given that one (the covariances
   conditioned on it, a rank-one update), and so on: a batch that does not repeat itself.

The candidates are where the bench operates: the replayed states of the log, binned in opening,
flow, temperature and back pressure, their medians rounded to what a CFD engineer would set up
(0.01 mm, 0.5 L/min, 5 °C, 0.5 bar).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from ..data.loaders import BenchLog
from ..features import FeatureSpec
from ..fitting.residuals import LogReplay, replay_log
from ..maps.coverage import describe_all
from ..model import ValveModel
from ..points import OperatingPoints
from ..solver.uncertainty import sensitivity
from ..core.units import from_si, to_si

#: correlation length of the maps' errors in standardised features [-]
CORRELATION_LENGTH = 0.5
#: the smallest scatter a new CFD run is assumed to have, in ln units (the mesh study of the
#: paper's Table 4 moved Δp by up to 1.9 %, i.e. C_d by about 1 %)
CFD_SCATTER = 0.01
#: log samples used for the integral (every n-th solved one)
EVERY = 4
#: rounding of a suggested run: opening [mm], flow [L/min], temperature [°C], back pressure [bar]
ROUNDING = {"u_mm": 0.01, "q_lpm": 0.5, "temperature_C": 5.0, "p_B_bar": 0.5}
#: candidate bins: in ln u, in q, and in p_B [bar], per temperature set point
BINS = {"log_u": 24, "q": 8, "p_B": 3}


@dataclass(frozen=True)
class Suggestion:
    """The ranked CFD runs and what they buy.

    Attributes
    ----------
    runs : pandas.DataFrame
        One row per suggested run, best first: ``rank``, ``u_mm``, ``q_lpm``,
        ``temperature_C``, ``p_B_bar``, ``dp_bar`` (the maps' pressure drop there),
        ``variance_reduction_percent`` (of the log's map-implied Δp variance, given the runs
        above it), ``cumulative_percent`` and ``outside_samples`` (why the run lies outside the
        CFD samples; empty inside).
    log_replay : LogReplay
        The replay of the log the suggestion weighs.
    dp_std_rms : float
        RMS over the log of the Δp standard deviation the maps imply [Pa].
    """

    runs: pd.DataFrame
    log_replay: LogReplay
    dp_std_rms: float

    def to_json(self) -> dict:
        return {"dp_std_rms_bar": round(float(from_si(self.dp_std_rms, "bar")), 4),
                "runs": [{key: (value.item() if hasattr(value, "item") else value)
                          for key, value in row.items()}
                         for row in self.runs.to_dict("records")]}

    def format_text(self) -> str:
        lines = [f"The maps imply a Δp standard deviation of "
                 f"{from_si(self.dp_std_rms, 'bar'):.3f} bar RMS over the log. CFD runs that "
                 f"would reduce it most, best first:",
                 f"  {'rank':>4} {'u [mm]':>7} {'q [L/min]':>9} {'T [°C]':>7} {'p_B [bar]':>9} "
                 f"{'Δp [bar]':>8} {'gain [%]':>8} {'total [%]':>9}  why"]
        for r in self.runs.itertuples(index=False):
            lines.append(f"  {r.rank:>4} {r.u_mm:>7.2f} {r.q_lpm:>9.1f} {r.temperature_C:>7.0f} "
                         f"{r.p_B_bar:>9.1f} {r.dp_bar:>8.1f} "
                         f"{r.variance_reduction_percent:>8.1f} {r.cumulative_percent:>9.1f}  "
                         f"{r.outside_samples or 'inside the samples'}")
        lines.append("  (gain: share of the log's map-implied Δp variance the run removes, given "
                     "the runs above it)")
        return "\n".join(lines)


def suggest_cfd(model: ValveModel, log: BenchLog, runs: int = 8, *,
                log_replay: LogReplay | None = None) -> Suggestion:
    """The ``runs`` CFD runs that most reduce the maps' share of the Δp uncertainty over
    ``log`` (see the module docstring). ``model``'s maps must report an uncertainty."""
    if model.flow_map.calibration is None and model.force_map.calibration is None:
        raise ValueError(f"model {model.name!r} has maps without an uncertainty "
                         f"({model.flow_map.kind}); choose maps built from CFD samples")
    log_replay = log_replay or replay_log(model, log)
    replay = log_replay.replay
    ok = np.flatnonzero(replay.ok)[::EVERY]
    side = np.where(~replay.moving, 0.0, np.where(
        replay.u <= np.fmin(replay.band[0], replay.band[1]), 1.0, -1.0))
    held = (~replay.moving & model.has_friction) | (replay.u >= model.valve.U_max)
    gains = sensitivity(model, replay.points[ok], replay.u[ok], replay.dp[ok], side[ok],
                        held[ok])
    spec = FeatureSpec.for_valve(model.valve)
    log_terms = _map_terms(model, spec, gains.flow_query, gains.force_query)
    weights = (gains.flow_gain**2, gains.force_gain**2)
    total = float(np.nansum(replay.dp_std[ok][gains.index] ** 2))  # reducible or not

    # a flow map built from one back pressure's samples only (the grid's) learns nothing from
    # runs at others: its candidates are run there (the grid's force map would learn its
    # cavitation law from them, which the candidates' gains do not count)
    fixed = getattr(model.flow_map, "fixed_back_pressure", None)
    candidates = _candidates(replay.points[ok][gains.index], replay.u[ok][gains.index], fixed)
    fluid = model.valve.oil.state(candidates.temperature)
    q, p_B, u = candidates.q, candidates.p_B, candidates.u
    dp = model.flow_map.pressure_drop(q, p_B, u, fluid)
    candidate_terms = _map_terms(model, spec, (q, p_B, u, fluid), (p_B + dp, p_B, u, fluid))
    scale = _feature_scale(log_terms)

    chosen, gain_of = _greedy(log_terms, candidate_terms, weights, scale, runs)
    reasons = (model.flow_map.reasons_at_flow(q, p_B, u, fluid)
               | model.force_map.extrapolation_reasons(p_B + dp, p_B, u, fluid))
    table = pd.DataFrame({
        "rank": np.arange(1, len(chosen) + 1),
        "u_mm": from_si(u[chosen], "mm"),
        "q_lpm": from_si(q[chosen], "L/min"),
        "temperature_C": from_si(candidates.temperature[chosen], "degC"),
        "p_B_bar": from_si(p_B[chosen], "bar"),
        "dp_bar": from_si(dp[chosen], "bar"),
        "variance_reduction_percent": 100 * np.array(gain_of) / total,
        "cumulative_percent": 100 * np.cumsum(gain_of) / total,
        "outside_samples": describe_all(reasons[chosen]),
    })
    std = replay.dp_std
    rms = float(np.sqrt(np.nanmean(std[replay.ok] ** 2))) if std is not None else float("nan")
    return Suggestion(table, log_replay, rms)


@dataclass(frozen=True)
class _MapTerms:
    """One map at a set of states: features, the reducible part of the calibrated σ
    (sqrt(σ² − floor²)) and the scatter a new CFD run there would have [ln units]."""

    features: np.ndarray
    std: np.ndarray
    scatter: float


def _map_terms(model: ValveModel, spec: FeatureSpec, flow_query, force_query
               ) -> tuple[_MapTerms, _MapTerms]:
    flow_map, force_map = model.flow_map, model.force_map
    # the interpolation's σ alone (the calibration's): a new run reduces it, not the CFD's own
    # error, which the new run's mesh has too
    flow_std, force_std = (np.zeros(len(query[0])) if map_.calibration is None else
                           np.reshape(map_.calibration.std(*map_.calibration_inputs(*query)), -1)
                           for map_, query in ((flow_map, flow_query), (force_map, force_query)))
    return (_MapTerms(spec.flow_features(*flow_query), _reducible(flow_std, flow_map),
                      _scatter(flow_map)),
            _MapTerms(spec.force_features(*force_query), _reducible(force_std, force_map),
                      _scatter(force_map)))


def _reducible(std: np.ndarray, map_) -> np.ndarray:
    floor = 0.0 if map_.calibration is None else map_.calibration.floor
    return np.sqrt(np.maximum(std**2 - floor**2, 0.0))


def _scatter(map_) -> float:
    floor = 0.0 if map_.calibration is None else map_.calibration.floor
    return max(floor, CFD_SCATTER)


def _feature_scale(terms) -> tuple[np.ndarray, np.ndarray]:
    """Per map, the features' spread over the log's states (what 'standardised' means here)."""
    return tuple(np.where(t.features.std(axis=0) > 0, t.features.std(axis=0), 1.0)
                 for t in terms)


def _greedy(log_terms, candidate_terms, weights, scale, runs: int):
    """Greedy integrated variance reduction (module docstring, steps 3 and 4)."""
    states = []
    for log_map, candidate_map, spread in zip(log_terms, candidate_terms, scale):
        x = log_map.features / spread
        c = candidate_map.features / spread
        cross = np.exp(-_squared_distances(x, c) / (2 * CORRELATION_LENGTH**2))
        among = np.exp(-_squared_distances(c, c) / (2 * CORRELATION_LENGTH**2))
        states.append({
            "xc": log_map.std[:, None] * candidate_map.std[None, :] * cross,
            "cc": candidate_map.std[:, None] * candidate_map.std[None, :] * among,
            "noise": candidate_map.scatter**2,
        })
    chosen, gains = [], []
    for _ in range(min(runs, len(candidate_terms[0].std))):
        score = sum(w @ (s["xc"] ** 2) / (np.diag(s["cc"]) + s["noise"])
                    for w, s in zip(weights, states))
        score[chosen] = -np.inf
        best = int(np.argmax(score))
        chosen.append(best)
        gains.append(float(score[best]))
        for s in states:  # condition every covariance on a run at the chosen candidate
            denominator = s["cc"][best, best] + s["noise"]
            s["xc"] = s["xc"] - np.outer(s["xc"][:, best], s["cc"][best, :]) / denominator
            s["cc"] = s["cc"] - np.outer(s["cc"][:, best], s["cc"][best, :]) / denominator
    return chosen, gains


def _squared_distances(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.maximum(np.sum(a**2, 1)[:, None] + np.sum(b**2, 1)[None, :] - 2 * a @ b.T, 0.0)


@dataclass(frozen=True)
class _Candidates:
    u: np.ndarray
    q: np.ndarray
    temperature: np.ndarray
    p_B: np.ndarray


def _candidates(points: OperatingPoints, u: np.ndarray,
                fixed_back_pressure: float | None = None) -> _Candidates:
    """Candidate runs where the bench operates: the states binned, their medians rounded (at
    ``fixed_back_pressure`` [Pa] if given)."""
    p_B = points.p_B if fixed_back_pressure is None else np.full(len(u), fixed_back_pressure)
    frame = pd.DataFrame({
        "u_mm": from_si(u, "mm"), "q_lpm": from_si(points.q, "L/min"),
        "temperature_C": from_si(points.temperature, "degC"),
        "p_B_bar": from_si(p_B, "bar")})
    frame = frame[frame["u_mm"] > 0]
    frame["temperature_C"] = _rounded(frame["temperature_C"], ROUNDING["temperature_C"])
    frame["u_bin"] = pd.cut(np.log(frame["u_mm"]), BINS["log_u"], labels=False)
    frame["q_bin"] = pd.cut(frame["q_lpm"], BINS["q"], labels=False)
    frame["p_B_bin"] = pd.cut(frame["p_B_bar"], BINS["p_B"], labels=False)
    medians = frame.groupby(["temperature_C", "u_bin", "q_bin", "p_B_bin"]).median()
    runs = pd.DataFrame({column: _rounded(medians[column], step)
                         for column, step in ROUNDING.items() if column != "temperature_C"})
    runs["temperature_C"] = medians.index.get_level_values("temperature_C")
    runs = runs[(runs["u_mm"] > 0) & (runs["q_lpm"] > 0)].drop_duplicates()
    return _Candidates(to_si(runs["u_mm"].to_numpy(), "mm"), to_si(runs["q_lpm"].to_numpy(), "L/min"),
                       to_si(runs["temperature_C"].to_numpy(), "degC"),
                       to_si(runs["p_B_bar"].to_numpy(), "bar"))


def _rounded(values: pd.Series, step: float) -> pd.Series:
    return np.round(values / step) * step


def suggestion_figure(suggestion: Suggestion, model: ValveModel):
    """The log's operating points (opening over flow, shaded by the Δp standard deviation the
    maps imply) over the sampled openings, with the suggested runs numbered."""
    return operating_points_figure(suggestion.log_replay, model, suggestion.runs)


def operating_points_figure(log_replay, model: ValveModel, runs: pd.DataFrame | None = None):
    """Where the bench operates: the openings and flows of a replay (``log_replay``, with the maps'
    Δp standard deviation) over the CFD's sampled openings, and the suggested CFD ``runs``
    numbered, if any."""
    from matplotlib.figure import Figure

    replay = log_replay.replay
    ok = replay.ok
    figure = Figure(figsize=(9.5, 5.2))
    ax = figure.subplots()
    std = (np.zeros(len(replay.u)) if replay.dp_std is None else replay.dp_std)
    shown = ax.scatter(from_si(replay.points.q[ok], "L/min"), from_si(replay.u[ok], "mm"),
                       c=from_si(std[ok], "bar"), s=3, cmap="viridis", rasterized=True)
    figure.colorbar(shown, ax=ax, label="Δp standard deviation from the maps [bar]",
                    fraction=0.05, pad=0.02)  # a slot as narrow as the bar
    coverage = model.flow_map.coverage
    if coverage is not None:
        openings = from_si(coverage.openings, "mm")
        for opening in openings:
            ax.axhline(opening, color="0.5", linewidth=0.8, linestyle="--")
        ax.plot([], [], color="0.5", linewidth=0.8, linestyle="--", label="sampled openings")
    if runs is not None:
        ax.plot(runs["q_lpm"], runs["u_mm"], "*", color="tab:red", markersize=13,
                markeredgecolor="black", label="suggested CFD runs")
        for r in runs.itertuples(index=False):
            ax.annotate(str(r.rank), (r.q_lpm, r.u_mm), textcoords="offset points",
                        xytext=(7, 4), fontsize=9, color="tab:red", fontweight="bold")
    ax.set_yscale("log")
    if coverage is not None:  # the sampled openings as the ticks, in plain numbers
        ax.set_yticks(openings, [f"{opening:g}" for opening in openings])
        ax.minorticks_off()
    ax.set_xlabel("q [L/min]")
    ax.set_ylabel("piston opening u [mm]")
    ax.set_title(f"Where the bench operates ({model.flow_map.kind} maps)"
                 + (", and where to run CFD next" if runs is not None else ""))
    ax.legend(loc="lower right", fontsize=10)
    ax.grid(alpha=0.3, which="both")
    # fixed margins for its labels, which keep their size [inches], instead of the constrained
    # layout, which measured every label over again at each save (a third of its drawing)
    width, height = figure.get_size_inches()
    figure.subplots_adjust(left=_MARGINS["left"] / width, right=1 - _MARGINS["right"] / width,
                           bottom=_MARGINS["below"] / height, top=1 - _MARGINS["above"] / height)
    return figure


#: room [inches] beside the operating points' panel: its tick labels and label left, the
#: colour bar's right, the flow's below, the title above
_MARGINS = {"left": 0.85, "right": 0.75, "below": 0.55, "above": 0.35}
