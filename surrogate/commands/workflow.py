"""``workflow``: from the paper's basic model to one the bench data cannot fault, step by step."""

from __future__ import annotations

import json

import numpy as np

from ..effects.handover import hand_over
from ..maps.crossval import most_accurate_kind
from ..maps.registry import MAP_KINDS
from ..core.memory import loading, release_freed, settle_survivors, settling
from ..description.modelfile import save_model
from ..core.outputs import Output, atomic_directory
from ..description.presets import maps
from ..core.progress import duration
from ..reporting.documents import workflow_document
from ..reporting.prose import naming_words, shape_words, summarise, workflow_summary
from ..reporting.kinds import compare_kinds, comparison_sentences
from ..reporting.verdict import verdict
from ..description.spec import ValveSource
from ..core.units import from_si
from ..workbench.compare import compare
from ..workbench.workflow import MAX_ADDITIONS, run_workflow
from .common import (add_command, add_data_options, guard_outputs, load_inputs, non_negative_int,
                     print_json, progress_for)

DEFAULT_OUT = "results/workflow"
#: the kinds built from CFD samples, whose staircases the report compares
COMPARED_KINDS = tuple(name for name, kind in MAP_KINDS.items() if kind.accuracy is not None)


def register(subparsers) -> None:
    parser = add_command(
        subparsers, "workflow",
        help="run the loop: paper's models, then diagnose and add until only noise is left; "
             "write the error staircase and a report",
        description="Start from the paper's basic model (BMBE), take the paper's steps (fitted "
                    "C_d, CFD maps with a flow-force scale, Coulomb friction K1 + K2*p_L), then "
                    "repeatedly diagnose the model and add the best significant effect, until "
                    "nothing significant is left; last, calibrate the maps to the bench per "
                    "opening within their own uncertainty. Writes the staircase (table and figure), the "
                    "final model file, its comparison with the data and an HTML report.")
    add_data_options(parser, model=False, out_help=f"output folder (default {DEFAULT_OUT})",
                     maps_help="the maps of the CFD steps, whose final model and diagnosis the "
                               "report follows (default: the kind whose flow force is the most "
                               "accurate by cross-validation)")
    parser.add_argument("--kinds", nargs="*", choices=COMPARED_KINDS, default=list(COMPARED_KINDS),
                        metavar="KIND",
                        help="map kinds whose staircases the report shows side by side, the "
                             "library's effects only (default: "
                             f"{' '.join(COMPARED_KINDS)}; none: just the main one)")
    parser.add_argument("--max-additions", type=non_negative_int, default=MAX_ADDITIONS,
                        help=f"effects the loop may add at most (default {MAX_ADDITIONS})")
    parser.add_argument("--no-calibration", action="store_true",
                        help="end without the last step, the maps calibrated to the bench per "
                             "opening within their own uncertainty")
    parser.set_defaults(func=run)


def hand_over_shapes(workflow, folder) -> dict[str, str]:
    """Write the final model's shape-free terms as effects files into ``folder``; return
    {effect name: file name}."""
    found = {step.added[0]: step.diagnosis.best for step in workflow.steps if step.shape_free}
    effects = [effect for effect in workflow.final.model.effects if effect.name in found]
    notes = {name: shape_words(best) + " " + naming_words(best) for name, best in found.items()}
    return hand_over(effects, folder, origin=workflow.log.source, notes=notes)


def run(args) -> int:
    with settling():
        return _run(args)


def _run(args) -> int:
    out = args.out or DEFAULT_OUT
    guard_outputs(args, Output("--out", out, "folder"))
    progress = progress_for(args)
    _, log, library = load_inputs(args, progress)
    settle_survivors()  # the modules and the log live to the end
    valve = ValveSource.read(args.valve)
    scores = None
    if args.maps:
        main_maps = args.maps.spec()
        main = str(args.maps)
    else:
        main, scores = most_accurate_kind(valve.parameters)
        main_maps = maps(main)
        progress(f"maps: {main}, whose flow force is the most accurate by cross-validation ("
                 + ", ".join(f"{kind} {100 * score:.1f} %" for kind, score in scores.items())
                 + ")")
    workflows = {}
    kinds = list(dict.fromkeys([main, *args.kinds]))  # the main kind first
    if len(kinds) > 1:
        progress(f"{main} maps first, then {', '.join(kinds[1:])} maps for comparison (the "
                 f"library's effects alone); --kinds without a kind runs {main} alone")
    for number, kind in enumerate(kinds, start=1):
        progress(f"workflow on {kind} maps ({number} of {len(kinds)})")
        # the kinds beside the main one show what the library's loop makes of their maps: a
        # term of free shape there would mostly take up that kind's own map error, and its
        # search is the loop's costliest part
        workflows[kind] = run_workflow(
            log, library=library, valve=valve, max_additions=args.max_additions,
            calibrate=not args.no_calibration, shapes=kind == main,
            maps_spec=main_maps if kind == main else maps(kind), progress=progress,
            narrate=summarise)
        if kind == main or number == len(kinds):
            # the main result as soon as it is known; the report again once the comparison
            # kinds beside it are done
            document = write_results(out, log, workflows, main, scores)
            if number < len(kinds):
                progress(f"wrote the {main} maps' results to {out}; the comparison kinds follow "
                         f"({', '.join(kinds[1:])}), their staircases added to the report after")
        # the kind's fits are done: glibc keeps what they freed unless asked (:mod:`..memory`),
        # and the next kind would start its peak on top of it
        release_freed()
        if number < len(kinds):
            progress(f"{number} of {len(kinds)} kinds done; "
                     f"{remaining_words(workflows, main, len(kinds) - number)}")
    progress(f"wrote {out}/report.html")
    workflow = workflows[main]
    if args.json:
        print_json(document)
    else:
        print(verdict(workflow).text())
        print(f"on {main} maps:")
        for number, step in enumerate(workflow.steps, start=1):
            print(f"{number:>2}. {', '.join(step.added) or step.model.name:<45} rms "
                  f"{from_si(step.rms, 'bar'):7.3f} bar")
        print(f"    noise floor {from_si(workflow.noise_floor, 'bar'):.3f} bar")
        print(workflow_summary(workflow))
        others = [kind for kind in workflows if kind != main]
        if others:
            print("for comparison, the library's effects alone on other maps:")
        for kind in others:
            print(f"    {kind} maps: {from_si(workflows[kind].final.rms, 'bar'):.3f} bar after "
                  f"{len(workflows[kind].steps)} steps")
        if others:
            for sentence in comparison_sentences(compare_kinds(workflows, main)):
                print(f"  - {sentence}")
        print(f"report: {out}/report.html")
    return 0


def remaining_words(workflows: dict, main: str, kinds_left: int) -> str:
    """The time the ``kinds_left`` comparison kinds still take, roughly: each about as long
    as the comparison kinds so far, or, before any, as the main kind less its shapes (on the
    shipped log each took about 0.8 of the main one's time)."""
    others = [w.seconds for kind, w in workflows.items() if kind != main]
    each = np.mean(others) if others else 0.8 * workflows[main].seconds
    return f"about {duration(each * kinds_left)} left"


def write_results(out, log, workflows: dict, main: str, scores) -> dict:
    """Write the main kind's staircase, final model, comparison, figures and report (with the
    staircases of the kinds done so far beside it) into ``out``, all at once; return the
    JSON document."""
    # the figures draw with matplotlib: imported when the results are written, not at every
    # command's start (half a second), with the collector paused as at the start (cli)
    with loading():
        from ..reporting.report import (comparison_section, diagnosis_section, figure_png,
                                        figure_pngs, misfit_figures, misfit_section,
                                        next_steps_section, staircase_section, staircase_table,
                                        staircases_section, verdict_html, write_html)
        from ..reporting.staircase import staircase_figure

    workflow = workflows[main]
    final = workflow.final
    comparison = compare(final.model, log, log_replay=final.log_replay)
    # the workflows live to the end: the figures' collections need not walk them
    settle_survivors()
    with atomic_directory(out) as staging:
        document = {**workflow_document(workflow),
                    "maps_flow_force_cv_error": None if scores is None else {
                        kind: round(score, 4) if np.isfinite(score) else None
                        for kind, score in scores.items()},
                    "other_kinds": {kind: workflow_document(other)
                                    for kind, other in workflows.items()
                                    if kind != main},
                    "kinds_compared": (compare_kinds(workflows, main).to_json()
                                       if len(workflows) > 1 else None)}
        document["effects_files"] = hand_over_shapes(workflow, staging)
        (staging / "workflow.json").write_text(json.dumps(document, indent=2) + "\n")
        staircase_table(workflow.steps).to_csv(staging / "staircase.csv", index=False)
        # drawn once, for the file and the report
        staircase_png = figure_png(staircase_figure(workflow.steps, workflow.noise_floor))
        (staging / "staircase.png").write_bytes(staircase_png)
        save_model(final.model, staging / "final_model.toml",
                   note=f"final model of the workflow on {log.source}")
        pngs = figure_pngs(comparison)  # drawn once, for the files and the report
        misfit = misfit_figures(workflow)
        for name, png in {**pngs, **misfit}.items():
            (staging / f"{name}.png").write_bytes(png)
        others = ([staircases_section(workflows, main, scores)] if len(workflows) > 1
                  else [])
        write_html(staging / "report.html", "CBV model against bench data: the workflow",
                   [staircase_section(workflow, staircase_png), misfit_section(workflow, misfit),
                    *others,
                    comparison_section(comparison, "The final model against the data", pngs),
                    diagnosis_section(workflow.final_diagnosis,
                                      "What is left: the final model's diagnosis"),
                    next_steps_section(workflow)],
                   opening=verdict_html(workflow),
                   note=f"Data: {log.source} ({len(log)} samples, {len(log.run_ids)} runs). "
                        f"Maps: {main}. Run time "
                        f"{duration(sum(w.seconds for w in workflows.values()))}.")
    return document
