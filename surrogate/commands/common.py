"""What the subcommands share: their parser conventions, common options, guarding the outputs,
loading the model and the log, and JSON output."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from ..data import load_bench_log
from ..effects import KNOWN, EffectLibrary, load_effects_file
from ..core.errors import InputError
from ..core.input_files import DEFAULT_LIMIT_MB, LIMIT_VARIABLE, megabytes
from ..maps.registry import MAP_KINDS, MapChoice
from ..model import ValveModel
from ..description.modelfile import PRESETS, load_spec, model_name
from ..core.outputs import Output, check_outputs
from ..core.paths import (PROJECT_ROOT, SHIPPED_BENCH_LOG, SHIPPED_CFD_SAMPLES, SHIPPED_SURROGATES,
                          shipped)
from ..core.progress import Progress
from ..valve import shipped_valve_path

EXIT_CODES = """exit codes:
  0  success
  1  internal error: a bug; one line says so and names the file with the details
  2  bad input or a misused command: the message names the file, line, column, key or
     option and what was expected; nothing is written"""

#: options whose values are files or folders a command reads
INPUT_OPTIONS = ("data", "model", "valve", "effects_file", "input", "cfd", "sequence")
#: what the package ships, which no command may overwrite or write into: the CFD samples and the
#: bench log (their folders, with their READMEs), the trained surrogates and the valve file
SHIPPED_INPUTS = ((SHIPPED_CFD_SAMPLES.parent, "the shipped CFD samples"),
                  (SHIPPED_BENCH_LOG.parent, "the shipped measurements"),
                  (SHIPPED_SURROGATES, "the shipped trained surrogates"),
                  (shipped_valve_path(), "the shipped valve file"))
#: how --maps reads its value, for the options' help
MAPS_HELP = ("a map kind ({kinds}) or the folder of a trained surrogate; a local folder named "
             "like a kind is refused as ambiguous: write ./nn for the folder")


class HelpFormatter(argparse.HelpFormatter):
    """Wraps descriptions as usual but prints the exit-code table as written."""

    def _fill_text(self, text, width, indent):
        if text.startswith("exit codes:"):
            return "".join(indent + line for line in text.splitlines(keepends=True))
        return super()._fill_text(text, width, indent)


class UsageError(InputError):
    """A command line argparse rejects; carries the usage line to print with it."""

    def __init__(self, message: str, usage: str):
        super().__init__(message)
        self.usage = usage


class CommandParser(argparse.ArgumentParser):
    """An ArgumentParser that raises :class:`UsageError` instead of exiting, so the command
    line reports misuse like any other bad input (and as JSON with --json)."""

    def error(self, message: str):
        raise UsageError(f"{self.prog}: {message}", self.format_usage())


def add_command(subparsers, name: str, help: str, description: str, *,
                json_help: str | None = "print the machine-readable result (or error) as JSON "
                                        "on stdout") -> argparse.ArgumentParser:
    """A subcommand's parser with the shared conventions: exit codes in --help, --quiet, and
    --json unless ``json_help`` is None."""
    parser = subparsers.add_parser(name, help=help, description=description, epilog=EXIT_CODES,
                                   formatter_class=HelpFormatter)
    # listed under their own heading in --help (argparse leaves the heading out while it is empty)
    parser.required_options = parser.add_argument_group("required options")
    parser.add_argument("-q", "--quiet", action="store_true",
                        help="no progress lines on stderr (errors are still reported)")
    if json_help:
        parser.add_argument("--json", action="store_true", help=json_help)
    parser.add_argument("--max-input-mb", type=positive_megabytes, metavar="MB",
                        help="the largest bench log or CFD table read [MB] (default "
                             f"${LIMIT_VARIABLE} or {DEFAULT_LIMIT_MB:g}); weight archives may "
                             "unpack to a sixteenth of it, TOML and JSON files a sixty-fourth")
    return parser


def positive_megabytes(text: str) -> float:
    """argparse type: a size in MB > 0, finite (:func:`~surrogate.core.input_files.megabytes`)."""
    try:
        return megabytes(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a size in MB > 0, got {text!r}") from None


def required(parser: argparse.ArgumentParser):
    """The group of a command's required options (made by :func:`add_command`)."""
    return parser.required_options


def non_negative_int(text: str) -> int:
    """argparse type: an integer >= 0."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 0, got {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 0, got {value}")
    return value


def positive_int(text: str) -> int:
    """argparse type: an integer >= 1."""
    value = non_negative_int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 1, got {value}")
    return value


def add_data_options(parser, *, model: bool = True, out_help: str = "output folder",
                     out_required: bool = False,
                     maps_help: str = "replace the model's flow and force maps") -> None:
    """--model, --maps, --data, --effects-file, --valve and --out of the workbench commands."""
    if model:
        required(parser).add_argument(
            "--model", required=True, type=model_option,
            help=f"a preset ({', '.join(PRESETS)}) or a model file (TOML)")
    parser.add_argument("--maps", metavar="KIND", type=maps_option,
                        help=f"{maps_help}: {maps_help_text()}")
    parser.add_argument("--data", help="bench log CSV (default: the shipped one, said so in the "
                                       "first progress line)")
    parser.add_argument("--effects-file", action="append", default=[], metavar="FILE",
                        help="Python file defining custom effects (repeatable)")
    parser.add_argument("--valve", help="valve file (default: the model's, or the shipped valve)")
    (required(parser) if out_required else parser).add_argument("--out", required=out_required,
                                                                help=out_help)


def notice(text: str) -> None:
    """A note on stderr that ``--quiet`` does not silence (an option spelt the old way)."""
    print(text, file=sys.stderr, flush=True)


def output_file(args, name: str, legacy_suffix: str, note=notice) -> tuple[Output, Path]:
    """Where a command that writes one file puts it: ``--out`` names a folder, like every other
    command's, and the file is ``name`` inside it. An ``--out`` ending in ``legacy_suffix`` is
    the spelling of the release before (the file itself): taken as before for this release, and
    said (``note``, a progress callable). Returns the output to guard and the file's path."""
    out = Path(args.out)
    if out.suffix.lower() == legacy_suffix:
        note(f"note: --out {args.out} names a file; --out names a folder now (the file is "
             f"written as FOLDER/{name}). A file name is taken as before in this release.")
        return Output("--out", out, "file"), out
    return Output("--out", out, "folder"), out / name


def legacy_option(args, old: str, new: str, note=notice) -> None:
    """Take ``--old`` for ``--new`` (the release before's spelling), saying so."""
    attribute, target = old.lstrip("-").replace("-", "_"), new.lstrip("-").replace("-", "_")
    value = getattr(args, attribute, None)
    if value is None:
        return
    if getattr(args, target, None) is not None:
        raise InputError(f"{old} and {new} name the same thing: give {new} only")
    note(f"note: {old} is now {new}; {old} is taken as before in this release")
    setattr(args, target, value)


def model_option(text: str) -> str:
    """argparse type of --model: a preset in any case is read as its name (``CFDA`` is cfda, as
    reports write it), so that every message and file names it one way; a path stays as
    given."""
    return model_name(text)


def maps_option(text: str) -> MapChoice:
    """argparse type of --maps: the maps it names, read once (:class:`~surrogate.maps.registry.
    MapChoice`); a kind in any case is read as its name (``GP`` is gp)."""
    return MapChoice.read(text)


def maps_help_text() -> str:
    """What a --maps value may be, for an option's help."""
    return MAPS_HELP.format(kinds=", ".join(MAP_KINDS))


def guard_outputs(args, *outputs: Output) -> None:
    """Refuse outputs that would overwrite an input or cannot be written, before any work.

    The inputs are everything the run reads (:func:`run_inputs`).
    """
    check_outputs([output for output in outputs if output.path], run_inputs(args))


def run_inputs(args) -> list[tuple[Path | str, str]]:
    """Every file and folder a command's run reads, with what it is: the paths its options name,
    what its model file names once resolved
    (:meth:`~surrogate.description.spec.ModelSpec.inputs`: the valve file, the CFD samples, a
    trained surrogate's folder and every file of it), what --maps names, and the shipped
    data, which no command may overwrite."""
    inputs: list[tuple[Path | str, str]] = list(SHIPPED_INPUTS)
    for name in INPUT_OPTIONS:
        value = getattr(args, name, None)
        option = "--" + name.replace("_", "-")
        inputs += [(path, f"given by {option}") for path in
                   (value if isinstance(value, list) else [value]) if path is not None]
    model = getattr(args, "model", None)
    if model:
        where = "preset" if model in PRESETS else "named by " + model
        inputs += [(path, f"{role}, {where}") for path, role in
                   load_spec(model, getattr(args, "valve", None)).inputs()]
    if getattr(args, "maps", None):
        inputs += [(path, f"{role}, given by --maps {args.maps}") for path, role in
                   args.maps.spec(getattr(args, "cfd", None)).inputs()]
    return inputs


def progress_for(args) -> Progress:
    return Progress(quiet=getattr(args, "quiet", False))


def effect_library(args, progress: Progress | None = None) -> EffectLibrary:
    """The built-in effects plus those of the --effects-file files (run: they are the user's
    own code, named on the command line), each checked against the effect contract
    (:func:`surrogate.testing.check_effect`) as it loads."""
    from ..testing import check_effect

    library = KNOWN  # the library and the shape-free terms a model file may name
    for path in args.effects_file:
        custom = load_effects_file(path)
        try:
            library = library + custom
        except InputError as error:
            raise InputError(f"{path}: {error}") from None
        for cls in custom.values():  # the contract the built-in effects pass, before any work
            try:
                check_effect(cls)
            except (AssertionError, InputError) as error:
                raise InputError(f"{path}: {error}") from None
        if progress is not None:
            progress(f"custom effects from {path}: {', '.join(custom)}")
    return library


def bench_log_path(args, progress, option: str = "data") -> Path | str:
    """The bench log a command reads: the one its ``--data`` (or ``option``) names, else the
    shipped one, and then the first progress line says so: data are never chosen silently."""
    given = getattr(args, option, None)
    if given:
        return given
    path = shipped(SHIPPED_BENCH_LOG)
    shown = path.relative_to(PROJECT_ROOT) if path.is_relative_to(PROJECT_ROOT) else path
    progress(f"no --{option} given: using the shipped log {shown}")
    return path


def load_inputs(args, progress: Progress) -> tuple[ValveModel | None, object, EffectLibrary]:
    """The model (if the command takes one), the bench log and the effect library."""
    data = bench_log_path(args, progress)  # first: which data is the first thing said
    library = effect_library(args, progress)
    model = None
    if getattr(args, "model", None):
        spec = load_spec(args.model, args.valve)
        where = args.model if args.model not in PRESETS else f"preset {args.model!r}"
        if getattr(args, "maps", None):
            spec = spec.on_maps(args.maps)
        model = spec.build(library, where)
    log = load_bench_log(data, progress)
    progress(f"{len(log)} samples in {len(log.run_ids)} runs from {log.source}")
    if model is not None:
        _refuse_foreign_runs(model, log, args.model)
    return model, log, library


def _refuse_foreign_runs(model: ValveModel, log, source: str) -> None:
    """Per-run parameters of runs the log lacks would act on no sample: the model was fitted to
    another log, and its other parameters were fitted alongside terms that are missing here."""
    runs = set(log.run_ids)
    for effect in model.effects:
        foreign = sorted({p.scope for p in effect.params.values()
                          if p.scope is not None and p.scope not in runs})
        if foreign:
            shown = ", ".join(foreign[:8]) + (f" and {len(foreign) - 8} more"
                                             if len(foreign) > 8 else "")
            raise InputError(f"{source}: effect {effect.name} has parameters for run(s) {shown}, "
                             f"which {log.source} lacks (its runs: "
                             f"{', '.join(log.run_ids[:8])}{' ...' if len(runs) > 8 else ''}); "
                             "use the log the model was fitted to, or fit it on this one")


def print_json(document: dict) -> None:
    print(json.dumps(document, indent=2, allow_nan=False))
