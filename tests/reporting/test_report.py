"""The HTML report's layout rules, checked on a report generated from a real (short) workflow.

Rendered in a 1,400-pixel browser window the report must read at a glance: table cells short
enough that no column is squeezed, figures with short titles and their full story in a caption,
measured and model told apart by marker and colour, RMS charts zoomed to their range.
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from html import unescape
from html.parser import HTMLParser

import numpy as np
import pytest

from surrogate.reporting.figures import TITLE_LENGTH, all_figures
from surrogate.reporting.report import (CELL_LENGTH, comparison_section, diagnosis_figure,
                                        diagnosis_section, next_steps_section,
                                        parameter_summary, readable, staircase_figure,
                                        staircase_section, verdict_html, write_html)
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
    return compare(workflow.final.model, workflow.log, log_replay=workflow.final.log_replay)


@pytest.fixture(scope="module")
def page(workflow, comparison):
    return "\n".join([staircase_section(workflow), comparison_section(comparison, "Final"),
                      diagnosis_section(workflow.final_diagnosis), next_steps_section(workflow)])


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


@pytest.mark.pipeline
def test_no_table_cell_is_longer_than_the_limit(page):
    cells = _Cells()
    cells.feed(page)
    assert cells.cells
    longest = max(cells.cells, key=len)
    assert len(longest) <= CELL_LENGTH, longest


@pytest.mark.pipeline
def test_every_figure_has_a_caption(page):
    cells = _Cells()
    cells.feed(page)
    assert cells.images and all("figure" in enclosing for enclosing in cells.images)
    assert cells.captions == len(cells.images)


@pytest.mark.pipeline
def test_the_staircase_shows_step_added_and_rms_at_a_glance(page):
    head = page.split("<table>", 1)[1].split("</thead>", 1)[0].split("<tr>", 1)[1]
    columns = [part.split(">", 1)[1].split("<", 1)[0] for part in head.split("<th")[1:]]
    assert columns == ["step", "added", "category", "rms [bar]", "held out [bar]",
                       "× noise floor"]
    assert "<details>" in page  # the parameters, one folded table per step


@pytest.mark.pipeline
def test_figure_titles_are_short(workflow, comparison):
    figures = [*all_figures(comparison).values(), diagnosis_figure(workflow.final_diagnosis),
               staircase_figure(workflow.steps, workflow.noise_floor)]
    titles = [figure.get_suptitle() for figure in figures]
    titles += [axes.get_title() for figure in figures for axes in figure.axes]
    assert max(len(title) for title in titles) <= TITLE_LENGTH, max(titles, key=len)
    assert readable(comparison.model) in page_caption(comparison)


def page_caption(comparison) -> str:
    return comparison_section(comparison, "x").split("<figcaption>", 1)[1]


@pytest.mark.pipeline
def test_measured_and_model_differ_in_marker_and_colour(comparison):
    axes = all_figures(comparison)["dp_vs_q"].axes[0]
    measured = [line for line in axes.lines if line.get_linestyle() == "None"]
    model = [line for line in axes.lines if line.get_linestyle() == "-"]
    assert measured and model
    assert all(line.get_marker() == "o" for line in measured)
    assert all(line.get_marker() in ("None", "", None) for line in model)
    assert {line.get_color() for line in measured}.isdisjoint(line.get_color() for line in model)


@pytest.mark.pipeline
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


#: the report's content width on a 1,000-pixel window [px]: the page's margins and padding off
NARROW_PAGE = 1000 - 2 * 16
#: the smallest legend text a reader should have to read there [px]
SMALLEST_LEGEND = 10.0


@pytest.mark.pipeline
def test_every_table_scrolls_inside_its_box(page):
    """A wide table scrolls inside its own box; the page itself never scrolls sideways."""
    assert page.count("<table>") == page.count('<div class="scroll"><table>') > 0


def _report_figures(workflow, comparison):
    from surrogate.reporting.views import residual_views, run_loops

    models = [(f"step {i + 1}", step.log_replay) for i, step in enumerate(workflow.steps)]
    return {**all_figures(comparison),
            "staircase": staircase_figure(workflow.steps, workflow.noise_floor),
            "diagnosis": diagnosis_figure(workflow.final_diagnosis),
            "residual views": residual_views(workflow.log, models),
            "run loops": run_loops(workflow.log, models[-2:])}


@pytest.mark.pipeline
def test_legends_stay_readable_on_a_narrow_page(workflow, comparison):
    """An image wider than the page shrinks to it: at 1,000 pixels every legend's text must
    still be 10 pixels high."""
    from surrogate.reporting.figures import DPI

    small = {}
    for name, figure in _report_figures(workflow, comparison).items():
        shown = min(1.0, NARROW_PAGE / (figure.get_figwidth() * DPI))
        legends = [*figure.legends, *(ax.get_legend() for ax in figure.axes)]
        for legend in filter(None, legends):
            for text in legend.get_texts():
                pixels = text.get_fontsize() * DPI / 72 * shown
                if pixels < SMALLEST_LEGEND:
                    small[name] = round(pixels, 1)
    assert not small, small


def _texts(figure) -> list[str]:
    """Every piece of text a figure shows: titles, axis labels, legends, annotations."""
    return [text.get_text() for text in figure.findobj(lambda artist: hasattr(artist, "get_text"))]


@pytest.mark.pipeline
def test_one_sign_convention_in_every_figure_table_and_sentence(workflow, comparison, page):
    """The residual is model − measured everywhere it is named (figures, tables, prose), and
    the residual figure plots exactly that: the model's Δp minus the measured one."""
    named = re.compile(r"(model|measured)\s*[−-]\s*(model|measured)")
    texts = [text for figure in _report_figures(workflow, comparison).values()
             for text in _texts(figure)] + [unescape(re.sub(r"<[^>]+>", " ", page))]
    orders = {match.groups() for text in texts for match in named.finditer(text)}
    assert orders == {("model", "measured")}, orders
    panels = all_figures(comparison)["residuals"]
    assert "model − measured" in panels.axes[0].get_ylabel()
    plotted = np.sort(panels.axes[0].collections[0].get_offsets()[:, 1])
    log_replay = comparison.log_replay
    expected = (log_replay.replay.dp - log_replay.measured)[log_replay.ok] / 1e5
    assert plotted.size and np.all(np.isin(np.round(plotted, 9), np.round(expected, 9)))


@pytest.mark.pipeline
def test_no_label_or_cell_is_cut_short(workflow, comparison, page):
    """Labels, ticks, legends and table cells are wrapped or shortened in words, never cut
    with an ellipsis."""
    for name, figure in _report_figures(workflow, comparison).items():
        figure.canvas.draw()  # tick labels get their text when the figure is drawn
        cut = [text for text in _texts(figure) if "…" in text or text.rstrip().endswith("...")]
        assert not cut, (name, cut)
    parser = _Cells()
    parser.feed(page)
    assert not [cell for cell in parser.cells if "…" in cell or cell.endswith("...")]


@pytest.mark.pipeline
def test_the_misfit_views_are_the_runs_median_lines_and_half_widths(workflow):
    """The dots of the residual views are each run's binned median line (top) and half-width
    (bottom) of the last model's residual, in bar, one per bin."""
    from surrogate.fitting.hysteresis import hysteresis_split
    from surrogate.reporting.views import VARIABLES, residual_views

    last = workflow.final.log_replay
    figure = residual_views(workflow.log, [("first", workflow.steps[0].log_replay), ("last", last)])
    axes = np.array(figure.axes).reshape(2, len(VARIABLES))
    split = hysteresis_split(workflow.log.frame)
    residual = np.nan_to_num(last.residual)
    for row, matrix in enumerate((split.median, split.half)):
        dots = next(line for line in axes[row, 0].lines if line.get_linestyle() == "None")
        dots = dots.get_ydata()
        assert np.allclose(dots, matrix @ residual / 1e5)


@pytest.mark.pipeline
def test_every_run_has_its_own_loop_on_its_own_scale(workflow):
    from surrogate.reporting.views import run_loops

    figure = run_loops(workflow.log, [("final", workflow.final.log_replay)])
    shown = [ax for ax in figure.axes if ax.get_visible() and ax.get_title()]
    assert len(shown) == len(workflow.log.run_ids)
    spans = [ax.get_ylim()[1] - ax.get_ylim()[0] for ax in shown]
    assert min(spans) < 0.5 * max(spans)  # zoomed per run: a 120-bar run is not a 30-bar one's


@pytest.mark.pipeline
def test_what_to_do_next_follows_from_what_the_workflow_found(workflow):
    """Each line of advice answers a finding: no shape-free step, no word of an effects file;
    the maps' limits named when the diagnosis shows them; never an empty list."""
    from surrogate.reporting.prose import next_steps
    from surrogate.reporting.report import next_steps_section

    steps = next_steps(workflow)
    assert steps and steps[-1].startswith("To trust the model beyond this log")
    shaped = any(step.shape_free for step in workflow.steps)
    assert shaped == any("found_*.py" in line for line in steps)
    assert bool(workflow.final_diagnosis.map_limits) == any("suggest-cfd" in line
                                                             for line in steps)
    html = next_steps_section(workflow)
    assert html.count("<li>") == len(steps) and "`" not in html


@pytest.mark.pipeline
def test_the_report_shows_where_the_bench_operates_over_the_cfds_openings(workflow):
    """The misfit section draws the log's openings over the sampled ones (suggest-cfd's view,
    without its runs) for maps built from CFD samples."""
    from surrogate.reporting.report import misfit_figures, misfit_section

    pngs = misfit_figures(workflow)
    assert {"residual_views", "run_loops", "operating_points"} <= set(pngs)
    assert misfit_section(workflow, pngs).count("<figure>") == 3


@pytest.mark.pipeline
def test_a_long_report_opens_with_contents_linking_every_section(tmp_path, page):
    """A report of many sections (the workflow's is 12,500 pixels tall) lists them at the top,
    each a link to its heading."""
    path = write_html(tmp_path / "report.html", "title", [page, "<h2>Next</h2><p>x</p>"])
    text = path.read_text()
    headings = re.findall(r'<h2 id="(section-\d+)">', text)
    assert len(headings) >= 3
    assert [f'href="#{anchor}"' in text for anchor in headings] == [True] * len(headings)
    assert text.index("<nav") < text.index("<h2")


@pytest.mark.pipeline
def test_the_report_opens_with_the_verdict_of_the_final_model(tmp_path, page, workflow):
    """Under the title, before the contents, three lines: what the final model lacks, where,
    and what to run next, of the final diagnosis' model with its RMS."""
    from surrogate.reporting.verdict import verdict

    path = write_html(tmp_path / "report.html", "title", [page, "<h2>Next</h2><p>x</p>"],
                      opening=verdict_html(workflow))
    text = path.read_text()
    opening = text[text.index("</h1>"):text.index("<nav")]
    assert [label in opening for label in ("<b>Lacks</b>", "<b>Where</b>", "<b>Next</b>")] \
        == [True] * 3
    found = verdict(workflow)
    assert found.lacks.split(":")[0] in opening
    assert f"{workflow.final.rms / 1e5:.2f} bar" in found.lacks  # the final model's RMS


def test_a_binned_line_breaks_where_the_log_has_no_samples():
    """Openings between 0.25 and 0.63 mm are never reached: the residual's line must not join
    the bins across them (it drew a trend where there are no data)."""
    from surrogate.reporting.views import _binned_line

    x = np.r_[np.linspace(0.05, 0.25, 200), np.full(40, 0.63)]
    centres, medians = _binned_line(x, np.sin(10 * x))
    gap = np.flatnonzero(np.isnan(centres))
    assert len(gap) == 1 and centres[gap[0] - 1] < 0.26 and centres[gap[0] + 1] == 0.63
    assert np.isnan(medians[gap[0]])
    dense = np.linspace(0.0, 1.0, 300)
    assert not np.isnan(_binned_line(dense, dense)[0]).any()


#: the browser the rendered page is measured in
CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
#: run in the page once loaded: every folded section opened, then every element whose box
#: reaches past the body's content box, and every box whose content is wider than the box
#: itself (a table that scrolls inside its box), written into a <pre> for --dump-dom to carry
_MEASURE = """<script>
document.querySelectorAll("details").forEach(function (d) { d.open = true; });
(function () {
  var body = document.body.getBoundingClientRect();
  var right = body.right - parseFloat(getComputedStyle(document.body).paddingRight);
  var found = {viewport: document.documentElement.clientWidth,
               page: document.documentElement.scrollWidth, over: []};
  document.body.querySelectorAll("*").forEach(function (e) {
    var box = e.getBoundingClientRect();
    var what = e.tagName + " " + (e.textContent || "").slice(0, 50);
    if (box.width > 0 && box.right > right + 0.5)
      found.over.push(what + ": right edge at " + Math.round(box.right) + " of "
                      + Math.round(right) + " px");
    if (e.clientWidth > 0 && e.scrollWidth > e.clientWidth + 1)
      found.over.push(what + ": " + e.scrollWidth + " px wide in " + e.clientWidth);
  });
  var out = document.createElement("pre");
  out.id = "measured";
  out.textContent = JSON.stringify(found);
  document.body.appendChild(out);
})();
</script>"""


def rendered_widths(path, width: int) -> dict:
    """``path``'s page rendered by headless Chromium in a window ``width`` pixels wide:
    ``viewport`` and ``page`` widths [px] and what reaches past its box (``over``)."""
    measured = path.with_name(f"measured_{path.name}")
    measured.write_text(path.read_text().replace("</body>", _MEASURE + "</body>"))
    dom = subprocess.run([CHROMIUM, "--headless", "--disable-gpu", "--no-sandbox",
                          f"--window-size={width},3000", "--dump-dom", measured.as_uri()],
                         capture_output=True, text=True, timeout=60, check=True).stdout
    found = re.search(r'<pre id="measured">(.*?)</pre>', dom, re.S)
    assert found, dom[-2000:]
    return json.loads(unescape(found.group(1)))


@pytest.mark.pipeline
@pytest.mark.skipif(CHROMIUM is None, reason="no chromium: the rendered page cannot be measured")
def test_nothing_overflows_a_1000_pixel_window(tmp_path, page, workflow):
    """Rendered at 1,000 pixels, with every folded table opened, no element reaches past the
    page's content box and no table is wider than its own box: nothing to scroll sideways."""
    from surrogate.reporting.report import staircases_section

    kinds = staircases_section({"gp": workflow, "grid": workflow}, "gp")  # the kinds compared
    path = write_html(tmp_path / "report.html", "title", [page, kinds],
                      opening=verdict_html(workflow))
    measured = rendered_widths(path, 1000)
    assert measured["page"] <= measured["viewport"], measured
    assert not measured["over"], measured["over"][:5]


def test_the_kinds_table_shows_cross_validation_only_where_it_chose_the_kind(workflow):
    """The kinds' flow-force CV error is a column where it chose the main kind; with the kind
    chosen by --maps none was computed, and the column is left out, not shown empty."""
    from surrogate.reporting.report import staircases_section

    chosen = staircases_section({"gp": workflow, "grid": workflow}, "gp")
    ranked = staircases_section({"gp": workflow, "grid": workflow}, "gp",
                                scores={"gp": 0.021, "grid": 0.05})
    assert "CV error" not in chosen and "chosen with --maps" in chosen
    assert "flow-force CV error [%]" in ranked and "2.1" in ranked and "5.0" in ranked
