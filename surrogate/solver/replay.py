"""Replay of a measured time series with quasi-static Coulomb friction (a play operator).

At each sample the friction band ±f_μ holds the piston wherever the net force lies inside it. The
band's two edges are the steady solutions with friction resisting an opening piston, u_open, and
a closing one, u_close (u_open <= u_close because the net force falls with u). Where an effect
bends the balance so that an edge has several equilibria, u_open is the smallest, the one a piston
opening from closed meets, and u_close the largest, the one a piston closing from the stop meets
(:mod:`.steady`, "Several equilibria"): the band is as wide as they allow, whatever the guess a
replay starts from. (A piston already sitting above the first equilibrium of an edge can be
pushed on to the next one; the play keeps it where it is instead.) So the piston

* stays where it was while u_open <= u_prev <= u_close (it sticks),
* is pushed open to u_open when u_prev < u_open,
* is pushed closed to u_close when u_prev > u_close,

i.e. u_k = clip(u_{k−1}, u_open_k, u_close_k): the classic play operator. Both edges come from
one batch solve over all samples; only the clip runs sample by sample. Without friction the edges
coincide and the replay is the steady solution.

Noisy inputs (errors in variables)
----------------------------------
Measured inputs carry sensor noise, and a play fed noisy edges *ratchets*: while the piston
slides open, u_k = max(u_{k−1}, u_open_k) follows the running maximum of the noise, not its
trend, so the replayed piston runs ahead of the real one by about a noise amplitude and keeps
that lead after every turn. The real piston never saw the sensor noise. With ``smoothing`` > 1 the
piston's *state* (where friction holds it) is therefore played on the band edges smoothed over
that many samples (a centred quadratic Savitzky–Golay filter within each run, which follows ramps
and their curvature without lag), while the *prediction* of a sliding sample is the edge at that
sample's own measured inputs, as before: the model still answers each sample's inputs, it just
does not let their noise push the friction state around. On a synthetic log made with the
package's own valve (:mod:`surrogate.synthetic.simulate`, nothing hidden) the true model's residual
RMS is 1.14 times the noise floor with 7 samples, 1.37 times with the classic play
(``python eval/workbench.py`` prints both).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from ..model import ValveModel
from ..points import CLOSING, OPENING, STEADY, OperatingPoints, concatenate
from .map_tables import applies, balance_reader, expandable, tables_for
from .steady import BATCH, Status, solve_steady
from .uncertainty import map_error_gains


@dataclass(frozen=True)
class Replay:
    """A replayed time series.

    Attributes
    ----------
    points : OperatingPoints
        The measured inputs, in time order.
    u : numpy.ndarray
        Piston position [m].
    dp : numpy.ndarray
        Predicted pressure drop p_L − p_B [Pa]; NaN where ``status`` is negative.
    status : numpy.ndarray of int
        :class:`~surrogate.solver.steady.Status` per sample.
    moving : numpy.ndarray of bool
        True where the piston moved at this sample, False where friction held it.
    reasons_outside : numpy.ndarray of int
        Why the maps are queried outside their data: bit flags of
        :mod:`surrogate.maps.coverage`, 0 inside.
    band : numpy.ndarray
        (2, n): the friction band's edges u_open and u_close at each sample [m], kept so that a
        replay with nearby parameters can start from them (``replay(..., guess=...)``).
    map_gain : numpy.ndarray or None
        (2, n): how far ``dp`` [Pa] moves per unit ln C_d error of the flow map (row 0) and per
        unit relative flow-force error of the force map (row 1)
        (:func:`.uncertainty.map_error_gains`); None for maps without an uncertainty, or when
        not asked for.
    map_std : numpy.ndarray or None
        (2, n): the maps' standard deviations of those two errors against the valve (the
        calibrated one and the CFD's own in quadrature, :mod:`surrogate.maps.cfd_error`) [1], so
        that ``map_gain * map_std`` is the one-σ effect (:attr:`map_error`).
    tables : TableView or None
        The samples' rows of the map tables the solver read instead of the maps (a fit's inner
        loop, :mod:`.map_tables`), for the replay's sensitivities to read them alike; None
        where it asked the maps.
    """

    points: OperatingPoints
    u: np.ndarray
    dp: np.ndarray
    status: np.ndarray
    moving: np.ndarray
    reasons_outside: np.ndarray
    band: np.ndarray
    map_gain: np.ndarray | None = None
    map_std: np.ndarray | None = None
    tables: object | None = None

    @property
    def map_error(self) -> np.ndarray | None:
        """(2, n) [Pa]: how far ``dp`` moves for a one-σ error of the flow map (row 0) and of
        the force map (row 1) (:func:`.uncertainty.map_error_effects`); None without."""
        return None if self.map_gain is None else self.map_gain * self.map_std

    @property
    def dp_std(self) -> np.ndarray | None:
        """Standard deviation of ``dp`` [Pa] that the maps' uncertainty implies (None without)."""
        return None if self.map_error is None else np.hypot(self.map_error[0], self.map_error[1])

    @property
    def extrapolating(self) -> np.ndarray:
        """True where the maps are queried outside their data."""
        return self.reasons_outside != 0

    @property
    def p_L(self) -> np.ndarray:
        """Predicted load pressure [Pa]."""
        return self.points.p_B + self.dp

    @property
    def ok(self) -> np.ndarray:
        return self.status >= 0

    def take(self, index) -> "Replay":
        """The replay of some samples only (whole runs, for the friction state to make sense)."""
        return Replay(self.points[index], self.u[index], self.dp[index], self.status[index],
                      self.moving[index], self.reasons_outside[index], self.band[:, index],
                      None if self.map_gain is None else self.map_gain[:, index],
                      None if self.map_std is None else self.map_std[:, index],
                      None if self.tables is None else self.tables[index])


def replay(model: ValveModel, points: OperatingPoints, segments=None, *,
           u_start: float = 0.0, guess: Replay | None = None,
           diagnostics: bool = True, smoothing: int = 1, progress=None) -> Replay:
    """Replay samples in time order with friction as a play.

    Parameters
    ----------
    model : ValveModel
    points : OperatingPoints
        Measured inputs in time order (their ``direction`` is not used: the play decides).
    segments : array_like of labels, optional
        Run label of each sample; the play restarts with the piston at ``u_start`` at the first
        sample of each run. Default: one run.
    u_start : float
        Piston position before each run's first sample [m]; 0, closed, for a ramp from rest.
    guess : Replay, optional
        A replay of the same points with nearby parameters; its friction band starts the solver.
    diagnostics : bool
        False skips what the maps say about themselves, the reasons a sample lies outside their
        data (all 0) and the Δp standard deviation (None): the inner loop of a fit needs
        neither.
    smoothing : int
        Samples over which the band edges are smoothed for the friction state (see the module
        docstring); 1, the default, is the classic play on the edges as they are.
    progress : Progress, optional
        Told how far the solves got, with the time left (:meth:`surrogate.core.progress.Progress.
        stage`), for a log of more than :data:`.steady.BATCH` samples.
    """
    count = len(points)
    stage = None
    # the work: one solve per sample and band edge, then the maps queried at the solutions
    work = (3 if model.has_friction else 2) * count
    if progress is not None and count > BATCH:
        stage = progress.stage("replaying", count, "samples")
    done = [0]

    def solved(points_done: int) -> None:
        done[0] += points_done
        if stage is not None:
            stage(min(count * done[0] // work, count))
    # a fit's inner loop (a guess, no diagnostics) reads each sample's maps from a table
    tables = None if guess is None or diagnostics else _tables(model, points, guess.band)
    u_edges, status_edges = _band_edges(model, points, guess, tables, solved)
    starts = segment_starts(segments, count)
    u, moving, status, _ = play(u_edges[0], u_edges[1], status_edges[0], status_edges[1],
                                 starts, u_start, smoothing)
    fluid = model.fluid(points)
    dp = np.full(count, np.nan)
    reasons = np.zeros(count, dtype=np.int64)
    solved_rows = np.flatnonzero(status >= 0)
    for part in _batches(solved_rows):
        sub = points[part]
        balance = balance_reader(model, sub, fluid[part], None if tables is None
                                 else tables[part])
        dp[part] = balance(u[part], np.arange(len(part))).dp
        if diagnostics:
            reasons[part] = model.extrapolation_reasons(u[part], sub.p_B + dp[part], sub,
                                                        fluid[part])
        solved(len(part) // 2)
    at_stop = (status == Status.OK) & (u >= model.valve.U_max)
    status[at_stop] = Status.AT_STOP
    map_gain = map_std = None
    if diagnostics:
        map_gain, map_std = _map_errors(model, points, u, dp, moving, status, u_edges, solved)
    if stage is not None and count * done[0] // work < count:
        stage(count)
    return Replay(points, u, dp, status, moving, reasons, u_edges, map_gain, map_std, tables)


def _band_edges(model: ValveModel, points: OperatingPoints, guess: Replay | None, tables,
                solved) -> tuple[np.ndarray, np.ndarray]:
    """(u, status) of the friction band's two edges at every sample, (2, samples) each: the
    opening and the closing equilibrium (the same twice without friction), both in one batch
    where they fit, one after the other on a big log. ``solved`` is told of the points done."""
    count = len(points)
    if model.has_friction and 2 * count <= BATCH:  # both edges of the band in one batch
        both = concatenate([points.replace(direction=np.full(count, OPENING)),
                            points.replace(direction=np.full(count, CLOSING))])
        start = None if guess is None else guess.band.ravel()
        edges = solve_steady(model, both, guess=start, positions_only=True,
                             tables=None if tables is None else tables.tile(2))
        return edges.u.reshape(2, count), edges.status.reshape(2, count)
    if model.has_friction:  # a big log: one edge after the other, each solved in batches
        u_edges, status_edges = np.empty((2, count)), np.empty((2, count), dtype=np.int8)
        for row, side in enumerate((OPENING, CLOSING)):
            edge = solve_steady(model, points.replace(direction=np.full(count, side)),
                                guess=None if guess is None else guess.band[row],
                                positions_only=True, solved=solved, tables=tables)
            u_edges[row], status_edges[row] = edge.u, edge.status
        return u_edges, status_edges
    start = None if guess is None else guess.band[0]
    edge = solve_steady(model, points, friction=False, guess=start, positions_only=True,
                        solved=solved, tables=tables)
    return np.vstack([edge.u, edge.u]), np.vstack([edge.status, edge.status])


def _map_errors(model: ValveModel, points: OperatingPoints, u, dp, moving, status, u_edges,
                solved) -> tuple[np.ndarray | None, np.ndarray | None]:
    """(gains, standard deviations), (2, samples) each, of Δp to the maps' errors at the
    replayed states (:func:`map_error_gains`), or (None, None) for maps without uncertainty.
    ``solved`` is told of the points done."""
    count = len(points)
    map_gain = map_std = None
    # a sliding piston sits on the band's edge of its direction; a stuck one stays put
    floats = moving if model.has_friction else np.ones(count, dtype=bool)
    side = np.where(~model.has_friction | ~moving, STEADY,
                    np.where(u <= np.fmin(u_edges[0], u_edges[1]), OPENING, CLOSING))
    held = ~floats | (status == Status.AT_STOP)
    for part in _batches(np.arange(count)):
        found = map_error_gains(model, points[part], u[part], dp[part], side[part], held[part])
        if found is None:
            break
        if map_gain is None:
            map_gain, map_std = np.empty((2, count)), np.empty((2, count))
        map_gain[:, part], map_std[:, part] = found
        solved(len(part) // 2)
    return map_gain, map_std


def _tables(model: ValveModel, points: OperatingPoints, band: np.ndarray):
    """The points' rows of the tables of ``model``'s maps, tabulated around ``band`` where
    missing (:mod:`.map_tables`); None where they would not hold them
    (:func:`.map_tables.applies`), or where the model changes the flow on maps that cannot be
    expanded about a sample's own (:func:`.map_tables.expandable`)."""
    expansions = model.may_change_the_flow
    if not applies(points, model.true_points(points)) or (expansions and not expandable(model)):
        return None
    tables = tables_for(model)
    tables.tabulate(model, points, band, expansions)
    return tables.view(points)


def _batches(index: np.ndarray) -> list[np.ndarray]:
    """``index`` cut into pieces of at most :data:`.steady.BATCH` points: the maps' grids
    allocate a few hundred bytes per point they are asked about, which a log of millions of
    samples would otherwise multiply."""
    return [index[start:start + BATCH] for start in range(0, len(index), BATCH)]


def segment_starts(segments, count: int) -> np.ndarray:
    starts = np.zeros(count, dtype=bool)
    if count:
        starts[0] = True
    if segments is not None:
        labels = np.asarray(segments)
        starts[1:] |= labels[1:] != labels[:-1]
    return starts


#: where a sample's opening comes from in the play (:func:`play`'s ``source``): the start of its
#: run, its own lower or upper band edge (it slides), or the state the piston was left in, the
#: (smoothed) lower or upper edge of the sample that last pushed it (it sticks)
FROM_START, OWN_LOW, OWN_HIGH, STATE_LOW, STATE_HIGH = range(5)


def play(u_open, u_close, status_open, status_close, starts, u_start, smoothing=1):
    """The play, restarting at u_start where ``starts``: the state follows
    clip(state_{k−1}, smoothed edges); a sample where the state slides takes its own edge.

    Returns (u, moving, status, source), ``source`` (2, n): for each sample, where its opening
    comes from (:data:`FROM_START` … :data:`STATE_HIGH`) and the sample whose edge it is (−1 for
    the run's start), which the replay's sensitivities follow (:mod:`.sensitivities`)."""
    count = len(u_open)
    status, low, high, state_low, state_high, high_kind = play_bounds(
        u_open, u_close, status_open, status_close, starts, smoothing)
    solved = status >= 0
    state = _play_states(state_low, state_high, solved, starts, u_start)
    previous = np.empty(count)
    previous[1:] = state[:-1]
    previous[starts] = u_start
    # pushed: the piston slides with this sample's own edge; else it stays where it was
    moving = solved & (state != previous)
    opened = state > previous
    u = np.where(moving, np.where(opened, low, high), state)
    # a sample that stays comes from the edge of the run's last sample that moved
    index = np.arange(count)
    last_moved = np.maximum.accumulate(np.where(moving, index, -1))
    run_start = np.maximum.accumulate(np.where(starts, index, 0))
    stays = ~moving & (last_moved >= run_start) & (last_moved >= 0)
    source = np.full((2, count), -1, dtype=np.int64)
    source[0] = FROM_START
    source[0, moving] = np.where(opened[moving], OWN_LOW, OWN_HIGH)
    source[1, moving] = index[moving]
    mover = last_moved[stays]
    source[0, stays] = np.where(opened[mover], STATE_LOW, high_kind[mover])
    source[1, stays] = mover
    return u, moving, status, source


def play_bounds(u_open, u_close, status_open, status_close, starts, smoothing=1):
    """What the play clamps each sample's state into: (status, low, high, state_low,
    state_high, high_kind), the band's edges as they are and as the state sees them (smoothed
    over ``smoothing`` samples), and which edge the state's upper bound is."""
    status = np.where(status_open < 0, status_open, np.where(status_close < 0, status_close,
                                                             Status.OK)).astype(np.int8)
    low = np.fmin(u_open, u_close)
    high = np.fmax(u_open, u_close)
    if smoothing > 1:
        solved = status >= 0
        state_low = smoothed_edge(low, starts, solved, smoothing)
        smoothed_high = smoothed_edge(high, starts, solved, smoothing)
        state_high = np.fmax(smoothed_high, state_low)
        # where the smoothed upper edge falls below the lower one, the state's upper bound is
        # the lower edge
        high_kind = np.where(smoothed_high >= state_low, STATE_HIGH, STATE_LOW)
    else:
        state_low, state_high = low, high
        high_kind = np.full(len(u_open), STATE_HIGH)
    return status, low, high, state_low, state_high, high_kind


def _play_states(state_low, state_high, solved, starts, u_start) -> np.ndarray:
    """The piston's state after each sample, state_k = clip(state_{k−1}, low_k, high_k), by a
    prefix scan instead of a loop: each sample's step is a clamp into [a, b] (none where it is
    unsolved; the constant u_start clipped to its band where a run starts), and a clamp after
    a clamp is a clamp, [clip(a₁, a₂, b₂), clip(b₁, a₂, b₂)], so ⌈log₂ n⌉ vector passes compose
    them all. min and max round nothing: the states are the loop's to the bit."""
    count = len(state_low)
    a = np.where(solved, state_low, -np.inf)
    b = np.where(solved, state_high, np.inf)
    restart = np.minimum(np.maximum(u_start, a), b)
    a, b = np.where(starts, restart, a), np.where(starts, restart, b)
    step = 1
    while step < count:
        later_a, later_b = a[step:], b[step:]
        a = np.concatenate([a[:step], np.minimum(np.maximum(a[:-step], later_a), later_b)])
        b = np.concatenate([b[:step], np.minimum(np.maximum(b[:-step], later_a), later_b)])
        step *= 2
    return np.minimum(np.maximum(u_start, a), b)


def smoothed_edge(edge: np.ndarray, starts: np.ndarray, solved: np.ndarray, window: int
                  ) -> np.ndarray:
    """``edge`` (n,) or (n, columns) smoothed within each run (quadratic Savitzky–Golay over
    ``window`` samples, scipy's ``savgol_filter(..., mode="interp")``); unsolved samples are
    bridged by linear interpolation first."""
    result = edge.copy()
    bounds = [*np.flatnonzero(starts).tolist(), len(edge)]
    for begin, end in zip(bounds[:-1], bounds[1:]):
        good = solved[begin:end]
        size = min(window, (end - begin) // 2 * 2 - 1)  # odd, and no longer than the run
        if good.sum() < 2 or size < 5:
            continue
        run = edge[begin:end]
        if not good.all():
            index = np.arange(end - begin)
            run = np.column_stack([np.interp(index, index[good], column[good])
                                   for column in run.reshape(end - begin, -1).T]
                                  ).reshape(run.shape)
        result[begin:end] = _savgol(run, size | 1)
    return result


@lru_cache(maxsize=16)
def _savgol_operators(size: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The quadratic Savitzky–Golay filter over ``size`` samples as linear maps: the centre
    weights, and the matrices that give the first and the last size//2 outputs from the first
    and the last ``size`` inputs (the quadratic fitted to them and evaluated there)."""
    half = size // 2
    fit = np.linalg.pinv(np.vander(np.arange(size, dtype=float), 3))
    # the centre weights in closed form (a quadratic's least squares over -m..m, evaluated at
    # 0): exact to rounding, and without importing scipy.signal (0.7 s of every command's start)
    offset = np.arange(-half, half + 1, dtype=float)
    centre = ((3 * (3 * half**2 + 3 * half - 1) - 15 * offset**2)
              / ((2 * half + 1) * (2 * half - 1) * (2 * half + 3)))
    return (centre,
            np.vander(np.arange(half, dtype=float), 3) @ fit,
            np.vander(np.arange(size - half, size, dtype=float), 3) @ fit)


def _savgol(x: np.ndarray, size: int) -> np.ndarray:
    """``x`` (L, ...) smoothed along its first axis as ``savgol_filter(x, size, 2,
    mode="interp", axis=0)`` (to rounding), with the filter's weights computed once."""
    weights, first, last = _savgol_operators(size)
    half, length = size // 2, len(x)
    y = np.empty_like(x)
    y[half:length - half] = sliding_window_view(x, size, axis=0) @ weights
    # np.tensordot(first, x[:size], axes=(1, 0))'s own product, to the bit, without its
    # handling of general axes (every run's band edges, at every replay)
    ends = (half, *x.shape[1:])
    y[:half] = np.dot(first, x[:size].reshape(size, -1)).reshape(ends)
    y[length - half:] = np.dot(last, x[length - size:].reshape(size, -1)).reshape(ends)
    return y
