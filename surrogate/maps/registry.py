"""Map kinds by name: how each kind of flow and force map is built, trained, saved and loaded.

A *map kind* is one :class:`MapKind` registered here: its options (with their checks), how to
build its flow and force maps for a valve, and, for the learned kinds, how to train, save and load
them. Nothing else in the package branches on kind names; a new kind is one module with its maps
plus one :func:`register` call (see docs/extending.md), as each built-in kind is:
:mod:`.orifice`, :mod:`.grid`, :mod:`.nn` and :mod:`.gp` (the learned kinds' shared parts in
:mod:`.learned`), which the package imports in that order (``surrogate/maps/__init__.py``), so
that every kind is registered whichever module is imported first.

Where a model's maps come from is a :class:`MapSource` (a kind and its options); a model's two
maps may come from different sources (:class:`MapsSpec`), as in the paper's ablations that pair
the CFD force map with the orifice equation.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..core.errors import InputError, did_you_mean, named
from ..limits import FLOW, FORCE
from ..core.paths import shipped
from ..core.units import from_si, to_si
from ..valve import ValveParameters
from .base import FlowMap, ForceMap
from .package import MANIFEST, package_files, read_manifest

SHIPPED = "shipped"  # an option value that names the file or folder the package ships


# --- options ---------------------------------------------------------------------------------------

def number_in(low: float, high: float, what: str):
    """An option's check: a number in (low, high]; ``what`` says why, in the message."""
    def parse(value, where: str) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise InputError(f"{where}: must be a number, got {value!r}")
        if not low < value <= high:
            raise InputError(f"{where}: must lie in ({low:g}, {high:g}], got {value:g} ({what})")
        return float(value)
    return parse


def _text(value, where: str) -> str:
    if not isinstance(value, str) or not value:
        raise InputError(f"{where}: must be a non-empty string, got {value!r}")
    return value


def sha256_hex(value, where: str) -> str:
    """An option's check: a SHA-256 in hex, as files record which data maps were built from."""
    text = _text(value, where)
    if len(text) != 64 or any(c not in "0123456789abcdef" for c in text):
        raise InputError(f"{where}: must be a SHA-256 in hex (64 characters), got {value!r}")
    return text


@dataclass(frozen=True)
class Option:
    """One option of a map kind, as a model file writes it.

    ``parse(value, where)`` checks a value read from a file and returns it (or raises InputError
    naming ``where``); ``default`` is used when the option is absent (None: no default). A
    ``path`` option names a file or folder (``"shipped"`` for the package's own, ``shipped``):
    files write it relative to themselves, so a model and its data move together, and a command
    counts it among the inputs no output may replace (:meth:`MapSource.inputs`).
    """

    name: str
    description: str
    parse: Callable[[object, str], object] = _text
    default: object = None
    path: bool = False
    shipped: Path | None = None  # what "shipped" names, for a path option


# --- kinds -----------------------------------------------------------------------------------------

@dataclass(frozen=True)
class MapKind:
    """A kind of map, by name.

    Attributes
    ----------
    name : str
        The name files and the command line use (``--maps``).
    description : str
        What the maps are, in a line.
    build : callable
        ``build(options, valve, base)`` -> (flow map, force map); ``options`` checked by
        :meth:`parse_options`, relative paths resolved against the folder ``base``.
    options : tuple of Option
        The options the kind takes; any other is an error.
    trainer : str or None
        ``"module:function"`` that trains the kind's predictors (learned kinds), imported only to
        train: training may need PyTorch, evaluation never does.
    save_predictor, load_predictor : callable or None
        Write a trained predictor into a surrogate folder (returning its manifest entry) and read
        it back, ``load_predictor(folder, entry, feature_count)`` (learned kinds).
    constraints : mapping
        What the learned flow and force maps guarantee by construction, for the manifest.
    data : callable or None
        ``data(cfd)`` -> the options that record which data the maps come from: the CFD samples
        they are built from (a path, or ``None`` for the shipped ones), or the trained surrogate
        and its hash; None for kinds that need no data.
    accuracy : callable or None
        ``accuracy(options, valve, base)`` -> the maps' cross-validation summary per scheme
        (:func:`.crossval.summary`); None for kinds without data.
    calibration_powers : mapping
        {distance name: power} that a learned kind's calibration is given rather than fits
        (:meth:`.sigma.SigmaCalibration.fit`, ``powers``), for its flow and its force map alike;
        none by default.
    """

    name: str
    description: str
    build: Callable[[Mapping, ValveParameters, Path], tuple[FlowMap, ForceMap]]
    options: tuple[Option, ...] = ()
    trainer: str | None = None
    save_predictor: Callable | None = None
    load_predictor: Callable | None = None
    constraints: Mapping[str, str] = field(default_factory=dict)
    data: Callable[..., dict] | None = None
    accuracy: Callable[..., dict] | None = None
    calibration_powers: Mapping[str, float] = field(default_factory=dict)

    @property
    def learned(self) -> bool:
        return self.trainer is not None

    def source(self, cfd: str | Path | None = None, **options) -> "MapSource":
        """A source of this kind: ``options`` plus, for a kind built from CFD samples, the file
        (default: the shipped one) and its SHA-256."""
        if self.data is not None:
            options = {**options, **self.data(cfd, **options)}
        elif cfd is not None:
            raise InputError(f"map kind {self.name!r} is not built from CFD samples; --cfd "
                             "applies to grid maps")
        options = self.parse_options(options, f"maps {self.name}")
        paths = {option.name for option in self.options if option.path}
        return MapSource.of(self.name, **{  # absolute, so a file anywhere can point at them
            key: str(Path(value).resolve()) if key in paths and value != SHIPPED else value
            for key, value in options.items()})

    def parse_options(self, raw: Mapping, where: str) -> dict:
        """The options of a file's map table, checked; unknown ones are an error."""
        known = {option.name: option for option in self.options}
        unknown = sorted(set(raw) - set(known))
        if unknown:
            allowed = ", ".join(known) or "none"
            raise InputError(f"{where}: unknown option(s) {', '.join(map(repr, unknown))} for "
                             f"map kind {self.name!r} (it takes: {allowed})")
        return {name: known[name].parse(value, f"{where} {name}") for name, value in raw.items()}

    def trainer_function(self) -> Callable:
        """The training function (imports it: the only place PyTorch may come in)."""
        if self.trainer is None:
            raise InputError(f"map kind {self.name!r} is not trained; it is built from "
                             f"{', '.join(o.name for o in self.options) or 'nothing'}")
        module, _, function = self.trainer.partition(":")
        return getattr(importlib.import_module(module), function)


MAP_KINDS: dict[str, MapKind] = {}


def register(kind: MapKind) -> MapKind:
    """Add a map kind to :data:`MAP_KINDS` under its name."""
    if kind.name in MAP_KINDS:
        raise InputError(f"a map kind named {kind.name!r} exists already")
    MAP_KINDS[kind.name] = kind
    return kind


def learned_kinds() -> list[str]:
    """The names of the registered kinds that are trained (:attr:`MapKind.learned`)."""
    return [name for name, kind in MAP_KINDS.items() if kind.learned]


def kind_named(text: str) -> str | None:
    """The registered kind ``text`` names, in any case (``"GP"`` is gp), or None."""
    return named(text, MAP_KINDS)


def map_kind(name: str) -> MapKind:
    """The registered kind called ``name``, in any case."""
    kind = kind_named(name)
    if kind is None:
        raise InputError(f"unknown map kind {name!r}{did_you_mean(name, MAP_KINDS)}: choose one "
                         f"of {', '.join(MAP_KINDS)}, or give the folder of a trained surrogate")
    return MAP_KINDS[kind]


@dataclass(frozen=True)
class MapSource:
    """Where maps come from: a kind and its (checked) options, as a file records them."""

    kind: str
    options: tuple[tuple[str, object], ...] = ()

    @classmethod
    def of(cls, kind: str, **options) -> "MapSource":
        return cls(kind, tuple(sorted(options.items())))

    @property
    def settings(self) -> dict:
        return dict(self.options)

    def to_dict(self) -> dict:
        return {"kind": self.kind, **self.settings}

    def inputs(self, base: Path = Path(".")) -> list[tuple[Path, str]]:
        """The files and folders these maps read, each with what it is: the value of every
        ``path`` option (the shipped file or folder for ``"shipped"``) and, for the folder of a
        trained surrogate, the files its manifest names."""
        found = []
        for option in map_kind(self.kind).options:
            value = self.settings.get(option.name, option.default)
            if not option.path or not isinstance(value, str):
                continue
            path = option.shipped if value == SHIPPED else resolve_path(value, base)
            if path is None:
                continue
            role = f"the {self.kind} maps' {option.name}"
            found.append((path, role))
            if (path / MANIFEST).is_file():
                found += [(file, f"a file of {role}") for file in package_files(path)[1:]]
        return found

    @classmethod
    def from_dict(cls, table, where: str, base: Path = Path(".")) -> "MapSource":
        """Read ``{kind = ..., options...}`` (or a kind name, or the folder of a trained
        surrogate, as older files wrote it), checking the options against the kind."""
        if isinstance(table, str):
            refuse_ambiguous_kind(table, base, where, command_line=False)
            table = {"kind": table}
        if not isinstance(table, Mapping):
            raise InputError(f"{where}: expected a map kind ({', '.join(MAP_KINDS)}) or a table "
                             f"{{ kind = ... }}, got {table!r}")
        kind = table.get("kind")
        if not isinstance(kind, str):
            raise InputError(f"{where}: needs a kind ({', '.join(MAP_KINDS)}, or the folder of a "
                             "trained surrogate)")
        options = {key: value for key, value in table.items() if key != "kind"}
        if kind not in MAP_KINDS and not options and is_surrogate_folder(kind, base):
            folder = kind  # a surrogate folder as the kind: the learned kind it holds
            kind = read_manifest(resolve_path(folder, base), learned_kinds())["kind"]
            options = {"folder": folder}
        kind = map_kind(kind).name  # "GP" is recorded as gp
        return cls.of(kind, **map_kind(kind).parse_options(options, where))


def is_surrogate_folder(text: str, base: Path) -> bool:
    """Whether ``text`` (relative to ``base``) is the folder of a trained surrogate."""
    return (resolve_path(text, base) / MANIFEST).is_file()


def refuse_ambiguous_kind(text: str, base: Path, where: str, *, command_line: bool = True
                          ) -> None:
    """Refuse a kind name that is also a folder in ``base`` holding a trained surrogate.

    ``--maps nn`` beside the ``nn`` folder that ``training/train.py --out .`` writes could mean
    either; taking the kind silently ignored the user's surrogate, taking the folder would change
    what ``--maps nn`` means wherever such a folder lies. So neither: the message says how to
    name each. A folder named like a kind without ``surrogate.json`` is no surrogate, and the
    kind is meant.
    """
    if kind_named(text) is None or not is_surrogate_folder(text, base):
        return
    kind = MAP_KINDS[kind_named(text)]
    # the committed surrogate of a learned kind: what "shipped" names for its folder option
    shipped_one = (next((option.shipped for option in kind.options if option.path), None)
                   if kind.learned else None)
    if command_line:
        folder, other = f"{where} ./{text}", (f"{where} {shipped_one} for the shipped one"
                                              if shipped_one else "rename the folder to use "
                                              f"{text} maps")
    else:
        folder = f'{{ kind = "{text}", folder = "./{text}" }}'
        other = (f'{{ kind = "{text}" }} for the shipped one' if shipped_one
                 else "rename the folder to use the kind")
    what = f"the shipped surrogate, {shipped_one}" if shipped_one else kind.description
    raise InputError(f"{where} {text}: ambiguous: {text!r} is the map kind ({what}) and "
                     f"{resolve_path(text, base)} is a trained surrogate folder here; write "
                     f"{folder} for the folder, or {other}")


@dataclass(frozen=True)
class MapsSpec:
    """The sources of a model's flow map and force map (usually one source for both)."""

    flow: MapSource
    force: MapSource

    @classmethod
    def both(cls, kind: str, **options) -> "MapsSpec":
        source = MapSource.of(kind, **options)
        return cls(source, source)

    @classmethod
    def of_kind(cls, kind: str, cfd: str | Path | None = None, **options) -> "MapsSpec":
        """Both maps of ``kind``, with its ``options``, their sources checked and completed by
        the kind (:meth:`MapKind.source`: a kind built from CFD samples records the file,
        default the shipped one, and its SHA-256)."""
        source = map_kind(kind).source(cfd, **options)
        return cls(source, source)

    def inputs(self, base: Path = Path(".")) -> list[tuple[Path, str]]:
        """The files and folders the two maps read (:meth:`MapSource.inputs`)."""
        return self.flow.inputs(base) + (self.force.inputs(base) if self.force != self.flow
                                         else [])

    def to_dict(self) -> dict:
        if self.flow == self.force:
            return self.flow.to_dict()
        return {"flow": self.flow.to_dict(), "force": self.force.to_dict()}

    @classmethod
    def from_dict(cls, table, where: str, base: Path = Path(".")) -> "MapsSpec":
        """``{kind = ...}`` for both maps, or ``{flow = {...}, force = {...}}``."""
        if isinstance(table, Mapping) and "kind" not in table and {"flow", "force"} & set(table):
            unknown = sorted(set(table) - {"flow", "force"})
            if unknown or set(table) != {"flow", "force"}:
                raise InputError(f"{where}: give kind = ... for both maps, or both flow = {{...}} "
                                 f"and force = {{...}}; got keys {', '.join(sorted(table))}")
            return cls(MapSource.from_dict(table["flow"], f"{where} flow", base),
                       MapSource.from_dict(table["force"], f"{where} force", base))
        source = MapSource.from_dict(table, where, base)
        return cls(source, source)


@dataclass(frozen=True)
class MapChoice:
    """The maps a command line names (``--maps``), read once: a registered kind, in any case
    (``GP`` is gp), or the folder of a trained surrogate, as the user wrote it. A value that is
    both a kind and such a folder in ``base`` stays as written, and :meth:`spec` refuses it as
    ambiguous (:func:`refuse_ambiguous_kind`): either reading would surprise someone, and
    ``./nn`` or the shipped folder's path says which is meant."""

    text: str  # the kind's name, or the folder as given
    option: str = "--maps"
    base: Path = Path(".")  # what a relative folder is read against

    @classmethod
    def read(cls, text: str, option: str = "--maps", base: Path | None = None) -> "MapChoice":
        base = Path.cwd() if base is None else base
        kind = kind_named(text)
        return cls(kind if kind is not None and not is_surrogate_folder(text, base) else text,
                   option, base)

    def __str__(self) -> str:
        return self.text

    def spec(self, cfd: str | None = None) -> MapsSpec:
        """Both maps of the kind or folder named (maps built from CFD samples read ``cfd``,
        default the shipped ones), the folder and its hash recorded."""
        refuse_ambiguous_kind(self.text, self.base, self.option)
        if kind_named(self.text) is not None:
            return MapsSpec.of_kind(self.text, cfd)
        # the folder of a trained surrogate: the learned kind it holds
        folder = MapSource.from_dict(self.text, self.option, self.base)
        return MapsSpec.of_kind(folder.kind, cfd, folder=folder.settings["folder"])


def build_maps(source: MapSource | MapsSpec | str, valve: ValveParameters,
               base: str | Path = ".") -> tuple[FlowMap, ForceMap]:
    """The flow and force map of a source (a kind name, a :class:`MapSource` or a
    :class:`MapsSpec`) for ``valve``; relative paths in the options resolve against ``base``.

    Maps are cached by source, valve and file contents, so the models of a workflow or of the
    paper's comparison share one grid and one loaded surrogate.
    """
    if isinstance(source, MapsSpec):
        flow = build_maps(source.flow, valve, base)[0]
        return flow, build_maps(source.force, valve, base)[1]
    if isinstance(source, str):
        source = MapSource.from_dict(source, "maps", Path(base))
    kind = map_kind(source.kind)
    base = Path(base)
    key = (source, valve, str(base.resolve()), _fingerprint(source, base))
    if key not in _CACHE:
        if len(_CACHE) >= _CACHE_SIZE:
            _CACHE.pop(next(iter(_CACHE)))
        with np.errstate(all="ignore"):  # damaged weights overflow: the check below says so
            maps = kind.build(source.settings, valve, base)
        check_plausible(*maps, valve, f"{source.kind} maps")
        _CACHE[key] = maps
    return _CACHE[key]


#: where :func:`check_plausible` asks the maps: openings [share of the stroke], load pressures
#: [bar], one back pressure [bar] and one temperature [°C], all inside any CBV's range
PROBE_OPENINGS = (0.1, 0.5, 0.9)
PROBE_LOADS_BAR = (30.0, 100.0, 250.0)
PROBE_BACK_BAR, PROBE_TEMPERATURE_C = 5.0, 40.0


def check_plausible(flow: FlowMap, force: ForceMap, valve: ValveParameters, what: str) -> None:
    """Refuse maps whose flow or force, asked at a few ordinary states of ``valve``, no valve
    has: not finite, no flow, a negative or astronomic one, a force beyond the plausible. Sealed weights
    can still be nonsense (scaled by 1e300 and sealed again); a fit or a replay on them would
    flow on with absurd numbers instead of stopping here, naming the maps."""
    u, p_L = np.meshgrid(np.asarray(PROBE_OPENINGS) * valve.U_max,
                         to_si(np.asarray(PROBE_LOADS_BAR), "bar"))
    u, p_L = u.ravel(), p_L.ravel()
    p_B = np.full_like(p_L, to_si(PROBE_BACK_BAR, "bar"))
    fluid = valve.oil.state(np.full_like(p_L, to_si(PROBE_TEMPERATURE_C, "degC")))
    with np.errstate(all="ignore"):
        q = from_si(np.asarray(flow.flow(p_L, p_B, u, fluid), float), "L/min")
        f = from_si(np.asarray(force.force(p_L, p_B, u, fluid), float), "N")
    where = (f"at openings of {', '.join(f'{share:g}' for share in PROBE_OPENINGS)} of the "
             f"stroke, p_L {', '.join(f'{p:g}' for p in PROBE_LOADS_BAR)} bar, p_B "
             f"{PROBE_BACK_BAR:g} bar, {PROBE_TEMPERATURE_C:g} °C")
    for name, values, limits in (("flow", q, FLOW), ("force", f, FORCE)):
        # an open valve under tens of bar passes some flow: none at all is as wrong as too much
        bad = [value for value in values if not limits.contains(float(value))
               or (name == "flow" and not value > 0.0)]
        if bad:
            raise InputError(f"{what}: the {name} map gives {float(bad[0]):.4g} "
                             f"{limits.unit} {where}; no valve has that (expected "
                             f"{limits.describe()}): its weights or samples are damaged or "
                             "scaled; retrain or restore them")


_CACHE: dict = {}
_CACHE_SIZE = 16


def _fingerprint(source: MapSource, base: Path) -> tuple:
    """Modification times and sizes of the files a source names (of every file in a folder it
    names: a surrogate's weights), so an edited file rebuilds, and is checked again."""
    stamps = []
    for _, value in source.options:
        if isinstance(value, str) and value != SHIPPED:
            path = resolve_path(value, base)
            for file in (sorted(path.iterdir()) if path.is_dir() else [path]):
                if file.exists():
                    stat = file.stat()
                    stamps.append((str(file), stat.st_mtime_ns, stat.st_size))
    return tuple(stamps)


def resolve_path(text: str, base: Path) -> Path:
    """The path an option's value names: absolute, or relative to ``base``."""
    path = Path(text).expanduser()
    return path if path.is_absolute() else base / path


def resolve_file(value: str, base: Path, shipped_path: Path) -> Path:
    """The path an option names: the shipped file for ``"shipped"``, else relative to ``base``."""
    if value == SHIPPED:
        return shipped(shipped_path)
    return resolve_path(value, base)


def cross_validation_summary(source: MapSource, valve: ValveParameters,
                             base: str | Path = ".") -> dict | None:
    """How accurate the maps of ``source`` are by cross-validation, per scheme
    (:func:`.crossval.summary`); None for kinds without data."""
    kind = map_kind(source.kind)
    return None if kind.accuracy is None else kind.accuracy(source.settings, valve, Path(base))
