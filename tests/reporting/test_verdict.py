"""The workflow's three-line verdict, from a diagnosis made by hand: it names what the final model
lacks, in words and in bar, and the run to make next; with nothing found, it says so."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from surrogate.diagnosis.result import Baseline, Candidate, Diagnosis, Label, MapLimit, Score
from surrogate.planning.bench_runs import Separation
from surrogate.reporting.verdict import lacks, verdict
from surrogate.core.units import BAR, to_si

FLOOR = 0.8 * BAR


def _candidate(name: str, title: str, kind: str, rms_after: float, significant: bool,
               group: tuple[str, ...] = ()) -> Candidate:
    return Candidate(Label(name, title, "", kind, "physics"),
                     Score(rms_after, -30.0 if significant else 5.0, significant=significant,
                           group=group or (name,), median_rms=0.9 * BAR,
                           half_width_rms=0.5 * BAR))


def _workflow(diagnosis: Diagnosis) -> SimpleNamespace:
    """A workflow of one step, the final model's, started from a given model."""
    step = SimpleNamespace(rms=diagnosis.rms_before, diagnosis=None, added=[], category="",
                           model=None)
    return SimpleNamespace(final_diagnosis=diagnosis, steps=[step], maps="",
                           noise_floor=diagnosis.noise_floor)


def _diagnosis(rms: float, candidates, **more) -> Diagnosis:
    baseline = Baseline(rms, FLOOR, 500.0, map_limits=more.pop("map_limits", ()),
                        median_before=1.2 * BAR, half_width_before=0.6 * BAR)
    return Diagnosis(None, more.pop("base", None), baseline, tuple(candidates), **more)


def test_a_finding_is_named_with_its_size_in_bar_and_the_run_that_settles_it():
    group = ("progressive_spring", "spring_preload_offset")
    spring = _candidate("progressive_spring", "progressive spring", "force", 1.0 * BAR, True,
                        group)
    preload = _candidate("spring_preload_offset", "spring preload offset", "force",
                         1.02 * BAR, False, group)
    run = Separation(to_si(30.0, "degC"), 35.0 * BAR, 0.0, 1.6 * BAR, FLOOR, group)
    found = verdict(_workflow(_diagnosis(1.5 * BAR, [spring, preload], separation=run)))
    size = np.sqrt(1.5**2 - 1.0**2)  # [bar] the RMS of the part of Δp the spring explains
    assert found.lacks.startswith("progressive spring (valve physics)")
    assert f"about {size:.2f} bar RMS of Δp" in found.lacks
    assert "from 1.50 bar to 1.00 bar" in found.lacks
    assert "spring preload offset" in found.lacks  # its look-alike, in words
    assert "progressive_spring" not in found.lacks  # the names are the commands' business
    assert "a force on the piston changing with the opening u" in found.where
    assert found.next.startswith("a bench run at 30 °C and p_Pe = 35 bar")
    assert "spring preload offset" in found.next and "1.60 bar RMS" in found.next
    lines = found.lines()
    assert len(lines) == 3 and [line.split(":")[0] for line in lines] == ["Lacks", "Where",
                                                                          "Next"]


def test_without_a_decisive_run_the_finding_is_to_be_fitted():
    friction = _candidate("friction_viscous", "friction growing with viscosity", "friction",
                          1.0 * BAR, True)
    found = verdict(_workflow(_diagnosis(1.5 * BAR, [friction])))
    assert "a friction growing with the oil's viscosity ν" in found.where
    assert found.next.startswith("fit friction growing with viscosity")
    assert "--add friction_viscous" in found.next


def test_with_nothing_found_the_verdict_says_so_and_where_what_is_left_lies():
    idle = _candidate("friction_viscous", "friction growing with viscosity", "friction",
                      0.84 * BAR, False)
    limits = (MapLimit("force map near 0.16 mm", 0.14 * BAR),)
    found = verdict(_workflow(_diagnosis(0.85 * BAR, [idle], map_limits=limits)))
    assert found.lacks.startswith("nothing more that this log can show")
    assert "0.85 bar RMS" in found.lacks and f"{0.85 / 0.8:.2f}× the noise floor" in found.lacks
    assert "friction" not in found.lacks  # the candidate that did not make it is not named
    assert "force map near 0.16 mm (0.14 bar RMS)" in found.where
    assert "suggest-cfd" in found.next and "force map near 0.16 mm" in found.next
    # no map limits: the worst run, and a run the log lacks to test the model beyond it
    log_replay = SimpleNamespace(residual=np.array([0.5, -0.5, 2.0, -2.0]) * BAR,
                                 runs=np.array(["R01", "R01", "R02", "R02"]))
    found = verdict(_workflow(_diagnosis(0.85 * BAR, [idle], base=log_replay)))
    assert "largest on run R02 (2.00 bar RMS)" in found.where
    assert found.next.startswith("a bench run at a temperature or pilot pressure the log lacks")


def test_what_the_loop_added_is_said_with_the_fall_it_brought():
    from surrogate.effects import ProgressiveSpring

    spring = ProgressiveSpring()
    finding = SimpleNamespace()
    steps = [SimpleNamespace(rms=r * BAR, diagnosis=d, added=a, category=c,
                             model=SimpleNamespace(effect=lambda name: spring))
             for r, d, a, c in [(19.0, None, [], ""), (14.0, None, ["discharge_scale"], ""),
                                (9.0, None, ["flow_force_scale"], ""), (2.0, None, [], "physics"),
                                (1.0, finding, ["progressive_spring"], "physics"),
                                (0.85, None, ["calibrated_flow_force"], "map correction")]]
    idle = _candidate("friction_viscous", "friction", "friction", 0.84 * BAR, False)
    workflow = _workflow(_diagnosis(0.85 * BAR, [idle]))
    workflow.steps, workflow.maps = steps, "gp"
    said = lacks(workflow)
    assert "Beyond the paper's CFDA (2.00 bar RMS) the loop added progressive spring: valve " \
           "physics, 2.00 → 1.00 bar; " in said
    assert "the CFD maps calibrated within their uncertainty: a correction of the CFD maps, " \
           "1.00 → 0.85 bar." in said
