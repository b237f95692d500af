"""Maps evaluated once: each sample's maps tabulated along the opening while a fit runs.

While a fit runs, the maps do not change. For one sample of a log (its flow q, back pressure p_B
and temperature), what the maps contribute to the force balance, the pressure drop Δp(u) that
passes q and the flow force f_ff(u) at that Δp, is a function of the opening u alone. A fit
replays its log dozens of times, and the solver asks the balance about a dozen times per sample
and replay, each time asking both maps (a Gaussian process, a network ensemble, or a grid of
PCHIP curves) afresh. So the first replay of a fit tabulates each sample's maps once, around the
openings where its piston was (its friction band, :data:`LEVELS`), and the solver reads the
tables from then on; an opening outside a sample's table asks the maps, as before.

Effects that change the flow
----------------------------
A leak, a discharge correction or a flowmeter's gain send another flow q_r than the measured one
through the restriction, and so ask the force map about another Δp. For models with such an
effect on smooth maps (:attr:`surrogate.maps.base.FlowMap.smooth`: the learned ones, an orifice)
each node also keeps ln Δp as a quartic in ln q_r and r = f_ff/Δp as one in ln Δp, through the
maps at five flows (and pressure drops) :data:`_EXPANSION_STEP` apart about the sample's own;
read within :data:`EXPANSION_REACH` of them, further away the maps are asked. A grid map's
sweeps are C¹ PCHIP curves held at their ends, with kinks no polynomial follows: models that
change the flow on grid maps ask the maps. The effects themselves are evaluated as always: only
the maps are tabulated.

The tables
----------
Nodes lie on one grid in ln u shared by all samples, plus the openings where a map has a kink
along u (a grid map's sampled openings, :meth:`surrogate.maps.base.FlowMap.opening_knots`); each
sample holds a contiguous window of it. Per node the tables keep ln Δp and r (smooth where f_ff
itself varies like Δp, as u⁻²) and their slopes in ln u, from the node values by three-point
differences, one-sided at a window's ends and at kinks: between two nodes both are cubic
Hermite interpolants, C¹ between kinks, third order in the step; the expansions' coefficients
are made at every :data:`EXPANSION_EVERY`-th node and linear in ln u between. ``python
eval/map_tables_accuracy.py`` compares the tables with the maps over the shipped log's bands (a
grid map's Δp, linear in ln u between kinks that are nodes, is exact) and a replay read from
them with one that asks the maps.

A row also keeps the maps' own answers with the piston on its stop (Δp at the sample's flow,
and the flow force at that Δp), asked of the maps when the row is tabulated: no window holds the
stroke itself, and a replay asks the balance there for every sample on the stop at each step, so
it reads them there instead of asking again (the same values, to the bit).

Who reads them: the replays of a fit's inner loop (a guess, no diagnostics) and their
sensitivities (:mod:`.replay`, :mod:`.sensitivities`); what is reported (a replay without a
guess, or with diagnostics) asks the maps. Rows are keyed by the measured inputs that fix a
sample's maps (q, p_B, temperature): a replay of some of a log's runs finds the rows already
there. One store per pair of maps, freed with them.
"""

from __future__ import annotations

import hashlib
import threading
import weakref
from typing import NamedTuple

import numpy as np

from ..model import Balance, ValveModel
from ..points import OperatingPoints
from .asked_maps import asked_balance

#: the tables' levels: node spacing in ln u [1], and how far beyond a sample's band (the
#: smallest and largest of its edges) the window reaches, in ln u [1]. The fine level holds the
#: solver's brackets around a guess (±2 %, then ±10 %). The coarse one serves only the sign
#: checks of the rule that picks among several equilibria, a factor 3 below an opening edge and
#: above a closing one (:mod:`.steady`): h is far from zero there on a valve with one
#: equilibrium, and the solver asks again on the fine level or the maps where the coarse one
#: finds a sign change.
LEVELS = ((0.01, 0.12), (0.2, np.log(3.0) + 0.2))
#: the level every balance reads, and the one the sign checks may read too
FINE, COARSE = 0, 1
#: nodes a store holds at most over its levels (about 40 bytes each with expansions): one that
#: would outgrow it starts afresh
MAX_NODES = 1_000_000
#: how far from the sample's own flow (in ln q_r) and pressure drop (in ln Δp) an expansion is
#: read [1]; beyond, the maps are asked
EXPANSION_REACH = 0.15
#: the spacing of the five flows and pressure drops an expansion passes through [1]
_EXPANSION_STEP = 0.05
#: expansions are made and stored at every this many nodes of a window (and at its last),
#: linear in ln u between: they multiply steps of at most EXPANSION_REACH, so their own error
#: counts that much less (smooth maps alone have them, and no kinks)
EXPANSION_EVERY = 4
#: sets of points whose rows a store remembers (a fit's log, its held-out subsets)
_KNOWN_VIEWS = 64
#: nodes tabulated in one call of the maps: their temporaries then stay in the processor's cache
_BLOCK = 4096
#: samples tabulated at a time (about 50 nodes each)
_SAMPLES_AT_A_TIME = 2048
#: nodes closer than this fraction of a step to a kink are dropped, so that no segment is tiny
_KINK_CLEARANCE = 0.25
#: a node's record: ln Δp and r = f_ff/Δp, and their slopes in ln u to the right of the node,
#: then to its left (the two differ at kinks), side by side as the interpolation gathers them;
#: the slopes in single precision (they multiply a step of at most 0.01 in ln u)
_NODE = np.dtype([("value", np.float64, 2), ("right", np.float32, 2), ("left", np.float32, 2)])
#: columns of a level's expansions: the first to fourth derivatives of ln Δp in ln q_r, then of
#: r in ln Δp, at the sample's own flow and Δp (single precision: they multiply small steps)
_EXPANSIONS = 8


def expandable(model: ValveModel) -> bool:
    """Whether ``model``'s maps may be read from a polynomial about a sample's own flow and Δp
    (:attr:`surrogate.maps.base.FlowMap.smooth`)."""
    return model.flow_map.smooth and model.force_map.smooth


class _Level:
    """One level of a store: its nodes in ln u, and each row's window of them."""

    def __init__(self, step: float, reach: float, knots: np.ndarray, stroke: float):
        self.step, self.reach, self.top = step, reach, np.log(stroke)
        low, high = np.log(stroke) - 20.0, np.log(stroke) + 1.0
        uniform = np.arange(np.floor(low / step), np.ceil(high / step) + 1) * step
        if knots.size:
            distance = np.min(np.abs(uniform[:, None] - knots[None, :]), axis=1)
            uniform = uniform[distance > _KINK_CLEARANCE * step]
        self.nodes = np.unique(np.concatenate([uniform, knots]))
        self.kink = np.isin(self.nodes, knots)
        self.locate = _Locator(self.nodes, _KINK_CLEARANCE * step / 2)
        self.clear()

    def clear(self) -> None:
        # per row: first node, node count, offset into the flat values; buffers that grow in
        # place (amortised), their rows never rewritten: what a reader found there stays true
        self.rows = self.nodes_used = self.expansions_used = 0
        self.first = np.empty(0, np.intp)
        self.count = np.empty(0, np.intp)
        self.offset = np.empty(0, np.intp)
        self.expansion_offset = np.empty(0, np.intp)  # a row's first entry in expansions
        self.values = np.empty(0, _NODE)
        self.expansions = np.empty((0, _EXPANSIONS), np.float32)  # at expansion_nodes only

    def windows(self, x_low: np.ndarray, x_high: np.ndarray):
        """(first node, node count) of windows reaching :attr:`reach` beyond [x_low, x_high]
        (ln u), up to the stroke, at least three nodes each."""
        low = x_low - self.reach
        high = np.minimum(x_high + self.reach, self.top)
        last = len(self.nodes) - 1
        begin = np.clip(np.searchsorted(self.nodes, low, "right") - 1, 0, last - 2)
        end = np.clip(np.searchsorted(self.nodes, high, "left"), begin + 2, last)
        return begin, end - begin + 1

    def holds(self, rows: np.ndarray, x_low: np.ndarray, x_high: np.ndarray) -> np.ndarray:
        """Whether each row's window reaches half :attr:`reach` beyond [x_low, x_high] (or to
        the stroke); False for rows −1."""
        held = (rows >= 0) & (rows < self.rows)
        if not held.any():
            return held
        safe = np.where(held, rows, 0)
        start = self.nodes[self.first[safe]]
        stop = self.nodes[self.first[safe] + self.count[safe] - 1]
        room = 0.5 * self.reach
        return held & (start <= x_low - room) & (
            (stop >= x_high + room) | (stop >= self.top))

    def reserve(self, rows: int, nodes: int, entries: int) -> None:
        """Room for this many more rows, nodes and expansion entries, made at once: the
        buffers of a tabulation in blocks would otherwise grow (and be copied) block by
        block."""
        self.first, self.count, self.offset, self.expansion_offset = (
            _room(array, self.rows + rows, slack=1.0)
            for array in (self.first, self.count, self.offset, self.expansion_offset))
        self.values = _room(self.values, self.nodes_used + nodes, slack=1.0)
        self.expansions = _room(self.expansions, self.expansions_used + entries, slack=1.0)

    def append(self, begin, count, values, expansions) -> None:
        rows, nodes, entries = len(begin), len(values), len(expansions)
        self.first, self.count, self.offset, self.expansion_offset = (
            _room(array, self.rows + rows)
            for array in (self.first, self.count, self.offset, self.expansion_offset))
        self.values = _room(self.values, self.nodes_used + nodes)
        self.expansions = _room(self.expansions, self.expansions_used + entries)
        new = slice(self.rows, self.rows + rows)
        self.first[new], self.count[new] = begin, count
        self.offset[new] = self.nodes_used + np.cumsum(count) - count
        held = expansion_nodes(count)
        self.expansion_offset[new] = self.expansions_used + np.cumsum(held) - held
        self.values[self.nodes_used:self.nodes_used + nodes] = values
        self.expansions[self.expansions_used:self.expansions_used + entries] = expansions
        self.rows += rows
        self.nodes_used += nodes
        self.expansions_used += entries

    def snapshot(self) -> "_Snapshot":
        return _Snapshot(self.nodes, self.first, self.count, self.offset, self.values,
                         self.expansion_offset, self.expansions, self.locate)


def expansion_nodes(count: np.ndarray) -> np.ndarray:
    """How many of a window's ``count`` nodes hold expansions: every
    :data:`EXPANSION_EVERY`-th from its first, and its last."""
    return (count - 2) // EXPANSION_EVERY + 2


def _ranges(starts: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """The indices start, start + 1, ..., start + length − 1 of every range, end to end."""
    return np.repeat(starts, lengths) + np.arange(lengths.sum()) - np.repeat(
        np.cumsum(lengths) - lengths, lengths)


def _room(array: np.ndarray, length: int, slack: float = 1.5) -> np.ndarray:
    """``array``, or a copy ``slack`` times as long as ``length`` (half as long again by
    default) with its rows, where it is too short to hold ``length`` rows."""
    if len(array) >= length:
        return array
    grown = np.empty((int(slack * length) + 16, *array.shape[1:]), array.dtype)
    grown[: len(array)] = array
    return grown


class _Snapshot(NamedTuple):
    """A level as a view took it: its nodes, each row's window and values, its locator."""

    nodes: np.ndarray
    first: np.ndarray
    count: np.ndarray
    offset: np.ndarray
    values: np.ndarray
    expansion_offset: np.ndarray
    expansions: np.ndarray
    locate: "_Locator"


class _Locator:
    """The segment of the nodes (ascending, in ln u) each x lies in, as
    ``searchsorted(nodes, x, "right") − 1``, from a table of uniform buckets narrower than
    most segments: a gather and a comparison or two instead of a binary search."""

    def __init__(self, nodes: np.ndarray, width: float):
        self.nodes = np.append(nodes, np.inf)  # x beyond the last node: its segment
        self.origin, self.width = float(nodes[0]), width
        edges = self.origin + width * np.arange(int(np.ceil((nodes[-1] - nodes[0]) / width)) + 1)
        self.segment = np.searchsorted(nodes, edges, "right") - 1

    def __call__(self, x: np.ndarray) -> np.ndarray:
        return self.with_ends(x)[0]

    def with_ends(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(segment, its left node, its right node) of each x: the nodes the search compared
        x with last, which an interpolation would otherwise gather again (the left one is the
        first node for a segment of −1, the right one +inf beyond the last node)."""
        # fmin/fmax and np.take: as clip, nan_to_num and fancy indexing, at a fraction of
        # their overhead (every balance a fit evaluates reads the tables here)
        with np.errstate(invalid="ignore"):
            bucket = np.fmin(np.fmax((x - self.origin) / self.width, 0), len(self.segment) - 1)
        segment = self.segment.take(bucket.astype(np.intp))
        # a bucket may hold a node (or, between close kinks, several); rounding may miss by one
        while True:
            left = self.nodes.take(np.maximum(segment, 0))
            right = self.nodes.take(segment + 1)
            below = x < left
            below &= segment >= 0
            above = x >= right
            if not (below.any() or above.any()):
                return segment, left, right
            segment = np.minimum(segment - below + above, len(self.nodes) - 2)


class MapTables:
    """The tabulated maps of many samples, for one pair of maps.

    Get it with :func:`tables_for`; :meth:`tabulate` adds or renews samples' rows,
    :meth:`view` reads them.
    """

    def __init__(self, model: ValveModel):
        self.stroke = model.valve.U_max
        knots = np.concatenate([model.flow_map.opening_knots(), model.force_map.opening_knots()])
        knots = np.log(knots[(knots > 0) & np.isfinite(knots)])
        self.levels = [_Level(step, reach, knots, self.stroke) for step, reach in LEVELS]
        self._lock = threading.Lock()
        self._keys: dict[bytes, int] = {}
        self._known: dict[bytes, np.ndarray] = {}
        self._expanded = np.empty(0, bool)  # per row: whether it holds expansions
        # per row: the maps with the piston on its stop, as they answer there (Δp at the
        # measured flow, the flow force at that Δp): a replay asks the balance of every sample
        # on the stop there at each step, and no window holds the stroke itself
        self._at_stroke = np.empty((0, 2))
        # counts the stores' clearings: a view of an earlier generation finds no rows
        self.generation = 0

    @property
    def size(self) -> int:
        """Nodes held over all levels."""
        return sum(level.nodes_used for level in self.levels)

    @staticmethod
    def _row_keys(points: OperatingPoints) -> list[bytes]:
        keys = np.ascontiguousarray(np.column_stack([points.q, points.p_B, points.temperature]))
        return [row.tobytes() for row in keys]

    def tabulate(self, model: ValveModel, points: OperatingPoints, band: np.ndarray,
                 expansions: bool = False) -> None:
        """Tabulate (or renew) the rows of the flowing (measured) ``points`` whose ``band``
        (2, n) [m] of openings a level does not hold with room to spare (half its reach), or
        that lack ``expansions`` (:attr:`~surrogate.model.ValveModel.may_change_the_flow`)."""
        band = np.asarray(band, float)
        with np.errstate(invalid="ignore"):
            low, high = np.nanmin(band, axis=0), np.nanmax(band, axis=0)
        usable = np.isfinite(low) & (low > 0) & (points.q > 0)
        x_low = np.log(np.where(usable, low, 1.0))
        x_high = np.log(np.where(usable, high, 1.0))
        view = self.view(points)
        with self._lock:
            rows = view.row if view.generation == self.generation else np.full(len(points), -1)
            covered = np.logical_and.reduce([level.holds(rows, x_low, x_high)
                                             for level in self.levels])
            if expansions:
                covered &= self._expanded[np.clip(rows, 0, max(len(self._expanded) - 1, 0))] \
                    if len(self._expanded) else False
            # what the rows being renewed hold now (rows are never rewritten, and a compaction
            # below makes new buffers): their nodes' values are the maps' and are not asked again
            before = [level.snapshot() for level in self.levels], self._at_stroke
        todo = np.flatnonzero(usable & ~covered)
        if not todo.size:
            return
        # unique inputs only: repeated samples share a row
        keys = self._row_keys(points[todo])
        _, unique = np.unique(np.asarray(keys, dtype=object), return_index=True)
        todo, keys = todo[unique], [keys[i] for i in unique]
        renewed = rows[todo]
        windows = [level.windows(x_low[todo], x_high[todo]) for level in self.levels]
        total = sum(int(count.sum()) for _, count in windows)
        if total > MAX_NODES:
            return
        with self._lock:
            if self.size + total > MAX_NODES:
                self._compact(total)
            for level, (_, count) in zip(self.levels, windows):
                level.reserve(len(todo), int(count.sum()), int(expansion_nodes(count).sum()))
        # a block of samples at a time, so that the maps' and the slopes' temporaries stay
        # small; each block's rows are usable as soon as they are in
        for block in range(0, len(todo), _SAMPLES_AT_A_TIME):
            part = slice(block, block + _SAMPLES_AT_A_TIME)
            sub = points[todo[part]]
            tables = [_tabulate(model, sub, level, begin[part], count[part], expansions,
                                _held_values(snapshot, renewed[part], begin[part], count[part]))
                      for level, snapshot, (begin, count) in zip(self.levels, before[0],
                                                                 windows)]
            at_stroke = _maps_at_stroke(model, sub, self.stroke, before[1], renewed[part])
            with self._lock:
                self._known = {}
                start = self.levels[0].rows
                for level, (begin, count), (values, expanded) in zip(self.levels, windows,
                                                                      tables):
                    level.append(begin[part], count[part], values, expanded)
                self._expanded = np.concatenate([self._expanded,
                                                 np.full(len(sub), expansions)])
                self._at_stroke = np.concatenate([self._at_stroke, at_stroke])
                for i, key in enumerate(keys[part]):  # a renewed row replaces the old one
                    self._keys[key] = start + i

    def view(self, points: OperatingPoints) -> "TableView":
        """The rows of ``points`` as the store holds them now (−1 where it has none);
        tabulating more later does not change the view."""
        # a fit replays the same samples again and again: their rows are remembered by a
        # digest of the inputs that key them, until rows are added
        digest = hashlib.blake2b(digest_size=16)
        for column in (points.q, points.p_B, points.temperature):
            digest.update(np.ascontiguousarray(column, float).tobytes())
        digest = digest.digest()
        with self._lock:
            rows = self._known.get(digest)
            if rows is None:
                get = self._keys.get
                rows = np.fromiter((get(key, -1) for key in self._row_keys(points)), np.intp,
                                   len(points))
                if len(self._known) >= _KNOWN_VIEWS:
                    self._known.clear()
                self._known[digest] = rows
            return TableView(rows, self, self.generation)

    def maps_at_stroke(self, generation: int) -> np.ndarray | None:
        """(rows, 2): each row's Δp [Pa] and flow force [N] with the piston on the stop, as the
        maps answer there; None after a clearing since ``generation``."""
        with self._lock:
            return self._at_stroke if generation == self.generation else None

    def snapshots(self, generation: int) -> list[_Snapshot] | None:
        """The levels as they are now, or None after a clearing since ``generation``."""
        with self._lock:
            if generation != self.generation:
                return None
            return [level.snapshot() for level in self.levels]

    def _compact(self, room: int) -> None:
        """Keep only each key's latest row (renewed rows leave their old ones behind), in new
        buffers: views taken before find none and ask the maps. Clear all where even the
        latest rows leave no ``room`` [nodes]."""
        live = np.array(sorted(self._keys.values()), np.intp)
        kept = sum(int(level.count[live].sum()) for level in self.levels)
        if kept + room > MAX_NODES:
            self._clear()
            return
        renumber = {row: new for new, row in enumerate(live.tolist())}
        for level in self.levels:
            first, count = level.first[live], level.count[live]
            values = level.values[_ranges(level.offset[live], count)]
            expansions = level.expansions[_ranges(level.expansion_offset[live],
                                                  expansion_nodes(count))]
            level.clear()
            level.append(first, count, values, expansions)
        self._keys = {key: renumber[row] for key, row in self._keys.items()}
        self._expanded = self._expanded[live]
        self._at_stroke = self._at_stroke[live]
        self._known = {}
        self.generation += 1

    def _clear(self) -> None:
        for level in self.levels:
            level.clear()
        self._keys, self._known, self._expanded = {}, {}, np.empty(0, bool)
        self._at_stroke = np.empty((0, 2))
        self.generation += 1


def _held_values(level: _Snapshot, rows: np.ndarray, begin: np.ndarray, count: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """(held, (held.sum(), 2) ln Δp and r): which nodes of the new windows (``begin``,
    ``count``) the points' current ``rows`` of ``level`` (−1: none) hold already, and their
    values there. A row renewed for a moved band or for expansions keeps its sample's inputs,
    and the nodes lie on the level's one grid, so a node both windows share has the same maps'
    values: only the others are asked for."""
    total = int(count.sum())
    row = np.repeat(rows, count)
    held = (row >= 0) & (row < len(level.first))
    if not held.any():
        return held, np.empty((0, 2))
    position = np.arange(total) - np.repeat(np.cumsum(count) - count, count)
    safe = np.where(held, row, 0)
    local = np.repeat(begin, count) + position - level.first[safe]
    held &= (local >= 0) & (local < level.count[safe])
    return held, level.values["value"][level.offset[safe[held]] + local[held]]


def _tabulate(model: ValveModel, points: OperatingPoints, level: _Level, begin, count,
              expansions: bool, held=None):
    """The node records (count.sum(), :data:`_NODE`) of ``points``' windows of ``level``, and
    the expansions (expansion_nodes(count).sum(), :data:`_EXPANSIONS`; NaN without
    ``expansions``) at every :data:`EXPANSION_EVERY`-th node of a window and its last.
    ``held``: the nodes whose values a row being renewed holds already, and those values
    (:func:`_held_values`); the maps are asked for the others."""
    which = np.repeat(np.arange(len(points)), count)
    position = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
    node = np.repeat(begin, count) + position
    u = np.exp(level.nodes[node])
    values = np.empty((2, u.size))
    if held is None:
        held = np.zeros(u.size, bool), np.empty((0, 2))
    values[:, held[0]] = held[1].T
    asked = np.flatnonzero(~held[0])
    if asked.size:
        log_dp, ratio = _maps_at(model, points, which[asked], u[asked], np.zeros(1))
        values[0, asked], values[1, asked] = log_dp[0], ratio[0]
    log_dp, ratio = values[:1], values[1:]
    slopes = _slopes(level.nodes, level.kink, values, begin, count)
    records = np.empty(u.size, _NODE)
    records["value"], records["right"], records["left"] = values.T, slopes[:2].T, slopes[2:].T
    # expansions on a sub-grid, linear in ln u between (as they are read): four in five of the
    # maps' calls were theirs, and their storage most of the tables'
    at = np.flatnonzero((position % EXPANSION_EVERY == 0)
                        | (position == np.repeat(count, count) - 1))
    if not expansions:
        return records, np.full((at.size, _EXPANSIONS), np.nan, np.float32)
    shifted_dp, shifted_ratio = _maps_at(model, points, which[at], u[at],
                                         _EXPANSION_STEP * np.array([-2.0, -1.0, 1.0, 2.0]),
                                         np.exp(log_dp[0, at]))
    around = np.vstack([shifted_dp[:2], log_dp[:, at], shifted_dp[2:]])
    ratios = np.vstack([shifted_ratio[:2], ratio[:, at], shifted_ratio[2:]])
    # the quartic through the five: its derivatives at the centre, by five-point differences
    h = _EXPANSION_STEP
    differences = np.array([[1, -8, 0, 8, -1], [-1, 16, -30, 16, -1], [-1, 2, 0, -2, 1],
                            [1, -4, 6, -4, 1]]) / np.array([[12 * h], [12 * h**2], [2 * h**3],
                                                            [h**4]])
    expanded = np.vstack([differences @ around, differences @ ratios]).T
    return records, np.ascontiguousarray(expanded, np.float32)


def _maps_at_stroke(model: ValveModel, points: OperatingPoints, stroke: float,
                    held: np.ndarray | None = None, rows: np.ndarray | None = None
                    ) -> np.ndarray:
    """(len(points), 2): Δp [Pa] at each (measured) point's flow with the piston on the stop
    (``stroke`` [m]), and the flow force [N] at that Δp, asked of the maps as
    :class:`TabulatedMaps` asks them for a point no window holds: the same values. A point
    whose current row of ``held`` (the store's, ``rows``; −1: none) is being renewed keeps
    them."""
    found = np.empty((len(points), 2))
    kept = (np.zeros(len(points), bool) if rows is None
            else (rows >= 0) & (rows < len(held)))
    found[kept] = held[rows[kept]]
    asked = np.flatnonzero(~kept)
    if asked.size:
        sub = points[asked]
        fluid = model.fluid(sub)
        u = np.full(len(sub), stroke)
        dp = model.flow_map.pressure_drop(sub.q, sub.p_B, u, fluid)
        found[asked] = np.column_stack([dp, model.flow_force(u, dp, sub, fluid)])
    return found


def _maps_at(model: ValveModel, points: OperatingPoints, which: np.ndarray, u: np.ndarray,
             steps: np.ndarray, dp: np.ndarray | None = None):
    """(len(steps), len(u)) ln Δp at the flows e^step·q of the samples ``which`` of
    ``points``, and r = f_ff/Δp at the pressure drops e^step·Δp, where Δp is given (``dp``
    [Pa]) or that of step 0 (``steps`` then holds 0 alone)."""
    log_dp = np.empty((len(steps), u.size))
    ratio = np.empty((len(steps), u.size))
    # each sample's own flow and fluid state at every one of its nodes: what the map finds at
    # the flow alone it may find once (FlowMap.at_flows), and the oil's state is found once
    fluids = model.fluid(points)
    own_flow = model.flow_map.at_flows(points.q, points.p_B, fluids)
    for block in range(0, u.size, _BLOCK):
        part = slice(block, block + _BLOCK)
        at = points[which[part]]
        fluid = fluids[which[part]]
        for row, step in enumerate(steps):
            log_dp[row, part] = np.log(
                own_flow(u[part], which[part]) if step == 0.0 else
                model.flow_map.pressure_drop(at.q * np.exp(step), at.p_B, u[part], fluid))
        centre = np.exp(log_dp[0, part]) if dp is None else dp[part]
        for row, step in enumerate(steps):
            shifted = centre * np.exp(step)
            ratio[row, part] = model.flow_force(u[part], shifted, at, fluid) / shifted
    return log_dp, ratio


class TableView:
    """Some points' rows of a :class:`MapTables`: rows are never rewritten, so a view reads
    what it found until the store is cleared (then it finds none, and the maps answer)."""

    def __init__(self, rows: np.ndarray, store: MapTables, generation: int):
        self.row, self.store, self.generation = rows, store, generation

    @property
    def levels(self) -> list[_Snapshot]:
        """The store's levels, or none after a clearing."""
        return self.store.snapshots(self.generation) or []

    def __getitem__(self, index) -> "TableView":
        rows = (self.row.take(index) if isinstance(index, np.ndarray) and index.dtype.kind in "iu"
                else self.row[index])
        return TableView(rows, self.store, self.generation)

    def maps_at_stroke(self) -> np.ndarray | None:
        """The store's maps with the piston on the stop, per row
        (:meth:`MapTables.maps_at_stroke`); None after a clearing."""
        return self.store.maps_at_stroke(self.generation)

    def tile(self, times: int) -> "TableView":
        """The view of the points repeated ``times`` over, as a replay stacks a band's edges."""
        return TableView(np.tile(self.row, times), self.store, self.generation)

    def read(self, u: np.ndarray, coarsest: int = FINE, expansions: bool = False):
        """(inside, (2, n) ln Δp and r, (4, n) expansions or None) of the view's points at
        openings ``u`` [m], from the finest level (up to ``coarsest``) whose window holds u;
        ``inside`` is False (and the values NaN) where a point has no row or no such window
        holds u."""
        u = np.asarray(u, float)
        with np.errstate(divide="ignore", invalid="ignore"):
            x = np.log(u)
        pending = np.flatnonzero((self.row >= 0) & np.isfinite(x))
        levels = self.levels[: coarsest + 1]
        finest = None
        if levels and pending.size == u.size:  # every point (a fit's usual case): no gathers
            finest = _interpolate(levels[0], self.row, x.ravel(), expansions)
            if finest[0].all():
                return finest
        values = np.full((2, u.size), np.nan)
        expanded = np.full((_EXPANSIONS, u.size), np.nan) if expansions else None
        inside = np.zeros(u.size, bool)
        for level in levels:
            if not pending.size:
                break
            if finest is not None:  # the finest level, read above for every point
                (found, main, extra), finest = finest, None
            else:
                found, main, extra = _interpolate(level, self.row[pending], x[pending],
                                                  expansions)
            at = pending[found]
            values[:, at] = main
            if expansions:
                expanded[:, at] = extra
            inside[at] = True
            pending = pending[~found]
        return inside, values, expanded

    def lookup(self, u: np.ndarray, coarsest: int = FINE
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(Δp [Pa], f_ff [N], inside) of the view's points at openings ``u`` [m] and their
        measured flows (:meth:`read`)."""
        inside, values, _ = self.read(u, coarsest)
        dp = np.exp(values[0])
        return dp, values[1] * dp, inside


def _interpolate(level: _Snapshot, rows: np.ndarray, x: np.ndarray, expansions: bool):
    """(found, (2, found.sum()) ln Δp and r, (4, found.sum()) expansions or None) at ln u ``x``
    of ``rows`` in one level's snapshot: cubic Hermite between the nodes around x, with the
    slope right of the segment's start and left of its end; the expansions linear."""
    if not level.first.size:
        return np.zeros(x.shape, bool), np.empty((2, 0)), np.empty((_EXPANSIONS, 0))
    segment, left, right = level.locate.with_ends(x)
    count = level.count.take(rows)
    local = segment - level.first.take(rows)
    found = (local >= 0) & (local < count - 1)
    if found.all():
        flat = level.offset.take(rows) + local
    else:
        flat, x = level.offset[rows[found]] + local[found], x[found]
        left, right = left[found], right[found]
    # a found segment lies inside its window: its ends are the nodes the search compared with
    width = right - left
    t = (x - left) / width
    # the cubic Hermite basis, its slope terms scaled by the segment's width
    t2 = t * t
    h01 = t2 * (3.0 - 2.0 * t)
    h00 = 1.0 - h01
    h10 = width * t * (1.0 - t) ** 2
    h11 = width * t2 * (t - 1.0)
    start = np.take(level.values, flat)  # np.take: a third of fancy indexing's time
    end = np.take(level.values, flat + 1)
    # one quantity at a time, its single-precision slopes widened first: the same sums in the
    # same order as on the (2, n) transposed fields, in a third of the time
    main = np.empty((2, len(t)))
    for quantity in range(2):
        main[quantity] = (h00 * start["value"][:, quantity] + h01 * end["value"][:, quantity]
                          + h10 * start["right"][:, quantity].astype(np.float64)
                          + h11 * end["left"][:, quantity].astype(np.float64))
    if not expansions:
        return found, main, None
    # linear between the window's expansion nodes around x (expansion_nodes)
    if not found.all():
        rows, local = rows[found], local[found]
    below = np.minimum(local // EXPANSION_EVERY, expansion_nodes(level.count[rows]) - 2)
    low = below * EXPANSION_EVERY
    high = np.minimum(low + EXPANSION_EVERY, level.count[rows] - 1)
    x0 = level.nodes[level.first[rows] + low]
    s = (x - x0) / (level.nodes[level.first[rows] + high] - x0)
    entry = level.expansion_offset[rows] + below
    extra = ((1.0 - s) * np.take(level.expansions, entry, axis=0).T
             + s * np.take(level.expansions, entry + 1, axis=0).T)
    return found, main, extra


def _slopes(nodes, kink, values, begin, count) -> np.ndarray:
    """(4, nodes) slopes in ln u of the rows' two tabulated quantities: rows 0–1 the slope to
    the right of each node, 2–3 to its left; three-point differences, one-sided at a window's
    ends and at kinks (where the two differ)."""
    total = values.shape[1]
    ends = np.cumsum(count)
    starts = ends - count
    position = np.arange(total) - np.repeat(starts, count)
    x = nodes[np.repeat(begin, count) + position]
    at_start = position == 0
    at_end = position == np.repeat(count - 1, count)
    at_kink = kink[np.repeat(begin, count) + position]

    def shifted(array, by):
        out = np.full_like(array, np.nan)
        if by > 0:
            out[..., :-by] = array[..., by:]
        else:
            out[..., -by:] = array[..., :by]
        return out

    x_next, x_prev = shifted(x, 1), shifted(x, -1)
    f, f_next, f_prev = values, shifted(values, 1), shifted(values, -1)
    with np.errstate(invalid="ignore", divide="ignore"):
        a, b = x - x_prev, x_next - x
        central = (-b / (a * (a + b)) * f_prev + (b - a) / (a * b) * f
                   + a / (b * (a + b)) * f_next)
    short = np.repeat(count < 3, count)
    # the right slope: one-sided forward at a window's start or a kink, the secant where no
    # forward stencil fits before the window's end or the next kink; the left one mirrored.
    # The one-sided stencils and secants are formed only at the few nodes that take them
    kink_next = np.append(at_kink[1:], False)
    kink_prev = np.insert(at_kink[:-1], 0, False)
    cramped_right = (position >= np.repeat(count - 2, count)) | kink_next
    cramped_left = (position < 2) | kink_prev
    right_end, left_end = at_start | at_kink, at_end | at_kink
    right, left = central, central.copy()
    with np.errstate(invalid="ignore", divide="ignore"):
        i = np.flatnonzero(~short & right_end & ~cramped_right)  # a forward stencil fits
        c, d = x_next[i] - x[i], x[i + 2] - x_next[i]
        right[:, i] = (-(2 * c + d) / (c * (c + d)) * f[:, i] + (c + d) / (c * d) * f_next[:, i]
                       - c / (d * (c + d)) * f[:, i + 2])
        i = np.flatnonzero(~short & left_end & ~cramped_left)  # a backward one fits
        e, g = x[i] - x_prev[i], x_prev[i] - x[i - 2]
        left[:, i] = ((2 * e + g) / (e * (e + g)) * f[:, i] - (e + g) / (e * g) * f_prev[:, i]
                      + e / (g * (e + g)) * f[:, i - 2])
        i = np.flatnonzero(short | (right_end & cramped_right))
        right[:, i] = (f_next[:, i] - f[:, i]) / (x_next[i] - x[i])
        i = np.flatnonzero(short | (left_end & cramped_left))
        left[:, i] = (f[:, i] - f_prev[:, i]) / (x[i] - x_prev[i])
    return np.vstack([right, left])


_STORES: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()
_STORES_LOCK = threading.Lock()


def tables_for(model: ValveModel) -> MapTables:
    """The table store of ``model``'s pair of maps (made on first use)."""
    with _STORES_LOCK:
        by_force = _STORES.setdefault(model.flow_map, weakref.WeakKeyDictionary())
        tables = by_force.get(model.force_map)
        if tables is None:
            tables = by_force[model.force_map] = MapTables(model)
    return tables


def release_tables(model: ValveModel) -> None:
    """Drop the tables of ``model``'s maps (a workflow whose fits are done: the memory goes
    back, a later fit tabulates afresh)."""
    with _STORES_LOCK:
        by_force = _STORES.get(model.flow_map)
        tables = None if by_force is None else by_force.pop(model.force_map, None)
    if tables is not None:
        with tables._lock:
            tables._clear()


def applies(points: OperatingPoints, true: OperatingPoints) -> bool:
    """Whether tables keyed by the measured ``points`` hold the maps of a model that corrects
    them to ``true``: the back pressure and temperature are as measured (a flow that differs is
    read from the expansions)."""
    return (np.array_equal(true.p_B, points.p_B)
            and np.array_equal(true.temperature, points.temperature))


class TabulatedMaps:
    """The maps at one balance call's points and openings, read from their tables: what a
    :class:`~surrogate.model.ValveModel` asks instead of its maps (its ``maps`` argument).
    Whatever the tables do not hold, the maps answer."""

    def __init__(self, model: ValveModel, view: TableView, points: OperatingPoints, fluid, u,
                 coarsest: int = FINE, expansions: bool | None = None):
        """``points``: as measured (the tables' keys; a model's corrected flow is read from
        the expansions about them); ``u`` [m] the openings of the balance call;
        ``expansions``: whether the model may change the flow (found here unless given)."""
        self.model, self.points, self.fluid, self.u = model, points, fluid, u
        self.expansions = model.may_change_the_flow if expansions is None else expansions
        self.inside, (self.log_dp, self.ratio), self.expanded = view.read(u, coarsest,
                                                                          self.expansions)
        self.rows, self.stroke, self.at_stroke = view.row, view.store.stroke, None
        if not self.inside.all():
            self.at_stroke = view.maps_at_stroke()
        # Δp at the measured flows, as pressure_drop found it for all the points: what
        # flow_force compares its Δp with
        self._own_dp = None

    def _on_stop(self, where: np.ndarray) -> np.ndarray:
        """The rows of the points ``where`` (positions) on the stop whose row holds the maps
        there; −1 for the others."""
        rows = np.full(len(where), -1)
        if self.at_stroke is not None and where.size:
            held = self.rows[where]
            on_stop = ((self.u[where] == self.stroke) & (held >= 0)
                       & (held < len(self.at_stroke)))
            rows[on_stop] = held[on_stop]
        return rows

    def pressure_drop(self, q: np.ndarray, index=slice(None)) -> np.ndarray:
        """Δp [Pa] that passes the flow ``q`` [m^3/s] through the restriction at the points
        ``index`` (all by default)."""
        q = np.asarray(q, float)
        reference = self.points.q[index]
        log_dp = self.log_dp[index]
        inside = self.inside[index]
        if np.array_equal(q, reference):  # the measured flow: the tables' own value
            dp = np.exp(log_dp)
            if isinstance(index, slice) and index == slice(None) and inside.all():
                self._own_dp = dp  # not changed below: no point is asked of the maps
        elif self.expanded is None:  # no expansions: the maps answer for another flow
            same = q == reference
            dp, inside = np.where(same, np.exp(log_dp), np.nan), inside & same
        else:
            with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
                step = np.log(q / reference)
                dp = np.exp(log_dp + _taylor(self.expanded[:4, index], step))
            inside = inside & (np.abs(step) <= EXPANSION_REACH) & np.isfinite(dp)
        if not inside.all():
            away = np.flatnonzero(~inside)
            where = np.arange(len(self.u))[index][away]
            # on the stop at the measured flow: the maps' answer there, kept
            rows = self._on_stop(where)
            kept = (rows >= 0) & (q[away] == reference[away])
            if kept.any():
                dp[away[kept]] = self.at_stroke[rows[kept], 0]
                away, where = away[~kept], where[~kept]
            if away.size:
                dp[away] = self.model.flow_map.pressure_drop(
                    q[away], self.points.p_B[where], self.u[where], self.fluid[where])
        return dp

    def flow_force(self, dp: np.ndarray) -> np.ndarray:
        """f_ff [N] at the pressure drops ``dp`` [Pa] of all the points."""
        dp = np.asarray(dp, float)
        tables_dp = np.exp(self.log_dp) if self._own_dp is None else self._own_dp
        inside = self.inside
        if np.array_equal(dp, tables_dp):  # Δp at the measured flow: the tables' own value
            ratio = self.ratio
        elif self.expanded is None:
            same = dp == tables_dp
            ratio, inside = np.where(same, self.ratio, np.nan), inside & same
        else:
            with np.errstate(divide="ignore", invalid="ignore"):
                step = np.log(dp / tables_dp)
                ratio = self.ratio + _taylor(self.expanded[4:], step)
            inside = inside & (np.abs(step) <= EXPANSION_REACH) & np.isfinite(ratio)
        force = ratio * dp
        if not inside.all():
            away = np.flatnonzero(~inside)
            # on the stop at the Δp kept there: the maps' answer there, kept
            rows = self._on_stop(away)
            kept = rows >= 0
            if kept.any():
                kept[kept] = dp[away[kept]] == self.at_stroke[rows[kept], 0]
                force[away[kept]] = self.at_stroke[rows[kept], 1]
                away = away[~kept]
            if away.size:
                force[away] = self.model.flow_force(self.u[away], dp[away], self.points[away],
                                                    self.fluid[away])
        return force


def _taylor(derivatives: np.ndarray, step: np.ndarray) -> np.ndarray:
    """Σ_k f⁽ᵏ⁾·stepᵏ/k! for k = 1…4 (the rows of ``derivatives``): the quartic's change."""
    d1, d2, d3, d4 = derivatives
    return step * (d1 + step * (d2 / 2 + step * (d3 / 6 + step * d4 / 24)))


class TabulatedBalance:
    """A model's balance at given (measured) points, its maps read from their tables where
    those hold the opening asked for (:class:`TabulatedMaps`)."""

    def __init__(self, model: ValveModel, view: TableView, points: OperatingPoints, fluid,
                 coarsest: int = FINE):
        self.model, self.view, self.coarsest = model, view, coarsest
        self.points, self.fluid = points, fluid
        # the model's effects stay as they are while a solver asks (a balance at a time)
        self.expansions = model.may_change_the_flow

    def __call__(self, u, index) -> Balance:
        """The balance of the points ``index`` at openings ``u`` [m]."""
        u = np.broadcast_to(np.asarray(u, float), np.shape(index)).copy()
        points, fluid = self.points[index], self.fluid[index]
        maps = TabulatedMaps(self.model, self.view[index], points, fluid, u, self.coarsest,
                             self.expansions)
        return self.model.balance(u, points, fluid, maps)


def balance_reader(model: ValveModel, points: OperatingPoints, fluid, view: TableView | None,
                   coarsest: int = FINE, keep: bool = False):
    """``balance(u, index)``: ``model``'s balance of the (measured) points ``index`` at
    openings ``u`` [m], its maps read from ``view``, their rows of the tables (levels up to
    ``coarsest``), where given and where they apply (:func:`applies`), else asked
    (:func:`.asked_maps.asked_balance`; ``keep``: what the flow map reads at the points'
    flows kept, for a solver that asks about them again and again)."""
    if view is not None and applies(points, model.true_points(points)):
        return TabulatedBalance(model, view, points, fluid, coarsest)
    return asked_balance(model, points, fluid, keep)
