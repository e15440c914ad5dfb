"""Independent check of a timed path speed: path acceleration and jerk, joint speed and acceleration.

Part of the independent checker (:mod:`planner.check`); it shares no code with the planner's
timing (:mod:`planner.timing`, :mod:`planner.feed_profile`). From the samples' arc length s, joints
q and timed speed v alone it rebuilds the joint path as a cubic spline q(s) (not-a-knot, through
the samples; samples closer than :data:`KNOT_GAP` merged, as a spline needs increasing knots) and
evaluates, with constant path acceleration on each interval between samples (the timing's own
model: ṡ² linear in s):

* path acceleration a_i = (v_{i+1}² − v_i²) / (2 h_i) on every interval, |a_i| ≤ ``path_acc``;
* path jerk (a_i − a_{i−1}) / τ_i at every sample, τ_i the mean duration of the two intervals,
  and at the two ends from and to zero acceleration when the path starts or ends at rest,
  ≤ ``path_jerk`` (feed profiles only: a section plan's toppra timing switches acceleration
  at once);
* joint speed |q'_j(s_i)| v_i ≤ q̇_max,j at every sample;
* joint acceleration |q'_j a_i + q''_j v²| at both ends of every interval ≤ q̈_max,j.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import CubicSpline

__all__ = ["DYNAMICS_TOL", "KNOT_GAP", "DynamicsViolation", "dynamics_violations"]

#: A dynamic limit counts as broken above (1 + this) × the limit [-]: the timings' solvers
#: (toppra's, HiGHS's) meet their rows to ~1e-7 of the bound; a real violation is far larger.
DYNAMICS_TOL = 1e-4
#: Samples closer than this along the path are one spline knot [m] (CAM programs repeat points).
KNOT_GAP = 1e-7
#: Below this speed [m/s] a path end counts as a rest point (the jerk from rest is checked there).
REST = 1e-9
#: At most this many violations are listed per constraint (the first ones along the path).
MAX_LISTED = 20


@dataclass(frozen=True)
class DynamicsViolation:
    """One broken dynamic limit at ``sample`` (SI ``value`` against ``limit``)."""

    sample: int
    constraint: str
    value: float
    limit: float


def dynamics_violations(s: np.ndarray, q: np.ndarray, speed: np.ndarray,
                        velocity_limit: np.ndarray, acceleration_limit: np.ndarray,
                        path_acc: float, path_jerk: float | None) -> tuple[list[DynamicsViolation],
                                                                             dict[str, float]]:
    """The timed speed's broken dynamic limits (module docstring) and the worst ratio of each.

    Args:
        s: arc length per sample [m], (n,), non-decreasing.
        q: joints per sample [rad], (n, nq).
        speed: timed path speed per sample [m/s], (n,).
        velocity_limit, acceleration_limit: joint limits [rad/s], [rad/s²], (nq,).
        path_acc: path acceleration limit [m/s²].
        path_jerk: path jerk limit [m/s³], or ``None`` to leave the jerk unchecked.
    """
    idx = np.flatnonzero(np.concatenate([[True], np.diff(s) > KNOT_GAP]))
    out: list[DynamicsViolation] = []
    worst: dict[str, float] = {}
    if idx.size < 2:
        return out, worst
    ss, v = s[idx], np.maximum(speed[idx], 0.0)
    spline = CubicSpline(ss, q[idx], axis=0, bc_type="not-a-knot")
    d1, d2 = spline(ss, 1), spline(ss, 2)
    h = np.diff(ss)
    x = v**2
    acc = (x[1:] - x[:-1]) / (2.0 * h)

    def report(name: str, ratio: np.ndarray, value: np.ndarray, limit: np.ndarray,
               at: np.ndarray) -> None:
        if ratio.size == 0:
            return
        worst[name] = max(worst.get(name, 0.0), float(np.max(ratio)))
        bad = np.flatnonzero(ratio > 1.0 + DYNAMICS_TOL)[:MAX_LISTED]
        out.extend(DynamicsViolation(int(idx[at[k]]), name, float(value[k]), float(limit[k]))
                   for k in bad)

    i = np.arange(h.size)
    report("path_acceleration", np.abs(acc) / path_acc, acc, np.full(h.size, path_acc), i)
    if path_jerk is not None:
        dt = 2.0 * h / np.maximum(v[:-1] + v[1:], 1e-300)
        jerk = np.diff(acc) / (0.5 * (dt[:-1] + dt[1:]))
        at = np.arange(1, h.size)
        if v[0] <= REST:
            jerk, at = np.concatenate([[acc[0] / (0.5 * dt[0])], jerk]), np.concatenate([[0], at])
        if v[-1] <= REST:
            jerk = np.concatenate([jerk, [-acc[-1] / (0.5 * dt[-1])]])
            at = np.concatenate([at, [h.size]])
        report("path_jerk", np.abs(jerk) / path_jerk, jerk, np.full(jerk.size, path_jerk), at)
    qd = np.abs(d1) * v[:, None]
    j = np.argmax(qd / velocity_limit, axis=1)
    all_i = np.arange(ss.size)
    report("joint_speed", qd[all_i, j] / velocity_limit[j], qd[all_i, j], velocity_limit[j], all_i)
    for end in (0, 1):
        e = i + end
        qdd = np.abs(d1[e] * acc[:, None] + d2[e] * x[e, None])
        j = np.argmax(qdd / acceleration_limit, axis=1)
        report("joint_acceleration", qdd[i, j] / acceleration_limit[j], qdd[i, j],
               acceleration_limit[j], e)
    return out, worst
