"""Writing a bench log or CFD samples back to a CSV in the documented schema (display units)."""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from ..core.outputs import atomic_file
from ..core.units import from_si
from .loaders import BenchLog, CfdSamples
from .schema import BENCH_SCHEMA, CFD_SCHEMA, FileSchema


def file_frame(frame: pd.DataFrame, schema: FileSchema) -> pd.DataFrame:
    """``frame`` (SI) as a file of ``schema`` holds it: its columns, in its units."""
    columns = {}
    for column in schema.columns:
        values = frame[column.si_name]
        columns[column.name] = from_si(values.to_numpy(), column.unit) if column.is_number \
            else values.to_numpy()
    return pd.DataFrame(columns)


def bench_log_frame(log: BenchLog) -> pd.DataFrame:
    """The log as the file holds it: the schema's columns, in its units (bar, L/min, °C)."""
    return file_frame(log.frame, BENCH_SCHEMA)


def write_bench_log(log: BenchLog, path: str | Path) -> Path:
    """Write ``log`` as a CSV that :func:`~surrogate.data.load_bench_log` reads back.

    A failure leaves no half-written file.
    """
    with atomic_file(path) as stream:
        bench_log_frame(log).to_csv(stream, index=False, float_format="%.6f")
    return Path(path)


def write_cfd_samples(samples: CfdSamples, path: str | Path) -> Path:
    """Write ``samples`` as a CSV that :func:`~surrogate.data.load_cfd_samples` reads back.

    A failure leaves no half-written file.
    """
    with atomic_file(path) as stream:
        file_frame(samples.frame, CFD_SCHEMA).to_csv(stream, index=False, float_format="%.6g")
    return Path(path)
