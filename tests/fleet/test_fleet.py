"""The fleet command: many valves' logs, a bad one among them, resuming, a real Dask cluster, and
the population's robust statistics."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from surrogate.cli import main
from surrogate.fleet.population import (
    robust_outliers,
    robust_spread,
    spread_floors,
    summary,
)
from surrogate.core.paths import PROJECT_ROOT, SHIPPED_BENCH_LOG, SHIPPED_CFD_SAMPLES

#: every n-th sample of the shipped test sequence: ~700 samples, a fit of a second or two
EVERY = 16
#: what two results of the same valve must agree in
RESULT_KEYS = ("status", "samples", "runs", "rms_bar", "heldout_rms_bar", "noise_floor_bar",
               "parameters", "log_sha256", "model_sha256")
BAD = "V9"  # the serial of the refused log


@pytest.fixture(scope="module")
def sequence():
    from surrogate.data import load_bench_log
    from surrogate.synthetic.simulate import noise_free_sequence

    return noise_free_sequence(load_bench_log(SHIPPED_BENCH_LOG), every=EVERY)


@pytest.fixture(scope="module")
def samples():
    from surrogate.data import load_cfd_samples

    return load_cfd_samples(SHIPPED_CFD_SAMPLES)


def write_valves(folder: Path, valves, sequence, samples) -> None:
    from surrogate.data.writer import write_bench_log
    from surrogate.synthetic.batch import virtual_log

    folder.mkdir(parents=True, exist_ok=True)
    for valve in valves:
        write_bench_log(virtual_log(valve, sequence, samples), folder / f"{valve.serial}.csv")


@pytest.fixture(scope="module")
def logs(tmp_path_factory, sequence, samples) -> Path:
    """Three virtual valves' logs (V1 to V3, no fault) and a refused one: a copy of V1's with
    the flow of its line 5 broken."""
    from surrogate.synthetic.batch import draw_fleet

    folder = tmp_path_factory.mktemp("fleet") / "logs"
    write_valves(folder, draw_fleet(3, seed=11, fault_share=0.0), sequence, samples)
    lines = (folder / "V1.csv").read_text().splitlines()
    cells = lines[4].split(",")
    cells[lines[0].split(",").index("q_lpm")] = "abc"
    lines[4] = ",".join(cells)
    (folder / f"{BAD}.csv").write_text("\n".join(lines) + "\n")
    return folder


def run_fleet(capsys, *argv: str) -> tuple[int, dict | None, str]:
    code = main(["fleet", *argv, "--json"])
    captured = capsys.readouterr()
    try:
        document = json.loads(captured.out)
    except ValueError:
        document = None
    return code, document, captured.err


@pytest.fixture(scope="module")
def local_run(logs, tmp_path_factory):
    """The fleet of ``logs`` on 2 local worker processes: (exit code, JSON, stderr, --out)."""
    out = tmp_path_factory.mktemp("local") / "out"
    # in its own process, as a user runs it (and a module's fixture has no capsys)
    done = subprocess.run([sys.executable, "-m", "surrogate", "fleet", "--data", str(logs),
                           "--model", "cfda", "--out", str(out), "--workers", "2", "--json"],
                          capture_output=True, text=True, cwd=PROJECT_ROOT, check=False,
                          env={**os.environ, "OMP_NUM_THREADS": "1"})
    return done.returncode, json.loads(done.stdout), done.stderr, out


def change_load_pressure(path: Path, line: int, by: float) -> None:
    """Add ``by`` bar to the load pressure of one line of a log."""
    lines = path.read_text().splitlines()
    cells = lines[line].split(",")
    column = lines[0].split(",").index("p_L_bar")
    cells[column] = f"{float(cells[column]) + by:.6f}"
    lines[line] = ",".join(cells)
    path.write_text("\n".join(lines) + "\n")


def local_run_logs(out: Path) -> Path:
    """The folder of the logs a fleet's results were made from."""
    return Path(next(iter(results(out).values()))["log"]).parent


def results(out: Path) -> dict[str, dict]:
    return {path.stem: json.loads(path.read_text()) for path in (out / "valves").glob("*.json")}


@pytest.mark.pipeline
@pytest.mark.slow  # a whole fleet command: seconds
def test_a_bad_log_is_recorded_with_its_located_error_and_the_others_are_written(local_run):
    code, document, err, out = local_run
    assert code == 3, err
    found = results(out)
    assert sorted(found) == ["V1", "V2", "V3", BAD]
    failed = pd.read_csv(out / "failed.csv")
    assert failed["serial"].tolist() == [BAD]
    message = failed["message"].iloc[0]
    assert f"{BAD}.csv, line 5, column 'q_lpm'" in message and "'abc'" in message
    assert found[BAD]["status"] == "failed" and found[BAD]["error"]["kind"] == "bad input"
    assert found[BAD]["error"]["problems"][0]["line"] == 5
    assert [f["serial"] for f in document["failed"]] == [BAD]
    assert f"{BAD}: FAILED (bad input)" in err and "line 5, column 'q_lpm'" in err
    for serial in ("V1", "V2", "V3"):
        record = found[serial]
        assert record["status"] == "ok"
        assert record["rms_bar"] >= record["noise_floor_bar"] > 0
        assert record["heldout_rms_bar"] >= 0.9 * record["rms_bar"]
        k1 = record["parameters"]["friction_constant.K1"]
        assert k1["unit"] == "N" and k1["stderr"] > 0 and 0 < k1["value"] < 30
    table = pd.read_csv(out / "valves.csv")
    assert table["serial"].tolist() == ["V1", "V2", "V3"]
    assert {"friction_constant.K1 [N]", "friction_constant.K1 stderr [N]", "rms [bar]",
            "heldout rms [bar]", "noise floor [bar]"} <= set(table.columns)
    parquet = pd.read_parquet(out / "valves.parquet")
    assert parquet["serial"].tolist() == table["serial"].tolist()
    np.testing.assert_allclose(parquet["rms [bar]"], table["rms [bar]"])
    population = json.loads((out / "population.json").read_text())
    k1s = table["friction_constant.K1 [N]"]
    assert population["figures"]["friction_constant.K1 [N]"]["median"] == pytest.approx(
        k1s.median())
    assert population["failed"] == 1 and population["valves"] == 3
    assert (out / "outliers.csv").exists()
    report = (out / "report.html").read_text()
    assert "data:image/png;base64," in report and BAD in report
    # every valve named in a table of its own, with its RMS
    valves = report[report.index("<h2 id=\"section-1\">Valves</h2>"):]
    valves = valves[:valves.index("</table>")]
    assert all(f">{serial}<" in valves for serial in ("V1", "V2", "V3"))
    assert "rms [bar]" in valves
    assert not [path for path in out.rglob(".*")], "a temporary file stayed behind"


@pytest.mark.pipeline
@pytest.mark.slow  # a whole fleet command: seconds
def test_a_rerun_skips_finished_valves_and_redoes_a_missing_or_changed_one(local_run, logs,
                                                                           tmp_path, capsys):
    """Same logs and model: nothing is fitted again (the files are not touched). An interrupted
    run (a result missing) and a changed log are done again, the rest still skipped."""
    _, _, _, finished = local_run
    data, out = tmp_path / "logs", tmp_path / "out"
    shutil.copytree(logs, data)
    shutil.copytree(finished, out)  # keeps the files' times
    times = {path.name: path.stat().st_mtime_ns for path in (out / "valves").iterdir()}
    code, _, err = run_fleet(capsys, "--data", str(data), "--model", "cfda", "--out", str(out),
                             "--workers", "2")
    assert code == 3
    assert "4 done before with this log and model (skipped), 0 to fit" in err
    assert {p.name: p.stat().st_mtime_ns for p in (out / "valves").iterdir()} == times
    (out / "valves" / "V2.json").unlink()  # V2 was not finished when the batch stopped
    change_load_pressure(data / "V3.csv", line=-1, by=0.5)  # V3's log changed
    code, document, err = run_fleet(capsys, "--data", str(data), "--model", "cfda", "--out",
                                    str(out), "--workers", "2")
    assert code == 3
    assert "2 done before with this log and model (skipped), 2 to fit" in err
    now = {p.name: p.stat().st_mtime_ns for p in (out / "valves").iterdir()}
    assert now["V1.json"] == times["V1.json"] and now[f"{BAD}.json"] == times[f"{BAD}.json"]
    assert now["V3.json"] != times["V3.json"] and "V2.json" in now
    assert results(out)["V2"]["parameters"] == results(finished)["V2"]["parameters"]
    assert document["fitted"] == 3
    # a record edited by hand is not read into the tables: the valve is done again, and said so
    edited = json.loads((out / "valves" / "V1.json").read_text())
    (out / "valves" / "V1.json").write_text(json.dumps(edited | {"parameters": [1, 2]}))
    code, document, err = run_fleet(capsys, "--data", str(data), "--model", "cfda", "--out",
                                    str(out), "--workers", "2")
    assert code == 3 and "V1.json: not a record as this version writes them" in err
    assert "3 done before with this log and model (skipped), 1 to fit" in err
    assert results(out)["V1"]["parameters"] == results(finished)["V1"]["parameters"]


@pytest.mark.pipeline
@pytest.mark.slow  # a whole fleet command: seconds
def test_without_the_fleet_extra_it_runs_locally_and_says_parquet_is_missing(local_run, tmp_path,
                                                                             monkeypatch, capsys):
    """No Dask and no pyarrow: the fleet runs on the local pool (here every valve is already
    done), valves.csv is written, valves.parquet is not, and one note says why."""
    _, _, _, finished = local_run
    out = tmp_path / "out"
    shutil.copytree(finished, out)
    (out / "valves.parquet").unlink()
    for name in ("dask", "distributed", "pyarrow"):
        monkeypatch.setitem(sys.modules, name, None)  # importing them now fails
    code, document, err = run_fleet(capsys, "--data", str(local_run_logs(finished)), "--model",
                                    "cfda", "--out", str(out), "--quiet")
    assert code == 3
    assert err.count("pyarrow is not installed") == 1 and ".[fleet]" in err
    assert not (out / "valves.parquet").exists() and (out / "valves.csv").exists()
    assert "valves.parquet" not in document["files"]


def test_importing_the_package_and_its_command_line_does_not_import_dask():
    code = ("import sys, surrogate.cli, surrogate.fleet.runner; "
            "assert not {'dask', 'distributed'} & set(sys.modules), 'dask imported'")
    subprocess.run([sys.executable, "-c", code], check=True, cwd=PROJECT_ROOT)


@pytest.mark.pipeline
@pytest.mark.slow  # a whole fleet command: seconds
def test_a_local_cluster_gives_the_same_results_as_the_local_pool(local_run, logs, tmp_path,
                                                                  capsys):
    distributed = pytest.importorskip("distributed")
    _, _, _, local = local_run
    out = tmp_path / "out"
    kept = dict(os.environ)  # Dask's nanny writes its workers' variables into ours
    try:
        with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                      dashboard_address=None) as cluster:
            code, _, err = run_fleet(capsys, "--data", str(logs), "--model", "cfda", "--out",
                                     str(out), "--scheduler", cluster.scheduler_address)
    finally:
        os.environ.clear()
        os.environ.update(kept)
    assert code == 3, err
    assert "on the Dask scheduler at tcp://" in err
    on_cluster, on_pool = results(out), results(local)
    assert sorted(on_cluster) == sorted(on_pool)
    for serial, record in on_pool.items():
        assert {k: on_cluster[serial].get(k) for k in RESULT_KEYS} == \
            {k: record.get(k) for k in RESULT_KEYS}, serial
    pool_workers = {r["worker"] for r in on_pool.values()}
    assert not pool_workers & {r["worker"] for r in on_cluster.values()}  # other processes


@pytest.mark.slow  # a whole fleet command: seconds
def test_an_interrupted_batch_leaves_whole_files_and_resumes(logs, tmp_path):
    """Ctrl-C once the first valve is written: exit 130, every written result whole, no
    temporary file; the rerun fits only what was missing."""
    out = tmp_path / "out"
    command = [sys.executable, "-m", "surrogate", "fleet", "--data", str(logs), "--model",
               "cfda", "--out", str(out), "--workers", "1"]
    process = subprocess.Popen(command, cwd=PROJECT_ROOT, stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True,
                               env={**os.environ, "OMP_NUM_THREADS": "1"})
    deadline = time.monotonic() + 120
    while not list((out / "valves").glob("*.json")) and time.monotonic() < deadline:
        time.sleep(0.05)
    process.send_signal(signal.SIGINT)
    _, err = process.communicate(timeout=60)
    assert process.returncode == 130, err
    assert "the same command resumes" in err
    written = list((out / "valves").glob("*.json"))
    assert 1 <= len(written) < 4
    for path in written:
        assert json.loads(path.read_text())["serial"] == path.stem
    assert not [path.name for path in (out / "valves").iterdir() if path.name.startswith(".")]
    assert not (out / "valves.csv").exists()  # the population is written at the end only
    done = subprocess.run(command + ["--quiet"], cwd=PROJECT_ROOT, capture_output=True,
                          text=True, check=False, env={**os.environ, "OMP_NUM_THREADS": "1"})
    assert done.returncode == 3
    assert len(list((out / "valves").glob("*.json"))) == 4
    assert (out / "valves.csv").exists()


@pytest.mark.pipeline
@pytest.mark.slow  # a whole fleet command: seconds
def test_diagnose_records_the_top_candidate_of_a_faulty_valve(sequence, samples, tmp_path,
                                                              capsys):
    from surrogate.synthetic.batch import VirtualValve

    valve = VirtualValve("S1", K1=6.3, K2=0.08, preload=226.0, spring_rate=114.0,
                         flow_force_scale=0.83, fault="friction_seal_pressure",
                         fault_values={"K_LP": 0.08}, seed=5)
    write_valves(tmp_path / "logs", [valve], sequence, samples)
    code, document, err = run_fleet(capsys, "--data", str(tmp_path / "logs"), "--model", "cfda",
                                    "--out", str(tmp_path / "out"), "--diagnose",
                                    "--workers", "1")
    assert code == 0, err
    record = results(tmp_path / "out")["S1"]
    top = record["diagnosis"]["top_candidate"]
    assert top["name"] == "friction_seal_pressure" and top["category"] == "physics"
    assert top["significant"] and top["delta_bic"] < -10
    assert "friction_seal_pressure" in top["summary"]
    assert record["diagnosis"]["finding"]["name"] == "friction_seal_pressure"
    assert "S1: rms" in err and "finding: friction_seal_pressure" in err
    table = pd.read_csv(tmp_path / "out" / "valves.csv")
    assert table.loc[0, "top candidate"] == "friction_seal_pressure"
    assert document["population"]["findings"] == {"friction_seal_pressure": 1}


def test_an_earlier_result_stands_only_for_the_same_log_model_and_work():
    from surrogate.fleet.results import still_stands, task_identity
    from surrogate.fleet.tasks import ValveTask

    task = ValveTask("V1", "/logs/V1.csv", "log-hash", "[model]", "model-hash", "cfda")
    done = {**task_identity(task), "status": "ok"}
    assert still_stands(done, task)
    assert not still_stands(None, task)
    assert not still_stands({**done, "log_sha256": "changed"}, task)
    assert not still_stands({**done, "model_sha256": "changed"}, task)
    assert still_stands({**done, "log": "/moved/V1.csv"}, task)  # the same bytes elsewhere
    diagnosing = ValveTask(*[getattr(task, f) for f in ("serial", "log", "log_sha256",
                                                        "model_toml", "model_sha256",
                                                        "model_label")], diagnose=True)
    assert not still_stands(done, diagnosing)  # fitted, but not diagnosed
    assert still_stands({**done, "diagnose": True}, task)  # diagnosed serves a plain fit
    refused = {**done, "status": "failed", "error": {"kind": "bad input", "message": "..."}}
    assert still_stands(refused, task)  # the same log is refused again: not redone
    crashed = {**refused, "error": {"kind": "internal error", "message": "..."}}
    assert not still_stands(crashed, task)  # worth another try
    assert not still_stands({**done, "format": 0}, task)


# --- the command line's own mistakes: exit 2, nothing written -------------------------------------

@pytest.mark.pipeline
@pytest.mark.parametrize("case", ["empty folder", "no match", "unknown model", "out in data",
                                  "workers and scheduler"])
def test_command_line_mistakes_exit_2_and_write_nothing(case, logs, tmp_path, capsys):
    out = tmp_path / "out"
    empty = tmp_path / "empty"
    empty.mkdir()
    argv, expected = {
        "empty folder": (["--data", str(empty), "--model", "cfda", "--out", str(out)],
                         "holds no bench log"),
        "no match": (["--data", str(tmp_path / "nothing" / "*.csv"), "--model", "cfda",
                      "--out", str(out)], "matches no file"),
        "unknown model": (["--data", str(logs), "--model", "cfdx", "--out", str(out)],
                          "unknown model 'cfdx'"),
        "out in data": (["--data", str(logs), "--model", "cfda", "--out", str(logs / "out")],
                        "lies inside the input folder"),
        "workers and scheduler": (["--data", str(logs), "--model", "cfda", "--out", str(out),
                                   "--workers", "2", "--scheduler", "tcp://127.0.0.1:1"],
                                  "--workers 2 is for the local pool"),
    }[case]
    before = sorted(path.name for path in logs.iterdir())
    code, document, err = run_fleet(capsys, *argv)
    assert code == 2
    assert expected in err and "Traceback" not in err
    assert document["error"]["exit_code"] == 2
    assert not out.exists() and not (logs / "out").exists()
    assert sorted(path.name for path in logs.iterdir()) == before


@pytest.mark.pipeline
def test_a_scheduler_without_dask_names_the_extra(logs, tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "distributed", None)  # as if Dask were not installed
    monkeypatch.setenv("CBV_SCHEDULER", "tcp://127.0.0.1:1")
    code, _, err = run_fleet(capsys, "--data", str(logs), "--model", "cfda", "--out",
                             str(tmp_path / "out"))
    assert code == 2
    assert "$CBV_SCHEDULER tcp://127.0.0.1:1" in err and ".[fleet]" in err
    assert not (tmp_path / "out" / "valves").exists()


@pytest.mark.pipeline
def test_the_environment_scheduler_conflicts_with_workers(logs, tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("CBV_SCHEDULER", "tcp://127.0.0.1:1")
    code, _, err = run_fleet(capsys, "--data", str(logs), "--model", "cfda", "--out",
                             str(tmp_path / "out"), "--workers", "1")
    assert code == 2 and "unset CBV_SCHEDULER" in err


# --- the population's statistics ------------------------------------------------------------------

def gaussian_fleet(count: int, seed: int) -> pd.DataFrame:
    """A clean fleet of four correlated figures: K1 and K2 correlated (+0.8), the preload and
    the flow-force scale anticorrelated (-0.5), in their own units."""
    correlation = np.array([[1, .8, 0, 0], [.8, 1, 0, 0], [0, 0, 1, -.5], [0, 0, -.5, 1]])
    scale = np.array([1.0, 0.004, 5.0, 0.015])
    draws = np.random.default_rng(seed).multivariate_normal(
        [6.3, 0.08, 226.0, 0.83], correlation * np.outer(scale, scale), size=count)
    return pd.DataFrame(draws, columns=["K1", "K2", "preload", "scale"],
                        index=[f"V{i:03d}" for i in range(count)])


def test_a_clean_gaussian_fleet_of_50_has_no_false_flags():
    frame = gaussian_fleet(50, seed=0)
    assert robust_outliers(frame, list(frame.columns)).outliers == []
    # and over many such fleets the share of false flags stays near the nominal 0.1 %
    flags = sum(len(robust_outliers(fleet, list(fleet.columns)).outliers)
                for fleet in (gaussian_fleet(50, seed) for seed in range(1, 41)))
    assert flags / (40 * 50) <= 0.01


@pytest.mark.parametrize("count", [25, 200])  # median/MAD scores, and the MCD
def test_a_planted_outlier_is_flagged_and_its_parameter_named(count):
    frame = gaussian_fleet(count, seed=3)
    frame.loc["V002", "K2"] = frame["K2"].median() + 8 * robust_spread(frame["K2"])
    analysis = robust_outliers(frame, list(frame.columns))
    assert analysis.method == ("minimum covariance determinant" if count == 200
                               else "median/MAD scores with rank correlations")
    flagged = {o.serial: o for o in analysis.outliers}
    assert "V002" in flagged
    named = flagged["V002"].standing_out
    assert named[0][0] == "K2" and named[0][1] > 5
    assert len(flagged) <= 1 + count // 100  # no more than chance would add


def test_an_outlier_only_against_the_correlation_is_flagged():
    """K1 and K2 each 3σ off, in opposite directions: neither is unusual alone, but together
    they break the fleet's +0.8 correlation; the MCD's distance sees it."""
    frame = gaussian_fleet(200, seed=4)
    frame.loc["V007", ["K1", "K2"]] = [6.3 + 3 * 1.0, 0.08 - 3 * 0.004]
    analysis = robust_outliers(frame, list(frame.columns))
    named = dict(next(o for o in analysis.outliers if o.serial == "V007").standing_out)
    assert set(named) & {"K1", "K2"}


def test_a_parameter_piled_on_its_bound_is_judged_by_its_standard_error():
    """A leakage of zero in most valves (no scatter: MAD 0) and one valve leaking nine standard
    errors: the spread is the typical standard error, the leaking valve stands out by it, and the
    valves a hair off zero do not."""
    frame = gaussian_fleet(100, seed=5)
    frame["G"] = np.r_[np.zeros(90), np.full(9, 1e-8), [0.0027]]
    frame["G stderr"] = np.r_[np.full(90, np.nan), np.full(10, 0.0003)]
    floors = spread_floors(frame, {"G": "G stderr"})
    assert floors["G"] == pytest.approx(0.0003)
    columns = ["K1", "K2", "preload", "scale", "G"]
    stats = summary(frame, columns, floors)
    assert stats["G"]["robust_spread"] == 0 and stats["G"]["spread_used"] == pytest.approx(0.0003)
    analysis = robust_outliers(frame, columns, floors)
    flagged = {o.serial: dict(o.standing_out) for o in analysis.outliers}
    assert flagged["V099"]["G"] == pytest.approx(9.0)
    assert len(flagged) <= 2


def test_too_few_valves_flag_none():
    frame = gaussian_fleet(5, seed=6)
    analysis = robust_outliers(frame, list(frame.columns))
    assert analysis.method == "none" and analysis.outliers == []


def test_the_fleet_reports_legends_stay_readable_on_a_narrow_page():
    """The histograms and the outliers' Δp(q) against the median valve, shrunk to a page
    1,000 px wide: every legend's text stays 10 px high (the workflow report's rule)."""
    from surrogate.fleet.report import curves_figure, histograms_figure
    from surrogate.description.modelfile import load_model
    from surrogate.reporting.figures import DPI

    rng = np.random.default_rng(3)
    table = pd.DataFrame({"serial": [f"V{i:03d}" for i in range(30)],
                          "friction_constant.K1 [N]": rng.normal(6.0, 1.0, 30),
                          "rms [bar]": rng.normal(1.0, 0.05, 30),
                          "friction_load_pressure.K2 [N/bar]": rng.normal(0.08, 0.005, 30)})
    model = load_model("bmbe")
    key = "friction_constant.K1"
    median = {key: 6.0}
    outliers = [(f"V{i:03d}", {key: 6.0 + 2.0 * i}) for i in range(5)]
    condition = {"q_max_lpm": 10.0, "p_Pe_bar": 70.0, "p_B_bar": 3.0, "temperature_C": 40.0}
    figures = {"histograms": histograms_figure(table, list(table.columns[1:]), {"V001"}),
               "curves": curves_figure(model, median, outliers, condition)}
    small = {}
    for name, figure in figures.items():
        shown = min(1.0, (1000 - 2 * 16) / (figure.get_figwidth() * DPI))
        legends = [*figure.legends, *(ax.get_legend() for ax in figure.axes)]
        assert any(legends), name
        for legend in filter(None, legends):
            for text in legend.get_texts():
                pixels = text.get_fontsize() * DPI / 72 * shown
                if pixels < 10.0:
                    small[name] = round(pixels, 1)
    assert not small, small


def test_a_small_fleets_figures_name_every_valve():
    """Three valves make no histogram: each is a dot named by its serial, in the figures'
    panels and in the pair plot, the outlier among them."""
    from surrogate.fleet.report import histograms_figure, pair_figure

    table = pd.DataFrame({"serial": ["SN1", "SN2", "SN3"], "K1 [N]": [5.1, 6.0, 4.9],
                          "K2 [N/bar]": [0.0512, 0.0634, 0.0498]})
    columns = list(table.columns[1:])
    for figure in (histograms_figure(table, columns, {"SN2"}),
                   pair_figure(table, columns, {"SN2"})):
        texts = {label.get_text() for ax in figure.axes for label in ax.get_yticklabels()}
        texts |= {text.get_text() for ax in figure.axes for text in ax.texts}
        assert {"SN1", "SN2", "SN3"} <= texts
        assert not any(patch.get_height() > 0 for ax in figure.axes for patch in ax.patches)
