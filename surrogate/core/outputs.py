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
    #: for a folder, what the command will write in it (relative paths; a trailing "/" marks a
    #: folder), checked before any work: none may be a link, a special file or of the other kind
    entries: tuple[str, ...] = ()


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
        for entry in output.entries:
            problem = _conflict(target / entry.rstrip("/"), folder=entry.endswith("/"))
            if problem:
                raise InputError(f"{output.option} {target}: {problem}")


def _conflict(destination: Path, *, folder: bool) -> str | None:
    """Why a run may not write a file (or a folder) at ``destination``, or None: a symbolic
    link would take the write elsewhere, a special file would hang or swallow it, and replacing
    a folder by a file (or the reverse) would remove what the user keeps there."""
    if destination.is_symlink():
        return (f"{destination} is a symbolic link, which this run would write through; "
                "remove the link or choose another folder")
    if not destination.exists():
        return None
    if destination.is_dir() and not folder:
        return (f"{destination} is a folder where this run writes a file; move it or choose "
                "another folder")
    if folder and not destination.is_dir():
        return (f"{destination} is a file where this run writes a folder; move it or choose "
                "another folder")
    if not folder and not destination.is_file():
        return (f"{destination} is a special file (a pipe, a socket or a device), not a "
                "regular file; remove it or choose another folder")
    return None


def _merge_conflicts(staging: Path, target: Path) -> str | None:
    """The first reason the staged tree may not be merged into ``target``, or None."""
    for path in sorted(staging.rglob("*")):
        problem = _conflict(target / path.relative_to(staging), folder=path.is_dir())
        if problem:
            return problem
    return None


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
    the same name already in ``target`` are replaced; others are kept, in subfolders too. An
    entry of ``target`` that the results would write through (a link) or replace by another
    kind (a folder where a file goes) stops the command (InputError) before anything is moved.
    Moving the files in and
    removing the temporary directory are not cut short by Ctrl-C or SIGTERM
    (:func:`.interrupts.deferred`): a signal then stops the command once they are done.
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
            problem = _merge_conflicts(staging, target)
            if problem:
                raise InputError(f"{target}: {problem}; nothing was written")
            _merge(staging, target)
    finally:
        with deferred():
            shutil.rmtree(staging, ignore_errors=True)


def _merge(source: Path, target: Path) -> None:
    """Move ``source``'s entries into the folder ``target``: files replace files of the same name,
    folders merge into folders (checked beforehand by :func:`_merge_conflicts`)."""
    for path in source.iterdir():
        destination = target / path.name
        if path.is_dir() and destination.is_dir():
            _merge(path, destination)
        else:
            path.replace(destination)


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
