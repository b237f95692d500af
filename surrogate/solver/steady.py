"""Batch steady-state solver: the piston position and load pressure for each operating point.

For a point (q, p_P, p_B, temperature, direction) the piston sits where the force balance of eq. 2
closes,

    h(u) = net_force(u) − s·friction(u) = 0,      0 < u <= U_max,

with the load pressure p_L(u) = p_B + Δp(q, u) from the flow map, and s = +1 while the piston opens
(friction holds it back), −1 while it closes, 0 without friction. h falls with u (unless an
effect bends it: below): a wider opening needs less pressure for the same flow, and the spring
pushes harder. As u → 0 with flow passing, Δp and hence h grow without bound, so the root is
bracketed by a vanishing opening and the stop. All points are solved together
(:func:`surrogate.numerics.roots.find_roots`).

Several equilibria
------------------
An effect can bend h so that it rises with u somewhere (a leak that carries the flow at small
openings, a force of free shape), and a point then has several equilibria: h crosses zero
downwards at stable ones and upwards at the unstable ones between them. Which one the piston
holds depends on where it comes from, so the solver picks one by a rule, never by where a
bracket or a guessed opening happened to land:

* **opening** (s = +1), and **without friction** (s = 0): the *smallest* stable equilibrium, the
  first one a piston opening from closed meets, the way a valve opens from rest;
* **closing** (s = −1): the *largest* one, the first one a piston closing from the stop meets,
  or the stop itself where h >= 0 there.

The friction band of the replay (:mod:`.replay`) is then as wide as the equilibria allow: a
piston on the way up stops at the first one above closed, one on the way down at the first one
below the stop. (A piston already sitting beyond the first equilibrium of a side can be pushed on
to the next one; the replay's play keeps it where it is instead.)

The check is cheap, not exhaustive: once a root u* is found (near a guess or over the stroke),
h is sampled once more, at u*/3 for the opening side and at min(3·u*, U_max) for the closing side
[m]; a point on the stop is checked from u* = U_max on the opening side. Where the sample lies on
the far side of zero (h <= 0 below the root while opening, h >= 0 above it while closing), an
equilibrium of higher priority lies beyond it: the root is solved again in the bracket the
sample opens with the floor or the stop (where h still on the far side means no equilibrium from
closed, or the stop), and checked again from there. Over the stroke, a closing point with h <= 0
at both ends is searched from the stop down (every factor 3 in u) for a place where h >= 0,
which a piston coming down would stop above.

The rule does not depend on the guess; the check's reach does: an interval where h has the other
sign that holds none of the samples is not seen (a narrow one, as near the parameters where a
pair of equilibria is born, or one far from the root found), and a guess that lands the first
root elsewhere can then change the answer. On a made-up family of models with a force bump (and
half of them a leak; tests/solver/test_solver.py has some), the one sample returns the rule's
equilibrium whatever the guess at 62 % of the points that have several, without the check 7 %
(``python eval/equilibria.py``). Two samples (u*/2 and u*/6) would reach 76 %, but each costs an
evaluation of h per point and solve, and a fit spends most of its time there: two made the
workflow 1.2 times as slow, one about 1.1 (eval/speed_vs_baseline.py). On a model whose h falls
with u the check finds nothing: the answer is the one root. Points without flow are solved as
before, unchecked.

Edge cases get a status instead of a number that looks valid:

* **at the stop**: h(U_max) >= 0, the piston rests on its stop, u = U_max;
* **closed**: no flow and the pilot cannot open the valve: u = 0 and p_L is the crack load
  pressure, the highest load pressure the closed valve holds;
* **no flow, held open**: the pilot alone opens the valve: p_L = p_B and u from the spring;
* **failures** (flagged, values NaN): invalid input, no equilibrium inside the stroke, a map that
  returns non-finite values, or no convergence.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from enum import IntEnum

import numpy as np
import pandas as pd

from ..maps.coverage import describe_all
from ..model import ValveModel
from ..core.parallel import map_threads
from ..points import OperatingPoints
from ..numerics.roots import find_roots, invert_increasing
from ..core.units import BAR, from_si
from .map_tables import COARSE, balance_reader
from .uncertainty import pressure_drop_std

_OPENING_FLOOR = 1e-7  # smallest opening tried, as a fraction of the stroke
# a guessed opening is bracketed within ±2 %, then on the root's side within 10 % and 40 %,
# before the full stroke is tried
_GUESS_WIDTHS = (0.02, 0.1, 0.4)
_U_RTOL = 1e-14  # relative tolerance on u: near closing eq. 15 amplifies u errors ~1e4-fold
# the rule's check of a root u*: h sampled at u*/f (opening side) or u*·f (closing side) for
# these f, nearest first (module docstring); each costs an evaluation of h per point and solve
_RULE_FACTORS = (3.0,)
# re-solves after a check found an equilibrium of higher priority, each checked again
_RULE_ROUNDS = 8


class Status(IntEnum):
    """Outcome per point. Non-negative values are solutions, negative ones failures."""

    OK = 0
    AT_STOP = 1
    CLOSED = 2
    INVALID_INPUT = -1
    NO_EQUILIBRIUM = -2
    MAP_FAILURE = -3
    NOT_CONVERGED = -4


def status_names(codes: np.ndarray) -> np.ndarray:
    """Each :class:`Status` code's name in lower case, as an object array whose equal values
    share one string."""
    distinct, inverse = np.unique(np.asarray(codes, np.int64), return_inverse=True)
    names = np.array([Status(int(code)).name.lower() for code in distinct], dtype=object)
    return names[inverse] if len(distinct) else np.array([], dtype=object)


REASONS = {
    Status.OK: "equilibrium inside the stroke",
    Status.AT_STOP: "piston on its mechanical stop (u = U_max)",
    Status.CLOSED: "no flow: valve closed, p_L is the crack load pressure",
    Status.INVALID_INPUT: "invalid input: non-finite value, negative flow or temperature",
    Status.NO_EQUILIBRIUM: "no equilibrium: the net force closes the valve even at a vanishing "
                           "opening (the flow map gives too little pressure drop there)",
    Status.MAP_FAILURE: "a map returned a non-finite value",
    Status.NOT_CONVERGED: "root finding did not converge",
}


@dataclass(frozen=True)
class SteadyState:
    """Solutions at a batch of points; see :class:`Status` for ``status``.

    Attributes
    ----------
    points : OperatingPoints
    u : numpy.ndarray
        Piston position [m]; NaN where the point failed.
    dp : numpy.ndarray
        Pressure drop p_L − p_B [Pa]; NaN where the point failed.
    status : numpy.ndarray of int
    reasons_outside : numpy.ndarray of int
        Why the solution queries a map outside its data: bit flags of
        :mod:`surrogate.maps.coverage`, 0 inside.
    dp_std : numpy.ndarray or None
        Standard deviation of ``dp`` [Pa] that the maps' uncertainty implies
        (:mod:`.uncertainty`); None for maps without one.
    """

    points: OperatingPoints
    u: np.ndarray
    dp: np.ndarray
    status: np.ndarray
    reasons_outside: np.ndarray
    dp_std: np.ndarray | None = None

    @property
    def extrapolating(self) -> np.ndarray:
        """True where the solution queries a map outside its data."""
        return self.reasons_outside != 0

    @property
    def p_L(self) -> np.ndarray:
        """Load pressure [Pa]."""
        return self.points.p_B + self.dp

    @property
    def ok(self) -> np.ndarray:
        """True where the point has a solution (possibly at the stop or closed)."""
        return self.status >= 0

    def reasons(self) -> list[str]:
        """The status of each point in words."""
        return [REASONS[Status(code)] for code in self.status]

    def failure_summary(self) -> str:
        """How many points failed, and why; empty if none did."""
        codes, counts = np.unique(self.status[self.status < 0], return_counts=True)
        return "; ".join(f"{count} point(s): {REASONS[Status(code)]}"
                         for code, count in zip(codes, counts))

    def to_frame(self) -> pd.DataFrame:
        """The solutions in display units, one row per point, with status and reason."""
        return pd.DataFrame({
            "q_lpm": from_si(self.points.q, "L/min"),
            "p_P_bar": from_si(self.points.p_P, "bar"),
            "p_B_bar": from_si(self.points.p_B, "bar"),
            "temperature_C": from_si(self.points.temperature, "degC"),
            "u_mm": from_si(self.u, "mm"),
            "p_L_bar": from_si(self.p_L, "bar"),
            "dp_bar": from_si(self.dp, "bar"),
            "dp_std_bar": (np.full(len(self.dp), np.nan) if self.dp_std is None
                           else from_si(self.dp_std, "bar")),
            "status": status_names(self.status),
            "extrapolating": self.extrapolating,
            "outside_samples": describe_all(self.reasons_outside),
            "reason": self.reasons(),
        })


#: points solved in one batch: the solver evaluates the balance over a grid of openings for
#: every point at once, a few kilobytes per point, so a log of millions is solved a batch at a
#: time (side by side on threads) in memory that does not grow with the log
BATCH = 50_000


def solve_steady(model: ValveModel, points: OperatingPoints, *, friction: bool = True,
                 guess: np.ndarray | None = None, positions_only: bool = False,
                 solved: Callable[[int], None] | None = None, tables=None) -> SteadyState:
    """Solve the force balance at every point (:func:`_solve_batch`, :data:`BATCH` points at a
    time; the points are independent, so the batches change nothing). ``solved`` is called
    with the number of points of each batch as it is done, for progress reports. ``tables``:
    the points' rows of their map tables (a :class:`.map_tables.TableView`), read instead of
    the maps where they hold the opening asked for."""
    count = len(points)
    if count <= BATCH:
        return _solve_batch(model, points, friction=friction, guess=guess,
                            positions_only=positions_only, tables=tables)

    def batch(start: int) -> SteadyState:
        part = slice(start, min(start + BATCH, count))
        return _solve_batch(model, points[part], friction=friction,
                            guess=None if guess is None else guess[part],
                            positions_only=positions_only,
                            tables=None if tables is None else tables[part])

    parts = []
    for part in map_threads(batch, range(0, count, BATCH)):
        parts.append(part)
        if solved is not None:
            solved(len(part.u))
    stds = [part.dp_std for part in parts]
    return SteadyState(points, *(np.concatenate([getattr(part, name) for part in parts])
                                 for name in ("u", "dp", "status", "reasons_outside")),
                       None if any(std is None for std in stds) else np.concatenate(stds))


def _solve_batch(model: ValveModel, points: OperatingPoints, *, friction: bool = True,
                 guess: np.ndarray | None = None, positions_only: bool = False,
                 tables=None) -> SteadyState:
    """Solve the force balance at every point.

    Parameters
    ----------
    model : ValveModel
    points : OperatingPoints
        Their ``direction`` selects the friction side (+1 opening, −1 closing, 0 none).
    friction : bool
        False leaves friction out whatever the direction (the paper's median-line comparison).
    guess : numpy.ndarray, optional
        Expected opening of each point [m] (NaN for none), e.g. the solution for nearby
        parameters during a fit. Points whose root lies within ±2 % of it are solved from that
        narrow bracket, which takes a few iterations instead of a dozen; the answer is the same.
        Points whose root lies further away widen that bracket on the root's side first.
    positions_only : bool
        True skips what only a caller of the pressure drop needs: ``dp`` of flowing points stays
        NaN, ``reasons_outside`` 0 and ``dp_std`` None. The replay asks for the friction band's
        edges this way.
    tables : TableView, optional
        The points' rows of their map tables (:mod:`.map_tables`), for flowing points.
    """
    count = len(points)
    u = np.full(count, np.nan)
    dp = np.full(count, np.nan)
    status = np.full(count, Status.NOT_CONVERGED, dtype=np.int8)
    invalid = points.invalid()
    status[invalid] = Status.INVALID_INPUT
    sign = points.direction.astype(float) if friction else np.zeros(count)

    flowing = np.flatnonzero(~invalid & (points.q > 0))
    if flowing.size:
        u[flowing], dp[flowing], status[flowing] = _solve_flowing(
            model, points[flowing], sign[flowing],
            None if guess is None else np.asarray(guess, float)[flowing],
            with_dp=not positions_only, tables=None if tables is None else tables[flowing])
    still = np.flatnonzero(~invalid & (points.q == 0))
    if still.size:
        u[still], dp[still], status[still] = _solve_still(model, points[still], sign[still])

    reasons = np.zeros(count, dtype=np.int64)
    solved = np.flatnonzero(status >= 0)
    if positions_only:
        return SteadyState(points, u, dp, status, reasons)
    if solved.size:
        sub = points[solved]
        reasons[solved] = model.extrapolation_reasons(u[solved], sub.p_B + dp[solved], sub,
                                                      model.fluid(sub))
    dp_std = pressure_drop_std(model, points, u, dp, sign, status == Status.AT_STOP)
    return SteadyState(points, u, dp, status, reasons, dp_std)


class _FlowingBalance:
    """The force balance h(u) = net force − s·friction of flowing points, falling with u (or
    not: see the module docstring), and the roots of it found so far."""

    def __init__(self, model, points, sign, tables=None):
        self.model, self.points, self.sign = model, points, sign
        # the side whose rule picks the smallest equilibrium (opening, or no friction)
        self.opens = sign >= 0
        self.fluid = model.fluid(points)
        self.balance = balance_reader(model, points, self.fluid, tables, keep=True)
        # for the rule's sign checks only: the coarse tables too (a sign change found there is
        # checked again on the fine ones or the maps)
        self.rough_balance = self.balance if tables is None else balance_reader(
            model, points, self.fluid, tables, COARSE)
        self.stroke = model.valve.U_max
        self.floor = self.stroke * _OPENING_FLOOR
        self.u = np.full(len(points), np.nan)
        self.status = np.full(len(points), Status.NOT_CONVERGED, dtype=np.int8)

    def __call__(self, u, i):
        balance = self.balance(u, i)
        return balance.net_force - self.sign[i] * balance.friction

    def rough(self, u, i):
        """h as :meth:`__call__`, possibly from coarse tables: for a sign far from zero."""
        balance = self.rough_balance(u, i)
        return balance.net_force - self.sign[i] * balance.friction

    def solve_in(self, lower, upper, which, h_lower, h_upper, f_middle=None) -> None:
        """Roots of the points ``which`` in brackets whose ends' values are known (and the
        middle's, where ``f_middle``'s mask says: :func:`.roots.find_roots`)."""
        roots = find_roots(lambda x, i: self(x, which[i]), lower, upper,
                           xatol=self.stroke * 1e-30, xrtol=_U_RTOL, f_lower=h_lower,
                           f_upper=h_upper, f_middle=f_middle)
        self.u[which] = roots.x
        self.status[which] = np.where(roots.converged, Status.OK,
                                      np.where(roots.status == -3, Status.MAP_FAILURE,
                                               Status.NOT_CONVERGED))


def _solve_flowing(model, points, sign, guess=None, with_dp=True, tables=None):
    """(u, Δp, status) of points with flow: first in narrow brackets around a guess, then the
    rest over the whole stroke."""
    h = _FlowingBalance(model, points, sign, tables)
    pending = np.arange(len(points))
    if guess is not None:
        left = np.ones(len(points), dtype=bool)  # a mask, not np.setdiff1d's sort
        left[_solve_near_guess(h, guess)] = False
        pending = pending[left]
    if pending.size:
        _solve_over_stroke(h, pending)
    _first_met(h)
    dp = np.full(len(points), np.nan)
    if with_dp:
        solved = np.flatnonzero(h.status >= 0)
        dp[solved] = h.balance(h.u[solved], solved).dp
    return h.u, dp, h.status


def _solve_near_guess(h: _FlowingBalance, guess: np.ndarray) -> np.ndarray:
    """Solve the points whose root lies in a bracket around their guessed opening; return them.

    h falls with u: where it is still positive at the bracket's upper end the root lies above
    it, where it is not positive at the lower end, below. The bracket moves that way, wider each
    time, evaluating only the new end (a diagnosis' probe step of a friction parameter moves the
    band's edges on the shipped log by up to 30 %).
    """
    usable = np.flatnonzero(np.isfinite(guess) & (guess > h.floor) & (guess < h.stroke))
    centre = guess[usable]
    lower = np.maximum(h.floor, centre * (1 - _GUESS_WIDTHS[0]))
    upper = np.minimum(h.stroke, centre * (1 + _GUESS_WIDTHS[0]))
    # both ends, and the middle where the root finder's first step (a bisection) lands, in one
    # call of the balance: a call's fixed cost is about its work on two thousand points, and a
    # fit's tables are read point by point, so the values are those of separate calls
    middle = lower + 0.5 * (upper - lower)
    h_lower, h_upper, h_middle = np.split(h(np.concatenate([lower, upper, middle]),
                                            np.tile(usable, 3)), 3)
    first = np.ones(usable.size, bool)  # whose middle is still that of their bracket
    for width in _GUESS_WIDTHS[1:]:
        up = np.flatnonzero((h_upper > 0) & (upper < h.stroke))
        down = np.flatnonzero((h_lower <= 0) & ~(h_upper > 0) & (lower > h.floor))
        lower[up], h_lower[up] = upper[up], h_upper[up]
        upper[up] = np.minimum(h.stroke, centre[up] * (1 + width))
        upper[down], h_upper[down] = lower[down], h_lower[down]
        lower[down] = np.maximum(h.floor, centre[down] * (1 - width))
        moved = np.concatenate([up, down])
        first[moved] = False
        if moved.size:
            ends = np.concatenate([upper[up], lower[down]])
            h_moved = h(ends, usable[moved])
            h_upper[up], h_lower[down] = h_moved[: up.size], h_moved[up.size:]
    # a sign change inside the stroke: the root is there, and the piston is off its stop
    inside = (h_lower > 0) & (h_upper < 0)
    if inside.any():
        h.solve_in(lower[inside], upper[inside], usable[inside], h_lower[inside],
                   h_upper[inside], (h_middle[inside], first[inside]))
    return usable[inside]


def _solve_over_stroke(h: _FlowingBalance, pending: np.ndarray) -> None:
    """The points ``pending`` over the whole stroke: on the stop where h >= 0 at the top, no
    equilibrium where h <= 0 at the floor, otherwise the root between. A closing piston where
    h <= 0 at both ends may still be held inside the stroke coming down from the stop
    (:func:`_down_from_the_stop`)."""
    at_top = h(np.full(pending.size, h.stroke), pending)
    broken = ~np.isfinite(at_top)
    at_stop = ~broken & (at_top >= 0)
    h.status[pending[broken]] = Status.MAP_FAILURE
    h.u[pending[at_stop]], h.status[pending[at_stop]] = h.stroke, Status.AT_STOP
    pending, top = pending[~broken & ~at_stop], at_top[~broken & ~at_stop]
    if not pending.size:
        return
    at_floor = h(np.full(pending.size, h.floor), pending)
    broken_floor = ~np.isfinite(at_floor)
    h.status[pending[broken_floor]] = Status.MAP_FAILURE
    no_equilibrium = ~broken_floor & (at_floor <= 0)
    h.status[pending[no_equilibrium]] = Status.NO_EQUILIBRIUM
    keep = ~broken_floor & ~no_equilibrium
    bracketed = pending[keep]
    h.solve_in(np.full(bracketed.size, h.floor), np.full(bracketed.size, h.stroke), bracketed,
               at_floor[keep], top[keep])
    closing = no_equilibrium & ~h.opens[pending]
    if closing.any():
        _down_from_the_stop(h, pending[closing], top[closing])


def _down_from_the_stop(h: _FlowingBalance, which: np.ndarray, top: np.ndarray) -> None:
    """Closing points with h < 0 on the stop and h <= 0 at the floor: where h >= 0 somewhere
    between, a piston coming down from the stop stops at the highest such place. h is sampled
    every factor 3 from the stop down to the floor (14 samples, only for these points, which
    need a leak or an effect that lifts h in the middle of the stroke); the root is solved
    between the highest sample with h >= 0 and the one above it."""
    ladder = h.stroke * 3.0 ** -np.arange(1, int(np.ceil(np.log(1 / _OPENING_FLOOR)
                                                         / np.log(3.0))) + 1)
    ladder = ladder[ladder > h.floor]
    values = h(np.tile(ladder, which.size), np.repeat(which, ladder.size)
               ).reshape(which.size, ladder.size)
    held = values >= 0  # NaN: no evidence
    rows = np.flatnonzero(held.any(axis=1))
    if not rows.size:
        return
    first = np.argmax(held[rows], axis=1)  # the highest sample with h >= 0
    above = np.where(first > 0, ladder[np.maximum(first - 1, 0)], h.stroke)
    h_above = np.where(first > 0, values[rows, np.maximum(first - 1, 0)], top[rows])
    sign_change = np.isfinite(h_above)  # a map failure above leaves the point as it was
    h.solve_in(ladder[first][sign_change], above[sign_change], which[rows][sign_change],
               values[rows, first][sign_change], h_above[sign_change])


def _first_met(h: _FlowingBalance) -> None:
    """Where a point has an equilibrium of higher priority than the one found, solve for that
    one instead (the rule and the check: module docstring).

    Opening side: h <= 0 at a sample below the root means h crossed zero downwards below it
    (h > 0 at a vanishing opening), so the first equilibrium from closed lies below the lowest
    such sample: the root is solved again between it and the next sample down, or the floor
    (where h <= 0 means no equilibrium, as over the stroke: the flow cannot push the piston off
    its seat). Points on the stop are checked too: an equilibrium inside the stroke comes first.
    Closing side: h >= 0 at a sample above the root means a piston coming down from the stop is
    held above it: solved again between the highest such sample and the next one up, or on the
    stop where h >= 0 there.
    """
    factors = np.asarray(_RULE_FACTORS)
    width = factors.size
    which = np.flatnonzero((h.status == Status.OK) | ((h.status == Status.AT_STOP) & h.opens))
    for _ in range(_RULE_ROUNDS):
        if not which.size:
            return
        root, opens = h.u[which], h.opens[which]
        # the samples [m], nearest to the root first: down towards the floor while opening, up
        # towards the stop while closing
        samples = np.where(opens[:, None], np.maximum(h.floor, root[:, None] / factors),
                           np.minimum(h.stroke, root[:, None] * factors))
        # a sample clipped to the floor or the stop like the one before it is that one
        repeated = np.zeros(samples.shape, dtype=bool)
        repeated[:, 1:] = samples[:, 1:] == samples[:, :-1]
        values = np.empty(samples.shape)
        index = np.broadcast_to(which[:, None], samples.shape)
        values[~repeated] = h.rough(samples[~repeated], index[~repeated])
        # a sign change the coarse tables see is checked on the fine ones, or the maps
        coarse_beyond = ~repeated & np.where(opens[:, None], values <= 0, values >= 0)
        if coarse_beyond.any():
            values[coarse_beyond] = h(samples[coarse_beyond], index[coarse_beyond])
        for k in range(1, width):
            values[repeated[:, k], k] = values[repeated[:, k], k - 1]
        # a sample "beyond": the rule's equilibrium lies further out than it (NaN: no evidence)
        beyond = np.where(opens[:, None], values <= 0, values >= 0)
        rows = np.flatnonzero(beyond.any(axis=1))
        if not rows.size:
            return
        points, opens = which[rows], opens[rows]
        # the farthest sample beyond is the bracket's near end; its far end is the next
        # sample out (not beyond, so of the other sign) or the floor or the stop
        far = width - 1 - np.argmax(beyond[rows, ::-1], axis=1)
        near_end, h_near = samples[rows, far], values[rows, far]
        limit = np.where(opens, h.floor, h.stroke)
        outermost = far == width - 1
        out = np.where(outermost, limit, samples[rows, np.minimum(far + 1, width - 1)])
        h_out = np.where(outermost, np.nan, values[rows, np.minimum(far + 1, width - 1)])
        ask = np.flatnonzero(outermost & (near_end != limit))
        if ask.size:
            h_out[ask] = h(out[ask], points[ask])
        # the limit reached with h still beyond: no equilibrium from closed, or the stop
        on_limit = (near_end == limit) | (outermost & np.where(opens, h_out <= 0, h_out >= 0))
        closed = points[on_limit & opens]
        h.u[closed], h.status[closed] = np.nan, Status.NO_EQUILIBRIUM
        stopped = points[on_limit & ~opens]
        h.u[stopped], h.status[stopped] = h.stroke, Status.AT_STOP
        # a bracket with a sign change (a map failure at its far end leaves the root found)
        again = np.flatnonzero(~on_limit & np.isfinite(h_out))
        if not again.size:
            return
        up = opens[again]
        lower = np.where(up, out[again], near_end[again])
        upper = np.where(up, near_end[again], out[again])
        h_lower = np.where(up, h_out[again], h_near[again])
        h_upper = np.where(up, h_near[again], h_out[again])
        h.solve_in(lower, upper, points[again], h_lower, h_upper)
        which = points[again][h.status[points[again]] == Status.OK]


def _solve_still(model, points, sign):
    """(u, Δp, status) of points without flow: closed (the load pressure that cracks it) or
    held open by the pilot alone."""
    fluid = model.fluid(points)
    stroke = model.valve.U_max

    def residual(u, p_L, i):
        balance = model.balance_without_flow(u, p_L, points[i], fluid[i])
        return balance.net_force - sign[i] * balance.friction

    everyone = np.arange(len(points))
    closed_at_zero_dp = residual(np.zeros(len(points)), points.p_B, everyone)
    held_open = np.flatnonzero(closed_at_zero_dp > 0)
    closed = np.flatnonzero(closed_at_zero_dp <= 0)
    u = np.full(len(points), np.nan)
    dp = np.full(len(points), np.nan)
    status = np.full(len(points), Status.NOT_CONVERGED, dtype=np.int8)

    if held_open.size:
        p_B = points.p_B[held_open]
        top = residual(np.full(held_open.size, stroke), p_B, held_open)
        on_stop = top >= 0
        u[held_open[on_stop]], status[held_open[on_stop]] = stroke, Status.AT_STOP
        between = held_open[~on_stop]
        roots = find_roots(lambda x, i: residual(x, points.p_B[between[i]], between[i]),
                           np.zeros(between.size), np.full(between.size, stroke),
                           xatol=stroke * 1e-30, xrtol=_U_RTOL)
        u[between] = roots.x
        status[between] = np.where(roots.converged, Status.OK, Status.NOT_CONVERGED)
        dp[held_open] = 0.0

    if closed.size:
        base = points.p_B[closed]
        roots = invert_increasing(
            lambda dp, i: residual(np.zeros(i.size), base[i] + dp, closed[i]),
            np.zeros(closed.size), np.full(closed.size, 100.0 * BAR), xatol=1e-6)
        u[closed] = 0.0
        dp[closed] = roots.x
        status[closed] = np.where(roots.converged, Status.CLOSED, Status.NOT_CONVERGED)
    bad = status < 0
    u[bad] = np.nan
    dp[bad] = np.nan
    return u, dp, status
