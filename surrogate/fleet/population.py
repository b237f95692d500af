"""A fleet's population: how its valves' fitted figures scatter, and which valves stand out.

Every statistic here is robust: a few faulty valves must not widen the yardstick they are
measured by.

* **Centre and spread**: the median and 1.4826 × the median absolute deviation (MAD), which is
  the standard deviation for a Gaussian population and ignores a minority of outliers. A spread
  is never taken below the figure's typical standard error (the median over valves): a
  parameter that sits on its bound in most valves (a leakage of zero) has a MAD of zero, and
  any valve that moved off it by its own uncertainty would look infinitely far away.
* **Correlations**: Spearman's rank correlation, which a few outliers barely move.
* **Outliers**: the robust Mahalanobis distance of each valve's figures from the population's.
  The figures are standardised by median and spread; their location and covariance are then
  estimated by the Minimum Covariance Determinant (scikit-learn's
  :class:`~sklearn.covariance.MinCovDet`, reweighted) over the most concentrated three quarters
  of the valves (:data:`MCD_SUPPORT`), which the outliers themselves do not pull. With too few
  valves for that (fewer than :data:`VALVES_PER_FIGURE` per figure, or than
  :data:`MIN_VALVES_FOR_COVARIANCE`) the median/MAD scores are used with the figures' rank
  correlations (Spearman's ρ as a Gaussian correlation, 2·sin(πρ/6)). A figure whose spread is
  its standard error (its scatter lies within its uncertainty) counts as independent of the
  others. A valve is an outlier when its squared distance exceeds the quantile
  :data:`OUTLIER_LEVEL` of the distance of a new valve from a Gaussian population of that many
  valves, p(n−1)(n+1)/(n(n−p))·F(p, n−p) (Hotelling's), not the asymptotic χ²(p). Simulated
  Gaussian fleets of 50 valves in 4 correlated figures had 4 % false flags with MCD's default
  estimate (half the valves) and the χ² cutoff, 0.7 % with three quarters and this cutoff, and
  0.2 % with the rank correlations, against the nominal 0.1 %; at 100 and 200 valves MCD's
  were 0.25 % and 0.2 %, and it finds more of the valves planted 5σ off in one figure (99 %
  against 94 % at 100 valves). tests/fleet/test_fleet.py keeps the false flags within 1 %.
* **Why a valve stands out**: the figures whose removal brings its distance back within the
  cutoff, the one that lowers it most first (the distance in the remaining figures, against
  the cutoff of as many), each with its robust z-score, (value − median) / spread.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy.special import fdtri  # F's quantile, without importing scipy.stats (0.5 s)

#: 1.4826 × MAD is the standard deviation of a Gaussian population
MAD_TO_SIGMA = 1.4826
#: the χ² quantile beyond which a valve is an outlier: a Gaussian population of 200 valves
#: would have 0.2 valves beyond it by chance
OUTLIER_LEVEL = 0.999
#: valves per figure below which no MCD is estimated (median/MAD scores and rank correlations):
#: MCD's estimate is noisy for few valves, and its false flags rise (module docstring)
VALVES_PER_FIGURE = 15
#: fewest valves for an MCD at all
MIN_VALVES_FOR_COVARIANCE = 50
#: share of the valves the MCD fits: a batch where more than a quarter of the valves are off has
#: a problem of its own, not outliers; a larger share than the default half makes the estimate
#: less noisy for a few dozen valves
MCD_SUPPORT = 0.75
#: fewest valves with a figure for any statistic of it
MIN_VALVES = 3
#: valves beyond the figures' count below which no valve is called an outlier: with as many
#: valves as figures any valve can be fitted exactly
SPARE_VALVES = 3


def robust_spread(values) -> float:
    """1.4826 × the median absolute deviation of the finite ``values`` (NaN without any)."""
    values = np.asarray(values, float)
    values = values[np.isfinite(values)]
    if not values.size:
        return float("nan")
    return float(MAD_TO_SIGMA * np.median(np.abs(values - np.median(values))))


def spread_floors(frame: pd.DataFrame, stderr_columns: dict[str, str]) -> dict[str, float]:
    """Each figure's typical standard error, the median over the valves that have one (0 where
    none has): the least spread a figure is taken to have (module docstring)."""
    floors = {}
    for column, errors in stderr_columns.items():
        values = pd.to_numeric(frame[errors], errors="coerce").to_numpy(float) \
            if errors in frame else np.array([])
        values = values[np.isfinite(values) & (values > 0)]
        floors[column] = float(np.median(values)) if values.size else 0.0
    return floors


def summary(frame: pd.DataFrame, columns: list[str],
            floors: dict[str, float] | None = None) -> dict[str, dict]:
    """Per figure: valves, median, robust spread (1.4826·MAD), the spread used (never below
    the figure's typical standard error, ``floors``), minimum and maximum."""
    floors = floors or {}
    result = {}
    for column in columns:
        values = pd.to_numeric(frame[column], errors="coerce").to_numpy(float)
        values = values[np.isfinite(values)]
        if not values.size:
            continue
        spread = robust_spread(values)
        result[column] = {"valves": int(values.size), "median": float(np.median(values)),
                          "robust_spread": spread,
                          "typical_stderr": floors.get(column),
                          "spread_used": max(spread, floors.get(column, 0.0)),
                          "min": float(values.min()), "max": float(values.max())}
    return result


def correlations(frame: pd.DataFrame, columns: list[str]) -> pd.DataFrame:
    """Spearman's rank correlation between the figures (NaN where one does not vary)."""
    numbers = frame[columns].apply(pd.to_numeric, errors="coerce")
    if len(numbers.dropna()) < MIN_VALVES:
        return pd.DataFrame(np.nan, index=columns, columns=columns)
    return numbers.corr(method="spearman")


@dataclass(frozen=True)
class Outlier:
    """One valve that stands out.

    Attributes
    ----------
    serial : str
    distance : float
        Its robust distance from the population [1].
    cutoff : float
        The distance beyond which a valve is an outlier [1].
    standing_out : tuple of (str, float)
        The figures that make it stand out, most first, each with its robust z-score.
    """

    serial: str
    distance: float
    cutoff: float
    standing_out: tuple[tuple[str, float], ...]

    def describe(self) -> str:
        """``friction_load_pressure.K2 [N/bar] (z = +6.1); rms [bar] (z = +9.3)``."""
        return "; ".join(f"{name} (z = {z:+.1f})" for name, z in self.standing_out)


@dataclass(frozen=True)
class OutlierAnalysis:
    """The robust distances of a population and its outliers.

    Attributes
    ----------
    method : str
        ``"minimum covariance determinant"`` or ``"median/MAD scores"`` (too few valves for a
        covariance), or ``"none"`` (too few valves at all).
    columns : list of str
        The figures the distance is taken over (those that vary).
    cutoff : float
        Robust distance beyond which a valve is an outlier [1].
    distances : pandas.Series
        Each valve's robust distance, by serial (NaN for a valve without every figure).
    z_scores : pandas.DataFrame
        Each valve's robust z-score per figure, by serial.
    outliers : list of Outlier
        Farthest first.
    """

    method: str
    columns: list[str]
    cutoff: float
    distances: pd.Series
    z_scores: pd.DataFrame
    outliers: list[Outlier] = field(default_factory=list)

    def flagged(self) -> set[str]:
        return {outlier.serial for outlier in self.outliers}

    def table(self) -> pd.DataFrame:
        """outliers.csv: serial, robust distance, cutoff, what makes it stand out (names and
        z-scores), then every figure's z-score."""
        rows = []
        for outlier in self.outliers:
            rows.append({"serial": outlier.serial,
                         "robust distance": outlier.distance, "cutoff": outlier.cutoff,
                         "stands out by": "; ".join(name for name, _ in outlier.standing_out),
                         "z-scores": "; ".join(f"{z:+.2f}" for _, z in outlier.standing_out),
                         **{f"z {column}": self.z_scores.loc[outlier.serial, column]
                            for column in self.z_scores.columns}})
        return pd.DataFrame(rows, columns=["serial", "robust distance", "cutoff",
                                           "stands out by", "z-scores",
                                           *(f"z {c}" for c in self.z_scores.columns)])


def robust_outliers(frame: pd.DataFrame, columns: list[str],
                    floors: dict[str, float] | None = None, *,
                    level: float = OUTLIER_LEVEL, seed: int = 0) -> OutlierAnalysis:
    """The valves of ``frame`` (indexed by serial, one column per figure) that stand out
    (module docstring). ``floors``: each figure's least spread (its typical standard error,
    :func:`spread_floors`); ``level``: the χ² quantile of the cutoff; ``seed``: of the MCD's
    random starts (the result does not depend on the order of the valves)."""
    floors = floors or {}
    numbers = frame[columns].apply(pd.to_numeric, errors="coerce")
    complete = numbers.dropna()
    empty = OutlierAnalysis("none", [], float("nan"), pd.Series(np.nan, index=frame.index),
                            pd.DataFrame(index=frame.index))
    if len(complete) < MIN_VALVES:
        return empty
    median = complete.median()
    mad_spread = complete.apply(robust_spread)
    spread = pd.Series({c: max(mad_spread[c], floors.get(c, 0.0)) for c in columns})
    used = [c for c in columns if np.isfinite(spread[c]) and spread[c] > 0]
    if not used:
        return empty
    count = len(complete)
    if count < len(used) + SPARE_VALVES:
        return empty
    z = (numbers[used] - median[used]) / spread[used]
    # figures that scatter beyond their uncertainty get a covariance; the rest count alone
    scattered = [c for c in used if mad_spread[c] >= floors.get(c, 0.0)]
    location = pd.Series(0.0, index=used)
    covariance = pd.DataFrame(np.eye(len(used)), index=used, columns=used)
    method = "median/MAD scores"
    if len(scattered) >= 2:
        inside = z.loc[complete.index, scattered].to_numpy()
        if count >= max(MIN_VALVES_FOR_COVARIANCE, VALVES_PER_FIGURE * len(scattered)):
            from sklearn.covariance import MinCovDet

            fitted = MinCovDet(random_state=seed, support_fraction=MCD_SUPPORT).fit(inside)
            location[scattered] = fitted.location_
            covariance.loc[scattered, scattered] = fitted.covariance_
            method = "minimum covariance determinant"
        else:
            covariance.loc[scattered, scattered] = _rank_correlation(inside)
            method = "median/MAD scores with rank correlations"
    centred = (z - location).to_numpy(float)
    matrix = covariance.to_numpy(float)
    distances = np.sqrt(np.einsum("ij,jk,ik->i", centred, np.linalg.pinv(matrix), centred))
    cutoff = float(np.sqrt(squared_cutoff(level, len(used), count)))
    analysis = OutlierAnalysis(method, used, cutoff, pd.Series(distances, index=frame.index),
                               z)
    for position in np.argsort(-np.nan_to_num(distances, nan=-1.0)):
        if not distances[position] > cutoff:
            break
        serial = frame.index[position]
        named = _standing_out(centred[position], matrix, level, count)
        analysis.outliers.append(Outlier(
            str(serial), float(distances[position]), cutoff,
            tuple((used[j], float(z.iloc[position, j])) for j in named)))
    return analysis


def squared_cutoff(level: float, dimensions: int, valves: int) -> float:
    """The ``level`` quantile of the squared Mahalanobis distance of a new valve from a Gaussian
    population of ``valves`` valves whose mean and covariance were estimated from them, in
    ``dimensions`` figures: p(n−1)(n+1)/(n(n−p))·F(p, n−p) (module docstring)."""
    p, n = dimensions, valves
    return p * (n - 1) * (n + 1) / (n * (n - p)) * float(fdtri(p, n - p, level))


def _rank_correlation(z: np.ndarray) -> np.ndarray:
    """The Gaussian correlation matrix that Spearman's ρ of the columns implies, 2·sin(πρ/6),
    made positive definite (a matrix of pairwise estimates need not be)."""
    rho = pd.DataFrame(z).corr(method="spearman").to_numpy()
    rho = np.where(np.isfinite(rho), 2.0 * np.sin(np.pi * rho / 6.0), 0.0)
    np.fill_diagonal(rho, 1.0)
    values, vectors = np.linalg.eigh(rho)
    return vectors @ np.diag(np.clip(values, 1e-3, None)) @ vectors.T


def _standing_out(centred: np.ndarray, covariance: np.ndarray, level: float,
                  valves: int) -> list[int]:
    """The figures (positions) whose removal, greedily, the largest drop of the squared distance
    first, brings the distance in the remaining figures within their own cutoff."""
    remaining = list(range(len(centred)))
    removed: list[int] = []

    def squared(kept: list[int]) -> float:
        if not kept:
            return 0.0
        block = covariance[np.ix_(kept, kept)]
        vector = centred[kept]
        return float(vector @ np.linalg.pinv(block) @ vector)

    while remaining and squared(remaining) > squared_cutoff(level, len(remaining), valves):
        drops = [squared(remaining) - squared([k for k in remaining if k != j])
                 for j in remaining]
        chosen = remaining[int(np.argmax(drops))]
        removed.append(chosen)
        remaining.remove(chosen)
    return removed
