"""The feed profile (planner.feed_profile), its checker (planner.check_profile), its KRL and its use.

Named problems: a straight joint path (q linear in s, so q'' = 0 and the joint limits are closed
forms) with a ceiling that dips; the demo job planned with a profile (``demo_profiled``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from planner.check import check_result
from planner.check_profile import DYNAMICS_TOL, dynamics_violations
from planner.export import PROFILE_STEP, export_plan, plan_to_krl
from planner.feed_profile import profile_path, profile_timing
from planner.plan import plan_of_result
from planner.sections import CUT
from planner.supervisor.ceiling import planned_speed_at
from robot_io.krl import KrlMove, KrlProgramSpec, KrlSection, render_krl
from robot_io.krl.lint import lint_krl
from robot_io.krl.reader import read_krl, read_krl_text

VEL = np.full(6, 2.0)      # rad/s
ACC = np.full(6, 10.0)     # rad/s²
A_MAX, J_MAX = 1.0, 10.0   # m/s², m/s³


def _line(n: int = 400, length: float = 0.2, slope: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """s [m] and q [rad]: every joint moves ``slope`` rad per metre of path."""
    s = np.linspace(0.0, length, n)
    return s, np.outer(s, np.full(6, slope)) + np.linspace(-1.0, 1.0, 6)


def _dip(s: np.ndarray) -> np.ndarray:
    """20 mm/s with a 2 mm/s stretch in the middle [m/s]."""
    return np.where((s > 0.08) & (s < 0.12), 0.002, 0.02)


def test_profile_stays_under_the_ceiling_and_meets_every_limit():
    s, q = _line()
    c = _dip(s)
    prof = profile_path(s, q, c, VEL, ACC, A_MAX, J_MAX)
    assert np.all(prof.speed <= c * (1 + 1e-12))
    assert np.all(prof.speed <= prof.bound_speed * (1 + 1e-12))
    assert prof.speed[0] == prof.speed[-1] == 0.0          # rest to rest
    viol, worst = dynamics_violations(s, q, prof.speed, VEL, ACC, A_MAX, J_MAX)
    assert viol == []
    assert worst["path_jerk"] > 0.9          # the jerk binds somewhere: the check can fail
    # slower than the bound (it has a jerk limit), but not by much at these limits
    assert prof.bound_cycle_time <= prof.cycle_time <= 1.03 * prof.bound_cycle_time


def test_checker_flags_the_pointwise_bound_for_its_jerk():
    """toppra's bound switches the acceleration at once: the checker must see it."""
    s, q = _line()
    c = _dip(s)
    bound = profile_path(s, q, c, VEL, ACC, A_MAX, J_MAX, jerk=False)
    viol, _ = dynamics_violations(s, q, bound.speed, VEL, ACC, A_MAX, J_MAX)
    assert {v.constraint for v in viol} == {"path_jerk"}
    assert all(v.value > J_MAX * (1 + DYNAMICS_TOL) or v.value < -J_MAX for v in viol)


def test_a_tighter_jerk_limit_costs_time_and_still_holds():
    s, q = _line()
    c = _dip(s)
    loose = profile_path(s, q, c, VEL, ACC, A_MAX, J_MAX)
    tight = profile_path(s, q, c, VEL, ACC, A_MAX, 0.5)
    assert tight.cycle_time > loose.cycle_time
    assert dynamics_violations(s, q, tight.speed, VEL, ACC, A_MAX, 0.5)[0] == []


def test_joint_speed_limit_holds_where_it_is_below_the_ceiling():
    """q' = 0.5 rad/m for every joint: q̇_max = 0.005 rad/s allows 10 mm/s, under the 20 mm/s."""
    s, q = _line()
    c = _dip(s)
    slow = np.full(6, 0.005)
    prof = profile_path(s, q, c, slow, ACC, A_MAX, J_MAX)
    assert prof.speed.max() <= 0.010 * (1 + 1e-6)
    assert prof.speed.max() >= 0.010 * 0.99
    assert dynamics_violations(s, q, prof.speed, slow, ACC, A_MAX, J_MAX)[0] == []


def test_timing_on_every_sample_keeps_repeated_points():
    s, q = _line(200)
    s = np.insert(s, 50, s[50])           # a repeated CAM point
    q = np.insert(q, 50, q[50], axis=0)
    c = _dip(s)
    timing, prof = profile_timing(s, q, c, VEL, ACC, A_MAX, J_MAX)
    assert timing.speed.shape == s.shape
    assert timing.speed[50] == timing.speed[51]
    assert np.all(np.diff(timing.time) >= 0)
    assert timing.cycle_time == prof.cycle_time


# ------------------------------------------------------------------------------ the demo job
def test_demo_profile_is_checked_and_near_the_pointwise_bound(demo_profiled, demo_optimized):
    res = demo_profiled
    assert res.profiled and res.method == "optimize"
    report = check_result(res)
    assert report.ok, report.violations[:5]
    assert report.worst_ratio["path_jerk"] <= 1 + DYNAMICS_TOL
    assert report.worst_ratio["deflection"] > 0.99           # at its ceilings
    prof = res.profile
    assert res.cycle_time <= 1.03 * prof.bound_cycle_time    # the target
    assert res.cycle_time < demo_optimized.cycle_time        # faster than one feed per section
    cut = res.kinds == CUT
    ceiling = np.full(len(res.kinds), np.nan)
    ceiling[res.model.index] = res.ceilings.feed
    assert np.all(res.feed[cut] <= ceiling[cut] * (1 + 1e-12))
    assert np.all(res.timing.speed <= res.feed * (1 + 1e-12))


def test_demo_profile_keeps_the_sections_and_their_feeds(demo_profiled, demo_optimized):
    res = demo_profiled
    assert [(s.start, s.stop, s.kind, s.feed) for s in res.sections] == \
        [(s.start, s.stop, s.kind, s.feed) for s in demo_optimized.sections]
    varied = 0
    for sec in res.sections:
        f = res.feed[sec.start:sec.stop]
        if sec.kind == CUT:
            varied += f.min() < 0.98 * f.max()
        else:                     # air and rapid keep their planned speed, the profile under it
            assert np.all(f <= sec.feed * (1 + 1e-12))
    assert varied > 3
    assert res.feed.min() > 0       # the rest points carry a commanded feed


def test_profiled_krl_round_trip_is_exact_in_feeds_and_lints_clean(demo_profiled, tmp_path):
    plan = plan_of_result(demo_profiled)
    prog = plan_to_krl(plan)
    scaled = [m for m in prog.moves if m.feed_scale is not None]
    assert len(scaled) > 20 and all(m.feed_scale > 0 for m in scaled)
    assert max(m.feed_scale for m in scaled) > 1 > min(m.feed_scale for m in scaled)
    paths = export_plan(plan, tmp_path)
    assert lint_krl(tmp_path) == []
    text = "".join(p.read_text(encoding="ascii") for p in paths if p.suffix == ".src")
    assert "$VEL.CP = " in text and " * 0." in text
    tp = read_krl(paths[0])
    assert [m.feed for m in tp.moves] == list(prog.move_feeds)       # exactly
    smp = plan.samples
    end = np.array(prog.sample_of_move)
    written = np.array(prog.move_feeds)
    assert np.all(written <= smp.feed[end])                      # never faster than planned
    assert np.all(written >= smp.feed[end] * (1 - PROFILE_STEP) / (1 + PROFILE_STEP) - 1e-9)


def test_section_plan_krl_is_unchanged_by_the_profile_code(demo_optimized):
    prog = plan_to_krl(plan_of_result(demo_optimized))
    assert all(m.feed_scale is None for m in prog.moves)
    assert list(prog.move_feeds) == [prog.sections[m.section].feed_m_s for m in prog.moves]


def test_paged_profile_reissues_the_scaled_speed_on_the_next_page(tmp_path):
    spec = KrlProgramSpec("PROF", bco_axes_deg=(0, -90, 90, 0, 45, 0), page_lines=100)
    moves, expect = [], []
    for i in range(300):
        scale = None if i % 7 else round(1.0 - i / 1000.0, 6)
        moves.append(KrlMove("LIN", (i * 0.5, 0, -2, 0, 90, 0), 0, feed_scale=scale))
        if scale is not None:
            cur = 0.004 * scale
        expect.append(cur)
    out = render_krl(spec, [KrlSection(0.004)], moves)
    assert len(out.pages) >= 3
    for name, body in out.files.items():
        (tmp_path / name).write_bytes(body.encode("ascii"))
    assert lint_krl(tmp_path) == []
    tp = read_krl(tmp_path / "PROF.src")
    assert [m.feed for m in tp.moves] == expect


@pytest.mark.parametrize("line, why", [
    ("$VEL.CP = P_F001 * 0.5", "at least 6 decimals"),
    ("$VEL.CP = P_F001 * 3.000000", "is not in"),
    ("$VEL.CP = P_NONE * 0.500000", "not a REAL declared"),
])
def test_lint_judges_scaled_feeds(line, why):
    spec = KrlProgramSpec("P", bco_axes_deg=(0, -90, 90, 0, 45, 0))
    out = render_krl(spec, [KrlSection(0.9)], [KrlMove("LIN", (0, 0, 0, 0, 90, 0), 0),
                                               KrlMove("LIN", (1, 0, 0, 0, 90, 0), 0,
                                                       feed_scale=0.5)])
    files = dict(out.files)
    assert lint_krl(files) == []
    files["P.src"] = files["P.src"].replace("$VEL.CP = P_F001 * 0.500000", line)
    problems = [p for p in lint_krl(files) if p.rule == "vel_cp"]
    assert len(problems) == 1 and why in problems[0].message
    # the reader takes the product
    tp = read_krl_text(out.files["P.src"], out.files["P.dat"])
    assert [m.feed for m in tp.moves] == [0.9, 0.9 * 0.5]


def test_writer_refuses_a_bad_scale():
    from robot_io.krl import KrlError

    spec = KrlProgramSpec("P", bco_axes_deg=(0, -90, 90, 0, 45, 0))
    with pytest.raises(KrlError, match="feed_scale"):
        render_krl(spec, [KrlSection(0.01)], [KrlMove("LIN", (0, 0, 0, 0, 90, 0), 0,
                                                      feed_scale=0.0)])
    with pytest.raises(KrlError, match="maximum"):
        render_krl(spec, [KrlSection(1.5)], [KrlMove("LIN", (0, 0, 0, 0, 90, 0), 0,
                                                     feed_scale=2.0)])


def test_supervisor_ceiling_is_the_planned_speed_where_the_tool_is(demo_profiled, demo_optimized):
    plan = plan_of_result(demo_profiled)
    smp = plan.samples
    cut = np.flatnonzero(smp.kind == CUT)
    for k in cut[[5, 100, 300]]:
        s = float(smp.s[k]) - 1e-9             # on the way to sample k
        sec = plan.section_at(s)
        assert planned_speed_at(plan, s, sec) == smp.feed[k]
    plan2 = plan_of_result(demo_optimized)
    for sec in plan2.sections:
        mid = 0.5 * (sec.s_start + sec.s_end)
        assert planned_speed_at(plan2, mid, plan2.section_at(mid)) == sec.feed or \
            not np.isfinite(sec.feed)
    assert planned_speed_at(plan, 0.0, None) == 0.0


def test_the_job_file_can_ask_for_one_feed_per_section():
    import tomllib

    from planner.demo import demo_job_file
    from planner.job import parse_job

    path = demo_job_file()
    doc = tomllib.loads(Path(path).read_text(encoding="utf-8"))
    doc.setdefault("plan", {})["method"] = "sections"
    assert parse_job(doc, str(path), Path(path).parent).plan.method == "sections"
