"""The error staircase drawn: the RMS after each step of a workflow, in sample and on held-out
runs, each step named by what it added and coloured by what that is (valve physics, a map
correction, a sensor error)."""

from __future__ import annotations

import textwrap

import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import Patch

from ..maps.orifice import BASIC_DISCHARGE_COEFFICIENT
from .display import in_bar
from .figures import LEFT, RIGHT, extents, place_panels
from .prose import NOISE_LEVEL

#: the colour of each category a step can add (look-alikes of two categories: "physics or
#: sensor", say, take their own)
CATEGORY_COLOURS = {"": "0.6", "physics": "tab:green", "map correction": "tab:blue",
                    "sensor": "tab:red"}
LOOK_ALIKES = "tab:purple"
#: the paper's starting model, named as the paper does
STARTS = {"bmbe": f"BMBE: orifice, C_d = {BASIC_DISCHARGE_COEFFICIENT:g}"}


def step_label(step, width: int = 22, lines: int = 4) -> str:
    """What a step added, in words: each effect's title (the model's name for the first step),
    wrapped at ``width`` characters; where that takes more than ``lines`` lines, the effects'
    names instead (a label is never cut short); a shape-free term marked *free shape*."""
    if not step.added:
        return "\n".join(textwrap.wrap(STARTS.get(step.model.name, step.model.name), width))
    names = step.added
    titles = []
    for name in names:
        effect = step.model.effect(name) if step.model.has_effect(name) else None
        title = getattr(effect, "title", "") or name
        titles.append(title.replace(", of free shape", " (free shape)"))
    wrapped = textwrap.wrap(" + ".join(titles), width)
    if len(wrapped) > lines:  # too long in words: the effects' names, shorter, never cut
        wrapped = textwrap.wrap(" + ".join(names), width, break_on_hyphens=False)
    return "\n".join(wrapped)


def colour(category: str) -> str:
    return CATEGORY_COLOURS.get(category, LOOK_ALIKES)


def plot_staircase(axes, steps, noise_floor: float, *, fontsize: float = 9,
                   width: int = 22, lines: int = 4) -> float:
    """The RMS after each step on ``axes`` as bars coloured by category, each labelled with its
    value, the held-out RMS as a diamond on it, and the noise floor and :data:`.prose.NOISE_LEVEL`
    times it [Pa in, bar shown]. A linear axis: the last steps' tenths of a bar are written on
    their bars, where a log axis hid them among its ticks. Returns the floor [bar]."""
    rms = np.array([in_bar(step.rms) for step in steps])
    heldout = np.array([in_bar(step.heldout_rms) for step in steps])
    positions = np.arange(len(steps))
    axes.bar(positions, rms, width=0.7, color=[colour(step.category) for step in steps],
             alpha=0.85)
    axes.plot(positions, heldout, "D", color="black", markerfacecolor="white", markersize=5,
              label="held out (each run left out)")
    for x, y, h in zip(positions, rms, heldout):
        axes.annotate(f"{y:.2f}", (x, max(y, h)), textcoords="offset points", xytext=(0, 5),
                      ha="center", fontsize=fontsize)
    floor = in_bar(noise_floor)
    axes.axhline(floor, color="black", linestyle="--", linewidth=1,
                 label=f"noise floor {floor:.2f} bar")
    axes.axhline(NOISE_LEVEL * floor, color="black", linestyle=":", linewidth=1,
                 label=f"{NOISE_LEVEL:g} × floor")
    axes.set_xticks(positions, [f"{i + 1}. {step_label(step, width, lines)}"
                                for i, step in enumerate(steps)],
                    rotation=45, ha="right", rotation_mode="anchor", fontsize=fontsize)
    axes.set_ylabel("residual RMS [bar]", fontsize=fontsize + 1)
    axes.set_ylim(0.0, 1.12 * max(float(np.nanmax(rms)), float(np.nanmax(heldout))))
    axes.tick_params(axis="y", labelsize=fontsize)
    seen = dict.fromkeys(step.category for step in steps[1:])
    handles = [Patch(color=colour(category), label=category or "start") for category in seen]
    line_handles, _ = axes.get_legend_handles_labels()
    axes.legend(handles=line_handles + handles, fontsize=fontsize, loc="upper right")
    return floor


def staircase_figure(steps, noise_floor: float) -> Figure:
    """The error staircase of one workflow."""
    figure = Figure(figsize=(10, 5.2))
    axes = figure.subplots()
    plot_staircase(axes, steps, noise_floor)
    axes.set_title("Error staircase: residual RMS after each step", fontsize=11)
    # placed by its step names' extents, measured once, instead of the constrained layout,
    # which measured every label over again at each save: the names, slanted, hang below the
    # panel, the first also left of it
    sizes = extents(figure, *axes.get_xticklabels())
    low, high = axes.get_xlim()
    panel = figure.get_size_inches()[0] - LEFT - RIGHT
    reach = sizes[0][0] - (0.0 - low) / (high - low) * panel if sizes else 0.0
    place_panels(figure, above=0.4, left=max(LEFT, reach + 0.1),
                 below=max((height for _, height in sizes), default=0.0) + 0.1, across=0.0,
                 down=0.0)
    return figure


def staircases_figure(workflows: dict) -> Figure:
    """The staircases of several map kinds one above the other ({kind: Workflow}), on one RMS
    axis: side by side, a dozen steps' names would overlap."""
    figure = Figure(figsize=(12, 5.0 * len(workflows)), layout="constrained")
    axes = figure.subplots(len(workflows), 1, sharey=True, squeeze=False)[:, 0]
    for ax, (kind, workflow) in zip(axes, workflows.items()):
        plot_staircase(ax, workflow.steps, workflow.noise_floor, fontsize=9, width=22)
        final = in_bar(workflow.final.rms)
        ax.set_title(f"{kind} maps: {final:.2f} bar after {len(workflow.steps)} steps",
                     fontsize=10)
    return figure


__all__ = ["staircase_figure", "staircases_figure", "plot_staircase", "step_label"]
