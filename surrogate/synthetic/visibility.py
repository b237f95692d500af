"""When a hidden effect left a log nothing to find: the stress suites' judgement of a log that
ends with nothing added.

A virtual valve's hidden effect can be too small to show under the maps' own error: a leak of
0.05 L/min, a laminar leakage of its realistic size that the CFD's error at the smallest openings
hides (the library stress suite's case 209: the leak, fitted, predicts the runs left out 0.2 %
better). A loop that adds nothing there is right, since a claim would rest on less than the
discovery rule asks. Such a case is judged against its *twin*, the same virtual valve (the same
map mismatch and sensor noise) with nothing hidden: when the log ends within :data:`RMS_RATIO` of
the noise floor and within :data:`TWIN_RATIO` of what the twin ends at, the effect moved nothing
the bench can see. A case in which the loop named a claim and then withheld it for a look-alike
is not such a case: the log showed something, and could not say what.

Both stress suites judge alike (:mod:`.offlibrary`, :mod:`.simulate`), and count the invisible
cases apart from the found ones.
"""

from __future__ import annotations

import numpy as np

#: the final RMS over the noise floor within which a case counts as explained
RMS_RATIO = 1.3
#: or within this factor of what the same virtual valve with nothing hidden ends at
TWIN_RATIO = 1.1


def over_floor(workflow) -> float:
    """The final RMS of a finished ``workflow`` over its noise floor."""
    return float(workflow.final.rms / workflow.noise_floor)


def left_nothing_to_find(rms_over_floor: float, twin_over_floor: float) -> bool:
    """Whether a log that ends at ``rms_over_floor`` times its noise floor, with nothing added
    and nothing withheld, is as its twin, which ends at ``twin_over_floor`` (nan: no twin run,
    never): within :data:`RMS_RATIO` of the floor and :data:`TWIN_RATIO` of the twin."""
    return bool(rms_over_floor <= RMS_RATIO and np.isfinite(twin_over_floor)
                and rms_over_floor <= TWIN_RATIO * twin_over_floor)
