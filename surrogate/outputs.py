"""Writing a command's output files all at once, or not at all, and never over its inputs.

A command checks where it will write before it computes anything (:func:`check_outputs`): an
output that is one of its inputs, or that lies where nothing can be written, is refused at once
instead of after a long fit. The files themselves are written to a temporary name and renamed into
place (:func:`atomic_file`, :func:`atomic_directory`), with the permissions any other file the
user creates would get.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

from .errors import InputError
from .interrupts import deferred


@dataclass(frozen=True)
class Output:
    """Where a command will write: ``path`` given by ``option``, a ``"file"`` or a ``"folder"``."""

    option: str
    path: str | Path
    kind: str = "file"


def check_outputs(outputs: Iterable[Output],
                  inputs: Iterable[str | Path | tuple[str | Path, str]]) -> None:
    """Refuse, before any work, outputs that would overwrite an input or cannot be written.

    Parameters
    ----------
    outputs : iterable of Output
        What the command will write.
    inputs : iterable of path, or of (path, what it is)
        Every file or folder the command reads (missing ones are skipped), through symbolic
        links: the files a command line names and those its model file, its maps and a trained
        surrogate's manifest name.

    Raises
    ------
    InputError
        Naming the option, the path and the input: an output that is an input, that holds one
        (an output folder) or that lies inside an input folder (a trained surrogate's), a file
        where a folder is meant or the reverse, a parent that is a file, or a place the user may
        not write to.
    """
    existing = []
    for item in inputs:
        path, role = item if isinstance(item, tuple) else (item, "")
        if path is not None and Path(path).exists():
            existing.append((Path(path), f" ({role})" if role else ""))
    for output in outputs:
        target = Path(output.path)
        for source, role in existing:
            if _same(target, source):
                raise InputError(f"{output.option} {target}: that is the input {source}{role}; "
                                 "refusing to overwrite an input, choose another path")
            if _inside(source, target):
                raise InputError(f"{output.option} {target}: this output folder holds the input "
                                 f"{source}{role}, which its files could replace; choose another "
                                 "folder")
            if source.is_dir() and _inside(target, source):
                raise InputError(f"{output.option} {target}: lies inside the input folder "
                                 f"{source}{role}, which this run reads; refusing to write into "
                                 "an input, choose another path")
        _check_writable(output.option, target, output.kind)


def _same(a: Path, b: Path) -> bool:
    if a.exists():
        return os.path.samefile(a, b)
    return a.resolve() == b.resolve()


def _inside(path: Path, folder: Path) -> bool:
    """Whether ``path`` lies (at any depth) inside ``folder``, both through symbolic links."""
    return folder.resolve() in path.resolve().parents


def _check_writable(option: str, target: Path, kind: str) -> None:
    if target.exists() or target.is_symlink():
        if kind == "folder" and not target.is_dir():
            raise InputError(f"{option} {target}: this is a file; give a folder to write into")
        if kind == "file" and target.is_dir():
            raise InputError(f"{option} {target}: this is a folder; give the path of a file")
    # The output is staged next to it (atomic_file, atomic_directory), so the nearest existing
    # ancestor of its parent must be a folder we may create files in; an existing output folder
    # must take the finished files too.
    ancestor = target.parent
    while not ancestor.exists():
        ancestor = ancestor.parent
    if not ancestor.is_dir():
        raise InputError(f"{option} {target}: {ancestor} is a file, not a folder, so nothing "
                         "can be written under it")
    places = [ancestor] + ([target] if kind == "folder" and target.is_dir() else [])
    for place in places:
        try:  # a real probe: permissions, read-only file systems and root all answer truthfully
            with tempfile.TemporaryFile(dir=place, prefix=".cbv-write-probe-"):
                pass
        except OSError as error:
            raise InputError(f"{option} {target}: cannot write in {place} "
                             f"({error.strerror or error})") from None


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _permissions() -> int:
    """The mode a new file gets here: 0666 less the process's umask (0644 with the usual 022)."""
    return 0o666 & ~_umask()


@contextlib.contextmanager
def atomic_directory(target: str | Path):
    """Yield a fresh temporary directory; on success move its files into ``target``.

    If the body raises (an interruption included), ``target`` is left exactly as it was and the
    temporary directory is removed: no half-written results, nothing hidden left behind. Files of
    the same name already in ``target`` are replaced; others are kept. Moving the files in and
    removing the temporary directory are not cut short by Ctrl-C or SIGTERM
    (:func:`surrogate.interrupts.deferred`): a signal then stops the command once they are done.
    """
    target = Path(target)
    target.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=f".{target.name}-", dir=target.parent))
    try:
        yield staging
        with deferred():
            if not target.exists():  # one rename: the folder appears whole
                os.chmod(staging, 0o777 & ~_umask())
                staging.replace(target)
                return
            for path in staging.iterdir():
                destination = target / path.name
                if destination.is_dir() and not destination.is_symlink():
                    shutil.rmtree(destination)
                path.replace(destination)
    finally:
        with deferred():
            shutil.rmtree(staging, ignore_errors=True)


@contextlib.contextmanager
def atomic_file(target: str | Path):
    """Yield a text stream; on success its content replaces ``target`` in one rename.

    If the body raises (an interruption included), the temporary file is removed and ``target``
    is left as it was. The file gets the usual permissions (mkstemp's own are owner-only).
    """
    target = Path(target)
    target.parent.mkdir(parents=True, exist_ok=True)
    handle, temporary = tempfile.mkstemp(prefix=f".{target.name}-", dir=target.parent)
    try:
        with os.fdopen(handle, "w", encoding="utf-8", newline="") as stream:
            yield stream
        with deferred():
            os.chmod(temporary, _permissions())
            os.replace(temporary, target)
    except BaseException:
        with deferred():
            Path(temporary).unlink(missing_ok=True)
        raise
