"""Errors of the bench's sensors: the model is fed measured values, the valve sees true ones."""

from __future__ import annotations

from ..units import BAR
from .base import Effect, Parameter


class PilotTransducerOffset(Effect):
    """An offset δ of the pilot-pressure transducer: true p_P = measured p_P − δ.

    The pilot pressure acts on the large area A_P = α_P·A_L, so an offset of a fraction of a bar
    shifts the whole characteristic by α_P·δ in Δp.
    """

    name = "pilot_transducer_offset"
    kind = "sensor"
    title = "pilot-pressure transducer offset"
    parameter_specs = (Parameter("delta", 0.0, "bar", min=-5.0 * BAR, max=5.0 * BAR,
                                 description="reading minus true pilot pressure"),)
    validity = "Acts as a constant force A_P·δ: indistinguishable from a spring preload offset."

    def correct_inputs(self, points):
        return points.replace(p_P=points.p_P - self["delta"])


class FlowmeterGain(Effect):
    """A gain error g of the flowmeter: true q = measured q·(1 + g).

    Encoder flowmeters drift with the oil's viscosity and wear; a gain error scales every flow.
    """

    name = "flowmeter_gain"
    kind = "sensor"
    title = "flowmeter gain error"
    parameter_specs = (Parameter("g", 0.0, "1", min=-0.3, max=0.3,
                                 description="relative error of the flow reading"),)
    validity = "Uniform over the range; indistinguishable from a discharge-coefficient scale."

    def correct_inputs(self, points):
        return points.replace(q=points.q * (1.0 + self["g"]))
