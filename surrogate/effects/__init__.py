"""Physical effects that plug into the valve model's force balance (see :mod:`.base`)."""

from .base import BalanceState, Effect, Parameter
from .flow_force import FlowForceScale
from .friction import CoulombFriction

#: built-in effects by name
REGISTRY: dict[str, type[Effect]] = {cls.name: cls for cls in (CoulombFriction, FlowForceScale)}

__all__ = ["REGISTRY", "BalanceState", "CoulombFriction", "Effect", "FlowForceScale", "Parameter"]
