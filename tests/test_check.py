"""The independent checker (planner/check.py): it passes a real plan and catches planted violations.

Named problems: the demo job planned by the optimiser (``demo_optimized`` in conftest.py), and
that plan with one fault planted at a time:

* one cut section's feed raised 1 % above its lowest ceiling: exactly the samples whose ceiling is
  below the new feed break, all on deflection (what binds them);
* one process limit moved into a gap of the plan's own values (the planner's evaluation at the
  planned feeds): exactly the samples beyond it are reported, under that constraint's name;
* the bookkeeping rules (feed-change bound, section length, feed bounds, timed speed) broken at
  known places, all at once, so no rule reports another's fault.

The plan fixture is shared by the session: feeds and sections are copied before planting.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from planner.ceilings import CEILING_RTOL
from planner.check import REL_TOL, check_plan, check_result
from planner.sections import CUT, RAPID, kind_runs, section_of_samples, step_lengths

#: Fraction a section's feed is raised by in the planted-feed test [-] (10x the ceiling tolerance).
RAISE = 1.01
#: A moved limit sits in a gap of the plan's values at least this wide, relative [-]: far wider
#: than the difference between the planner's mapped model and the checker's per-point one
#: (round-off for force and deflection, the numerical power integral's ≪ 0.1 %).
GAP_MIN = 2e-3


def _sections(res) -> list[tuple[int, int, int, float]]:
    return [(s.start, s.stop, s.kind, s.feed) for s in res.sections]


def _ceiling_per_sample(res) -> np.ndarray:
    ceiling = np.full(len(res.prep.path), np.nan)
    ceiling[res.model.index] = res.ceilings.feed
    return ceiling


def test_unmodified_plan_has_no_violation(demo_optimized):
    res = demo_optimized
    report = check_result(res)
    assert report.samples_checked == int(np.sum(res.kinds == CUT)) > 700
    assert report.ok and report.violations == []
    assert all(report.worst_ratio[k] <= 1.0 + REL_TOL for k in ("force", "deflection", "power"))
    # the plan is at its limit somewhere: a checker that cannot fail would pass a zero feed too
    assert report.worst_ratio["deflection"] > 0.999


def test_section_raised_above_its_ceiling_is_reported_at_exactly_its_samples(demo_optimized):
    res = demo_optimized
    n = len(res.prep.path)
    ceiling = _ceiling_per_sample(res)

    def clear(s) -> bool:
        """Deflection-bound, several samples, still below feed_max once raised, and no sample
        whose true edge could lie either side of the raised feed (ceiling ≤ edge ≤ ceiling ·
        (1 + CEILING_RTOL))."""
        c = ceiling[s.start:s.stop]
        f = s.feed * RAISE
        return (s.kind == CUT and s.binding == "deflection" and s.stop - s.start >= 6
                and f < res.limits.feed_max and not np.any((c < f) & (f <= c * (1 + CEILING_RTOL)))
                and np.any(c > f))

    candidates = [i for i, s in enumerate(res.sections) if clear(s)]
    assert candidates, "no deflection-bound section to raise clearly above its ceiling"
    i = candidates[0]
    sec = res.sections[i]
    raised = sec.feed * RAISE
    feed = res.feed.copy()
    feed[sec.start:sec.stop] = raised
    sections = _sections(res)
    sections[i] = (sec.start, sec.stop, CUT, raised)
    report = check_plan(res.prep, feed, res.kinds, None, sections, res.limits)
    expected = {k for k in range(sec.start, sec.stop) if ceiling[k] < raised}
    assert 0 < len(expected) < sec.stop - sec.start  # the tight samples, not the whole section
    assert {v.sample for v in report.violations} == expected
    assert {v.constraint for v in report.violations} == {"deflection"}
    assert set(section_of_samples(res.sections, n)[sorted(expected)]) == {i}
    for v in report.violations:
        assert v.limit == res.limits.deflection_tol < v.value < res.limits.deflection_tol * RAISE
        assert v.where == res.prep.path.where(v.sample)


def _gap_limit(values: np.ndarray) -> float:
    """A value in the widest relative gap between the plan's 10th and 90th percentile values (the
    deflection of a deflection-bound plan crowds at its limit: no gap near the median)."""
    v = np.sort(values)
    lo, hi = int(0.1 * v.size), int(0.9 * v.size)
    rel = (v[lo + 1:hi] - v[lo:hi - 1]) / np.abs(v[lo:hi - 1])
    g = lo + int(np.argmax(rel))
    assert rel.max() > GAP_MIN, "no clear gap to put the limit in"
    return float(0.5 * (v[g] + v[g + 1]))


@pytest.mark.parametrize(("constraint", "field", "value_of"), [
    ("force", "force_max", lambda ev: ev.force),
    ("deflection", "deflection_tol", lambda ev: ev.deflection_norm),
    ("power", "power_max", lambda ev: ev.power),
    ("chatter", "margin_min", lambda ev: ev.margin),  # a margin is a floor: raised, not lowered
])
def test_moved_limit_is_reported_at_exactly_the_samples_beyond_it(demo_optimized, constraint,
                                                                  field, value_of):
    res = demo_optimized
    values = value_of(res.evaluation)
    limit = _gap_limit(values)
    limits = dataclasses.replace(res.limits, **{field: limit})
    report = check_plan(res.prep, res.feed, res.kinds, None, _sections(res), limits)
    beyond = values < limit if constraint == "chatter" else values > limit
    expected = res.model.index[beyond]
    assert 0.05 * values.size < expected.size < 0.95 * values.size
    assert sorted(v.sample for v in report.violations) == expected.tolist()
    assert {v.constraint for v in report.violations} == {constraint}
    found = dict(zip(res.model.index, values, strict=True))
    for v in report.violations:
        assert v.limit == limit
        assert v.value == pytest.approx(found[v.sample], rel=1e-4)
    if constraint != "chatter":
        assert report.worst_ratio[constraint] == pytest.approx(values.max() / limit, rel=1e-4)


def test_broken_bookkeeping_is_reported_rule_by_rule(demo_optimized):
    """Feed-change bound, section length, feed_max and the timed speed, broken at once."""
    res = demo_optimized
    path = res.prep.path
    ds = step_lengths(path.s)
    sections = _sections(res)
    cut = [s for s in sections if s[2] == CUT]
    steps = [(b[0], abs(b[3] - a[3])) for a, b in zip(cut, cut[1:], strict=False) if a[1] == b[0]]
    change_max = 0.5 * max(d for _, d in steps)
    runs = {(a, b) for a, b, _ in kind_runs(res.kinds)}
    length_min = 1.5 * res.limits.section_length_min
    feed_max = 0.99 * max(s[3] for s in cut)  # below the fastest cut section, and the air moves
    limits = dataclasses.replace(res.limits, feed_change_max=change_max,
                                 section_length_min=length_min, feed_max=feed_max)
    speed = res.feed.copy()
    too_fast = np.flatnonzero(res.kinds == CUT)[[10, 200, 500]]
    speed[too_fast] *= 1.001
    report = check_plan(res.prep, res.feed, res.kinds, speed, sections, limits)
    got = {}
    # the planned feed as "timed speed" steps between sections: the path-acceleration and joint
    # checks (test_feed_profile.py) rightly flag it; this test is about the bookkeeping rules
    dynamic = {"path_acceleration", "path_jerk", "joint_speed", "joint_acceleration"}
    for v in report.violations:
        if v.constraint not in dynamic:
            got.setdefault(v.constraint, set()).add(v.sample)
    expected = {
        "feed_change": {a for a, d in steps if d > change_max * (1 + 1e-6)},
        "section_length": {a for a, b, _, _ in cut
                           if ds[a:b].sum() < length_min and (a, b) not in runs},
        "feed_bounds": {a for a, _, kind, f in sections if kind != RAPID and f > feed_max},
        "timed_speed": set(too_fast.tolist()),
    }
    assert all(expected.values())
    assert got == expected  # and nothing from the process limits: the feeds did not change
    bounds = [v for v in report.violations if v.constraint == "feed_bounds"]
    assert all(v.limit == feed_max and v.value > feed_max for v in bounds)


def test_feed_below_feed_min_names_feed_min_as_the_limit(demo_optimized):
    res = demo_optimized
    cut = [s for s in _sections(res) if s[2] == CUT]
    feed_min = 1.01 * min(s[3] for s in cut)
    limits = dataclasses.replace(res.limits, feed_min=feed_min)
    report = check_plan(res.prep, res.feed, res.kinds, None, _sections(res), limits)
    bounds = [v for v in report.violations if v.constraint == "feed_bounds"]
    assert bounds
    assert all(v.value < feed_min for v in bounds)
    assert all(v.limit == feed_min for v in bounds)
