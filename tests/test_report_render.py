"""The report as a user sees it: rendered by headless Chromium, offline, plots visible.

Skips (with the reason) where no Chromium is installed: ``apt-get install chromium``.
"""

from __future__ import annotations

import numpy as np
import pytest

from planner.outputs import write_plan_outputs
from planner.plan import plan_job
from planner.report import find_browser, render_screenshot

pytestmark = pytest.mark.skipif(find_browser() is None,
                                reason="no Chromium to render the report (apt-get install chromium)")


def test_rendered_report_shows_the_plots(tmp_path):
    from importlib import resources

    from planner.job import load_job

    job = load_job(str(resources.files("planner").joinpath("data/demo/demo_job.toml")))
    written = write_plan_outputs(plan_job(job), tmp_path).files
    shot = render_screenshot(written["report"], tmp_path / "report.png", height=2600)
    import matplotlib.image as mpimg

    img = mpimg.imread(shot)[..., :3]
    assert img.shape[0] == 2600 and img.shape[1] == 1240
    # a page of plots, not a blank or an error page: much ink, many colours
    ink = np.mean(np.any(img < 0.9, axis=2))
    assert ink > 0.05
    colours = np.unique((img[::4, ::4] * 15).astype(int).reshape(-1, 3), axis=0)
    assert len(colours) > 100
    # the embedded plot is there: its binding-constraint bands are violet (deflection, #9467bd)
    violet = np.all(np.abs(img - np.array([0x94, 0x67, 0xbd]) / 255) < 0.08, axis=2)
    assert violet.sum() > 1000
