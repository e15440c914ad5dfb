"""Independent check of a plan: every sample re-evaluated, nothing taken from the optimiser.

The planner evaluates the model through one mapped CasADi Function and reduces the constraints to
feed ceilings. This checker does neither: for every ``cut`` sample it calls the per-point numeric
model (:meth:`models.point.PointModel.analyze`: one pose, its own joint-limit and singularity
checks) at the *planned* feed of that sample, and computes the spindle power by integrating the
instantaneous tangential edge force over the engaged arc numerically (not the closed form the
planner uses); with the compensation-aware tolerance (``compensate_deflection``) it holds
u·|δ| + |δ_k − δ_(k−1)| (:meth:`planner.limits.Limits.deflection_held`), recomputing δ of the
previous sample at this sample's feed. Where the job's calibration states its uncertainty, force
and deflection are held with the bound of :mod:`planner.limit_confidence`, as the planner holds
them. A posture chosen along the path is measured from the joints
(continuity, wrist, limits, rate; :func:`planner.posture.check_posture`). It then checks the
plan's own bookkeeping: feeds inside the bounds, no cut faster
than its programmed feed × ``cam_feed_scale_max`` and no air move faster than programmed or than
the rapid speed, neighbouring cut sections within the feed-change bound, sections no shorter than
the minimum (unless their whole run is) and never empty, and the timed path speed never above the
planned feed. The timed speed itself is checked against the path acceleration and the joints'
speed and acceleration limits, and a feed profile's also against the path jerk
(:mod:`planner.check_profile`). In a feed profile the feed varies inside a section: its samples'
feeds, not the section's, are held to the programmed feed caps, and the feed-change bound between
sections (a section plan's steps) does not apply — the profile's changes are bounded by the path
acceleration and jerk.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from models.analysis import Cut
from models.cutting import edge_forces, immersion_angles
from models.point import PointModel
from planner.ceilings import model_parameters
from planner.check_profile import dynamics_violations
from planner.limit_confidence import limit_confidence
from planner.limits import Limits
from planner.prepare import Prepared
from planner.sections import CUT, RAPID, kind_runs, step_lengths

__all__ = ["ARC_POINTS", "CheckReport", "REL_TOL", "SPEED_TOL", "Violation", "check_plan", "check_result"]

#: Relative tolerance of a limit check [-]: the planner's ceilings are the feasible end of a
#: regula-falsi bracket of 0.1 % (planner.ceilings.CEILING_RTOL), so a real violation is far larger
#: than floating-point noise.
REL_TOL = 1e-9
#: Points of the numerical power integral over the engaged arc (trapezoids; error ≪ 0.1 %).
ARC_POINTS = 721
#: Timed speed may exceed the planned feed by this fraction (toppra's interpolation) [-].
SPEED_TOL = 1e-6


@dataclass(frozen=True)
class Violation:
    """One broken limit.

    Attributes:
        sample: path sample (or the first sample of the section).
        constraint: what is broken.
        value: the value found (SI).
        limit: the limit (SI).
        where: ``file:line`` of the sample.
    """

    sample: int
    constraint: str
    value: float
    limit: float
    where: str


@dataclass(frozen=True)
class CheckReport:
    """What the checker found.

    Attributes:
        samples_checked: cut samples re-evaluated.
        violations: every broken limit.
        worst_ratio: per constraint, the largest value / limit found (≤ 1 is inside).
    """

    samples_checked: int
    violations: list[Violation] = field(default_factory=list)
    worst_ratio: dict[str, float] = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return not self.violations


def _power(cut: Cut, feed: float, coeffs: np.ndarray) -> float:
    """Spindle power [W] by numerical integration of the tangential edge force."""
    phi_st, phi_ex = (float(v) for v in immersion_angles(cut.a_e, cut.radius, cut.mode))
    phi = np.linspace(phi_st, phi_ex, ARC_POINTS)
    c = feed / (cut.flutes * cut.spindle_speed / (2.0 * np.pi))
    f_t = np.asarray(edge_forces(phi, c * np.sin(phi), cut.a_p, coeffs)[0], float).reshape(-1)
    torque = cut.flutes / (2.0 * np.pi) * cut.radius * np.trapezoid(f_t, phi)
    return float(torque * cut.spindle_speed)


def check_plan(prep: Prepared, feed: np.ndarray, kinds: np.ndarray, speed: np.ndarray | None,
               sections: list[tuple[int, int, int, float]], limits: Limits,
               profiled: bool = False) -> CheckReport:
    """Re-evaluate a plan independently.

    Args:
        prep: the prepared job the plan was made for.
        feed: planned feed per sample [m/s], (n,).
        kinds: kind code per sample, (n,).
        speed: timed path speed per sample [m/s], (n,), or None.
        sections: ``(start, stop, kind, feed)`` per section, in order.
        limits: the limits to check against.
        profiled: the plan is a feed profile (module docstring): per-sample feed caps, the path
            jerk, no feed-change bound between sections.
    """
    job = prep.job
    params = model_parameters(job, prep)
    model = PointModel(prep.robot, params, job.model.process_model, job.model.mass_model,
                       job.model.chatter_criterion, helix_angle=prep.tool.helix_angle)
    e, path = prep.engagement, prep.path
    feed_dir = e.feed_dir if e.feed_dir is not None else path.feed_dir
    codes = {0: "up", 1: "down", 2: "slot"}
    tool = prep.tool
    omega = job.spindle.rpm * 2.0 * np.pi / 60.0
    viol: list[Violation] = []
    worst: dict[str, float] = {"chatter": 0.0, "force": 0.0, "deflection": 0.0, "power": 0.0}

    def add(k: int, what: str, value: float, limit: float, ratio: float) -> None:
        worst[what] = max(worst.get(what, 0.0), ratio)
        if ratio > 1.0 + REL_TOL:
            viol.append(Violation(int(k), what, float(value), float(limit), path.where(k)))

    def cut_at(k: int) -> Cut:
        return Cut(feed_dir=feed_dir[k], radial_dir=e.radial_dir[k], a_e=float(e.a_e[k]),
                   a_p=float(e.a_p[k]), mode=codes[int(e.mode[k])], spindle_speed=omega,
                   flutes=tool.flutes, radius=tool.radius)

    cut_samples = np.flatnonzero(kinds == CUT)
    # the calibration's uncertainty bound, where the job states one (planner.limit_confidence)
    confidence = limit_confidence(job, e.a_e[cut_samples], e.a_p[cut_samples], e.mode[cut_samples],
                                  tool.flutes, tool.radius, tool.flutes * job.spindle.rpm / 60.0)
    for n, k in enumerate(cut_samples):
        cut = cut_at(k)
        a = model.analyze(prep.kinematics.q[k], cut, float(feed[k]))
        k_force = k_defl = 1.0
        if confidence is not None:
            kf, kd = confidence.factors(np.array([float(feed[k])]),
                                        np.asarray(a.force_o, float).reshape(1, 3), np.array([n]))
            k_force, k_defl = float(kf[0]), float(kd[0])
        add(k, "force", a.force * k_force, limits.force_max, a.force * k_force / limits.force_max)
        d = float(np.linalg.norm(a.deflection))
        change = 0.0
        if limits.compensate_deflection and k > 0 and kinds[k - 1] == CUT:
            # compensated: the LIN into k moves from −δ(k−1) to −δ(k); at k's feed (limits.py)
            prev = model.analyze(prep.kinematics.q[k - 1], cut_at(k - 1), float(feed[k]))
            change = float(np.linalg.norm(np.asarray(a.deflection) - np.asarray(prev.deflection)))
        held = float(limits.deflection_held(d, change))
        held *= k_defl
        add(k, "deflection", held, limits.deflection_tol, held / limits.deflection_tol)
        p = _power(cut, float(feed[k]), params.coefficients)
        add(k, "power", p, limits.power_max, p / limits.power_max)
        if model.criterion == "gamma_window":
            ok = a.gamma_margin > 0.0
            value, limit = a.gamma_margin, 0.0
        elif model.criterion == "floquet":
            ok = a.stable
            value, limit = a.floquet_margin, 0.0
        else:
            ok = a.stable_eigen and a.margin >= limits.margin_min
            value, limit = a.margin, limits.margin_min
        worst["chatter"] = max(worst["chatter"], 0.0 if ok else 2.0)
        if not ok:
            viol.append(Violation(int(k), "chatter", float(value), float(limit), path.where(k)))
    ds = step_lengths(path.s)
    prog = path.feed
    ds = step_lengths(path.s)
    for a, b, kind, f in sections:
        if b <= a:
            viol.append(Violation(a, "section_samples", float(b - a), 1.0, path.where(a)))
            continue
        if kind == RAPID:
            if f > limits.rapid_speed * (1 + REL_TOL):
                viol.append(Violation(a, "rapid_speed", f, limits.rapid_speed, path.where(a)))
            continue
        if kind == CUT:
            if not (limits.feed_min * (1 - REL_TOL) <= f <= limits.feed_max * (1 + REL_TOL)):
                bound = limits.feed_min if f < limits.feed_min else limits.feed_max
                viol.append(Violation(a, "feed_bounds", f, bound, path.where(a)))
            cap = prog[a:b] * limits.cam_feed_scale_max
        else:   # air: as programmed, never above the rapid speed
            if f > limits.rapid_speed * (1 + REL_TOL):
                viol.append(Violation(a, "rapid_speed", f, limits.rapid_speed, path.where(a)))
            cap = prog[a:b]
        # a sample that adds no path (ds = 0) has no speed of its own
        fs = feed[a:b] if profiled else np.full(b - a, f)
        over = np.flatnonzero(np.isfinite(cap) & (fs > cap * (1 + REL_TOL)) & (ds[a:b] > 0.0))
        if over.size:
            k = a + int(over[0])
            viol.append(Violation(k, "cam_feed", float(fs[over[0]]), float(cap[over[0]]),
                                  path.where(k)))
        if profiled and kind == CUT:
            top = np.flatnonzero(feed[a:b] > limits.feed_max * (1 + REL_TOL))
            if top.size:
                k = a + int(top[0])
                viol.append(Violation(k, "feed_bounds", float(feed[k]), limits.feed_max,
                                      path.where(k)))
    runs = kind_runs(kinds)
    run_of = np.zeros(len(path), int)
    for i, (a, b, _) in enumerate(runs):
        run_of[a:b] = i
    cut_secs = [x for x in sections if x[2] == CUT]
    for (_, b0, _, f0), (a1, _, _, f1) in zip(cut_secs, cut_secs[1:], strict=False):
        if b0 == a1 and not profiled and limits.feed_change_max is not None and \
                abs(f1 - f0) > limits.feed_change_max * (1 + 1e-6) + 1e-12:
            viol.append(Violation(a1, "feed_change", abs(f1 - f0), limits.feed_change_max,
                                  path.where(a1)))
    for a, b, _, _ in cut_secs:
        run = runs[run_of[a]]
        length = ds[a:b].sum()
        if length < limits.section_length_min * (1 - 1e-9) and (run[0], run[1]) != (a, b):
            viol.append(Violation(a, "section_length", float(length), limits.section_length_min,
                                  path.where(a)))
    if speed is not None:
        over = np.flatnonzero(speed > feed * (1 + SPEED_TOL) + 1e-12)
        for k in over[:20]:
            viol.append(Violation(int(k), "timed_speed", float(speed[k]), float(feed[k]),
                                  path.where(k)))
        data = prep.robot.data
        dyn, ratios = dynamics_violations(
            path.s, prep.kinematics.q, speed, np.asarray(data.velocity, float),
            np.asarray(data.acceleration, float), limits.path_acc_max,
            limits.path_jerk_max if profiled else None)
        worst.update(ratios)
        viol.extend(Violation(d.sample, d.constraint, d.value, d.limit, path.where(d.sample))
                    for d in dyn)
    viol.extend(_posture_violations(prep))
    return CheckReport(samples_checked=int(cut_samples.size), violations=viol, worst_ratio=worst)


def _posture_violations(prep: Prepared) -> list[Violation]:
    """A posture chosen along the path, measured from the joints themselves
    (:func:`planner.posture.check_posture`): joint jumps, wrist flips, joint limits and the
    rotation rate, one violation per kind (the first sample; value = samples found)."""
    posture = getattr(prep, "posture", None)
    if posture is None or posture.fallback:
        return []
    from planner.posture import check_posture

    pc = check_posture(prep)
    out = []
    for what, ks in (("posture_jump", pc.jumps), ("posture_wrist_flip", pc.wrist_flips),
                     ("posture_joint_limits", pc.limit_violations),
                     ("posture_rate", pc.rate_violations)):
        if ks:
            out.append(Violation(int(ks[0]), what, float(len(ks)), 0.0, prep.path.where(int(ks[0]))))
    return out


def check_result(res) -> CheckReport:
    """:func:`check_plan` on a :class:`planner.plan.PlanResult`."""
    return check_plan(res.prep, res.feed, res.kinds, res.timing.speed,
                      [(s.start, s.stop, s.kind, s.feed) for s in res.sections], res.limits,
                      profiled=bool(getattr(res, "profiled", False)))
