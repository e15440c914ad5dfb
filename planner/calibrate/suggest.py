"""What to change when the calibrated boundary refuses a job: the depth per level and the spindle
speed at which every one of the job's sections keeps P(chatter) ≤ ``chatter_probability_max``.

A feed planner cannot remove chatter that does not depend on the feed (the time-domain model is
linear in the chip); the boundary ``P(chatter | margin, a_p, rpm)`` says where the depth and the
speed can. :func:`suggest_levels_and_speed` splits the job's total depth into the fewest equal
levels and, for that depth, finds the lowest spindle speed in the allowed range at which the
boundary's P(chatter) is at most ``p_max`` at every section (each section's pose, cut frame and
a_e as planned, the margin under the calibrated model). Fewest levels first (each level is a whole
pass of the contour), then the lowest speed (the gentlest on the tool and the spindle).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from planner.calibrate.context import CalibrationContext
from planner.calibrate.fit_boundary import Boundary, criterion_margin
from planner.calibrate.records import CutRecord

__all__ = ["CutSuggestion", "chatter_probabilities", "rank_settings", "suggest_levels_and_speed"]


@dataclass(frozen=True)
class CutSuggestion:
    """A depth split and spindle speed the boundary accepts.

    Attributes:
        levels: passes the total depth is split into; ap_mm: the depth of each [mm].
        rpm: the spindle speed [rev/min].
        p_worst: the largest P(chatter) over the job's sections there [-]; section_worst: where
            (the plan's section number, from 1).
    """

    levels: int
    ap_mm: float
    rpm: float
    p_worst: float
    section_worst: int | None

    def as_json(self) -> dict:
        return {"levels": self.levels, "ap_mm": self.ap_mm, "rpm": self.rpm,
                "p_worst": self.p_worst, "section_worst": self.section_worst}

    def line(self) -> str:
        return (f"{self.levels} levels of {self.ap_mm:.3g} mm at {self.rpm:g} rpm (worst "
                f"P(chatter) {self.p_worst:.2f}, section {self.section_worst})")


def chatter_probabilities(ctx: CalibrationContext, boundary: Boundary,
                          templates: Sequence[CutRecord], ap_mm: float, speeds: np.ndarray,
                          params=None) -> np.ndarray:
    """The boundary's P(chatter) (its point estimate, what the planner's margin floor holds to
    ``chatter_probability_max``) of every template cut at depth ``ap_mm`` [mm] at each spindle
    speed [rev/min], shape (len(speeds), len(templates))."""
    speeds = np.asarray(speeds, float)
    if ctx.criterion == "floquet":   # its margin depends on the speed
        m = np.array([[criterion_margin(ctx, replace(t, ap_mm=ap_mm, rpm=float(v)), params)
                       for t in templates] for v in speeds])
    else:
        m = np.tile([criterion_margin(ctx, replace(t, ap_mm=ap_mm), params) for t in templates],
                    (speeds.size, 1))
    out = []
    for k, v in enumerate(speeds):
        # the point estimate, as the planner's margin floor uses it (fit_boundary.required_margin)
        mu, _ = boundary.logit(np.column_stack([m[k], np.full(len(templates), ap_mm),
                                                np.full(len(templates), v)]))
        out.append(1.0 / (1.0 + np.exp(-mu)))
    return np.stack(out)


def rank_settings(ctx: CalibrationContext, boundary: Boundary, templates: Sequence[CutRecord],
                  depth_mm: float, rpm_range: tuple[float, float], params=None,
                  max_levels: int = 8, rpm_step: float = 500.0) -> list[CutSuggestion]:
    """Every (levels, spindle speed) candidate with its worst P(chatter) over the templates, in
    the order of preference: fewest levels, then lowest speed."""
    speeds = np.arange(rpm_range[0], rpm_range[1] + rpm_step / 2, rpm_step)
    sections = [t.source.get("section") for t in templates]
    out = []
    for levels in range(1, max_levels + 1):
        ap = depth_mm / levels
        p = chatter_probabilities(ctx, boundary, templates, ap, speeds, params)
        for k, v in enumerate(speeds):
            i = int(np.argmax(p[k]))
            out.append(CutSuggestion(levels, float(ap), float(v), float(p[k, i]), sections[i]))
    return out


def suggest_levels_and_speed(ctx: CalibrationContext, boundary: Boundary,
                             templates: Sequence[CutRecord], p_max: float, depth_mm: float,
                             rpm_range: tuple[float, float], params=None, max_levels: int = 8,
                             rpm_step: float = 500.0) -> CutSuggestion | None:
    """The fewest levels and, for them, the lowest spindle speed with P(chatter) ≤ ``p_max`` at
    every template (module docstring); None when no split up to ``max_levels`` and no speed in
    ``rpm_range`` [rev/min] will do.

    Args:
        templates: the job's sections (:func:`planner.calibrate.testcuts.section_templates`).
        depth_mm: the total axial depth to remove [mm].
        params: the model parameters of the margins (the calibrated ones).
    """
    if not 0.0 < p_max < 1.0:
        raise ValueError(f"p_max must lie in (0, 1), got {p_max!r}")
    for c in rank_settings(ctx, boundary, templates, depth_mm, rpm_range, params, max_levels,
                           rpm_step):
        if c.p_worst <= p_max:
            return c
    return None
