"""Map kinds by name, as the command line's ``--maps`` option knows them."""

from __future__ import annotations

from pathlib import Path

from ..data.loaders import load_cfd_samples
from ..errors import InputError
from ..paths import SHIPPED_CFD_SAMPLES, shipped
from ..valve import ValveParameters
from .base import FlowMap, ForceMap
from .grid import GridFlowMap, GridForceMap

MAP_KINDS = ("grid",)


def build_maps(kind: str, valve: ValveParameters, cfd_samples: str | Path | None = None
               ) -> tuple[FlowMap, ForceMap]:
    """The flow and force map of a kind.

    Parameters
    ----------
    kind : str
        ``"grid"``: interpolation of the CFD samples.
    valve : ValveParameters
    cfd_samples : path, optional
        CFD-sample file for the grid; default the shipped one.
    """
    if kind == "grid":
        samples = load_cfd_samples(cfd_samples or shipped(SHIPPED_CFD_SAMPLES))
        return GridFlowMap.from_samples(samples), GridForceMap.from_samples(samples, valve)
    raise InputError(f"unknown map kind {kind!r}; choose one of {', '.join(MAP_KINDS)}")
