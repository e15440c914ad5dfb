"""Time along the path: ruckig-shaped feed transitions, then toppra under the robot's joint limits.

1. **Feed bound.** Sections give a piecewise-constant path-speed bound. Every change between
   neighbouring sections is shaped by ruckig (1-DOF, velocity interface, path acceleration and
   jerk limits): a slow-down is finished *before* the slower section starts and a speed-up starts
   *after* the faster one begins, so the shaped bound never exceeds any section's feed.
2. **toppra.** The joint path q(s) (cubic spline through the samples, s the tool-tip arc length)
   is time-parametrised with the joint velocity and acceleration limits of the robot, plus one
   virtual coordinate equal to s whose velocity limit is the shaped feed bound and whose
   acceleration limit is the path acceleration — so ṡ never exceeds the plan and the timing is
   the fastest the robot can follow. Rest to rest.

Where toppra's ṡ falls clearly below the shaped bound, the robot, not the process, limits the
speed; :func:`time_path` reports it per sample.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import toppra
import toppra.algorithm as algo
import toppra.constraint as constraint
from ruckig import ControlInterface, InputParameter, Result, Ruckig, Trajectory

from models.errors import CctmillError

__all__ = [
    "ROBOT_LIMITED",
    "ROBOT_LIMITED_SECTION",
    "Timing",
    "TimingError",
    "cycle_of",
    "shape_feed",
    "spline_grid",
    "time_path",
    "toppra_speed",
    "transition",
]

#: ṡ below this fraction of the shaped feed bound counts as robot-limited [-].
ROBOT_LIMITED = 0.98
#: A *section* is robot-limited when its timed mean speed falls below this fraction of its feed
#: [-]. Looser than the per-sample rule above on purpose: the mean includes the ruckig-shaped feed
#: changes at both ends of the section, which slow it even where the joints limit nothing.
ROBOT_LIMITED_SECTION = 0.9
#: Consecutive samples closer than this along the path are merged for the spline [m] (a spline
#: needs strictly increasing knots; CAM programs repeat points).
KNOT_TOL = 1e-7
#: Samples per ruckig transition profile [-].
PROFILE_POINTS = 25


class TimingError(CctmillError):
    """toppra or ruckig could not time the path."""


@dataclass(frozen=True)
class Timing:
    """The timed path. SI, ``n`` samples.

    Attributes:
        bound: the ruckig-shaped path-speed bound at each sample [m/s], (n,).
        speed: toppra's path speed ṡ at each sample [m/s], (n,).
        time: time at each sample [s], (n,).
        joint_speed: |q̇| at each sample [rad/s], (n, nq).
        robot_limited: ṡ < :data:`ROBOT_LIMITED` × bound, (n,) bool.
        cycle_time: the whole path [s].
        compute_time: wall time of the timing [s].
    """

    bound: np.ndarray
    speed: np.ndarray
    time: np.ndarray
    joint_speed: np.ndarray
    robot_limited: np.ndarray
    cycle_time: float
    compute_time: float


def transition(v_from: float, v_to: float, acc: float, jerk: float) -> tuple[np.ndarray, np.ndarray]:
    """A jerk-limited change of path speed (ruckig, velocity interface), from rest acceleration.

    Returns:
        (distance [m], speed [m/s]) along the transition, each (:data:`PROFILE_POINTS`,),
        distance from 0 to the transition's length.
    """
    inp = InputParameter(1)
    inp.control_interface = ControlInterface.Velocity
    inp.current_position = [0.0]
    inp.current_velocity = [float(v_from)]
    inp.current_acceleration = [0.0]
    inp.target_velocity = [float(v_to)]
    inp.target_acceleration = [0.0]
    inp.max_velocity = [max(v_from, v_to) * 2.0 + 1.0]
    inp.max_acceleration = [float(acc)]
    inp.max_jerk = [float(jerk)]
    traj = Trajectory(1)
    res = Ruckig(1).calculate(inp, traj)
    if res not in (Result.Working, Result.Finished):
        raise TimingError(f"ruckig could not shape a feed change {v_from * 1e3:.3f} → "
                          f"{v_to * 1e3:.3f} mm/s ({res}); check path_acc_max / path_jerk_max")
    ts = np.linspace(0.0, traj.duration, PROFILE_POINTS)
    pos = np.empty(ts.size)
    vel = np.empty(ts.size)
    for i, t in enumerate(ts):
        p, v, _ = traj.at_time(t)
        pos[i], vel[i] = p[0], v[0]
    return pos - pos[0], np.clip(vel, min(v_from, v_to), max(v_from, v_to))


def shape_feed(s: np.ndarray, feed: np.ndarray, acc: float, jerk: float) -> np.ndarray:
    """The piecewise-constant per-sample feed [m/s], (n,), with every change shaped by ruckig.

    A drop at sample k (feed[k] < feed[k−1]) is finished by s[k−1]... the transition ends where the
    slower stretch begins; a rise starts where the faster one begins. The result is the pointwise
    minimum of the steps and all transition profiles, never above ``feed``.
    """
    bound = feed.astype(float).copy()
    changes = np.flatnonzero(np.diff(feed) != 0) + 1
    cache: dict[tuple[float, float], tuple[np.ndarray, np.ndarray]] = {}
    for k in changes:
        lo_side, hi_side = feed[k - 1], feed[k]
        key = (float(lo_side), float(hi_side))
        if key not in cache:
            cache[key] = transition(lo_side, hi_side, acc, jerk)
        dist, vel = cache[key]
        boundary = s[k - 1]
        if hi_side < lo_side:  # slow down before the boundary
            where = boundary - dist[-1] + dist
            sel = (s >= where[0]) & (s <= boundary)
        else:                  # speed up after it
            where = boundary + dist
            sel = (s >= boundary) & (s <= where[-1])
        if np.any(sel):
            bound[sel] = np.minimum(bound[sel], np.interp(s[sel], where, vel))
    return np.minimum(bound, feed)


def spline_grid(s: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray,
                                                        toppra.SplineInterpolator]:
    """The samples toppra times (``keep``: consecutive samples closer than :data:`KNOT_TOL`
    merged), their arc lengths ``ss`` and the cubic spline of (q, s) over them.

    Raises:
        TimingError: fewer than two distinct samples.
    """
    keep = np.concatenate([[True], np.diff(s) > KNOT_TOL])
    ss = s[keep]
    if ss.size < 2:
        raise TimingError("the path is shorter than one step; nothing to time")
    return keep, ss, toppra.SplineInterpolator(ss, np.column_stack([q[keep], ss]))


def toppra_speed(ss: np.ndarray, path: toppra.SplineInterpolator, bound: np.ndarray,
                 velocity_limit: np.ndarray, acceleration_limit: np.ndarray,
                 path_acc: float) -> np.ndarray:
    """toppra's path speed ṡ ≥ 0 [m/s] at the grid ``ss`` (m,): the joint speed (nq,) [rad/s]
    and acceleration (nq,) [rad/s²] limits, plus a virtual coordinate equal to s whose speed
    limit is ``bound`` (m,) [m/s] and whose acceleration limit is ``path_acc`` [m/s²]. Rest to
    rest.

    Raises:
        TimingError: toppra fails or finds no parametrisation.
    """

    def vlim(x: float) -> np.ndarray:
        lim = np.concatenate([velocity_limit, [np.interp(x, ss, bound)]])
        return np.column_stack([-lim, lim])

    alim = np.concatenate([acceleration_limit, [path_acc]])
    cons = [constraint.JointVelocityConstraintVarying(vlim),
            constraint.JointAccelerationConstraint(np.column_stack([-alim, alim]))]
    inst = algo.TOPPRA(cons, path, gridpoints=ss, parametrizer="ParametrizeConstAccel")
    try:
        _, sd, _ = inst.compute_parameterization(0.0, 0.0)
    except Exception as e:  # toppra raises bare exceptions from its solvers
        raise TimingError(f"toppra failed to time the path: {e}") from e
    sd = np.asarray(sd, float)
    if sd.size != ss.size or not np.all(np.isfinite(sd)):
        raise TimingError("toppra found no feasible parametrisation: the path-speed bound or the "
                          "joint limits leave no way through (check the limits in the robot data)")
    return np.maximum(sd, 0.0)


def cycle_of(s: np.ndarray, speed: np.ndarray) -> np.ndarray:
    """Time at each grid point [s], (m,): trapezoids in 1/ṡ, the constant-acceleration form on
    each interval."""
    dt = 2.0 * np.diff(s) / np.maximum(speed[:-1] + speed[1:], 1e-12)
    return np.concatenate([[0.0], np.cumsum(dt)])


def time_path(s: np.ndarray, q: np.ndarray, feed: np.ndarray, velocity_limit: np.ndarray,
              acceleration_limit: np.ndarray, path_acc: float, path_jerk: float) -> Timing:
    """Time the path with toppra under the shaped feed bound and the joint limits.

    Args:
        s: tool-tip arc length per sample [m], (n,), non-decreasing.
        q: joints per sample [rad], (n, nq).
        feed: path-speed bound per sample [m/s], (n,) (the sections' feeds).
        velocity_limit: joint speed limits [rad/s], (nq,).
        acceleration_limit: joint acceleration limits [rad/s²], (nq,).
        path_acc: path acceleration limit [m/s²].
        path_jerk: path jerk limit of feed transitions [m/s³].
    """
    t0 = time.perf_counter()
    if not np.all(np.isfinite(feed)) or np.any(feed <= 0):
        raise TimingError("every sample needs a positive finite feed bound")
    bound = shape_feed(s, feed, path_acc, path_jerk)
    keep, ss, path = spline_grid(s, q)
    nq = q.shape[1]
    xd = toppra_speed(ss, path, bound[keep], velocity_limit, acceleration_limit, path_acc)
    t_grid = cycle_of(ss, xd)
    speed = np.interp(s, ss, xd)
    times = np.interp(s, ss, t_grid)
    dqds = path(s, 1)[:, :nq]
    joint_speed = np.abs(dqds) * speed[:, None]
    robot = speed < ROBOT_LIMITED * bound
    return Timing(bound=bound, speed=speed, time=times, joint_speed=joint_speed, robot_limited=robot,
                  cycle_time=float(t_grid[-1]), compute_time=time.perf_counter() - t0)
