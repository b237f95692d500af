"""The median line of a ramp test: the data with the friction hysteresis averaged out.

Following the paper (after Handroos & Halme 1996): the samples are binned by flow; in each bin the
median pressure drop of the up-ramp and that of the down-ramp are averaged. Friction shifts the two
ramps by about the same amount in opposite directions, so their mean is the friction-free curve the
paper compares its models with (Table 5). The pilot and back pressure and the temperature of each
bin are averaged the same way, so a model can be evaluated at the bin's operating point.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..data.loaders import BenchRun
from ..points import OperatingPoints
from ..core.units import LPM

DEFAULT_BIN_WIDTH = 0.5 * LPM  # [m^3/s]
MIN_SAMPLES_PER_SIDE = 3


def median_line(run: BenchRun, bin_width: float = DEFAULT_BIN_WIDTH,
                min_samples: int = MIN_SAMPLES_PER_SIDE) -> pd.DataFrame:
    """The median line of one run.

    Parameters
    ----------
    run : BenchRun
    bin_width : float
        Width of the flow bins [m^3/s]; bins start at the smallest flow of the run.
    min_samples : int
        Bins with fewer up- or down-ramp samples than this are left out.

    Returns
    -------
    pandas.DataFrame
        One row per bin, SI units: ``q``, ``dp``, ``p_P``, ``p_B``, ``temperature`` (mean of the
        up and down medians), ``dp_up``, ``dp_down`` (the two medians), ``n_up``, ``n_down``.
    """
    frame = run.frame.assign(dp=run.frame["p_L"] - run.frame["p_B"])
    start = frame["q"].min()
    frame = frame.assign(bin=np.floor((frame["q"] - start) / bin_width).astype(int))
    columns = ["q", "dp", "p_P", "p_B", "temperature"]
    medians = frame.groupby(["bin", "direction"])[columns].median().unstack("direction")
    counts = frame.groupby(["bin", "direction"]).size().unstack("direction", fill_value=0)
    for side in ("up", "down"):
        if side not in counts:
            counts[side] = 0
    keep = (counts["up"] >= min_samples) & (counts["down"] >= min_samples)
    medians, counts = medians[keep.reindex(medians.index, fill_value=False)], counts[keep]
    line = pd.DataFrame({name: 0.5 * (medians[(name, "up")] + medians[(name, "down")])
                         for name in columns})
    line["dp_up"] = medians[("dp", "up")]
    line["dp_down"] = medians[("dp", "down")]
    line["n_up"] = counts["up"]
    line["n_down"] = counts["down"]
    return line.reset_index(drop=True)


def median_points(line: pd.DataFrame) -> OperatingPoints:
    """The operating points of a median line, without friction direction."""
    return OperatingPoints.create(line["q"].to_numpy(), line["p_P"].to_numpy(),
                                  line["p_B"].to_numpy(), line["temperature"].to_numpy())
