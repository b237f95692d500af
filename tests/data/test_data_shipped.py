"""The shipped files load, in SI units, with the content their READMEs describe."""

import numpy as np
import pytest

from surrogate.data import load_any, load_bench_log, load_cfd_samples
from surrogate.data.schema import BENCH_SCHEMA, CFD_SCHEMA, schema_table
from surrogate.core.paths import PROJECT_ROOT, SHIPPED_BENCH_LOG, SHIPPED_CFD_SAMPLES


def test_cfd_samples_load_in_si():
    samples = load_cfd_samples(SHIPPED_CFD_SAMPLES)
    frame = samples.frame
    assert len(samples) == 154
    first = frame.iloc[0]  # C0001: 20 degC, u 0.05 mm, q 1 L/min, p_B 5 bar, p_L 28.301 bar
    assert first["case"] == "C0001" and first["line"] == 2
    assert first["temperature"] == pytest.approx(293.15)
    assert first["u"] == pytest.approx(0.05e-3)
    assert first["q"] == pytest.approx(1e-3 / 60)
    assert first["p_B"] == pytest.approx(5e5)
    assert first["p_L"] == pytest.approx(28.301e5)
    assert first["nu"] == pytest.approx(117.505e-6)
    assert sorted(np.unique(frame["u"].round(8) * 1e3)) == pytest.approx(
        [0.05, 0.08, 0.10, 0.13, 0.16, 0.20, 0.63])
    assert frame["case"].str.startswith("P").sum() == 16


def test_bench_log_loads_in_si_with_twelve_runs():
    log = load_bench_log(SHIPPED_BENCH_LOG)
    assert len(log) == 11000
    assert log.run_ids == [f"R{i:02d}" for i in range(1, 13)]
    runs = log.runs()
    assert sum(len(run) for run in runs) == 11000
    assert {round(run.p_Pe_nominal / 1e5) for run in runs} == {50, 65, 80, 120}
    assert {round(run.temperature - 273.15, -1) for run in runs} == {20, 40, 60}
    for run in runs:
        assert np.all(np.diff(run.frame["time"]) > 0)
    assert set(log.frame["direction"]) == {"up", "down"}
    assert log.frame["q"].min() >= 1e-3 / 60 * 0.99  # samples below 1 L/min were left out


def test_load_any_recognises_both_kinds():
    assert type(load_any(SHIPPED_CFD_SAMPLES)).__name__ == "CfdSamples"
    assert type(load_any(SHIPPED_BENCH_LOG)).__name__ == "BenchLog"


@pytest.mark.parametrize("schema, readme", [(CFD_SCHEMA, "cfd_samples/README.md"),
                                            (BENCH_SCHEMA, "measurements/README.md")])
def test_readmes_document_the_schema_the_loader_enforces(schema, readme):
    assert schema_table(schema) in (PROJECT_ROOT / readme).read_text()
