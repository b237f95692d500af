"""Small helpers for the package's TOML files (valve files, later model files)."""

from __future__ import annotations

from .errors import InputError


def require_keys(table: dict, keys: set[str], source: str) -> None:
    """Raise :class:`InputError` unless ``table`` has exactly ``keys``; names what is off."""
    missing = sorted(keys - set(table))
    extra = sorted(set(table) - keys)
    problems = []
    if missing:
        problems.append(f"missing {', '.join(missing)}")
    if extra:
        problems.append(f"unknown {', '.join(extra)}")
    if problems:
        raise InputError(f"{source}: {'; '.join(problems)} "
                         f"(expected exactly: {', '.join(sorted(keys))})")
