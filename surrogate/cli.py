"""``python -m surrogate`` (installed as ``cbv-surrogate``): the command line.

Each subcommand lives in its own module under :mod:`surrogate.commands` and exposes
``register(subparsers)``, which adds its parser (with :func:`surrogate.commands.common.add_command`)
and sets ``func`` to the function that runs it.

Whatever goes wrong, the user sees one message, never a traceback:

* exit 2, bad input or a misused command: the message names the file, line, column, key or option
  and what was expected;
* exit 1, an internal error (a bug): one line says so and names the file holding the details;
* exit 130 on Ctrl-C (SIGINT) and 143 on SIGTERM, after removing whatever was half-written
  (:mod:`surrogate.core.interrupts`).

With ``--json`` the error is also a JSON document on stdout, like the results.
"""

from __future__ import annotations

import argparse
import datetime
import gc
import json
import os
import sys
import tempfile
import traceback

from . import __version__
from .core.memory import loading

# The commands import pandas, SciPy and the package: modules, classes and functions that live
# as long as the process, none of them garbage, which the cyclic collector would otherwise walk
# some two hundred times while they load, and again in every full collection after. So it
# pauses while they load, and then leaves them out of its walks (gc.freeze).
with loading():
    from .commands import COMMANDS
    from .commands.common import EXIT_CODES, CommandParser, HelpFormatter, UsageError
    from .data.errors import DataFileError
    from .core.errors import InputError
    from .core.input_files import LIMIT_VARIABLE
    from .core.interrupts import exit_code, handling_interrupts
    from .core.parallel import blas_limited

EXIT_OK, EXIT_FAILURE, EXIT_BAD_INPUT = 0, 1, 2


def program_name() -> str:
    """How the user called us: the installed script or the module."""
    return "cbv-surrogate" if os.path.basename(sys.argv[0]) == "cbv-surrogate" \
        else "python -m surrogate"


def build_parser() -> argparse.ArgumentParser:
    parser = CommandParser(
        prog=program_name(),
        description="Counterbalance-valve models from CFD maps and bench data. Run a command "
                    "with --help for its options.",
        epilog=EXIT_CODES, formatter_class=HelpFormatter)
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for command in COMMANDS:
        command.register(subparsers)
    return parser


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    as_json = "--json" in argv
    try:
        args = build_parser().parse_args(argv)
    except UsageError as error:
        return _report(error, EXIT_BAD_INPUT, as_json, kind="usage")
    except SystemExit as done:  # --help and --version print and stop here
        return int(done.code or 0)
    as_json = bool(getattr(args, "json", False))
    with handling_interrupts():
        return _run(args, argv, as_json)


def console() -> None:
    """``cbv-surrogate`` and ``python -m surrogate``: run the command line, then end the
    process with its exit code.

    The process ends with the command, and its memory goes back to the system with it. The
    interpreter's finalisation would first walk every object in full garbage collections, for
    nothing: 0.3–0.5 CPU s after a workflow on an off-library log (about 265,000 tracked
    objects), a twentieth of its run. Frozen (``gc.freeze``), they are left out of those walks
    (finalisation then took 0.08–0.12 CPU s; what refers to nothing else is still freed as the
    modules are torn down). :func:`main` itself leaves the collector as it was, for callers
    that go on."""
    code = main()
    gc.freeze()
    sys.exit(code)


def _run(args, argv: list[str], as_json: bool) -> int:
    bound = getattr(args, "max_input_mb", None)
    before = os.environ.get(LIMIT_VARIABLE)
    if bound is not None:
        # through the environment, so that a fleet's worker processes read with the same bound
        os.environ[LIMIT_VARIABLE] = repr(bound)
    try:
        with blas_limited():  # every command's matrices are small (surrogate.core.parallel)
            return args.func(args) or EXIT_OK
    except InputError as error:
        return _report(error, EXIT_BAD_INPUT, as_json)
    except FileNotFoundError as error:
        return _report(InputError(f"{error.filename or error}: no such file"), EXIT_BAD_INPUT,
                       as_json)
    except BrokenPipeError:  # output piped into `head` and the like: not an error
        sys.stderr.close()
        return EXIT_OK
    except KeyboardInterrupt as interruption:  # Ctrl-C or SIGTERM: staging already removed
        code = exit_code(interruption)
        print(f"interrupted ({'SIGTERM' if code == 143 else 'Ctrl-C'}): stopped; no output "
              "was left half-written", file=sys.stderr)
        return code
    except Exception as error:  # a bug: say so in one line, keep the traceback in a file
        details = _write_details(argv)
        return _report(error, EXIT_FAILURE, as_json, kind="internal error", details=details)
    finally:
        if bound is not None:  # a run in-process (a test, a notebook) leaves the bound as it was
            if before is None:
                os.environ.pop(LIMIT_VARIABLE, None)
            else:
                os.environ[LIMIT_VARIABLE] = before


def _report(error: BaseException, code: int, as_json: bool, kind: str = "bad input",
            details: str | None = None) -> int:
    if code == EXIT_FAILURE:
        message = (f"internal error: {type(error).__name__}: {error}. This is a bug in "
                   f"cbv-surrogate, not in your input; the details are in {details}")
    else:
        message = str(error)
    if isinstance(error, UsageError):
        print(error.usage.rstrip(), file=sys.stderr)
    print(message if code == EXIT_FAILURE else f"error: {message}", file=sys.stderr)
    if as_json:  # the same error for programs, on stdout where they read the results
        document = {"kind": kind, "exit_code": code, "message": message}
        if isinstance(error, DataFileError):
            document["problems"] = [vars(problem) for problem in error.problems]
        if isinstance(error, UsageError):
            document["usage"] = error.usage.strip()
        if details:
            document["details"] = details
        print(json.dumps({"error": document}, indent=2))
    return code


def _write_details(argv: list[str]) -> str:
    """Write the traceback of the error being handled to a file; return the file's path."""
    stamp = datetime.datetime.now().strftime("%Y%m%d-%H%M%S")
    handle, path = tempfile.mkstemp(prefix=f"cbv-surrogate-error-{stamp}-", suffix=".txt")
    with os.fdopen(handle, "w", encoding="utf-8") as stream:
        stream.write(f"cbv-surrogate {__version__}, Python {sys.version.split()[0]}\n")
        stream.write(f"command: {program_name()} {' '.join(argv)}\n\n")
        stream.write(traceback.format_exc())
    return path
