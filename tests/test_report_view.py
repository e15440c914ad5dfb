"""The report's 3-D toolpath view and the plots that scale (planner/report/view3d.py, plots.py).

The view is self-contained (plotly.js packed in the page once, no script from the network), every
section's ends survive the decimation, and headless Chromium draws it (a screenshot whose view is
not blank). The 10,000-sample job's report stays under 5 MB. Skips, with the reason, where
Chromium is not installed (``apt-get install chromium``).
"""

from __future__ import annotations

import re
import tomllib
from importlib import resources
from pathlib import Path

import numpy as np
import pytest

from planner.job import load_job, parse_job
from planner.outputs import write_plan_outputs
from planner.plan import plan_job
from planner.report import find_browser, render_screenshot
from planner.report.plots import binned, crossings
from planner.report.view3d import COLOUR_MODES, toolpath_figure, view_samples

DEMO = Path(str(resources.files("planner").joinpath("data/demo/demo_job.toml")))
#: The long job of benchmarks/plan_speed.py: the demo contour sampled every 0.15 mm.
LONG_STEP_MM = 0.15
#: The issue's target for a 10,000-sample job's report.html [bytes].
REPORT_MAX_BYTES = 5_000_000

no_browser = pytest.mark.skipif(find_browser() is None,
                                reason="no Chromium to render the report (apt-get install chromium)")


@pytest.fixture(scope="module")
def demo(tmp_path_factory):
    folder = tmp_path_factory.mktemp("demo_report")
    out = write_plan_outputs(plan_job(load_job(DEMO)), folder)
    return out.result, out.files


def test_view_samples_keep_every_section_boundary():
    rows = [{"sample_start": a, "sample_stop": a + 7} for a in range(0, 10_500, 7)]
    keep = view_samples(10_500, rows, max_points=1000)
    assert keep.size < 10_500 / 2
    assert set(range(0, 10_500, 7)) <= set(keep.tolist())      # every first sample
    assert set(range(6, 10_500, 7)) <= set(keep.tolist())      # every last sample
    assert np.all(np.diff(keep) > 0) and keep[-1] == 10_499
    assert np.array_equal(view_samples(50, rows[:3], max_points=1000), np.arange(50))


def test_binned_statistics_and_crossing():
    s = np.linspace(0.0, 1.0, 101)
    v = np.where(s < 0.5, 1.0, 3.0)
    v[10] = np.nan
    b = binned(s, v, np.array([0.0, 0.25, 0.75, 1.0]), ("min", "max"))
    assert b["min"].tolist() == [1.0, 1.0, 3.0] and b["max"].tolist() == [1.0, 3.0, 3.0]
    # the force crosses its limit between grid points: the crossing, not a grid point
    feeds = np.array([5.0, 5.25, 5.5, 5.75])
    force = np.array([280.0, 295.0, 310.0, 325.0])
    assert crossings(feeds, force - 300.0) == pytest.approx([5.25 + 0.25 / 3])


def test_the_view_colours_hover_and_frames(demo):
    res, _ = demo
    from planner.report import BINDING_COLOURS

    fig = toolpath_figure(res, BINDING_COLOURS)
    names = [t["name"] for t in fig["data"]]
    assert "stock" in names and any(n.startswith("part frame") for n in names)
    cut = next(t for t in fig["data"] if t["name"] == "cut")
    hover = cut["hovertemplate"]
    for word in ("sample", "line", "feed", "binds", "a_e", "a_p"):
        assert word in hover
    buttons = fig["layout"]["updatemenus"][0]["buttons"]
    assert len(buttons) == len(COLOUR_MODES) == 4
    labels = [b["label"] for b in buttons]
    assert labels == ["planned feed", "binding constraint", "deflection", "chatter margin"]
    # the binding mode's colour bar names the bindings of the plan
    binding = buttons[1]["args"][0]["line.colorbar"][0]
    assert set(binding["ticktext"]) == {r["binding"] for r in res.section_rows if r["kind"] == "cut"}
    # the demo is short: every cut sample drawn, one point each, gaps (None) between the cuts
    from planner.sections import CUT

    points = [c for c in cut["customdata"] if c is not None]
    assert len(points) == int(np.sum(res.kinds == CUT))
    assert None in cut["x"]


def test_report_is_self_contained_with_headline_and_table(demo):
    res, files = demo
    page = Path(files["report"]).read_text(encoding="utf-8")
    # no script, style or image from the network; plotly.js once, packed
    assert not re.search(r"<script[^>]+src=", page)
    assert not re.search(r"""(src|href)=["']https?://""", page)
    assert page.count('id="cctmill-plotlyjs-gz"') == 1
    assert "cctmillViews" in page and "DecompressionStream" in page
    for word in ("rpm", "em25_2f", "al6061", "kr210_r2700_extra", "$BASE", "$TOOL",
                 "a_e max [mm]", "a_p max [mm]"):
        assert word in page, word
    # robot-bound sections name their joint
    if any(r["robot_limited"] for r in res.section_rows):
        assert re.search(r"A\d (speed|accel\.) \d+ %", page)
    # beyond 50 rows the rest of the section table is behind the "show all" switch
    if len(res.section_rows) > 50:
        assert page.count('<tbody class="more">') == 1 and 'id="all-sections"' in page


@no_browser
def test_rendered_report_draws_the_3d_view(demo, tmp_path):
    _, files = demo
    shot = render_screenshot(files["report"], tmp_path / "report.png", width=1240, height=1800)
    from PIL import Image

    img = np.asarray(Image.open(shot).convert("RGB"), float) / 255.0
    assert img.shape[:2] == (1800, 1240)
    # the view's area (below the headline tables): a drawn WebGL canvas has many colours, the
    # feed colour scale (viridis) among them; an empty or failed view is white and grey
    view = img[700:1500, 30:1100]
    colours = np.unique((view[::3, ::3] * 15).astype(int).reshape(-1, 3), axis=0)
    assert len(colours) > 60
    saturation = view.max(axis=2) - view.min(axis=2)
    assert np.mean(saturation > 0.25) > 0.002


@pytest.mark.slow
def test_the_10k_sample_report_is_under_5_mb(tmp_path):
    doc = tomllib.loads(DEMO.read_text(encoding="utf-8"))
    doc["path"]["step_max_mm"] = LONG_STEP_MM
    doc["job"]["name"] = "bracket_contour_long"
    job = parse_job(doc, str(DEMO), DEMO.parent)
    out = write_plan_outputs(plan_job(job), tmp_path)
    assert out.plan.summary["samples"] >= 10_000 if hasattr(out.plan, "summary") else True
    assert len(out.result.prep.path) >= 10_000
    size = Path(out.files["report"]).stat().st_size
    assert size < REPORT_MAX_BYTES, f"report.html is {size / 1e6:.2f} MB"


def test_the_kinematics_plot_scales_and_gives_joint_limits(tmp_path, monkeypatch):
    from planner.report import plots

    n = 12_000
    rng = np.random.default_rng(7)
    s = np.linspace(0.0, 12.0, n)
    lower, upper = np.radians([-185.0, -140.0]), np.radians([185.0, -5.0])
    q = np.column_stack([0.1 * np.sin(40 * s), -1.2 + 0.05 * rng.standard_normal(n)])
    mode = np.where(np.sin(300 * s) > 0, 1, 0)
    labels: list[str] = []
    real_save = plots.save_figure

    def save(plt, fig, title, path, bottom=0.0):
        labels.extend(t.get_text() for ax in fig.axes if ax.get_legend()
                      for t in ax.get_legend().get_texts())
        return real_save(plt, fig, title, path, bottom)

    monkeypatch.setattr(plots, "save_figure", save)
    png = plots.plot_path_kinematics(s, q, lower, upper, ("A1", "A2"), np.ones(n, bool),
                                     np.full(n, 2e-3), np.full(n, 1e-3), mode, tmp_path / "k.png")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # the legend gives each joint's limits (not only the travel used), drawn per bin when long
    assert any(t.startswith("A1 limits [-185, 185] deg") for t in labels), labels
    assert any(t.startswith("A2 limits [-140, -5] deg") for t in labels), labels
    assert any("per bin" in t for t in labels)


def test_progress_bars_only_on_a_terminal(monkeypatch):
    import io
    import sys

    from planner import _progress

    monkeypatch.setattr(sys, "stderr", io.StringIO())          # captured, as in a script
    assert not _progress.on_terminal()
    assert _progress.bar(50_000, "inverse kinematics", True).disable

    class Tty(io.StringIO):
        def isatty(self) -> bool:
            return True

    monkeypatch.setattr(sys, "stderr", Tty())
    monkeypatch.delenv("CI", raising=False)
    monkeypatch.setenv("TERM", "xterm")
    assert _progress.on_terminal()
    monkeypatch.setenv("CI", "true")                            # a CI runner with a pseudo-tty
    assert not _progress.on_terminal()
