"""Why a plan is infeasible before any optimisation: a sample whose process limit (force,
deflection, power, chatter) no feed down to ``feed_min_mm_s`` meets — the section, the limit, the
value found and what to change, in the words :class:`planner.plan.PlanInfeasibleError` carries."""

from __future__ import annotations

import math

import numpy as np

from planner.ceilings import Ceilings, PathModel
from planner.limits import Limits
from planner.prepare import Prepared
from planner.sections import CUT, split_by_length

__all__ = ["floor_problem"]


def _margin_short(prep: Prepared, model: PathModel, k: int, margin: float, limits: Limits) -> str:
    """Why an eigen margin is short at engaged sample ``k``: the job's floor, or what the
    calibrated boundary needs for ``[model] chatter_probability_max``."""
    floor = None if model.margin_floor is None else float(model.margin_floor[k])
    if floor is None or floor <= limits.margin_min:
        return f"margin {margin:.3g} N/m below the required {limits.margin_min:.3g} N/m "
    p_max = prep.job.model.chatter_probability_max
    if not math.isfinite(floor):
        return (f"P(chatter) > {p_max:g} by the calibrated boundary at this a_p and spindle speed "
                "whatever the margin ")
    return (f"margin {margin:.3g} N/m below the {floor:.3g} N/m that P(chatter) <= {p_max:g} "
            "needs by the calibrated boundary ")


def _way_out(prep: Prepared, margin: float, k: int, model: PathModel) -> str:
    """What the calibrated boundary would accept at this sample: a shallower cut or a faster
    spindle ("" without a probability requirement and a boundary)."""
    from planner.calibrate.fit_boundary import allowed_depth_and_speed, boundary_from_job

    p_max = prep.job.model.chatter_probability_max
    boundary = boundary_from_job(prep.job) if p_max is not None else None
    if boundary is None or model.criterion != boundary.criterion:
        return ""
    sample = int(model.index[k])
    ap_mm = float(prep.engagement.a_p[sample]) * 1e3
    rpm = float(prep.job.spindle.rpm)
    depth, speed = allowed_depth_and_speed(boundary, p_max, margin, ap_mm, rpm)
    top = prep.tool.spindle_speed_max
    top_rpm = None if top is None else top * 60.0 / (2.0 * math.pi)
    hints = []
    if depth is not None and 0.0 < depth < ap_mm:
        hints.append(f"a_p <= {depth:.2f} mm at {rpm:g} rpm")
    if speed is not None and speed > rpm:
        hints.append(f"{speed:.0f} rpm at this a_p" + (
            f" (above the tool's {top_rpm:g} rpm)" if top_rpm and speed > top_rpm else ""))
    return f"; the calibrated boundary accepts {' or '.join(hints)} here" if hints else ""


def floor_problem(prep: Prepared, model: PathModel, ceil: Ceilings, runs, ds, limits: Limits
                  ) -> tuple[str, int, str, int] | None:
    """The first sample whose limit no feed down to ``feed_min`` meets, as (message, section
    index, constraint, sample); None when there is none."""
    bad = np.flatnonzero(ceil.floor_violation != "")
    if bad.size == 0:
        return None
    k = int(bad[0])
    sample = int(model.index[k])
    cells = [c for a, b, kind in runs if kind == CUT for c in split_by_length(ds, a, b,
                                                                          limits.section_length_min)]
    cell = next(i for i, (a, b) in enumerate(cells) if a <= sample < b)
    what = str(ceil.floor_violation[k])
    ev = model.evaluate(np.array([limits.feed_min]), np.array([k]))
    detail = {
        "force": f"{ev.force[0]:.1f} N > force_max_n {limits.force_max:.1f} N (the edge forces "
                 "alone exceed it: raise the limit or cut shallower)",
        "deflection": f"{ev.deflection_norm[0] * 1e3:.3f} mm > deflection_tol_mm "
                      f"{limits.deflection_tol * 1e3:.3f} mm (raise the tolerance, cut shallower "
                      "or move the part where the arm is stiffer)",
        "power": f"{ev.power[0] * 1e-3:.2f} kW > power_max_kw {limits.power_max * 1e-3:.2f} kW",
        "chatter": (f"Floquet spectral radius {model.floquet_radius()[k]:.4f} >= 1 "
                    if model.criterion == "floquet" else
                    f"gamma {np.degrees(ev.gamma[0]):.2f} deg outside the calibrated window "
                    if model.criterion == "gamma_window" else
                    _margin_short(prep, model, k, float(ev.margin[0]), limits))
                   + "at every feed (change the pose, the tool rotation, the spindle speed or "
                     "the depths of cut)"
                   + (_way_out(prep, float(ev.margin[0]), k, model)
                      if model.criterion == "eigen" else ""),
    }[what]
    e = prep.engagement
    p = prep.path
    n_bad = bad.size
    return (
        f"section {cell + 1} (s {p.s[cells[cell][0]]:.3f}-{p.s[cells[cell][1] - 1]:.3f} m, "
        f"{p.where(sample)}): {what} limit cannot be met even at feed_min_mm_s "
        f"{limits.feed_min * 1e3:g}: {detail}; a_e {e.a_e[sample] * 1e3:.2f} mm, a_p "
        f"{e.a_p[sample] * 1e3:.2f} mm ({n_bad} sample{'s' if n_bad > 1 else ''} affected)",
        cell, what, sample)
