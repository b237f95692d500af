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


@pytest.fixture(scope="session")
def valve():
    from surrogate import load_valve

    return load_valve()


@pytest.fixture(scope="session")
def cfd_samples():
    from surrogate.data import load_cfd_samples

    return load_cfd_samples(SHIPPED_CFD_SAMPLES)


@pytest.fixture(scope="session")
def bench_log():
    from surrogate.data import load_bench_log

    return load_bench_log(SHIPPED_BENCH_LOG)


@pytest.fixture(scope="session")
def grid_maps(cfd_samples, valve):
    from surrogate.maps import GridFlowMap, GridForceMap

    return GridFlowMap.from_samples(cfd_samples), GridForceMap.from_samples(cfd_samples, valve)
