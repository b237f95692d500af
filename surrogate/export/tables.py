"""The fitted valve as lookup tables, and the play that turns them into a valve with friction.

A system simulator needs the valve's load pressure for the flow, back pressure, pilot pressure
and temperature it feeds it, with the hysteresis that friction gives. The Python replay
(:func:`surrogate.solver.replay.replay`, the classic play, ``smoothing=1``) does that in two
parts, and the tables keep both:

1. the friction band's edges over (q, p_B, p_P, T): the piston's equilibrium opening while it
   opens, u_open, and while it closes, u_close, and the pressure drop at each, Δp_open and
   Δp_close; each node one force balance solved by :func:`surrogate.solver.solve_steady`;
2. the play: the piston stays where it was unless an edge pushes it,
   u = clip(u_previous, min(edges), max(edges)). A pushed piston sits on an edge and its Δp is
   that edge's own Δp; a piston held by friction keeps its opening and its Δp comes from a third
   table, Δp(q, u, p_B, T) at any opening (with p_P too, if a term on the flow side reads it).

Why Δp on the edges is a table of its own rather than Δp(q, u_edge): at equilibrium Δp is set by
the force balance and barely moves with the opening, while Δp at a *given* opening moves with it
steeply (like 1/u²), so an interpolated opening fed through the third table would turn a 0.5 %
error of u into a 1 % error of Δp. On the shipped log and the ``cfda`` preset that halves the
resolution error of the sliding samples.

A held piston's Δp is the third table's times the ratio of the edge's Δp to the third table's at
the sample that last pushed it: the two agree exactly at the nodes, and between them the ratio
carries the edge's accurate Δp on while the piston is held, instead of a jump to the third
table's value at an interpolated opening (in exact arithmetic the ratio is 1, as in the replay).

Any effect, a custom one included, is tabulated by the same solver: nothing is generated per map
kind or per effect. The FMU interpolates by cubic convolution between the nodes (:func:`
interpolate`) and holds the edge values beyond the grid; openings and pressure drops are
interpolated as ln(value) and flows and openings along ln(axis), along which they are close to
straight (Δp grows like a power of q and of 1/u, the opening like the flow). A table block that
interpolates linearly between the same nodes (Simscape, Hopsan) is less accurate;
:func:`resolution_error` measures both. :meth:`ValveTables.replay` is that interpolation and play in
Python, the reference that a table block or the FMU (:mod:`.fmu`) must reproduce;
:func:`resolution_error` measures what the grid's resolution costs against the solver itself.
"""

from __future__ import annotations

import itertools
import json
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import pandas as pd

from ..core.errors import InputError
from ..model import ValveModel
from ..points import CLOSING, OPENING, OperatingPoints
from ..solver.steady import Status, solve_steady
from ..core.units import from_si, to_si

#: display unit of each axis and table
UNITS = {"q": "L/min", "p_B": "bar", "p_P": "bar", "temperature": "degC", "u": "mm",
         "u_open": "mm", "u_close": "mm", "dp_open": "bar", "dp_close": "bar", "dp": "bar"}
#: column suffix of each display unit
SUFFIXES = {"L/min": "lpm", "bar": "bar", "degC": "C", "mm": "mm"}
#: what each axis and table is, for the manifest and the CSV's documentation
MEANINGS = {
    "q": "flow through the valve, load to back port",
    "p_B": "back pressure (gauge)", "p_P": "pilot pressure (gauge)",
    "temperature": "oil temperature", "u": "piston opening",
    "u_open": "equilibrium opening while the piston opens (flow rising, friction holding it "
              "back)",
    "u_close": "equilibrium opening while the piston closes (flow falling, friction holding it "
               "open)",
    "dp_open": "pressure drop p_L - p_B at u_open",
    "dp_close": "pressure drop p_L - p_B at u_close",
    "dp": "pressure drop p_L - p_B with the piston held at the opening u"}
#: axes interpolated along ln(x)
LOG_AXES = ("q", "u")
#: the axes of the band's edges, in order
EDGE_AXES = ("q", "p_B", "p_P", "temperature")
#: the edge tables, in the order the FMU's tables file holds them
EDGE_TABLES = ("u_open", "u_close", "dp_open", "dp_close")
#: node spacing of each axis at grid scale 1: ln(q), ln(u) in natural-log units, pressures [Pa],
#: temperature [K]; chosen so that ``cfda`` on grid maps, the roughest maps the package has
#: (kinks at every sampled opening), replays the shipped log within 0.1 bar RMS of the solver
STEPS = {"q": 0.12, "u": 0.07, "p_B": to_si(1.5, "bar"), "p_P": to_si(3.0, "bar"),
         "temperature": 6.0}


@dataclass(frozen=True)
class Table:
    """Values on a rectilinear grid, interpolated by cubic convolution and held beyond it.

    Attributes
    ----------
    name : str
        One of :data:`EDGE_TABLES` or ``"dp"``.
    axes : tuple of str
        The variables along each dimension, in order.
    nodes : tuple of numpy.ndarray
        Each axis' nodes [SI], increasing.
    values : numpy.ndarray
        The table [SI], of shape ``tuple(len(n) for n in nodes)``, > 0.
    """

    name: str
    axes: tuple[str, ...]
    nodes: tuple[np.ndarray, ...]
    values: np.ndarray

    def __call__(self, cubic: bool = True, **coordinates: np.ndarray) -> np.ndarray:
        """The table at the points given by each axis' values [SI]: ln of the values
        interpolated (:func:`interpolate`) along ln q and ln u and the other axes as they are."""
        nodes = [np.log(n) if axis in LOG_AXES else n for axis, n in zip(self.axes, self.nodes)]
        at = [np.log(np.clip(coordinates[axis], n[0], n[-1])) if axis in LOG_AXES
              else coordinates[axis] for axis, n in zip(self.axes, self.nodes)]
        return np.exp(interpolate(nodes, np.log(self.values), at, cubic))


def interpolate(nodes, values: np.ndarray, coordinates, cubic: bool = True) -> np.ndarray:
    """Cubic convolution of ``values`` on the grid ``nodes`` at ``coordinates`` (one array per
    axis), each coordinate held to its axis' range; the FMU's C does the same, in the same
    order.

    Along each axis the four nodes around a point are weighted by Hermite's cubic with
    central-difference slopes (:func:`stencil`), on evenly spaced nodes Catmull-Rom's (Keys'
    cubic convolution with a = -1/2): there it reproduces quadratics exactly, where linear
    interpolation only reproduces straight lines, and so needs about half the nodes per axis
    for the same error (on the shipped log and ``cfda`` over the log's range: 0.08 bar RMS with
    0.36 million nodes against 0.13 bar with 1 million, linearly). In the outer cells the missing node is extrapolated linearly
    from the two inside it; an axis of two or three nodes is interpolated linearly, one of one
    node held. The 4^d products of the axes' weights are summed. ``cubic=False``: multilinear
    interpolation between the same nodes, what a linear table block does.
    """
    coordinates = np.broadcast_arrays(*(np.asarray(c, float) for c in coordinates))
    shape = coordinates[0].shape
    stencils = [stencil(axis, x.ravel(), cubic) for axis, x in zip(nodes, coordinates)]
    result = np.zeros(coordinates[0].size)
    for combination in itertools.product(*(range(len(s[0])) for s in stencils)):
        weight, index = np.ones(result.size), []
        for (indices, weights), which in zip(stencils, combination):
            index.append(indices[which])
            weight = weight * weights[which]
        result += weight * values[tuple(index)]
    return result.reshape(shape)


def stencil(axis: np.ndarray, x: np.ndarray, cubic: bool = True
            ) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """The nodes (indices) along one axis that a point's value is made of, and their weights
    (:func:`interpolate`); ``x`` is held to the axis' range.

    The cubic is Hermite's between the cell's two nodes with central-difference slopes,
    (f[i+1] − f[i−1]) / (x[i+1] − x[i−1]): on evenly spaced nodes exactly Catmull-Rom's, and
    on uneven nodes (inserted where the valve needs them, :func:`refined_grid`) still
    continuous in value and slope and exact for straight lines."""
    count = len(axis)
    x = np.clip(x, axis[0], axis[-1])
    if count == 1:
        return [np.zeros(x.size, dtype=np.intp)], [np.ones(x.size)]
    cell = np.clip(np.searchsorted(axis, x, side="right") - 1, 0, count - 2)
    width = axis[cell + 1] - axis[cell]
    t = (x - axis[cell]) / width
    if count < 4 or not cubic:
        return [cell, cell + 1], [1.0 - t, t]
    first, last = cell == 0, cell == count - 2
    # a missing outer node mirrored across the end node: f(-1) = 2 f(0) - f(1) at the mirrored
    # position, so the end cell's slope there is the cell's own secant
    x_before = np.where(first, axis[cell] - width, axis[np.maximum(cell - 1, 0)])
    x_after = np.where(last, axis[cell + 1] + width, axis[np.minimum(cell + 2, count - 1)])
    slope_low = width / (axis[cell + 1] - x_before)  # share of Δ in the slope at the low node
    slope_high = width / (x_after - axis[cell])
    t2, t3 = t * t, t * t * t
    h00, h10 = 2 * t3 - 3 * t2 + 1.0, t3 - 2 * t2 + t
    h01, h11 = -2 * t3 + 3 * t2, t3 - t2
    before, after = -h10 * slope_low, h11 * slope_high
    low, high = h00 - h11 * slope_high, h01 + h10 * slope_low
    low, high = np.where(first, low + 2 * before, low), np.where(first, high - before, high)
    before = np.where(first, 0.0, before)
    high, low = np.where(last, high + 2 * after, high), np.where(last, low - after, low)
    after = np.where(last, 0.0, after)
    return ([np.maximum(cell - 1, 0), cell, cell + 1, np.minimum(cell + 2, count - 1)],
            [before, low, high, after])


@dataclass(frozen=True)
class TableGrid:
    """The ranges the tables span [SI] and their node spacing.

    Flows (and the Δp table's openings) are spaced evenly in ln(x), the other axes evenly;
    ``scale`` divides every spacing of :data:`STEPS` (2 halves them: four times finer in 4-d
    means about 16 times the nodes, for roughly a quarter of the resolution error). Nodes
    ``inserted`` between them refine an axis only where the valve changes quickly along it
    (:func:`surrogate.export.refinement.refined_grid`).

    Attributes
    ----------
    q, p_B, p_P, temperature : tuple of float
        (low, high) of each input [m^3/s, Pa, Pa, K].
    scale : float
        Refinement of the spacing, in [0.25, 8].
    inserted : tuple of (str, tuple of float)
        Extra nodes [SI] by axis name (an axis of :data:`EDGE_AXES` or ``"u"``).
    """

    q: tuple[float, float]
    p_B: tuple[float, float]
    p_P: tuple[float, float]
    temperature: tuple[float, float]
    scale: float = 1.0
    inserted: tuple[tuple[str, tuple[float, ...]], ...] = ()

    def __post_init__(self):
        for name in EDGE_AXES:
            low, high = getattr(self, name)
            shown = f"[{from_si(low, UNITS[name]):.4g}, {from_si(high, UNITS[name]):.4g}]"
            if not (np.isfinite(low) and np.isfinite(high) and high >= low):
                raise InputError(f"the tables' range of the {MEANINGS[name]}, {shown} "
                                 f"{UNITS[name]}, is not a range (low <= high)")
        if self.q[0] <= 0:
            raise InputError("the tables' flow range must start above 0 L/min: the closed valve "
                             "(no flow) is not tabulated")
        if self.temperature[0] <= 0:
            raise InputError("the tables' temperature range must lie above absolute zero")
        if not (np.isfinite(self.scale) and 0.25 <= self.scale <= 8):
            raise InputError(f"a grid scale of {self.scale} is outside [0.25, 8]")

    @classmethod
    def around(cls, points: OperatingPoints, scale: float = 1.0) -> "TableGrid":
        """The range of ``points`` (a bench log's inputs) widened by a margin: flows by 20 %
        below and 10 % above, back pressure by 1 bar, pilot pressure by 10 bar, temperature by
        5 K, so that a simulation near the measured range stays on the grid."""
        def span(values):
            values = np.asarray(values, float)[np.isfinite(values)]
            if not values.size:
                raise InputError("no finite operating points to span the tables over")
            return float(values.min()), float(values.max())
        q = span(points.q[points.q > 0])
        p_B, p_P, temperature = span(points.p_B), span(points.p_P), span(points.temperature)
        bar = to_si(1.0, "bar")
        return cls((0.8 * q[0], 1.1 * q[1]), (max(0.0, p_B[0] - bar), p_B[1] + bar),
                   (max(0.0, p_P[0] - 10 * bar), p_P[1] + 10 * bar),
                   (temperature[0] - 5.0, temperature[1] + 5.0), scale)

    def axis(self, name: str, low: float | None = None, high: float | None = None
             ) -> np.ndarray:
        """The nodes of axis ``name`` [SI] over its range (or from ``low`` to ``high``)."""
        if low is None:
            low, high = getattr(self, name)
        if high <= low:
            return np.array([float(low)])
        step = STEPS[name] / self.scale
        if name in LOG_AXES:
            count = max(2, int(np.ceil(np.log(high / low) / step)) + 1)
            even = np.geomspace(low, high, count)
        else:
            count = max(2, int(np.ceil((high - low) / step)) + 1)
            even = np.linspace(low, high, count)
        extra = np.asarray(dict(self.inserted).get(name, ()), float)
        extra = extra[(extra > low) & (extra < high)]
        if not extra.size:
            return even
        nodes = np.unique(np.r_[even, extra])
        # nodes closer than a thousandth of a step would make a cell of nothing
        close = np.diff(np.log(nodes) if name in LOG_AXES else nodes) < 1e-3 * step
        return np.delete(nodes, np.flatnonzero(close) + 1)

    def with_nodes(self, name: str, nodes) -> "TableGrid":
        """The grid with ``nodes`` [SI] inserted along axis ``name``."""
        inserted = dict(self.inserted)
        inserted[name] = tuple(sorted({*inserted.get(name, ()), *map(float, nodes)}))
        return replace(self, inserted=tuple(sorted(inserted.items())))

    @property
    def inserted_count(self) -> dict[str, int]:
        """How many nodes were inserted along each axis."""
        return {name: len(nodes) for name, nodes in self.inserted}

    def edge_nodes(self) -> tuple[np.ndarray, ...]:
        """The nodes of the band's edges, in :data:`EDGE_AXES` order."""
        return tuple(self.axis(name) for name in EDGE_AXES)

    def to_json(self) -> dict:
        """The ranges in display units, the spacing and the scale."""
        return {"ranges": {name: [round(float(v), 6) for v in
                                  from_si(np.array(getattr(self, name)), UNITS[name])]
                           for name in EDGE_AXES},
                "units": {name: UNITS[name] for name in EDGE_AXES},
                "spacing": {"q": f"{STEPS['q'] / self.scale:.4g} in ln(q)",
                            "u": f"{STEPS['u'] / self.scale:.4g} in ln(u)",
                            "p_B": f"{from_si(STEPS['p_B'], 'bar') / self.scale:.4g} bar",
                            "p_P": f"{from_si(STEPS['p_P'], 'bar') / self.scale:.4g} bar",
                            "temperature": f"{STEPS['temperature'] / self.scale:.4g} K"},
                "scale": self.scale,
                "inserted": {name: [round(float(v), 6) for v in from_si(np.array(nodes),
                                                                        UNITS[name])]
                             for name, nodes in self.inserted}}


@dataclass(frozen=True)
class ValveTables:
    """The valve's tables and what they are of.

    Attributes
    ----------
    model : str
        The model's name.
    edges : dict of str to Table
        :data:`EDGE_TABLES` over :data:`EDGE_AXES`.
    dp : Table
        Δp at any opening, over (q, u, p_B[, p_P], T).
    left_out : dict of str to str
        The model's terms the tables leave out, with why (:mod:`.valve_only`).
    failed_nodes : int
        Edge nodes where the force balance found no equilibrium (filled from the nearest
        solved flow of the same row).
    """

    model: str
    edges: dict[str, Table]
    dp: Table
    left_out: dict[str, str] = field(default_factory=dict)
    failed_nodes: int = 0

    @property
    def tables(self) -> tuple[Table, ...]:
        return (*(self.edges[name] for name in EDGE_TABLES), self.dp)

    def node_count(self) -> int:
        return sum(table.values.size for table in self.tables)

    def replay(self, points: OperatingPoints, segments=None, u_start: float = 0.0,
               cubic: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """(u [m], Δp [Pa]) of points in time order, the piston's play between the edges
        restarting at ``u_start`` where ``segments`` (run labels) changes: what the FMU does,
        step by step (``cubic=False``: with linear interpolation, as a linear table block)."""
        at = _coordinates(points)
        u_open, u_close, dp_open, dp_close = (self.edges[name](cubic, **at)
                                              for name in EDGE_TABLES)
        opening_lower = u_open <= u_close
        low = np.where(opening_lower, u_open, u_close)
        high = np.where(opening_lower, u_close, u_open)
        dp_low = np.where(opening_lower, dp_open, dp_close)
        dp_high = np.where(opening_lower, dp_close, dp_open)
        starts = np.zeros(len(points), dtype=bool)
        if len(points):
            starts[0] = True
        if segments is not None:
            labels = np.asarray(segments)
            starts[1:] |= labels[1:] != labels[:-1]
        u, dp = np.empty(len(points)), np.full(len(points), np.nan)
        pushed = np.zeros(len(points), dtype=bool)
        state = u_start
        for k, (lo, hi, start) in enumerate(zip(low.tolist(), high.tolist(), starts.tolist())):
            if start:
                state = u_start
            if state < lo:  # pushed open onto the lower edge
                state, dp[k], pushed[k] = lo, dp_low[k], True
            elif state > hi:  # pushed closed onto the upper edge
                state, dp[k], pushed[k] = hi, dp_high[k], True
            u[k] = state
        at_u = self.dp(cubic, u=u, **at)
        # a held piston keeps the ratio of the edge's Δp to the Δp table's at the sample that
        # last pushed it (see the module docstring)
        ratio = np.ones(len(points))
        last = 1.0
        for k in range(len(points)):
            if starts[k]:
                last = 1.0
            if pushed[k]:
                last = dp[k] / at_u[k]
            ratio[k] = last
        dp = np.where(pushed, dp, ratio * at_u)
        return u, dp

    def manifest(self, grid: TableGrid) -> dict:
        """What the tables are, their axes and units, and what they leave out."""
        return {
            "model": self.model,
            "interpolation": "cubic Hermite along every axis between a cell's two nodes, "
                             "the slope at a node (f[i+1] - f[i-1]) / (x[i+1] - x[i-1]) "
                             "(Catmull-Rom where the nodes are evenly spaced; the grid is even "
                             "but for nodes inserted where the valve changes quickly), the "
                             "missing node of an outer cell mirrored across the end node "
                             "with f = 2 f[0] - f[1]; flows and openings along ln(axis); "
                             "every table (openings and pressure drops, all > 0) "
                             "interpolated as ln(value) and exponentiated; each input held "
                             "to its axis' range (no extrapolation). Linear interpolation "
                             "between the same nodes works too, less accurately "
                             "(resolution_error_linear)",
            "play": "lo, hi = the smaller and larger of u_open, u_close (dp_lo, dp_hi theirs); "
                    "the piston starts closed (u = 0, r = 1); at each step: if u < lo then "
                    "u = lo, dp = dp_lo, r = dp_lo / dp(q, u, p_B, T); elif u > hi then u = hi, "
                    "dp = dp_hi, r = dp_hi / dp(q, u, p_B, T); else u is held and "
                    "dp = r * dp(q, u, p_B, T); p_L = p_B + dp",
            "tables": {table.name: {"axes": list(table.axes), "unit": UNITS[table.name],
                                    "meaning": MEANINGS[table.name],
                                    "shape": list(table.values.shape)}
                       for table in self.tables},
            "axes": {axis: {"unit": UNITS[axis], "meaning": MEANINGS[axis]}
                     for axis in (*EDGE_AXES, "u")},
            "grid": grid.to_json(),
            "left_out": self.left_out,
            "failed_nodes": self.failed_nodes,
            "not_modelled": "the closed valve (a flow below the grid's lowest is held at it); "
                            "the piston's dynamics (the tables are steady states); the "
                            "workbench's smoothing of noisy measured inputs (the tables play "
                            "the classic play, as a simulator's exact inputs need)"}


def _coordinates(points: OperatingPoints) -> dict[str, np.ndarray]:
    return {"q": points.q, "p_B": points.p_B, "p_P": points.p_P,
            "temperature": points.temperature}


def tabulate(model: ValveModel, grid: TableGrid, progress=None,
             previous: ValveTables | None = None) -> ValveTables:
    """Solve the model over the grid: both edges at every (q, p_B, p_P, T) node, then Δp at
    every opening. ``model`` should hold the valve's physics only (:mod:`.valve_only`).
    ``previous``: tables of the same model on a grid this one refines; their nodes are kept and
    only the new ones solved.

    Raises
    ------
    InputError
        Where the model cannot be tabulated over the grid: no equilibrium at any flow of a
        (p_B, p_P, T) node, or no positive, finite pressure drop at some node.
    """
    progress = progress or (lambda message: None)
    edge_nodes = grid.edge_nodes()
    known, new = _known(previous and previous.edges["u_open"], EDGE_AXES, edge_nodes)
    q, p_B, p_P, temperature = (m[new] for m in np.meshgrid(*edge_nodes, indexing="ij"))
    progress(f"tabulating {model.name}: the force balance at {q.size:,} grid nodes on each edge "
             "of the friction band"
             + (f" (the other {int(known.sum()):,} kept)" if known.any() else ""))
    edges, failed = {}, previous.failed_nodes if previous else 0
    for side, direction in (("open", OPENING), ("close", CLOSING)):
        points = OperatingPoints.create(q, p_P, p_B, temperature, direction)
        state = solve_steady(model, points)
        good = state.status >= 0
        failed += int((~good).sum())
        for name, solved in ((f"u_{side}", state.u), (f"dp_{side}", state.dp)):
            values = np.full(new.shape, np.nan)
            if previous is not None:
                values[known] = _known_values(previous.edges[name], edge_nodes)
            values[new] = np.where(good, solved, np.nan)
            edges[name] = Table(name, EDGE_AXES, edge_nodes, _stored(_filled_along_flow(
                values, name)))
        progress(f"{side} edge: {int(good.sum()):,} of {q.size:,} nodes solved")
    lowest = min(float(np.min(edges["u_open"].values)), float(np.min(edges["u_close"].values)))
    u_low = 0.5 * lowest
    if previous is not None and previous.dp.nodes[previous.dp.axes.index("u")][0] <= u_low:
        u_low = float(previous.dp.nodes[previous.dp.axes.index("u")][0])  # keep its openings
    nodes = {"q": edge_nodes[0], "u": grid.axis("u", u_low, model.valve.U_max),
             "p_B": edge_nodes[1], "p_P": edge_nodes[2], "temperature": edge_nodes[3]}
    with_pilot = _flow_side_reads_pilot(model, nodes)
    axes = ("q", "u", "p_B") + (("p_P",) if with_pilot else ()) + ("temperature",)
    axis_nodes = tuple(nodes[axis] for axis in axes)
    known, new = _known(previous and previous.dp, axes, axis_nodes)
    values = dict(zip(axes, (m[new] for m in np.meshgrid(*axis_nodes, indexing="ij"))))
    progress(f"tabulating Δp at {int(new.sum()):,} (flow, opening, ...) nodes"
             + (f" (the other {int(known.sum()):,} kept)" if known.any() else ""))
    points = OperatingPoints.create(values["q"], values.get("p_P", nodes["p_P"][0]),
                                    values["p_B"], values["temperature"])
    dp = np.full(new.shape, np.nan)
    if previous is not None and known.any():
        dp[known] = _known_values(previous.dp, axis_nodes)
    dp[new] = _pressure_drop(model, values["u"], points)
    for table, array in [*((t.name, t.values) for t in edges.values()), ("dp", dp)]:
        bad = ~(np.isfinite(array) & (array > 0))
        if bad.any():
            raise InputError(f"{model.name}: the tables cannot hold {table}: it is not a "
                             f"positive, finite number at {int(bad.sum())} of {array.size} "
                             "grid nodes; narrow the ranges to where the valve passes flow "
                             "(the closed valve is not tabulated)")
    return ValveTables(model.name, edges, Table("dp", axes, axis_nodes, _stored(dp)),
                       failed_nodes=failed)


def _shared(previous: Table, nodes: tuple[np.ndarray, ...]
            ) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Per axis: where each of ``nodes`` sits in ``previous``' nodes, and whether it is one."""
    where, hit = [], []
    for old, axis in zip(previous.nodes, nodes):
        index = np.clip(np.searchsorted(old, axis), 0, len(old) - 1)
        where.append(index)
        hit.append(old[index] == axis)
    return where, hit


def _known(previous: Table | None, axes: tuple[str, ...], nodes: tuple[np.ndarray, ...]
           ) -> tuple[np.ndarray, np.ndarray]:
    """Masks over the grid of ``nodes``: the nodes ``previous`` (a table over the same
    ``axes``, or None) already holds, and the ones to compute."""
    shape = tuple(len(axis) for axis in nodes)
    if previous is None or previous.axes != axes:
        return np.zeros(shape, dtype=bool), np.ones(shape, dtype=bool)
    _, hit = _shared(previous, nodes)
    known = np.ones(shape, dtype=bool)
    for dimension, present in enumerate(hit):
        known &= present.reshape([-1 if d == dimension else 1 for d in range(len(shape))])
    return known, ~known


def _known_values(previous: Table, nodes: tuple[np.ndarray, ...]) -> np.ndarray:
    """``previous``' values at the nodes it shares with the grid of ``nodes``, in the order of
    :func:`_known`'s mask."""
    where, hit = _shared(previous, nodes)
    return previous.values[np.ix_(*(index[present] for index, present in zip(where, hit)))
                           ].ravel()


def _stored(values: np.ndarray) -> np.ndarray:
    """``values`` rounded to single precision, as the FMU stores them (half the size; 6e-8
    relative, far below the resolution error), so that the Python replay of the tables and
    the FMU interpolate the very same numbers. Non-finite values stay as they are, to be
    refused by name."""
    with np.errstate(over="ignore", invalid="ignore"):
        rounded = values.astype(np.float32).astype(float)
    return np.where(np.isfinite(values), rounded, values)


def _pressure_drop(model: ValveModel, u: np.ndarray, points: OperatingPoints) -> np.ndarray:
    """Δp [Pa] with the piston at ``u`` [m], as the replay computes it for a held piston
    (:meth:`surrogate.model.ValveModel.balance`: sensor terms, if any, first), a batch at a
    time so that memory stays bounded."""
    from ..solver.steady import BATCH

    dp = np.empty(len(points))
    for start in range(0, len(points), BATCH):
        part = slice(start, start + BATCH)
        sub = points[part]
        true = model.true_points(sub)
        dp[part] = model.pressure_drop(u[part], true, model.fluid(true))
    return dp


def _filled_along_flow(values: np.ndarray, name: str) -> np.ndarray:
    """``values`` with failed nodes (NaN) filled from the nearest solved flow of the same row;
    a row with no solution at all cannot be tabulated."""
    filled = values.copy()
    rows = filled.reshape(values.shape[0], -1)
    for column in range(rows.shape[1]):
        good = np.isfinite(rows[:, column])
        if not good.any():
            raise InputError(f"the force balance has no equilibrium at any flow of one "
                             f"(p_B, p_P, T) node of {name}; narrow the ranges to where the "
                             "valve works")
        if not good.all():
            index = np.arange(rows.shape[0])
            nearest = index[good][np.abs(index[:, None] - index[good][None, :]).argmin(axis=1)]
            rows[:, column] = rows[nearest, column]
    return rows.reshape(values.shape)


def _flow_side_reads_pilot(model: ValveModel, nodes: dict[str, np.ndarray]) -> bool:
    """Whether Δp at a given opening changes with the pilot pressure (a custom term on the flow
    side may read it; the maps do not), tried on random states of the grid."""
    if nodes["p_P"].size < 2:
        return False
    count = 64
    rng = np.random.default_rng(0)

    def drawn(axis):
        return rng.uniform(nodes[axis][0], nodes[axis][-1], count)
    q, u, p_B, temperature = drawn("q"), drawn("u"), drawn("p_B"), drawn("temperature")
    drops = [_pressure_drop(model, u, OperatingPoints.create(q, p_P, p_B, temperature))
             for p_P in (nodes["p_P"][0], nodes["p_P"][-1])]
    return not np.allclose(drops[0], drops[1], rtol=1e-12, atol=0.0, equal_nan=True)


def column(name: str) -> str:
    """A CSV column's name: the variable and its display unit (``q_lpm``, ``dp_open_bar``)."""
    return f"{name}_{SUFFIXES[UNITS[name]]}"


def table_frames(tables: ValveTables) -> dict[str, pd.DataFrame]:
    """``edges.csv`` (the four edge tables side by side) and ``dp.csv``, one row per grid node,
    the axes first, display units, the first axis varying slowest."""
    frames = {}
    for file, group in (("edges.csv", [tables.edges[name] for name in EDGE_TABLES]),
                        ("dp.csv", [tables.dp])):
        first = group[0]
        mesh = np.meshgrid(*first.nodes, indexing="ij")
        frame = pd.DataFrame({column(axis): from_si(m.ravel(), UNITS[axis])
                              for axis, m in zip(first.axes, mesh)})
        for table in group:
            frame[column(table.name)] = from_si(table.values.ravel(), UNITS[table.name])
        frames[file] = frame
    return frames


def write_tables(tables: ValveTables, grid: TableGrid, folder: Path,
                 extra: dict | None = None) -> list[Path]:
    """The tables as CSV (long format, display units), one MATLAB ``.mat`` file and
    ``manifest.json``, into ``folder`` (which the caller stages). Returns the files."""
    from scipy.io import savemat

    written = []
    for name, frame in table_frames(tables).items():
        path = folder / name
        frame.to_csv(path, index=False, float_format="%.10g")
        written.append(path)
    mat = {}
    for table in tables.tables:
        mat[table.name] = from_si(table.values, UNITS[table.name])
        for axis, nodes in zip(table.axes, table.nodes):
            mat[f"{table.name}_{axis}"] = from_si(nodes, UNITS[axis])
    path = folder / "valve_tables.mat"
    savemat(path, mat, do_compression=True)
    written.append(path)
    manifest = tables.manifest(grid) | (extra or {})
    manifest["files"] = {p.name: _describe(p.name, tables) for p in written}
    manifest["files"]["manifest.json"] = "this file"
    path = folder / "manifest.json"
    path.write_text(json.dumps(manifest, indent=2, allow_nan=False) + "\n")
    written.append(path)
    return written


def _describe(name: str, tables: ValveTables) -> str:
    if name.endswith(".mat"):
        return ("MATLAB file: each table (u_open, u_close, dp_open, dp_close, dp) as an N-d "
                "array in display units (mm, bar), its axes as <table>_<axis> vectors "
                "(L/min, mm, bar, °C), for n-D Lookup Table blocks")
    group = EDGE_TABLES if name == "edges.csv" else ("dp",)
    axes = tables.edges["u_open"].axes if name == "edges.csv" else tables.dp.axes
    return (f"one row per grid node: the axes {', '.join(column(a) for a in axes)}, then "
            + "; ".join(f"{column(t)}: {MEANINGS[t]} [{UNITS[t]}]" for t in group))


def resolution_error(tables: ValveTables, model: ValveModel, points: OperatingPoints,
                     segments=None) -> dict[str, float]:
    """What the grid's resolution costs: the tables' replay (:meth:`ValveTables.replay`)
    against the solver's classic play (:func:`surrogate.solver.replay.replay`,
    ``smoothing=1``) on the same points: RMS and largest difference of Δp [Pa], over the
    points where the solver found an equilibrium with flow passing; ``rms_linear`` and
    ``max_linear`` the same with linear interpolation between the same nodes."""
    from ..solver.replay import replay

    reference = replay(model, points, segments, diagnostics=False)
    found = {}
    for cubic, suffix in ((True, ""), (False, "_linear")):
        _, dp = tables.replay(points, segments, cubic=cubic)
        both = reference.ok & np.isfinite(dp) & (reference.status != Status.CLOSED)
        if not both.any():
            raise InputError(f"{model.name}: the solver found no equilibrium at any sample, "
                             "so the tables' resolution cannot be measured there")
        difference = dp[both] - reference.dp[both]
        found |= {f"rms{suffix}": float(np.sqrt(np.mean(difference ** 2))),
                  f"max{suffix}": float(np.max(np.abs(difference))), "points": int(both.sum())}
    return found
