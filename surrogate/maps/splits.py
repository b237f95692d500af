"""How the CFD samples are divided for cross-validation (:mod:`.crossval`): by sweep,
opening, temperature and back pressure. All splits are deterministic, so figures can be
reproduced and the committed surrogates checked."""

from __future__ import annotations

import numpy as np
import pandas as pd


def sweep_keys(frame: pd.DataFrame) -> pd.Series:
    """A label per sample naming its sweep: temperature, opening and back pressure."""
    return (frame["temperature"].round(1).astype(str) + "|" + (frame["u"] * 1e6).round(1).astype(str)
            + "|" + (frame["p_B"] / 1e3).round(0).astype(str))


def reference_back_pressure(frame: pd.DataFrame) -> float:
    """The most common back pressure [Pa]: that of the main set."""
    levels, counts = np.unique(frame["p_B"].round(0), return_counts=True)
    return float(levels[np.argmax(counts)])


def main_set(frame: pd.DataFrame) -> np.ndarray:
    """True for the samples at the reference back pressure."""
    return np.isclose(frame["p_B"], reference_back_pressure(frame), rtol=0, atol=1e2)


def leave_one_opening_out(frame: pd.DataFrame) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """(label, training mask, test mask) for each interior opening of the main set in turn."""
    main = main_set(frame)
    splits = []
    for u in np.unique(frame.loc[main, "u"].round(9))[1:-1]:
        at = np.isclose(frame["u"], u, rtol=0, atol=1e-9)
        splits.append((f"u = {u * 1e3:.2f} mm", ~at, at & main))
    return splits


def leave_smallest_opening_out(frame: pd.DataFrame) -> tuple[str, np.ndarray, np.ndarray, float]:
    """(label, training mask, test mask, reach) for the main set's smallest opening left out at
    every temperature: a map trained without it goes on from the next opening to it, as the
    map with it goes on toward the seat; ``reach`` is ln(next / smallest), how far that is."""
    main = main_set(frame)
    openings = np.unique(frame.loc[main, "u"].round(9))
    at = np.isclose(frame["u"], openings[0], rtol=0, atol=1e-9)
    return (f"u = {openings[0] * 1e3:.2f} mm", ~at, at & main,
            float(np.log(openings[1] / openings[0])))


def temperature_mask(frame: pd.DataFrame, temperature: float) -> np.ndarray:
    """True for the samples at ``temperature`` [K]."""
    return np.isclose(frame["temperature"], temperature, rtol=0, atol=0.01)


def leave_one_temperature_out(frame: pd.DataFrame) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """(label, training mask, test mask) for each temperature in turn: training leaves out every
    sample at that temperature; the test uses its main-set samples (the back-pressure question is
    asked separately)."""
    main = main_set(frame)
    splits = []
    for t in np.unique(frame["temperature"].round(2)):
        at = temperature_mask(frame, t)
        splits.append((f"{t - 273.15:.0f} °C", ~at, at & main))
    return splits


def back_pressure_set(frame: pd.DataFrame) -> np.ndarray:
    """True for the samples away from the reference back pressure."""
    return ~main_set(frame)


def back_pressure_set_by_opening(frame: pd.DataFrame
                                 ) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """(label, training mask, test mask) for each opening of the back-pressure set in turn:
    training keeps every other sample, the opening's runs at the reference back pressure too."""
    others = back_pressure_set(frame)
    splits = []
    for u in np.unique(frame.loc[others, "u"].round(9)):
        test = others & np.isclose(frame["u"], u, rtol=0, atol=1e-9)
        splits.append((f"back-pressure set at u = {u * 1e3:.2f} mm", ~test, test))
    return splits


#: relative tolerance for "the same value" when samples are grouped (into sweeps, say)
SAME_RTOL = 1e-6


def group_keys(values: np.ndarray) -> np.ndarray:
    """Values that agree to a relative :data:`SAME_RTOL` mapped onto one representative each."""
    keys = np.empty_like(values)
    order = np.argsort(values)
    current = values[order[0]]
    for i in order:
        if abs(values[i] - current) > SAME_RTOL * abs(current):
            current = values[i]
        keys[i] = current
    return keys
