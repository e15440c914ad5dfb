"""The feed planner: every plan re-checked independently, optimiser vs thesis vs constant, errors.

Named problems: the bundled demo job (``planner/data/demo``: outside contour of an Al 6061
bracket on the KR 210, engagement from the stock) and variants of it with other limits.
"""

from __future__ import annotations

import json
import tomllib
from importlib import resources
from pathlib import Path

import numpy as np
import pytest

from planner.ceilings import CONSTRAINTS
from planner.check import check_result
from planner.cli import main
from planner.job import parse_job
from planner.outputs import write_plan_outputs
from planner.partition import fastest_split, split_time
from planner.plan import PlanInfeasibleError, plan_prepared
from planner.plan_file import BINDINGS, SAMPLE_ARRAYS, load_plan
from planner.prepare import prepare
from planner.sections import CUT, RAPID, kind_runs, step_lengths

DEMO = Path(str(resources.files("planner").joinpath("data/demo/demo_job.toml")))


def _demo_doc() -> dict:
    return tomllib.loads(DEMO.read_text(encoding="utf-8"))


def _job(**tables):
    """The demo job with some tables' keys replaced."""
    doc = _demo_doc()
    for table, keys in tables.items():
        doc.setdefault(table, {}).update(keys)
    return parse_job(doc, "variant.toml", DEMO.parent)


@pytest.fixture(scope="module")
def demo_prep():
    return prepare(_job())


@pytest.fixture(scope="module")
def demo_plans(demo_prep):
    return {m: plan_prepared(demo_prep, m) for m in ("optimize", "sections", "thesis", "constant")}


@pytest.mark.parametrize("method", ["optimize", "sections", "thesis", "constant"])
def test_independent_checker_finds_no_violation(demo_plans, method):
    res = demo_plans[method]
    report = check_result(res)
    assert report.samples_checked == int(np.sum(res.kinds == CUT)) > 700
    assert report.ok, report.violations[:5]
    # the plan really is at a limit somewhere (a checker that cannot fail would pass a 0 feed);
    # the thesis keeps its safety factor away from it
    assert max(report.worst_ratio.values()) > (0.8 if method == "thesis" else 0.99)


def test_checker_catches_a_plan_that_is_too_fast(demo_plans):
    res = demo_plans["sections"]
    feed = res.feed * 1.05
    from planner.check import check_plan

    report = check_plan(res.prep, feed, res.kinds, None,
                        [(s.start, s.stop, s.kind, s.feed * 1.05) for s in res.sections], res.limits)
    assert not report.ok
    assert {v.constraint for v in report.violations} >= {"deflection"}
    assert all(":" in v.where for v in report.violations)


def test_optimizer_beats_thesis_beats_constant(demo_plans):
    t = {m: r.cycle_time for m, r in demo_plans.items()}
    # the profile (optimize) is faster than its own sections at one feed each
    assert t["optimize"] < t["sections"] < t["thesis"] < t["constant"]
    # the thesis's safety factor alone costs ~1/1.1 of the cut; the optimiser must keep it
    assert t["sections"] < 0.95 * t["thesis"]
    for m in ("optimize", "sections"):
        assert demo_plans[m].solver.success
        assert demo_plans[m].solver.status == "Solve_Succeeded"


def test_optimum_reaches_the_fastest_split_bound(demo_plans):
    """Without a feed-change bound the optimiser's cut time is the exact split optimum's."""
    res = demo_plans["sections"]
    ds = step_lengths(res.prep.path.s)
    ceiling = np.full(ds.size, np.nan)
    ceiling[res.model.index] = res.ceilings.feed
    bound = sum(split_time(ds, ceiling, fastest_split(ds, ceiling, a, b,
                                                      res.limits.section_length_min))
                for a, b, kind in kind_runs(res.kinds) if kind == CUT)
    assert res.cut_time_bound == pytest.approx(bound, rel=1e-12)
    cut = res.kinds == CUT
    planned = {m: float(np.sum(ds[cut] / r.feed[cut])) for m, r in demo_plans.items()}
    assert bound * (1 - 1e-9) <= planned["sections"] <= bound * (1 + 2e-3)
    # no plan with sections >= section_length_min is faster; the thesis is above it
    assert planned["thesis"] > 1.05 * bound


def test_sections_partition_the_path_and_never_mix_kinds(demo_plans):
    for res in demo_plans.values():
        n = len(res.prep.path)
        stops = [s.start for s in res.sections[1:]] + [n]
        assert res.sections[0].start == 0
        assert [s.stop for s in res.sections] == stops
        for s in res.sections:
            assert np.all(res.kinds[s.start:s.stop] == s.kind)
            assert s.binding in BINDINGS
        for row in res.section_rows:
            assert row["binding"] in BINDINGS


def test_feed_of_every_cut_section_is_its_tightest_sample_or_below(demo_plans):
    res = demo_plans["sections"]
    ceiling = np.full(len(res.prep.path), np.nan)
    ceiling[res.model.index] = res.ceilings.feed
    at_limit = 0
    for s in res.sections:
        if s.kind != CUT:
            continue
        lowest = np.nanmin(ceiling[s.start:s.stop])
        assert s.feed <= lowest * (1 + 1e-9)
        at_limit += s.feed >= lowest * (1 - 1e-3)
    assert at_limit >= 0.8 * sum(s.kind == CUT for s in res.sections)


def test_ceiling_is_the_edge_of_feasibility(demo_prep, demo_plans):
    res = demo_plans["optimize"]
    model, ceil = res.model, res.ceilings
    inside = model.evaluate(ceil.feed)
    assert np.all(inside.all_ok)
    # held by a process constraint (not feed_max, the programmed feed or the tool's chip load)
    bound = np.flatnonzero(np.isin(ceil.binding, CONSTRAINTS))
    assert bound.size > 0.9 * len(ceil.binding)
    above = model.evaluate(ceil.feed[bound] * 1.003, bound)
    assert not np.any(above.all_ok)
    for k in range(len(CONSTRAINTS)):  # the named binding constraint is the one that breaks
        named = ceil.binding[bound] == CONSTRAINTS[k]
        assert np.all(~above.ok[named, k])


def test_rescaling_the_feed_variable_does_not_change_the_answer(demo_prep):
    a = plan_prepared(demo_prep, "sections")
    b = plan_prepared(demo_prep, "sections", f_ref=1e-3)
    assert b.solver.success
    np.testing.assert_allclose(a.feed, b.feed, rtol=2e-4)
    assert len(a.sections) == len(b.sections)


def test_thesis_baseline_is_reproducible_and_follows_safety_factor(demo_prep):
    a = plan_prepared(demo_prep, "thesis", safety_factor=1.1)
    b = plan_prepared(demo_prep, "thesis", safety_factor=1.1)
    np.testing.assert_array_equal(a.feed, b.feed)
    c = plan_prepared(demo_prep, "thesis", safety_factor=1.3)
    assert c.cycle_time > a.cycle_time
    ceiling = np.full(len(demo_prep.path), np.nan)
    ceiling[a.model.index] = a.ceilings.feed
    for res, sf in ((a, 1.1), (c, 1.3)):
        for sec in res.sections:
            if sec.kind == CUT:  # f_real = f_max / SF at the midpoint, or less
                mid_ceiling = np.nanmax(ceiling[sec.start:sec.stop])
                assert sec.feed <= mid_ceiling / sf * (1 + 1e-12)


def test_infeasible_force_limit_names_section_and_constraint():
    job = _job(limits={"force_max_n": 20.0})
    with pytest.raises(PlanInfeasibleError, match=r"section \d+ \(s .* m, .*bracket_contour.nc:\d+\):"
                       r" force limit cannot be met even at feed_min_mm_s") as err:
        plan_prepared(prepare(job), "optimize")
    assert err.value.constraint == "force"
    assert "edge forces" in str(err.value)
    # the message numbers the section from 1, as plan.json and the KRL program do
    assert str(err.value).startswith(f"section {err.value.section + 1} (s ")


def test_infeasible_plan_from_the_cli_is_one_line(capsys, tmp_path):
    text = DEMO.read_text(encoding="utf-8").replace("force_max_n = 300.0", "force_max_n = 20.0")
    text = text.replace('toolpath = ["bracket_contour.nc"]',
                        f'toolpath = ["{(DEMO.parent / "bracket_contour.nc").as_posix()}"]')
    job = tmp_path / "tight.toml"
    job.write_text(text, encoding="utf-8")
    assert main(["plan", str(job), "-o", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert "section" in err[0] and "force limit cannot be met" in err[0]
    assert not (tmp_path / "out" / "plan.json").exists()


def test_deflection_tolerance_below_the_floor_is_infeasible(demo_prep):
    job = _job(limits={"deflection_tol_mm": 0.1})
    with pytest.raises(PlanInfeasibleError, match="deflection limit cannot be met") as err:
        plan_prepared(prepare(job), "optimize")
    assert err.value.constraint == "deflection"


def test_power_limit_binds_when_small():
    res = plan_prepared(prepare(_job(spindle={"power_max_kw": 0.3})), "optimize")
    assert "power" in {s.binding for s in res.sections}
    assert check_result(res).ok
    assert res.evaluation.power.max() <= 300.0 * (1 + 1e-9)


def test_feed_change_bound_holds_between_neighbouring_sections():
    # a section plan's steps (a feed profile's changes are bounded by path acceleration and jerk)
    res = plan_prepared(prepare(_job(limits={"feed_change_max_mm_s": 1.0})), "sections")
    cut = [s for s in res.sections if s.kind == CUT]
    steps = [abs(b.feed - a.feed) for a, b in zip(cut, cut[1:], strict=False) if a.stop == b.start]
    assert max(steps) <= 1e-3 * (1 + 1e-6)
    assert "feed_change" in {s.binding for s in res.sections}
    assert check_result(res).ok


def test_timing_never_exceeds_the_plan_and_rapids_are_timed(demo_plans):
    res = demo_plans["sections"]
    assert np.all(res.timing.speed <= res.feed * (1 + 1e-6) + 1e-12)
    assert np.all(res.timing.bound <= res.feed + 1e-15)
    assert res.cycle_time >= res.process_time * 0.999 - 1e-9 - np.sum(
        np.diff(res.prep.path.s)[res.kinds[1:] == RAPID] / res.feed[1:][res.kinds[1:] == RAPID])
    assert np.all(np.diff(res.timing.time) >= 0)


def test_plan_files_follow_the_contract(demo_plans, tmp_path):
    res = demo_plans["optimize"]
    written = write_plan_outputs(res, tmp_path).files
    plan = load_plan(tmp_path)
    assert plan.method == "optimize"
    doc = json.loads((tmp_path / "plan.json").read_text(encoding="utf-8"))
    with np.load(tmp_path / "samples.npz") as z:
        arrays = {k: z[k] for k in z.files}
    for key in ("method", "sections", "cycle_time_s", "constraints", "solver", "samples_file"):
        assert key in doc
    assert set(doc["solver"]) >= {"status", "iterations", "build_time_s", "solve_time_s"}
    for sec in doc["sections"]:
        for key in ("s_start_m", "s_end_m", "feed_mm_s", "binding", "margin_N_per_m",
                    "force_max_N", "deflection_max_mm", "gamma_deg"):
            assert key in sec
    assert doc["cycle_time_s"] == pytest.approx(res.cycle_time)
    n = len(res.prep.path)
    for name, tail in SAMPLE_ARRAYS.items():
        assert arrays[name].shape == (n, *tail)
    cut = arrays["kind"] == CUT
    assert np.all(np.isfinite(arrays["force_N"][cut]))
    assert np.all(np.isfinite(plan.samples.force[plan.samples.kind == CUT]))
    html = written["report"].read_text(encoding="utf-8")
    assert html.count("data:image/png;base64,") == 2
    assert "<img" in html and "src=\"http" not in html
    assert written["plot_along_path"].stat().st_size > 20_000


def test_pose_in_base_is_the_ik_pose(demo_plans, tmp_path):
    """abc_wp_deg/position_wp_m describe the solved pose: rebuild the flange from them."""
    res = demo_plans["optimize"]
    write_plan_outputs(res, tmp_path, report=False)
    s = load_plan(tmp_path).samples
    from robot_io.krl.frames import frame_from_mm_deg as frame_matrix

    job = res.prep.job
    base = job.base_frame()
    tool = job.tool_frame()
    robot = res.prep.robot
    for k in (0, 100, 500, len(res.prep.path) - 1):
        t_wp = frame_matrix(s.position_wp[k] * 1e3, np.degrees(s.abc_wp[k]))
        p, rot = robot.pose_function(s.q[k], np.zeros(3))
        flange = np.eye(4)
        flange[:3, :3] = np.asarray(rot)
        flange[:3, 3] = np.asarray(p).reshape(3)
        np.testing.assert_allclose(base @ t_wp, flange @ tool, atol=1e-6)


def test_cli_plan_demo_json(tmp_path, capsys):
    assert main(["plan", "--demo", "-o", str(tmp_path), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["method"] == "optimize"
    assert doc["solver"]["status"] == "Solve_Succeeded"
    assert (tmp_path / "plan.json").is_file() and (tmp_path / "report.html").is_file()


def test_floquet_criterion_plans_are_checked_and_its_verdict_can_refuse():
    """The exact time-periodic criterion: a light cut plans and passes the checker; the demo's
    10 mm deep cut at 4000 rpm is unstable by Floquet (the averaged thesis model calls it stable),
    so the planner refuses it naming the criterion."""
    light = _job(model={"chatter_criterion": "floquet"},
                 engagement={"source": "fixed", "ae_mm": 1.0, "ap_mm": 1.0, "milling": "down"})
    res = plan_prepared(prepare(light), "optimize")
    assert np.all(res.model.floquet_radius() < 1.0)
    assert check_result(res).ok
    with pytest.raises(PlanInfeasibleError, match=r"chatter limit .* Floquet spectral radius 1\.\d+"):
        plan_prepared(prepare(_job(model={"chatter_criterion": "floquet"})), "optimize")
