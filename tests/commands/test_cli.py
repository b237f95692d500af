"""Command-line conventions: help, exit codes, --quiet, file permissions and warnings."""

from __future__ import annotations

import os
import stat

import pytest

from surrogate.cli import build_parser, main
from surrogate.commands import COMMANDS

COMMAND_NAMES = [command.__name__.rsplit(".", 1)[1].replace("_", "-") for command in COMMANDS]


@pytest.mark.pipeline
@pytest.mark.parametrize("name", COMMAND_NAMES)
def test_help_lists_exit_codes_and_required_options_under_their_heading(name, capsys):
    assert main([name, "--help"]) == 0
    text = capsys.readouterr().out
    assert "exit codes:" in text and "2  bad input" in text
    subparser = build_parser()._subparsers._group_actions[0].choices[name]
    for action in subparser._actions:
        if action.required and action.option_strings:
            assert action.option_strings[-1] in text.split("required options:", 1)[1]


@pytest.mark.pipeline
def test_top_level_help_lists_exit_codes(capsys):
    assert main(["--help"]) == 0
    assert "exit codes:" in capsys.readouterr().out


@pytest.mark.pipeline
def test_quiet_silences_progress_but_not_results(one_run_log, capsys):
    assert main(["compare", "--model", "cfda", "--data", str(one_run_log)]) == 0
    loud = capsys.readouterr()
    assert "replaying cfda" in loud.err
    assert main(["compare", "--model", "cfda", "--data", str(one_run_log), "--quiet"]) == 0
    quiet = capsys.readouterr()
    assert quiet.err == "" and quiet.out == loud.out


@pytest.mark.pipeline
def test_written_files_get_the_usual_permissions(one_run_log, tmp_path, capsys):
    previous = os.umask(0o022)
    try:
        out = tmp_path / "fitted.toml"
        assert main(["fit", "--model", "cfda", "--data", str(one_run_log), "--out", str(out),
                     "--quiet"]) == 0
        assert stat.S_IMODE(out.stat().st_mode) == 0o644
        folder = tmp_path / "compare"
        assert main(["compare", "--model", "cfda", "--data", str(one_run_log), "--out",
                     str(folder), "--quiet"]) == 0
        assert {stat.S_IMODE(path.stat().st_mode) for path in folder.iterdir()} == {0o644}
    finally:
        os.umask(previous)


@pytest.mark.pipeline
def test_per_run_parameters_of_runs_the_log_lacks_are_refused(one_run_log, tmp_path, capsys):
    """The model was fitted to another log: its other parameters were fitted beside terms that
    act on no sample here, so it is refused (exit 2) rather than replayed with a warning."""
    model = tmp_path / "model.toml"
    model.write_text('[model]\nmaps = { kind = "grid" }\n[[effects]]\nname = "pilot_zero_drift"\n'
                     '[effects.parameters]\n'
                     'delta_R01 = { value = 0.1, unit = "bar" }\n'
                     'delta_R99 = { value = 0.2, unit = "bar" }\n')
    assert main(["compare", "--model", str(model), "--data", str(one_run_log), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "run(s) R99," in err and "lacks (its runs: R01)" in err


# --- names in any case, with a did-you-mean ------------------------------------------------------

@pytest.mark.parametrize("argv, option, expected", [
    (["compare", "--model", "CFDA"], "model", "cfda"),
    (["compare", "--model", "Cfda-GP", "--maps", "GP"], "model", "cfda-gp"),
    (["compare", "--model", "cfda", "--maps", "GP"], "maps", "gp"),
    (["paper", "--maps", "Grid"], "maps", "grid"),
    (["predict", "--maps", "NN", "--input", "q.csv", "--output", "o.csv"], "maps", "nn"),
    (["suggest-cfd", "--model", "BMBE"], "model", "bmbe"),
    (["steady", "--model", "CFDA", "--maps", "ORIFICE", "--p-P-bar", "80", "--out", "o.csv"],
     "maps", "orifice"),
])
def test_presets_and_kinds_are_read_in_any_case_as_their_names(argv, option, expected, tmp_path,
                                                                monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert str(getattr(build_parser().parse_args(argv), option)) == expected


def test_the_python_api_reads_names_in_any_case_too():
    from surrogate.maps.registry import MapSource, map_kind
    from surrogate.description.modelfile import load_spec

    assert load_spec("CFDA").name == "cfda"
    assert map_kind("GP").name == "gp"
    assert MapSource.from_dict({"kind": "Grid"}, "test").kind == "grid"


def test_a_file_named_like_a_preset_in_another_case_is_the_file(tmp_path, monkeypatch):
    from surrogate.description.modelfile import model_name

    monkeypatch.chdir(tmp_path)
    (tmp_path / "CFDA").write_text("")
    assert model_name("CFDA") == "CFDA" and model_name("cfda") == "cfda"
    assert model_name("Bmbe") == "bmbe"


@pytest.mark.pipeline
@pytest.mark.parametrize("argv, words", [
    (["compare", "--model", "cfad"], "unknown model 'cfad' (did you mean 'cfda'?)"),
    (["compare", "--model", "cfda-np"], "did you mean 'cfda-nn'?"),
    (["predict", "--maps", "gird", "--input", "q.csv", "--output", "o.csv"],
     "unknown map kind 'gird' (did you mean 'grid'?)"),
])
def test_a_near_miss_gets_a_did_you_mean(argv, words, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    assert words in capsys.readouterr().err


@pytest.mark.pipeline
def test_a_name_far_from_every_choice_gets_no_guess(capsys):
    assert main(["compare", "--model", "xyz"]) == 2
    assert "did you mean" not in capsys.readouterr().err


# --- the data a command reads are never chosen silently -----------------------------------------

class _Stop(Exception):
    """Raised where the log would be read: what was said before is all a test needs."""


@pytest.mark.pipeline
@pytest.mark.parametrize("argv", [
    ["compare", "--model", "cfda"], ["diagnose", "--model", "cfda"],
    ["fit", "--model", "cfda", "--out", "m"], ["workflow", "--out", "w"],
    ["suggest-cfd"], ["paper", "--out", "p"],
    ["export", "--model", "cfda", "--format", "tables", "--out", "e"],
], ids=lambda argv: argv[0])
def test_the_shipped_log_is_named_in_the_first_progress_line(argv, tmp_path, monkeypatch,
                                                              capsys):
    from surrogate.commands import common, paper, suggest_cfd
    from surrogate.core.errors import InputError

    def stop(path, progress=None):
        raise InputError(f"stopped before reading {path}")

    for module in (common, paper, suggest_cfd):
        monkeypatch.setattr(module, "load_bench_log", stop)
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    first = capsys.readouterr().err.splitlines()[0]
    assert first.endswith("no --data given: using the shipped log "
                          "measurements/bench_measurements.csv"), first


@pytest.mark.pipeline
def test_a_given_log_is_read_without_that_line(one_run_log, capsys):
    assert main(["compare", "--model", "cfda", "--data", str(one_run_log)]) == 0
    assert "no --data given" not in capsys.readouterr().err


# --- one vocabulary: --data and --out (a folder); the old spellings for one release -------------

@pytest.mark.pipeline
def test_fit_and_simulate_write_into_the_out_folder(one_run_log, tmp_path):
    assert main(["fit", "--model", "cfda", "--data", str(one_run_log), "--out",
                 str(tmp_path / "fitted"), "--quiet"]) == 0
    assert (tmp_path / "fitted" / "model.toml").is_file()
    assert main(["simulate", "--hidden", "friction_viscous", "--sequence", str(one_run_log),
                 "--out", str(tmp_path / "virtual"), "--quiet"]) == 0
    assert (tmp_path / "virtual" / "log.csv").is_file()


@pytest.mark.pipeline
@pytest.mark.parametrize("old, new", [
    (["fit", "--model", "cfda", "--data", "{log}", "--out", "{tmp}/m.toml"], "m.toml"),
    (["simulate", "--hidden", "none", "--sequence", "{log}", "--out", "{tmp}/v.csv"], "v.csv"),
    (["predict", "--maps", "grid", "--input", "{queries}", "--output", "{tmp}/p.csv"], "p.csv"),
], ids=["fit --out FILE.toml", "simulate --out FILE.csv", "predict --input --output"])
def test_the_old_spellings_still_work_for_a_release_and_say_so(old, new, one_run_log, tmp_path,
                                                               capsys):
    queries = tmp_path / "queries.csv"
    queries.write_text("u_mm,p_L_bar,p_B_bar,temperature_C\n0.1,100,5,40\n")
    argv = [part.format(log=one_run_log, tmp=tmp_path, queries=queries) for part in old]
    assert main([*argv, "--quiet"]) == 0
    assert (tmp_path / new).is_file()
    assert "note:" in capsys.readouterr().err  # said even with --quiet


@pytest.mark.pipeline
def test_predict_writes_into_its_out_folder(tmp_path):
    queries = tmp_path / "queries.csv"
    queries.write_text("u_mm,p_L_bar,p_B_bar,temperature_C\n0.1,100,5,40\n0.2,80,5,20\n")
    assert main(["predict", "--maps", "grid", "--data", str(queries), "--out",
                 str(tmp_path / "out"), "--quiet"]) == 0
    written = (tmp_path / "out" / "predictions.csv").read_text().splitlines()
    assert len(written) == 3 and "q_lpm_pred" in written[0]


@pytest.mark.parametrize("seconds, said", [(5, "5 s"), (89.4, "89 s"), (119.6, "2 min 0 s"),
                                           (2413, "40 min 13 s"), (3725, "1 h 2 min")])
def test_times_are_said_as_people_read_them(seconds, said):
    """Run times and ETAs in minutes and hours, not "2413 s"; rounding never says "60 s"."""
    from surrogate.core.progress import duration

    assert duration(seconds) == said


@pytest.mark.parametrize("per_second, said", [(12.4, "12/s"), (0.25, "4 s each"),
                                              (0.01, "1 min 40 s each")])
def test_slow_work_is_said_per_item_not_as_zero_per_second(per_second, said):
    """A refit taking 4 s read "0/s" in the progress line."""
    from surrogate.core.progress import rate

    assert rate(per_second) == said


def test_the_main_jobs_eta_follows_the_kinds_already_run():
    """After the main kind, the comparison kinds' time is guessed from it (less its shapes);
    after one of them, from what they took."""
    from types import SimpleNamespace

    from surrogate.commands.workflow import remaining_words

    done = {"gp": SimpleNamespace(seconds=100.0)}
    assert remaining_words(done, "gp", 2) == "about 2 min 40 s left"
    done["grid"] = SimpleNamespace(seconds=50.0)
    assert remaining_words(done, "gp", 1) == "about 50 s left"


def test_the_command_line_starts_without_matplotlib():
    """The figures' library (half a second of a start) is imported only by a command that
    draws: parsing and running diagnose, fit or export never need it."""
    import subprocess
    import sys

    from surrogate.core.paths import PROJECT_ROOT

    code = ("import sys, surrogate.cli; "
            "assert 'matplotlib' not in sys.modules, 'matplotlib imported at start-up'")
    subprocess.run([sys.executable, "-c", code], check=True, cwd=PROJECT_ROOT)
