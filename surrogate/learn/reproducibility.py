"""Is a retrained surrogate the committed one? Bitwise where the environment matches, within a
measured tolerance where it does not.

Training is deterministic for a given environment: the same seeds, the same data and the same
library builds give the same weights, bit for bit. Across environments (another NumPy, PyTorch or
BLAS, another CPU's vector instructions) the floating-point rounding differs, and the network's
training amplifies it: 2,500 Adam steps on a non-convex loss end in a neighbouring minimum.
``python eval/retraining.py`` measures how far: retraining on inputs moved by one unit in the last
place (a float-level difference, as another platform makes) moves the network's pressure drop by
up to 0.8 % and its flow force by up to 1.0 % (RMS over the CFD states up to 0.09 % and 0.16 %),
the GP's by 1e-10 (and the GP trained in another environment differs from this one's by 2e-7).
A broken training moves them further (see :data:`TOLERANCES`).

So the committed surrogates record the environment they were trained in (:func:`environment`), and
a check of a retraining asks for bitwise agreement where it matches and for agreement within the
tolerance of its kind otherwise.
"""

from __future__ import annotations

import platform
from dataclasses import dataclass

import numpy as np

from ..fluid import FluidState
from ..maps.base import FlowMap, ForceMap
from ..valve import ValveParameters


def environment() -> dict:
    """What decides the rounding of a training run: versions, CPU and the math libraries."""
    import scipy
    import sklearn
    import torch
    from threadpoolctl import threadpool_info

    blas = sorted(f"{pool.get('internal_api')} {pool.get('version')} "
                  f"{pool.get('architecture')} x{pool.get('num_threads')}"
                  for pool in threadpool_info() if pool.get("user_api") == "blas")
    return {"python": platform.python_version(), "machine": platform.machine(),
            "numpy": np.__version__, "scipy": scipy.__version__, "torch": torch.__version__,
            "scikit-learn": sklearn.__version__,
            "torch_cpu": torch.backends.cpu.get_cpu_capability(),
            "torch_threads": torch.get_num_threads(), "blas": blas}


@dataclass(frozen=True)
class Tolerance:
    """Largest relative differences in Δp and in the flow force between two trainings that the
    rounding of another platform can explain [-]: RMS over the CFD states and the largest."""

    rms: float
    max: float

    def admits(self, difference: dict) -> bool:
        """Whether ``difference`` (from :func:`prediction_difference`) lies within."""
        return (max(difference["dp_rms"], difference["flow_force_rms"]) <= self.rms
                and max(difference["dp_max"], difference["flow_force_max"]) <= self.max)


#: Per kind, from ``eval/retraining.py`` (results/retraining/retraining.md):
#:
#: * network: about three times the largest difference float-level perturbations produced (RMS
#:   0.16 %, largest 1.0 %), so no platform's rounding trips it. Broken data trip it: the hold-out
#:   leaked into the training set (flow force RMS 1.0 %, largest 8 %) or a density 1 % off (Δp RMS
#:   1.0 %). Changes of schedule that leave an equally good network (a fifth of the epochs, one
#:   member instead of three, the flow net in one stage: RMS 0.1-0.3 %) stay within: the
#:   training's own sensitivity to rounding is that large, so predictions cannot tell them apart.
#: * GP: its training is nearly linear algebra, so float-level differences stay at 1e-10 and
#:   another environment's at 2e-7; the tolerance leaves a factor 50 above that, and every broken
#:   training tried (no optimiser restarts, hold-out leaked, density off) differs by 4e-3 or more.
TOLERANCES = {"nn": Tolerance(rms=0.005, max=0.03), "gp": Tolerance(rms=1e-6, max=1e-5)}


def nudged_by_one_ulp(samples, seed: int):
    """The CFD samples with q, p_L and f_sim each moved by one unit in the last place (random
    direction per value): the size of difference another platform's rounding makes."""
    from ..data.loaders import CfdSamples

    frame = samples.frame.copy()
    rng = np.random.default_rng(seed)
    for column in ("q", "p_L", "f_sim"):
        values = frame[column].to_numpy()
        frame[column] = np.where(rng.random(len(values)) < 0.5, np.nextafter(values, -np.inf),
                                 np.nextafter(values, np.inf))
    return CfdSamples(frame, samples.source)


def prediction_difference(flow_a: FlowMap, force_a: ForceMap, flow_b: FlowMap,
                          force_b: ForceMap, frame, valve: ValveParameters) -> dict:
    """Relative differences of two map pairs at the states of CFD samples ``frame`` (SI).

    Compares the pressure drop at each sample's (q, p_B, u, fluid) and the flow-force part of
    f_sim, f_sim − p_L·A_L − p_B·(A_s3 − A_B), at its (p_L, p_B, u, fluid): the quantities the
    solver uses. Returns RMS and largest relative difference of each [-].
    """
    fluid = FluidState(frame["nu"].to_numpy(), frame["rho"].to_numpy())
    q, p_L, p_B, u = (frame[name].to_numpy() for name in ("q", "p_L", "p_B", "u"))
    uniform = p_L * valve.A_L + p_B * (valve.A_s3 - valve.A_B)
    dp = flow_a.pressure_drop(q, p_B, u, fluid) / flow_b.pressure_drop(q, p_B, u, fluid) - 1.0
    flow_force = ((force_a.force(p_L, p_B, u, fluid) - uniform)
                  / (force_b.force(p_L, p_B, u, fluid) - uniform) - 1.0)
    return {"dp_rms": float(np.sqrt(np.mean(dp**2))), "dp_max": float(np.max(np.abs(dp))),
            "flow_force_rms": float(np.sqrt(np.mean(flow_force**2))),
            "flow_force_max": float(np.max(np.abs(flow_force)))}
