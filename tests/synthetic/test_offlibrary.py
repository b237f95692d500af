"""Physics beyond the library: a shape the diagnosis draws, handed over as code, does the work.

The log comes from a virtual valve (:mod:`surrogate.synthetic.mismatch`: its CFD perturbed like a
real valve's, with behaviour where the CFD has no samples) with an off-library effect hidden in
it (:mod:`surrogate.synthetic.offlibrary`): a detent force over a narrow band of the opening,
which no library term has. The model under test runs on the shipped grid maps and never sees the
virtual valve. The whole stress suite is `python eval/offlibrary.py`.
"""

from __future__ import annotations

import json

import pandas as pd
import pytest

from surrogate.cli import main
from surrogate.diagnosis.diagnose import diagnose
from surrogate.diagnosis.lookalikes import MAPS_ERROR
from surrogate.data.writer import write_bench_log
from surrogate.effects import KNOWN, LIBRARY, load_effects_file
from surrogate.fitting.heldout import run_groups
from surrogate.fitting.logfit import fit_to_log
from surrogate.fitting.residuals import replay_log
from surrogate.description.modelfile import load_model, save_model
from surrogate.description.presets import maps
from surrogate.reporting.prose import summarise
from surrogate.synthetic.mismatch import MapMismatch
from surrogate.synthetic.offlibrary import OFF_LIBRARY, off_library_suite
from surrogate.synthetic.simulate import hidden_effect_case, noise_free_sequence
from surrogate.workbench.workflow import heldout_rms, run_workflow

#: the file handed over must keep at least this share of the shape-free term's held-out gain
KEPT_GAIN = 0.9


@pytest.fixture(scope="module")
def detent_case(bench_log):
    case = next(c for c in off_library_suite() if c.hidden == "detent_force")
    return hidden_effect_case(case.hidden, case.values, seed=case.seed,
                              sequence=noise_free_sequence(bench_log, every=8),
                              library=LIBRARY + OFF_LIBRARY, mismatch=MapMismatch(),
                              maps_under_test=maps("grid"))


@pytest.mark.pipeline
@pytest.mark.slow
def test_a_shape_found_by_diagnose_is_handed_over_as_a_file_that_does_its_work(
        detent_case, tmp_path, capsys, monkeypatch):
    """diagnose --out writes the shape-free find as found_*.py; fit --effects-file --add takes
    it (its scale from 0) and predicts held-out runs as well as the shape-free term did.

    The log's file name, its run ids and an extra column's name each try to end the handed-over
    file's docstring and open a file: loading the file must run nothing of theirs."""
    monkeypatch.chdir(tmp_path)
    model_file = tmp_path / "start.toml"
    log_file = tmp_path / 'x"""+str(open("PWNED_path","w"))+""".csv'
    save_model(detent_case.start, model_file)
    write_bench_log(detent_case.log, log_file)
    table = pd.read_csv(log_file, dtype={"run": str})
    table["run"] = table["run"] + '"""+str(open("PWNED_run","w"))+"""'
    table['x"""+str(open("PWNED_column","w"))+"""'] = 1.0
    table.to_csv(log_file, index=False)
    common = ["--model", str(model_file), "--data", str(log_file)]
    assert main(["diagnose", *common, "--out", str(tmp_path / "diag"), "--json"]) == 0
    document = json.loads(capsys.readouterr().out)
    best = document["candidates"][0]
    assert best["significant"] and best["name"] == "shape_force_of_opening", document["summary"]
    (found_name, file_name), = document["effects_files"].items()
    assert found_name == best["name"]
    found = tmp_path / "diag" / file_name
    assert found.is_file() and "np.interp" in found.read_text()
    name = found.stem
    assert main(["fit", *common, "--effects-file", str(found), "--add", name,
                 "--out", str(tmp_path / "fitted.toml")]) == 0
    assert main(["effects", "--effects-file", str(found)]) == 0
    assert not list(tmp_path.rglob("PWNED*")), "loading the handed-over file ran an input's code"

    fitted = fit_to_log(load_model(str(tmp_path / "fitted.toml"), library=KNOWN + load_effects_file(found)),
                        detent_case.log)
    start = fit_to_log(detent_case.start, detent_case.log)
    schemes = run_groups(detent_case.log)
    before = heldout_rms(start, replay_log(start.model, detent_case.log), schemes)
    after = heldout_rms(fitted, replay_log(fitted.model, detent_case.log), schemes)
    shape_gain = before - best["heldout_rms_bar"] * 1e5
    assert before - after >= KEPT_GAIN * shape_gain, (before, after, best["heldout_rms_bar"])
    assert 0.5 < fitted.model.effect(name).params["scale"].value < 1.5


@pytest.mark.pipeline
@pytest.mark.slow
def test_a_step_predicts_held_out_runs_as_its_diagnosis_judged_it(bench_log):
    """A leak that opens above a pressure drop (stress case 4252): the diagnosis judged its
    shape-free leakage at 1.16 bar on held-out runs, and the staircase, refitting and checking
    the step itself, once found 36 bar, refused the leak and left the log at 1.4x the noise
    floor: a linear refit's prediction, J·δ, of a leak at the smallest flows of the hottest run.
    The check replays the run left out; its figure and the diagnosis's agree."""
    case = next(c for c in off_library_suite() if c.seed == 4252)
    leak = hidden_effect_case(case.hidden, case.values, seed=case.seed,
                              sequence=noise_free_sequence(bench_log, every=8),
                              library=LIBRARY + OFF_LIBRARY, mismatch=MapMismatch(),
                              maps_under_test=maps("grid"))
    workflow = run_workflow(leak.log, start=leak.start, max_additions=1, calibrate=False)
    assert len(workflow.steps) == 2, workflow.dropped
    step = workflow.steps[1]
    assert step.model.effect(step.added[0]).kind == "leakage"
    assert step.heldout_rms < workflow.steps[0].heldout_rms
    assert abs(step.heldout_check / step.heldout_rms - 1.0) < 0.1, (step.heldout_check,
                                                                   step.heldout_rms)


@pytest.mark.pipeline
@pytest.mark.slow
def test_a_finding_that_comes_to_light_after_the_calibration_is_added(bench_log):
    """A leak growing with the temperature (off-library case 4550, grid maps) hides behind the
    maps' error until the maps are calibrated: the loop added nothing before the calibration,
    and its final diagnosis then named a leak of free shape it did not add (1.27x the noise
    floor). The loop goes on after the calibration: the leak is added on top of it, the maps'
    factors refitted with it, and the log ends within 1.3x the floor."""
    case = next(c for c in off_library_suite(leaks=8) if c.seed == 4550)
    leak = hidden_effect_case(case.hidden, case.values, seed=case.seed,
                              sequence=noise_free_sequence(bench_log, every=8),
                              library=LIBRARY + OFF_LIBRARY, mismatch=MapMismatch(),
                              maps_under_test=maps("grid"))
    workflow = run_workflow(leak.log, start=leak.start, max_additions=3)
    added = [step.added for step in workflow.steps]
    calibration = next(i for i, names in enumerate(added) if "calibrated_flow_force" in names)
    assert calibration < len(added) - 1, added  # something followed the calibration
    kinds = [workflow.final.model.effect(name).kind for names in added[calibration + 1:]
             for name in names]
    assert kinds == ["leakage"], added
    assert workflow.final.rms < 1.3 * workflow.noise_floor
    assert workflow.final_diagnosis.best is None  # nothing left unadded


@pytest.mark.parametrize("name", list(OFF_LIBRARY))
def test_every_off_library_effect_keeps_the_effect_contract(name):
    from surrogate.testing import check_effect

    check_effect(OFF_LIBRARY[name])


def test_leaks_of_other_laws_join_the_suite_without_moving_its_cases():
    """The leak laws come after the shape cases, from a stream of their own: a suite with them
    holds the same shape cases and controls as one without (their seeds and values), each law in
    turn, sizes from barely visible to dominant, thresholds from low to high."""
    from surrogate.synthetic.offlibrary import LEAK_LAWS, LEAK_THRESHOLDS_BAR

    plain = off_library_suite(20, 10)
    with_leaks = off_library_suite(20, 10, leaks=40)
    assert with_leaks[:20] == plain[:20] and with_leaks[-10:] == plain[-10:]
    leaks = with_leaks[20:-10]
    assert [case.hidden for case in leaks] == [LEAK_LAWS[i % 4] for i in range(40)]
    assert len({case.seed for case in with_leaks}) == len(with_leaks)
    sizes = [case.values["G"] for case in leaks]
    assert 0.05 <= min(sizes) < 0.1 and 0.6 < max(sizes) <= 1.0
    thresholds = [case.values["p0"] for case in leaks if case.hidden == "threshold_leakage"]
    assert min(thresholds) < 50 and max(thresholds) > 110
    assert all(LEAK_THRESHOLDS_BAR[0] <= p0 <= LEAK_THRESHOLDS_BAR[1] for p0 in thresholds)


def test_a_case_is_invisible_only_when_nothing_was_added_and_nothing_is_left():
    from surrogate.synthetic.offlibrary import OffLibraryOutcome

    quiet = OffLibraryOutcome("turbulent_leakage", (), (), (), 1.06, 1.05)
    assert quiet.invisible and quiet.clean and not quiet.found
    left = OffLibraryOutcome("turbulent_leakage", (), (), (), 1.5, 1.05)  # above the floor
    assert not left.invisible and not left.clean
    unlike_twin = OffLibraryOutcome("turbulent_leakage", (), (), (), 1.25, 1.02)
    assert not unlike_twin.invisible
    wrong = OffLibraryOutcome("turbulent_leakage", ("shape_force_of_opening",), (),
                              ("shape_force_of_opening",), 1.05, 1.05)
    assert not wrong.invisible and not wrong.clean
    assert not OffLibraryOutcome("turbulent_leakage", (), (), (), 1.06).invisible  # no twin run
    # a claim named and withheld for a look-alike: the log showed something
    named = OffLibraryOutcome("turbulent_leakage", (), (), (), 1.06, 1.05, ("laminar_leakage",))
    assert not named.invisible and not named.clean
