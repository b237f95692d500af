"""The replay's sensitivities (surrogate.solver.sensitivities) against replays: every effect's
column of the Jacobian, linearised from one replay, matches a forward difference that replays the
log with the parameter stepped, wherever no sample starts or stops sliding between the two."""

from __future__ import annotations

import numpy as np
import pytest

from surrogate.data import load_bench_log
from surrogate.effects import LIBRARY, SHAPES
from surrogate.fitting.logfit import fit_to_log
from surrogate.fitting.residuals import replay_log, state_smoothing_samples
from surrogate.description.modelfile import load_model
from surrogate.core.paths import SHIPPED_BENCH_LOG
from surrogate.points import OperatingPoints
from surrogate.solver.sensitivities import pressure_drop_changes
from surrogate.core.units import to_si

#: a relative step, as the fit's forward differences take
STEP = 1e-4
#: the share of samples whose linearised change must agree with the replayed one, within
#: :data:`AGREE` of the column's RMS: the rest are samples that switch between sticking and
#: sliding, where a difference jumps and a derivative does not
AGREEING = 0.97
AGREE = 0.02


@pytest.fixture(scope="module")
def setting():
    log = load_bench_log(SHIPPED_BENCH_LOG)
    runs = log.frame["run"].unique()[::5][:5]
    log = log.take(np.flatnonzero(log.frame["run"].isin(runs).to_numpy()))
    return log, load_model("cfda")


def switched_on(effect):
    """``effect`` with its free parameters at a tenth of their range (or of one unit), so that
    it acts and the model is not at a bound."""
    for parameter in effect.params.values():
        if parameter.vary:
            span = parameter.max - parameter.min
            parameter.value = parameter.min + 0.1 * (span if np.isfinite(span) else 1.0)
    return effect


#: every library effect with a parameter for the whole log (the pilot's zero drift has one per
#: run) and a shape of each hook: a force, a friction, a leak
EFFECTS = sorted(set(LIBRARY) - {"pilot_zero_drift"}) + [
    "shape_force_of_opening", "shape_friction_of_q", "shape_leakage"]


@pytest.mark.parametrize("name", EFFECTS)
def test_every_effects_column_matches_a_replay(name, setting):
    log, cfda = setting
    library = SHAPES if name.startswith("shape_") else LIBRARY
    model_effects = {effect.name for effect in cfda.effects}
    effects = [e.copy() for e in cfda.effects]
    if name not in model_effects:
        effects.append(switched_on(library[name]()))
    model = cfda.with_effects(effects)
    if name.startswith("shape_"):  # knots where the log is
        model = fit_to_log(model, log, names=[], max_evaluations=1).model
    # as in a fit's inner loop, the replays compared start from a guess, and so read the maps
    # from their tables (surrogate.solver.map_tables) alike
    base = replay_log(model, log, diagnostics=False)
    base = replay_log(model, log, guess=base, diagnostics=False)
    keys = [key for key, p in model.parameters().items()
            if p.vary and key.startswith(name + ".")][:3]
    assert keys, name
    trials = []
    for key in keys:
        trial = model.copy()
        parameter = trial.parameters()[key]
        shown = parameter.display_value  # steps in display units, as the fit takes them
        parameter.value = float(to_si(shown + STEP * max(abs(shown), 1.0), parameter.unit))
        trials.append(trial)
    linear = pressure_drop_changes(model, OperatingPoints.from_bench(log.frame),
                                   log.frame["run"].to_numpy(), base.replay, trials,
                                   smoothing=state_smoothing_samples(log))
    for j, (key, trial) in enumerate(zip(keys, trials)):
        replayed = replay_log(trial, log, guess=base, diagnostics=False).replay.dp - base.replay.dp
        solved = np.isfinite(base.replay.dp)
        assert np.all(np.isfinite(linear[solved, j])) and np.all(np.isnan(linear[~solved, j]))
        both = solved & np.isfinite(replayed)
        assert both.mean() > 0.5, key
        scale = np.sqrt(np.mean(replayed[both] ** 2))
        if scale == 0.0:  # the step moves nothing (a knot outside the log): neither may
            assert np.all(linear[both, j] == 0.0), key
            continue
        agree = np.abs(linear[both, j] - replayed[both]) <= AGREE * scale
        assert agree.mean() >= AGREEING, (key, agree.mean())


@pytest.mark.parametrize("name", [name for name in LIBRARY if name not in
                                  ("friction_constant", "friction_load_pressure",
                                   "flow_force_scale")])
def test_a_shared_read_alike_replay_is_the_candidates_own(name, setting):
    """A diagnosis differences its candidates' probes against the model's replay read from the
    tables (ReadAlike) wherever the model with the candidate added, off, replays the same to
    the bit; a candidate that changes the flow or brings the first friction gets its own."""
    from surrogate.fitting.logfit import ReadAlike

    log, cfda = setting
    base = replay_log(cfda, log)  # asks the maps, as a diagnosis' base replay does
    frictionless = cfda.with_effects([e for e in cfda.effects if e.kind != "friction"])
    assert not frictionless.has_friction
    for model in (cfda, frictionless):
        alike = ReadAlike(model, log, base)
        trial = model.copy()
        trial.effects.append(LIBRARY[name].for_runs(log.run_ids))
        shared = alike.extended_by(trial.effect(name))
        if shared is None:
            assert trial.may_change_the_flow or not model.has_friction, name
            continue
        read_alone = ReadAlike(trial, log, base)()
        np.testing.assert_array_equal(shared().replay.dp, read_alone.replay.dp)
        np.testing.assert_array_equal(shared().replay.u, read_alone.replay.u)


def test_a_logs_sampling_interval_is_the_median_step_within_its_runs_found_once():
    from surrogate.data import load_bench_log
    from surrogate.core.paths import SHIPPED_BENCH_LOG

    log = load_bench_log(SHIPPED_BENCH_LOG)
    frame = log.frame
    steps = frame.groupby("run", sort=False)["time"].diff().dropna()
    assert log.sampling_interval == float(np.median(steps.to_numpy()))
    assert "sampling_interval" in vars(log)  # kept: every replay of the log asks
    assert state_smoothing_samples(log) == int(round(0.28 / log.sampling_interval)) // 2 * 2 + 1
