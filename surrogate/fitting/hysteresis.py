"""A run's residual split into its median line and its half-width, the paper's two views.

At equal flow, a map error moves a run's ramp up and ramp down nearly alike: it shifts the
*median line*, the mean of the two branches (the paper's Table 5 compares models by it). Friction
changes their *split*, the *half-width*, half their difference (Table 6 fits friction to it). So
the half-width is where the maps' error barely reaches: a friction candidate must explain it, and
a force or flow candidate must explain the median line (:mod:`~surrogate.diagnosis.diagnose`).

The split is linear. Per run, the flow range both branches cover is cut into bins; a bin's median
and half-width are averages of each branch's samples in it. As matrices the split applies alike to
a residual and to its changes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

#: flow bins per run, and the samples each branch needs in a bin for the bin to count
BINS = 12
MIN_SAMPLES = 2


@dataclass(frozen=True)
class HysteresisSplit:
    """The two views of a set of samples.

    Attributes
    ----------
    median, half : numpy.ndarray
        (bins, n) matrices: a residual r over the n samples has the median line ``median @ r``
        and the half-width ``half @ r`` (up minus down, halved) in each bin [units of r].
    runs : numpy.ndarray
        The run of each bin.
    """

    median: np.ndarray
    half: np.ndarray
    runs: np.ndarray

    @property
    def bins(self) -> int:
        return len(self.runs)

    def rms(self, residual: np.ndarray) -> tuple[float, float]:
        """RMS of the median line and of the half-width of ``residual`` over the bins (NaN for
        a log without runs that go both ways)."""
        if not self.bins:
            return float("nan"), float("nan")
        return (float(np.sqrt(np.mean((self.median @ residual) ** 2))),
                float(np.sqrt(np.mean((self.half @ residual) ** 2))))


def hysteresis_split(frame: pd.DataFrame, bins: int = BINS,
                     min_samples: int = MIN_SAMPLES) -> HysteresisSplit:
    """The split of the samples of ``frame`` (a bench log's rows: ``run``, ``q``, ``direction``)
    in their order."""
    runs = frame["run"].astype(str).to_numpy()
    q = frame["q"].to_numpy(float)
    up = frame["direction"].to_numpy() == "up"
    count = len(frame)
    pairs, labels = [], []  # each bin's rising and falling samples, and its run
    for run in dict.fromkeys(runs):
        # the run's own samples only: a bin's samples lie in its run
        rows = np.flatnonzero(runs == run)
        run_q, rising = q[rows], up[rows]
        falling = ~rising
        if rising.sum() < min_samples or falling.sum() < min_samples:
            continue
        low = max(run_q[rising].min(), run_q[falling].min())
        high = min(run_q[rising].max(), run_q[falling].max())
        if not high > low:
            continue
        edges = np.linspace(low, high, bins + 1)
        which = np.clip(np.searchsorted(edges, run_q, side="right") - 1, 0, bins - 1)
        within = (run_q >= low) & (run_q <= high)
        for b in range(bins):
            a = rows[np.flatnonzero(rising & within & (which == b))]
            d = rows[np.flatnonzero(falling & within & (which == b))]
            if len(a) < min_samples or len(d) < min_samples:
                continue
            pairs.append((a, d))
            labels.append(run)
    # the bins' rows filled in place, not stacked from rows of their own
    median, half = np.zeros((len(pairs), count)), np.zeros((len(pairs), count))
    for row, (a, d) in enumerate(pairs):
        median[row, a], median[row, d] = 0.5 / len(a), 0.5 / len(d)
        half[row, a], half[row, d] = 0.5 / len(a), -0.5 / len(d)
    return HysteresisSplit(median, half, np.array(labels) if labels else np.zeros(0, str))
