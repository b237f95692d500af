"""``fleet``: one model fitted (and optionally diagnosed) on every valve's bench log of a batch, on
this machine or a Dask cluster; the population's statistics and the valves that stand out."""

from __future__ import annotations

import json
import math
import os
import time
from pathlib import Path

import pandas as pd

from ..core.errors import InputError
from ..fleet.population import (
    OUTLIER_LEVEL,
    correlations,
    robust_outliers,
    spread_floors,
    summary,
)
from ..fleet.results import (
    QUALITY_COLUMNS,
    VALVES_FOLDER,
    failed_table,
    parameter_column,
    read_result,
    result_path,
    stderr_column,
    still_stands,
    valves_table,
    write_parquet,
    write_result,
)
from ..fleet.runner import DASK_EXTRA, DaskCluster, LocalPool
from ..fleet.tasks import ValveTask, file_sha256, find_logs, model_sha256
from ..description.modelfile import PRESETS, load_spec
from ..core.outputs import Output, atomic_directory, check_outputs
from ..core.parallel import available_cores
from ..core.progress import duration
from .common import (
    EXIT_CODES,
    add_command,
    effect_library,
    maps_help_text,
    maps_option,
    model_option,
    notice,
    positive_int,
    print_json,
    progress_for,
    required,
    run_inputs,
)

#: the environment variable naming a Dask scheduler when --scheduler does not
SCHEDULER_VARIABLE = "CBV_SCHEDULER"
#: exit code when some valves failed and the others were written
EXIT_SOME_FAILED = 3
FLEET_EXIT_CODES = EXIT_CODES + f"""
  {EXIT_SOME_FAILED}  some valves failed (a log refused, a fit impossible): each is listed with its
     located error in FOLDER/failed.csv, the others are written"""
#: the quality figure the outliers are judged on besides the parameters
RMS_FIGURE = QUALITY_COLUMNS["rms_bar"]


def register(subparsers) -> None:
    parser = add_command(
        subparsers, "fleet", help="fit (and diagnose) a model on every valve's bench log of a "
                                  "batch; population statistics and outliers",
        description="Fit the model's free parameters to each valve's bench log (one CSV per "
                    "valve, named by its serial), on local worker processes or on a Dask "
                    "cluster, and report the fleet: per valve the fitted parameters with "
                    "standard errors, the RMS, the RMS on held-out runs and the noise floor "
                    "(and with --diagnose the diagnosis' top candidate); across the fleet the "
                    "median, robust spread and correlations of the parameters, and the valves "
                    "that stand out by robust distance, with the parameter that makes each "
                    "stand out. Each valve's result is written as it completes "
                    "(FOLDER/valves/SERIAL.json): a rerun skips the valves whose log and model "
                    "are unchanged, so an interrupted batch resumes. A log that is refused does "
                    "not stop the fleet: it is listed in FOLDER/failed.csv and the exit code "
                    f"is {EXIT_SOME_FAILED}.")
    parser.epilog = FLEET_EXIT_CODES
    required(parser).add_argument(
        "--data", required=True,
        help="a folder of bench logs (every *.csv in it, one per valve, the file's name its "
             "serial) or a glob of them, quoted: 'bench/*/V*.csv'")
    required(parser).add_argument(
        "--model", required=True, type=model_option,
        help=f"a preset ({', '.join(PRESETS)}) or a model file (TOML), as fit takes it")
    required(parser).add_argument(
        "--out", required=True,
        help="output folder: valves/SERIAL.json per valve, valves.csv and .parquet, "
             "population.json, outliers.csv, failed.csv, report.html; kept between runs")
    parser.add_argument("--maps", metavar="KIND", type=maps_option,
                        help=f"replace the model's flow and force maps: {maps_help_text()}")
    parser.add_argument("--valve", help="valve file (default: the model's, or the shipped valve)")
    parser.add_argument("--effects-file", action="append", default=[], metavar="FILE",
                        help="Python file defining custom effects (repeatable)")
    parser.add_argument("--diagnose", action="store_true",
                        help="also diagnose each fitted valve (as `diagnose` does; several "
                             "times the fit's time)")
    parser.add_argument("--scheduler", metavar="ADDRESS",
                        help="run on the Dask cluster whose scheduler is at ADDRESS "
                             f"(tcp://host:8786; default: ${SCHEDULER_VARIABLE} if set; needs "
                             f"the fleet extra: {DASK_EXTRA}); its workers must see the logs at "
                             "the same paths")
    parser.add_argument("--workers", type=positive_int,
                        help="local worker processes, one valve each at a time (default: the "
                             f"cores, here {available_cores()})")
    parser.set_defaults(func=run)


#: what a fleet writes into --out beside the records (and valves.parquet with pyarrow)
FLEET_FILES = ("valves.csv", "failed.csv", "outliers.csv", "population.json", "report.html")


def run(args) -> int:
    progress = progress_for(args)
    logs = find_logs(args.data)
    executor = _executor(args)
    # the per-valve records are written into OUT/valves as they come, not staged: every place
    # of them is checked now, with the tables the fleet writes at the end
    entries = (f"{VALVES_FOLDER}/", *(f"{VALVES_FOLDER}/{serial}.json" for serial, _ in logs),
               *FLEET_FILES, "valves.parquet")
    check_outputs([Output("--out", args.out, "folder", entries)],
                  run_inputs(args) + [(path, f"{serial}'s bench log, given by --data")
                                      for serial, path in logs])
    library = effect_library(args, progress)
    spec = load_spec(args.model, args.valve)
    if args.maps:
        spec = spec.on_maps(args.maps)
    where = args.model if args.model not in PRESETS else f"preset {args.model!r}"
    model = spec.build(library, where)  # a model that cannot be built stops here, exit 2
    model_toml = spec.to_toml()  # its paths absolute: a worker reads it anywhere
    effects = tuple(str(Path(path).resolve()) for path in args.effects_file)
    model_hash = model_sha256(model_toml, effects)
    tasks = [ValveTask(serial, str(path.resolve()), file_sha256(path), model_toml, model_hash,
                       args.model, effects, args.diagnose) for serial, path in logs]
    records = {}
    pending = []
    for task in tasks:
        earlier = read_result(args.out, task.serial)
        path = result_path(args.out, task.serial)
        if earlier is None and path.exists():
            progress(f"{path}: not a record as this version writes them (edited or damaged); "
                     f"{task.serial} is done again")
        if still_stands(earlier, task):
            records[task.serial] = earlier
        else:
            pending.append(task)
    work = "fit and diagnose" if args.diagnose else "fit"
    progress(f"{len(tasks)} valve(s) in {args.data}: {len(tasks) - len(pending)} done before "
             f"with this log and model (skipped), {len(pending)} to {work} on "
             f"{executor.describe()}")
    if pending:
        _run_pending(executor, pending, records, args.out, progress)
    ordered = [records[task.serial] for task in tasks]
    document = _write_population(args, ordered, model, progress)
    failures = document["failed"]
    if args.json:
        print_json(document)
    else:
        print(_text(document))
    return EXIT_SOME_FAILED if failures else 0


def _executor(args):
    """A Dask cluster if --scheduler (or the environment) names one, else the local pool."""
    scheduler, source = args.scheduler, "--scheduler"
    if not scheduler and os.environ.get(SCHEDULER_VARIABLE):
        scheduler, source = os.environ[SCHEDULER_VARIABLE], f"${SCHEDULER_VARIABLE}"
    if scheduler and args.workers is not None:
        raise InputError(f"--workers {args.workers} is for the local pool, but {source} "
                         f"{scheduler} names a Dask cluster, whose workers are its own; give one "
                         + ("or the other" if source == "--scheduler" else
                            f"(unset {SCHEDULER_VARIABLE} to run locally)"))
    if scheduler:
        cluster = DaskCluster(scheduler, source)
        cluster.reachable()  # a wrong address is told now, within seconds
        return cluster
    return LocalPool(args.workers or available_cores())


def _run_pending(executor, pending: list[ValveTask], records: dict, out, progress) -> None:
    """Run the pending valves, writing each result as it completes."""
    executor.check()
    (Path(out) / VALVES_FOLDER).mkdir(parents=True, exist_ok=True)
    began = time.perf_counter()
    done = 0
    try:
        for record in executor.results(pending):
            write_result(out, record)
            records[record["serial"]] = record
            done += 1
            spent = time.perf_counter() - began
            left = spent / done * (len(pending) - done)
            progress(f"{_valve_line(record)} [{done}/{len(pending)}"
                     + (f", about {duration(left)} left" if done < len(pending) else "") + "]")
    except KeyboardInterrupt:
        notice(f"{done} valve(s) finished in this run are kept in {Path(out) / VALVES_FOLDER}; "
               "the same command resumes with the others")
        raise


def _valve_line(record: dict) -> str:
    if record["status"] != "ok":
        return f"{record['serial']}: FAILED ({record['error']['kind']}): " + \
            _located(record["error"]["message"])
    line = (f"{record['serial']}: rms {record['rms_bar']:.3f} bar"
            + (f", held out {record['heldout_rms_bar']:.3f} bar"
               if record.get("heldout_rms_bar") is not None else "")
            + f", noise floor {record['noise_floor_bar']:.3f} bar ({record['seconds']:.1f} s)")
    finding = ((record.get("diagnosis") or {}).get("finding") or {}).get("name")
    if record.get("diagnosis") is not None:
        line += f"; finding: {finding or 'none'}"
    return line


def _located(message: str) -> str:
    """An error's first line and, for a refused file, its first problem (file, line, column):
    what one line of progress can hold (failed.csv holds the whole message)."""
    lines = [line.strip().removeprefix("- ") for line in message.splitlines() if line.strip()]
    return " ".join(lines[:2]) + (f" (and {len(lines) - 2} more lines)" if len(lines) > 2 else "")


def _write_population(args, records: list[dict], model, progress) -> dict:
    """valves.csv/.parquet, failed.csv, population.json, outliers.csv and report.html, written
    together; returns the JSON document the command prints."""
    table = valves_table(records)
    failed = failed_table(records)
    parameters = _parameter_columns(records)
    figures = [c for c in [*parameters, RMS_FIGURE] if c in table]
    floors = spread_floors(table, {column: stderr_column(key, unit) for column, (key, unit)
                                   in parameters.items()}) if len(table) else {}
    statistics = summary(table, figures, floors) if figures else {}
    correlation = correlations(table, figures) if figures else None
    analysis = robust_outliers(table.set_index("serial"), figures, floors) if figures else \
        robust_outliers(table.set_index("serial"), [])
    if len(table):
        table["robust distance"] = analysis.distances.reindex(table["serial"]).to_numpy()
        table["outlier"] = table["serial"].isin(analysis.flagged())
    outliers = analysis.table()
    document = {
        "out": str(args.out), "model": args.model, "valves": len(records),
        "fitted": len(table), "diagnosed": bool(args.diagnose),
        "failed": [{"serial": r.serial, "kind": r.kind, "message": r.message}
                   for r in failed.itertuples()],
        "population": {
            "figures": statistics,
            "correlations": None if correlation is None else {
                "method": "spearman", "figures": list(correlation.columns),
                "matrix": [[None if math.isnan(v) else round(float(v), 4) for v in row]
                           for row in correlation.to_numpy()]},
            "outliers": {"method": analysis.method, "level": OUTLIER_LEVEL,
                         "cutoff": None if analysis.cutoff != analysis.cutoff
                         else round(analysis.cutoff, 4),
                         "figures": analysis.columns}},
        "outliers": [{"serial": o.serial, "robust_distance": round(o.distance, 3),
                      "stands_out_by": [{"figure": name, "z": round(z, 2)}
                                        for name, z in o.standing_out]}
                     for o in analysis.outliers]}
    if args.diagnose and "finding" in table:
        document["population"]["findings"] = {
            str(name): int(count) for name, count in table["finding"].value_counts().items()}
    files = list(FLEET_FILES)
    # the report draws with matplotlib, half a second of a start: only when it is written
    from ..fleet.report import FleetSummary, write_fleet_report

    with atomic_directory(args.out) as staging:
        table.to_csv(staging / "valves.csv", index=False)
        if write_parquet(table, staging / "valves.parquet"):
            files.insert(1, "valves.parquet")
        else:
            notice("note: valves.parquet not written: pyarrow is not installed (it comes with "
                   f"the fleet extra, {DASK_EXTRA}); valves.csv holds the same table")
        failed.to_csv(staging / "failed.csv", index=False)
        outliers.to_csv(staging / "outliers.csv", index=False)
        population = {"model": args.model, "valves": len(table), "failed": len(failed),
                      **document["population"]}
        (staging / "population.json").write_text(
            json.dumps(population, indent=2, allow_nan=False) + "\n", encoding="utf-8")
        write_fleet_report(staging / "report.html", FleetSummary(
            table, figures, {column: key for column, (key, _) in parameters.items()},
            statistics, correlation if correlation is not None else pd.DataFrame(), analysis, failed,
            args.model, bool(args.diagnose)), model, records)
    document["files"] = [f"{VALVES_FOLDER}/", *files]
    progress(f"wrote {', '.join(document['files'])} to {args.out}")
    return document


def _parameter_columns(records: list[dict]) -> dict[str, tuple[str, str]]:
    """Column -> (key, unit) of every free parameter of the valve (not of one bench run) that
    the fitted valves have, in the model's order."""
    columns = {}
    for record in records:
        for key, parameter in (record.get("parameters") or {}).items():
            if record.get("status") == "ok" and "run" not in parameter:
                columns.setdefault(parameter_column(key, parameter["unit"]),
                                   (key, parameter["unit"]))
    return columns


def _text(document: dict) -> str:
    lines = [(f"fleet of {document['valves']} valve(s), model {document['model']}: "
             f"{document['fitted']} fitted, {len(document['failed'])} failed")]
    figures = document["population"]["figures"]
    if figures:
        width = max(len(name) for name in figures) + 2
        lines.append(f"  {'figure':<{width}}{'median':>12}{'spread':>12}")
        for name, stats in figures.items():
            lines.append(f"  {name:<{width}}{stats['median']:>12.5g}"
                         f"{stats['spread_used']:>12.3g}")
    outliers = document["outliers"]
    method = document["population"]["outliers"]
    if method["method"] == "none":
        lines.append("  outliers: too few valves to tell")
    else:
        lines.append(f"  {len(outliers)} outlier(s) by robust distance > {method['cutoff']:.2f} "
                     f"({method['method']})" + (":" if outliers else ""))
        for outlier in outliers:
            lines.append(f"    {outlier['serial']}: distance {outlier['robust_distance']:.1f}, "
                         "by " + "; ".join(f"{entry['figure']} (z = {entry['z']:+.1f})"
                                          for entry in outlier["stands_out_by"]))
    for failure in document["failed"]:
        lines.append(f"  FAILED {failure['serial']} ({failure['kind']}): "
                     + _located(failure["message"]))
    lines.append(f"  written to {document['out']}: {', '.join(document['files'])}")
    return "\n".join(lines)
