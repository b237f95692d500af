"""The workbench commands' contracts (JSON keys, files written, exit codes) on a small log."""

from __future__ import annotations

import json
import tomllib

import pandas as pd
import pytest

from surrogate.cli import main
from surrogate.description.modelfile import load_model, save_model


@pytest.fixture(scope="module")
def viscous_log(tmp_path_factory):
    """A synthetic log with friction growing with viscosity hidden (every 12th sample)."""
    folder = tmp_path_factory.mktemp("logs")
    assert main(["simulate", "--hidden", "friction_viscous", "--every", "12", "--seed", "4",
                 "--out", str(folder), "--quiet"]) == 0
    return folder / "log.csv"


def run_json(capsys, argv):
    assert main(argv) == 0
    return json.loads(capsys.readouterr().out)


@pytest.mark.pipeline
def test_compare_json_contract(capsys, viscous_log, tmp_path):
    out = tmp_path / "compare"
    result = run_json(capsys, ["compare", "--model", "cfda", "--data", str(viscous_log),
                               "--out", str(out), "--json"])
    assert {"rms_bar", "noise_floor_bar", "runs"} <= set(result)
    assert len(result["runs"]) == 12
    for run in result["runs"]:
        assert {"run", "temperature_C", "p_Pe_bar", "rms_bar", "bias_bar"} <= set(run)
    assert result["rms_bar"] > result["noise_floor_bar"] > 0
    assert (out / "report.html").read_text().count("data:image/png;base64") >= 3
    # the maps' own uncertainty: a Δp standard deviation overall, per run and per sample, and
    # the share of samples outside the CFD samples per reason
    assert result["dp_std_bar"] > 0 and all(run["dp_std_bar"] > 0 for run in result["runs"])
    assert set(result["outside_samples"]) >= {"any", "opening in an unsampled gap"}
    samples = pd.read_csv(out / "samples.csv")
    assert len(samples) == sum(run["samples"] for run in result["runs"])
    assert (samples["dp_std_bar"] > 0).all()
    assert {"dp_model_bar", "dp_measured_bar", "outside_samples", "status"} <= set(samples)


@pytest.mark.pipeline
@pytest.mark.parametrize("kind", ["nn", "gp"])
def test_compare_on_learned_maps(capsys, viscous_log, kind):
    result = run_json(capsys, ["compare", "--model", "cfda", "--maps", kind, "--data",
                               str(viscous_log), "--json"])
    assert result["model"] == f"cfda ({kind} maps)"
    assert result["dp_std_bar"] > 0


@pytest.mark.pipeline
def test_diagnose_json_contract_names_the_hidden_effect(capsys, viscous_log):
    result = run_json(capsys, ["diagnose", "--model", "cfda", "--data", str(viscous_log), "--json"])
    assert {"rms_before_bar", "noise_floor_bar", "summary", "candidates"} <= set(result)
    best = result["candidates"][0]
    assert {"name", "description", "category", "rms_after_bar", "heldout_rms_bar", "inclusion",
            "delta_bic", "significant", "params"} <= set(best)
    assert best["name"] == "friction_viscous" and best["significant"]
    assert best["category"] == "physics"
    assert best["heldout_rms_bar"] < result["heldout_rms_bar"]  # it predicts unseen runs better
    assert best["inclusion"] > 0.5
    assert best["gains_in_own_view"]  # a friction narrowing the runs' hysteresis half-width
    assert "friction_viscous" in result["summary"]
    # ranked by ΔBIC against the maps' own error, best first; beside a library finding, the
    # shape-free terms that generalise it follow the library's candidates, never added
    library = [c for c in result["candidates"] if "shape" not in c]
    ranked = [c["delta_bic"] for c in library]
    assert ranked == sorted(ranked)
    shapes = [c for c in result["candidates"] if "shape" in c]
    assert result["candidates"][:len(library)] == library
    assert not any(c["significant"] for c in shapes)
    assert all(c["category"] in ("physics", "map correction", "sensor")
               for c in result["candidates"])


@pytest.mark.pipeline
def test_fit_writes_a_model_file_that_loads_and_compares(capsys, viscous_log, tmp_path):
    path = tmp_path / "fitted.toml"
    result = run_json(capsys, ["fit", "--model", "cfda", "--data", str(viscous_log),
                               "--add", "friction_viscous", "--out", str(path), "--json"])
    assert result["rms_bar"] < 1.3 * result["noise_floor_bar"]
    document = tomllib.loads(path.read_text())
    assert [e["name"] for e in document["effects"]][-1] == "friction_viscous"
    again = run_json(capsys, ["compare", "--model", str(path), "--data", str(viscous_log), "--json"])
    assert again["rms_bar"] == pytest.approx(result["rms_bar"], rel=1e-3)


@pytest.mark.pipeline
@pytest.mark.slow
def test_workflow_json_contract(capsys, viscous_log, tmp_path):
    out = tmp_path / "workflow"
    result = run_json(capsys, ["workflow", "--data", str(viscous_log), "--out", str(out),
                               "--maps", "grid", "--kinds", "--max-additions", "1", "--json"])
    steps = result["steps"]
    assert [s["model"] for s in steps[:4]] == ["bmbe", "bmbebf", "cfd-maps", "cfda"]
    assert all({"model", "added", "category", "rms_bar", "heldout_rms_bar"} <= set(s)
               for s in steps)
    assert [s["category"] for s in steps[:4]] == ["", "map correction", "map correction",
                                                  "physics"]
    assert steps[-1]["added"] == ["friction_viscous"] and steps[-1]["category"] == "physics"
    assert steps[-1]["rms_bar"] < steps[3]["rms_bar"] < steps[0]["rms_bar"]
    # the added effect predicts runs its fit did not see better; the held-out RMS is never
    # below the in-sample one
    assert steps[-1]["heldout_rms_bar"] < steps[3]["heldout_rms_bar"]
    assert all(s["heldout_rms_bar"] >= s["rms_bar"] - 1e-3 for s in steps)
    for name in ("report.html", "staircase.png", "staircase.csv", "final_model.toml",
                 "workflow.json"):
        assert (out / name).is_file()
    assert load_model(str(out / "final_model.toml")).has_effect("friction_viscous")
    # the summary opens with the three-line verdict
    assert set(result["verdict"]) == {"lacks", "where", "next"}
    assert result["summary"].splitlines()[0] == f"Lacks: {result['verdict']['lacks']}"


@pytest.mark.pipeline
@pytest.mark.slow
def test_workflow_shows_every_kinds_staircase_and_defaults_to_the_most_accurate(capsys,
                                                                               viscous_log,
                                                                               tmp_path):
    out = tmp_path / "workflow"
    result = run_json(capsys, ["workflow", "--data", str(viscous_log), "--out", str(out),
                               "--max-additions", "0", "--json"])
    scores = result["maps_flow_force_cv_error"]
    assert set(scores) == {"grid", "nn", "gp"}
    assert result["maps"] == min(scores, key=scores.get)
    assert set(result["other_kinds"]) == {"grid", "nn", "gp"} - {result["maps"]}
    for other in result["other_kinds"].values():
        assert [s["model"] for s in other["steps"][:4]] == ["bmbe", "bmbebf", "cfd-maps", "cfda"]
    report = (out / "report.html").read_text()
    assert "The staircase on every kind of map" in report
    # which kind to trust where the kinds' physics differ: the best on held-out runs
    compared = result["kinds_compared"]
    heldout = compared["heldout_rms_bar"]
    assert set(heldout) == {"grid", "nn", "gp"} and compared["trusted"] == min(heldout,
                                                                              key=heldout.get)
    assert "Where the kinds agree, where they differ, and what to trust" in report


@pytest.mark.pipeline
def test_workflow_writes_the_main_kinds_results_before_the_comparison_kinds(
        capsys, viscous_log, tmp_path, monkeypatch):
    """The main kind's results are on disk as soon as its staircase is done: a comparison kind
    that fails (an interruption, say) leaves them there."""
    import surrogate.commands.workflow as command

    real = command.run_workflow
    calls = []

    def main_then_stop(log, **options):
        calls.append(options["maps_spec"])
        if len(calls) > 1:
            raise KeyboardInterrupt
        return real(log, **options)

    monkeypatch.setattr(command, "run_workflow", main_then_stop)
    out = tmp_path / "workflow"
    try:
        code = main(["workflow", "--data", str(viscous_log), "--out", str(out), "--maps", "grid",
                     "--kinds", "grid", "nn", "--max-additions", "0", "--no-calibration"])
    except SystemExit as stop:
        code = stop.code
    assert code != 0 and len(calls) == 2
    document = json.loads((out / "workflow.json").read_text())
    assert document["maps"] == "grid" and document["other_kinds"] == {}
    for name in ("report.html", "staircase.csv", "final_model.toml"):
        assert (out / name).is_file()


def test_model_file_round_trip(tmp_path):
    model = load_model("cfda")
    model.effect("friction_constant").params["K1"].value = 7.25
    save_model(model, tmp_path / "m.toml")
    loaded = load_model(str(tmp_path / "m.toml"))
    assert [e.name for e in loaded.effects] == [e.name for e in model.effects]
    for a, b in zip(model.parameters().values(), loaded.parameters().values()):
        assert a.value == pytest.approx(b.value, rel=1e-12) and a.vary == b.vary


@pytest.mark.pipeline
@pytest.mark.parametrize("text, message", [
    ("[model]\nname = 'x'\n", "maps"),
    ("[model]\nmaps = { kind = 'grid' }\n[[effects]]\nname = 'no_such_effect'\n",
     "unknown effect"),
    ("[model]\nmaps = { kind = 'grid' }\n[[effects]]\nname = 'friction_constant'\n"
     "parameters = { K1 = { value = 5.0, unit = 'N/bar' } }\n", "is in N"),
    ("[model]\nmaps = { kind = 'grid' }\n[[effects]]\nname = 'friction_constant'\n"
     "parameters = { K1 = { value = -5.0, unit = 'N' } }\n", "outside"),
    ("not = [toml", "not a valid TOML"),
])
def test_bad_model_files_exit_2_with_a_message(capsys, viscous_log, tmp_path, text, message):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    assert main(["compare", "--model", str(path), "--data", str(viscous_log)]) == 2
    assert message in capsys.readouterr().err


@pytest.mark.pipeline
def test_unknown_preset_and_effect_exit_2(capsys, viscous_log, tmp_path):
    assert main(["compare", "--model", "nonsense", "--data", str(viscous_log)]) == 2
    assert "preset" in capsys.readouterr().err
    assert main(["fit", "--model", "cfda", "--data", str(viscous_log), "--add", "warp_drive",
                 "--out", str(tmp_path / "x.toml")]) == 2
    assert "unknown effect" in capsys.readouterr().err
    assert not (tmp_path / "x.toml").exists()


@pytest.mark.pipeline
def test_simulate_a_valve_that_differs_from_its_cfd(tmp_path):
    """--mismatch makes the valve differ from the maps it is built around by about the CFD's own
    error (the shipped bench's noise and inputs unchanged, the same seed's); --mismatch 0 is the
    maps themselves."""
    def log(name, *options):
        path = tmp_path / f"{name}.csv"
        assert main(["simulate", "--every", "64", "--seed", "3", "--quiet", *options,
                     "--out", str(path)]) == 0
        return pd.read_csv(path)

    for kind in ("grid", "gp"):
        perfect = log(f"{kind}_perfect", "--maps", kind)
        virtual = log(f"{kind}_virtual", "--maps", kind, "--mismatch", "1")
        for column in ("q_lpm", "p_P_bar", "p_B_bar", "temperature_C"):
            assert (virtual[column] == perfect[column]).all(), column
        moved = ((virtual["p_L_bar"] - perfect["p_L_bar"]) ** 2).mean() ** 0.5
        assert 0.2 < moved < 3.0, (kind, moved)  # bar: the size of the effects sought
    still = log("gp_still", "--maps", "gp", "--mismatch", "0")
    assert (still["p_L_bar"] - log("gp_perfect_again", "--maps", "gp")["p_L_bar"]).abs().max() \
        < 1e-9
