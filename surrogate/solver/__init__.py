"""The steady-state force-balance solver and the replay of measured time series."""

from .replay import Replay, replay
from .steady import REASONS, SteadyState, Status, solve_steady

__all__ = ["REASONS", "Replay", "SteadyState", "Status", "replay", "solve_steady"]
