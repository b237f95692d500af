"""Ctrl-C and SIGTERM: the command stops with 130 or 143 and leaves nothing half-written."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from surrogate.cli import main
from surrogate.core.errors import InputError
from surrogate.core.interrupts import Interrupted, deferred, handling_interrupts
from surrogate.core.outputs import Output, atomic_directory, atomic_file, check_outputs
from surrogate.core.parallel import map_threads


@pytest.fixture
def two_runs_here(tmp_path, two_run_log) -> Path:
    """Runs R01 and R06 of the shipped log, every 10th sample, copied into the test's own folder
    (the tests check what is left in it)."""
    path = tmp_path / "log.csv"
    shutil.copyfile(two_run_log, path)
    return path


def _left_behind(folder: Path) -> list[str]:
    return sorted(path.name for path in folder.iterdir() if path.name != "log.csv")


@pytest.mark.pipeline
@pytest.mark.parametrize("signum, code", [(signal.SIGTERM, 143), (signal.SIGINT, 130)])
def test_a_signal_while_writing_removes_the_staging_folder(signum, code, two_runs_here, tmp_path,
                                                           monkeypatch, capsys):
    """The signal arrives while compare's figures are being written into its staging folder."""
    from surrogate.reporting import report

    real = report.figure_png

    def signalled(figure):
        os.kill(os.getpid(), signum)  # the handler raises here, in the middle of the writing
        return real(figure)

    monkeypatch.setattr(report, "figure_png", signalled)
    monkeypatch.chdir(tmp_path)
    assert main(["compare", "--model", "cfda", "--data", "log.csv", "--out", "out", "-q"]) == code
    assert _left_behind(tmp_path) == [], "a staging folder or a partial output stayed behind"
    assert "interrupted" in capsys.readouterr().err
    assert signal.getsignal(signal.SIGTERM) == signal.SIG_DFL  # handlers restored


def test_a_signal_while_files_move_into_place_waits_until_they_have(tmp_path, monkeypatch):
    """Moving the finished files in is not cut in half: the signal is raised after it."""
    target = tmp_path / "out"
    target.mkdir()
    (target / "old.txt").write_text("kept")
    moved = []
    real = Path.replace

    def replace(self, destination):
        if not moved:
            os.kill(os.getpid(), signal.SIGTERM)
        moved.append(self.name)
        return real(self, destination)

    monkeypatch.setattr(Path, "replace", replace)
    with handling_interrupts(), pytest.raises(Interrupted) as caught:
        with atomic_directory(target) as staging:
            for name in ("a.txt", "b.txt", "c.txt"):
                (staging / name).write_text(name)
    assert caught.value.exit_code == 143
    assert sorted(p.name for p in target.iterdir()) == ["a.txt", "b.txt", "c.txt", "old.txt"]
    assert [p.name for p in tmp_path.iterdir()] == ["out"]


def test_an_interrupted_file_write_leaves_the_old_file(tmp_path):
    target = tmp_path / "model.toml"
    target.write_text("old")
    with handling_interrupts(), pytest.raises(Interrupted):
        with atomic_file(target) as stream:
            stream.write("new, half")
            os.kill(os.getpid(), signal.SIGINT)
    assert target.read_text() == "old" and [p.name for p in tmp_path.iterdir()] == ["model.toml"]


def test_deferred_raises_nothing_when_no_signal_came():
    reached = []
    with handling_interrupts():
        with deferred():
            reached.append("the block")
        reached.append("past it")  # an Interrupted raised on leaving would skip this
    assert reached == ["the block", "past it"]


@pytest.mark.pipeline
def test_a_real_process_stopped_by_sigterm_exits_143_and_leaves_nothing(two_runs_here, tmp_path):
    """The signal arrives at the workflow's first fit, seconds before it writes anything (a
    compare stopped as it began replaying finished first at times: a second of work was left)."""
    process = subprocess.Popen(
        [sys.executable, "-m", "surrogate", "workflow", "--kinds", "--data", "log.csv",
         "--out", "out"], cwd=tmp_path, stderr=subprocess.PIPE, stdout=subprocess.DEVNULL,
        text=True)
    seen = []
    for line in process.stderr:  # wait until it is at work, then stop it
        seen.append(line)
        if "fitting" in line:
            process.send_signal(signal.SIGTERM)
            break
    rest = process.stderr.read()
    assert process.wait(timeout=120) == 143, "".join(seen) + rest
    assert "Traceback" not in rest and "interrupted" in rest
    assert _left_behind(tmp_path) == []


def test_a_failing_item_stops_the_pool_from_starting_the_rest():
    started = []
    release = threading.Event()

    def work(item):
        started.append(item)
        if item == 0:
            raise ValueError("first item fails")
        release.wait(1.0)  # keep the other worker busy while the first one fails
        return item

    with pytest.raises(ValueError):
        list(map_threads(work, range(50), workers=2))
    release.set()
    assert len(started) < 50


def test_an_output_folder_whose_parent_cannot_take_the_staging_folder_is_refused(tmp_path,
                                                                                monkeypatch):
    """The staging folder goes next to --out: its parent is probed too, before any work."""
    import tempfile

    out = tmp_path / "out"
    out.mkdir()
    real = tempfile.TemporaryFile

    def probe(*args, dir=None, **kwargs):
        if Path(dir) == tmp_path:
            raise PermissionError(13, "Read-only file system")
        return real(*args, dir=dir, **kwargs)

    monkeypatch.setattr(tempfile, "TemporaryFile", probe)
    with pytest.raises(InputError, match=f"cannot write in {tmp_path} .Read-only"):
        check_outputs([Output("--out", out, "folder")], [])
