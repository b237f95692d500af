"""Flow and force maps behind one interface (:mod:`.base`): orifice, grid, and learned maps.

Each built-in map kind registers itself (:mod:`.registry`) from its own module; importing them
here, in the order help texts and errors list the kinds, registers all of them whichever module
of the package is imported first.
"""

from .base import FlowMap, ForceMap, MapResult
from .orifice import OrificeFlowMap, UniformPressureForceMap  # the kind "orifice"
from .grid import GridFlowMap, GridForceMap  # the kind "grid"
from . import nn  # noqa: F401 -- registers the kind "nn"
from . import gp  # noqa: F401 -- registers the kind "gp"

__all__ = ["FlowMap", "ForceMap", "GridFlowMap", "GridForceMap", "MapResult", "OrificeFlowMap",
           "UniformPressureForceMap"]
