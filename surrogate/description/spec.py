"""Model specifications: a valve model described as plain data, read from and written to TOML.

A :class:`ModelSpec` holds everything needed to build a :class:`~surrogate.model.ValveModel`, and
to rebuild it on another machine: the valve (its parameters, and the file they came from), where
the flow and force maps come from (kind and options, with the CFD file's SHA-256), and the effects
with their parameters in display units. It is the only way the package builds a model: the
presets, the paper's models, the workflow's steps, the simulator's reference valve and a user's
file are all specs. A spec round-trips through TOML exactly: ``ModelSpec.from_toml(s.to_toml())
== s``.

A model file (format 2)::

    [model]
    name = "cfda"
    format = 2

    [valve]                          # the valve's parameters, as in a valve file
    source = "shipped"               # the file they came from (a hint: the values are here)
    name = "3-port restrictive CBV (paper)"
    A_L_mm2 = 10.7
    ...
    oil = { name = "ISO VG46 HV", nu40_cSt = 46.0, ... }

    [maps]                           # both maps from one source, or flow = {...}, force = {...}
    kind = "grid"
    cfd = "shipped"                  # the CFD samples: "shipped" or a path (relative to this file)
    cfd_sha256 = "3f0c..."           # which samples: building on others is refused

    [[effects]]
    name = "friction_constant"
    title = "constant Coulomb friction"
    [effects.parameters]
    K1 = { value = 6.5, unit = "N", min = 0.0, max = 200.0, vary = true }

Files of the first format (``[model]`` holding ``valve = "shipped"`` and ``maps = {...}``) still
load. Reading never runs code: a custom effect named in a file must be supplied again in the
library (``--effects-file``); its ``source`` is recorded as a hint.
"""

from __future__ import annotations

import os
import tomllib
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path

from ..effects import KNOWN, Effect, EffectLibrary
from ..core.errors import InputError
from ..core.input_files import read_input_text
from ..maps.registry import SHIPPED, MapChoice, MapsSpec, MapSource, build_maps, map_kind
from ..model import ValveModel
from ..core.outputs import atomic_file
from ..core.tomlio import dumps, loads
from ..valve import ValveParameters, load_valve, shipped_valve_path

FORMAT = 2
_TOP_KEYS = {"model", "valve", "maps", "effects"}
_MODEL_KEYS = {"name", "description", "format"}
_LEGACY_MODEL_KEYS = {"name", "description", "valve", "maps"}
_EFFECT_KEYS = {"name", "title", "source", "parameters"}
_RECORD_ORDER = ("value", "unit", "min", "max", "vary", "stderr")


@dataclass(frozen=True)
class ValveSource:
    """A valve's parameters and the file they came from (``"shipped"`` or an absolute path)."""

    reference: str
    parameters: ValveParameters

    @classmethod
    def shipped(cls) -> "ValveSource":
        return cls(SHIPPED, load_valve())

    @classmethod
    def read(cls, path: str | Path | None) -> "ValveSource":
        """The valve of a valve file (None: the shipped valve)."""
        if path is None or path == SHIPPED:
            return cls.shipped()
        return cls(str(Path(path).resolve()), load_valve(path))

    def to_dict(self, folder: Path | None = None) -> dict:
        document = self.parameters.to_dict()
        return {"source": _relative(self.reference, folder), **document["valve"],
                "oil": document["oil"]}

    @classmethod
    def from_dict(cls, table, where: str, base: Path) -> "ValveSource":
        """A ``[valve]`` table: the values, or just ``source`` to read them from a file."""
        if isinstance(table, str):  # format 1: valve = "shipped" or a path
            return cls._from_file(table, where, base)
        if not isinstance(table, Mapping):
            raise InputError(f"{where}: expected a [valve] table, got {table!r}")
        reference = table.get("source", SHIPPED)
        if not isinstance(reference, str):
            raise InputError(f"{where}: source must be a string (\"shipped\" or a path), got "
                             f"{reference!r}")
        values = {key: value for key, value in table.items() if key not in ("source", "oil")}
        if not values and "oil" not in table:
            return cls._from_file(reference, where, base)
        parameters = ValveParameters.from_dict({"valve": values, "oil": table.get("oil")},
                                               source=where)
        return cls(_absolute(reference, base), parameters)

    @classmethod
    def _from_file(cls, reference: str, where: str, base: Path) -> "ValveSource":
        """The valve of the file a model file names. Its errors quote nothing of it (keys,
        values, lines): the user named the model file, not this one, which could be any file
        on the machine; ``--valve FILE`` shows what is wrong in full."""
        path = reference if reference == SHIPPED else _absolute(reference, base)
        try:
            return cls.read(path)
        except InputError as error:
            if path == SHIPPED or "cannot read valve file" in str(error):
                raise InputError(f"{where} = {reference!r}: {error}") from None
            raise InputError(f"{where} = {reference!r}: {path} is not a valid valve file (its "
                             "content is not shown: the model file named it; give it with "
                             f"--valve {path} to see what is wrong)") from None


@dataclass(frozen=True)
class EffectSpec:
    """An effect by name, with its parameters' records (display units, see
    :meth:`surrogate.parameters.Parameter.to_record`)."""

    name: str
    parameters: tuple[tuple[str, tuple[tuple[str, object], ...]], ...] = ()
    title: str = ""
    source: str | None = None

    @classmethod
    def of(cls, effect: Effect) -> "EffectSpec":
        """The spec of a live effect: its parameters as they are now."""
        return cls(effect.name,
                   tuple((name, _frozen_record(parameter.to_record()))
                         for name, parameter in effect.params.items()),
                   effect.title, effect.source if effect.custom else None)

    @classmethod
    def start(cls, effect: type[Effect], **values: float) -> "EffectSpec":
        """An effect at its default parameters, or at ``values`` (display units)."""
        return cls.of(effect(**values))

    def build(self, library: EffectLibrary, where: str) -> Effect:
        """The effect, from ``library``, with the recorded parameters (checked strictly)."""
        try:
            cls = library.effect(self.name)
        except InputError as error:
            hint = f" (it came from {self.source})" if self.source else ""
            raise InputError(f"{where}: {error}{hint}") from None
        where = f"{where} ({cls.name})"
        try:
            effect = cls.for_parameters([name for name, _ in self.parameters])
        except InputError as error:
            raise InputError(f"{where}: {error}") from None
        for name, record in self.parameters:
            if name not in effect.params:
                raise InputError(f"{where}: unknown parameter {name!r}; it has "
                                 f"{', '.join(effect.params) or 'none'}")
            effect.params[name].update_from_record(dict(record), f"{where}, parameter {name!r}")
        effect.check_parameters(where)
        return effect

    def to_dict(self) -> dict:
        entry = {"name": self.name}
        if self.title:
            entry["title"] = self.title
        if self.source:
            entry["source"] = self.source
        entry["parameters"] = {name: dict(record) for name, record in self.parameters}
        return entry

    @classmethod
    def from_dict(cls, entry, where: str) -> "EffectSpec":
        if not isinstance(entry, Mapping) or not isinstance(entry.get("name"), str):
            raise InputError(f"{where}: needs a name = \"...\" (a table under [[effects]])")
        _unknown_keys(entry, _EFFECT_KEYS, where)
        for key in ("title", "source"):
            if key in entry and not isinstance(entry[key], str):
                raise InputError(f"{where}: {key} must be a string, got {entry[key]!r}")
        parameters = entry.get("parameters", {})
        if not isinstance(parameters, Mapping):
            raise InputError(f"{where}: parameters must be a table of name = {{ value = ..., "
                             f"unit = ... }}, got {parameters!r}")
        records = []
        for name, record in parameters.items():
            if not isinstance(record, Mapping):
                raise InputError(f"{where}, parameter {name!r}: needs {{ value = ..., unit = ... "
                                 f"}}, got {record!r}")
            records.append((name, _frozen_record(record)))
        return cls(entry["name"], tuple(records), entry.get("title", ""), entry.get("source"))


@dataclass(frozen=True)
class ModelSpec:
    """A valve model as plain data (see the module docstring).

    Attributes
    ----------
    name : str
        Display name.
    valve : ValveSource
        The valve's parameters and where they came from.
    maps : MapsSpec
        Where the flow and force maps come from.
    effects : tuple of EffectSpec
        The effects, in order, with their parameters.
    description : str
        What the model is, in a sentence.
    """

    name: str
    valve: ValveSource = field(default_factory=ValveSource.shipped)
    maps: MapsSpec = field(default_factory=lambda: MapsSpec.both("grid"))
    effects: tuple[EffectSpec, ...] = ()
    description: str = ""

    # --- building ---------------------------------------------------------------------------------

    @classmethod
    def of(cls, model: ValveModel, description: str = "") -> "ModelSpec":
        """The spec of ``model`` as it is now (its parameters' current values, bounds and
        standard errors), to save or rebuild it.

        Raises
        ------
        InputError
            For a model assembled from maps directly, which cannot say where they came from.
        """
        if model.origin is None:
            raise InputError(f"model {model.name!r} was assembled from maps directly and does "
                             "not record where they come from; build it from a ModelSpec to "
                             "save it")
        valve, maps = model.origin
        return cls(model.name, valve, maps, tuple(EffectSpec.of(e) for e in model.effects),
                   description)

    def build(self, library: EffectLibrary = KNOWN, where: str | None = None) -> ValveModel:
        """The :class:`~surrogate.model.ValveModel` this spec describes.

        Raises
        ------
        InputError
            Naming ``where`` (default: the model's name) and the effect, for an effect the
            library lacks, a parameter it does not have, or a record it cannot take.
        """
        where = where or f"model {self.name!r}"
        effects, seen = [], {}
        for index, spec in enumerate(self.effects, start=1):
            if spec.name in seen:
                raise InputError(f"{where}, effect {index}: {spec.name!r} is already effect "
                                 f"{seen[spec.name]}; list each effect once")
            seen[spec.name] = index
            effects.append(spec.build(library, f"{where}, effect {index}"))
        try:
            flow_map, force_map = build_maps(self.maps, self.valve.parameters)
        except InputError as error:
            raise InputError(f"{where} maps: {error}") from None
        return ValveModel(self.valve.parameters, flow_map, force_map, effects, self.name,
                          origin=(self.valve, self.maps))

    def named(self, name: str, description: str | None = None) -> "ModelSpec":
        return replace(self, name=name,
                       description=self.description if description is None else description)

    def with_effects(self, effects: Iterable[EffectSpec], name: str | None = None
                     ) -> "ModelSpec":
        return replace(self, effects=tuple(effects), name=name or self.name)

    def adding(self, *effects: EffectSpec, name: str | None = None) -> "ModelSpec":
        """This spec with more effects at the end."""
        return self.with_effects([*self.effects, *effects], name)

    def with_maps(self, maps: MapsSpec, name: str | None = None) -> "ModelSpec":
        return replace(self, maps=maps, name=name or self.name)

    def on_maps(self, choice: MapChoice, cfd: str | None = None) -> "ModelSpec":
        """This spec on the maps ``choice`` names (an option such as --maps), named for them."""
        return self.with_maps(choice.spec(cfd), f"{self.name} ({choice} maps)")

    def with_valve(self, valve: ValveSource) -> "ModelSpec":
        return replace(self, valve=valve)

    def inputs(self) -> list[tuple[Path, str]]:
        """Every file and folder this model reads (or names as its valve's source), each with
        what it is: the valve file, and what the maps read (:meth:`MapsSpec.inputs`: every
        ``path`` option of their kind, a trained surrogate's folder and the files its manifest
        names). A command refuses outputs over any of them."""
        valve = shipped_valve_path() if self.valve.reference == SHIPPED \
            else Path(self.valve.reference)
        return [(valve, "the model's valve file"), *self.maps.inputs()]

    # --- files ------------------------------------------------------------------------------------

    def to_document(self, folder: Path | None = None) -> dict:
        """The model file's content; paths relative to ``folder`` where they can be."""
        model = {"name": self.name, "format": FORMAT}
        if self.description:
            model["description"] = self.description
        return {"model": model, "valve": self.valve.to_dict(folder),
                "maps": _maps_to_dict(self.maps, folder),
                "effects": [effect.to_dict() for effect in self.effects]}

    def to_toml(self, header: str = "", folder: Path | None = None) -> str:
        return dumps(self.to_document(folder), header)

    def write(self, path: str | Path, note: str = "") -> None:
        """Write the model file, all at once (paths in it relative to its folder)."""
        path = Path(path)
        header = "Valve model written by cbv-surrogate" + (f"\n{note}" if note else "")
        text = self.to_toml(header, path.resolve().parent)
        with atomic_file(path) as stream:
            stream.write(text)

    @classmethod
    def from_document(cls, document, where: str, base: Path = Path(".")) -> "ModelSpec":
        """Read a parsed model file strictly (unknown keys, wrong types, duplicate effects,
        bad map options and bad valve values are errors naming ``where``); relative paths
        resolve against ``base``."""
        base = Path(base).resolve()
        if not isinstance(document, Mapping):
            raise InputError(f"{where}: not a model file")
        _unknown_keys(document, _TOP_KEYS, where)
        table = document.get("model")
        if not isinstance(table, Mapping):
            raise InputError(f"{where}: needs a [model] table with maps = {{ kind = ... }}")
        legacy = "maps" in table or "valve" in table
        if legacy:
            _unknown_keys(table, _LEGACY_MODEL_KEYS, f"{where} [model]")
            extra = sorted({"valve", "maps"} & set(document))
            if extra:
                raise InputError(f"{where}: {', '.join(extra)} given twice, in [model] and as "
                                 "a table of its own")
            maps_table, valve_table = table.get("maps"), table.get("valve", SHIPPED)
        else:
            _unknown_keys(table, _MODEL_KEYS, f"{where} [model]")
            if table.get("format", FORMAT) != FORMAT:
                raise InputError(f"{where} [model]: format {table.get('format')!r} is not one "
                                 f"this version reads ({FORMAT})")
            maps_table, valve_table = document.get("maps"), document.get("valve", SHIPPED)
        if maps_table is None:
            raise InputError(f"{where}: needs maps = {{ kind = ... }} ([maps] table)")
        for key in ("name", "description"):
            if key in table and not isinstance(table[key], str):
                raise InputError(f"{where} [model]: {key} must be a string, got {table[key]!r}")
        maps = MapsSpec.from_dict(maps_table, f"{where} maps", base)
        valve = ValveSource.from_dict(valve_table, f"{where} [model] valve" if legacy
                                      else f"{where} [valve]", base)
        entries = document.get("effects", [])
        if not isinstance(entries, list):
            raise InputError(f"{where}: effects must be an array of tables ([[effects]]), got "
                             f"{entries!r}")
        effects = tuple(EffectSpec.from_dict(entry, f"{where}, effect {index}")
                        for index, entry in enumerate(entries, start=1))
        seen: dict[str, int] = {}
        for index, effect in enumerate(effects, start=1):
            if effect.name in seen:
                raise InputError(f"{where}, effect {index}: {effect.name!r} is already effect "
                                 f"{seen[effect.name]}; list each effect once")
            seen[effect.name] = index
        return cls(table.get("name", Path(where).stem), valve, _absolute_maps(maps, base),
                   effects, table.get("description", ""))

    @classmethod
    def from_toml(cls, text: str, where: str = "model file", base: Path = Path(".")
                  ) -> "ModelSpec":
        try:
            document = loads(text, where)
        except tomllib.TOMLDecodeError as error:
            raise InputError(f"{where}: not a valid TOML model file ({error})") from None
        return cls.from_document(document, where, base)

    @classmethod
    def read(cls, path: str | Path) -> "ModelSpec":
        """A model file."""
        path = Path(path)
        text = read_input_text(path, "a TOML model file")
        return cls.from_toml(text, str(path), path.resolve().parent)


# --- helpers ---------------------------------------------------------------------------------------

def _unknown_keys(table: Mapping, allowed: set[str], where: str) -> None:
    unknown = sorted(set(table) - allowed)
    if unknown:
        raise InputError(f"{where}: unknown key(s) {', '.join(map(repr, unknown))}; allowed: "
                         f"{', '.join(sorted(allowed))}")


def _frozen_record(record: Mapping) -> tuple[tuple[str, object], ...]:
    """A parameter record in a fixed key order, hashable (unknown keys kept, at the end, so that
    building reports them)."""
    known = [(key, record[key]) for key in _RECORD_ORDER if key in record]
    return tuple(known + [(key, value) for key, value in record.items()
                          if key not in _RECORD_ORDER])


def _absolute(reference: str, base: Path) -> str:
    if reference == SHIPPED:
        return SHIPPED
    path = Path(reference).expanduser()
    return str(path if path.is_absolute() else (base / path).resolve())


def _relative(reference: str, folder: Path | None) -> str:
    """A path as a file in ``folder`` should write it: relative where it can be."""
    if reference == SHIPPED or folder is None or not os.path.isabs(reference):
        return reference
    try:
        return os.path.relpath(reference, folder)
    except ValueError:  # another drive
        return reference


def _path_options(kind: str) -> set[str]:
    return {option.name for option in map_kind(kind).options if option.path}


def _absolute_maps(maps: MapsSpec, base: Path) -> MapsSpec:
    def absolute(source: MapSource) -> MapSource:
        paths = _path_options(source.kind)
        return MapSource.of(source.kind, **{key: _absolute(value, base) if key in paths else value
                                           for key, value in source.options})
    return MapsSpec(absolute(maps.flow), absolute(maps.force))


def _maps_to_dict(maps: MapsSpec, folder: Path | None) -> dict:
    def relative(source: MapSource) -> MapSource:
        paths = _path_options(source.kind)
        return MapSource.of(source.kind, **{key: _relative(value, folder) if key in paths
                                           else value for key, value in source.options})
    return MapsSpec(relative(maps.flow), relative(maps.force)).to_dict()
