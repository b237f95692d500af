"""Effects whose parameter takes a different value in each bench run.

Some errors are constant within a test but change between tests: a transducer re-zeroed before
each run, a sensor that drifts over a day. Such an effect has one parameter per run, named
``<template>_<run>`` (``delta_R01``, ``delta_R02``, ...), created for the runs of the log it is
fitted to (:meth:`PerRunEffect.for_runs`). Each parameter carries its run as its ``scope``: it
changes only that run's samples, so a fit differentiates it by replaying that run alone, and a
dozen runs cost one replay, not a dozen.

A run the effect has no parameter for (a log it was not fitted to, or points that belong to no
run) gets the template's default value, i.e. the effect is off there.
"""

from __future__ import annotations

import copy
from typing import ClassVar

import numpy as np

from .base import Effect, Parameter


class PerRunEffect(Effect):
    """Base class: subclasses set ``template`` (the parameter every run gets a copy of) and use
    :meth:`per_point` in their hook."""

    template: ClassVar[Parameter]
    #: a run's value (display units) below which a diagnosis does not flag the run: what the
    #: sensor's own noise or spec allows
    check_threshold: ClassVar[float] = 0.0

    def __init__(self, runs: tuple[str, ...] = (), **values: float):
        """One parameter per run in ``runs`` (default value: the template's, the effect off);
        ``values`` in the display unit by parameter name, e.g. ``delta_R01=0.2`` (bar)."""
        self.params = {}
        for run in runs:
            parameter = copy.copy(self.template)
            parameter.name, parameter.scope = self.parameter_name(run), str(run)
            self.params[parameter.name] = parameter
        unknown = set(values) - set(self.params)
        if unknown:
            raise TypeError(f"{type(self).__name__} has no parameter(s) "
                            f"{', '.join(sorted(unknown))} for runs {', '.join(runs) or 'none'}")
        for key, value in values.items():
            self.params[key].set_display(value)

    @classmethod
    def parameter_name(cls, run: str) -> str:
        return f"{cls.template.name}_{run}"

    @classmethod
    def for_runs(cls, runs: list[str]) -> "PerRunEffect":
        return cls(tuple(str(run) for run in runs))

    @classmethod
    def for_parameters(cls, names: list[str]) -> "PerRunEffect":
        prefix = f"{cls.template.name}_"
        # other names get no parameter, so that the model file's loader reports them as unknown
        return cls(tuple(name[len(prefix):] for name in names if name.startswith(prefix)))

    def per_point(self, points) -> np.ndarray:
        """The parameter's SI value at each point, from the point's run."""
        value = np.full(len(points), self.template.value)
        if points.run is None or not self.params:
            return value
        for parameter in self.params.values():
            value[points.run == parameter.scope] = parameter.value
        return value
