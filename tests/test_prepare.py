"""A job end to end before planning: read, sample, solve, engage — on the bundled demo job."""

from __future__ import annotations

import json
from importlib import resources
from pathlib import Path

import numpy as np
import pytest

from planner.cli import main
from planner.job import load_job
from planner.prepare import inspect_job, prepare

DEMO = str(resources.files("planner").joinpath("data/demo/demo_job.toml"))
SHARED = Path(__file__).resolve().parents[2] / "shared" / "data" / "toolpaths"
INSPECT_KEYS = {"format", "units", "moves", "rapids", "arcs", "length_m", "cutting_length_m",
                "bbox_m", "feed_mm_min", "has_tool_axis", "warnings"}


@pytest.fixture(scope="module")
def demo():
    return prepare(load_job(DEMO))


def test_demo_job_is_fully_reachable_and_continuous(demo):
    kin = demo.kinematics
    assert kin.all_reachable, kin.problems
    assert kin.jumps.size == 0
    assert len(demo.path) > 500
    # Every sample traces back to a line of the CAM file.
    lines = Path(demo.toolpaths[0].file).read_text().splitlines()
    assert all(1 <= ln <= len(lines) for ln in demo.path.line)


def test_demo_engagement_is_the_programmed_contour(demo):
    """Outside contour, climb milling, 3 mm stock on the straight walls, a_p = 10 mm per level."""
    e = demo.engagement
    cutting = e.mode >= 0
    assert set(np.unique(e.mode[cutting])) == {1}  # down (climb) milling only
    assert np.allclose(e.a_p[cutting], 0.010, atol=1e-6)
    # On the straight walls the radial depth is the 3 mm of stock the contour removes.
    assert np.median(e.a_e[cutting]) == pytest.approx(0.003, abs=2e-5)
    # Y_o = Z_o × X_o runs along the tool axis (towards the spindle), as docs/model.md §4 needs.
    y_o = np.cross(e.feed_dir[cutting], e.radial_dir[cutting])
    assert np.allclose(y_o, demo.path.tool_axis[cutting], atol=1e-9)


def test_inspect_job_summary(demo):
    out = inspect_job(demo)
    assert out["reachability"]["all_reachable"]
    assert out["engagement"]["modes"]["down"] > 0
    assert INSPECT_KEYS <= out["toolpaths"][0].keys()
    json.dumps(out)  # serialisable


def test_cli_inspect_job_writes_plot(tmp_path, capsys):
    png = tmp_path / "kin.png"
    assert main(["inspect", DEMO, "--json", "--plot", str(png)]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["samples"] > 500 and out["reachability"]["unreachable_samples"] == 0
    assert png.read_bytes()[:4] == b"\x89PNG" and png.stat().st_size > 20_000


def test_cli_inspect_toolpath_contract(capsys):
    demo_nc = str(resources.files("planner").joinpath("data/demo/bracket_contour.nc"))
    assert main(["inspect", demo_nc, "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert INSPECT_KEYS <= out.keys()
    assert out["format"] == "gcode" and out["units"] == "mm"
    assert out["arcs"] == 12 and out["has_tool_axis"] is False
    assert out["feed_mm_min"] == {"min": pytest.approx(300.0), "max": pytest.approx(1200.0)}
    # The finished contour is 200 x 120 with R20 corners; the tool centre runs 12.7 mm outside.
    assert out["bbox_m"][1][0] == pytest.approx(0.2127, abs=1e-9)
    assert out["bbox_m"][1][1] == pytest.approx(0.1327, abs=1e-9)


@pytest.mark.skipif(not SHARED.is_dir(), reason=f"shared toolpaths not found at {SHARED}")
def test_cli_inspect_every_shared_file_prints_a_summary(capsys):
    for path in sorted(SHARED.iterdir()):
        if path.name.endswith(".source.txt"):
            continue
        rc = main(["inspect", str(path), "--json", "--lenient"])
        out = json.loads(capsys.readouterr().out)
        assert rc == 0 and out["moves"] > 0, path.name
        assert INSPECT_KEYS <= out.keys()


def test_cli_inspect_missing_file_is_one_line(capsys, tmp_path):
    assert main(["inspect", str(tmp_path / "nope.nc")]) == 2
    err = capsys.readouterr().err
    assert "not found" in err and ":0:0" not in err and len(err.strip().splitlines()) == 1


def test_cli_inspect_of_a_job_that_cannot_be_reached_exits_2(capsys, tmp_path):
    """A job out of reach is a job that cannot be cut: inspect says so and exits 2, like plan,
    and lists joint ranges only of the samples reached (issue 22)."""
    text = Path(DEMO).read_text(encoding="utf-8")
    text = text.replace("base_mm = [1500.0, -60.0, 400.0]", "base_mm = [2600.0, -60.0, 400.0]")
    text = text.replace('toolpath = ["bracket_contour.nc"]',
                        f'toolpath = ["{(Path(DEMO).parent / "bracket_contour.nc").as_posix()}"]')
    job = tmp_path / "far.toml"
    job.write_text(text, encoding="utf-8")
    assert main(["inspect", str(job)]) == 2
    out = capsys.readouterr()
    assert "reachable     NO" in out.out
    err = out.err.strip().splitlines()
    assert len(err) == 1 and "cannot be reached" in err[0], err
    assert main(["inspect", str(job), "--json"]) == 2
    doc = json.loads(capsys.readouterr().out)
    assert doc["reachability"]["unreachable_samples"] > 0
