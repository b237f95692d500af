"""Small helpers for the package's TOML files (valve files, model files).

Python reads TOML (``tomllib``) but does not write it; :func:`dumps` writes the small subset the
package's own files use: tables, arrays of tables, and values that are strings, numbers, booleans
or inline tables of those.
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Mapping

from .errors import InputError

#: how deeply a valve or model file may nest its tables and arrays; the formats need 4
MAX_DEPTH = 32


def loads(text: str, where: str) -> dict:
    """Parse TOML text (:func:`tomllib.loads`; its TOMLDecodeError is the caller's to word),
    refusing, as an InputError naming ``where``, a document nested deeper than
    :data:`MAX_DEPTH`: the parser recurses and would fail on thousands of levels, and so would
    anything walking the result."""
    try:
        document = tomllib.loads(text)
    except RecursionError:
        document = None
    if document is None or nesting_depth(document) > MAX_DEPTH:
        raise InputError(f"{where}: nested too deep (more than {MAX_DEPTH} levels of tables and "
                         "arrays)")
    return document


def nesting_depth(document) -> int:
    """How many tables (objects) and arrays deep ``document`` goes, measured without recursion
    so that any depth is."""
    deepest, stack = 0, [(document, 1)]
    while stack:
        value, depth = stack.pop()
        if isinstance(value, Mapping):
            children = value.values()
        elif isinstance(value, list):
            children = value
        else:
            continue
        deepest = max(deepest, depth)
        stack.extend((child, depth + 1) for child in children)
    return deepest


def require_keys(table: dict, keys: set[str], source: str) -> None:
    """Raise :class:`InputError` unless ``table`` is a table with exactly ``keys``; names what
    is off (an array of tables, ``[[valve]]``, where one table ``[valve]`` belongs included)."""
    if not isinstance(table, Mapping):
        what = "an array of tables ([[...]])" if isinstance(table, list) else type(table).__name__
        raise InputError(f"{source}: must be one table [...] with the keys "
                         f"{', '.join(sorted(keys))}; got {what}")
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


def _value(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        if isinstance(value, float) and math.isinf(value):
            return "inf" if value > 0 else "-inf"
        if isinstance(value, float) and math.isnan(value):
            return "nan"
        return repr(value) if isinstance(value, float) else str(value)
    if isinstance(value, str):
        escaped = value.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n")
        return f'"{escaped}"'
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{_key(k)} = {_value(v)}" for k, v in value.items()) + " }"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_value(v) for v in value) + "]"
    raise TypeError(f"cannot write {type(value).__name__} to TOML")


def _key(key: str) -> str:
    return key if key.replace("_", "").replace("-", "").isalnum() else _value(key)


def dumps(document: dict, header: str = "") -> str:
    """TOML text of ``document``: a dict whose values are scalars, tables (dict) of scalars and
    inline tables, or arrays of such tables (list of dict). Tables may nest one level
    (``[effects.parameters]``)."""
    lines = [f"# {line}".rstrip() for line in header.splitlines()]
    scalars = {k: v for k, v in document.items() if not isinstance(v, (dict, list))
               or (isinstance(v, list) and not all(isinstance(i, dict) for i in v))}
    lines += [f"{_key(k)} = {_value(v)}" for k, v in scalars.items()]
    for key, value in document.items():
        if isinstance(value, dict):
            _table(lines, key, value, array=False)
        elif isinstance(value, list) and value and all(isinstance(i, dict) for i in value):
            for item in value:
                _table(lines, key, item, array=True)
    return "\n".join(lines).strip() + "\n"


def _table(lines: list[str], name: str, table: dict, array: bool) -> None:
    lines.append("")
    lines.append(f"[[{name}]]" if array else f"[{name}]")
    nested = {k: v for k, v in table.items()
              if isinstance(v, dict) and not _inline(v, len(_key(k)) + 3)}
    for key, value in table.items():
        if key not in nested:
            lines.append(f"{_key(key)} = {_value(value)}")
    for key, value in nested.items():
        lines.append(f"[{name}.{key}]")
        for inner_key, inner in value.items():
            lines.append(f"{_key(inner_key)} = {_value(inner)}")


_LINE = 100


def _inline(table: dict, indent: int = 0) -> bool:
    """Short tables of scalars are written inline; tables of tables, and tables too long for a
    line, get a section."""
    if any(isinstance(v, dict) for v in table.values()):
        return False
    return indent + len(_value(table)) <= _LINE
