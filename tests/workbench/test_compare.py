"""The workbench's compare step: a model against a bench log, its tables, JSON and figures."""

import json

import numpy as np
import pandas as pd
import pytest

from surrogate.data import BenchLog
from surrogate.description.modelfile import load_model
from surrogate.reporting.figures import write_figures
from surrogate.core.units import from_si, to_si
from surrogate.workbench.compare import compare, hysteresis_width

RUNS = ["R01", "R04", "R06", "R11"]  # 20, 40 and 60 °C; set points 50, 65, 80 and 120 bar


@pytest.fixture(scope="module")
def model():
    from surrogate.description.modelfile import load_model

    return load_model("cfda")


@pytest.fixture(scope="module")
def log(bench_log):
    """A few runs of the shipped log, to keep the replays short."""
    frame = bench_log.frame[bench_log.frame["run"].isin(RUNS)].reset_index(drop=True)
    return BenchLog(frame, bench_log.source)


@pytest.fixture(scope="module")
def comparison(model, log):
    return compare(model, log)


@pytest.fixture(scope="module")
def perfect_log(comparison, log):
    """The log with p_L replaced by the model's own prediction: data the model fits exactly."""
    frame = log.frame.copy()
    replay = comparison.log_replay.replay
    assert replay.ok.all()
    frame["p_L"] = frame["p_B"] + replay.dp
    return BenchLog(frame, "perfect.csv")


def _is_rounded(value: float) -> bool:
    return round(value, 4) == value


def test_json_contract(comparison):
    document = comparison.to_json()
    json.dumps(document, allow_nan=False)  # plain, strict JSON
    assert document["model"] == "cfda"
    for key in ("rms_bar", "noise_floor_bar"):
        assert isinstance(document[key], float) and _is_rounded(document[key])
    assert [r["run"] for r in document["runs"]] == RUNS
    for row in document["runs"]:
        for key in ("temperature_C", "p_Pe_bar", "rms_bar", "bias_bar", "hysteresis_error_bar"):
            assert isinstance(row[key], float) and _is_rounded(row[key]), (key, row[key])
        assert isinstance(row["samples"], int)
        assert row["worst"] and {"line", "time_s", "q_lpm", "residual_bar"} <= set(row["worst"][0])
    assert {r["p_Pe_bar"] for r in document["runs"]} == {50.0, 65.0, 80.0, 120.0}
    assert {r["temperature_C"] for r in document["rms_by_p_Pe_and_temperature"]} == {20, 40, 60}
    assert {"rms_bar", "bias_bar", "samples", "extrapolating"} <= set(document["regions"][0])


def test_per_run_and_per_region_rms_pool_back_to_the_overall_rms(comparison):
    runs, regions = comparison.runs, comparison.regions
    overall = from_si(comparison.rms, "bar")
    solved = runs["samples"] - runs["failed"]
    assert solved.sum() == comparison.solved == regions["samples"].sum()
    pooled = np.sqrt(np.sum(solved * runs["rms_bar"] ** 2) / solved.sum())
    assert pooled == pytest.approx(overall, rel=1e-12)
    count = regions["samples"]
    pooled = np.sqrt(np.sum(count * regions["rms_bar"] ** 2) / count.sum())
    assert pooled == pytest.approx(overall, rel=1e-12)
    assert regions["rms_bar"].is_monotonic_decreasing  # worst region first


def test_a_model_equal_to_the_data_has_no_residual(model, comparison, perfect_log):
    perfect = compare(model, perfect_log)
    assert from_si(perfect.rms, "bar") < 1e-9
    assert perfect.runs["rms_bar"].abs().max() < 1e-9
    assert perfect.runs["hysteresis_error_bar"].abs().max() < 1e-9
    # the hysteresis the model predicts is unchanged, and is now also the measured one
    assert np.allclose(perfect.runs["hysteresis_model_bar"],
                       comparison.runs["hysteresis_model_bar"], atol=1e-9)
    json.dumps(perfect.to_json(), allow_nan=False)  # a zero noise floor is no division by zero
    assert "R06" in perfect.format_text()


def test_an_offset_in_one_run_shows_as_its_bias(model, perfect_log):
    """Measured 1 bar high in one run: model minus measured is −1 bar there, 0 elsewhere."""
    frame = perfect_log.frame.copy()
    frame.loc[frame["run"] == "R06", "p_L"] += to_si(1.0, "bar")
    shifted = compare(model, BenchLog(frame, "shifted.csv"))
    runs = shifted.runs.set_index("run")
    assert runs.loc["R06", "bias_bar"] == pytest.approx(-1.0, abs=1e-9)
    assert runs.loc["R06", "rms_bar"] == pytest.approx(1.0, abs=1e-9)
    assert runs.drop("R06")["rms_bar"].abs().max() < 1e-9
    assert runs["hysteresis_error_bar"].abs().max() < 1e-9  # an offset is no hysteresis
    assert shifted.pivot.loc[65.0, 40.0] == pytest.approx(1.0, abs=1e-9)
    worst = shifted.regions.iloc[0]
    assert (worst["p_Pe_bar"], worst["temperature_C"]) == (65.0, 40.0)
    assert worst["bias_bar"] == pytest.approx(-1.0, abs=1e-9)


def test_hysteresis_width_of_a_known_loop():
    q = np.linspace(1.0, 12.0, 200)
    curve = 40.0 + 3.0 * q + 0.2 * q**2  # [bar]
    runs = np.repeat(["A", "B", "C"], 400)
    flow = np.tile(np.concatenate([q, q[::-1]]), 3)
    direction = np.tile(np.repeat(["up", "down"], 200), 3)
    direction[800:] = "up"  # run C has no ramp down
    dp = np.tile(np.concatenate([curve, curve[::-1]]), 3)
    dp = dp + np.where(direction == "up", 1.0, -1.0) * np.repeat([0.5, 2.0, 0.5], 400)
    width = hysteresis_width(runs, to_si(flow, "L/min"), direction, to_si(dp, "bar"))
    assert list(width.index) == ["A", "B", "C"]
    assert from_si(width["A"], "bar") == pytest.approx(1.0, abs=1e-9)
    assert from_si(width["B"], "bar") == pytest.approx(4.0, abs=1e-9)
    assert np.isnan(width["C"])


def test_text_summary_lists_every_run(comparison):
    text = comparison.format_text()
    assert f"{from_si(comparison.rms, 'bar'):.3f} bar" in text
    assert all(run in text for run in RUNS)


def test_figures_are_written(comparison, tmp_path):
    paths = write_figures(comparison, tmp_path / "figures")
    assert set(paths) == {"dp_vs_q", "residuals", "hysteresis"}
    for path in paths.values():
        data = path.read_bytes()
        assert data.startswith(b"\x89PNG") and 10_000 < len(data) < 2_000_000
    # the report's figures, to the byte
    from surrogate.reporting.report import figure_pngs

    assert {name: path.read_bytes() for name, path in paths.items()} == figure_pngs(comparison)


def test_text_tables_never_merge_columns_and_say_what_is_not_measured(bench_log, tmp_path):
    """A log with only up-ramps has no hysteresis width: the text says "not measured", not
    "nan"; a long run id and a huge residual widen their columns instead of running into the
    next one."""
    frame = bench_log.frame[(bench_log.frame["run"].isin(["R01", "R06"]))
                            & (bench_log.frame["direction"] == "up")].copy()
    frame["run"] = frame["run"].replace({"R01": "R01-a-very-long-run-identifier"})
    log = BenchLog(frame.iloc[::4].reset_index(drop=True), "up-only.csv")
    text = compare(load_model("cfda"), log).format_text()
    assert "nan" not in text and "not measured" in text
    header = next(line for line in text.splitlines() if line.strip().startswith("run"))
    row = next(line for line in text.splitlines() if "very-long" in line)
    # every heading ends where its column's values end: right-aligned numbers line up
    for heading in ("samples", "RMS", "extrap."):
        end = header.index(heading) + len(heading)
        assert row[end - 1] != " " and (end == len(row) or row[end] == " "), (header, row)


def test_a_big_log_lists_its_worst_runs_in_the_text(bench_log):
    from surrogate.workbench.compare import TEXT_RUNS

    frames = [bench_log.frame.iloc[::40].assign(run=bench_log.frame["run"].iloc[::40] + f"-{k}")
              for k in range(3)]
    log = BenchLog(pd.concat(frames, ignore_index=True), "many.csv")
    text = compare(load_model("cfda"), log).format_text()
    assert f"The {TEXT_RUNS} runs of largest RMS (of 36" in text
