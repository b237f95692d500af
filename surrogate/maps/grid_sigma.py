"""The grid maps' calibration and accuracy, shipped for the shipped CFD samples as the learned
kinds' are.

A grid's σ comes from its own errors on samples left out of it (:class:`.grid.GridUncertainty`):
rebuilding the grid for every cross-validation fold and fitting the calibration's constants
takes about 3 CPU seconds, which every command on grid maps paid again (a tenth of a diagnosis).
The learned kinds ship their calibration with their weights (``surrogate/trained/<kind>``); the
grid ships its own here, for the samples and valve it was computed from, recognised by a
fingerprint of their values. Any other sample set or valve is calibrated on first use, as before.

Beside it the file keeps the grid's cross-validation summary (:func:`.crossval.summary`), as a
learned kind's manifest keeps its own: the workflow ranks the kinds by it at every start
(:func:`.crossval.most_accurate_kind`), and rebuilding the grid for its folds was a tenth of a
workflow on a small log, for the same numbers every time.

``python training/train.py --kinds grid`` writes it; a test recomputes it and compares, so it
cannot drift from what the samples give.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from pathlib import Path

import numpy as np

from ..data.loaders import CfdSamples
from ..core.paths import SHIPPED_SURROGATES
from ..valve import ValveParameters
from .sigma import SigmaCalibration

#: where the shipped grid calibration lives
SHIPPED_GRID_CALIBRATION = SHIPPED_SURROGATES / "grid" / "calibration.json"
FORMAT_VERSION = 1


def fingerprint(samples: CfdSamples, valve: ValveParameters) -> str:
    """SHA-256 of the samples' values (columns and rows in order) and of the valve's parameters:
    what a grid's cross-validated errors, and so its calibration, are computed from."""
    digest = hashlib.sha256()
    frame = samples.frame
    for column in frame.columns:
        digest.update(str(column).encode())
        values = frame[column].to_numpy()
        digest.update(np.ascontiguousarray(values, float).tobytes() if values.dtype.kind in "fiub"
                      else "\x1f".join(map(str, values)).encode())
    digest.update(json.dumps(dataclasses.asdict(valve), sort_keys=True, default=str).encode())
    return digest.hexdigest()


def shipped_calibrations(samples: CfdSamples, valve: ValveParameters,
                         path: Path = SHIPPED_GRID_CALIBRATION) -> dict | None:
    """{"flow": ..., "force": ...} :class:`~.sigma.SigmaCalibration` stored at ``path`` for
    exactly these samples and valve, or None (no file, another format, other data)."""
    stored = _stored_for(samples, valve, path)
    if stored is None:
        return None
    return {name: SigmaCalibration.from_dict(stored[name]) for name in ("flow", "force")}


def shipped_summary(samples: CfdSamples, valve: ValveParameters,
                    path: Path = SHIPPED_GRID_CALIBRATION) -> dict | None:
    """The cross-validation summary stored at ``path`` for exactly these samples and valve
    (per scheme, as :func:`.crossval.summary` gives it), or None (no file or no summary in it,
    another format, other data)."""
    stored = _stored_for(samples, valve, path)
    return None if stored is None else stored.get("cross_validation")


def _stored_for(samples: CfdSamples, valve: ValveParameters, path: Path) -> dict | None:
    """The file at ``path`` as stored, if it is of this format and for exactly these samples
    and valve; else None (no file, unreadable, another format, other data)."""
    try:
        stored = json.loads(Path(path).read_text())
    except (OSError, ValueError):
        return None
    if (stored.get("format_version") != FORMAT_VERSION
            or stored.get("fingerprint") != fingerprint(samples, valve)):
        return None
    return stored


def write_calibrations(path: Path, samples: CfdSamples, valve: ValveParameters,
                       calibrations: dict, summary: dict | None = None) -> None:
    """Store ``calibrations`` (and the cross-validation ``summary`` they give, where given) for
    ``samples`` and ``valve`` at ``path`` (its folder made)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    data = {"format_version": FORMAT_VERSION, "fingerprint": fingerprint(samples, valve),
            **{name: calibrations[name].to_dict() for name in ("flow", "force")}}
    if summary is not None:
        data["cross_validation"] = summary
    path.write_text(json.dumps(data, indent=2) + "\n")
