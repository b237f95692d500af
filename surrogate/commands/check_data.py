"""``check-data PATH [PATH ...]``: validate CFD-sample files and bench logs and summarise them."""

from __future__ import annotations

import json
import sys

from ..data import DataFileError, load_any
from ..data.summary import format_summary, summarize
from .common import add_command, progress_for


def register(subparsers) -> None:
    parser = add_command(
        subparsers, "check-data", help="validate and summarise CFD-sample files and bench logs",
        description="Recognise each file as CFD samples or a bench log, validate it against the "
                    "documented schema and its plausibility limits, and print a summary. Exits 2 "
                    "if any file is rejected; every problem found is listed with its line and "
                    "column.",
        json_help="print the summaries (or the errors) as JSON on stdout")
    parser.add_argument("paths", nargs="+", metavar="PATH", help="CSV file(s) to check")
    parser.set_defaults(func=run)


def run(args) -> int:
    summaries, errors = [], []
    progress = progress_for(args)
    for path in args.paths:
        try:
            table = load_any(path, progress)
        except DataFileError as error:
            errors.append(error)
            print(f"error: {error}", file=sys.stderr)
            continue
        summary = summarize(table)
        summaries.append(summary)
        if not args.json:
            print(format_summary(summary))
    if args.json:
        document = summaries if len(args.paths) > 1 else (summaries or [None])[0]
        if errors:
            document = {"kind": "bad input", "exit_code": 2,
                        "message": "\n".join(str(e) for e in errors),
                        "problems": [vars(p) for e in errors for p in e.problems],
                        "accepted": summaries}
            document = {"error": document}
        print(json.dumps(document, indent=2))
    return 2 if errors else 0
