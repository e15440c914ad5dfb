"""The feed-ceiling search of planner/ceilings.py, against closed-form edges and the point model.

:meth:`PathModel.ceilings` searches, per engaged sample, the highest feed meeting every limit: a
log-spaced grid, then Illinois regula falsi in log-feed down to a bracket of CEILING_RTOL. Two kinds
of oracle:

* closed form: :class:`ClosedFormPath` is the search with its constraints replaced by functions
  whose edge is known exactly (no robot, no job);
* the demo job: the per-point numeric model (:meth:`models.point.PointModel.analyze`, what the
  independent checker calls, not the mapped Function the search uses) at the ceiling and 0.2 %
  above it.

Named problems:
    LIMITS: the demo job's feed range, 0.5 ... 40 mm/s (other limits unused by ClosedFormPath).
    Demo variants: force_max 100 N (force binds at about 200 samples, deflection at the others) and
    20 N (force broken even at feed_min somewhere).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from models.analysis import Cut
from models.point import PointModel
from planner.ceilings import (
    CEILING_RTOL,
    CONSTRAINTS,
    FEED_GRID,
    MAX_REFINE_STEPS,
    Evaluation,
    PathModel,
)
from planner.limits import Limits

LIMITS = Limits(force_max=300.0, deflection_tol=0.2e-3, power_max=10e3, feed_min=0.5e-3,
                feed_max=40e-3, feed_change_max=None, margin_min=0.0, section_length_min=10e-3,
                path_acc_max=1.0, path_jerk_max=10.0, rapid_speed=0.25)
GRID = np.geomspace(LIMITS.feed_min, LIMITS.feed_max, FEED_GRID)
#: Just above a ceiling [-]: twice the search's tolerance, so the true edge is below it.
ABOVE = 1.0 + 2.0 * CEILING_RTOL
#: exp(log f) / f − 1 can be this large [-].
ULP = 4.0 * np.finfo(float).eps
#: Round-off allowed between the mapped Function and the per-point model at a limit [-] (the
#: checker's REL_TOL): a ceiling can sit exactly on an edge.
ROUND_OFF = 1e-9
#: Demo samples of each binding kind re-evaluated by the point model (seeded draw).
DEMO_DRAW = 120


class ClosedFormPath(PathModel):
    """The search of :class:`PathModel` on constraints with known edges.

    Constraint j of sample k holds iff f ≤ ``edge[k, j]`` [m/s]. Its slack is (f / edge)^p − 1, the
    value / limit − 1 of a quantity growing as f^p (force, deflection and power are of that kind),
    or, with ``step``, −1 / +1: a verdict with no useful magnitude. Only what the search reads is
    set up (limits, the evaluation counter, :meth:`evaluate`): there is no prepared job, so the base
    constructor is not called.
    """

    def __init__(self, edge: np.ndarray, power: float | np.ndarray = 1.0, step: bool = False,
                 limits: Limits = LIMITS) -> None:
        self.limits = limits
        self.edge = np.atleast_2d(np.asarray(edge, float))
        self.power = np.broadcast_to(np.asarray(power, float), self.edge.shape)
        self.step = step
        self.evaluations = 0
        self.progress = False
        self._bar = None

    def __len__(self) -> int:
        return self.edge.shape[0]

    def slack(self, feeds: np.ndarray, subset: np.ndarray | None = None) -> np.ndarray:
        sel = np.arange(len(self)) if subset is None else np.asarray(subset, int)
        ratio = np.asarray(feeds, float).reshape(-1, 1) / self.edge[sel]
        return np.where(ratio <= 1.0, -1.0, 1.0) if self.step else ratio ** self.power[sel] - 1.0

    def evaluate(self, feeds: np.ndarray, subset: np.ndarray | None = None) -> Evaluation:
        feeds = np.asarray(feeds, float).reshape(-1)
        slack = self.slack(feeds, subset)
        self.evaluations += 1
        unused = {f.name: np.zeros(feeds.size) for f in dataclasses.fields(Evaluation)}
        return Evaluation(**{**unused, "feed": feeds, "ok": slack <= 0.0, "slack": slack})


def _random_edges(seed: int, m: int = 400) -> np.ndarray:
    """Edges [m/s], shape (m, 4): per sample a lowest one log-uniform over a range 3x wider than
    [feed_min, feed_max] on both sides, in a random column, the others up to 5x above it."""
    rng = np.random.default_rng(seed)
    lowest = np.exp(rng.uniform(np.log(LIMITS.feed_min / 3.0), np.log(LIMITS.feed_max * 3.0), m))
    edge = lowest[:, None] * np.exp(rng.uniform(0.0, np.log(5.0), (m, len(CONSTRAINTS))))
    edge[np.arange(m), rng.integers(0, len(CONSTRAINTS), m)] = lowest
    return edge


# ---------------------------------------------------------------------------------- closed form


@pytest.mark.parametrize(("power", "step"), [(0.5, False), (1.0, False), (2.0, False),
                                             (5.0, False), (1.0, True)])
def test_ceiling_is_the_closed_form_edge_to_its_tolerance(power, step):
    edge = _random_edges(int(power * 10) + step)
    path = ClosedFormPath(edge, power, step)
    ceil = path.ceilings()
    lowest = edge.min(axis=1)
    inside = (lowest >= LIMITS.feed_min) & (lowest < LIMITS.feed_max)
    above, below = lowest >= LIMITS.feed_max, lowest < LIMITS.feed_min
    assert inside.sum() > 100 and above.sum() > 10 and below.sum() > 10
    # never above the edge: every limit holds at the ceiling (where one can hold at all) ...
    assert np.all(path.slack(ceil.feed[~below], np.flatnonzero(~below)) <= 0.0)
    # ... and at most CEILING_RTOL below it
    assert np.all(ceil.feed[inside] * (1.0 + CEILING_RTOL) >= lowest[inside])
    names = np.array(CONSTRAINTS)[edge.argmin(axis=1)]
    np.testing.assert_array_equal(ceil.binding[inside], names[inside])
    np.testing.assert_array_equal(ceil.floor_violation[~below], "")
    # met at feed_max: the ceiling is feed_max and nothing binds
    np.testing.assert_array_equal(ceil.feed[above], LIMITS.feed_max)
    np.testing.assert_array_equal(ceil.binding[above], "feed_max")
    # not met at feed_min: the ceiling is feed_min, naming the broken limit
    np.testing.assert_array_equal(ceil.feed[below], LIMITS.feed_min)
    np.testing.assert_array_equal(ceil.binding[below], ceil.floor_violation[below])
    for k in np.flatnonzero(below):
        broken = {CONSTRAINTS[j] for j in np.flatnonzero(edge[k] < LIMITS.feed_min)}
        assert ceil.floor_violation[k] in broken
    # one mapped evaluation per grid feed, then one per regula-falsi step over the open brackets
    assert ceil.evaluations == path.evaluations <= FEED_GRID + 15


@pytest.mark.parametrize(("edge", "feed", "binding"), [
    (LIMITS.feed_max, LIMITS.feed_max, "feed_max"),  # met exactly at feed_max
    (10.0 * LIMITS.feed_max, LIMITS.feed_max, "feed_max"),
    (LIMITS.feed_max * (1 - 1e-4), LIMITS.feed_max * (1 - 1e-4), "force"),  # in the last interval
    (GRID[2], GRID[2], "force"),  # on a grid feed: the slack is 0 there, which holds
    (GRID[2] * (1 + 1e-6), GRID[2] * (1 + 1e-6), "force"),
    (LIMITS.feed_min * (1 + 1e-4), LIMITS.feed_min * (1 + 1e-4), "force"),
    (LIMITS.feed_min, LIMITS.feed_min, "force"),  # met exactly at feed_min
])
def test_edges_at_the_ends_and_on_the_grid(edge, feed, binding):
    path = ClosedFormPath([[1.0, edge, 1.0, 1.0]], power=1.0)  # the force column
    ceil = path.ceilings()
    # an edge on a grid feed f comes back as exp(log f), which may be an ulp above it
    assert feed / (1.0 + CEILING_RTOL) <= ceil.feed[0] <= feed * (1.0 + ULP)
    assert ceil.binding[0] == binding
    assert ceil.floor_violation[0] == ""


@pytest.mark.parametrize("j", range(len(CONSTRAINTS)))
def test_limit_broken_even_at_feed_min_names_it(j):
    edge = np.ones((2, len(CONSTRAINTS)))
    edge[0, j] = LIMITS.feed_min * (1 - 1e-6)
    edge[1, j] = LIMITS.feed_min * 1e-3
    ceil = ClosedFormPath(edge).ceilings()
    np.testing.assert_array_equal(ceil.feed, LIMITS.feed_min)
    np.testing.assert_array_equal(ceil.floor_violation, CONSTRAINTS[j])
    np.testing.assert_array_equal(ceil.binding, CONSTRAINTS[j])


def test_binding_is_the_lowest_edge_even_when_two_are_close():
    """Two edges 0.5 % apart: the ceiling is the lower, and names its constraint."""
    edge = np.array([[3e-3, 3.015e-3, 1.0, 1.0], [1.0, 1.0, 20.1e-3, 20e-3]])
    ceil = ClosedFormPath(edge, power=np.array([1.0, 3.0, 1.0, 0.5])).ceilings()
    np.testing.assert_array_equal(ceil.binding, ["chatter", "power"])
    assert np.all(ceil.feed <= [3e-3, 20e-3])
    assert np.all(ceil.feed * (1 + CEILING_RTOL) >= [3e-3, 20e-3])


def test_steep_slack_still_gives_a_feasible_ceiling():
    """(f / edge)^30 − 1: regula falsi crawls (its steps land next to the feasible end) and the
    step cap ends the search; the ceiling stays on the feasible side."""
    edge = _random_edges(3, m=200)
    path = ClosedFormPath(edge, power=30.0)
    ceil = path.ceilings()
    met = edge.min(axis=1) >= LIMITS.feed_min
    assert np.all(path.slack(ceil.feed[met], np.flatnonzero(met)) <= 0.0)
    assert path.evaluations <= FEED_GRID + MAX_REFINE_STEPS


def test_steep_slack_ceiling_is_within_its_tolerance():
    """Regula falsi alone crawls on (f / edge)^30 − 1; the halving steps after HALVING_AFTER close
    the bracket to CEILING_RTOL within MAX_REFINE_STEPS."""
    edge = _random_edges(3, m=200)
    ceil = ClosedFormPath(edge, power=30.0).ceilings()
    lowest = edge.min(axis=1)
    inside = (lowest >= LIMITS.feed_min) & (lowest < LIMITS.feed_max)
    assert np.all(ceil.feed[inside] * (1.0 + CEILING_RTOL) >= lowest[inside])


# ---------------------------------------------------------------------------------- demo job


def _point_model_ok(prep, path: PathModel, feeds: np.ndarray,
                    subset: np.ndarray | None = None) -> np.ndarray:
    """Per engaged sample (or ``subset`` of them), whether (chatter, force, deflection) hold at
    ``feeds`` [m/s] by the per-point model (the cut rebuilt from the engagement, as planner.check
    does), shape (k, 3) bool."""
    job, lim = prep.job, path.limits
    model = PointModel(prep.robot, path.params, job.model.process_model, job.model.mass_model,
                       job.model.chatter_criterion, helix_angle=prep.tool.helix_angle)
    e = prep.engagement
    feed_dir = e.feed_dir if e.feed_dir is not None else prep.path.feed_dir
    omega = job.spindle.rpm * 2.0 * np.pi / 60.0
    subset = np.arange(len(path)) if subset is None else np.asarray(subset, int)
    out = np.zeros((subset.size, 3), bool)
    for i, k in enumerate(path.index[subset]):
        cut = Cut(feed_dir=feed_dir[k], radial_dir=e.radial_dir[k], a_e=float(e.a_e[k]),
                  a_p=float(e.a_p[k]), mode={0: "up", 1: "down", 2: "slot"}[int(e.mode[k])],
                  spindle_speed=omega, flutes=prep.tool.flutes, radius=prep.tool.radius)
        a = model.analyze(prep.kinematics.q[k], cut, float(feeds[i]))
        out[i] = (a.stable and a.margin >= lim.margin_min,
                  a.force <= lim.force_max * (1 + ROUND_OFF),
                  np.linalg.norm(a.deflection) <= lim.deflection_tol * (1 + ROUND_OFF))
    return out


def test_demo_ceiling_is_the_edge_by_the_point_model(demo_prepared):
    """force_max 100 N: force binds at some samples, deflection at the others; at each ceiling the
    point model meets every limit, 0.2 % above it the named one breaks (a seeded draw of the
    samples of each kind keeps it quick)."""
    base = PathModel(demo_prepared)
    path = PathModel(demo_prepared, limits=dataclasses.replace(base.limits, force_max=100.0))
    ceil = path.ceilings()
    assert {"force", "deflection"} <= set(ceil.binding) <= {"force", "deflection", "feed_max"}
    assert np.all(ceil.floor_violation == "")
    np.testing.assert_array_equal(ceil.feed[ceil.binding == "feed_max"], path.limits.feed_max)
    rng = np.random.default_rng(11)
    column = {"force": 1, "deflection": 2}
    for name, j in column.items():
        where = np.flatnonzero(ceil.binding == name)
        pick = np.sort(rng.choice(where, min(where.size, DEMO_DRAW), replace=False))
        at = _point_model_ok(demo_prepared, path, ceil.feed[pick], pick)
        assert np.all(at), pick[~at.all(axis=1)][:10]
        above = _point_model_ok(demo_prepared, path, ceil.feed[pick] * ABOVE, pick)
        assert not np.any(above[:, j]), f"{name} still holds 0.2 % above its ceiling"
    free = np.flatnonzero(ceil.binding == "feed_max")
    assert np.all(_point_model_ok(demo_prepared, path, ceil.feed[free], free))


def test_demo_limit_broken_at_feed_min_is_named(demo_prepared):
    """force_max 20 N: the lightest cuts still meet it, the heaviest break it even at feed_min."""
    base = PathModel(demo_prepared)
    path = PathModel(demo_prepared, limits=dataclasses.replace(base.limits, force_max=20.0))
    ceil = path.ceilings()
    floor = ceil.floor_violation != ""
    assert 0 < floor.sum() < len(path)
    np.testing.assert_array_equal(ceil.floor_violation[floor], "force")
    np.testing.assert_array_equal(ceil.feed[floor], path.limits.feed_min)
    at_min = _point_model_ok(demo_prepared, path, np.full(len(path), path.limits.feed_min))
    np.testing.assert_array_equal(at_min[:, 1], ~floor)  # force broken at feed_min exactly there


def test_deflection_held_is_norm_uncompensated_and_u_norm_plus_change_compensated():
    norm, change = np.array([1e-4, 2e-4]), np.array([1e-5, 0.0])
    np.testing.assert_array_equal(LIMITS.deflection_held(norm, change), norm)
    assert LIMITS.deflection_model_uncertainty == 0.3 and not LIMITS.compensate_deflection
    comp = dataclasses.replace(LIMITS, compensate_deflection=True, deflection_model_uncertainty=0.5)
    np.testing.assert_allclose(comp.deflection_held(norm, change), 0.5 * norm + change)


def test_limits_from_job_read_the_compensation_keys(demo_prepared):
    job = demo_prepared.job
    assert not Limits.from_job(job).compensate_deflection
    doc = job.model_dump()
    doc["limits"]["deflection_model_uncertainty"] = 0.2
    doc["export"] = {"compensate_deflection": True}
    lim = Limits.from_job(type(job).model_validate(doc))
    assert lim.compensate_deflection and lim.deflection_model_uncertainty == 0.2


def test_compensated_deflection_limit_holds_u_delta_plus_the_change_along_the_lin(demo_prepared):
    """With compensation the tolerance applies to u·‖δ‖ + ‖δ_i − δ_(i−1)‖ (both at the same
    feed; zero change where the sample before does not cut); the ceilings hold it."""
    base = PathModel(demo_prepared)
    comp = PathModel(demo_prepared, limits=dataclasses.replace(base.limits,
                                                               compensate_deflection=True))
    f = np.full(len(comp), 5e-3)
    ev, plain = comp.evaluate(f), base.evaluate(f)
    np.testing.assert_allclose(ev.deflection_norm, plain.deflection_norm)
    follows = np.flatnonzero(np.diff(comp.index) == 1) + 1
    change = np.zeros(len(comp))
    change[follows] = np.linalg.norm(plain.deflection[follows] - plain.deflection[follows - 1],
                                     axis=1)
    np.testing.assert_allclose(ev.deflection_change, change, atol=1e-15)
    np.testing.assert_allclose(ev.deflection_held, 0.3 * ev.deflection_norm + change)
    assert plain.deflection_held.size == len(base) and plain.deflection_change.size == 0
    ceil = comp.ceilings()
    at = comp.evaluate(ceil.feed)
    assert np.all(at.deflection_held <= comp.limits.deflection_tol * (1 + 1e-9))
    # compensation lets most samples run faster than the plain ‖δ‖ rule does
    assert np.median(ceil.feed / base.ceilings().feed) > 1.2
