"""Errors of the bench's sensors: the model is fed measured values, the valve sees true ones."""

from __future__ import annotations

from ..core.units import BAR
from .base import Effect, Parameter
from .per_run import PerRunEffect


class PilotTransducerOffset(Effect):
    """An offset δ of the pilot-pressure transducer: true p_P = measured p_P − δ.

    The pilot pressure acts on the large area A_P = α_P·A_L, so an offset of a fraction of a bar
    shifts the whole characteristic by α_P·δ in Δp.
    """

    name = "pilot_transducer_offset"
    kind = "sensor"
    category = "sensor"
    title = "pilot-pressure transducer offset"
    parameter_specs = (Parameter("delta", 0.0, "bar", min=-5.0 * BAR, max=5.0 * BAR,
                                 description="reading minus true pilot pressure"),)
    validity = "Acts as a constant force A_P·δ: indistinguishable from a spring preload offset."

    def correct_inputs(self, points):
        return points.replace(p_P=points.p_P - self["delta"])


class PilotZeroDrift(PerRunEffect):
    """A pilot-pressure transducer offset δ that differs from run to run (its zero drifts or is
    reset between tests): true p_P = measured p_P − δ_run.

    Within a run it acts as :class:`PilotTransducerOffset` does, a constant force A_P·δ that shifts
    the sliding piston's characteristic by about α_P·δ in Δp; from run to run it changes at random,
    following neither temperature nor pilot set point.
    """

    name = "pilot_zero_drift"
    kind = "sensor"
    category = "sensor"
    title = "pilot-pressure transducer zero, different in each run"
    template = Parameter("delta", 0.0, "bar", min=-2.0 * BAR, max=2.0 * BAR,
                         description="reading minus true pilot pressure in this run")
    check_threshold = 0.3  # [bar] a pilot transducer's 1σ noise on the shipped bench
    validity = ("One offset per run of the log it was fitted to; other runs get none. A run whose "
                "piston sits on its stop does not feel the pilot pressure and leaves its offset "
                "undetermined. Within a run, indistinguishable from any constant force.")

    def correct_inputs(self, points):
        return points.replace(p_P=points.p_P - self.per_point(points))


class FlowmeterGain(Effect):
    """A gain error g of the flowmeter: true q = measured q·(1 + g).

    Encoder flowmeters drift with the oil's viscosity and wear; a gain error scales every flow.
    """

    name = "flowmeter_gain"
    kind = "sensor"
    category = "sensor"
    title = "flowmeter gain error"
    parameter_specs = (Parameter("g", 0.0, "1", min=-0.3, max=0.3,
                                 description="relative error of the flow reading"),)
    validity = "Uniform over the range; indistinguishable from a discharge-coefficient scale."

    def correct_inputs(self, points):
        return points.replace(q=points.q * (1.0 + self["g"]))
