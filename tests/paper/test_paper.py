"""The paper's comparison on the shipped data, and the ``paper`` command's contract."""

import contextlib
import io
import json

import numpy as np
import pandas as pd
import pytest

from surrogate.cli import main
from surrogate.data.loaders import BenchRun
from surrogate.core.outputs import atomic_directory
from surrogate.paper.comparison import category
from surrogate.paper.median import median_line
from surrogate.core.paths import SHIPPED_CFD_SAMPLES


@pytest.fixture(scope="module")
def paper_run(tmp_path_factory):
    """``paper --maps grid --json --out DIR`` run once: (exit code, JSON, output folder)."""
    out = tmp_path_factory.mktemp("paper")
    stdout, stderr = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
        code = main(["paper", "--maps", "grid", "--json", "--out", str(out)])
    return code, json.loads(stdout.getvalue()), out, stderr.getvalue()


def _cell_means(document) -> dict[str, float]:
    frame = pd.DataFrame(document["table5"])
    return frame.groupby("model")["mean_abs_bar"].mean().to_dict()


@pytest.mark.pipeline
@pytest.mark.slow
def test_paper_command_succeeds_and_reports_progress(paper_run):
    code, _, _, stderr = paper_run
    assert code == 0
    assert "Table 6" in stderr  # progress is shown while it works


@pytest.mark.pipeline
@pytest.mark.slow
def test_cfda_beats_best_fit_beats_basic_effort_on_average(paper_run):
    means = _cell_means(paper_run[1])
    assert means["CFDA"] < means["BMBEBF"] < means["BMBE"], means


@pytest.mark.pipeline
@pytest.mark.slow
def test_cfda_is_within_5_bar_in_most_cells(paper_run):
    cfda = [r for r in paper_run[1]["table5"] if r["model"] == "CFDA"]
    assert len(cfda) == 9
    assert sum(r["mean_abs_bar"] < 5.0 for r in cfda) >= 5


@pytest.mark.pipeline
@pytest.mark.slow
def test_json_contract(paper_run):
    document = paper_run[1]
    assert {"model", "p_Pe_bar", "temperature_C", "mean_abs_bar"} <= set(document["table5"][0])
    assert {(r["model"], r["p_Pe_bar"], r["temperature_C"]) for r in document["table5"]} == {
        (m, p, t) for m in ("BMBE", "BMBEBF", "CFDA") for p in (50, 65, 80) for t in (20, 40, 60)}
    assert {"temperature_C", "fitted_on_p_Pe_bar", "K1_N", "K2_N_per_bar"} <= set(
        document["table6"][0])
    assert {(r["temperature_C"], r["fitted_on_p_Pe_bar"]) for r in document["table6"]} == {
        (t, p) for t in (20, 40, 60) for p in (65, 50)}


@pytest.mark.pipeline
@pytest.mark.slow
def test_the_papers_flow_force_scale_is_the_back_pressure_its_maps_left_out(paper_run, tmp_path):
    """The paper needed a flow-force scale of 0.9; its maps ignore the back pressure (eq. 19).
    The grid with the cavitation law of the CFD's back-pressure set needs none, within 2 %; the
    same grid from the samples at 5 bar alone (no law to fit: the paper's maps) needs the
    paper's."""
    assert abs(paper_run[1]["fitted"]["CFDA_flow_force_scale"] - 1.0) < 0.02
    samples = pd.read_csv(SHIPPED_CFD_SAMPLES)
    at_five_bar = tmp_path / "cfd_at_5_bar.csv"
    samples[np.isclose(samples["p_B_bar"], 5.0)].to_csv(at_five_bar, index=False)
    stdout = io.StringIO()
    with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(io.StringIO()):
        assert main(["paper", "--maps", "grid", "--cfd", str(at_five_bar), "--json"]) == 0
    assert 0.85 < json.loads(stdout.getvalue())["fitted"]["CFDA_flow_force_scale"] < 0.92


@pytest.mark.pipeline
@pytest.mark.slow
def test_friction_grows_as_the_oil_cools(paper_run):
    """Table 6's finding: more hysteresis at lower temperature (friction at p_L = 80 bar)."""
    fits = {r["temperature_C"]: r for r in paper_run[1]["table6"] if r["fitted_on_p_Pe_bar"] == 65}
    friction = [fits[t]["K1_N"] + 80 * fits[t]["K2_N_per_bar"] for t in (20, 40, 60)]
    assert friction[0] > friction[1] > friction[2], friction


@pytest.mark.pipeline
@pytest.mark.slow
def test_paper_files_are_written(paper_run):
    out = paper_run[2]
    names = {path.name for path in out.iterdir()}
    assert {"table5.csv", "table5.md", "table6.csv", "table6.md", "paper.json"} <= names
    assert len([n for n in names if n.endswith(".png")]) == 6
    assert json.loads((out / "paper.json").read_text())["table5"] == paper_run[1]["table5"]
    markdown = (out / "table5.md").read_text()
    assert all(model in markdown for model in ("BMBE", "BMBEBF", "CFDA"))


@pytest.mark.pipeline
def test_paper_command_rejects_a_log_without_the_papers_runs(tmp_path, bench_lines, capsys):
    path = tmp_path / "one_run.csv"
    path.write_text("\n".join(bench_lines) + "\n")
    assert main(["paper", "--data", str(path), "--json"]) == 2
    assert "no run at p_Pe" in capsys.readouterr().err


def test_median_line_averages_up_and_down_medians():
    rng = np.random.default_rng(0)
    bins = np.repeat(np.arange(22), 10)  # 10 samples in each 0.5 L/min bin from 1 to 12 L/min
    q = (1.0 + 0.5 * (bins + rng.uniform(0.05, 0.95, bins.size))) / 60000
    true = 40e5 + 5e5 * q / q.max()
    frames = []
    for direction, offset in (("up", +6e5), ("down", -6e5)):
        frames.append(pd.DataFrame({
            "q": q, "p_B": 3e5, "p_L": 3e5 + true + offset + rng.normal(0, 1e4, q.size),
            "p_P": 70e5, "temperature": 313.15, "direction": direction}))
    line = median_line(BenchRun("synthetic", pd.concat(frames, ignore_index=True)))
    expected = 40e5 + 5e5 * line["q"] / q.max()
    assert len(line) == 22
    np.testing.assert_allclose(line["dp"], expected, atol=2e4)
    np.testing.assert_allclose(line["dp_up"] - line["dp_down"], 12e5, atol=2e4)


@pytest.mark.parametrize("distance, expected", [(4.99, "++"), (5.0, "+"), (15.0, "+"),
                                                (15.01, "-")])
def test_accuracy_categories(distance, expected):
    assert category(distance) == expected


def test_failed_command_leaves_no_half_written_output(tmp_path):
    target = tmp_path / "results"
    target.mkdir()
    (target / "keep.txt").write_text("from before")
    with pytest.raises(RuntimeError):
        with atomic_directory(target) as staging:
            (staging / "table5.csv").write_text("partial")
            raise RuntimeError("figure failed")
    assert [p.name for p in target.iterdir()] == ["keep.txt"]
    assert [p.name for p in tmp_path.iterdir()] == ["results"]  # no staging folder left behind
