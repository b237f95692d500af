"""How the back pressure moves the flow force: one law of the cavitation number, fitted to the
CFD's back-pressure set, for a map built from the sweeps at one back pressure (the grid).

The grid (:mod:`.grid`) interpolates the sweeps run at one back pressure (the shipped set's
5 bar). At a lower back pressure the jet leaving the throttling edge cavitates sooner, the
pressure does not recover on the piston's face, and the flow force falls. What decides it is the
cavitation number σ = (p_B + p_atm − p_sat)/Δp of the learned maps' features
(:meth:`surrogate.features.FeatureSpec.cavitation_number`): the CFD's back-pressure set runs the
same opening and flow at 1.5, 5 and 10 bar, and its flow-force fraction α = f_ff/(A_L·Δp) falls
by half where σ drops below 0.02 and stays within a few per cent where σ > 0.3, at every opening.
The paper left p_B out of its maps (its eq. 19 eliminates it).

One law for every opening, flow and oil::

    α = α_∞ · c(σ),    c(σ) = 1 − exp(−(σ/σ₀)^m)

c tends to 1 without cavitation (σ → ∞) and falls as the jet cavitates. σ₀ and m are fitted by
least squares in ln|α| to every group of samples at one fluid state, opening and flow run at two
or more back pressures, each group with its own α_∞. A map built at the reference back pressure
p_ref then answers α(p_B) = α_ref·c(σ)/c(σ_ref), σ_ref at p_ref and the same Δp. Below the
smallest σ the law was fitted on, c is held there, as the grid holds its sweeps' ends. How well
the law predicts an opening it was not fitted to, and what that does to the grid's σ, is in
docs/maps.md (the grid's cross-validation leaves one opening's back-pressure set out at a time).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy.optimize import least_squares

from ..features import FeatureSpec
from ..valve import ValveParameters
from .splits import SAME_RTOL, group_keys, main_set

#: bounds of the fitted σ₀ [1] and m [1]: far beyond anything a valve's CFD shows, only to keep
#: a degenerate set (one group, every σ alike) from running off
_SIGMA0_RANGE = (1e-4, 10.0)
_EXPONENT_RANGE = (0.2, 5.0)


@dataclass(frozen=True)
class CavitationLaw:
    """c(σ) = 1 − exp(−(σ/σ₀)^m) of the flow-force fraction (module docstring).

    Attributes
    ----------
    sigma0 : float
        Cavitation number [1] at which c = 1 − 1/e.
    exponent : float
        m [1].
    sigma_low : float
        Smallest cavitation number [1] of the samples the law was fitted on; c is held below.
    spec : FeatureSpec
        The valve's constants that turn (p_B, Δp) into σ.
    groups : int
        How many groups of samples (one fluid state, opening and flow each, several back
        pressures) it was fitted on.
    """

    sigma0: float
    exponent: float
    sigma_low: float
    spec: FeatureSpec
    groups: int

    def factor(self, sigma) -> np.ndarray:
        """c(σ) [1] at cavitation numbers ``sigma`` [1], held below :attr:`sigma_low`."""
        sigma = np.maximum(np.asarray(sigma, float), self.sigma_low)
        return -np.expm1(-(sigma / self.sigma0) ** self.exponent)

    def ratio(self, p_B, reference: float, dp) -> np.ndarray:
        """α at back pressure ``p_B`` [Pa] over α at ``reference`` [Pa], at pressure drop ``dp``
        [Pa] (all broadcast together): c(σ)/c(σ_ref), 1 where p_B is the reference."""
        p_B, dp = np.broadcast_arrays(np.asarray(p_B, float), np.asarray(dp, float))
        sigma = self.spec.cavitation_number(p_B, dp)
        sigma_reference = self.spec.cavitation_number(np.full(p_B.shape, reference), dp)
        return self.factor(sigma) / self.factor(sigma_reference)

    def describe(self) -> str:
        return (f"cavitation law of the flow force: c(σ) = 1 − exp(−(σ/{self.sigma0:.4g})"
                f"^{self.exponent:.3g}), fitted on {self.groups} groups of the back-pressure set")

    @classmethod
    def fit(cls, frame: pd.DataFrame, valve: ValveParameters) -> "CavitationLaw | None":
        """The law of the samples in ``frame`` (SI columns of :class:`~surrogate.data.CfdSamples`,
        flows > 0), or None where they hold too little to fit it: fewer than two groups of one
        fluid state, opening and flow at two or more back pressures (with the flow force of one
        sign in each)."""
        spec = FeatureSpec.for_valve(valve)
        dp, fraction, sigma = _fractions(frame, valve, spec)
        keys = [group_keys(frame[name].to_numpy()) for name in ("nu", "u", "q")]
        groups = []
        for _, index in pd.Series(np.arange(len(frame))).groupby(keys):
            index = index.to_numpy()
            if (len(np.unique(np.round(frame["p_B"].to_numpy()[index], -2))) >= 2
                    and np.all(dp[index] > 0)
                    and (np.all(fraction[index] > 0) or np.all(fraction[index] < 0))):
                groups.append(index)
        if len(groups) < 2:
            return None
        log_alpha = [np.log(np.abs(fraction[index])) for index in groups]
        log_sigma = [np.log(sigma[index]) for index in groups]

        def residuals(theta):
            log_sigma0, exponent = theta[0], theta[1]
            return np.concatenate([
                values - offset - np.log(-np.expm1(-np.exp(exponent * (logs - log_sigma0))))
                for values, logs, offset in zip(log_alpha, log_sigma, theta[2:])])

        start = np.concatenate([[np.log(0.05), 1.0], [values.max() for values in log_alpha]])
        low = np.concatenate([[np.log(_SIGMA0_RANGE[0]), _EXPONENT_RANGE[0]],
                              np.full(len(groups), -np.inf)])
        high = np.concatenate([[np.log(_SIGMA0_RANGE[1]), _EXPONENT_RANGE[1]],
                               np.full(len(groups), np.inf)])
        solution = least_squares(residuals, start, bounds=(low, high))
        used = np.concatenate(groups)
        return cls(float(np.exp(solution.x[0])), float(solution.x[1]),
                   float(np.min(sigma[used])), spec, len(groups))


def _fractions(frame: pd.DataFrame, valve: ValveParameters, spec: FeatureSpec):
    """Δp [Pa], the flow-force fraction α [1] and the cavitation number σ [1] of each sample."""
    dp = (frame["p_L"] - frame["p_B"]).to_numpy()
    flow_force = frame["f_sim"].to_numpy() - spec.uniform_force(frame["p_L"], frame["p_B"])
    with np.errstate(divide="ignore", invalid="ignore"):
        fraction = flow_force / (valve.A_L * dp)
    return dp, fraction, spec.cavitation_number(frame["p_B"].to_numpy(), dp)


def left_out_opening_errors(frame: pd.DataFrame, valve: ValveParameters) -> pd.DataFrame:
    """How well the law predicts an opening it was not fitted to: each sample of the
    back-pressure set (``frame``'s samples away from its reference back pressure, flows > 0)
    from the law of the other openings' sets and the opening's own run at the reference, at the
    same fluid state and flow.

    One row per such sample: u [m], q [m^3/s], p_B [Pa], sigma [1], and the error in ln α of
    the law (``with_law``) and of ignoring the back pressure (``ignoring_p_B``, α of the run at
    the reference), as the paper's maps do.
    """
    frame = frame[frame["q"] > 0].reset_index(drop=True)
    spec = FeatureSpec.for_valve(valve)
    _, alpha, sigma = _fractions(frame, valve, spec)
    main = main_set(frame)
    u, q, nu = (frame[name].to_numpy() for name in ("u", "q", "nu"))
    rows = []
    for opening in np.unique(u[~main]):
        at = np.isclose(u, opening, rtol=SAME_RTOL, atol=0)
        law = CavitationLaw.fit(frame[~(at & ~main)], valve)
        for index in np.flatnonzero(at & ~main):
            same = np.flatnonzero(at & main & np.isclose(q, q[index], rtol=SAME_RTOL, atol=0)
                                  & np.isclose(nu, nu[index], rtol=SAME_RTOL, atol=0))
            if law is None or len(same) == 0:
                continue
            reference = same[0]
            predicted = alpha[reference] * law.factor(sigma[index]) / law.factor(sigma[reference])
            rows.append({"u": opening, "q": q[index], "p_B": frame["p_B"].iloc[index],
                         "sigma": sigma[index],
                         "with_law": np.log(predicted / alpha[index]),
                         "ignoring_p_B": np.log(alpha[reference] / alpha[index])})
    return pd.DataFrame(rows, columns=["u", "q", "p_B", "sigma", "with_law", "ignoring_p_B"])

