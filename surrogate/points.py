"""Operating points: what the valve is asked to do, one entry per point, SI inside."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from .core.errors import InputError
from .core.units import to_si

OPENING, CLOSING, STEADY = 1, -1, 0
_DIRECTIONS = {"up": OPENING, "down": CLOSING}


@dataclass(frozen=True)
class OperatingPoints:
    """A batch of operating points of the valve in its relief mode.

    Attributes
    ----------
    q : numpy.ndarray
        Flow through the valve, load to back port [m^3/s].
    p_P : numpy.ndarray
        Pilot pressure (gauge) [Pa].
    p_B : numpy.ndarray
        Back pressure (gauge) [Pa].
    temperature : numpy.ndarray
        Oil temperature [K].
    direction : numpy.ndarray of int
        +1 while the piston opens (flow ramping up), −1 while it closes (ramping down), 0 for a
        point without history (friction left out). Selects the side of the friction band.
    run : numpy.ndarray of str, or None
        The bench run each point belongs to, for effects whose parameters differ from run to run
        (:mod:`surrogate.effects.per_run`); None for points that belong to no run.
    """

    q: np.ndarray
    p_P: np.ndarray
    p_B: np.ndarray
    temperature: np.ndarray
    direction: np.ndarray
    run: np.ndarray | None = None

    def __post_init__(self):
        arrays = np.broadcast_arrays(*(np.asarray(getattr(self, name), float)
                                       for name in ("q", "p_P", "p_B", "temperature")),
                                     np.asarray(self.direction, np.int8))
        for name, array in zip(("q", "p_P", "p_B", "temperature", "direction"), arrays):
            object.__setattr__(self, name, np.ascontiguousarray(array).ravel())
        if self.run is not None:
            # fixed-width text, not objects: effects compare labels on every model evaluation
            run = np.asarray(self.run).astype(str, copy=False).ravel()
            if run.shape != self.q.shape:
                raise InputError(f"{run.size} run labels for {self.q.size} operating points")
            object.__setattr__(self, "run", run)

    @classmethod
    def create(cls, q, p_P, p_B, temperature, direction=STEADY) -> "OperatingPoints":
        """Points from arrays (or scalars) in SI units; see the class attributes."""
        return cls(q, p_P, p_B, temperature, direction)

    @classmethod
    def from_bench(cls, frame: pd.DataFrame) -> "OperatingPoints":
        """The points of a bench log's SI frame (:class:`surrogate.data.BenchLog`)."""
        # every replay of a log starts here: compared as an array, the labels cost a tenth of
        # the time pandas' map takes (3 ms on the shipped log); anything else is mapped as ever
        labels = frame["direction"].to_numpy()
        up, down = labels == "up", labels == "down"
        direction = (np.where(up, _DIRECTIONS["up"], _DIRECTIONS["down"]) if np.all(up | down)
                     else frame["direction"].map(_DIRECTIONS).to_numpy())
        return cls(frame["q"].to_numpy(), frame["p_P"].to_numpy(), frame["p_B"].to_numpy(),
                   frame["temperature"].to_numpy(), direction, frame["run"].to_numpy())

    @classmethod
    def from_display(cls, q_lpm, p_P_bar, p_B_bar, temperature_C,
                     direction=STEADY) -> "OperatingPoints":
        """Points from display units: L/min, bar, °C."""
        return cls(to_si(q_lpm, "L/min"), to_si(p_P_bar, "bar"), to_si(p_B_bar, "bar"),
                   to_si(temperature_C, "degC"), direction)

    def __len__(self) -> int:
        return len(self.q)

    def __getitem__(self, index) -> "OperatingPoints":
        if isinstance(index, np.ndarray) and index.dtype.kind in "iu" and index.ndim == 1:
            # positions, as the solver takes its subsets: np.take gathers the same elements
            # at a third of fancy indexing's time on the run labels' text
            arrays = tuple(None if array is None else array.take(index) for array in (
                self.q, self.p_P, self.p_B, self.temperature, self.direction, self.run))
        else:
            arrays = (self.q[index], self.p_P[index], self.p_B[index], self.temperature[index],
                      self.direction[index], None if self.run is None else self.run[index])
        if arrays[0].ndim != 1 or not all(a is None or a.flags.c_contiguous for a in arrays):
            return OperatingPoints(*arrays)  # a scalar or a strided subset: made flat as ever
        # a flat subset of checked arrays is as __post_init__ would leave it: the solver takes
        # subsets at every step, and the checks cost more than the subset
        subset = object.__new__(OperatingPoints)
        for name, array in zip(("q", "p_P", "p_B", "temperature", "direction", "run"), arrays):
            object.__setattr__(subset, name, array)
        return subset

    def replace(self, **arrays) -> "OperatingPoints":
        """A copy with some attributes replaced (e.g. corrected sensor readings)."""
        values = {name: getattr(self, name) for name in
                  ("q", "p_P", "p_B", "temperature", "direction", "run")}
        values.update(arrays)
        return OperatingPoints(**values)

    def invalid(self) -> np.ndarray:
        """True where a point cannot be solved: non-finite values, negative flow or temperature."""
        finite = np.isfinite(self.q) & np.isfinite(self.p_P) & np.isfinite(self.p_B) & np.isfinite(
            self.temperature)
        return ~finite | (self.q < 0) | (self.temperature <= 0)


def concatenate(batches: list[OperatingPoints]) -> OperatingPoints:
    """One batch made of several."""
    if not batches:
        raise InputError("no operating points")
    arrays = [np.concatenate([getattr(b, name) for b in batches])
              for name in ("q", "p_P", "p_B", "temperature", "direction")]
    # run labels survive only if every batch has them
    labelled = all(b.run is not None for b in batches)
    run = np.concatenate([b.run for b in batches]) if labelled else None
    return OperatingPoints(*arrays, run)
