"""Exporting a fitted valve: the FMU against the solver's replay, the tables' files, the steady
characteristic, and what cannot be exported.

One export of ``cfda`` (grid maps, the roughest the package has) at the default grid serves the
FMU and table tests (about 7 s); the source-only FMU is written on a coarse grid.
"""

from __future__ import annotations

import json
import zipfile

import numpy as np
import pandas as pd
import pytest

from surrogate.cli import main
from surrogate.data import load_bench_log
from surrogate.effects import custom_effect
from surrogate.core.errors import InputError
from surrogate.export.fmu import simulate_log
from surrogate.export.refinement import refined_grid
from surrogate.export.tables import TableGrid, interpolate
from surrogate.export.tabulable import refuse_untabulable
from surrogate.export.valve_only import valve_physics
from surrogate.description.modelfile import load_model
from surrogate.core.paths import SHIPPED_BENCH_LOG
from surrogate.points import OperatingPoints
from surrogate.solver.replay import replay
from surrogate.core.units import from_si

fmpy = pytest.importorskip("fmpy")  # the test extra installs it


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    out = tmp_path_factory.mktemp("export") / "cfda"
    assert main(["export", "--model", "cfda", "--format", "fmu", "--format", "tables",
                 "--out", str(out), "--quiet"]) == 0
    return out


@pytest.fixture(scope="module")
def shipped_log():
    log = load_bench_log(SHIPPED_BENCH_LOG)
    return log, OperatingPoints.from_bench(log.frame), log.frame["run"].to_numpy()


@pytest.mark.pipeline
def test_the_fmu_validates(exported):
    from fmpy.validation import validate_fmu

    assert validate_fmu(str(exported / "cfda.fmu")) == []


@pytest.mark.pipeline
def test_the_fmu_reproduces_the_replay_of_the_shipped_log(exported, shipped_log):
    log, points, runs = shipped_log
    model = valve_physics(load_model("cfda")).model
    reference = replay(model, points, runs, diagnostics=False)  # the classic play
    dp = simulate_log(str(exported / "cfda.fmu"), points, runs)
    error = from_si(dp - reference.dp, "bar")
    rms, largest = float(np.sqrt(np.mean(error ** 2))), float(np.max(np.abs(error)))
    print(f"FMU against the replay: {rms:.4f} bar RMS, {largest:.3f} bar at most")
    assert rms < 0.1
    assert largest < 1.0
    # and the export's own measurement of the tables' resolution says the same
    summary = json.loads((exported / "export.json").read_text())
    assert summary["resolution_error_bar"]["rms"] == pytest.approx(rms, abs=2e-4)


@pytest.mark.pipeline
def test_the_fmu_plays_friction_as_state(exported):
    """Up and down the same flows, the FMU's Δp differs by the friction band: its state."""
    q = np.r_[np.linspace(1, 10, 40), np.linspace(10, 1, 40)] / 60_000
    points = OperatingPoints.create(q, 65e5, 5e5, 313.15)
    runs = np.zeros(len(q))
    dp = simulate_log(str(exported / "cfda.fmu"), points, runs)
    up, down = dp[:40], dp[40:][::-1]
    assert np.all(up[5:-5] > down[5:-5] + 5e5)  # cfda's friction: > 5 bar of hysteresis


def unseen_runs() -> tuple[OperatingPoints, np.ndarray]:
    """Smooth flow ramps up and down (0.5 to 14 L/min) at states the shipped log never
    visits: back pressures of 0.5 and 9 bar, oil at 12 and 68 degC, a pilot pressure of 30 and
    100 bar."""
    ramp = np.r_[np.geomspace(0.5, 14, 60), np.geomspace(14, 0.5, 60)] / 60_000
    states = [(30e5, 0.5e5, 285.15), (100e5, 9e5, 341.15), (65e5, 9e5, 285.15),
              (45e5, 0.5e5, 341.15)]
    columns = [np.concatenate([np.full(ramp.size, value) for value in column])
               for column in zip(*states)]
    runs = np.repeat(np.arange(len(states)), ramp.size)
    return OperatingPoints.create(np.tile(ramp, len(states)), *columns), runs


@pytest.mark.pipeline
def test_the_fmu_follows_the_solver_on_runs_outside_the_fitted_log(exported):
    """The tables span the valve's envelope, not the log's: on smooth runs far from the log
    the FMU stays within the export's tolerance of the package's replay, and says it is
    inside its tables."""
    points, runs = unseen_runs()
    model = valve_physics(load_model("cfda")).model
    reference = replay(model, points, runs, diagnostics=False)
    fmu = str(exported / "cfda.fmu")
    error = from_si(simulate_log(fmu, points, runs) - reference.dp, "bar")[reference.ok]
    rms = float(np.sqrt(np.mean(error ** 2)))
    summary = json.loads((exported / "export.json").read_text())
    print(f"FMU against the replay on unseen runs: {rms:.4f} bar RMS, "
          f"{np.max(np.abs(error)):.3f} bar at most")
    assert reference.ok.mean() > 0.95
    assert rms < summary["tolerance_bar"]
    assert np.all(simulate_log(fmu, points, runs, output="outside") == 0)


@pytest.mark.pipeline
def test_runs_outside_the_fitted_log_need_the_valves_envelope(tmp_path):
    """The unseen runs are a real test of the envelope: an FMU over the log's own range (with a
    margin), held at its edges, misses the solver there by bars and says it is outside."""
    out = tmp_path / "log-range"
    assert main(["export", "--model", "cfda", "--format", "fmu", "--ranges", "log",
                 "--out", str(out), "--quiet"]) == 0
    points, runs = unseen_runs()
    reference = replay(valve_physics(load_model("cfda")).model, points, runs,
                       diagnostics=False)
    fmu = str(out / "cfda.fmu")
    error = from_si(simulate_log(fmu, points, runs) - reference.dp, "bar")[reference.ok]
    rms = float(np.sqrt(np.mean(error ** 2)))
    print(f"an FMU over the log's range against the replay on unseen runs: {rms:.2f} bar RMS")
    assert rms > 1.0
    assert np.any(simulate_log(fmu, points, runs, output="outside") > 0)


@pytest.mark.pipeline
def test_the_fmu_holds_its_inputs_to_the_tables_and_says_so(exported):
    """Far outside the grid the FMU answers with the edge's values, never NaN, and flags the
    inputs held (1 q, 2 p_B, 4 p_P, 8 T) on its output and through the logger, once."""
    points = OperatingPoints.create(np.array([1e-4, 1e-4, 1e-9, 1.0, 1.0]), 65e5,
                                    np.array([5e5, 5e5, 5e5, -1e6, -1e6]), 313.15)
    points = points.replace(p_P=np.array([65e5, 65e5, 1e9, 1e9, 1e9]),
                            temperature=np.array([313.15, 313.15, 313.15, 313.15, 1000.0]))
    messages = []

    def logger(component, instance, status, category, message):
        messages.append((category.decode(), message.decode()))
    fmu = str(exported / "cfda.fmu")
    dp = simulate_log(fmu, points, np.zeros(5), logger=logger)
    assert np.all(np.isfinite(dp)) and np.all(dp > 0)
    flags = simulate_log(fmu, points, np.zeros(5), output="outside")
    # 6 L/min is inside; a near-zero flow (the third) is the cracking valve, held, not flagged
    assert flags.tolist() == [0, 0, 4, 1 + 2 + 4, 1 + 2 + 4 + 8]
    warnings = [message for category, message in messages if category == "logStatusWarning"]
    assert [w.split(" ")[0] for w in warnings] == ["p_P", "q", "p_B", "T"]  # each once
    assert "outside the tables'" in warnings[0] and "bar" in warnings[0]


@pytest.mark.pipeline
def test_the_tables_files_say_what_they_hold(exported):
    from scipy.io import loadmat

    manifest = json.loads((exported / "manifest.json").read_text())
    edges = pd.read_csv(exported / "edges.csv")
    assert list(edges.columns) == ["q_lpm", "p_B_bar", "p_P_bar", "temperature_C", "u_open_mm",
                                   "u_close_mm", "dp_open_bar", "dp_close_bar"]
    shape = manifest["tables"]["u_open"]["shape"]
    assert len(edges) == np.prod(shape)
    assert np.all(edges.u_open_mm <= edges.u_close_mm + 1e-9)  # friction: opening needs more
    mat = loadmat(exported / "valve_tables.mat")
    assert list(mat["dp_open"].shape) == shape
    np.testing.assert_allclose(mat["dp_open"].ravel(), edges.dp_open_bar, rtol=1e-9)
    np.testing.assert_allclose(mat["u_open_q"].ravel(), np.unique(edges.q_lpm), rtol=1e-9)
    ranges = manifest["grid"]["ranges"]
    assert ranges["q"][0] == pytest.approx(edges.q_lpm.min(), rel=1e-6)
    assert ranges["p_P"][1] == pytest.approx(edges.p_P_bar.max(), rel=1e-6)
    for name in ("edges.csv", "dp.csv", "valve_tables.mat"):
        assert name in manifest["files"]
    with zipfile.ZipFile(exported / "cfda.fmu") as fmu:
        names = fmu.namelist()
        inside = json.loads(fmu.read("resources/manifest.json"))
    assert {"modelDescription.xml", "sources/fmu_valve.c", "resources/tables.bin",
            "binaries/linux64/cfda.so"} <= set(names)
    assert inside["left_out"] == {} and inside["grid"] == manifest["grid"]


@pytest.mark.pipeline
def test_a_source_only_fmu_without_a_compiler_leaving_out_the_sensor_terms(tmp_path,
                                                                            monkeypatch, capsys):
    model = tmp_path / "with_sensor.toml"
    model.write_text(_with_sensor_term())
    monkeypatch.setenv("PATH", str(tmp_path))  # no compiler on it
    monkeypatch.delenv("CC", raising=False)
    out = tmp_path / "out"
    assert main(["export", "--model", str(model), "--format", "fmu", "--out", str(out),
                 "--grid-scale", "0.25", "--tolerance", "50"]) == 0
    captured = capsys.readouterr()
    assert "source-only" in captured.err and "no C compiler" in captured.err
    (fmu,) = out.glob("*.fmu")
    with zipfile.ZipFile(fmu) as archive:
        names = archive.namelist()
        inside = json.loads(archive.read("resources/manifest.json"))
    assert "sources/fmu_valve.c" in names
    assert not any(name.startswith("binaries/") for name in names)
    assert list(inside["left_out"]) == ["pilot_transducer_offset"]
    assert "sensor" in inside["left_out"]["pilot_transducer_offset"]


def _with_sensor_term() -> str:
    from surrogate.effects import LIBRARY
    from surrogate.description.presets import preset
    from surrogate.description.spec import EffectSpec

    return preset("cfda").adding(EffectSpec.start(LIBRARY["pilot_transducer_offset"],
                                                  delta=0.5), name="cfda+offset").to_toml()


@pytest.mark.pipeline
def test_the_steady_characteristic(tmp_path):
    out = tmp_path / "steady"
    assert main(["steady", "--model", "cfda", "--p-P-bar", "65", "--p-B-bar", "5",
                 "--temperature-C", "40", "--points", "12", "--out", str(out), "--quiet"]) == 0
    frame = pd.read_csv(out / "steady.csv")
    document = json.loads((out / "steady.json").read_text())
    up, down = frame[frame.branch == "up"], frame[frame.branch == "down"]
    assert len(up) == len(down) == 12 and set(frame.status) == {"ok"}
    # friction holds the piston back going up: more pressure at every flow
    assert np.all(up.dp_bar.to_numpy() > down.dp_bar.to_numpy())
    np.testing.assert_allclose(document["branches"]["up"]["dp_bar"], up.dp_bar, rtol=1e-5)
    assert document["p_P_bar"] == 65 and (out / "steady.png").read_bytes()[:4] == b"\x89PNG"
    # the set point, as logs and reports give it: p_P = p_Pe + p_B, the same curve
    by_set_point = tmp_path / "by_set_point"
    assert main(["steady", "--model", "cfda", "--p-Pe-bar", "60", "--p-B-bar", "5",
                 "--temperature-C", "40", "--points", "12", "--out", str(by_set_point),
                 "--quiet"]) == 0
    again = json.loads((by_set_point / "steady.json").read_text())
    assert again["p_P_bar"] == 65 and again["p_Pe_bar"] == 60
    pd.testing.assert_frame_equal(pd.read_csv(by_set_point / "steady.csv"), frame)


def test_interpolation_is_exact_for_quadratics_and_at_the_nodes():
    nodes = [np.linspace(0, 1, 7), np.linspace(-2, 3, 5)]
    x, y = np.meshgrid(*nodes, indexing="ij")
    values = 3 * x ** 2 - x * y + 0.5 * y ** 2 + 1
    at = [np.random.default_rng(1).uniform(0.17, 0.83, 50),
          np.random.default_rng(2).uniform(-0.75, 1.75, 50)]  # inner cells
    np.testing.assert_allclose(interpolate(nodes, values, at),
                               3 * at[0] ** 2 - at[0] * at[1] + 0.5 * at[1] ** 2 + 1, rtol=1e-12)
    np.testing.assert_allclose(interpolate(nodes, values, [x.ravel(), y.ravel()]),
                               values.ravel(), rtol=1e-12)
    linear = interpolate(nodes, values, at, cubic=False)
    assert not np.allclose(linear, 3 * at[0] ** 2 - at[0] * at[1] + 0.5 * at[1] ** 2 + 1)


@custom_effect("force", units={"k": "N"})
def batch_mean_force(state, k=1.0):
    """A force that reads its whole batch."""
    return k * state.p_L / np.mean(state.p_L)


@custom_effect("force", units={"k": "N"})
def elementwise_force(state, k=1.0):
    """A force of the state alone."""
    return k * state.p_L / 1e7


@pytest.mark.parametrize("effect, refused", [(batch_mean_force, True),
                                             (elementwise_force, False)])
def test_custom_terms_must_be_functions_of_the_state(effect, refused):
    model = load_model("cfda")
    model = model.with_effects([*model.effects, effect(k=2.0)])
    points = OperatingPoints.create(np.array([1e-4]), 7e6, 5e5, 313.15)
    grid = TableGrid.around(points)
    if refused:
        with pytest.raises(InputError, match="batch_mean_force.*cannot be tabulated"):
            refuse_untabulable(model, grid, "model.toml")
    else:
        refuse_untabulable(model, grid, "model.toml")


@custom_effect("friction", units={"k": "N"})
def friction_step_below_30C(state, k=10.0):
    """A friction that rises by k within a few kelvin below 30 degC."""
    return k / (1.0 + np.exp((state.temperature - 303.15) / 1.0))


def test_the_grid_is_refined_only_where_the_valve_changes_quickly():
    """A friction stepping up within a few kelvin near 30 degC: the even grid (5-6 K apart) misses the
    solver between its temperature nodes; the refinement inserts temperature nodes there and
    nowhere else along T until every cell's middle meets the tolerance (grid maps' kinks at
    the sampled openings may ask for flow nodes too)."""
    model = load_model("cfda")
    model = valve_physics(model.with_effects([*model.effects, friction_step_below_30C()])).model
    grid = TableGrid((2 / 60_000, 10 / 60_000), (4e5, 6e5), (60e5, 70e5), (278.15, 328.15))
    tolerance = 0.1e5
    refined = refined_grid(model, grid, tolerance)
    inserted = dict(refined.grid.inserted)
    # a cubic's stencil spans two cells either side: the step spoils those and no others
    assert np.all(np.abs(np.array(inserted["temperature"]) - 303.15) < 2.5 * 6.0)
    assert refined.met and refined.rounds >= 1
    assert max(refined.worst.values()) <= tolerance
    even = refined_grid(model, grid, np.inf)  # no refinement: the even grid's own misses
    assert even.rounds == 0 and even.worst["temperature"] > 3 * tolerance
