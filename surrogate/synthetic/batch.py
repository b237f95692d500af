"""A virtual fleet: many valves of one design, each built with its own tolerances, a few with a
fault the rest lack, every one tested on the same bench sequence.

Each valve is the reference valve (:func:`.simulate.reference_spec`) with its own draws of the
manufacturing scatter (:class:`FleetScatter`): Coulomb friction K1 and K2, spring preload F_cr,
spring rate K_f and the flow-force scale. All of them share one CFD-size map mismatch
(:mod:`.mismatch`): the CFD errs for the design, not for one valve, so every valve of a batch
differs from the maps in the same way, while each bench run adds its own sensor noise. A share
of the valves (:data:`FAULT_SHARE`) carries one fault from the effect library on top
(:data:`FAULTS`: a seal friction growing with |p_L − p_P|, or a laminar leakage), its size
drawn between 0.6 and 1.5 times the realistic magnitude, as the workbench's stress suites draw
theirs.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..data.loaders import BenchLog, CfdSamples
from ..effects import LIBRARY
from ..model import ValveModel
from ..description.presets import cfda_effects
from ..description.spec import EffectSpec, ModelSpec
from .mismatch import MapMismatch, mismatched_truth
from .simulate import (
    REALISTIC_MAGNITUDES,
    REFERENCE_VALUES,
    SensorNoise,
    reference_spec,
    simulate,
)

#: the faults a virtual valve may carry, from the effect library
FAULTS = ("friction_seal_pressure", "laminar_leakage")
#: share of the fleet with a fault
FAULT_SHARE = 0.05
#: a fault's size as a factor on its realistic magnitude (the stress suites' range)
FAULT_FACTORS = (0.6, 1.5)
#: how far the design's CFD errs: the size of a real CFD's error (:class:`.mismatch.MapMismatch`)
DESIGN_MISMATCH = MapMismatch()


@dataclass(frozen=True)
class FleetScatter:
    """1σ of each valve's manufacturing scatter about the reference valve.

    Attributes
    ----------
    K1 : float
        Constant Coulomb friction [N].
    K2 : float
        Friction per load pressure [N/bar].
    preload : float
        Spring force at u = 0, F_cr [N].
    spring_rate : float
        Spring rate K_f, relative [1].
    flow_force_scale : float
        Flow-force scale [1].
    """

    K1: float = 1.0
    K2: float = 0.004
    preload: float = 5.0
    spring_rate: float = 0.03
    flow_force_scale: float = 0.015


@dataclass(frozen=True)
class VirtualValve:
    """One valve of a virtual fleet, with the values it was built with (display units).

    Attributes
    ----------
    serial : str
    K1 : float
        [N]
    K2 : float
        [N/bar]
    preload : float
        F_cr [N]
    spring_rate : float
        K_f [N/mm]
    flow_force_scale : float
        [1]
    fault : str or None
        The library effect it carries that the others lack.
    fault_values : dict
        The fault's parameters (display units).
    seed : int
        Of its bench run's sensor noise.
    """

    serial: str
    K1: float
    K2: float
    preload: float
    spring_rate: float
    flow_force_scale: float
    fault: str | None = None
    fault_values: dict = field(default_factory=dict)
    seed: int = 0

    def truth_spec(self, reference: ModelSpec | None = None) -> ModelSpec:
        """The valve as a model spec: the reference with this valve's values and fault."""
        reference = reference or reference_spec()
        valve = reference.valve.parameters
        parameters = replace(valve, F_cr=self.preload, K_f=self.spring_rate * 1e3,
                             name=f"{valve.name}, serial {self.serial}")
        effects = list(cfda_effects(scale=self.flow_force_scale, K1=self.K1, K2=self.K2))
        if self.fault:
            effects.append(EffectSpec.start(LIBRARY.effect(self.fault), **self.fault_values))
        return (reference.with_valve(replace(reference.valve, parameters=parameters))
                .with_effects(effects, name=f"virtual valve {self.serial}"))


def draw_fleet(count: int, *, seed: int = 0, scatter: FleetScatter = FleetScatter(),
               fault_share: float = FAULT_SHARE, faults: tuple[str, ...] = FAULTS,
               prefix: str = "V") -> list[VirtualValve]:
    """``count`` virtual valves: the reference's values plus Gaussian scatter, and
    round(``fault_share``·count) of them (chosen at random) with a fault, the faults taking
    turns."""
    rng = np.random.default_rng(seed)
    valve = reference_spec().valve.parameters
    faulty = set(rng.choice(count, size=round(fault_share * count), replace=False).tolist())
    width = len(str(count))
    fleet = []
    turn = 0
    for number in range(count):
        draws = rng.standard_normal(5)
        fault, values = None, {}
        if number in faulty:
            fault = faults[turn % len(faults)]
            turn += 1
            factor = float(rng.uniform(*FAULT_FACTORS))
            values = {key: factor * value for key, value in REALISTIC_MAGNITUDES[fault].items()}
        fleet.append(VirtualValve(
            serial=f"{prefix}{number + 1:0{width}d}",
            K1=max(0.5, REFERENCE_VALUES["K1"] + scatter.K1 * draws[0]),
            K2=max(0.0, REFERENCE_VALUES["K2"] + scatter.K2 * draws[1]),
            preload=valve.F_cr + scatter.preload * draws[2],
            spring_rate=valve.K_f * 1e-3 * (1.0 + scatter.spring_rate * draws[3]),
            flow_force_scale=REFERENCE_VALUES["scale"] + scatter.flow_force_scale * draws[4],
            fault=fault, fault_values=values, seed=int(rng.integers(2**31))))
    return fleet


def virtual_log(valve: VirtualValve, sequence: BenchLog, samples: CfdSamples, *,
                mismatch: MapMismatch | None = DESIGN_MISMATCH, mismatch_seed: int = 0,
                noise: SensorNoise | None = None) -> BenchLog:
    """The valve's bench log over ``sequence``: its truth on the design's mismatched maps
    (``mismatch`` drawn with ``mismatch_seed``, shared by the fleet; None: the maps as they
    are), replayed with sensor noise of the valve's own seed."""
    truth: ValveModel = valve.truth_spec().build(LIBRARY)
    if mismatch is not None:
        truth = mismatched_truth(truth, samples, mismatch_seed, mismatch)
    log = simulate(truth, sequence, noise=noise, seed=valve.seed)
    return BenchLog(log.frame, f"virtual valve {valve.serial}")
