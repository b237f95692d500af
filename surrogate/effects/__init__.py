"""Physical effects that plug into the valve model (see :mod:`.base` for the five stages).

The built-in :data:`LIBRARY` holds physically distinct candidates an engineer would consider when
a model and bench data disagree; users add their own with :func:`custom_effect` in a file of
their own, loaded as a library of its own (``LIBRARY + load_effects_file(path)``).
"""

from .base import CATEGORIES, KINDS, BalanceState, Effect, FlowState
from .custom import custom_effect, load_effects_file
from .flow import DischargeScale, LaminarLeakage
from .flow_force import BackPressureFlowForce, FlowForceScale, NearSeatFlowForce
from .friction import (ConstantFriction, LoadPressureFriction, PilotDifferentialFriction,
                       PilotPressureFriction, SealPressureFriction, ViscousFriction)
from .library import EffectLibrary
from .per_run import PerRunEffect
from .sensors import FlowmeterGain, PilotTransducerOffset, PilotZeroDrift
from .spring import ProgressiveSpring, SpringPreloadOffset
from ..parameters import Parameter

BUILT_IN = (FlowForceScale, BackPressureFlowForce, NearSeatFlowForce, SpringPreloadOffset,
            ProgressiveSpring, ConstantFriction, LoadPressureFriction, PilotPressureFriction,
            SealPressureFriction, PilotDifferentialFriction, ViscousFriction, DischargeScale,
            LaminarLeakage, PilotTransducerOffset, PilotZeroDrift, FlowmeterGain)

#: the built-in effects, by name
LIBRARY = EffectLibrary(BUILT_IN)

__all__ = ["BUILT_IN", "CATEGORIES", "KINDS", "LIBRARY", "BalanceState", "Effect", "EffectLibrary", "FlowState",
           "Parameter", "PerRunEffect", "custom_effect", "load_effects_file",
           *(c.__name__ for c in BUILT_IN)]
