"""A grid chosen to meet a tolerance: nodes inserted where the valve changes quickly.

An even grid fine enough for the sharpest feature of a fitted valve is far too fine everywhere
else: a friction of free shape in the oil's viscosity may change over one kelvin near a logged
temperature while the rest of the valve is smooth over ten. So the grid starts even
(:class:`~.tables.TableGrid`) and is refined along each axis separately: the band's edges are
solved at the middle of every cell along the axis, for a sample of the other axes' nodes, and a
cell whose interpolated pressure drop misses the solver's there by more than the tolerance, RMS
over the sample, gets a node in its middle. The middle is where an interpolant between nodes
strays most; the error falls about fourfold each time a smooth cell is halved, twofold at a
kink. Rounds repeat until no cell misses, or the node budget or the rounds are spent, which the
result says.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..model import ValveModel
from ..points import CLOSING, OPENING, OperatingPoints
from ..solver.steady import Status, solve_steady
from ..core.units import from_si
from .tables import EDGE_AXES, LOG_AXES, TableGrid, ValveTables, tabulate

#: how many combinations of the other axes' nodes each cell's middle is solved at
SAMPLED_COMBINATIONS = 96
#: rounds of insertion at most
ROUNDS = 6
#: the refined grid's edge nodes at most, as a multiple of the even grid's
NODE_BUDGET = 3.0


@dataclass(frozen=True)
class Refinement:
    """A grid refined to a tolerance and its tables.

    Attributes
    ----------
    grid : TableGrid
    tables : ValveTables
        Tabulated on ``grid``.
    worst : dict of str to float
        Per axis, the largest RMS miss [Pa] of the interpolated edge Δp at a cell's middle in
        the last check (of the grid before the insertions the budget refused, if it stopped).
    rounds : int
        How many rounds inserted nodes.
    stopped_by : str
        Empty when no cell missed by more than the tolerance at the last check; else why the
        refinement stopped: ``"budget"`` (:data:`NODE_BUDGET`) or ``"rounds"``
        (:data:`ROUNDS`).
    """

    grid: TableGrid
    tables: ValveTables
    worst: dict[str, float]
    rounds: int
    stopped_by: str = ""

    @property
    def met(self) -> bool:
        return not self.stopped_by


def refined_grid(model: ValveModel, grid: TableGrid, tolerance: float, progress=None,
                 seed: int = 0) -> Refinement:
    """Tabulate ``model`` on ``grid``, inserting nodes along each axis where the band's edges'
    Δp between nodes misses the solver's by more than ``tolerance`` [Pa] (see the module's
    docstring)."""
    progress = progress or (lambda message: None)
    budget = NODE_BUDGET * _edge_count(grid)
    rng = np.random.default_rng(seed)
    tables = tabulate(model, grid, progress)
    for round_ in range(1, ROUNDS + 1):
        worst, wanted = _check(model, tables, grid, tolerance, rng)
        count = sum(len(nodes) for nodes in wanted.values())
        if not count:
            return Refinement(grid, tables, worst, round_ - 1)
        refined = grid
        for axis, nodes in wanted.items():
            if len(nodes):
                refined = refined.with_nodes(axis, nodes)
        if _edge_count(refined) > budget:
            progress(f"the grid would need {_edge_count(refined):,} nodes per edge to meet the "
                     f"tolerance everywhere, over the budget of {budget:,.0f}: keeping "
                     f"{_edge_count(grid):,}")
            return Refinement(grid, tables, worst, round_ - 1, "budget")
        shown = ", ".join(f"{len(nodes)} along {axis}" for axis, nodes in wanted.items()
                          if len(nodes))
        progress(f"refining: {count} cell{'s' if count > 1 else ''} miss the solver by more than "
                 f"{from_si(tolerance, 'bar'):.3g} bar RMS in the middle (at most "
                 f"{from_si(max(worst.values()), 'bar'):.3g} bar); inserting nodes: {shown}")
        grid, tables = refined, tabulate(model, refined, progress, previous=tables)
    worst, wanted = _check(model, tables, grid, tolerance, rng)
    return Refinement(grid, tables, worst, ROUNDS,
                      "rounds" if any(len(nodes) for nodes in wanted.values()) else "")


def _check(model: ValveModel, tables: ValveTables, grid: TableGrid, tolerance: float,
           rng: np.random.Generator) -> tuple[dict[str, float], dict[str, np.ndarray]]:
    """Per axis: the largest RMS miss [Pa] at a cell's middle, and the middles [SI] of the
    cells that miss by more than ``tolerance`` [Pa]."""
    misses = {axis: _cell_misses(model, tables, grid, axis, rng) for axis in EDGE_AXES}
    return ({axis: float(np.max(miss, initial=0.0)) for axis, (_, miss) in misses.items()},
            {axis: middles[miss > tolerance] for axis, (middles, miss) in misses.items()})


def _edge_count(grid: TableGrid) -> int:
    return int(np.prod([len(nodes) for nodes in grid.edge_nodes()]))


def _cell_misses(model: ValveModel, tables: ValveTables, grid: TableGrid, axis: str,
                 rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """The middles [SI] of the cells along ``axis`` and, per cell, the RMS over a sample of the
    other axes' nodes of the larger miss [Pa] of the two edges' interpolated Δp against the
    solver's there (samples without an equilibrium left out; a cell without any: 0)."""
    nodes = grid.axis(axis)
    if len(nodes) < 2:
        return np.empty(0), np.empty(0)
    middles = (np.sqrt(nodes[1:] * nodes[:-1]) if axis in LOG_AXES
               else 0.5 * (nodes[1:] + nodes[:-1]))
    others = [name for name in EDGE_AXES if name != axis]
    picks = {name: rng.choice(grid.axis(name), SAMPLED_COMBINATIONS) for name in others}
    at = {name: np.tile(values, len(middles)) for name, values in picks.items()}
    at[axis] = np.repeat(middles, SAMPLED_COMBINATIONS)
    miss = np.zeros(at[axis].size)
    found_any = np.zeros(at[axis].size, dtype=bool)
    for side, direction in (("open", OPENING), ("close", CLOSING)):
        points = OperatingPoints.create(at["q"], at["p_P"], at["p_B"], at["temperature"],
                                        direction)
        state = solve_steady(model, points)
        found = (state.status >= 0) & (state.status != Status.CLOSED)
        interpolated = tables.edges[f"dp_{side}"](**at)
        miss = np.maximum(miss, np.where(found, np.abs(interpolated - state.dp), 0.0))
        found_any |= found
    squares = np.where(found_any, miss ** 2, 0.0).reshape(len(middles), -1).sum(axis=1)
    counted = found_any.reshape(len(middles), -1).sum(axis=1)
    return middles, np.sqrt(squares / np.maximum(counted, 1))
