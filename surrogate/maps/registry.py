"""Map kinds by name, as the command line's ``--maps`` option knows them."""

from __future__ import annotations

from pathlib import Path

from ..data.loaders import load_cfd_samples
from ..errors import InputError
from ..paths import SHIPPED_CFD_SAMPLES, shipped
from ..valve import ValveParameters
from .base import FlowMap, ForceMap
from .grid import GridFlowMap, GridForceMap
from .learned import load_learned_maps

MAP_KINDS = ("grid", "nn", "gp")
TRAINED = Path(__file__).resolve().parents[1] / "trained"


def trained_folder(kind: str) -> Path:
    """Folder of the committed surrogate of a learned kind ("nn" or "gp")."""
    return TRAINED / kind


def build_maps(kind: str, valve: ValveParameters, cfd_samples: str | Path | None = None
               ) -> tuple[FlowMap, ForceMap]:
    """The flow and force map of a kind.

    Parameters
    ----------
    kind : str
        ``"grid"``: interpolation of the CFD samples; ``"nn"`` or ``"gp"``: the committed learned
        surrogates (``surrogate/trained/``); or the path of a surrogate folder written by
        ``training/train.py``.
    valve : ValveParameters
    cfd_samples : path, optional
        CFD-sample file for the grid; default the shipped one.
    """
    if kind == "grid":
        samples = load_cfd_samples(cfd_samples or shipped(SHIPPED_CFD_SAMPLES))
        return GridFlowMap.from_samples(samples), GridForceMap.from_samples(samples, valve)
    if kind in ("nn", "gp"):
        return load_learned_maps(trained_folder(kind))
    if Path(kind).is_dir():
        return load_learned_maps(kind)
    raise InputError(f"unknown map kind {kind!r}: choose one of {', '.join(MAP_KINDS)} or give "
                     "the folder of a trained surrogate")
