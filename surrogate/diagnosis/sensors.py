"""Per-run parameters that look like a sensor fault: checks for the bench, never model terms."""

from __future__ import annotations

import numpy as np

from ..core.units import from_si
from .result import Candidate, SensorCheck

#: a run's parameter is flagged when it exceeds this many standard errors
SENSOR_CHECK_SIGMAS = 3.0


def sensor_checks(candidates: list[Candidate],
                  schemes: dict[str, dict[str, list[str]]]) -> tuple[SensorCheck, ...]:
    """Per-run parameters that look like a sensor fault, largest first.

    A sensor's zero drifts at random from run to run; an offset that the runs at the same pilot
    set point, or at the same temperature, share follows the operating point, and is map error
    or physics. So a run is flagged when its value departs from the mean of the other runs at its
    set point, and from that of the other runs at its temperature (from zero where it has no
    such peers), by more than :data:`SENSOR_CHECK_SIGMAS` standard errors and more than the
    sensor's own noise allows (the effect's ``check_threshold``)."""
    peers: dict[str, list[list[str]]] = {}
    for scheme in ("pilot pressure", "temperature"):
        for runs in schemes.get(scheme, {}).values():
            for run in runs:
                peers.setdefault(run, []).append([other for other in runs if other != run])
    checks = []
    for candidate in candidates:
        if not candidate.per_run:
            continue
        values = {str(p.scope): p.display_value for p in candidate.params}
        for parameter in candidate.params:
            groups = [[values[run] for run in group if run in values]
                      for group in peers.get(str(parameter.scope), [])]
            departure = min((parameter.display_value - (float(np.mean(g)) if g else 0.0)
                             for g in groups), key=abs, default=parameter.display_value)
            stderr = from_si(parameter.stderr, parameter.unit) if parameter.stderr else 0.0
            if (stderr and abs(departure) > SENSOR_CHECK_SIGMAS * stderr
                    and abs(departure) > candidate.check_threshold):
                checks.append(SensorCheck(candidate.name, candidate.title, str(parameter.scope),
                                          parameter.display_value, float(stderr),
                                          parameter.unit))
    return tuple(sorted(checks, key=lambda check: -abs(check.value)))
