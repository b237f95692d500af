"""Writing a bench log back to a CSV in the documented schema (display units)."""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from ..outputs import atomic_file
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

    A failure leaves no half-written file.
    """
    with atomic_file(path) as stream:
        bench_log_frame(log).to_csv(stream, index=False, float_format="%.6f")
    return Path(path)
