"""A trained surrogate's folder as a sealed package: one manifest, the files it names, checked.

A surrogate folder holds ``surrogate.json`` (the manifest) and the weight files its predictor
entries name. Loading one trusts nothing it has not checked:

* the manifest is JSON of bounded depth, an object with the keys the loaders read, each of the
  type and in the physical range it must have (:func:`check_manifest`; the predictors' own
  entries and arrays are checked by their kinds, :mod:`.nn` and :mod:`.gp`);
* a file the manifest names lies inside the folder: a relative path without ``..``, that no
  symbolic link leads out of (:func:`member`);
* the manifest records the SHA-256 of every weight file (``"sha256"`` next to ``"file"`` in each
  predictor entry, written by :func:`seal` when a folder is trained), and a weight file whose
  bytes differ is refused (:func:`verify`). A model file records the manifest's own SHA-256
  (:mod:`.registry`), so a model names its weights down to the last bit.

Folders written before the hashes were recorded still load, with a one-line warning that their
weights are not sealed (:func:`verify`): their arrays are still checked for names, shapes and
finite values, which catches corrupt and truncated files; only an edit that keeps the arrays
plausible goes unseen, which is what retraining (``training/train.py``) then seals.
"""

from __future__ import annotations

import hashlib
import json
import math
import zipfile
from collections.abc import Iterable, Mapping
from pathlib import Path, PurePosixPath, PureWindowsPath

import numpy as np

from ..core.errors import InputError
from ..features import FEATURE_NAMES, FORCE_FEATURE_NAMES
from ..core.input_files import check_input, check_size, read_input, read_input_text
from ..core.tomlio import nesting_depth

MANIFEST = "surrogate.json"
FORMAT_VERSION = 2  # 2: network weights as .npz (1: PyTorch state_dicts, still read)
_READABLE = (1, 2)
#: the largest calibration scale or slope a manifest may give (ln units per unit of spread or
#: distance)
CALIBRATION_MAX = 1e3
#: how deeply a manifest may nest its objects and arrays; the format needs 5 (a domain's points)
MAX_DEPTH = 32


def file_hash(path: str | Path) -> str:
    """SHA-256 of a weight file's bytes (a regular file within the weights' bound)."""
    return hashlib.sha256(read_input(path, "a weight file", "weights")).hexdigest()


# --- the manifest --------------------------------------------------------------------------------

def write_manifest(folder: Path, manifest: dict) -> None:
    """Write ``manifest`` as the ``surrogate.json`` of ``folder``, in this version's format."""
    manifest = {"format_version": FORMAT_VERSION, **manifest}
    (folder / MANIFEST).write_text(json.dumps(manifest, indent=2) + "\n")


def read_manifest(folder: str | Path, kinds: list[str]) -> dict:
    """The ``surrogate.json`` of a surrogate folder, checked for its format, for naming one of
    ``kinds`` (the registry's learned kinds, :func:`.registry.learned_kinds`) and for every value
    the maps are built from (:func:`check_manifest`)."""
    path = Path(folder) / MANIFEST
    if not path.is_file():
        raise InputError(f"{folder}: not a surrogate folder (no {MANIFEST}); train one with "
                         "`python training/train.py`")
    manifest = parse_json(read_input_text(path, "a surrogate manifest (JSON)"), str(path))
    if not isinstance(manifest, dict):
        raise InputError(f"{path}: must be a JSON object {{...}}, got "
                         f"{json_type(manifest)}; not a surrogate manifest")
    if manifest.get("format_version") not in _READABLE or manifest.get("kind") not in kinds:
        raise InputError(f"{path}: unknown surrogate format (need format_version "
                         f"{FORMAT_VERSION} and a learned kind: {', '.join(kinds)})")
    return check_manifest(manifest, str(path))


def parse_json(text: str, where: str) -> object:
    """A JSON document whose nesting is at most :data:`MAX_DEPTH` deep."""
    try:
        document = json.loads(text)
    except RecursionError:
        raise InputError(f"{where}: nested too deep (more than {MAX_DEPTH} levels of objects "
                         "and arrays); not a surrogate manifest") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as error:
        raise InputError(f"{where}: not valid JSON ({error})") from None
    if nesting_depth(document) > MAX_DEPTH:
        raise InputError(f"{where}: nested too deep (more than {MAX_DEPTH} levels of objects "
                         "and arrays); not a surrogate manifest")
    return document


def table(data, key: str, where: str) -> dict:
    """``data[key]``, which must be an object."""
    value = require(data, key, where)
    if not isinstance(value, Mapping):
        raise InputError(f"{place(where, key)}: must be an object {{...}}, got {json_type(value)}")
    return value


def require(data, key: str, where: str):
    if not isinstance(data, Mapping):
        raise InputError(f"{where}: must be an object {{...}}, got {json_type(data)}")
    if key not in data:
        raise InputError(f"{where}: missing key {key!r}")
    return data[key]


def number(data, key: str, where: str, *, low: float = -math.inf, high: float = math.inf,
           above: bool = False, default=None) -> float:
    """``data[key]`` as a finite number in [low, high] (or (low, high] with ``above``)."""
    if default is not None and isinstance(data, Mapping) and key not in data:
        return default
    value = require(data, key, where)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise InputError(f"{place(where, key)}: must be a finite number, got {json_type(value)}")
    if not (low < value if above else low <= value) or not value <= high:
        raise InputError(f"{place(where, key)}: must lie in {'(' if above else '['}{low:g}, "
                         f"{high:g}]{_unit_hint(key)}")
    return float(value)


def numbers(data, key: str, where: str, shape: tuple | None = None, *, low: float = -math.inf,
            above: bool = False) -> np.ndarray:
    """``data[key]``, an array of finite numbers of ``shape`` (None: any; an entry None: any
    length there), each >= low (> low with ``above``)."""
    value = require(data, key, where)
    return check_array(value, place(where, key), shape, low=low, above=above)


def check_array(value, where: str, shape: tuple | None = None, *, low: float = -math.inf,
                above: bool = False, integer: bool = False) -> np.ndarray:
    """``value`` as an array of finite numbers of ``shape``; refused with ``where`` otherwise."""
    if isinstance(value, np.ndarray):
        if value.dtype.kind not in "iuf" or (integer and value.dtype.kind == "f"):
            raise InputError(f"{where}: must hold {'whole ' if integer else ''}numbers, holds "
                             f"{value.dtype}")
        array = value.astype(float)
    else:
        try:
            array = np.array(value, dtype=float)
        except (TypeError, ValueError):
            raise InputError(f"{where}: must be an array of numbers") from None
        if array.dtype != float or _has_bools(value):
            raise InputError(f"{where}: must be an array of numbers")
    if shape is not None:
        if array.ndim != len(shape) or any(n is not None and n != m
                                           for n, m in zip(shape, array.shape)):
            wanted = "(" + ", ".join("any" if n is None else str(n) for n in shape) + \
                     ("," if len(shape) == 1 else "") + ")"
            raise InputError(f"{where}: has shape {array.shape}, expected {wanted}")
    if not np.all(np.isfinite(array)):
        raise InputError(f"{where}: holds NaN or infinite values; every value must be finite")
    if integer and not np.all(array == np.round(array)):
        raise InputError(f"{where}: must hold whole numbers")
    if array.size and not np.all(array > low if above else array >= low):
        raise InputError(f"{where}: every value must be {'>' if above else '>='} {low:g}")
    return array


def text(data, key: str, where: str, choices: Iterable[str] | None = None) -> str:
    value = require(data, key, where)
    if not isinstance(value, str):
        raise InputError(f"{place(where, key)}: must be a string, got {json_type(value)}")
    choices = None if choices is None else list(choices)
    if choices is not None and value not in choices:
        raise InputError(f"{place(where, key)}: must be one of {', '.join(choices)}")
    return value


def place(where: str, key: str) -> str:
    """A key's place: ``where`` (a file and ``:``, or a place in it) then the key."""
    return f"{where} {key}" if where.endswith(":") else f"{where}.{key}"


def _has_bools(value) -> bool:
    if isinstance(value, bool):
        return True
    return isinstance(value, list) and any(_has_bools(item) for item in value)


def json_type(value) -> str:
    """The JSON type of a value (never the value: a manifest's text is not echoed)."""
    if value is None:
        return "null"
    if isinstance(value, float) and not math.isfinite(value):
        return "NaN or infinity"
    return {bool: "a boolean", int: "a number", float: "a number", str: "a string",
            list: "an array", dict: "an object"}.get(type(value), type(value).__name__)


def _unit_hint(key: str) -> str:
    return {"A_L": " (m², the load area)", "back_area": " (m²)", "length": " (m, the stroke)",
            "w": " (m)", "p_atm": " (Pa)", "p_sat": " (Pa, absolute)"}.get(key, "")


#: the feature scales of a manifest: [m], [m], [m²], [m²], [Pa], [Pa]; the ranges are far wider
#: than any valve's (a stroke of 1 µm to 100 mm) but exclude what would break the features: zero
#: or negative areas and lengths, a vacuum for the atmosphere
FEATURE_RANGES = {"length": (1e-6, 0.1), "w": (1e-5, 1.0), "A_L": (1e-10, 0.1),
                  "back_area": (1e-10, 0.1), "p_atm": (5e4, 2e5), "p_sat": (0.0, 1e7)}
_COVERAGE_PER_OPENING = ("dp_low", "dp_high", "q_low", "q_high")


def check_manifest(manifest: Mapping, path: str) -> dict:
    """Check what every learned kind reads from the manifest at ``path`` (an object of a known
    format and kind, :func:`read_manifest`): the feature scales, the coverage, and
    each map's domain, calibration and predictor entry (an object; its contents are the kind's
    to check). Returns the manifest."""
    where = f"{path}:"
    features = table(manifest, "features", where)
    unknown = sorted(set(features) - set(FEATURE_RANGES))
    if unknown:
        raise InputError(f"{where} features: unknown key(s) {', '.join(map(repr, unknown))}; "
                         f"allowed: {', '.join(FEATURE_RANGES)}")
    for key, (low, high) in FEATURE_RANGES.items():
        if key in ("p_atm", "p_sat") and key not in features:
            continue  # FeatureSpec's defaults
        number(features, key, place(where, "features"), low=low, high=high, above=key != "p_sat")
    if "coverage" in manifest:
        coverage = table(manifest, "coverage", where)
        here = place(where, "coverage")
        openings = numbers(coverage, "openings", here, (None,), low=0.0, above=True)
        if len(openings) == 0 or np.any(np.diff(openings) <= 0):
            raise InputError(f"{place(here, 'openings')}: must be increasing, at least one")
        for key in _COVERAGE_PER_OPENING:
            numbers(coverage, key, here, (len(openings),), low=0.0)
        for key, low in (("nu_range", 0.0), ("p_B_range", -1.1e5)):
            values = numbers(coverage, key, here, (2,), low=low, above=key == "nu_range")
            if values[0] > values[1]:
                raise InputError(f"{place(here, key)}: must be (low, high)")
        numbers(coverage, "back_pressures", here, (None,), low=-1.1e5)
    for name in ("flow", "force"):
        entry = table(manifest, name, where)
        here = place(where, name)
        table(entry, "predictor", here)
        domain = table(entry, "domain", here)
        at = place(here, "domain")
        size = len(feature_names(entry, name, here))
        lower = numbers(domain, "lower", at, (size,))
        upper = numbers(domain, "upper", at, (size,))
        if np.any(upper < lower):
            raise InputError(f"{at}: upper must not lie below lower")
        numbers(domain, "mean", at, (size,))
        numbers(domain, "std", at, (size,), low=0.0, above=True)
        points = numbers(domain, "points", at, (None, size))
        if len(points) == 0:
            raise InputError(f"{place(at, 'points')}: must hold at least one point")
        number(domain, "reach", at, low=0.0)
        if name == "flow" and "cfd_error" in entry:  # σ of ln C_d: 1 would be a factor e
            number(entry, "cfd_error", here, low=0.0, high=1.0)
        if entry.get("calibration") is not None:
            calibration = table(entry, "calibration", here)
            at = place(here, "calibration")
            # σ is in ln units: a floor of 1 is a factor e, and no constant need be astronomic
            # (a scale of 1e308 squared overflows to an infinite σ)
            for key, high in (("scale", CALIBRATION_MAX), ("floor", 1.0)):
                number(calibration, key, at, low=0.0, high=high, default=0.0)
            number(calibration, "power", at, low=0.0, high=10.0, above=True, default=1.0)
            slopes = calibration.get("slopes", {})
            if not isinstance(slopes, Mapping):
                raise InputError(f"{place(at, 'slopes')}: must be an object {{name: slope}}")
            for key in slopes:
                number(slopes, key, place(at, "slopes"), low=0.0, high=CALIBRATION_MAX)
            powers = calibration.get("powers", {})
            if not isinstance(powers, Mapping):
                raise InputError(f"{place(at, 'powers')}: must be an object {{name: power}}")
            for key in powers:
                number(powers, key, place(at, "powers"), low=0.0, high=10.0, above=True)
    return dict(manifest)


#: the feature lists a map may read: the flow's three; the force's first three or all four
ALLOWED_FEATURES = {"flow": (FEATURE_NAMES,),
                    "force": (FEATURE_NAMES, FORCE_FEATURE_NAMES)}


def feature_names(entry: Mapping, name: str, where: str) -> tuple[str, ...]:
    """The features the ``name`` map ("flow" or "force") of a manifest reads, in order: its
    entry's ``feature_names``, or the three shared ones (a manifest written before a map could
    read a fourth)."""
    names = entry.get("feature_names", list(FEATURE_NAMES))
    allowed = ALLOWED_FEATURES[name]
    if not isinstance(names, list) or tuple(names) not in allowed:
        raise InputError(f"{place(where, 'feature_names')}: must be "
                         + " or ".join(json.dumps(list(option)) for option in allowed))
    return tuple(names)


# --- the files -----------------------------------------------------------------------------------

def member(folder: Path, name, where: str) -> Path:
    """The file ``name`` of a manifest, which must lie inside ``folder``: a relative path
    without ``..``, not reached through a link that leads out of the folder."""
    if not isinstance(name, str) or not name.strip():
        raise InputError(f"{where}: a file name must be a non-empty string, got {json_type(name)}")
    for flavour in (PurePosixPath(name), PureWindowsPath(name)):
        if flavour.is_absolute() or flavour.drive or flavour.anchor or ".." in flavour.parts:
            raise InputError(f"{where}: the file {name!r} lies outside the surrogate folder (an "
                             "absolute path or '..'); a manifest names only files inside its "
                             "own folder")
    path = folder / name
    if not path.resolve().is_relative_to(folder.resolve()):
        raise InputError(f"{where}: the file {name!r} leads outside the surrogate folder "
                         "(through a symbolic link); a manifest names only files inside its "
                         "own folder")
    return path


def entry_files(entry: Mapping, where: str) -> list[str]:
    """The file names a predictor entry gives: ``file`` (one file) or ``files`` (format 1)."""
    if "file" in entry:
        return [entry["file"]]
    files = entry.get("files")
    if not isinstance(files, list) or not files:
        raise InputError(f"{where}: needs file = the weight file's name")
    return files


def read_npz(path: Path, what: str) -> dict[str, np.ndarray]:
    """Every array of a ``.npz`` file, read as plain numbers (``allow_pickle=False``: loading
    never runs code); refused, naming the file, when it is missing, truncated, not an ``.npz``
    archive, or holds anything but numbers."""
    check_input(path, what, "weights")  # before numpy opens it: a FIFO would block the read
    try:
        _check_unpacked_size(path, what)
        data = np.load(path, allow_pickle=False)
        if not isinstance(data, np.lib.npyio.NpzFile):
            raise ValueError("a single .npy array, not an .npz archive")
        with data:
            arrays = {key: data[key] for key in data.files}
    except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile) as error:
        # missing, truncated, not a zip archive, or object arrays (pickles)
        raise InputError(f"{path}: cannot load {what} as plain arrays ({error})") from None
    for key, value in arrays.items():
        if value.dtype.kind not in "iuf":
            raise InputError(f"{path}: array {key!r} holds {value.dtype}, not numbers")
    return arrays


def _check_unpacked_size(path: Path, what: str) -> None:
    """Refuse an archive whose arrays would unpack beyond the weights' bound, from the zip's
    directory and each array's header, before an array is read: a few hundred kB of zeros can
    claim gigabytes. A file that is no zip archive is left to :func:`numpy.load` to refuse."""
    if not zipfile.is_zipfile(path):
        return
    with zipfile.ZipFile(path) as archive:
        members = archive.infolist()
        check_size(path, sum(info.file_size for info in members), f"{what} (unpacked)",
                   "weights")
        for info in members:
            with archive.open(info) as stream:
                version = np.lib.format.read_magic(stream)
                header = (np.lib.format.read_array_header_1_0 if version == (1, 0)
                          else np.lib.format.read_array_header_2_0)
                shape, _, dtype = header(stream)
                size = math.prod(shape) * dtype.itemsize
                check_size(path, size, f"{what} (array {info.filename!r} unpacked)", "weights")


def seal(folder: Path, entry: dict) -> dict:
    """``entry`` (a predictor's manifest entry naming one ``file`` in ``folder``) with the
    SHA-256 of that file's bytes, as loading checks it."""
    return {**entry, "sha256": file_hash(Path(folder) / entry["file"])}


def verify(folder: Path, entry: Mapping, where: str) -> bool:
    """Check that the files of a predictor entry lie inside ``folder`` and, when the manifest
    records their SHA-256, that they hold those bytes. Returns whether the entry is sealed.

    Raises
    ------
    InputError
        A file outside the folder, missing, or whose bytes are not the recorded ones.
    """
    names = entry_files(entry, where)
    paths = [member(folder, name, place(where, "file")) for name in names]
    recorded = entry.get("sha256")
    if recorded is None:
        return False
    if len(paths) != 1 or not isinstance(recorded, str) or len(recorded) != 64 or any(
            c not in "0123456789abcdef" for c in recorded):
        raise InputError(f"{place(where, 'sha256')}: must be the SHA-256 (64 hex digits) of its one file")
    path = paths[0]
    if not path.is_file():
        raise InputError(f"{path}: missing (named by {where})")
    actual = file_hash(path)
    if actual != recorded:
        raise InputError(f"{path}: these weights are not the ones the manifest recorded "
                         f"(SHA-256 {actual[:12]}…, {MANIFEST} records {recorded[:12]}…): the "
                         "file was changed or damaged after training; restore it, or retrain "
                         "the surrogate with training/train.py")
    return True


def sealed_hashes(path: Path) -> set[str]:
    """The SHA-256 a model file may record for the manifest at ``path``: that of its bytes, and
    that of the same manifest as written before the weights' hashes were added (so model files
    recording a manifest from then still load; the weights are checked against the hashes now)."""
    data = read_input(path, "a surrogate manifest (JSON)")
    hashes = {hashlib.sha256(data).hexdigest()}
    try:
        manifest = json.loads(data)
    except (ValueError, RecursionError):
        return hashes
    if isinstance(manifest, Mapping):
        unsealed = {**manifest}
        changed = False
        for name in ("flow", "force"):
            entry = unsealed.get(name)
            predictor = entry.get("predictor") if isinstance(entry, Mapping) else None
            if isinstance(predictor, Mapping) and "sha256" in predictor:
                unsealed[name] = {**entry, "predictor": {key: value for key, value in
                                                         predictor.items() if key != "sha256"}}
                changed = True
        if changed:
            before = json.dumps(unsealed, indent=2) + "\n"  # as write_manifest wrote it
            hashes.add(hashlib.sha256(before.encode()).hexdigest())
    return hashes


def package_files(folder: str | Path) -> list[Path]:
    """The folder, its manifest and every file the manifest names (as far as the manifest can
    be read: a broken one is reported when the folder loads). What a run that loads the folder
    reads, so that no output may replace it."""
    folder = Path(folder)
    files = [folder, folder / MANIFEST]
    try:
        manifest = parse_json(read_input_text(folder / MANIFEST, "a surrogate manifest (JSON)"),
                              str(folder / MANIFEST))
    except (OSError, InputError, UnicodeDecodeError):
        return files
    for name in ("flow", "force"):
        entry = manifest.get(name) if isinstance(manifest, Mapping) else None
        predictor = entry.get("predictor") if isinstance(entry, Mapping) else None
        if isinstance(predictor, Mapping):
            for file in (predictor.get("files") or [predictor.get("file")]):
                if isinstance(file, str) and file:
                    files.append(folder / file)
    return files
