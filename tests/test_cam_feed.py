"""The programmed feed as the user's intent (planner.cam_feed, issue 16): no cut above the CAM
feed × cam_feed_scale_max, air moves as programmed and never above the rapid speed, plunges over
the plunge only, no empty or zero-length sections, and the checker holding all of it."""

from __future__ import annotations

import tomllib
from dataclasses import replace
from importlib import resources
from pathlib import Path

import numpy as np
import pytest

from models.errors import InputError
from planner.check import check_result
from planner.job import JobError, parse_job
from planner.plan import plan_prepared
from planner.prepare import prepare
from planner.sections import AIR, CUT, RAPID, step_lengths

DEMO = Path(str(resources.files("planner").joinpath("data/demo/demo_job.toml")))


def _job(folder: Path = DEMO.parent, **tables):
    doc = tomllib.loads(DEMO.read_text(encoding="utf-8"))
    for table, keys in tables.items():
        doc.setdefault(table, {}).update(keys)
    return parse_job(doc, "variant.toml", folder)


@pytest.fixture(scope="module")
def plans():
    """The demo planned with the default factor (1) and with the demo's (2)."""
    out = {}
    for scale in (1.0, 2.0):
        prep = prepare(_job(limits={"cam_feed_scale_max": scale}))
        out[scale] = {m: plan_prepared(prep, m) for m in ("optimize", "thesis")}
    return out


@pytest.mark.parametrize("scale", [1.0, 2.0])
@pytest.mark.parametrize("method", ["optimize", "thesis"])
def test_no_cut_runs_faster_than_the_programmed_feed_times_the_factor(plans, scale, method):
    res = plans[scale][method]
    prog = res.prep.path.feed
    cut = res.kinds == CUT
    assert np.all(res.feed[cut] <= prog[cut] * scale * (1 + 1e-12))
    assert check_result(res).ok, check_result(res).violations[:3]


def test_the_default_factor_binds_at_the_cam_feed(plans):
    res = plans[1.0]["optimize"]
    assert any(s.binding == "cam_feed" for s in res.plan_sections if s.kind == "cut")
    # the program asks for F1200 (20 mm/s) on the contour: nothing cuts faster
    assert res.feed[res.kinds == CUT].max() <= 0.020 * (1 + 1e-12)


@pytest.mark.parametrize("scale", [1.0, 2.0])
def test_air_moves_run_as_programmed_and_never_above_the_rapid_speed(plans, scale):
    res = plans[scale]["optimize"]
    prog = res.prep.path.feed
    for sec in res.sections:
        if sec.kind == RAPID:
            assert sec.feed == res.limits.rapid_speed and sec.binding == "rapid"
        elif sec.kind == AIR:
            p = prog[sec.start:sec.stop]
            p = p[np.isfinite(p)]
            assert sec.feed <= res.limits.rapid_speed
            assert p.size == 0 or np.all(sec.feed <= p * (1 + 1e-12)), (sec, p)
            assert sec.binding != "feed_max" or p.size == 0
    assert np.all(res.timing.speed[res.kinds == AIR] <= res.limits.rapid_speed * (1 + 1e-6))


def test_a_plunge_feed_holds_over_the_plunge_only(plans):
    """The demo's second level: the plunge (line 25, F300) is its own air section; the lateral
    move after it (line 26, programmed F1200) runs at 20 mm/s, not at the plunge's 5 mm/s."""
    res = plans[2.0]["optimize"]
    line = res.prep.path.line
    by_line = {}
    for sec in res.sections:
        if sec.kind == AIR:
            for ln in set(line[sec.start:sec.stop].tolist()):
                by_line.setdefault(ln, []).append(sec)
    assert [round(s.feed * 1e3, 6) for s in by_line[25]] == [5.0]
    assert "plunge" in by_line[25][0].note
    assert [round(s.feed * 1e3, 6) for s in by_line[26]] == [20.0]


def test_no_section_is_empty_or_of_zero_length(plans, tmp_path):
    for res in (plans[1.0]["optimize"], plans[2.0]["thesis"]):
        ds = step_lengths(res.prep.path.s)
        for sec in res.sections:
            assert sec.stop > sec.start
            assert ds[sec.start:sec.stop].sum() > 0.0, sec
    # a program with a zero-length move between a rapid and the cut, and a repeated point
    program = (DEMO.parent / "bracket_contour.nc").read_text(encoding="utf-8")
    program = program.replace("N35 Z10.\n", "N35 Z10.\nN36 G1 Z10. F300.\nN37 G1 Z10.\n", 1)
    (tmp_path / "zero.nc").write_text(program, encoding="utf-8")
    res = plan_prepared(prepare(_job(tmp_path, job={"toolpath": ["zero.nc"]})), "optimize")
    ds = step_lengths(res.prep.path.s)
    assert all(sec.stop > sec.start and ds[sec.start:sec.stop].sum() > 0 for sec in res.sections)
    assert check_result(res).ok


def test_a_cut_programmed_below_feed_min_is_refused_with_its_line(tmp_path):
    program = (DEMO.parent / "bracket_contour.nc").read_text(encoding="utf-8")
    program = program.replace("N45 G3 X-12.700 Y60. I0. J15. F1200.",
                              "N45 G3 X-12.700 Y60. I0. J15. F12.", 1)
    (tmp_path / "slow.nc").write_text(program, encoding="utf-8")
    prep = prepare(_job(tmp_path, job={"toolpath": ["slow.nc"]}))
    with pytest.raises(InputError, match=r"slow.nc:13 is programmed at 12.0 mm/min.*feed_min_mm_s"):
        plan_prepared(prep, "optimize")


def test_feed_max_above_the_rapid_speed_is_a_units_slip():
    with pytest.raises(JobError, match=r"feed_max_mm_s 2400 is above rapid_mm_s 250.*40 mm/s"):
        _job(limits={"feed_max_mm_s": 2400.0})


def test_the_checker_catches_a_cut_above_the_programmed_feed(plans):
    res = plans[1.0]["optimize"]
    sec = next(s for s in res.sections if s.kind == CUT and s.binding == "cam_feed")
    bad = replace(sec, feed=sec.feed * 1.01)
    sections = [bad if s is sec else s for s in res.sections]
    feed = res.feed.copy()
    feed[sec.start:sec.stop] = bad.feed
    from planner.check import check_plan

    report = check_plan(res.prep, feed, res.kinds, None,
                        [(s.start, s.stop, s.kind, s.feed) for s in sections], res.limits)
    assert any(v.constraint == "cam_feed" for v in report.violations)
