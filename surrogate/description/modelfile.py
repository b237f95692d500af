"""Models by name or file: a preset, or a model file, built into a :class:`ValveModel`.

The file format and its rules are those of :class:`~.spec.ModelSpec`; the presets are in
:mod:`.presets`. Loading never runs code: the effects a file names come from the library it is
given (the built-in one plus any ``--effects-file``).
"""

from __future__ import annotations

from pathlib import Path

from ..effects import KNOWN, EffectLibrary
from ..core.errors import InputError, did_you_mean
from ..model import ValveModel
from .presets import PRESETS, preset, preset_named
from .spec import ModelSpec, ValveSource

__all__ = ["PRESETS", "load_model", "load_spec", "model_name", "save_model"]


def model_name(text: str) -> str:
    """``text`` as a model is named: the preset it names in any case (``"CFDA"`` is cfda), or
    the text itself, a model file's path. A file of that name wins over a preset in another
    case, as an exact preset name wins over a file."""
    if text in PRESETS or Path(text).is_file():
        return text
    return preset_named(text) or text


def load_spec(name_or_path: str, valve_path: str | None = None) -> ModelSpec:
    """The spec of a preset (by name) or of a model file (by path).

    ``valve_path`` replaces the model's valve (for presets, the shipped one otherwise).
    """
    valve = ValveSource.read(valve_path) if valve_path else None
    name = model_name(name_or_path)
    if name in PRESETS:
        return preset(name, valve)
    path = Path(name_or_path)
    # any entry of that name is read as a model file, so that a folder, a FIFO or a broken link
    # is refused for what it is; only a name that is nothing at all is an unknown model
    if not (path.exists() or path.is_symlink()):
        raise InputError(f"unknown model {name_or_path!r}"
                         f"{did_you_mean(name_or_path, PRESETS)}: give a preset "
                         f"({', '.join(PRESETS)}) or the path of a model file")
    spec = ModelSpec.read(path)
    return spec.with_valve(valve) if valve else spec


def load_model(name_or_path: str, valve_path: str | None = None,
               library: EffectLibrary = KNOWN) -> ValveModel:
    """A preset by name, or a model file by path, built with the effects of ``library``."""
    spec = load_spec(name_or_path, valve_path)
    name = model_name(name_or_path)
    where = name if name not in PRESETS else f"preset {name!r}"
    return spec.build(library, where)


def save_model(model: ValveModel, path: str | Path, note: str = "") -> None:
    """Write ``model`` as a model file (see :class:`~.spec.ModelSpec`); ``stderr`` entries are
    informative."""
    ModelSpec.of(model).write(path, note)
