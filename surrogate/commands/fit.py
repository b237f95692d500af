"""``fit``: add effects to a model, refit every free parameter on a bench log, save the model."""

from __future__ import annotations

from ..core.errors import InputError
from ..fitting.logfit import fit_to_log
from ..fitting.residuals import noise_floor, replay_log
from ..description.modelfile import save_model
from ..core.outputs import atomic_directory
from ..core.units import from_si
from .common import (add_command, add_data_options, guard_outputs, load_inputs, output_file,
                     print_json, progress_for)


def register(subparsers) -> None:
    parser = add_command(
        subparsers, "fit", help="add effects, refit on a bench log and save the model file",
        description="Add the named effects (built-in, or custom from --effects-file) to the "
                    "model, fit all free parameters to every sample of the bench log and write the "
                    "fitted model as a TOML file.")
    add_data_options(parser, out_help="output folder: the fitted model is written as "
                                      "FOLDER/model.toml", out_required=True)
    parser.add_argument("--add", action="append", default=[], metavar="NAME",
                        help="effect to add (repeatable)")
    parser.set_defaults(func=run)


def run(args) -> int:
    output, path = output_file(args, "model.toml", ".toml")
    guard_outputs(args, output)
    progress = progress_for(args)
    model, log, library = load_inputs(args, progress)
    classes = [library.effect(name) for name in args.add]
    shaped = [cls.name for cls in classes if getattr(cls, "shape_free", False)]
    if shaped:
        raise InputError(f"--add {', '.join(shaped)}: a shape-free term takes its knots from "
                         "the log a diagnosis fits it to; `diagnose --out DIR` writes the shape "
                         "it finds as an effects file (found_*.py), which --effects-file FILE "
                         "--add NAME adds")
    repeated = sorted({name for name in args.add if args.add.count(name) > 1})
    if repeated:
        raise InputError(f"--add {', '.join(repeated)} given more than once; add an effect once")
    already = [cls.name for cls in classes if model.has_effect(cls.name)]
    if already:
        raise InputError(f"model {model.name!r} has {', '.join(already)} already")
    name = "+".join([model.name, *args.add])
    model = model.with_effects([*model.effects, *(cls.for_runs(log.run_ids) for cls in classes)],
                               name=name)
    progress(f"fitting {name}")
    result = fit_to_log(model, log, progress=progress)
    log_replay = replay_log(result.model, log).require_solved(result.model.name)
    floor = noise_floor(log_replay.residual, log_replay.runs, source=log_replay.log.source)
    note = f"fitted to {log.source}: rms {from_si(log_replay.rms(), 'bar'):.3f} bar"
    if output.kind == "folder":
        with atomic_directory(output.path) as staging:
            save_model(result.model, staging / path.name, note=note)
    else:
        save_model(result.model, path, note=note)
    progress(f"wrote {path}")
    if args.json:
        print_json({
            "model": result.model.name, "added": args.add, "file": str(path),
            "rms_bar": round(float(from_si(log_replay.rms(), "bar")), 4),
            "noise_floor_bar": round(float(from_si(floor, "bar")), 4),
            "parameters": result.model.parameters().to_records(free_only=True)})
    else:
        print(result.report())
        print(f"  noise floor {from_si(floor, 'bar'):.3f} bar; model written to {path}")
    return 0
