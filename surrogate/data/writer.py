"""Writing a bench log back to a CSV in the documented schema (display units)."""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from ..units import from_si
from .loaders import BenchLog
from .schema import BENCH_SCHEMA


def bench_log_frame(log: BenchLog) -> pd.DataFrame:
    """The log as the file holds it: the schema's columns, in its units (bar, L/min, °C)."""
    columns = {}
    for column in BENCH_SCHEMA.columns:
        values = log.frame[column.si_name]
        columns[column.name] = from_si(values.to_numpy(), column.unit) if column.is_number \
            else values.to_numpy()
    return pd.DataFrame(columns)


def write_bench_log(log: BenchLog, path: str | Path) -> Path:
    """Write ``log`` as a CSV that :func:`~surrogate.data.load_bench_log` reads back.

    The file is written beside its destination and renamed into place, so a failure leaves no
    half-written file.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    temporary = path.with_name(f".{path.name}.tmp")
    bench_log_frame(log).to_csv(temporary, index=False, float_format="%.6f")
    temporary.replace(path)
    return path
