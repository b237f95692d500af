"""Writing a command's output files all at once, or not at all."""

from __future__ import annotations

import contextlib
import shutil
import tempfile
from pathlib import Path


@contextlib.contextmanager
def atomic_directory(target: str | Path):
    """Yield a fresh temporary directory; on success move its files into ``target``.

    If the body raises, ``target`` is left exactly as it was: no half-written results. Files of
    the same name already in ``target`` are replaced; others are kept.
    """
    target = Path(target)
    target.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=f".{target.name}-", dir=target.parent))
    try:
        yield staging
        target.mkdir(exist_ok=True)
        for path in staging.iterdir():
            destination = target / path.name
            if destination.is_dir() and not destination.is_symlink():
                shutil.rmtree(destination)
            path.replace(destination)
    finally:
        shutil.rmtree(staging, ignore_errors=True)
