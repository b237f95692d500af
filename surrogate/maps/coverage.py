"""Where the CFD samples are, and why a query lies outside them.

Every map kind is built from the same kind of data, so every kind says in the same terms where a
query extrapolates. A query is flagged, with each reason that applies, when it lies

* outside the sampled openings, or in a gap between two sampled openings much wider than the
  CFD's usual spacing (the shipped samples jump from 0.20 to 0.63 mm);
* outside the pressure drops sampled at its opening (interpolated in ln u between the openings
  around it), or outside the flows sampled there;
* outside the sampled viscosities (temperatures, for the valve's oil) or back pressures;
* far from every sample in the learned maps' feature space (a hole in a non-rectangular grid;
  learned maps only).

The reasons are bit flags (:data:`REASONS`); :func:`describe` turns them into words.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.units import P_ATM, from_si

OPENING_OUTSIDE = 1
OPENING_GAP = 2
DP_OUTSIDE = 4
FLOW_OUTSIDE = 8
VISCOSITY_OUTSIDE = 16
BACK_PRESSURE_OUTSIDE = 32
FEATURES_SPARSE = 64

#: flag -> what it means, in the words of a column or a table
REASONS = {
    OPENING_OUTSIDE: "opening outside the sampled ones",
    OPENING_GAP: "opening in an unsampled gap",
    DP_OUTSIDE: "pressure drop outside the samples at this opening",
    FLOW_OUTSIDE: "flow outside the samples at this opening",
    VISCOSITY_OUTSIDE: "viscosity outside the sampled ones",
    BACK_PRESSURE_OUTSIDE: "back pressure outside the sampled ones",
    FEATURES_SPARSE: "far from every sample (a hole in the data)",
}

#: a gap between neighbouring openings counts as unsampled when it is this many times the
#: median spacing (in ln u) of the samples' openings
GAP_FACTOR = 2.5
_FIELDS = ("openings", "dp_low", "dp_high", "q_low", "q_high", "nu_range", "p_B_range",
           "back_pressures")
#: relative slack on every range (a query at a sampled value rounded differently is inside)
_SLACK = 0.02


@dataclass(frozen=True)
class Coverage:
    """The sampled region: openings, Δp and q ranges per opening, viscosities, back pressures.

    All arrays in SI: ``openings`` [m] increasing; ``dp_low``/``dp_high`` [Pa] and
    ``q_low``/``q_high`` [m^3/s] per opening; ``nu_range`` [m^2/s] and ``p_B_range`` [Pa] as
    (low, high); ``back_pressures`` [Pa] the distinct sampled back pressures.
    """

    openings: np.ndarray
    dp_low: np.ndarray
    dp_high: np.ndarray
    q_low: np.ndarray
    q_high: np.ndarray
    nu_range: np.ndarray
    p_B_range: np.ndarray
    back_pressures: np.ndarray

    @classmethod
    def of_samples(cls, frame) -> "Coverage":
        """The coverage of CFD samples (an SI frame, :class:`~surrogate.data.CfdSamples`)."""
        u = frame["u"].to_numpy()
        openings = np.unique(np.round(u, 12))
        dp = (frame["p_L"] - frame["p_B"]).to_numpy()
        q = frame["q"].to_numpy()
        at = [np.isclose(u, opening, rtol=1e-6, atol=0) for opening in openings]
        return cls(openings, np.array([dp[m].min() for m in at]),
                   np.array([dp[m].max() for m in at]), np.array([q[m].min() for m in at]),
                   np.array([q[m].max() for m in at]),
                   np.array([frame["nu"].min(), frame["nu"].max()]),
                   np.array([frame["p_B"].min(), frame["p_B"].max()]),
                   np.unique(np.round(frame["p_B"].to_numpy(), -2)))

    def to_dict(self) -> dict:
        return {key: getattr(self, key).tolist() for key in _FIELDS}

    @classmethod
    def from_dict(cls, data: dict) -> "Coverage":
        return cls(*(np.asarray(data[key], float) for key in _FIELDS))

    def back_pressure_distance(self, p_B) -> np.ndarray:
        """How far ``p_B`` [Pa] lies from the nearest sampled back pressure, as |ln| of the ratio
        of absolute pressures [-]: the CFD runs at few back pressures, and between or beyond
        them cavitation changes the flow and its force in ways the features do not fully carry
        (:mod:`.sigma`)."""
        absolute = np.asarray(p_B, float)[..., None] + P_ATM
        return np.min(np.abs(np.log(absolute / (self.back_pressures + P_ATM))), axis=-1)

    @property
    def central_back_pressure(self) -> float:
        """The median of the sampled back pressures [Pa]: where the CFD's sweeps are usually run
        (the shipped set's 5 bar, beside its back-pressure set at 1.5 and 10 bar), the
        reference of the cavitation model's error (:func:`.cfd_error.cavitation_error`)."""
        return float(np.median(self.back_pressures))

    def opening_distance(self, u) -> np.ndarray:
        """How far ``u`` [m] lies from the nearest sampled opening, as a share of half the
        closest spacing of two sampled openings in ln u, at most 1 [-]: 0 on a sampled opening,
        1 anywhere between openings from halfway to the closest neighbour on (the reach of the
        flow network's opening offsets, :mod:`.opening_offsets`). Every opening is a mesh of its
        own, and between openings a map has only its features to go by (:mod:`.sigma`).
        The bound is what cross-validation can calibrate: a left-out opening lies a whole
        spacing from the others (at 1 here, in every fold), so the errors tell how unsure a map
        is between openings but not how that grows across a gap three times as wide (unbounded,
        |ln u − ln u_i| with the power fitted to left-out openings made σ explode across the
        0.20-0.63 mm gap); σ grows there with the features' distance."""
        log_openings = np.log(self.openings)
        log_u = np.log(np.maximum(np.asarray(u, float), 1e-12))[..., None]
        distance = np.min(np.abs(log_u - log_openings), axis=-1)
        if len(log_openings) < 2:
            return np.minimum(distance, 1.0)
        return np.minimum(distance / (float(np.min(np.diff(log_openings))) / 2), 1.0)

    def gaps(self) -> list[tuple[float, float]]:
        """The unsampled gaps between neighbouring openings, (low, high) [m]."""
        if len(self.openings) < 3:
            return []
        steps = np.diff(np.log(self.openings))
        wide = steps > GAP_FACTOR * np.median(steps)
        return [(self.openings[i], self.openings[i + 1]) for i in np.flatnonzero(wide)]

    def reasons(self, dp, q, p_B, u, nu) -> np.ndarray:
        """Bit flags (:data:`REASONS`) of each query; 0 inside the samples.

        Parameters: Δp [Pa], q [m^3/s], p_B [Pa], u [m], ν [m^2/s], broadcast together.
        """
        dp, q, p_B, u, nu = np.broadcast_arrays(*(np.asarray(x, float) for x in
                                                  (dp, q, p_B, u, nu)))
        flags = np.zeros(u.shape, dtype=np.int64)
        low, high = self.openings[0], self.openings[-1]
        flags |= np.where((u < low * (1 - _SLACK)) | (u > high * (1 + _SLACK)),
                          OPENING_OUTSIDE, 0)
        near_sample = np.any(np.abs(u[..., None] / self.openings - 1.0) <= _SLACK, axis=-1)
        for gap_low, gap_high in self.gaps():
            flags |= np.where((u > gap_low) & (u < gap_high) & ~near_sample, OPENING_GAP, 0)
        log_u = np.log(np.clip(u, low, high))
        for lower, upper, value, flag in ((self.dp_low, self.dp_high, dp, DP_OUTSIDE),
                                          (self.q_low, self.q_high, q, FLOW_OUTSIDE)):
            # ranges interpolated in ln u (in ln of the quantity) between the openings around u
            bottom = np.exp(np.interp(log_u, np.log(self.openings), np.log(lower)))
            top = np.exp(np.interp(log_u, np.log(self.openings), np.log(upper)))
            flags |= np.where((value < bottom * (1 - _SLACK)) | (value > top * (1 + _SLACK)),
                              flag, 0)
        flags |= np.where((nu < self.nu_range[0] * (1 - _SLACK))
                          | (nu > self.nu_range[1] * (1 + _SLACK)), VISCOSITY_OUTSIDE, 0)
        slack = max(_SLACK * self.p_B_range[1], 0.05e5)
        flags |= np.where((p_B < self.p_B_range[0] - slack) | (p_B > self.p_B_range[1] + slack),
                          BACK_PRESSURE_OUTSIDE, 0)
        return flags

    def describe_gaps(self) -> str:
        return ", ".join(f"{from_si(a, 'mm'):g}–{from_si(b, 'mm'):g} mm" for a, b in self.gaps())


def describe(flags: int) -> str:
    """The reasons of one query's flags in words ("" when inside the samples)."""
    return "; ".join(text for flag, text in REASONS.items() if int(flags) & flag)


def describe_all(flags: np.ndarray) -> np.ndarray:
    """:func:`describe` of each flag value, as an object array whose equal values share one
    string (each distinct combination of flags is worded once: a log of millions of samples has
    a few dozen)."""
    distinct, inverse = np.unique(np.ravel(np.asarray(flags, np.int64)), return_inverse=True)
    words = np.array([describe(int(value)) for value in distinct], dtype=object)
    return words[inverse] if len(distinct) else np.array([], dtype=object)


def shares(flags: np.ndarray) -> dict[str, float]:
    """The share of queries flagged for each reason (and for any)."""
    flags = np.asarray(flags, np.int64)
    result = {"any": float(np.mean(flags != 0)) if flags.size else 0.0}
    for flag, text in REASONS.items():
        result[text] = float(np.mean((flags & flag) != 0)) if flags.size else 0.0
    return result
