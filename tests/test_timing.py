"""Timing (ruckig-shaped feed bound, toppra) and the section algorithms on named small problems.

Named problems: a straight 0.2 m line travelled by the KR 210's tool tip (joint path from the IK
of the demo cell, so the joints move slowly), and synthetic ceiling/γ profiles for the thesis
section algorithm.
"""

from __future__ import annotations

import numpy as np
import pytest

from planner.optimize import PlanSolverError, optimize_sections
from planner.sections import AIR, CUT, RAPID, kind_runs, sample_kinds, split_by_length, step_lengths
from planner.thesis_sections import thesis_sections, wrap_angle
from planner.timing import shape_feed, time_path, transition

ACC = 1.0    # path acceleration [m/s²]
JERK = 10.0  # path jerk [m/s³]


@pytest.mark.parametrize(("v0", "v1"), [(0.01, 0.04), (0.04, 0.005), (0.002, 0.0021)])
def test_ruckig_transition_respects_acceleration_and_ends_at_target(v0, v1):
    dist, vel = transition(v0, v1, ACC, JERK)
    assert vel[0] == pytest.approx(v0) and vel[-1] == pytest.approx(v1)
    assert np.all(np.diff(dist) >= 0)
    # dv/dt = v dv/ds, measured between profile points
    dvdt = np.diff(vel) / np.maximum(np.diff(dist), 1e-15) * 0.5 * (vel[1:] + vel[:-1])
    assert np.max(np.abs(dvdt)) <= ACC * 1.05
    # a jerk-limited change takes longer than the acceleration-limited one
    assert dist[-1] >= abs(v1 ** 2 - v0 ** 2) / (2 * ACC) * 0.999


def test_shaped_bound_never_exceeds_any_section_feed():
    s = np.linspace(0.0, 0.3, 3001)
    feed = np.where(s < 0.1, 0.03, np.where(s < 0.2, 0.005, 0.02))
    bound = shape_feed(s, feed, ACC, JERK)
    assert np.all(bound <= feed + 1e-15)
    # the slow-down is finished where the slow section starts; the speed-up starts after it
    assert bound[np.searchsorted(s, 0.1)] == pytest.approx(0.005, rel=1e-6)
    assert bound[np.searchsorted(s, 0.2) - 1] == pytest.approx(0.005, rel=1e-6)
    before = s < 0.1
    assert np.min(bound[before]) < 0.03  # the transition reaches back into the fast section


def test_straight_line_time_is_cruise_plus_ramps(robot):
    """Rest to rest at feed f over L with path acceleration a (joints far from their limits):
    t = L/f + f/a (two ramps of f/a each cost f/(2a) extra)."""
    n = 401
    length = 0.2
    s = np.linspace(0.0, length, n)
    q0 = np.radians([0.0, -90.0, 90.0, 0.0, 45.0, 0.0])
    q = q0 + np.outer(s / length, np.radians([2.0, 1.0, -1.0, 0.0, 0.5, 0.0]))
    f = 0.02
    t = time_path(s, q, np.full(n, f), robot.data.velocity, robot.data.acceleration, ACC, JERK)
    # toppra's grid (0.5 mm) resolves the 0.2 mm ramps only coarsely: 0.5 % tolerance
    assert t.cycle_time == pytest.approx(length / f + f / ACC, rel=5e-3)
    assert np.all(t.speed <= f * (1 + 1e-9))
    assert np.all(t.joint_speed <= robot.data.velocity * (1 + 1e-6))
    assert not np.any(t.robot_limited[n // 4: 3 * n // 4])


def test_joint_speed_limits_the_robot_not_the_process(robot):
    """A fast feed on a path that swings A1 a lot: toppra caps ṡ by A1's speed limit."""
    n = 401
    s = np.linspace(0.0, 0.1, n)
    q = np.zeros((n, 6))
    q[:, 0] = np.radians(-150.0 + 300.0 * s / 0.1)  # 300° of A1 over 0.1 m of tip travel
    q[:, 1], q[:, 2], q[:, 4] = np.radians(-90.0), np.radians(90.0), np.radians(45.0)
    t = time_path(s, q, np.full(n, 0.5), robot.data.velocity, robot.data.acceleration, 10.0, 100.0)
    mid = slice(n // 3, 2 * n // 3)
    assert np.all(t.robot_limited[mid])
    a1 = t.joint_speed[mid, 0]
    assert np.max(a1) == pytest.approx(robot.data.velocity[0], rel=0.02)


def test_kinds_runs_and_cells():
    cutting = np.array([False, False, True, True, True, True, False, True, True])
    kinds = sample_kinds(9, np.array([2, 3, 4, 7, 8]), cutting)
    assert kinds.tolist() == [RAPID, RAPID, CUT, CUT, CUT, AIR, RAPID, CUT, CUT]
    assert kind_runs(kinds) == [(0, 2, RAPID), (2, 5, CUT), (5, 6, AIR), (6, 7, RAPID), (7, 9, CUT)]
    ds = step_lengths(np.arange(20) * 1e-3)
    pieces = split_by_length(ds, 0, 20, 4.5e-3)
    assert pieces[0][0] == 0 and pieces[-1][1] == 20
    assert all(ds[a:b].sum() >= 4.5e-3 - 1e-15 for a, b in pieces)
    assert split_by_length(ds, 3, 5, 1.0) == [(3, 5)]


def _synthetic(n=401, length=0.4):
    s = np.linspace(0.0, length, n)
    kinds = np.full(n, CUT)
    return s, kinds, kind_runs(kinds), step_lengths(s)


def test_thesis_halves_where_gamma_turns_faster_than_its_margin():
    """γ constant on the first half, turning fast on the second; a flat ceiling. The thesis
    algorithm keeps long sections where γ is constant and halves them where it turns."""
    s, kinds, runs, ds = _synthetic()
    ceiling = np.full(s.size, 0.01)
    binding = np.full(s.size, "chatter")

    def gamma_at(samples, feeds):
        x = s[samples]
        turn = np.where(x > 0.2, (x - 0.2) * 5.0, 0.0)  # 5 rad/m beyond s = 0.2 m
        return wrap_angle(0.1 + turn + 2.0 * feeds)      # γ(f_max) − γ(f_real) = 2 Δf

    secs = thesis_sections(runs, s, ceiling, binding, gamma_at, 0.1, 0.01, 1.1, 1e-4)
    first = [x for x in secs if s[x.stop - 1] <= 0.1]   # both neighbouring midpoints unturned
    second = [x for x in secs if s[x.start] > 0.2]
    assert first and min(ds[x.start:x.stop].sum() for x in first) >= 0.099
    assert max(ds[x.start:x.stop].sum() for x in second) < 0.05
    assert all(x.feed == pytest.approx(0.01 / 1.1) for x in secs)
    again = thesis_sections(runs, s, ceiling, binding, gamma_at, 0.1, 0.01, 1.1, 1e-4)
    assert [(x.start, x.stop, x.feed) for x in again] == [(x.start, x.stop, x.feed) for x in secs]


def test_thesis_every_sample_rule_catches_a_dip_between_midpoints():
    s, kinds, runs, ds = _synthetic()
    ceiling = np.full(s.size, 0.01)
    ceiling[(s > 0.02) & (s < 0.025)] = 0.004  # a dip far from any midpoint
    binding = np.full(s.size, "deflection")

    def gamma_at(samples, feeds):
        return np.zeros(np.size(samples))

    published = thesis_sections(runs, s, ceiling, binding, gamma_at, 0.1, 0.01, 1.1, 1e-4,
                                every_sample=False)
    safe = thesis_sections(runs, s, ceiling, binding, gamma_at, 0.1, 0.01, 1.1, 1e-4)
    feed_pub = np.concatenate([np.full(x.stop - x.start, x.feed) for x in published])
    feed_safe = np.concatenate([np.full(x.stop - x.start, x.feed) for x in safe])
    assert np.any(feed_pub > ceiling)        # as published: midpoints only, the dip is missed
    assert np.all(feed_safe <= ceiling)      # every sample held
    assert len(safe) > len(published)


def test_optimizer_follows_ceilings_and_merges_equal_cells():
    s, kinds, runs, ds = _synthetic()
    ceiling = np.where(s < 0.2, 0.02, 0.01)
    binding = np.where(s < 0.2, "force", "deflection")
    secs, res = optimize_sections(runs, ds, ceiling, binding, 1e-3, 0.04, 0.01, None, 0.02)
    assert res.success and res.iterations > 0
    assert len(secs) == 2
    assert secs[0].feed == pytest.approx(0.02, rel=1e-4) and secs[0].binding == "force"
    assert secs[1].feed == pytest.approx(0.01, rel=1e-4) and secs[1].binding == "deflection"
    bounded, _ = optimize_sections(runs, ds, ceiling, binding, 1e-3, 0.04, 0.01, 2e-3, 0.0)
    steps = np.abs(np.diff([x.feed for x in bounded]))
    assert np.all(steps <= 2e-3 * (1 + 1e-6))
    assert "feed_change" in {x.binding for x in bounded}


def test_unconverged_optimisation_is_an_error_naming_a_section():
    s, kinds, runs, ds = _synthetic()
    ceiling = 0.01 + 0.005 * np.sin(40 * s)
    binding = np.full(s.size, "force")
    with pytest.raises(PlanSolverError, match=r"did not converge \(IPOPT: Maximum_Iterations_Exceeded"
                       r".*cell \d+ \(samples \d+\.\.\d+\): (force|feed_min|feed_change) "
                       r"(violated by|closest to binding)") as err:
        optimize_sections(runs, ds, ceiling, binding, 1e-3, 0.04, 0.01, 1e-3, 0.02, max_iter=1)
    assert err.value.status == "Maximum_Iterations_Exceeded"
    assert err.value.constraint in {"force", "feed_min", "feed_change"}
    assert err.value.section is not None
