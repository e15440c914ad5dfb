"""The cheap screen: reach and feed ceilings at a subset of the samples, to prune a grid.

A full plan at a placement costs IK at every sample, the ceilings of every cut sample, the
optimisation and the timing. The screen solves IK at every ``k``-th sample only (about
:data:`SCREEN_SAMPLES` of them, the first sample always, seeded along the subset as the planner
seeds along the path), evaluates the ceilings of the engaged ones with the planner's own point model
and caps, and estimates the cut time Σ ds / ceiling over the whole path (each sample at the
ceiling of the subset sample before it). Engagement does not depend on the placement (it is in
the workpiece frame): it is computed once per job and process, and only turned into the new base.

The screen is only a filter: :func:`select` keeps every placement the screen found feasible whose
estimate is within ``ratio`` of the best estimate, and the study ranks the kept ones by their full
plans. ``benchmarks/placement.py`` measures how much it prunes and whether it keeps the best.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from models.errors import CctmillError
from planner.place.grid import Placement
from planner.place.spec import JobSpec, job_at, job_of, local_path

__all__ = ["SCREEN_RATIO", "SCREEN_SAMPLES", "ScreenResult", "screen_placement", "select"]

#: Samples the screen solves IK at (about; every ``len(path) // SCREEN_SAMPLES``-th).
SCREEN_SAMPLES = 64
#: Default pruning: keep placements whose estimated cut time is within this factor of the best
#: estimate [-]. The estimate ignores air moves, rapids and the robot's joint limits on timing, so
#: it ranks placements only roughly: the factor is wide.
SCREEN_RATIO = 1.3

#: digest → the job prepared at its own placement (for its placement-independent engagement).
_PREPARED: dict[str, Any] = {}


@dataclass(frozen=True)
class ScreenResult:
    """The screen at one placement.

    Attributes:
        placement: the placement.
        feasible: every subset sample reached and no ceiling below ``feed_min``.
        cut_time_estimate: Σ ds / ceiling over the cut samples [s] (None when infeasible).
        samples: subset samples solved.
        reason: why it is infeasible, or None.
        wall_time: [s] (not compared).
    """

    placement: Placement
    feasible: bool
    cut_time_estimate: float | None = None
    samples: int = 0
    reason: str | None = None
    wall_time: float = field(default=0.0, compare=False)

    def as_json(self) -> dict[str, Any]:
        return {**self.placement.as_json(), "feasible": self.feasible,
                "cut_time_estimate_s": self.cut_time_estimate, "samples": self.samples,
                "reason": self.reason, "wall_time_s": self.wall_time}


def _prepared(spec: JobSpec):
    from planner.prepare import prepare

    if spec.digest not in _PREPARED:
        _PREPARED[spec.digest] = prepare(job_of(spec))
    return _PREPARED[spec.digest]


def screen_placement(spec: JobSpec, placement: Placement,
                     samples: int = SCREEN_SAMPLES) -> ScreenResult:
    """Screen ``spec``'s job at ``placement`` (see the module docstring). Never raises for the
    placement's sake."""
    t0 = time.perf_counter()
    try:
        r = _screen(spec, placement, samples)
    except CctmillError as e:
        r = ScreenResult(placement, False, reason=local_path(spec, str(e)))
    return replace(r, wall_time=time.perf_counter() - t0)


def _screen(spec: JobSpec, placement: Placement, samples: int) -> ScreenResult:
    from planner.cam_feed import apply_cam_feed, cam_feed_caps
    from planner.ceilings import PathModel, engaged_samples
    from planner.ik import IKOptions, solve_path
    from planner.prepare import Prepared
    from planner.sections import step_lengths
    from planner.tool_limits import TOOL_BINDING, tool_feed_cap

    own = _prepared(spec)
    job = job_at(spec, placement)
    si = job.to_si()
    base = si.base
    rot, t = base[:3, :3], base[:3, 3]
    path, eng = own.path, own.engagement
    n = len(path)
    stride = max(1, n // max(1, samples))
    idx = np.arange(0, n, stride)
    sub = replace(path, s=path.s[idx], position=path.position_wp[idx] @ rot.T + t,
                  position_wp=path.position_wp[idx], tool_axis=path.tool_axis_wp[idx] @ rot.T,
                  tool_axis_wp=path.tool_axis_wp[idx], feed=path.feed[idx],
                  cutting=path.cutting[idx], move=path.move[idx], line=path.line[idx],
                  file=path.file[idx], base=base)
    fixed = job.kinematics.tool_rotation == "fixed"
    kin = solve_path(own.robot, sub, si.tool, IKOptions(
        seed=si.seed_joints, choose_for_stiffness=job.kinematics.choose_for_stiffness and not fixed,
        tool_rotation=si.tool_rotation if fixed else None))
    if not kin.all_reachable:
        return ScreenResult(placement, False, samples=idx.size,
                            reason=local_path(spec, f"screen: {kin.problems[0]}"))
    # engagement directions: own base → workpiece → this base
    turn = own.path.base[:3, :3] @ rot.T
    e = replace(eng, a_e=eng.a_e[idx], a_p=eng.a_p[idx], mode=eng.mode[idx],
                radial_dir=eng.radial_dir[idx] @ turn,
                engaged_angle=None if eng.engaged_angle is None else eng.engaged_angle[idx],
                feed_dir=None if eng.feed_dir is None else eng.feed_dir[idx] @ turn,
                plunge=None if eng.plunge is None else eng.plunge[idx], warnings=())
    prep = Prepared(job=job, robot=own.robot, tool=own.tool, toolpaths=own.toolpaths, path=sub,
                    kinematics=kin, engagement=e)
    model = PathModel(prep, threads=1)  # one core a worker
    full = np.flatnonzero(engaged_samples(path.s, path.cutting & (eng.mode >= 0)))
    if len(model) == 0:
        return ScreenResult(placement, True, cut_time_estimate=0.0 if full.size == 0 else math.nan,
                            samples=idx.size)
    lim = model.limits
    spindle = si.spindle_speed
    tool_cap = np.full(len(model), tool_feed_cap(own.tool, spindle))
    ceil = apply_cam_feed(apply_cam_feed(model.ceilings(), tool_cap, TOOL_BINDING),
                          cam_feed_caps(sub, model.index, lim))
    bad = np.flatnonzero(ceil.floor_violation != "")
    if bad.size:
        k = int(idx[model.index[bad[0]]])
        return ScreenResult(placement, False, samples=idx.size,
                            reason=f"screen: {ceil.floor_violation[bad[0]]} limit cannot be met at "
                                   f"feed_min at {local_path(spec, path.where(k))}")
    # every engaged sample of the full path at the ceiling of the subset sample before it
    at = idx[model.index]
    j = np.clip(np.searchsorted(at, full, side="right") - 1, 0, at.size - 1)
    ds = step_lengths(path.s)
    estimate = float(np.sum(ds[full] / ceil.feed[j]))
    return ScreenResult(placement, True, cut_time_estimate=estimate, samples=idx.size)


def select(results: list[ScreenResult], ratio: float = SCREEN_RATIO) -> list[Placement]:
    """The placements worth a full plan: screened feasible, estimate ≤ ``ratio`` × the best."""
    ok = [r for r in results if r.feasible and r.cut_time_estimate is not None
          and math.isfinite(r.cut_time_estimate)]
    if not ok:
        return []
    best = min(r.cut_time_estimate for r in ok)  # type: ignore[type-var]
    return [r.placement for r in ok if r.cut_time_estimate <= ratio * best]  # type: ignore[operator]
