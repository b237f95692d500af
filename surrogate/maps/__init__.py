"""Flow and force maps behind one interface (:mod:`.base`): orifice, grid, and learned maps."""

from .base import FlowMap, ForceMap, MapResult
from .grid import GridFlowMap, GridForceMap
from .orifice import OrificeFlowMap, UniformPressureForceMap

__all__ = ["FlowMap", "ForceMap", "GridFlowMap", "GridForceMap", "MapResult", "OrificeFlowMap",
           "UniformPressureForceMap"]
