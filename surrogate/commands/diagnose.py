"""``diagnose``: which physical effect is the model missing? Refit with each candidate."""

from __future__ import annotations

import json

from ..diagnosis.diagnose import candidate_effects, diagnose
from ..diagnosis.rule import (BIC_THRESHOLD, GAIN_FRACTION, HELDOUT_GAIN, INCLUSION_MIN,
                              NOISE_MARGIN)
from ..core.errors import InputError
from ..fitting.logfit import fit_to_log
from ..fitting.residuals import replay_log
from ..core.outputs import Output, atomic_directory
from ..effects.handover import hand_over
from ..reporting.prose import diagnosis_document, naming_words, shape_words, summarise
from ..core.units import from_si
from ..workbench.compare import compare
from .common import (add_command, add_data_options, guard_outputs, load_inputs, print_json,
                     progress_for)


def register(subparsers) -> None:
    parser = add_command(
        subparsers, "diagnose", help="rank candidate effects by how much of the residual they "
                                     "explain",
        description="Fit the model's free parameters to the bench log, then refit it with each "
                    "candidate effect (the library and any --effects-file) and report, for "
                    "each, its category (physics, map correction, sensor), the RMS after, the "
                    "RMS on held-out runs (each run predicted by a refit to the others), "
                    "ΔBIC against the maps' own error, its inclusion frequency over bootstrap "
                    "resamples of runs, the residual's median line and hysteresis half-width "
                    "after it, and the fitted parameters with standard errors. A candidate is "
                    f"significant when ΔBIC < {BIC_THRESHOLD:g} once smooth map-discrepancy "
                    "terms of the maps' calibrated size, refitted with the model's "
                    "parameters, have explained what they can, it lowers "
                    f"the held-out RMS by more than {100 * HELDOUT_GAIN:g} % (and so the RMS "
                    "with one temperature or one pilot pressure left out), the residual is "
                    f"above {NOISE_MARGIN:g}x the noise floor and the gain above "
                    f"{GAIN_FRACTION:g}x of it, and it (with the candidates it cannot be told "
                    f"from) is chosen in at least {100 * INCLUSION_MIN:.0f} % of the resamples. "
                    "Per-run candidates are sensor checks, "
                    "never added. Candidates the data cannot tell apart are reported as a "
                    "group.")
    add_data_options(parser, out_help="write diagnosis.json, candidates.csv, a figure and "
                                      "report.html into this folder, and, when the best "
                                      "candidate is a shape-free term, its shape as an "
                                      "effects file (found_*.py)")
    parser.add_argument("--candidates", nargs="+", metavar="NAME",
                        help="only these effects (default: every effect the model lacks)")
    parser.set_defaults(func=run)


def run(args) -> int:
    guard_outputs(args, Output("--out", args.out, "folder"))
    progress = progress_for(args)
    model, log, library = load_inputs(args, progress)
    if not candidate_effects(model, library, args.candidates):  # checks names before the fit
        raise InputError(f"nothing to diagnose: model {model.name!r} has every candidate "
                         f"({', '.join(args.candidates or ['the whole library'])}) already")
    progress(f"fitting the free parameters of {model.name}")
    model = fit_to_log(model, log, progress=progress).model
    progress(f"diagnosing {model.name}")
    # the comparison's tables are for the report alone: without --out the replay is all
    log_replay = replay_log(model, log).require_solved(model.name)
    diagnosis = diagnose(model, log, library, base=log_replay, candidates=args.candidates,
                         progress=progress)
    progress(f"done in {progress.elapsed:.1f} s")
    document = diagnosis_document(diagnosis)
    # a shape without a name is handed over, found or withheld for its look-alikes (to test
    # by hand on a log that tells them apart)
    shape = diagnosis.best or (diagnosis.declined.claim if diagnosis.declined else None)
    if args.out:
        # the report draws with matplotlib, half a second of a start: only when it is written
        from ..reporting.report import (comparison_section, diagnosis_figure, diagnosis_section,
                                        diagnosis_table, figure_png, write_html)

        with atomic_directory(args.out) as staging:
            if shape is not None and shape.shape_free:
                document["effects_files"] = hand_over(
                    [shape.effect], staging, origin=log.source,
                    notes={shape.name: shape_words(shape) + " " + naming_words(shape)})
            (staging / "diagnosis.json").write_text(json.dumps(document, indent=2))
            diagnosis_table(diagnosis).to_csv(staging / "candidates.csv", index=False)
            (staging / "diagnosis.png").write_bytes(figure_png(diagnosis_figure(diagnosis)))
            write_html(staging / "report.html", f"Diagnosis: {model.name}",
                       [diagnosis_section(diagnosis),
                        comparison_section(compare(model, log, log_replay=log_replay),
                                           "The fitted model against the data")])
        progress(f"wrote {args.out}/report.html")
    if args.json:
        print_json(document)
    else:
        print(format_diagnosis(diagnosis))
    return 0


def format_diagnosis(diagnosis) -> str:
    lines = [summarise(diagnosis), "",
             f"  current RMS {from_si(diagnosis.rms_before, 'bar'):.3f} bar, noise floor "
             f"{from_si(diagnosis.noise_floor, 'bar'):.3f} bar, "
             f"{diagnosis.effective_samples:.0f} effectively independent samples", "",
             f"  {'candidate':<30}{'RMS after':>10}{'ΔBIC':>9}  {'signif.':<8}parameters"]
    for c in diagnosis.candidates:
        params = "; ".join(str(p) for p in c.params if p.vary)
        same = [n for n in c.group if n != c.name]
        lines.append(f"  {c.name:<30}{from_si(c.rms_after, 'bar'):>10.3f}{c.delta_bic:>9.1f}  "
                     f"{'yes' if c.significant else 'no':<8}{params}"
                     + (f"  [same as {', '.join(same)}]" if same else ""))
    return "\n".join(lines)
