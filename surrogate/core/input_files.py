"""Reading an input file: a regular file of bounded size, checked before a byte is read.

A path that a command line or a model file names may be anything: ``/dev/zero`` (a read that
never ends), a FIFO (one that never returns), a folder, a file of 100 GB. Every input the package
reads goes through :func:`read_input`, which refuses, naming the file, what is not a regular file
(by its type, before opening it: opening a FIFO blocks) and what is larger than the bound for its
kind. The bounds scale with one number, ``--max-input-mb`` on the command line or
``$CBV_MAX_INPUT_MB`` (default 1024): a bench log or CFD table may be that large, a weight
archive a sixteenth of it (unpacked), a TOML or JSON file a sixty-fourth.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

from .errors import InputError

#: the environment variable that raises (or lowers) every bound, in MB
LIMIT_VARIABLE = "CBV_MAX_INPUT_MB"
#: the bound of a table (a bench log, CFD samples) unless raised [MB]
DEFAULT_LIMIT_MB = 1024.0
#: the share of that bound each kind of file may take
SHARES = {"table": 1.0, "weights": 1 / 16, "text": 1 / 64}
_MB = 1_000_000


def megabytes(text: str) -> float:
    """A bound as written [MB]: a finite number > 0, else ValueError (the command line's option
    and the environment variable read it alike)."""
    number = float(text)
    if not 0 < number < float("inf"):
        raise ValueError(f"expected a size in MB > 0, got {text}")
    return number


def limit_mb() -> float:
    """The bound of a table [MB]: ``$CBV_MAX_INPUT_MB`` or the default."""
    value = os.environ.get(LIMIT_VARIABLE)
    if value is None:
        return DEFAULT_LIMIT_MB
    try:
        return megabytes(value)
    except ValueError:
        raise InputError(f"${LIMIT_VARIABLE}={value!r}: expected a size in MB > 0") from None


def limit_bytes(kind: str) -> int:
    """The largest file of ``kind`` ("table", "weights" or "text") read [bytes]."""
    return int(limit_mb() * SHARES[kind] * _MB)


def _raise_hint() -> str:
    return (f"raise the bound with --max-input-mb (or ${LIMIT_VARIABLE}), now "
            f"{limit_mb():g} MB for a table")


def regular_file(path: str | Path, what: str) -> os.stat_result:
    """The status of ``path``, which must be a regular file (through symbolic links), or
    InputError: missing, a folder, a device, a FIFO or a socket, or a link that loops."""
    try:
        status = os.stat(path)
    except FileNotFoundError:
        raise InputError(f"{path}: no such file ({what})") from None
    except OSError as error:  # a link loop, a name too long, no permission
        raise InputError(f"{path}: cannot read {what} ({error.strerror or error})") from None
    if stat.S_ISDIR(status.st_mode):
        raise InputError(f"{path}: a folder, not {what}")
    if not stat.S_ISREG(status.st_mode):
        kind = ("a FIFO (named pipe)" if stat.S_ISFIFO(status.st_mode) else
                "a device" if stat.S_ISCHR(status.st_mode) or stat.S_ISBLK(status.st_mode)
                else "a socket" if stat.S_ISSOCK(status.st_mode) else "a special file")
        raise InputError(f"{path}: {kind}, not a regular file; {what} is read from a file")
    return status


def check_size(path: str | Path, size: int, what: str, kind: str) -> None:
    """Refuse ``size`` [bytes] of ``path`` beyond the bound of ``kind``."""
    bound = limit_bytes(kind)
    if size > bound:
        raise InputError(f"{path}: {size / _MB:,.4g} MB, larger than the {bound / _MB:,.4g} MB "
                         f"read as {what}; {_raise_hint()}")


def check_input(path: str | Path, what: str, kind: str = "text") -> os.stat_result:
    """The status of the input file ``path``, refused (InputError) before it is opened when it
    is not a regular file (:func:`regular_file`) or is larger than the bound of ``kind``: for
    readers that open the file themselves (numpy, PyTorch, importlib)."""
    status = regular_file(path, what)
    check_size(path, status.st_size, what, kind)
    return status


def read_input(path: str | Path, what: str, kind: str = "text") -> bytes:
    """The bytes of the input file ``path`` (``what`` it is, for messages), refused before
    reading when it is not a regular file or is larger than the bound of ``kind``."""
    check_input(path, what, kind)
    bound = limit_bytes(kind)
    try:
        with open(path, "rb") as stream:
            # the file may have been swapped since the check: read one byte past the bound
            if not stat.S_ISREG(os.fstat(stream.fileno()).st_mode):
                raise InputError(f"{path}: not a regular file; {what} is read from a file")
            data = stream.read(bound + 1)
    except OSError as error:
        raise InputError(f"{path}: cannot read {what} ({error.strerror or error})") from None
    check_size(path, len(data), what, kind)
    return data


def read_input_text(path: str | Path, what: str, kind: str = "text") -> str:
    """:func:`read_input` decoded as UTF-8, refused naming the file when it is not."""
    data = read_input(path, what, kind)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as error:
        line = data[:error.start].count(b"\n") + 1
        raise InputError(f"{path}, line {line}: not UTF-8 text; {what} is a text file") from None


__all__ = ["DEFAULT_LIMIT_MB", "LIMIT_VARIABLE", "check_input", "check_size", "limit_bytes",
           "limit_mb", "megabytes", "read_input", "read_input_text", "regular_file"]
