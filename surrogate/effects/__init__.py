"""Physical effects that plug into the valve model (see :mod:`.base` for the five stages).

The built-in :data:`LIBRARY` holds physically distinct candidates an engineer would consider when
a model and bench data disagree; users add their own with :func:`custom_effect` in a file of
their own, loaded as a library of its own (``LIBRARY + load_effects_file(path)``). The
shape-free terms (:mod:`.shapes`, :data:`SHAPES`) are no library candidates: a diagnosis tries
them beside the library; nor are the maps' calibration per opening (:mod:`.per_opening`), which
the workflow fits last. A model file may name either (:data:`KNOWN`).
"""

from .base import CATEGORIES, KINDS, BalanceState, Effect, FlowState
from .per_opening import CALIBRATIONS
from .custom import custom_effect, load_effects_file
from .flow import DischargeScale, LaminarLeakage
from .flow_force import BackPressureFlowForce, FlowForceScale, NearSeatFlowForce
from .friction import (ConstantFriction, LoadPressureFriction, PilotDifferentialFriction,
                       PilotPressureFriction, SealPressureFriction, ViscousFriction)
from .library import EffectLibrary
from .per_run import PerRunEffect
from .sensors import FlowmeterGain, PilotTransducerOffset, PilotZeroDrift
from .shapes import SHAPE_FREE, ShapeFreeEffect
from .spring import ProgressiveSpring, SpringPreloadOffset
from ..parameters import Parameter

BUILT_IN = (FlowForceScale, BackPressureFlowForce, NearSeatFlowForce, SpringPreloadOffset,
            ProgressiveSpring, ConstantFriction, LoadPressureFriction, PilotPressureFriction,
            SealPressureFriction, PilotDifferentialFriction, ViscousFriction, DischargeScale,
            LaminarLeakage, PilotTransducerOffset, PilotZeroDrift, FlowmeterGain)

#: the built-in effects, by name
LIBRARY = EffectLibrary(BUILT_IN)
#: the shape-free terms, by name
SHAPES = EffectLibrary(SHAPE_FREE)
#: the maps' calibration per opening, by name
CALIBRATION = EffectLibrary(CALIBRATIONS)
#: every effect a model file may name without an effects file
KNOWN = LIBRARY + SHAPES + CALIBRATION

__all__ = ["BUILT_IN", "CALIBRATION", "CALIBRATIONS", "CATEGORIES", "KINDS", "KNOWN", "LIBRARY",
           "SHAPES", "SHAPE_FREE",
           "BalanceState", "Effect", "EffectLibrary", "FlowState", "Parameter", "PerRunEffect",
           "ShapeFreeEffect", "custom_effect", "load_effects_file",
           *(c.__name__ for c in BUILT_IN)]
