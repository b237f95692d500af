"""Physical effects that plug into the valve model (see :mod:`.base` for the five stages).

The built-in library holds physically distinct candidates an engineer would consider when a model
and bench data disagree; users add their own with :func:`custom_effect`.
"""

from ..errors import InputError
from .base import KINDS, BalanceState, Effect, FlowState, Parameter
from .custom import custom_effect, load_effects_file
from .flow import DischargeScale, LaminarLeakage
from .flow_force import BackPressureFlowForce, FlowForceScale, NearSeatFlowForce
from .friction import (ConstantFriction, LoadPressureFriction, PilotDifferentialFriction,
                       PilotPressureFriction, SealPressureFriction, ViscousFriction)
from .per_run import PerRunEffect
from .sensors import FlowmeterGain, PilotTransducerOffset, PilotZeroDrift
from .spring import ProgressiveSpring, SpringPreloadOffset

#: the library, by name (custom effects are added when their file is loaded)
REGISTRY: dict[str, type[Effect]] = {}


def register(cls: type[Effect]) -> type[Effect]:
    """Add an effect class to :data:`REGISTRY` under its ``name``."""
    if not cls.name or cls.kind not in KINDS:
        raise InputError(f"{cls.__name__}: an effect needs a name and a kind in {KINDS}")
    existing = REGISTRY.get(cls.name)
    if existing is not None and existing.__qualname__ != cls.__qualname__:
        raise InputError(f"an effect named {cls.name!r} exists already; choose another name")
    REGISTRY[cls.name] = cls
    return cls


def effect_class(name: str) -> type[Effect]:
    """The registered effect class called ``name``."""
    try:
        return REGISTRY[name]
    except KeyError:
        raise InputError(f"unknown effect {name!r}; known effects: {', '.join(REGISTRY)} "
                         "(custom ones need --effects-file)") from None


BUILT_IN = (FlowForceScale, BackPressureFlowForce, NearSeatFlowForce, SpringPreloadOffset,
            ProgressiveSpring, ConstantFriction, LoadPressureFriction, PilotPressureFriction,
            SealPressureFriction, PilotDifferentialFriction, ViscousFriction, DischargeScale,
            LaminarLeakage, PilotTransducerOffset, PilotZeroDrift, FlowmeterGain)
for _cls in BUILT_IN:
    register(_cls)

__all__ = ["BUILT_IN", "KINDS", "REGISTRY", "BalanceState", "Effect", "FlowState", "Parameter",
           "PerRunEffect",
           "custom_effect", "effect_class", "load_effects_file", "register", *(
               c.__name__ for c in BUILT_IN)]
