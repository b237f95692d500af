"""A user's hypothesis as a custom effect: an opening force near the seat.

Near closure (u below the smallest CFD opening, 0.05 mm) the grid maps hold the flow-force
fraction constant, but on the real valve the pressure drop also acts on the seat land, pushing
the piston open with a force that fades as it lifts off. Load with

    python -m surrogate diagnose --model final_model.toml --effects-file examples/seat_force.py
"""

import numpy as np

from surrogate.effects import custom_effect


@custom_effect("force", units={"a": "N/bar", "u0": "mm"},
               bounds={"a": (-1.0, 1.0), "u0": (0.002, 0.5)},
               title="opening force of the pressure drop on the seat land, fading with opening")
def seat_land_force(state, a=0.0, u0=0.05):
    """Opening force a·Δp·exp(−u/u0) [N]: the pressure drop acting on the seat land near
    closure, gone once the piston has lifted a few u0."""
    return a * (state.p_L - state.p_B) * np.exp(-state.u / u0)
