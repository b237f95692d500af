"""Command-line conventions: help, exit codes, --quiet, file permissions and warnings."""

from __future__ import annotations

import os
import stat

import pytest

from surrogate.cli import build_parser, main
from surrogate.commands import COMMANDS
from surrogate.paths import SHIPPED_BENCH_LOG

COMMAND_NAMES = [command.__name__.rsplit(".", 1)[1].replace("_", "-") for command in COMMANDS]


@pytest.fixture(scope="module")
def small_log(tmp_path_factory):
    """Run R01 of the shipped log, every 10th sample."""
    lines = SHIPPED_BENCH_LOG.read_text().splitlines()
    rows = [line for line in lines[1:] if line.startswith("R01,")][::10]
    path = tmp_path_factory.mktemp("log") / "r01.csv"
    path.write_text("\n".join([lines[0], *rows]) + "\n")
    return path


@pytest.mark.parametrize("name", COMMAND_NAMES)
def test_help_lists_exit_codes_and_required_options_under_their_heading(name, capsys):
    assert main([name, "--help"]) == 0
    text = capsys.readouterr().out
    assert "exit codes:" in text and "2  bad input" in text
    subparser = build_parser()._subparsers._group_actions[0].choices[name]
    for action in subparser._actions:
        if action.required and action.option_strings:
            assert action.option_strings[-1] in text.split("required options:", 1)[1]


def test_top_level_help_lists_exit_codes(capsys):
    assert main(["--help"]) == 0
    assert "exit codes:" in capsys.readouterr().out


def test_quiet_silences_progress_but_not_results(small_log, capsys):
    assert main(["compare", "--model", "cfda", "--data", str(small_log)]) == 0
    loud = capsys.readouterr()
    assert "replaying cfda" in loud.err
    assert main(["compare", "--model", "cfda", "--data", str(small_log), "--quiet"]) == 0
    quiet = capsys.readouterr()
    assert quiet.err == "" and quiet.out == loud.out


def test_written_files_get_the_usual_permissions(small_log, tmp_path, capsys):
    previous = os.umask(0o022)
    try:
        out = tmp_path / "fitted.toml"
        assert main(["fit", "--model", "cfda", "--data", str(small_log), "--out", str(out),
                     "--quiet"]) == 0
        assert stat.S_IMODE(out.stat().st_mode) == 0o644
        folder = tmp_path / "compare"
        assert main(["compare", "--model", "cfda", "--data", str(small_log), "--out",
                     str(folder), "--quiet"]) == 0
        assert {stat.S_IMODE(path.stat().st_mode) for path in folder.iterdir()} == {0o644}
    finally:
        os.umask(previous)


def test_per_run_parameters_of_runs_the_log_lacks_are_refused(small_log, tmp_path, capsys):
    """The model was fitted to another log: its other parameters were fitted beside terms that
    act on no sample here, so it is refused (exit 2) rather than replayed with a warning."""
    model = tmp_path / "model.toml"
    model.write_text('[model]\nmaps = { kind = "grid" }\n[[effects]]\nname = "pilot_zero_drift"\n'
                     '[effects.parameters]\n'
                     'delta_R01 = { value = 0.1, unit = "bar" }\n'
                     'delta_R99 = { value = 0.2, unit = "bar" }\n')
    assert main(["compare", "--model", str(model), "--data", str(small_log), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "run(s) R99," in err and "lacks (its runs: R01)" in err
