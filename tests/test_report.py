"""The HTML report's layout rules, checked on a report generated from a real (short) workflow.

Rendered in a 1,400-pixel browser window the report must read at a glance: table cells short
enough that no column is squeezed, figures with short titles and their full story in a caption,
measured and model told apart by marker and colour, RMS charts zoomed to their range.
"""

from __future__ import annotations

from html.parser import HTMLParser

import numpy as np
import pytest

from surrogate.reporting.figures import TITLE_LENGTH, all_figures
from surrogate.reporting.report import (CELL_LENGTH, comparison_section, diagnosis_figure,
                                        diagnosis_section, parameter_summary, readable,
                                        staircase_figure, staircase_section)
from surrogate.synthetic.simulate import hidden_effect_case, noise_free_sequence
from surrogate.workbench.compare import compare
from surrogate.workbench.workflow import run_workflow

pytestmark = pytest.mark.slow  # one short workflow (~10 s) for all of them


@pytest.fixture(scope="module")
def workflow(bench_log):
    case = hidden_effect_case("friction_viscous", sequence=noise_free_sequence(bench_log, every=12),
                              seed=4)
    return run_workflow(case.log, max_additions=1)


@pytest.fixture(scope="module")
def comparison(workflow):
    return compare(workflow.final.model, workflow.log, played=workflow.final.played)


@pytest.fixture(scope="module")
def page(workflow, comparison):
    return "\n".join([staircase_section(workflow), comparison_section(comparison, "Final"),
                      diagnosis_section(workflow.final_diagnosis)])


class _Cells(HTMLParser):
    """Collects the text of every table cell and what encloses every image."""

    def __init__(self):
        super().__init__()
        self.cells, self.images, self.captions, self.stack, self.text = [], [], 0, [], None

    def handle_starttag(self, tag, attrs):
        if tag in ("td", "th"):
            self.text = []
        if tag == "img":
            self.images.append(list(self.stack))
        if tag == "figcaption":
            self.captions += 1
        self.stack.append(tag)

    def handle_endtag(self, tag):
        if tag in ("td", "th") and self.text is not None:
            self.cells.append("".join(self.text).strip())
            self.text = None
        if self.stack and self.stack[-1] == tag:
            self.stack.pop()

    def handle_data(self, data):
        if self.text is not None:
            self.text.append(data)


def test_no_table_cell_is_longer_than_the_limit(page):
    cells = _Cells()
    cells.feed(page)
    assert cells.cells
    longest = max(cells.cells, key=len)
    assert len(longest) <= CELL_LENGTH, longest


def test_every_figure_has_a_caption(page):
    cells = _Cells()
    cells.feed(page)
    assert cells.images and all("figure" in enclosing for enclosing in cells.images)
    assert cells.captions == len(cells.images)


def test_the_staircase_shows_step_added_and_rms_at_a_glance(page):
    head = page.split("<table>", 1)[1].split("</thead>", 1)[0].split("<tr>", 1)[1]
    columns = [part.split(">", 1)[1].split("<", 1)[0] for part in head.split("<th")[1:]]
    assert columns == ["step", "added", "category", "rms [bar]", "held out [bar]",
                       "× noise floor"]
    assert "<details>" in page  # the parameters, one folded table per step


def test_figure_titles_are_short(workflow, comparison):
    figures = [*all_figures(comparison).values(), diagnosis_figure(workflow.final_diagnosis),
               staircase_figure(workflow.steps, workflow.noise_floor)]
    titles = [figure.get_suptitle() for figure in figures]
    titles += [axes.get_title() for figure in figures for axes in figure.axes]
    assert max(len(title) for title in titles) <= TITLE_LENGTH, max(titles, key=len)
    assert readable(comparison.model) in page_caption(comparison)


def page_caption(comparison) -> str:
    return comparison_section(comparison, "x").split("<figcaption>", 1)[1]


def test_measured_and_model_differ_in_marker_and_colour(comparison):
    axes = all_figures(comparison)["dp_vs_q"].axes[0]
    measured = [line for line in axes.lines if line.get_linestyle() == "None"]
    model = [line for line in axes.lines if line.get_linestyle() == "-"]
    assert measured and model
    assert all(line.get_marker() == "o" for line in measured)
    assert all(line.get_marker() in ("None", "", None) for line in model)
    assert {line.get_color() for line in measured}.isdisjoint(line.get_color() for line in model)


def test_the_rms_chart_is_zoomed_to_its_range(workflow):
    axes = diagnosis_figure(workflow.final_diagnosis).axes[0]
    low, high = axes.get_xlim()
    rms = [c.rms_after for c in workflow.final_diagnosis.candidates]
    assert low > 0.5 * min(rms) / 1e5  # not from zero: close candidates stay apart
    assert high - low < 2.0 * (max(rms) - min(rms) + workflow.final_diagnosis.rms_before) / 1e5


def test_parameter_summary_keeps_to_the_limit_and_collapses_runs():
    from surrogate.effects import ConstantFriction, PilotZeroDrift

    drift = PilotZeroDrift.for_runs([f"R{i:02d}" for i in range(1, 13)])
    for number, parameter in enumerate(drift.params.values()):
        parameter.value = 1e4 * (number - 6)
    text = parameter_summary([*ConstantFriction().params.values(), *drift.params.values()])
    assert "per run" in text and "(12 runs)" in text and len(text) <= CELL_LENGTH
    many = [p for _ in range(20) for p in ConstantFriction().params.values()]
    short = parameter_summary(many, limit=60)
    assert len(short) <= 60 and short.endswith("more")
    assert np.isfinite(len(short))
