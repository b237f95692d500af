"""Data layer: CFD samples and bench logs, validated, in SI units."""

from .errors import DataFileError, Problem
from .loaders import BenchLog, BenchRun, CfdSamples, load_any, load_bench_log, load_cfd_samples
from .schema import BENCH_SCHEMA, CFD_SCHEMA

__all__ = [
    "BENCH_SCHEMA", "CFD_SCHEMA", "BenchLog", "BenchRun", "CfdSamples", "DataFileError", "Problem",
    "load_any", "load_bench_log", "load_cfd_samples",
]
