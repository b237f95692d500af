"""The maps' own error, as the diagnosis allows for it: a few smooth discrepancy terms.

A real valve's CFD maps are never exact, and in the force balance a 1 N flow-force error moves Δp
by about 1 bar, as much as the effects a diagnosis looks for. A diagnosis that knows only the
sensor noise "discovers" whatever term best soaks up the maps' error. So every refit carries
nuisance terms for that error (Kennedy & O'Hagan's model discrepancy, in a practical low-rank
form):

    δΔp(x) = Σ_m Σ_b φ_b(u)·(a_mb + a'_mb·z_ν(x) + a''_mb·z_B(x))·e_m(x) / √2,
    a, a', a'' ~ N(0, 1),

where e_m(x) is how far the computed Δp moves for a one-σ error of map m (the flow map, the force
map: :func:`surrogate.solver.uncertainty.map_error_gains`). That σ is the maps' σ against the
valve, the calibrated one combined with the CFD's own error (:mod:`surrogate.maps.cfd_error`):
cross-validation measures how well a map reproduces its samples, and cannot see an error that
every sample of an opening shares, as a mesh's does. A real valve differs from its CFD by both.
φ_b are hat functions in ln u normalised so that Σ_b φ_b² = 1 (knots at the sampled openings, in
the unsampled gaps and below the smallest opening: a map's error is shared by nearby openings and
is not shared far away), z_ν ∈ [−1, 1] the viscosity's place in the log's range (a map's error
may change with temperature) and z_B ∈ [−1, 1] the back pressure's, in ln of the absolute
pressure (a map's error may change with the back pressure: the CFD runs at few back pressures,
and cavitation moves the flow force between them in ways the maps miss). At each point the prior
variance of δΔp is then (1 + z_ν² + z_B²)/2 times the maps' σ_Δp²: half of it at the log's
middle, up to 1.5 times at its corners, where the maps extrapolate. The coefficients enter every
fit as penalised unknowns: what the maps' uncertainty can explain, they explain; a candidate
effect must explain more.

Without the back-pressure trend the maps' error could not change sign with the back pressure, and
what the valve's cavitation does to the flow force was taken for physics: on a virtual valve with
nothing hidden (GP maps, the twin of eval/offlibrary.py case 4244) a progressive spring stood in
for it (ΔBIC −18, chosen in 59 % of resamples over runs); with it, ΔBIC −7, not significant.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..effects.per_opening import hat_basis
from ..model import ValveModel
from ..solver.replay import Replay
from ..core.units import P_ATM
from .residuals import LogReplay


#: knots added inside every unsampled gap (fractions of the gap in ln u) and below the smallest
#: opening (fraction of it)
GAP_KNOTS = (1.0 / 3.0, 2.0 / 3.0)
SEAT_KNOT = 0.3


@dataclass(frozen=True)
class Discrepancy:
    """The nuisance columns of a log's replay.

    Attributes
    ----------
    columns : numpy.ndarray
        (n, k): the Δp change [Pa] at each solved sample per unit of each coefficient, whose prior
        is N(0, 1).
    names : list of str
        What each column stands for (``"force map near 0.13 mm"``, ``"... × viscosity"``).
    """

    columns: np.ndarray
    names: list[str]
    #: N_runᵀ·N_run per run, by the runs' labels (:meth:`run_grams`)
    _grams: dict = field(default_factory=dict, compare=False, repr=False)
    #: each run's rows of the columns, by the runs' labels (:meth:`run_columns`)
    _run_columns: dict = field(default_factory=dict, compare=False, repr=False)

    @property
    def size(self) -> int:
        return self.columns.shape[1]

    def run_grams(self, labels: list[str], rows: list[np.ndarray]) -> np.ndarray:
        """(runs, k, k): each run's N_runᵀ·N_run, for the run ``rows`` (masks) labelled
        ``labels``. The held-out refits of every candidate of a diagnosis share the nuisance
        columns, and these products are most of their cost (k is tens of columns, a log
        thousands of samples), so they are kept."""
        key = tuple(labels)
        if key not in self._grams:
            self._grams[key] = np.stack([self.columns[m].T @ self.columns[m] for m in rows])
        return self._grams[key]

    def run_columns(self, labels: list[str], positions: list[np.ndarray]) -> list[np.ndarray]:
        """Each run's rows of the columns, for the runs' samples ``positions`` labelled
        ``labels``: kept, as :meth:`run_grams` are, for every held-out refit on these columns."""
        key = tuple(labels)
        if key not in self._run_columns:
            self._run_columns[key] = [self.columns.take(rows, axis=0) for rows in positions]
        return self._run_columns[key]

    def rows(self, index) -> "Discrepancy":
        return Discrepancy(self.columns[index], self.names)


def knots(model: ValveModel) -> np.ndarray:
    """Knots in u [m]: the force map's sampled openings, points inside its unsampled gaps and one
    below its smallest opening (none for maps without samples)."""
    coverage = model.force_map.coverage or model.flow_map.coverage
    if coverage is None:
        return np.zeros(0)
    points = list(coverage.openings)
    for low, high in coverage.gaps():
        points += [low * (high / low) ** t for t in GAP_KNOTS]
    points.append(coverage.openings[0] * SEAT_KNOT)
    return np.sort(np.asarray(points, float))


def hat_weights(u: np.ndarray, at: np.ndarray) -> np.ndarray:
    """(n, len(at)) hat functions in ln u through the knots ``at``, held at the end knots, each
    row scaled to unit norm (so a row's weights square-sum to one)."""
    weights = hat_basis(at, u)
    return weights / np.linalg.norm(weights, axis=1, keepdims=True)


def map_error_with_cfd(replay: Replay) -> np.ndarray | None:
    """(2, n) [Pa]: how far each sample's Δp moves for a one-σ error of the flow map (row 0)
    and the force map (row 1) against the valve (the replay's
    :attr:`~surrogate.solver.replay.Replay.map_error`, whose σ carries the CFD's own error);
    None for maps without an uncertainty."""
    return replay.map_error


def unit_range(values: np.ndarray) -> np.ndarray:
    """``values`` mapped linearly onto [−1, 1] over their range (zeros if they do not vary)."""
    low, high = np.min(values), np.max(values)
    return 2.0 * (values - low) / (high - low) - 1.0 if high > low else np.zeros(len(values))


def map_discrepancy(model: ValveModel, base: LogReplay, ok: np.ndarray) -> Discrepancy | None:
    """The nuisance columns at the solved samples ``ok`` of ``base`` (a replay with
    diagnostics), or None for maps that report no uncertainty."""
    effects = map_error_with_cfd(base.replay)
    at = knots(model)
    if effects is None or at.size < 2 or not ok.any():
        return None
    u = base.replay.u[ok]
    weights = hat_weights(np.where(np.isfinite(u), u, at[0]), at)
    points = base.replay.points
    z_nu = unit_range(np.log(model.fluid(points).nu[ok]))
    z_back = unit_range(np.log(model.true_points(points).p_B[ok] + P_ATM))
    columns, names = [], []
    for row, which in ((0, "flow map"), (1, "force map")):
        effect = np.nan_to_num(effects[row, ok])
        if not np.any(effect):
            continue
        for b, knot in enumerate(at):
            where = f"{which} near {knot * 1e3:.3g} mm"
            columns += [weights[:, b] * effect * trend / np.sqrt(2.0)
                        for trend in (1.0, z_nu, z_back)]
            names += [where, f"{where} × viscosity", f"{where} × back pressure"]
    if not columns:
        return None
    return Discrepancy(np.column_stack(columns), names)
