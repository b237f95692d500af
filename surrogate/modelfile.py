"""Models by name or file: a preset, or a model file, built into a :class:`ValveModel`.

The file format and its rules are those of :class:`~surrogate.spec.ModelSpec`; the presets are
in :mod:`surrogate.presets`. Loading never runs code: the effects a file names come from the
library it is given (the built-in one plus any ``--effects-file``).
"""

from __future__ import annotations

from pathlib import Path

from .effects import KNOWN, EffectLibrary
from .errors import InputError
from .model import ValveModel
from .presets import PRESETS, preset
from .spec import ModelSpec, ValveSource

__all__ = ["PRESETS", "load_model", "load_spec", "save_model"]


def load_spec(name_or_path: str, valve_path: str | None = None) -> ModelSpec:
    """The spec of a preset (by name) or of a model file (by path).

    ``valve_path`` replaces the model's valve (for presets, the shipped one otherwise).
    """
    valve = ValveSource.read(valve_path) if valve_path else None
    if name_or_path in PRESETS:
        return preset(name_or_path, valve)
    path = Path(name_or_path)
    if not path.is_file():
        raise InputError(f"unknown model {name_or_path!r}: give a preset ({', '.join(PRESETS)}) "
                         "or the path of a model file")
    spec = ModelSpec.read(path)
    return spec.with_valve(valve) if valve else spec


def load_model(name_or_path: str, valve_path: str | None = None,
               library: EffectLibrary = KNOWN) -> ValveModel:
    """A preset by name, or a model file by path, built with the effects of ``library``."""
    spec = load_spec(name_or_path, valve_path)
    where = name_or_path if name_or_path not in PRESETS else f"preset {name_or_path!r}"
    return spec.build(library, where)


def save_model(model: ValveModel, path: str | Path, note: str = "") -> None:
    """Write ``model`` as a model file (see :class:`~surrogate.spec.ModelSpec`); ``stderr``
    entries are informative."""
    ModelSpec.of(model).write(path, note)
