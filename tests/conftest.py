"""Shared fixtures: the shipped files and small good files to break in tests."""

from __future__ import annotations

import pytest

from surrogate.paths import SHIPPED_BENCH_LOG, SHIPPED_CFD_SAMPLES


@pytest.fixture(scope="session")
def cfd_lines() -> list[str]:
    """Header and first 12 rows of the shipped CFD samples, as text lines."""
    return SHIPPED_CFD_SAMPLES.read_text().splitlines()[:13]


@pytest.fixture(scope="session")
def bench_lines() -> list[str]:
    """Header and first 12 rows of the shipped bench log, as text lines."""
    return SHIPPED_BENCH_LOG.read_text().splitlines()[:13]
