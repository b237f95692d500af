"""Grid interpolation of the CFD samples: the paper's q_sim and f_sim maps.

The samples are sweeps: for each fluid state (oil temperature) and each piston opening u, the CFD
was run at several flows q. Each sweep becomes one smooth curve; a query interpolates between the
curves of the neighbouring openings and fluid states. The grid need not be rectangular: each sweep
has its own flow range (the shipped samples lack the high flows at small openings, whose pressure
drop would exceed 400 bar), and each fluid state may have its own openings.

Interpolation and extrapolation rules
-------------------------------------
Flow map, stored as ln Δp(ln q) per sweep:

* **in q** (and so in Δp): monotone cubic (PCHIP) in ln q–ln Δp; beyond a sweep's flows, the
  curve continues along its end tangent, i.e. as the power law Δp ∝ q^n the last samples show.
* **in u**: ln Δp linear in ln u between neighbouring openings at the same flow; equivalently the
  discharge coefficient C_d is a power law of u between them. The same rule bridges the wide gap
  between 0.20 and 0.63 mm. Below the smallest opening and above the largest, C_d is held at its
  value there (Δp ∝ u⁻² at fixed flow), which keeps Δp → ∞ as u → 0, as a closing valve needs.
* **in temperature**: linear in ln ν between the sampled fluid states (plain interpolation), held
  at the nearest one outside their range. Temperature enters only through the viscosity, so the
  map serves any oil given its ν (density differences are not rescaled).
* **in p_B**: the map is built from the samples at one reference back pressure (the most common
  one: 5 bar in the shipped set); p_B enters only through Δp = p_L − p_B. The back-pressure set
  shows that this is an approximation once the flow cavitates (Δp at a flow up to 9 % higher at
  1.5 bar); those samples are left out of the flow grid and serve to check it (the force grid
  reads them through its cavitation law, below).

Force map, stored as α = f_ff/(A_L·Δp) per sweep, where f_ff = f_sim − p_L·A_L − p_B·(A_s3 − A_B)
is the flow force (the part of f_sim a uniform pressure would not give):

* **in Δp**: PCHIP in ln Δp, α held beyond a sweep's range (flow force proportional to Δp);
* **in u**: linear in ln u between the sampled openings; below the smallest, α goes on as the
  power of u the two smallest openings give (α ∝ u^k, 0 ≤ k ≤ 1; the shipped samples' k is
  0.5–0.7): at a fixed Δp the jet's momentum, and with it the flow force, vanishes as the valve
  closes, where holding α would keep the force of the smallest opening down to the seat. Above
  the largest opening α is held;
* **in temperature**: as the flow map;
* **in p_B**: the sweeps at the reference back pressure give α there; at another back pressure α
  follows the cavitation law the samples' back-pressure set gives
  (:class:`~.cavitation.CavitationLaw`: α·c(σ)/c(σ_ref), σ the cavitation number), where the
  samples hold one (two or more groups of runs at one opening and flow at several back
  pressures), and is held otherwise.

Where a query lies outside the samples the grid is built from, and why, is said as for every map
kind (:mod:`.coverage`): outside or between far-apart openings, outside a sweep's range, outside
the sampled viscosities, away from the reference back pressure. The grid's uncertainty grows
with the distance from its samples, as its own cross-validated errors show
(:class:`GridUncertainty`).

The map kind ``grid`` (:mod:`.registry`) builds these maps from a CFD-sample file, refusing one
whose SHA-256 is not the one a model file records.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import partial
from pathlib import Path

import numpy as np

from ..data.loaders import CfdSamples, load_cfd_samples
from ..core.errors import InputError
from ..fluid import FluidState, broadcast_query
from ..core.paths import SHIPPED_CFD_SAMPLES
from ..core.units import BAR, from_si
from ..valve import ValveParameters
from .base import FlowMap, ForceMap
from .cavitation import CavitationLaw
from .cfd_error import FORCE_CFD_ERROR, flow_cfd_error
from .coverage import DP_OUTSIDE, Coverage
from .crossval import calibrate, cross_validate, errors_on, meshes_carried, summary
from .curves import COMPARED_KNOTS, CurveSet
from .grid_sigma import shipped_calibrations, shipped_summary
from .package import file_hash
from .registry import (SHIPPED, MapKind, MapSource, Option, build_maps, register,
                       resolve_file, sha256_hex)
from .splits import group_keys, leave_smallest_opening_out, main_set

_TINY_OPENING = 1e-12  # [m] openings below this are treated as this, to keep logarithms finite
#: queries interpolated at a time: each query asks four sweeps' curves, and a block's
#: temporaries (a few dozen arrays of four times its length) then stay in the processor's cache,
#: which a whole log's would not. Every step is elementwise, so the values are the same to the
#: bit whatever the block
_BLOCK = 4096
#: the range the exponent of the flow-force fraction's power of u below the smallest opening is
#: kept in: it may fall toward the seat as fast as the opening, never grow (the jet's momentum,
#: and so the flow force, vanishes as the valve closes)
_POWER_BELOW = (0.0, 1.0)


@dataclass(frozen=True)
class _FluidLevel:
    """The sweeps of one fluid state: an increasing set of openings, one curve each."""

    nu: float
    log_u: np.ndarray
    curve: np.ndarray


class _SweepGrid:
    """Sweeps over fluid levels × openings; interpolation common to the flow and force grids.

    ``excess_slope`` continues the value linearly in ln u beyond the sampled openings (−2 for
    ln Δp at constant C_d; 0 to hold). A query touches at most four sweeps: two openings at each
    of two fluid levels; all four are evaluated in one vectorised call.
    """

    excess_slope = 0.0
    #: the grid's calibration bridged openings left out of it, across spans as wide as the
    #: unsampled gap: there the gap's prior is a floor under its σ (:func:`.cfd_error.valve_sigma`)
    calibration_spans_gaps = True
    #: below the smallest opening, continue the value as a power of u (the force grid's flow-force
    #: fraction) instead of ``excess_slope``'s linear continuation
    power_below = False
    #: the calibrated uncertainty (:class:`GridUncertainty`), attached when built with a valve
    uncertainty = None
    #: how α changes with the back pressure (:class:`~.cavitation.CavitationLaw`): the force
    #: grid's, where its samples give one
    cavitation = None

    def __init__(self, levels: list[_FluidLevel], curves: CurveSet, reference_back_pressure: float,
                 excluded: int):
        self.levels = sorted(levels, key=lambda level: level.nu)
        self.log_nu = np.log([level.nu for level in self.levels])
        self.curves = curves
        self.reference_back_pressure = reference_back_pressure
        self.excluded_samples = excluded
        # openings and their curves per level, padded to a rectangle (+inf: never reached)
        widest = max(len(level.log_u) for level in self.levels)
        self._log_u = np.full((len(self.levels), widest), np.inf)
        self._curve = np.zeros((len(self.levels), widest), dtype=np.intp)
        self._count = np.array([len(level.log_u) for level in self.levels])
        for k, level in enumerate(self.levels):
            self._log_u[k, : len(level.log_u)] = level.log_u
            self._curve[k, : len(level.log_u)] = level.curve
        # the openings of every fluid level when they are the same (the shipped grid's are): one
        # binary search then brackets a query's opening at both its levels
        shared = all(np.array_equal(level.log_u, self.levels[0].log_u) for level in self.levels)
        self._shared_log_u = self.levels[0].log_u if shared else None

    def _interpolate(self, x, log_u, log_nu, flags: bool = True
                     ) -> tuple[np.ndarray, np.ndarray | None]:
        """Value at (x, ln u, ln ν) and (if ``flags``) whether it lies inside the sampled sweeps,
        :data:`_BLOCK` queries at a time (:meth:`_interpolate_block`)."""
        if len(x) <= _BLOCK:
            return self._interpolate_block(x, log_u, log_nu, flags)
        parts = [self._interpolate_block(x[start:start + _BLOCK], log_u[start:start + _BLOCK],
                                         log_nu[start:start + _BLOCK], flags)
                 for start in range(0, len(x), _BLOCK)]
        value = np.concatenate([value for value, _ in parts])
        return value, np.concatenate([inside for _, inside in parts]) if flags else None

    def _interpolate_block(self, x, log_u, log_nu, flags: bool
                           ) -> tuple[np.ndarray, np.ndarray | None]:
        """:meth:`_interpolate` of one block of queries."""
        k0, k1, t, nu_excess = _bracket_shared(self.log_nu, log_nu)
        inside = np.abs(nu_excess) <= 1e-6
        if self._shared_log_u is not None:
            j00, j01, s0, excess0 = j10, j11, s1, excess1 = _bracket_shared(self._shared_log_u,
                                                                            log_u)
        else:
            j00, j01, s0, excess0 = _bracket(self._log_u[k0], self._count[k0], log_u)
            j10, j11, s1, excess1 = _bracket(self._log_u[k1], self._count[k1], log_u)
        widest = self._curve.shape[1]
        flat = self._curve.ravel()
        curve = np.concatenate([flat.take(k0 * widest + j00), flat.take(k0 * widest + j01),
                                flat.take(k1 * widest + j10), flat.take(k1 * widest + j11)])
        xs = np.concatenate([x, x, x, x])
        values = self.curves(curve, xs).reshape(4, -1)
        value = self._blend(values, s0, s1, excess0, excess1, t, k0, k1)
        if not flags:
            return value, None
        within = self.curves.inside(curve, xs).reshape(4, -1)
        inside &= ((t >= 1.0) | ((np.abs(excess0) <= 1e-9) & (within[0] | (s0 >= 1.0))
                                 & (within[1] | (s0 <= 0.0))))
        inside &= ((t <= 0.0) | ((np.abs(excess1) <= 1e-9) & (within[2] | (s1 >= 1.0))
                                 & (within[3] | (s1 <= 0.0))))
        return value, inside

    def _blend(self, values, s0, s1, excess0, excess1, t, k0, k1) -> np.ndarray:
        """The value at the queries from the four sweeps' ``values`` (4, n) about each: at
        the openings j0, j1 of the fluid level k0, then of the level k1, blended with the
        openings' weights ``s0``, ``s1`` (and the excess beyond the sampled openings [ln u])
        and the levels' weight ``t``."""
        level0 = (1.0 - s0) * values[0] + s0 * values[1] + self.excess_slope * excess0
        level1 = (1.0 - s1) * values[2] + s1 * values[3] + self.excess_slope * excess1
        if self.power_below and (np.any(excess0 < 0.0) or np.any(excess1 < 0.0)):
            level0 = self._continued_below(level0, values[0], values[1], excess0, k0)
            level1 = self._continued_below(level1, values[2], values[3], excess1, k1)
        return (1.0 - t) * level0 + t * level1

    def _continued_below(self, level, smallest, next_one, excess, k):
        """``level`` with the queries below the smallest opening (``excess`` < 0 [ln u]) on the
        power of u that the smallest two openings' values (``smallest``, ``next_one``, same sign)
        give, its exponent kept within :data:`_POWER_BELOW`; held where their signs differ."""
        below = excess < 0.0
        if not np.any(below):
            return level
        # the smallest openings' spacing of the levels of the points below alone (a few in a
        # hundred), not of every point's
        level_below = k[below]
        spacing = self._log_u[level_below, 1] - self._log_u[level_below, 0]
        low, high = smallest[below], next_one[below]
        with np.errstate(divide="ignore", invalid="ignore"):
            power = np.clip(np.log(high / low) / spacing, *_POWER_BELOW)
        continued = np.where((low * high > 0.0) & np.isfinite(power),
                             low * np.exp(power * excess[below]), low)
        level = level.copy()
        level[below] = continued
        return level

    def sweep_distances(self, u, nu) -> dict[str, np.ndarray]:
        """How far the grid interpolates or extrapolates to reach a query at opening ``u`` [m]
        and viscosity ``nu`` [m^2/s], in ln u and in ln ν [-].

        Between two sampled values a and b, linear interpolation errs by about f''·(x−a)(b−x)/2,
        so that distance is sqrt((x−a)(b−x)): zero on a sampled value, largest in the middle of
        a wide gap. Beyond the sampled values the grid holds or continues the end value and errs
        by the function's slope times how far beyond, a distance of its own: above the largest
        opening ("opening beyond") and below the smallest ("opening below", toward the seat,
        which the calibration leaves to :meth:`GridUncertainty.seat_slopes`). The opening's
        distances are those at the fluid levels around the query, weighted as they are.
        """
        log_u = np.log(np.maximum(np.ravel(u), _TINY_OPENING))
        log_nu = np.log(np.ravel(nu))
        levels = len(self.levels)
        k0, k1, t, nu_excess = _bracket(np.broadcast_to(self.log_nu, (len(log_u), levels)),
                                        np.full(len(log_u), levels), log_nu)
        distances = {"opening": 0.0, "opening beyond": 0.0, "opening below": 0.0,
                     "viscosity": _span(t, self.log_nu[k1] - self.log_nu[k0]),
                     "viscosity beyond": np.abs(nu_excess)}
        for k, weight in ((k0, 1.0 - t), (k1, t)):
            j0, j1, s, excess = _bracket(self._log_u[k], self._count[k], log_u)
            distances["opening"] = distances["opening"] + weight * _span(
                s, self._log_u[k, j1] - self._log_u[k, j0])
            distances["opening beyond"] = distances["opening beyond"] + weight * np.maximum(
                excess, 0.0)
            distances["opening below"] = distances["opening below"] + weight * np.maximum(
                -excess, 0.0)
        return distances

    def opening_knots(self) -> np.ndarray:
        """The sampled openings [m] of every fluid level: between them the grid is linear in
        ln u, so its value has a kink at each."""
        return np.exp(np.unique(np.concatenate([level.log_u for level in self.levels])))

    @property
    def fixed_back_pressure(self) -> float:
        """The one back pressure [Pa] whose samples the grid uses: CFD runs at others would not
        change it (:mod:`surrogate.planning.cfd_runs`)."""
        return self.reference_back_pressure

    @property
    def calibration(self):
        """The calibration of this map's uncertainty (fitted on first use), or None."""
        if self.uncertainty is None:
            return None
        return self.uncertainty.calibrations["flow" if isinstance(self, FlowMap) else "force"]

    def describe(self) -> str:
        """The sweeps the grid holds, in display units."""
        others = "give its cavitation law" if self.cavitation is not None else "left out"
        lines = [f"{type(self).__name__}: {len(self.curves)} sweeps at p_B = "
                 f"{from_si(self.reference_back_pressure, 'bar'):g} bar "
                 f"({self.excluded_samples} samples at other back pressures {others})"]
        for level in self.levels:
            openings = ", ".join(f"{from_si(u, 'mm'):g}" for u in np.exp(level.log_u))
            lines.append(f"  ν = {from_si(level.nu, 'cSt'):.4g} cSt: u = {openings} mm")
        if self.cavitation is not None:
            lines.append(f"  {self.cavitation.describe()}")
        return "\n".join(lines)


def _bracket(knots: np.ndarray, count: np.ndarray, value: np.ndarray):
    """Neighbouring knots of each value, per row.

    ``knots`` holds one ascending row per value, padded with +inf beyond ``count`` entries.
    Returns the lower and upper knot index, the weight of the upper one (values outside the knots
    are clamped to the nearest) and the excess beyond the knots (value − clamped value).
    """
    rows = np.arange(len(value))
    clamped = np.minimum(np.maximum(value, knots[:, 0]), knots[rows, count - 1])
    excess = value - clamped
    lower = np.minimum(np.sum(clamped[:, None] >= knots[:, 1:], axis=1), np.maximum(count - 2, 0))
    upper = np.minimum(lower + 1, count - 1)
    low, high = knots[rows, lower], knots[rows, upper]
    with np.errstate(invalid="ignore", divide="ignore"):
        weight = np.where(high > low, (clamped - low) / (high - low), 0.0)
    return lower, upper, _snap(weight), excess


def _bracket_shared(knots: np.ndarray, value: np.ndarray):
    """:func:`_bracket` for one ascending row of ``knots`` shared by every value: a binary
    search instead of comparing each value with every knot (the same indices and weights)."""
    count = len(knots)
    clamped = np.minimum(np.maximum(value, knots[0]), knots[count - 1])
    excess = value - clamped
    # the knots after the first at or below the value: _bracket's count of them
    if count - 2 <= COMPARED_KNOTS:  # the few inner knots compared one by one: no search
        lower = np.zeros(len(clamped), np.intp)
        for knot in knots[1:count - 1]:
            lower += clamped >= knot  # False for NaN, as _bracket counts (no knot below)
    else:
        lower = np.minimum(np.searchsorted(knots[1:], clamped, side="right"), count - 2)
        lower = np.where(np.isnan(clamped), 0, lower)  # as _bracket counts for NaN
    upper = np.minimum(lower + 1, count - 1)
    low, high = knots.take(lower), knots.take(upper)
    with np.errstate(invalid="ignore", divide="ignore"):
        weight = np.where(high > low, (clamped - low) / (high - low), 0.0)
    return lower, upper, _snap(weight), excess


def _span(weight: np.ndarray, gap: np.ndarray) -> np.ndarray:
    """Interpolation distance sqrt((x−a)(b−x)) = gap·sqrt(w(1−w)) between knots ``gap`` apart
    at weight ``w``."""
    with np.errstate(invalid="ignore"):
        return np.where(np.isfinite(gap), gap * np.sqrt(weight * (1.0 - weight)), 0.0)


def _snap(weight: np.ndarray) -> np.ndarray:
    """Interpolation weights within 1e-9 of 0 or 1 made exact, so that a query on a sampled
    opening or fluid state uses (and is judged by) that sweep alone."""
    return np.where(weight < 1e-9, 0.0, np.where(weight > 1.0 - 1e-9, 1.0, weight))


def _sweeps(samples: CfdSamples, reference_back_pressure: float | None):
    """Group the samples at the reference back pressure into sweeps.

    Returns (reference p_B, number of samples left out, {ν: {u: frame sorted by q}}).
    """
    frame = samples.frame[samples.frame["q"] > 0]
    if frame.empty:
        raise InputError(f"{samples.source}: no samples with flow > 0 to build a grid from")
    if reference_back_pressure is None:
        levels, counts = np.unique(np.round(frame["p_B"].to_numpy(), 0), return_counts=True)
        reference_back_pressure = float(levels[np.argmax(counts)])
    at_reference = np.isclose(frame["p_B"], reference_back_pressure, rtol=0, atol=1e-3 * BAR)
    used = frame[at_reference]
    if used.empty:
        raise InputError(f"{samples.source}: no samples at the reference back pressure "
                         f"{from_si(reference_back_pressure, 'bar'):g} bar")
    groups: dict[float, dict[float, object]] = {}
    nu_keys = group_keys(used["nu"].to_numpy())
    u_keys = group_keys(used["u"].to_numpy())
    for (nu, u), sweep in used.groupby([nu_keys, u_keys]):
        sweep = sweep.sort_values("q")
        if len(sweep) < 2 or np.any(np.diff(sweep["q"]) <= 0):
            raise InputError(
                f"{samples.source}: the sweep at u = {from_si(u, 'mm'):g} mm, "
                f"ν = {from_si(nu, 'cSt'):.4g} cSt needs at least two distinct flows "
                f"(lines {', '.join(map(str, sweep['line']))})")
        dp = (sweep["p_L"] - sweep["p_B"]).to_numpy()
        if np.any(np.diff(dp) <= 0):
            raise InputError(
                f"{samples.source}: in the sweep at u = {from_si(u, 'mm'):g} mm, "
                f"ν = {from_si(nu, 'cSt'):.4g} cSt the pressure drop does not rise with the flow "
                f"(lines {', '.join(map(str, sweep['line']))}); a grid map needs monotone sweeps")
        groups.setdefault(nu, {})[u] = sweep
    return reference_back_pressure, int(len(frame) - len(used)), groups


def _build(groups, curve_of_sweep) -> tuple[list[_FluidLevel], list]:
    levels, curves = [], []
    for nu, by_opening in groups.items():
        openings = sorted(by_opening)
        ids = []
        for u in openings:
            ids.append(len(curves))
            curves.append(curve_of_sweep(by_opening[u]))
        levels.append(_FluidLevel(nu, np.log(openings), np.asarray(ids, np.intp)))
    return levels, curves


class GridFlowMap(_SweepGrid, FlowMap):
    """q_sim by interpolating the CFD sweeps (rules in the module docstring).

    Build it with :meth:`from_samples`.
    """

    kind = "grid"
    excess_slope = -2.0  # ln Δp per ln u at constant C_d

    @property
    def cfd_error(self) -> float:
        """σ of ln C_d that the CFD adds [1]: what the samples interpolated estimate of their own
        meshes (:attr:`GridUncertainty.flow_cfd_error`); the shipped samples' without them."""
        if self.uncertainty is None:
            return FlowMap.cfd_error
        return self.uncertainty.flow_cfd_error

    @classmethod
    def from_samples(cls, samples: CfdSamples, *, reference_back_pressure: float | None = None,
                     sweeps=None) -> "GridFlowMap":
        """Build from CFD samples.

        Parameters
        ----------
        samples : CfdSamples
            Validated samples.
        reference_back_pressure : float, optional
            Back pressure [Pa] of the samples to use; default the most common one.
        sweeps : tuple, optional
            The samples' sweeps at that back pressure (:func:`_sweeps`), when the force grid
            is built from them too.
        """
        reference, excluded, groups = sweeps or _sweeps(samples, reference_back_pressure)

        def curve(sweep):
            return np.log(sweep["q"].to_numpy()), np.log((sweep["p_L"] - sweep["p_B"]).to_numpy())

        levels, curves = _build(groups, curve)
        grid = cls(levels, CurveSet(curves, outside="tangent"), reference, excluded)
        grid.coverage = Coverage.of_samples(_used_samples(samples, reference))
        return grid

    def __repr__(self) -> str:
        return f"GridFlowMap({len(self.curves)} sweeps)"

    def pressure_drop(self, q, p_B, u, fluid: FluidState) -> np.ndarray:
        q, p_B, u, fluid = broadcast_query(q, p_B, u, fluid)
        shape = q.shape
        q, u, nu = q.ravel(), u.ravel(), fluid.nu.ravel()
        flowing = q > 0
        log_dp, _ = self._interpolate(np.log(np.where(flowing, q, 1.0)),
                                      np.log(np.maximum(u, _TINY_OPENING)), np.log(nu),
                                      flags=False)
        dp = np.where(flowing, np.exp(log_dp), 0.0)
        dp = np.where(flowing & (u <= 0), np.inf, dp)
        return dp.reshape(shape)

    def at_openings(self, p_B, u, fluid: FluidState):
        """:meth:`FlowMap.at_openings`: the points' brackets in opening and viscosity, and the
        sweeps they read, found once; each flow then reads and blends the sweeps as
        :meth:`pressure_drop` does (the same values, to the bit)."""
        u = np.asarray(u, float)
        if u.ndim != 1 or self._shared_log_u is None:
            return super().at_openings(p_B, u, fluid)
        return _FlowAtOpenings(self, u, fluid)

    def at_flows(self, q, p_B, fluid: FluidState):
        """:meth:`FlowMap.at_flows`: each point's sweeps read at its flow once, at every
        opening of the two fluid levels about it; each opening then only blends them (for
        grids whose fluid levels share their openings)."""
        q = np.asarray(q, float)
        if q.ndim != 1 or self._shared_log_u is None:
            return super().at_flows(q, p_B, fluid)
        return _FlowAtFlows(self, q, fluid)

    def calibration_inputs(self, q, p_B, u, fluid: FluidState):
        if self.uncertainty is None:
            return None
        q, p_B, u, fluid = broadcast_query(q, p_B, u, fluid)
        return self.uncertainty.inputs(self, p_B, u, fluid)


class _FlowAtFlows:
    """A flow grid at fixed flows and fluid states (:meth:`GridFlowMap.at_flows`), for openings
    to come: what :meth:`_SweepGrid._interpolate_block` reads from the sweeps at a point's flow
    does not depend on the opening, so it is read once per point at every opening of the
    point's two fluid levels (for grids whose fluid levels share their openings), and an
    opening only blends what the block would have read (the same values, to the bit)."""

    def __init__(self, grid: GridFlowMap, q: np.ndarray, fluid: FluidState):
        self.grid, self.q = grid, q
        self.k0, self.k1, self.t, _ = _bracket_shared(grid.log_nu, np.log(np.ravel(fluid.nu)))
        width = self.width = len(grid._shared_log_u)
        x = np.log(np.where(q > 0, q, 1.0))
        # per point, the sweeps of its level k0 at every opening, then those of its level k1
        sweeps = np.hstack([grid._curve[self.k0, :width], grid._curve[self.k1, :width]])
        self.values = np.empty(sweeps.shape)
        points = max(_BLOCK // (2 * width), 1)  # a block's worth of queries at a time
        for start in range(0, len(q), points):
            part = slice(start, start + points)
            self.values[part] = grid.curves(sweeps[part].ravel(), np.repeat(x[part], 2 * width)
                                            ).reshape(-1, 2 * width)
        self.values = self.values.ravel()

    def __call__(self, u: np.ndarray, index: np.ndarray) -> np.ndarray:
        """Δp [Pa] of the points ``index`` (positions) at openings ``u`` [m]."""
        q = self.q.take(index)
        u = np.asarray(u, float)
        log_u = np.log(np.maximum(u, _TINY_OPENING))
        log_dp = np.empty(len(index))
        for start in range(0, len(index), _BLOCK):  # as pressure_drop's blocks, for the cache
            part = slice(start, start + _BLOCK)
            j0, j1, s, excess = _bracket_shared(self.grid._shared_log_u, log_u[part])
            row = index[part] * (2 * self.width)
            values = np.stack([self.values.take(row + j0), self.values.take(row + j1),
                               self.values.take(row + self.width + j0),
                               self.values.take(row + self.width + j1)])
            log_dp[part] = self.grid._blend(values, s, s, excess, excess,
                                            self.t.take(index[part]), None, None)
        flowing = q > 0
        dp = np.where(flowing, np.exp(log_dp), 0.0)
        return np.where(flowing & (u <= 0), np.inf, dp)


class _FlowAtOpenings:
    """A flow grid at fixed openings and fluid states (:meth:`GridFlowMap.at_openings`), for
    flows to come: what :meth:`_SweepGrid._interpolate_block` finds from the opening and the
    viscosity, found once per point (for grids whose fluid levels share their openings)."""

    def __init__(self, grid: GridFlowMap, u: np.ndarray, fluid: FluidState):
        self.grid, self.u = grid, u
        log_u = np.log(np.maximum(u, _TINY_OPENING))
        k0, k1, t, _ = _bracket_shared(grid.log_nu, np.log(np.ravel(fluid.nu)))
        j0, j1, s, excess = _bracket_shared(grid._shared_log_u, log_u)
        widest = grid._curve.shape[1]
        flat = grid._curve.ravel()
        # the four sweeps each point reads, and the blend's weights, as the block computes them
        self.curves = np.stack([flat.take(k0 * widest + j0), flat.take(k0 * widest + j1),
                                flat.take(k1 * widest + j0), flat.take(k1 * widest + j1)])
        self.s, self.t = s, t
        self.rest, self.extra = 1.0 - s, grid.excess_slope * excess

    def __call__(self, q: np.ndarray, index=slice(None)) -> np.ndarray:
        """Δp [Pa] at the flows ``q`` [m^3/s] of the points ``index``."""
        q = np.asarray(q, float)
        curves, s, t = self.curves[:, index], self.s[index], self.t[index]
        rest, extra, u = self.rest[index], self.extra[index], self.u[index]
        flowing = q > 0
        x = np.log(np.where(flowing, q, 1.0))
        log_dp = np.empty(len(q))
        for start in range(0, len(q), _BLOCK):  # as pressure_drop's blocks, for the cache
            part = slice(start, start + _BLOCK)
            values = self.grid.curves(curves[:, part].ravel(),
                                      np.concatenate([x[part]] * 4)).reshape(4, -1)
            level0 = rest[part] * values[0] + s[part] * values[1] + extra[part]
            level1 = rest[part] * values[2] + s[part] * values[3] + extra[part]
            log_dp[part] = (1.0 - t[part]) * level0 + t[part] * level1
        dp = np.where(flowing, np.exp(log_dp), 0.0)
        return np.where(flowing & (u <= 0), np.inf, dp)


class GridForceMap(_SweepGrid, ForceMap):
    """f_sim by interpolating the flow-force fraction of the CFD sweeps (rules in the module
    docstring). Build it with :meth:`from_samples`."""

    kind = "grid"
    power_below = True

    def __init__(self, *args, A_L: float, back_area: float,
                 cavitation: CavitationLaw | None = None, **kwargs):
        super().__init__(*args, **kwargs)
        self.A_L = A_L
        self.back_area = back_area
        self.cavitation = cavitation

    @classmethod
    def from_samples(cls, samples: CfdSamples, valve: ValveParameters, *,
                     reference_back_pressure: float | None = None, sweeps=None
                     ) -> "GridForceMap":
        """Build from CFD samples and the valve's areas (to separate the flow force).

        Parameters as :meth:`GridFlowMap.from_samples`.
        """
        reference, excluded, groups = sweeps or _sweeps(samples, reference_back_pressure)
        back_area = valve.A_s3 - valve.A_B

        def curve(sweep):
            dp = (sweep["p_L"] - sweep["p_B"]).to_numpy()
            flow_force = (sweep["f_sim"] - sweep["p_L"] * valve.A_L
                          - sweep["p_B"] * back_area).to_numpy()
            return np.log(dp), flow_force / (valve.A_L * dp)

        levels, curves = _build(groups, curve)
        law = CavitationLaw.fit(samples.frame[samples.frame["q"] > 0], valve)
        grid = cls(levels, CurveSet(curves, outside="hold"), reference, excluded, A_L=valve.A_L,
                   back_area=back_area, cavitation=law)
        grid.coverage = Coverage.of_samples(_used_samples(samples, reference))
        return grid

    def __repr__(self) -> str:
        return f"GridForceMap({len(self.curves)} sweeps)"

    def _fraction(self, p_L, p_B, u, fluid, flags: bool):
        p_L, p_B, u, fluid = broadcast_query(p_L, p_B, u, fluid)
        dp = np.maximum(p_L - p_B, 0.0)
        fraction, inside = self._interpolate(np.log(np.maximum(dp.ravel(), 1e-300)),
                                             np.log(np.maximum(u.ravel(), _TINY_OPENING)),
                                             np.log(fluid.nu.ravel()), flags)
        inside = None if inside is None else inside.reshape(dp.shape)
        fraction = fraction.reshape(dp.shape)
        if self.cavitation is not None:
            fraction = fraction * self.cavitation.ratio(p_B, self.reference_back_pressure, dp)
        return p_L, p_B, dp, fraction, inside

    def force(self, p_L, p_B, u, fluid: FluidState) -> np.ndarray:
        p_L, p_B, dp, fraction, _ = self._fraction(p_L, p_B, u, fluid, flags=False)
        return p_L * self.A_L + p_B * self.back_area + fraction * self.A_L * dp

    def extrapolation_reasons(self, p_L, p_B, u, fluid: FluidState) -> np.ndarray:
        p_L, p_B, u, fluid = broadcast_query(p_L, p_B, u, fluid)
        return super().extrapolation_reasons(p_L, p_B, u, fluid) | np.where(
            p_L <= p_B, DP_OUTSIDE, 0)

    def flow_force(self, p_L, p_B, u, fluid: FluidState) -> np.ndarray:
        p_L, p_B, dp, fraction, _ = self._fraction(p_L, p_B, u, fluid, flags=False)
        return fraction * self.A_L * dp

    def calibration_inputs(self, p_L, p_B, u, fluid: FluidState):
        if self.uncertainty is None:
            return None
        p_L, p_B, u, fluid = broadcast_query(p_L, p_B, u, fluid)
        return self.uncertainty.inputs(self, p_B, u, fluid)


def _used_samples(samples: CfdSamples, reference: float):
    """The samples a grid is built from: those with flow at the reference back pressure."""
    frame = samples.frame
    return frame[(frame["q"] > 0) & np.isclose(frame["p_B"], reference, rtol=0,
                                               atol=1e-3 * BAR)]


#: whether each distance of the grid's flow-force calibration fits a power of its own. The
#: distances measure different things (interpolating across a span of openings or of fluid
#: levels, going on beyond the last one, the cavitation law away from the reference back
#: pressure), and with the meshes' biases known (:func:`meshes_bridged_in_errors`) the errors
#: left along them grow differently: one power shared by all sat at the range's lower end (0.5)
#: for the left-out openings' errors, which are one offset per opening, and so read the
#: back-pressure folds' errors (1.5 and 10 bar asked from 5 bar) as σ nearly as wide at half
#: the distance. Each its own: opening 0.5, opening beyond 4, viscosity beyond 2.3, back
#: pressure 2.7, and a floor of 1.6 % (1.59 % before). Not the flow's: fitted so, its viscosity
#: distance (one left-out temperature interpolates) took the range's upper end, 4, and its ±2σ
#: held 83 % of the virtual valves' q at 30 and 50 °C and 77 % in the other oils, 98.4 % at
#: the sampled openings (``eval/valve_coverage.py``; 90, 87 and 97 % with one power)
FORCE_EACH_POWER = True


#: powers of the grid's flow calibration given per distance, not fitted. Linear interpolation
#: between two fluid levels errs by f''·(x−a)(b−x)/2, the square of the viscosity distance
#: (:meth:`_SweepGrid.sweep_distances`), so its power is 2. The folds cannot say otherwise: the
#: only errors along ν are a left-out temperature's, all at one distance (0.82: 40 °C bridged
#: from 20 and 60 °C), and the one power the opening's distances fit (2.7) set how σ fell toward
#: the levels; at 30 and 50 °C and in the other oils, half that span, the grid's ±2σ held 88 and
#: 84 % of the virtual valves' q over 120 valves (with power 2, 96 and 94 %;
#: ``eval/valve_coverage.py --seeds``)
FLOW_POWERS = {"viscosity": 2.0}


def meshes_bridged_in_errors(errors, samples: CfdSamples) -> np.ndarray:
    """The variance [1²] the CFD meshes' own biases put into each of the grid's cross-validated
    flow-force errors (:func:`.crossval.errors_on` rows): FORCE_CFD_ERROR²·(1 + share²) wherever
    the fold's grid lacked the sample's opening at the sample's fluid level and bridged (or held)
    its neighbours instead, share their bridged bias (:func:`.cfd_error.mesh_bias_share`), 0
    where the grid had it.

    The learned kinds' calibrations take a left-out opening's meshes as known
    (:func:`.crossval.meshes_in_errors`), since every map adds the CFD's error to σ by itself
    (:meth:`.base.ForceMap.mesh_error_at`). The grid interpolates each fluid level on its own, so
    a sweep left out (k-fold) also leaves its level without the opening's mesh: those errors
    carry it as well (the grid's force errors there are one offset per opening, alternating in
    sign between neighbours, as the meshes' biases would be: +4.1, -4.1, +4.4, -5.1 % at 0.10,
    0.13, 0.16, 0.20 mm leaving the opening out). Learned as σ of the grid's own, they made its
    fitted power sit at the range's lower end (0.5, errors flat in the distance) and its ±2σ
    hold 98.8 % of the virtual valves' flow force between openings and 98.6 % at other back
    pressures (97.8 and 96.9 % taken as known; ``eval/valve_coverage.py``). Across the
    unsampled gap the gap's own prior (:data:`.cfd_error.GAP_FORCE_ERROR`) is a floor under
    that σ (:func:`.cfd_error.valve_sigma`)."""
    bridged = ((errors["force_distance:opening"] > 0)
               | (errors["force_distance:opening beyond"] > 0)).to_numpy()
    return FORCE_CFD_ERROR ** 2 * meshes_carried(errors, samples, bridged)


class GridUncertainty:
    """What the grid maps' calibrated uncertainty is made of.

    A grid has no spread of its own: its standard deviation (of ln C_d; of the flow force,
    relative) grows with the distances it interpolates over, from the nearest sampled opening and
    fluid state (:meth:`_SweepGrid.sweep_distances`), and with the distance of the back pressure
    from the sampled one (:mod:`.sigma`). The constants come from the grid's own errors on
    samples left out of it (:mod:`.crossval`); rebuilding the grid for every fold takes
    a second, so that runs when a standard deviation is first asked for.
    """

    def __init__(self, samples: CfdSamples, valve: ValveParameters):
        self.samples, self.valve = samples, valve
        self._calibrations = None
        self._errors = None
        self._flow_cfd_error = None

    @property
    def flow_cfd_error(self) -> float:
        """σ of ln C_d that the samples' meshes put on them [1] (:func:`.cfd_error.
        flow_cfd_error`: the paper's mesh study pooled with how these samples' openings scatter),
        computed on first use."""
        if self._flow_cfd_error is None:
            self._flow_cfd_error = flow_cfd_error(self.samples.frame)
        return self._flow_cfd_error

    @staticmethod
    def inputs(grid: "_SweepGrid", p_B, u, fluid):
        """(None, distances) of a query to ``grid``: the distances it interpolates and
        extrapolates over in opening and viscosity, and that of the back pressure from the
        sampled one."""
        return None, {**grid.sweep_distances(u, fluid.nu),
                      "back pressure": grid.coverage.back_pressure_distance(np.ravel(p_B))}

    @property
    def errors(self):
        """The grid's cross-validated errors (:func:`.crossval.cross_validate`),
        computed on first use; the back-pressure set asked one opening at a time, the rest of
        it fitting the force's cavitation law."""
        if self._errors is None:
            self._errors = cross_validate(self.samples, self.valve,
                                          partial(grid_maps_on, self.samples, self.valve),
                                          back_pressure_by_opening=True)
        return self._errors

    @property
    def calibrations(self) -> dict:
        """{"flow": ..., "force": ...} :class:`~.sigma.SigmaCalibration`: the shipped one for
        the shipped samples and valve (:mod:`.grid_sigma`), otherwise fitted on first
        use."""
        if self._calibrations is None:
            self._calibrations = shipped_calibrations(self.samples, self.valve)
        if self._calibrations is None:
            self._calibrations = self.fitted_calibrations()
        return self._calibrations

    def fitted_calibrations(self) -> dict:
        """The calibrations fitted to this grid's cross-validated errors, never the shipped
        ones."""
        # the flow's errors without the meshes' biases as known variance, unlike the learned
        # kinds': taken out, they left the grid's flow σ across the unsampled gap too narrow
        # for the virtual valves' q there (docs/maps.md, "How the learned maps are built"); its
        # powers one fitted power but the viscosity's, the interpolation's (FLOW_POWERS), which
        # its folds cannot fit. Not the networks' given one for the back pressure
        # (sigma.BACK_PRESSURE_LINEAR): the grid does not read the back pressure as an input;
        # its flow holds the reference back pressure's C_d, and its error away from it is the
        # flow's cavitation, which sets in with the cavitation number rather than in
        # proportion. The flow force's errors carry the meshes the folds bridged as known
        # variance (meshes_bridged_in_errors), and each of its distances fits a power of its
        # own (FORCE_EACH_POWER)
        errors = self.errors[~toward_seat(self.errors)]
        flow, force = calibrate(errors, use_spread=False, powers=(FLOW_POWERS, {}),
                                known=(None, meshes_bridged_in_errors(errors, self.samples)),
                                each_power=(False, FORCE_EACH_POWER))
        seat = self.seat_slopes()
        return {"flow": replace(flow, seat=seat["flow"]),
                "force": replace(force, seat=seat["force"])}

    def seat_slopes(self) -> dict[str, float]:
        """How fast the grid's continuation below its smallest opening errs [ln units per unit
        of ln(u₀/u)], {"flow": ln C_d's, "force": the relative flow force's}, scored as the
        grid goes on: rebuilt without its smallest opening at every temperature, continued from
        the next two to it (:func:`.splits.leave_smallest_opening_out`), the RMS error there
        over how far it went. 0 with fewer than three openings."""
        frame = self.samples.frame
        if len(np.unique(frame.loc[main_set(frame), "u"].round(9))) < 3:
            return {"flow": 0.0, "force": 0.0}
        _, train, test, reach = leave_smallest_opening_out(frame)
        flow_map, force_map = grid_maps_on(self.samples, self.valve, train)
        errors = errors_on(flow_map, force_map, frame[test & (frame["q"] > 0)], self.valve)
        return {name: float(np.sqrt(np.mean(errors[column] ** 2)) / reach)
                for name, column in (("flow", "discharge_error"), ("force", "force_error"))}

    def summary(self) -> dict:
        """The cross-validation summary per scheme (:func:`.crossval.summary`): the shipped one
        for the shipped samples and valve (:mod:`.grid_sigma`), otherwise computed."""
        return shipped_summary(self.samples, self.valve) or self.computed_summary()

    def computed_summary(self) -> dict:
        """The cross-validation summary computed from this grid's errors, never the shipped
        one."""
        return summary(self.errors, self.calibrations["flow"], self.calibrations["force"],
                       known=self.known_in_errors())

    def known_in_errors(self) -> tuple:
        """(flow, force) variance the calibration takes as already in the cross-validated
        errors (:func:`meshes_bridged_in_errors`; none for the flow)."""
        return None, meshes_bridged_in_errors(self.errors, self.samples)


def toward_seat(errors) -> np.ndarray:
    """True for the cross-validated errors (:func:`.crossval.errors_on` rows) a fold's grid
    reached only by going on below its smallest opening. Such a fold drops a temperature's
    smallest sweeps and goes on from openings the grid, holding them all, never goes on from;
    how the grid errs toward the seat is its own fold's (:meth:`GridUncertainty.seat_slopes`),
    and the calibration is fitted without them."""
    return ((errors["flow_distance:opening below"] > 0)
            | (errors["force_distance:opening below"] > 0)).to_numpy()


def grid_maps_on(samples: CfdSamples, valve: ValveParameters, train=None
                 ) -> tuple[GridFlowMap, GridForceMap]:
    """The grid maps of ``samples`` (of the ``train`` ones, for a cross-validation fold), with
    their uncertainty attached."""
    if train is not None:
        samples = samples.subset(train)
    sweeps = _sweeps(samples, None)  # the same sweeps make both grids
    flow = GridFlowMap.from_samples(samples, sweeps=sweeps)
    force = GridForceMap.from_samples(samples, valve, sweeps=sweeps)
    flow.uncertainty = force.uncertainty = GridUncertainty(samples, valve)
    return flow, force


# --- the kind: grid maps of a CFD-sample file ----------------------------------------------------

def _grid_data(cfd, **options) -> dict:
    if cfd is not None:  # a file the user names: checked here, where its errors may quote it
        load_cfd_samples(cfd)
    reference = SHIPPED if cfd is None else str(Path(cfd).resolve())
    return {"cfd": reference,
            "cfd_sha256": file_hash(resolve_file(reference, Path("."), SHIPPED_CFD_SAMPLES))}


def _grid_samples(options, base) -> CfdSamples:
    """The CFD samples the grid options name, checked against the hash a model recorded."""
    path = resolve_file(options.get("cfd", SHIPPED), base, SHIPPED_CFD_SAMPLES)
    expected = options.get("cfd_sha256")
    if expected is not None and path.is_file() and file_hash(path) != expected:
        raise InputError(f"{path}: these CFD samples are not the ones the model was built from "
                         f"(SHA-256 {file_hash(path)[:12]}…, the model records {expected[:12]}…); "
                         "refit the model on them, or point cfd = ... at the original file")
    # named by a model file (or checked already where the user named it, :func:`_grid_data`):
    # its errors do not quote it, as it may be any file at all
    return load_cfd_samples(path, named_by="the maps' cfd option")


def _build_grid(options, valve, base):
    return grid_maps_on(_grid_samples(options, base), valve)


def _grid_accuracy(options, valve, base):
    # the shipped summary is read for the samples alone: building the grid only to ask its
    # uncertainty for it was two thirds of ranking the kinds at a workflow's start (0.1 CPU s)
    samples = _grid_samples(options, base)
    shipped = shipped_summary(samples, valve)
    if shipped:
        return shipped
    # through the maps' cache, not grid_maps_on(samples): the cross-validation behind the
    # summary (seconds) is then the one the workflow's own grid maps use, at the cost of
    # reading the samples' file once more
    flow, _ = build_maps(MapSource.of("grid", **options), valve, base)
    return flow.uncertainty.summary()


register(MapKind(
    "grid", "interpolation of the CFD samples (surrogate/maps/grid.py)", _build_grid,
    (Option("cfd", "the CFD-sample file (default: the shipped one)", default=SHIPPED, path=True,
            shipped=SHIPPED_CFD_SAMPLES),
     Option("cfd_sha256", "SHA-256 of the CFD-sample file the model was built from",
            sha256_hex)),
    data=_grid_data, accuracy=_grid_accuracy))
