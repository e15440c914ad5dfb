"""The posture along the path (planner/posture.py) on the off-axis demo cell, and its DP."""

from __future__ import annotations

import dataclasses
import itertools
import math
from importlib import resources

import numpy as np
import pytest

from planner.ceilings import PathModel
from planner.check import check_result
from planner.job import JobError, load_job
from planner.plan import plan_prepared
from planner.posture import (
    Posture,
    PostureOptions,
    _dp,
    apply_posture,
    check_posture,
    choose_posture,
    on_a6_axis,
    posture_by_section,
    tool_rotation_offsets,
)
from planner.prepare import prepare
from planner.sections import step_lengths

DEMO = str(resources.files("planner").joinpath("data/demo/demo_job.toml"))
OFFAXIS = str(resources.files("planner").joinpath("data/demo_offaxis/demo_offaxis_job.toml"))
RATE = 1.0  # the off-axis job's posture_rate_deg_per_mm (the default)


@pytest.fixture(scope="module")
def today():
    return prepare(load_job(OFFAXIS), posture="first_sample")


@pytest.fixture(scope="module")
def chosen(today) -> Posture:
    return choose_posture(today, PostureOptions(rate_deg_per_mm=RATE))


@pytest.fixture(scope="module")
def posed(today, chosen):
    return apply_posture(today, chosen)


def test_offaxis_job_is_the_mount_it_documents(today):
    job = today.job
    assert job.cell.tcp_mm == [250.0, 0.0, 200.0]
    assert job.cell.tcp_abc_deg == [0.0, -90.0, 0.0]
    # the tool axis (TCP +x) is the flange's +z: off and perpendicular to the A6 axis (flange x)
    tool = job.tool_frame()
    np.testing.assert_allclose(tool[:3, 0], [0.0, 0.0, 1.0], atol=1e-12)
    assert today.kinematics.all_reachable, today.kinematics.problems
    assert not on_a6_axis(today)


def test_posture_is_continuous_rate_bounded_inside_limits_without_flips(today, chosen, posed):
    assert chosen.fallback == ""
    kin = posed.kinematics
    assert kin.all_reachable and kin.jumps.size == 0
    rep = check_posture(posed, chosen.offset, RATE)
    assert rep.ok, rep
    assert rep.rate_max <= math.radians(RATE) * 1e3 * (1 + 1e-9)
    # the same wrist configuration as today's at every sample, inside the limits
    assert np.all(np.sign(kin.q[:, 4]) == np.sign(today.kinematics.q[:, 4]))
    lo, hi = today.robot.data.lower, today.robot.data.upper
    assert np.all((kin.q >= lo - 1e-9) & (kin.q <= hi + 1e-9))
    # the posture actually turns the tool (the off-axis cell has something to gain)
    assert np.ptp(chosen.offset) > math.radians(10.0)


def test_posture_check_measures_the_rotation_and_finds_what_is_wrong(today, chosen, posed):
    # measured from the joints against today's (the posture's reference), its own rate bound
    rep = check_posture(posed)
    assert rep.ok, rep
    assert rep.rate_max == pytest.approx(chosen.rate_max, rel=1e-4, abs=1e-6)
    assert check_posture(today).rate_max == 0.0  # no posture: nothing to measure the rate of
    # a rotation turned too fast, a joint jump, a wrist flip, a joint outside its limits
    fast = chosen.offset.copy()
    fast[400:] += math.radians(5.0)
    assert 400 in check_posture(posed, fast, RATE).rate_violations
    q = posed.kinematics.q.copy()
    q[300:, 0] += math.radians(30.0)
    q[500, 4] *= -1.0
    q[600, 2] = today.robot.data.upper[2] + 0.1
    bad = dataclasses.replace(posed, kinematics=dataclasses.replace(posed.kinematics, q=q))
    rep = check_posture(bad, chosen.offset, RATE)
    assert 300 in rep.jumps and 500 in rep.wrist_flips and 600 in rep.limit_violations
    assert not rep.ok


def test_posture_is_the_rotation_it_reports_and_keeps_the_task(today, chosen, posed):
    measured = tool_rotation_offsets(today, posed.kinematics, today.kinematics)
    np.testing.assert_allclose(measured, chosen.offset, atol=1e-5)
    assert np.max(posed.kinematics.position_error) < 1e-6


def test_chosen_posture_is_never_slower_than_todays_on_the_binding_ceiling(today, chosen, posed):
    assert chosen.time_chosen <= chosen.time_today * (1 + 1e-12)
    assert chosen.gain > 0.05
    # on the planner's own ceilings of every cut sample, not only the DP's stations
    ds = step_lengths(today.path.s)
    m0, m1 = PathModel(today), PathModel(posed)
    np.testing.assert_array_equal(m0.index, m1.index)
    t0 = float(np.sum(ds[m0.index] / m0.ceilings().feed))
    t1 = float(np.sum(ds[m1.index] / m1.ceilings().feed))
    assert t1 < t0


def test_offaxis_cell_plans_with_the_posture_and_checks_clean(today, posed):
    r0 = plan_prepared(today, "optimize")
    r1 = plan_prepared(posed, "optimize")
    assert r1.solver.success
    assert r1.cycle_time < r0.cycle_time
    assert check_result(r1).ok
    rows = posture_by_section(posed.posture, r1.sections)
    assert len(rows) == len(r1.sections)
    assert sum(r["time_chosen_s"] for r in rows) == pytest.approx(posed.posture.time_chosen)


def test_on_the_a6_axis_the_posture_changes_nothing():
    """Demo cell (spindle on A6): turning about the tool axis moves A6 alone — no gain."""
    prep = prepare(load_job(DEMO))
    assert on_a6_axis(prep)
    kept = choose_posture(prep)
    assert "A6 axis" in kept.fallback and not np.any(kept.offset)
    assert kept.kinematics is prep.kinematics
    # and the search, made to run, finds nothing to gain and keeps today's rotation
    po = choose_posture(prep, PostureOptions(span_deg=60.0, ik_step_deg=30.0, station_mm=20.0,
                                             skip_on_axis=False))
    assert abs(po.gain) < 1e-3
    assert np.max(np.abs(po.offset)) < 1e-12


def test_job_key_path_posture_and_its_contradiction(today, posed):
    job = today.job
    kin = job.kinematics.model_copy(update={"posture": "path"})
    prep = prepare(job.model_copy(update={"kinematics": kin}))
    assert prep.posture is not None and "posture_s" in prep.wall_times
    np.testing.assert_allclose(prep.kinematics.q, posed.kinematics.q, atol=1e-9)
    kin = job.kinematics.model_copy(update={"posture": "path", "tool_rotation": "fixed"})
    with pytest.raises(JobError, match="posture"):
        prepare(job.model_copy(update={"kinematics": kin}))
    with pytest.raises(JobError, match="posture"):
        prepare(job, posture="everywhere")


def _brute(cost, feas, moves, change):
    k, g = cost.shape
    best, arg = math.inf, None
    for states in itertools.product(range(g), repeat=k):
        if not all(feas[a, s] for a, s in enumerate(states)):
            continue
        steps = [abs(states[a] - states[a - 1]) for a in range(1, k)]
        if any(d > moves[a + 1] for a, d in enumerate(steps)):
            continue
        v = sum(cost[a, s] for a, s in enumerate(states)) + sum(
            change[a + 1] * d for a, d in enumerate(steps))
        if v < best:
            best, arg = v, states
    return best, arg


def test_dp_is_the_exact_optimum_under_the_rate_bound(rng):
    for _ in range(20):
        k, g = 5, 4
        cost = rng.uniform(0.0, 1.0, (k, g))
        feas = rng.uniform(size=(k, g)) > 0.25
        feas[:, 1] = True  # a feasible path exists
        moves = rng.integers(0, 3, k)
        change = np.full(k, 0.05)
        best, _ = _brute(cost, feas, moves, change)
        s = _dp(cost, feas, moves, change)
        assert all(feas[a, s[a]] for a in range(k))
        assert all(abs(s[a] - s[a - 1]) <= moves[a] for a in range(1, k))
        v = cost[np.arange(k), s].sum() + float(np.sum(change[1:] * np.abs(np.diff(s))))
        assert v == pytest.approx(best)


def test_posture_options_are_frozen():
    with pytest.raises(dataclasses.FrozenInstanceError):
        PostureOptions().rate_deg_per_mm = 2.0  # type: ignore[misc]
