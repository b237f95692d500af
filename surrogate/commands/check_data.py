"""``check-data PATH [PATH ...]``: validate CFD-sample files and bench logs and summarise them."""

from __future__ import annotations

import json
import sys

from ..data import DataFileError, load_any
from ..data.summary import format_summary, summarize


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "check-data", help="validate and summarise CFD-sample files and bench logs",
        description="Recognise each file as CFD samples or a bench log, validate it against the "
                    "documented schema and print a summary. Exits 2 if any file is rejected; "
                    "every problem found is listed with its line and column.")
    parser.add_argument("paths", nargs="+", metavar="PATH", help="CSV file(s) to check")
    parser.add_argument("--json", action="store_true", help="print the summaries as JSON")
    parser.set_defaults(func=run)


def run(args) -> int:
    summaries, failed = [], False
    for path in args.paths:
        try:
            table = load_any(path)
        except DataFileError as error:
            print(f"error: {error}", file=sys.stderr)
            failed = True
            continue
        summary = summarize(table)
        summaries.append(summary)
        if not args.json:
            print(format_summary(summary))
    if args.json:
        print(json.dumps(summaries if len(args.paths) > 1 else (summaries or [None])[0], indent=2))
    return 2 if failed else 0
