"""Training the bridged network of the learned flow-force maps, in PyTorch.

The network (:class:`surrogate.maps.network.BridgedArchitecture`) is one small network of the
Reynolds number (plus a slope in the pressure level) per sampled opening, blended linearly
between openings, plus one network of the cavitation number shared by all openings and,
optionally, a smooth trend in the opening and the Reynolds number;
:class:`surrogate.maps.network.BridgedNet` evaluates it with NumPy. This module fits its
parameters: Adam with a cosine schedule, then L-BFGS.
"""

from __future__ import annotations

import numpy as np
import torch

from ..maps.network import BridgedArchitecture, bridge_weights
from .monotone_nn import _hold, minimise

#: weight decay on the hidden weights (keeps the small networks smooth)
DECAY = 1e-4
#: penalty on the differences of neighbouring openings' pressure-level slopes: a free slope per
#: opening runs off where a left-out sweep leaves an opening with a hole in Δp (docs/maps.md,
#: "How the learned maps are built")
LEVEL_SMOOTHING = 3e-4
#: with a trend (BridgedArchitecture.trend_width): penalty on the mean square of each opening's
#: network's departure from the mean of all openings' at the same inputs, so that the trend
#: carries how the force changes from opening to opening (chosen by the four-scheme
#: cross-validation of the flow force, docs/maps.md)
OPENING_SHRINK = 0.1


class TorchBridgedNet(torch.nn.Module):
    """The bridged network as a PyTorch module (see :class:`BridgedArchitecture`)."""

    def __init__(self, architecture: BridgedArchitecture, seed: int, offset: float):
        super().__init__()
        self.architecture = architecture
        knots, width = len(architecture.knots), architecture.width
        generator = torch.Generator().manual_seed(seed)

        def parameter(*shape, scale=1.0, fill=None):
            value = (torch.full(shape, fill, dtype=torch.float64) if fill is not None
                     else scale * torch.randn(*shape, generator=generator, dtype=torch.float64))
            return torch.nn.Parameter(value)

        self.local_W = parameter(knots, width, scale=0.5)
        self.local_b = parameter(knots, width, scale=0.5)
        self.local_v = parameter(knots, width, scale=0.1)
        self.local_c = parameter(knots, fill=offset)
        self.local_l = parameter(knots, fill=0.0)
        self.shared_W = parameter(width, scale=0.5)
        self.shared_b = parameter(width, scale=0.5)
        self.shared_v = parameter(width, scale=0.1)
        self.shared_l = parameter(1, fill=0.0)
        if architecture.level_column is not None:
            self.local_m = parameter(knots, fill=0.0)
        if architecture.trend_width:
            trend_width = architecture.trend_width
            self.trend_W = parameter(trend_width, 2, scale=0.5)
            self.trend_b = parameter(trend_width, scale=0.5)
            self.trend_v = parameter(trend_width, scale=0.1)
            self.trend_l = parameter(2, fill=0.0)

    def per_opening(self, local: torch.Tensor, level: torch.Tensor | None = None):
        """Every opening's small network at every row, shape (rows, knots)."""
        hidden = torch.tanh(local[:, None, None] * self.local_W[None] + self.local_b[None])
        per_opening = ((hidden * self.local_v[None]).sum(-1) + self.local_c[None]
                       + local[:, None] * self.local_l[None])
        if level is not None:
            per_opening = per_opening + level[:, None] * self.local_m[None]
        return per_opening

    def forward(self, weights: torch.Tensor, local: torch.Tensor, shared: torch.Tensor,
                level: torch.Tensor | None = None, trend_x: torch.Tensor | None = None):
        """R at rows of hat ``weights``, held Reynolds (``local``), cavitation (``shared``) and
        pressure-level features, and with a trend its (opening, Reynolds) inputs as it holds
        them (``trend_x``, rows × 2)."""
        cavitation = ((torch.tanh(shared[:, None] * self.shared_W[None] + self.shared_b[None])
                       * self.shared_v[None]).sum(-1) + self.shared_l * shared)
        total = (weights * self.per_opening(local, level)).sum(1) + cavitation
        if not self.architecture.trend_width:
            return total
        return (total + torch.tanh(trend_x @ self.trend_W.T + self.trend_b) @ self.trend_v
                + trend_x @ self.trend_l)

    def penalty(self, local: torch.Tensor | None = None,
                level: torch.Tensor | None = None) -> torch.Tensor:
        """Weight decay on the hidden weights, the level slopes' roughness across openings (none
        without a level column) and, with a trend, the per-opening networks' departure from
        their mean at the rows ``local``, ``level``; each times its own weight."""
        hidden = torch.sum(self.local_W**2) + torch.sum(self.shared_W**2)
        if self.architecture.trend_width:
            hidden = hidden + torch.sum(self.trend_W**2)
        total = DECAY * hidden
        if self.architecture.level_column is not None:
            total = total + LEVEL_SMOOTHING * torch.sum(torch.diff(self.local_m) ** 2)
        if self.architecture.trend_width:
            per_opening = self.per_opening(local, level)
            departure = per_opening - per_opening.mean(dim=1, keepdim=True)
            total = total + OPENING_SHRINK * torch.mean(departure**2)
        return total


def train_bridged(architecture: BridgedArchitecture, z: np.ndarray, target: np.ndarray, *,
                  seed: int, epochs: int = 2000, polish: int = 300,
                  learning_rate: float = 2e-2) -> dict[str, np.ndarray]:
    """Fit the network to ``target`` at standardised features ``z`` by least squares; return its
    parameters as NumPy arrays (the state :class:`~surrogate.maps.network.BridgedNet` reads)."""
    network = TorchBridgedNet(architecture, seed, float(np.mean(target)))
    weights = torch.as_tensor(bridge_weights(z[:, architecture.bridge_column], architecture.knots,
                                             architecture.smoothing_degree))
    held = _hold(torch.as_tensor(z), architecture.held)  # as the NumPy network holds them
    local = held[:, architecture.local_column]
    shared = held[:, architecture.shared_column]
    level = None if architecture.level_column is None else held[:, architecture.level_column]
    trend_x = _hold(torch.as_tensor(z), architecture.trend_held)[
        :, [architecture.bridge_column, architecture.local_column]]
    goal = torch.as_tensor(target)

    def objective():
        return (torch.mean((network(weights, local, shared, level, trend_x) - goal) ** 2)
                + network.penalty(local, level))

    minimise(network, objective, epochs=epochs, learning_rate=learning_rate, polish=polish)
    return {key: value.detach().numpy().copy() for key, value in network.state_dict().items()}
