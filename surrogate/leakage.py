"""The flow split between the main restriction and leakage paths at one pressure drop.

With a leakage effect, the flow q measured through the valve divides: the main restriction
carries q_r and the leakage paths the rest, and both see the same Δp. The restriction's share
solves

    g(q_r) = q_r + leak(Δp_r(q_r)) − q = 0,   q_r in [0, q],

which rises with q_r. Each step solves that equation with Δp_r(q_r) replaced by the power law
through the last two evaluations of the map (an orifice is close to one), kept inside the bracket
on q_r. The power law is the secant of ln Δp(ln q_r) through those two evaluations, so at the step
its error is ½·f''·ln(step/current)·ln(step/previous) with f'' = d²ln Δp/d(ln q)²; once that
product is below :data:`SETTLED`, and Newton's residual on the law's equation is within the
split's tolerance (1e-9 of q [m^3/s]), the law's Δp at the step stands in for the map's, which
saves the map call that would only confirm it. Without that second condition a leak whose slope
jumps (a table held beyond its last row) sent Newton round a cycle onto an earlier evaluation,
where the law is exact but the step no root: the split then ended up to 40 % off in Δp at some
openings, and the force balance zig-zagged in u (stress case 4262 of eval/offlibrary.py). On
the shipped log almost every sample settles after three map calls. Only the points not yet
converged are iterated.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

#: safeguarded secant steps at most
STEPS = 80
#: the split ends when the power law's error in ln Δp is below 1e-9 for |f''| <= 20: the grid's
#: sweeps have |f''| <= 1.4, an orifice 0, laminar flow 0
SETTLED = 1e-10


def shared_pressure_drop(q: np.ndarray, dp: np.ndarray,
                         restriction_dp: Callable[[np.ndarray, np.ndarray], np.ndarray],
                         leak_at: Callable[[np.ndarray], Callable[[np.ndarray], np.ndarray]]
                         ) -> np.ndarray:
    """Δp [Pa] at which the restriction and the leakage paths together pass ``q`` [m^3/s].

    Parameters
    ----------
    q : numpy.ndarray
        Flow through the valve at each point [m^3/s].
    dp : numpy.ndarray
        Δp of the restriction alone passing all of ``q`` [Pa] (the answer without leakage).
    restriction_dp : callable
        ``restriction_dp(q_r, index)``: the restriction's Δp [Pa] at flow ``q_r`` for the points
        ``index``.
    leak_at : callable
        ``leak_at(index)`` returns ``leak(Δp)``, the leakage flow [m^3/s] of the points ``index``.
    """
    flowing = np.flatnonzero((q > 0) & np.isfinite(dp) & (dp > 0))
    q = q[flowing]
    g_full = leak_at(flowing)(dp[flowing])  # g at q_r = q
    if not np.any(g_full > 0):
        return dp
    dp = dp.copy()
    low, high = np.zeros(flowing.size), q.copy()
    previous, previous_drop = q.copy(), dp[flowing]
    share = np.clip(q - g_full, 0.0, q)
    active = np.arange(flowing.size)  # points not converged yet: only these are iterated
    for _ in range(STEPS):
        index = flowing[active]
        leak = leak_at(index)
        current, wanted = share[active], q[active]
        drop = restriction_dp(current, index)
        g = current + leak(drop) - wanted
        lower = np.where(g < 0, current, low[active])
        upper = np.where(g >= 0, current, high[active])
        with np.errstate(divide="ignore", invalid="ignore"):
            secant = (np.log(drop / previous_drop[active])
                      / np.log(current / previous[active]))
        exponent = np.where(np.isfinite(secant), np.clip(secant, 0.5, 4.0), 2.0)
        step, miss = _power_law_step(current, drop, exponent, wanted, leak)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            predicted = drop * (step / current) ** exponent
            # the secant's error at the step, in ln Δp: ½·f''·ln(step/current)·ln(step/prev)
            spread = np.abs(np.log(step / current) * np.log(step / previous[active]))
        # a step stands in for the map only where Newton found the power law's root: a leak
        # whose slope jumps (a table's kink, a table held beyond its last row) can send it round
        # a cycle, and a step that is no root, on an earlier evaluation, has no error at all
        settled = ((spread <= SETTLED) & (exponent == secant) & (step > lower)
                   & (step < upper) & np.isfinite(predicted)
                   & (np.abs(miss) <= 1e-9 * wanted))
        dp[index] = np.where(settled, predicted, drop)
        # converged: the flows balance to 1e-9 of q (so the leak, and Δp, to ~1e-9), the
        # power law's next step is settled, or the bracket is down to rounding (the
        # restriction passes almost nothing)
        done = (np.abs(g) <= 1e-9 * wanted) | settled | (upper - lower <= 1e-12 * upper)
        low[active], high[active] = lower, upper
        previous[active], previous_drop[active] = current, drop
        share[active] = np.where((step > lower) & (step < upper), step,
                                 0.5 * (lower + upper))
        active = active[~done]
        if not active.size:
            break
    return dp


def _power_law_step(share, drop, exponent, q, leak, newton_steps: int = 3
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Root x of x + leak(Δp(x)) = q with Δp(x) = drop·(x/share)^exponent (no map call), and
    that equation's residual [m^3/s] at the iterate before Newton's last update: as small as the
    split's tolerance where Newton has converged, not where it went round a cycle."""
    x = share
    miss = np.full(np.shape(share), np.inf)
    for _ in range(newton_steps):
        with np.errstate(divide="ignore", invalid="ignore"):
            pressure = drop * (x / share) ** exponent
            nudge = 1e-6 * pressure
            leaking = leak(pressure)  # once: a leak of free shape costs as much as a map call
            slope = (leak(pressure + nudge) - leaking) / nudge  # d leak / dΔp
            derivative = 1.0 + slope * exponent * pressure / x
            miss = x + leaking - q
            x = x - miss / derivative
    return x, miss
