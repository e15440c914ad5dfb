"""The supervisor's ceiling: the plan's path speed at the tool's place along the path.

A section plan has one feed per section; a feed profile (``cctmill plan --method optimize``) a
speed per sample, which the KRL program runs move by move (:mod:`planner.export`). The
supervisor's 100 % override is that speed: :func:`planned_speed_at` is the planned feed of the
sample the move in progress goes to — the first sample at or past the arc length ``s`` — kept
inside the section the supervisor tracks. For a section plan it is the section's feed, as before.
"""

from __future__ import annotations

import math

import numpy as np

from planner.plan_file import Plan, PlanSection

__all__ = ["planned_speed_at"]


def planned_speed_at(plan: Plan, s: float, sec: PlanSection | None) -> float:
    """The planned path speed [m/s] at arc length ``s`` [m] inside section ``sec`` (0 before the
    first section, or where the plan has no feed: a rapid at the controller's speed)."""
    if sec is None or not math.isfinite(sec.feed):
        return 0.0
    smp = plan.samples
    a, b = sec.sample_start, sec.sample_stop
    if b <= a or smp.feed is None:
        return float(sec.feed)
    k = int(np.searchsorted(smp.s, s, side="left"))
    f = float(smp.feed[min(max(k, a), b - 1)])
    return f if math.isfinite(f) and f > 0 else float(sec.feed)
