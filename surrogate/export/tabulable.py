"""Whether a model's terms can be tabulated: each a function of the operating point alone.

A table holds one value per (q, p_B, p_P, T) and opening, computed in batches of grid nodes, and
the FMU looks it up one sample at a time. A term whose value at a state also depends on the
other states it is called with (a mean over the batch, a difference between neighbouring
samples, the order of the samples) or on what is not an input of the FMU (the bench run a
sample belongs to) gives a table that answers nothing a simulator could ask. The library's
terms are all pointwise; a user's custom term is checked here before any work, by calling it on
random states of the grid in one batch, in reverse order and one by one.
"""

from __future__ import annotations

import numpy as np

from ..core.errors import InputError
from ..model import ValveModel
from ..points import OperatingPoints
from .tables import TableGrid

#: states each custom term is tried on
TRIALS = 16


def refuse_untabulable(model: ValveModel, grid: TableGrid, source: str) -> None:
    """Raise :class:`InputError` naming the first custom term of ``model`` that is not a
    function of the operating point and the opening alone (or that fails on the grid).

    Parameters
    ----------
    model : ValveModel
        The valve physics to export (:mod:`.valve_only`).
    grid : TableGrid
        The ranges it will be tabulated over [SI].
    source : str
        Where the model comes from (its file or preset), for the message.
    """
    rng = np.random.default_rng(0)

    def drawn(low, high):
        return rng.uniform(low, high, TRIALS)
    q = np.exp(drawn(np.log(grid.q[0]), np.log(grid.q[1])))
    points = OperatingPoints.create(q, drawn(*grid.p_P), drawn(*grid.p_B),
                                    drawn(*grid.temperature))
    u = drawn(0.05, 1.0) * model.valve.U_max
    for effect in model.effects:
        if not getattr(effect, "custom", False):
            continue
        alone = model.with_effects([effect])
        where = (f"{source}: custom effect {effect.name!r}"
                 + (f" (from {effect.source})" if getattr(effect, "source", None) else ""))
        try:
            batch = _evaluate(alone, u, points)
            reverse = _evaluate(alone, u[::-1], points[::-1])[:, ::-1]
            single = np.column_stack([_evaluate(alone, u[k:k + 1], points[k:k + 1])
                                      for k in range(TRIALS)])
        except InputError as error:
            raise InputError(f"{where} cannot be tabulated: called on states of the export's "
                             f"grid (no bench run, no time) it failed: {error}") from None
        for other, how in ((reverse, "in reverse order"), (single, "one at a time")):
            if not np.allclose(batch, other, rtol=1e-9, atol=1e-12, equal_nan=True):
                raise InputError(
                    f"{where} cannot be tabulated: its value at a state changes when the same "
                    f"states are given {how}, so it reads the other states of its batch (a "
                    "mean, a difference between samples, their order), not only its own; an "
                    "exported valve is a function of (q, p_B, p_P, T) and the opening. Rewrite "
                    "it elementwise, or export the model without it")


def _evaluate(model: ValveModel, u: np.ndarray, points: OperatingPoints) -> np.ndarray:
    """(Δp [Pa], net force [N], friction [N]) of ``model`` at ``u`` [m] and ``points``, as
    rows."""
    balance = model.balance(u, points, model.fluid(points))
    return np.vstack([balance.dp, balance.net_force, balance.friction])
