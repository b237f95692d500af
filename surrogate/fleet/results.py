"""A fleet's results on disk: one JSON file per valve, written as it completes, and the fleet's
tables made from them.

``FOLDER/valves/<serial>.json`` holds what :func:`~.runner.run_valve` returned, with the hashes
of the valve's log and of the model it was fitted with. A rerun reads it back and skips the valve
when both hashes match (and it holds a diagnosis, if one is asked for): a changed log, another
model or a result file that cannot be read is done again, and a batch that was interrupted
resumes where it stopped. Every file is written under a temporary name and renamed into place,
so a file there is always whole. JSON only: a result is never pickled.

A valve whose log was refused stays refused while its log and the model are the same, so it is
not redone either; a valve that failed by an internal error (a bug, a worker that died) is.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd

from .. import __version__
from ..core.errors import InputError
from ..core.input_files import read_input_text
from ..core.outputs import atomic_file
from .tasks import ValveTask

#: the folder of the per-valve result files, inside --out
VALVES_FOLDER = "valves"
#: version of the per-valve record's layout
RECORD_FORMAT = 1
#: quality columns of the fleet table: record key -> column
QUALITY_COLUMNS = {"rms_bar": "rms [bar]", "heldout_rms_bar": "heldout rms [bar]",
                   "noise_floor_bar": "noise floor [bar]"}


def task_identity(task: ValveTask) -> dict:
    """What a record says about its task: the valve, its log and the model, with their
    hashes."""
    return {"format": RECORD_FORMAT, "serial": task.serial, "log": task.log,
            "log_sha256": task.log_sha256, "model_label": task.model_label,
            "model_sha256": task.model_sha256, "diagnose": task.diagnose,
            "version": __version__}


def failure_record(task: ValveTask, kind: str, message: str, *, problems: list | None = None,
                   details: str | None = None) -> dict:
    """The failure part of a record: ``kind`` is "bad input" (the log or the model refused, the
    message locates it) or "internal error"."""
    error = {"kind": kind, "message": message}
    if problems is not None:
        error["problems"] = problems
    if details is not None:
        error["details"] = details
    return {"status": "failed", "error": error}


def result_path(out: str | Path, serial: str) -> Path:
    return Path(out) / VALVES_FOLDER / f"{serial}.json"


def read_result(out: str | Path, serial: str) -> dict | None:
    """The valve's record if its file exists and reads as one; None otherwise (then it is
    redone)."""
    path = result_path(out, serial)
    if not path.is_file() or path.is_symlink():
        return None
    try:
        record = json.loads(read_input_text(path, "a fleet record (JSON)"))
    except (InputError, ValueError, RecursionError):
        return None
    return record if well_formed(record, serial) else None


def well_formed(record, serial: str) -> bool:
    """Whether ``record`` has the layout this version writes (a hand-edited one may not: then
    the valve is done again, not read into the fleet's tables)."""
    if not isinstance(record, dict) or record.get("serial") != serial:
        return False
    if record.get("status") == "failed":
        error = record.get("error")
        return isinstance(error, dict) and all(isinstance(error.get(key), str)
                                               for key in ("kind", "message"))
    if record.get("status") != "ok":
        return False
    numbers = [record.get(key) for key in QUALITY_COLUMNS]
    parameters = record.get("parameters")
    if not all(value is None or _number(value) for value in numbers) \
            or not isinstance(parameters, dict):
        return False
    for parameter in parameters.values():
        if not (isinstance(parameter, dict) and isinstance(parameter.get("unit"), str)
                and _number(parameter.get("value"))
                and (parameter.get("stderr") is None or _number(parameter["stderr"]))):
            return False
    diagnosis = record.get("diagnosis")
    return diagnosis is None or (isinstance(diagnosis, dict) and all(
        isinstance(diagnosis.get(key) or {}, dict) for key in ("top_candidate", "finding")))


def _number(value) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def still_stands(record: dict | None, task: ValveTask) -> bool:
    """Whether an earlier ``record`` is this task's result: the same log bytes and model, a
    diagnosis if one is asked for, and not an internal error (which is worth another try)."""
    if record is None or record.get("format") != RECORD_FORMAT:
        return False
    if (record.get("log_sha256"), record.get("model_sha256")) != (task.log_sha256,
                                                                  task.model_sha256):
        return False
    if record.get("status") == "failed":
        return record.get("error", {}).get("kind") == "bad input"
    return record.get("status") == "ok" and (record.get("diagnose") or not task.diagnose)


def write_result(out: str | Path, record: dict) -> Path:
    """Write a valve's record, whole or not at all."""
    path = result_path(out, record["serial"])
    text = json.dumps(_plain(record), indent=2, allow_nan=False) + "\n"
    with atomic_file(path) as stream:
        stream.write(text)
    return path


def parameter_column(key: str, unit: str) -> str:
    """The fleet table's column of a parameter: ``friction_constant.K1 [N]``."""
    return f"{key} [{unit}]"


def stderr_column(key: str, unit: str) -> str:
    return f"{key} stderr [{unit}]"


def valves_table(records: list[dict]) -> pd.DataFrame:
    """One row per fitted valve: serial, the quality figures, every free parameter with its
    standard error (display units in the column names), and the diagnosis in brief."""
    rows = []
    for record in records:
        if record.get("status") != "ok":
            continue
        row = {"serial": record["serial"]}
        row.update({column: record.get(key) for key, column in QUALITY_COLUMNS.items()})
        row.update(samples=record.get("samples"), runs=record.get("runs"),
                   converged=record.get("converged"))
        for key, parameter in record.get("parameters", {}).items():
            row[parameter_column(key, parameter["unit"])] = parameter["value"]
            row[stderr_column(key, parameter["unit"])] = parameter.get("stderr")
        diagnosis = record.get("diagnosis")
        if diagnosis is not None:
            top = diagnosis.get("top_candidate") or {}
            finding = diagnosis.get("finding") or {}
            row.update({"top candidate": top.get("name"), "top category": top.get("category"),
                        "top ΔBIC": top.get("delta_bic"),
                        "top significant": top.get("significant"),
                        "top summary": top.get("summary"),
                        "finding": finding.get("name"), "finding category": finding.get("category"),
                        "finding kind": finding.get("kind")})
        row["log"] = record.get("log")
        rows.append(row)
    frame = pd.DataFrame(rows)
    if frame.empty:
        return pd.DataFrame({"serial": pd.Series(dtype=str)})
    for column in frame.columns:
        if column.endswith("]"):  # numbers, even where a valve lacks one (NaN, not None)
            frame[column] = pd.to_numeric(frame[column], errors="coerce")
    return frame


def failed_table(records: list[dict]) -> pd.DataFrame:
    """One row per failed valve: serial, log, kind of failure and the located message."""
    rows = [{"serial": r["serial"], "log": r.get("log"), "kind": r["error"]["kind"],
             "message": r["error"]["message"]}
            for r in records if r.get("status") == "failed"]
    return pd.DataFrame(rows, columns=["serial", "log", "kind", "message"])


def write_parquet(frame: pd.DataFrame, path: Path) -> bool:
    """Write ``frame`` as Parquet through pyarrow; False (and nothing written) without it."""
    try:
        import pyarrow  # noqa: F401  (the fleet extra's; pandas needs it for Parquet)
    except ImportError:
        return False
    frame.to_parquet(path, index=False)
    return True


def _plain(value):
    """JSON data without NumPy scalars and with None for NaN."""
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, (np.floating, float)):
        return float(value) if np.isfinite(value) else None
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.bool_):
        return bool(value)
    return value
