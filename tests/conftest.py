"""Shared fixtures: the shipped files and small good files to break in tests."""

from __future__ import annotations

import pytest

from surrogate.core.paths import SHIPPED_BENCH_LOG, SHIPPED_CFD_SAMPLES


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
def meshes_of_their_own(cfd_samples):
    """A user's CFD of the shipped valve whose meshes err more than the shipped ones (whose
    openings scatter by 0.5 %): each opening's Δp scaled by exp(+3 %, −3 %, 0, +3 %, …) in
    increasing order of the openings."""
    import numpy as np

    from surrogate.data.loaders import CfdSamples

    frame = cfd_samples.frame.copy()
    openings = np.unique(frame["u"].round(12))
    bias = np.array([0.03, -0.03, 0.0])[np.searchsorted(openings, frame["u"].round(12)) % 3]
    frame["p_L"] = frame["p_B"] + (frame["p_L"] - frame["p_B"]) * np.exp(bias)
    return CfdSamples(frame, "meshes of their own")


@pytest.fixture(scope="session")
def bench_log():
    from surrogate.data import load_bench_log

    return load_bench_log(SHIPPED_BENCH_LOG)


@pytest.fixture(scope="session")
def grid_maps(cfd_samples, valve):
    from surrogate.maps import GridFlowMap, GridForceMap

    return GridFlowMap.from_samples(cfd_samples), GridForceMap.from_samples(cfd_samples, valve)


def write_runs(folder, runs: tuple[str, ...], every: int = 10):
    """A small real log in ``folder``: the shipped log's ``runs``, every ``every``-th sample of
    each; returns its path."""
    lines = SHIPPED_BENCH_LOG.read_text().splitlines()
    rows = [line for line in lines[1:] if line.split(",")[0] in runs][::every]
    path = folder / "log.csv"
    path.write_text("\n".join([lines[0], *rows]) + "\n")
    return path


@pytest.fixture(scope="session")
def one_run_log(tmp_path_factory):
    """Run R01 of the shipped log (20 °C, p_Pe 50 bar), every 10th sample: a real log small
    enough for a command line's round trip."""
    return write_runs(tmp_path_factory.mktemp("one_run"), ("R01",))


@pytest.fixture(scope="session")
def two_run_log(tmp_path_factory):
    """Runs R01 and R06 of the shipped log (20 °C and 50 bar; 40 °C and 65 bar), every 10th
    sample: two temperatures and two pilot pressures."""
    return write_runs(tmp_path_factory.mktemp("two_runs"), ("R01", "R06"))
