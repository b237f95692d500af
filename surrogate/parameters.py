"""Named model parameters, in the manner of lmfit: one :class:`Parameter`, and the
:class:`Parameters` of a whole model keyed ``"effect.parameter"``.

Values are SI inside the package. Every parameter carries the unit it is shown and written in and
crosses the boundary in that unit: effect constructors, model files, JSON and reports all speak
display units (``K2 = 0.05`` N/bar, not 5e-7 N/Pa). A parameter's *record*
(:meth:`Parameter.to_record`) is the one serialised form, written alike to TOML and to JSON.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass

import numpy as np

from .core.errors import InputError
from .core.units import from_si, label, to_si

_RECORD_KEYS = {"value", "unit", "min", "max", "vary", "stderr"}


@dataclass
class Parameter:
    """A named model parameter, in the manner of ``lmfit.Parameter``.

    Attributes
    ----------
    name : str
        Name, unique within its effect.
    value : float
        Value in SI units.
    unit : str
        Unit it is displayed and written in (a key of :mod:`surrogate.core.units`).
    min, max : float
        Bounds in SI units.
    vary : bool
        Whether fitting may change it.
    description : str
        What it means, in words.
    stderr : float or None
        Standard error from the last fit [SI], if any.
    scope : str or None
        The bench run it acts on, for a parameter that changes only that run's samples (see
        :mod:`surrogate.effects.per_run`); a fit then differentiates it by replaying that run
        alone.
    """

    name: str
    value: float
    unit: str = "1"
    min: float = -np.inf
    max: float = np.inf
    vary: bool = True
    description: str = ""
    stderr: float | None = None
    scope: str | None = None

    @property
    def display_value(self) -> float:
        """The value in :attr:`unit`."""
        return float(from_si(self.value, self.unit))

    @property
    def display_stderr(self) -> float | None:
        if self.stderr is None:
            return None
        return float(abs(from_si(self.stderr, self.unit) - from_si(0.0, self.unit)))

    @property
    def display_bounds(self) -> tuple[float, float]:
        """(min, max) in :attr:`unit`."""
        return float(from_si(self.min, self.unit)), float(from_si(self.max, self.unit))

    @property
    def at_bound(self) -> bool:
        """True when the value sits on a bound, within a millionth of the allowed range (a fit
        pushed it there, and its curvature then says nothing about the uncertainty)."""
        span = self.max - self.min
        slack = 1e-6 * span if np.isfinite(span) else 1e-12 * max(abs(self.value), 1.0)
        return self.value <= self.min + slack or self.value >= self.max - slack

    def set_display(self, value: float) -> None:
        """Set the value from :attr:`unit`."""
        self.value = float(to_si(value, self.unit))

    def to_record(self) -> dict:
        """The parameter as files and JSON hold it: value, unit, bounds (display units), vary,
        and the standard error if a fit gave one."""
        low, high = self.display_bounds
        record = {"value": self.display_value, "unit": self.unit, "min": low, "max": high,
                  "vary": self.vary}
        if self.display_stderr is not None:
            record["stderr"] = self.display_stderr
        return record

    def update_from_record(self, record, where: str) -> None:
        """Set value, bounds and vary from a record (display units), strictly.

        Raises
        ------
        InputError
            Naming ``where``: unknown keys, another unit, values that are not finite numbers, a
            ``vary`` that is not a boolean, min >= max, bounds wider than the parameter's own
            (they are physics: friction >= 0), or a value outside them.
        """
        if not isinstance(record, Mapping) or "value" not in record:
            raise InputError(f"{where}: needs {{ value = ..., unit = ... }}, got {record!r}")
        unknown = sorted(set(record) - _RECORD_KEYS)
        if unknown:
            raise InputError(f"{where}: unknown key(s) {', '.join(map(repr, unknown))}; allowed: "
                             f"{', '.join(sorted(_RECORD_KEYS))}")
        unit = record.get("unit", self.unit)
        if unit != self.unit:
            raise InputError(f"{where}: is in {self.unit}, not {unit}")
        own_low, own_high = self.display_bounds
        value = _number(record["value"], "value", where)
        low = _number(record.get("min", own_low), "min", where, infinite=True)
        high = _number(record.get("max", own_high), "max", where, infinite=True)
        if "stderr" in record and _number(record["stderr"], "stderr", where) < 0:
            raise InputError(f"{where}: stderr must be >= 0, got {record['stderr']!r}")
        vary = record.get("vary", self.vary)
        if not isinstance(vary, bool):
            raise InputError(f"{where}: vary must be true or false, got {vary!r}")
        if not low < high:
            raise InputError(f"{where}: min = {low:g} must be below max = {high:g} (to hold the "
                             "parameter fixed, set vary = false and keep the bounds apart)")
        slack = 1e-9 * max(abs(own_low) if np.isfinite(own_low) else 0.0,
                           abs(own_high) if np.isfinite(own_high) else 0.0, 1.0)
        if low < own_low - slack or high > own_high + slack:
            raise InputError(f"{where}: bounds [{low:g}, {high:g}] {unit} reach beyond the "
                             f"parameter's own [{own_low:g}, {own_high:g}]; they may only narrow "
                             "them")
        if not low <= value <= high:
            raise InputError(f"{where}: value {value:g} lies outside [min, max] = [{low:g}, "
                             f"{high:g}] {unit}")
        self.min = max(float(to_si(low, unit)), self.min)  # no wider than its own by rounding
        self.max = min(float(to_si(high, unit)), self.max)
        self.value = min(max(float(to_si(value, unit)), self.min), self.max)
        self.vary = vary
        if "stderr" in record:
            self.stderr = float(abs(to_si(record["stderr"], unit) - to_si(0.0, unit)))

    def __str__(self) -> str:
        text = f"{self.name} = {self.display_value:.5g}"
        if self.stderr is not None:
            text += f" ± {self.display_stderr:.2g}"
        if self.unit != "1":
            text = f"{text} {label(self.unit)}"
        return text + " (at bound)" if self.at_bound else text


def _number(value, what: str, where: str, *, infinite: bool = False) -> float:
    """A number from a file (not a boolean, not text), finite unless ``infinite``."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InputError(f"{where}: {what} must be a number, got {value!r}")
    value = float(value)
    if value != value or (not infinite and abs(value) == float("inf")):
        raise InputError(f"{where}: {what} must be a finite number, got {value!r}")
    return value


class Parameters(Mapping[str, Parameter]):
    """The parameters of a model, keyed ``"effect.parameter"``, like ``lmfit.Parameters``.

    The entries are the model's own :class:`Parameter` objects: setting a value here sets it in
    the model.
    """

    def __init__(self, items: Iterable[tuple[str, Parameter]] = ()):
        self._items: dict[str, Parameter] = {}
        for key, parameter in items:
            if key in self._items:
                raise InputError(f"parameter {key!r} appears twice")
            self._items[key] = parameter

    def __getitem__(self, key: str) -> Parameter:
        try:
            return self._items[key]
        except KeyError:
            raise KeyError(f"no parameter {key!r}; there are {', '.join(self._items) or 'none'}"
                           ) from None

    def __iter__(self) -> Iterator[str]:
        return iter(self._items)

    def __len__(self) -> int:
        return len(self._items)

    def __repr__(self) -> str:
        return f"Parameters({', '.join(f'{k}={p.display_value:.5g}' for k, p in self.items())})"

    def free(self) -> list[str]:
        """Keys of the parameters a fit varies."""
        return [key for key, parameter in self._items.items() if parameter.vary]

    def valuesdict(self) -> dict[str, float]:
        """Key -> SI value, as the physics reads them (lmfit's ``valuesdict``)."""
        return {key: parameter.value for key, parameter in self._items.items()}

    def to_records(self, free_only: bool = False) -> dict[str, dict]:
        """Key -> record (display units): the one form written to files and JSON."""
        return {key: parameter.to_record() for key, parameter in self._items.items()
                if parameter.vary or not free_only}

    def pretty(self) -> str:
        """A table in display units, one line a parameter (lmfit's ``pretty_print``)."""
        return "\n".join(f"{key:<36} {parameter}" for key, parameter in self._items.items())
