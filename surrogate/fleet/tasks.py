"""A fleet's work: one task per valve, each the valve's bench log and the model to fit to it.

A task carries no data, only where to find it (the log's path) and the model as the text of its
model file, so that it costs nothing to send to a worker and each worker reads its own log: the
driver never holds the logs, however many valves a batch has. The hashes of the log file and of
the model say whether a valve's earlier result still stands (:mod:`.results`).
"""

from __future__ import annotations

import glob
import hashlib
import re
from dataclasses import dataclass
from pathlib import Path

from ..core.errors import InputError
from ..core.input_files import regular_file

#: what a bench log's file name ends in when ``--data`` names a folder (the documented schema is
#: CSV; a glob picks any other files)
LOG_SUFFIX = ".csv"
#: a serial: it names the valve's record file and appears in reports and on the terminal
SERIAL = re.compile(r"[\w.\-]{1,100}")
#: bytes read at a time while hashing a log: a log of millions of rows is never held whole
HASH_CHUNK = 1 << 20


@dataclass(frozen=True)
class ValveTask:
    """One valve's work, as sent to a worker.

    Attributes
    ----------
    serial : str
        The valve's serial number: its log file's stem.
    log : str
        The bench log's absolute path (a worker of a cluster must see the same path).
    log_sha256 : str
        SHA-256 of the log file's bytes, when the task was made.
    model_toml : str
        The model to fit, as the text of a model file (paths in it absolute).
    model_sha256 : str
        SHA-256 of the model's text and of the effects files' content.
    model_label : str
        The model as the user named it (a preset or a file), for messages.
    effects_files : tuple of str
        Python files of custom effects the model may name (absolute paths).
    diagnose : bool
        Whether to diagnose the fitted model on the log too.
    """

    serial: str
    log: str
    log_sha256: str
    model_toml: str
    model_sha256: str
    model_label: str
    effects_files: tuple[str, ...] = ()
    diagnose: bool = False


def file_sha256(path: str | Path) -> str:
    """SHA-256 of a file's bytes, read in chunks (a regular file: a FIFO would block)."""
    regular_file(path, "a bench log")
    digest = hashlib.sha256()
    with open(path, "rb") as stream:
        for chunk in iter(lambda: stream.read(HASH_CHUNK), b""):
            digest.update(chunk)
    return digest.hexdigest()


def model_sha256(model_toml: str, effects_files: tuple[str, ...] = ()) -> str:
    """SHA-256 of what decides a fit besides the log: the model's text and the code of the
    effects files it may use."""
    digest = hashlib.sha256(model_toml.encode("utf-8"))
    for path in effects_files:
        digest.update(b"\0" + Path(path).read_bytes())
    return digest.hexdigest()


def _check_log_entry(data: str, path: Path) -> None:
    """Refuse a log that is a symbolic link (the fleet would read, and its errors quote, a file
    nobody named: ``SN1.csv -> /etc/passwd``), not a regular file (a folder named ``x.csv``, a
    FIFO, a device), or whose serial could not name its record file."""
    if path.is_symlink():
        raise InputError(f"--data {data}: {path} is a symbolic link; a fleet reads bench logs "
                         "that are files of their own: copy the log in, or give --data the "
                         "folder that holds it")
    regular_file(path, f"a bench log (--data {data})")
    if not SERIAL.fullmatch(path.stem):
        raise InputError(f"--data {data}: {path}: a serial (the log's file name) is letters, "
                         "digits, '.', '_' and '-', at most 100 of them; rename the file")


def find_logs(data: str) -> list[tuple[str, Path]]:
    """The bench logs ``--data`` names, as (serial, path), sorted by serial.

    ``data`` is a folder (every ``*.csv`` file directly in it) or a glob pattern (every file it
    matches, ``**`` reaching into subfolders). The serial is the file's stem.

    Raises
    ------
    InputError
        When nothing is found, or when two files would give one serial.
    """
    folder = Path(data)
    if folder.is_dir():
        paths = [path for path in folder.iterdir() if path.suffix.lower() == LOG_SUFFIX]
        if not paths:
            raise InputError(f"--data {data}: this folder holds no bench log (*{LOG_SUFFIX} "
                             "files, one per valve, named by its serial)")
    else:
        paths = [Path(path) for path in glob.glob(data, recursive=True)
                 if Path(path).suffix.lower() == LOG_SUFFIX or Path(path).is_file()]
        if not paths:
            what = "matches no file" if glob.has_magic(data) else "no such file or folder"
            raise InputError(f"--data {data}: {what}; give a folder of bench logs or a glob "
                             "such as 'logs/*.csv' (quoted, so that the shell leaves it alone)")
    for path in sorted(paths):
        _check_log_entry(data, path)
    by_serial: dict[str, list[Path]] = {}
    for path in paths:
        by_serial.setdefault(path.stem, []).append(path)
    clashes = {serial: found for serial, found in by_serial.items() if len(found) > 1}
    if clashes:
        serial, found = next(iter(sorted(clashes.items())))
        raise InputError(f"--data {data}: {len(clashes)} serial(s) named by more than one file, "
                         f"e.g. {serial!r}: {', '.join(map(str, sorted(found)))}; a valve's "
                         "serial is its log's file name, so each must be unique")
    return sorted(((serial, found[0]) for serial, found in by_serial.items()),
                  key=lambda entry: entry[0])
