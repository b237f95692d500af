"""Effects with a parameter per bench run: they act on their run alone, a run replays alone as it
does within its log (which makes the fit's one-run Jacobian columns exact), and they survive a
model file."""

from __future__ import annotations

import numpy as np
import pytest

from surrogate.effects import LIBRARY, PilotZeroDrift
from surrogate.core.errors import InputError
from surrogate.fitting.logfit import fit_to_log, probe_column, probe_runs
from surrogate.fitting.residuals import replay_log, run_rows
from surrogate.description.modelfile import load_model, save_model
from surrogate.points import OperatingPoints
from surrogate.core.units import to_si


@pytest.fixture(scope="module")
def short_log(bench_log):
    """Three sliding runs and one on the stop, every 6th sample."""
    frame = bench_log.frame
    keep = frame["run"].isin(["R01", "R06", "R11", "R04"]).to_numpy()
    rows = np.flatnonzero(keep)
    rows = rows[np.isin(rows, rows[::6])]
    return bench_log.take(rows)


def test_each_run_gets_its_own_offset_and_points_without_a_run_get_none():
    effect = PilotZeroDrift.for_runs(["A", "B"])
    effect.params["delta_A"].set_display(0.5)
    points = OperatingPoints(np.ones(3), np.full(3, 60e5), np.full(3, 5e5), np.full(3, 313.0),
                             np.zeros(3), ["A", "B", "C"])
    corrected = effect.correct_inputs(points)
    assert np.allclose(corrected.p_P, [60e5 - 0.5e5, 60e5, 60e5])
    assert corrected.run.tolist() == ["A", "B", "C"]
    anonymous = effect.correct_inputs(points.replace(run=None))
    assert np.array_equal(anonymous.p_P, points.p_P)
    assert [p.scope for p in effect.params.values()] == ["A", "B"]


def test_a_run_replays_alone_as_within_its_log_and_only_its_offset_moves_it(short_log):
    model = load_model("cfda")
    whole = replay_log(model, short_log)
    rows = run_rows(short_log, "R06")
    alone = replay_log(model, short_log.take(rows))
    assert np.array_equal(alone.residual, whole.residual[rows], equal_nan=True)

    drifting = PilotZeroDrift.for_runs(short_log.run_ids)
    drifting.params["delta_R06"].set_display(0.4)
    shifted = replay_log(model.with_effects([*model.effects, drifting]), short_log)
    change = shifted.replay.dp - whole.replay.dp
    others = np.delete(np.arange(len(change)), rows)
    assert np.all(change[others] == 0.0)
    # the pilot acts on α_P = 2.72 times the load area: 0.4 bar reads as about 1 bar of Δp
    assert 0.5e5 < np.nanmean(change[rows]) < 1.5e5


def test_every_runs_probe_from_one_replay_of_the_log_is_the_runs_own(short_log):
    """A diagnosis probes a run's pilot zero in every run from one replay of the log with every
    run's offset stepped (probe_runs), where probe_column replays each run alone: the same
    step, the same column to the bit, the same verdict on whether the run feels it."""
    model = load_model("cfda")
    trial = model.with_effects([*model.effects, PilotZeroDrift.for_runs(short_log.run_ids)])
    base = replay_log(model, short_log)
    ok = np.isfinite(base.residual)
    keys = [f"pilot_zero_drift.delta_{run}" for run in short_log.run_ids]
    shared = probe_runs(trial, ["friction_constant.K1", *keys], short_log, base, ok)
    assert list(shared) == keys  # a parameter of the whole log is probed on its own
    for key in keys:
        own = probe_column(trial, key, short_log, base, ok)
        assert (shared[key].key, shared[key].step, shared[key].felt) == (key, own.step, own.felt)
        np.testing.assert_array_equal(shared[key].change, own.change)
    assert not shared["pilot_zero_drift.delta_R04"].felt  # the run on its stop
    assert probe_runs(trial, keys[:1], short_log, base, ok) == {}  # one run: nothing to share


def test_fit_recovers_offsets_of_the_sliding_runs_and_leaves_the_stop_run_alone(short_log):
    truth_offsets = {"R01": 0.3, "R06": -0.4, "R11": 0.2, "R04": 0.0}
    model = load_model("cfda")
    drifting = PilotZeroDrift.for_runs(short_log.run_ids)
    for run, value in truth_offsets.items():
        drifting.params[f"delta_{run}"].set_display(value)
    truth = model.with_effects([*model.effects, drifting])
    frame = short_log.frame.copy()
    frame["p_L"] = frame["p_B"] + replay_log(truth, short_log).replay.dp
    synthetic = type(short_log)(frame, "synthetic")

    names = [f"pilot_zero_drift.delta_{run}" for run in truth_offsets]
    start = model.with_effects([*model.effects, PilotZeroDrift.for_runs(short_log.run_ids)])
    fitted = fit_to_log(start, synthetic, names).model.effect("pilot_zero_drift")
    for run in ("R01", "R06", "R11"):
        assert fitted.params[f"delta_{run}"].display_value == pytest.approx(
            truth_offsets[run], abs=0.02)
    # the piston of R04 sits on its stop: the pilot pressure does not matter there
    assert abs(fitted.params["delta_R04"].display_value) < 0.5


def test_per_run_parameters_survive_a_model_file(tmp_path):
    model = load_model("cfda")
    drifting = LIBRARY.effect("pilot_zero_drift").for_runs(["R01", "R02"])
    drifting.params["delta_R02"].value = to_si(-0.25, "bar")
    path = tmp_path / "m.toml"
    save_model(model.with_effects([*model.effects, drifting]), path)
    loaded = load_model(str(path)).effect("pilot_zero_drift")
    assert loaded.params["delta_R02"].display_value == pytest.approx(-0.25)
    assert loaded.params["delta_R02"].scope == "R02"

    path.write_text(path.read_text().replace("delta_R01", "offset_R01"))
    with pytest.raises(InputError, match="unknown parameter 'offset_R01'"):
        load_model(str(path))
