"""How a replay's pressure drop answers each parameter, from one replay instead of one per
parameter.

A fit's Jacobian by finite differences replays the whole log once per parameter: every sample's
band edges solved again, the maps asked a dozen times each. Yet the replay's opening is defined
implicitly. At a band edge the piston sits where the balance

    G(u, θ) = net force − s·friction = 0        (s = +1 opening, −1 closing)

closes, so by the implicit function theorem du/dθ = −G_θ / G_u there (G_u along the flow map's
Δp(u), as :mod:`.uncertainty` differentiates it for the maps' errors). The replay's Δp is the
balance's at that opening, Δp(u, θ), so

    dΔp/dθ = Δp_θ + Δp_u · du/dθ.

Which edge a sample's opening is, the play says (:func:`.replay.play`'s ``source``): a sliding
sample's own edge, a stuck sample's the edge (smoothed over the run, a linear filter) of the
sample that last pushed the piston, or nothing where the run starts. Each derivative is one
forward difference at a fixed opening, no solve; and for a parameter of an effect that acts
through its force or friction alone (most of them: springs, frictions, forces of free shape),
not through the flow, the inputs or the maps, G_θ is that effect's hooks evaluated twice on the
balance states of the edges (:attr:`surrogate.model.Balance.state`), so the maps are not asked
for it at all.

What this leaves out is what a finite difference would see as a jump: a sample that starts or
stops sliding between the two parameter values, the few samples at a turn. The fit's Jacobian
steers its steps and, at the optimum, linearises the held-out refits and the standard errors
(:mod:`surrogate.fitting.heldout`): the derivative is what those want, and a tiny forward
difference across such a jump was noise in them (:func:`surrogate.fitting.logfit.probe_column`
takes a fiftieth of a range for that reason).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..effects.base import Effect
from ..model import ValveModel
from ..points import OperatingPoints
from .map_tables import balance_reader
from .replay import (FROM_START, OWN_HIGH, OWN_LOW, STATE_HIGH, STATE_LOW, Replay, play,
                     segment_starts, smoothed_edge)

#: relative step of the opening in the derivatives along u [1]
_U_STEP = 1e-6
#: the hooks through which an effect changes the flow, the inputs or Δp (beyond a force)
_FLOW_HOOKS = ("correct_inputs", "restriction_flow", "leakage")


def pressure_drop_changes(model: ValveModel, points: OperatingPoints, segments,
                          replay: Replay, trials: Sequence[ValveModel], *, u_start: float = 0.0,
                          smoothing: int = 1) -> np.ndarray:
    """The change of the replay's Δp [Pa] at each sample that each of ``trials`` (``model``
    with one parameter shifted, as a Jacobian's forward difference shifts it) makes,
    linearised: (n, len(trials)), NaN where ``replay`` has no solution. The opening's change is
    not followed where the piston rests on its stop or is closed (it does not move) or no flow
    passes (Δp does not depend on it); Δp's own change there is.

    ``points``, ``segments``, ``u_start`` and ``smoothing`` are the replay's (:func:`.replay.
    replay`).
    """
    count, columns = len(points), len(trials)
    fluid = model.fluid(points)
    stroke = model.valve.U_max
    changed = [_changed_effects(model, trial) for trial in trials]
    fast = [all(not _acts_on_flow(effect) for _, effect in pairs) for pairs in changed]

    # 1. each band edge's du/dθ where the piston floats on it
    edge_change = np.zeros((2, count, columns))
    for row, sign in ((0, 1.0), (1, -1.0)):
        u_edge = replay.band[row]
        floating = np.flatnonzero(np.isfinite(u_edge) & (points.q > 0) & (u_edge > 0)
                                  & (u_edge < stroke))
        if not floating.size:
            continue
        sub, at, sub_fluid = points[floating], u_edge[floating], fluid[floating]
        balance_at = _balance_as_replayed(model, replay, floating, sub, sub_fluid)
        balance = balance_at(at)
        state, here = balance.state, _g(balance, sign)
        step = _U_STEP * at
        g_u = (_g(balance_at(at + step), sign) - here) / step
        for j, trial in enumerate(trials):
            if fast[j]:
                g_theta = sum(_hooks(new, state, sign) - _hooks(old, state, sign)
                              for old, new in changed[j])
            else:
                g_theta = _g(_balance_as_replayed(trial, replay, floating, sub, sub_fluid)(at),
                             sign) - here
            with np.errstate(divide="ignore", invalid="ignore"):
                edge_change[row, floating, j] = -g_theta / g_u

    # 2. which edge each sample's opening is (the play, replayed on the band it found)
    status_edges = np.where(np.isfinite(replay.band), 0, -1)
    starts = segment_starts(segments, count)
    *_, source = play(replay.band[0], replay.band[1], status_edges[0], status_edges[1],
                       starts, u_start, smoothing)
    opens_low = ~(replay.band[0] > replay.band[1])  # the lower edge is the opening one
    low = np.where(opens_low[:, None], edge_change[0], edge_change[1])
    high = np.where(opens_low[:, None], edge_change[1], edge_change[0])
    solved = np.isfinite(replay.band).all(axis=0)
    if smoothing > 1:  # the state follows the edges smoothed over each run: a linear filter
        state_low = smoothed_edge(low, starts, solved, smoothing) if columns else low
        state_high = smoothed_edge(high, starts, solved, smoothing) if columns else high
    else:
        state_low, state_high = low, high
    du = np.zeros((count, columns))
    kind, index = source
    for code, table in ((OWN_LOW, low), (OWN_HIGH, high), (STATE_LOW, state_low),
                        (STATE_HIGH, state_high)):
        at = kind == code
        du[at] = table[index[at]]
    du[kind == FROM_START] = 0.0

    # 3. Δp at each sample's own opening: its direct change and its slope in u
    change = np.full((count, columns), np.nan)
    solved_rows = np.flatnonzero(np.isfinite(replay.dp))
    if not solved_rows.size:
        return change
    sub, at, sub_fluid = points[solved_rows], replay.u[solved_rows], fluid[solved_rows]
    dp = replay.dp[solved_rows]
    step = _U_STEP * np.maximum(at, 1e-3 * stroke)
    balance_at = _balance_as_replayed(model, replay, solved_rows, sub, sub_fluid)
    dp_u = (balance_at(at + step).dp - dp) / step
    for j, trial in enumerate(trials):
        direct = 0.0 if fast[j] else (
            _balance_as_replayed(trial, replay, solved_rows, sub, sub_fluid)(at).dp - dp)
        change[solved_rows, j] = direct + dp_u * du[solved_rows, j]
    return change


def _balance_as_replayed(model, replay: Replay, rows, points, fluid):
    """``balance(u)`` of the samples ``rows`` as the replay evaluated ``model`` (or a trial of
    it): from the map tables it read (:mod:`.map_tables`), or from the maps."""
    read = balance_reader(model, points, fluid,
                          None if replay.tables is None else replay.tables[rows])
    index = np.arange(len(points))
    return lambda u: read(u, index)


def _g(balance, sign: float) -> np.ndarray:
    """The band edge's balance G = net force − s·friction [N]."""
    return balance.net_force - sign * balance.friction


def _hooks(effect: Effect | None, state, sign: float) -> np.ndarray:
    """One effect's part of G [N] at a balance state: its force less s times its friction (0
    for None)."""
    if effect is None:
        return 0.0
    force, friction = effect.force(state), effect.friction(state)
    return ((0.0 if force is None else force)
            - sign * (0.0 if friction is None else friction))


def _acts_on_flow(effect: Effect) -> bool:
    """Whether ``effect`` changes the flow, the inputs or Δp, not only the forces."""
    return any(getattr(type(effect), hook) is not getattr(Effect, hook) for hook in _FLOW_HOOKS)


def _changed_effects(model: ValveModel, trial: ValveModel) -> list[tuple[Effect | None, Effect]]:
    """The (model's, trial's) effects whose parameters differ, matched by name; an effect the
    model lacks pairs with None (a candidate probed by adding it)."""
    model_effects = {effect.name: effect for effect in model.effects}
    pairs = []
    for effect in trial.effects:
        old = model_effects.get(effect.name)
        if old is None or any(old.params[key].value != effect.params[key].value
                              for key in effect.params):
            pairs.append((old, effect))
    return pairs
