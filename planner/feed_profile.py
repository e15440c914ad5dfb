"""Feed profile: a path speed per sample under the ceilings, path acceleration and jerk, joint limits.

Two steps (docs/planner.md, "Feed profile"):

1. **Pointwise bound** (:func:`pointwise_bound`). toppra times the joint path q(s) (cubic spline,
   s the tool-tip arc length) with the joints' speed and acceleration limits and a virtual
   coordinate equal to s whose speed limit is the per-sample ceiling and whose acceleration limit
   is the path acceleration. No jerk limit: this is the fastest any feed plan can be under these
   limits — the physical limit of feed planning, and a strict lower bound on every plan's cycle.
2. **Jerk pass** (:func:`jerk_limited`). With x = ṡ² per grid point, u_i = (x_{i+1} − x_i)/(2 h_i)
   the path acceleration on interval i (constant on it), the path jerk between intervals i−1 and
   i is (u_i − u_{i−1}) / τ_i with τ_i = (Δt_{i−1} + Δt_i)/2. The pass solves the linear program

       maximise   Σ_i w_i x_i / x̂_i                     (w_i: time around grid point i at x̂)
       subject to 0 ≤ x_i ≤ x̂_i                          (x̂: the pointwise bound's ṡ²)
                  |u_i| ≤ a_max                           (path acceleration)
                  |q'_j u_i + q''_j x_e| ≤ q̈_max,j        (joint acceleration, e = i and i+1)
                  |u_i − u_{i−1}| ≤ j_max τ̂_i             (path jerk, τ̂ from x̂)

   τ̂ is computed from the pointwise bound; since x ≤ x̂, every real τ_i ≥ τ̂_i, so the linear
   jerk rows are a *sound* (conservative) form of the real, non-convex jerk limit. The program is
   always feasible (x = 0), convex and solved exactly by HiGHS (scipy). Rest to rest, with zero
   acceleration at both ends.

Why not an NLP (IPOPT through CasADi, x as variable, the exact jerk rows): the LP is within a
fraction of a per cent of the pointwise bound on the demo job (benchmarks/plan_speed.py), so the
exact rows could gain at most that, and the LP needs no start point, cannot fail to converge and
takes well under a second for 10,000 samples.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import toppra
from scipy.optimize import Bounds, LinearConstraint, milp

from planner.timing import ROBOT_LIMITED, Timing, TimingError, cycle_of, spline_grid, toppra_speed

__all__ = [
    "LP_MARGIN",
    "REST_SPEED",
    "FeedProfile",
    "cycle_of",
    "jerk_limited",
    "pointwise_bound",
    "profile_path",
    "profile_timing",
]

#: Speed below which a grid point counts as at rest [m/s] (the path's two ends).
REST_SPEED = 1e-9
#: ṡ² of the LP's solution is lowered by this fraction before use [-]. Every row is homogeneous
#: in x and scaled to its bound, so this puts each row inside its bound by more than HiGHS's
#: primal feasibility tolerance (1e-7 of the bound).
LP_MARGIN = 1e-6


@dataclass(frozen=True)
class FeedProfile:
    """The feed profile and its bound, on the kept grid (samples closer than KNOT_TOL merged).

    Attributes:
        s: grid arc length [m], (m,).
        speed: profiled path speed [m/s], (m,).
        bound_speed: the pointwise bound's speed (toppra, no jerk limit) [m/s], (m,).
        cycle_time: the profile's duration [s].
        bound_cycle_time: the pointwise bound's duration [s].
        lp_rows: rows of the jerk pass's LP; lp_status: HiGHS's message.
        bound_time, lp_time: wall time of the two steps [s].
    """

    s: np.ndarray
    speed: np.ndarray
    bound_speed: np.ndarray
    cycle_time: float
    bound_cycle_time: float
    lp_rows: int
    lp_status: str
    bound_time: float
    lp_time: float


def pointwise_bound(ss: np.ndarray, path: toppra.SplineInterpolator, ceiling: np.ndarray,
                    velocity_limit: np.ndarray, acceleration_limit: np.ndarray,
                    path_acc: float) -> np.ndarray:
    """toppra's path speed [m/s], (m,), under the ceiling (m,) [m/s], the joint speed (nq,)
    [rad/s] and acceleration (nq,) [rad/s²] limits and the path acceleration [m/s²]."""
    return np.minimum(toppra_speed(ss, path, ceiling, velocity_limit, acceleration_limit,
                                   path_acc), ceiling)


def jerk_limited(ss: np.ndarray, bound: np.ndarray, dq: np.ndarray, ddq: np.ndarray,
                 acceleration_limit: np.ndarray, path_acc: float,
                 path_jerk: float) -> tuple[np.ndarray, int, str]:
    """The jerk pass (module docstring): the profiled speed [m/s], (m,), never above ``bound``.

    Args:
        ss: grid [m], (m,), increasing.
        bound: the pointwise bound's speed [m/s], (m,).
        dq, ddq: q'(s) [rad/m] and q''(s) [rad/m²] at the grid, (m, nq).
        acceleration_limit: joint acceleration limits [rad/s²], (nq,).
        path_acc: path acceleration limit [m/s²]; path_jerk: path jerk limit [m/s³].
    """
    m = ss.size
    h = np.diff(ss)
    xr = bound**2
    sc = np.where(xr > REST_SPEED**2, xr, 1.0)          # x_i = sc_i z_i, z_i in [0, 1]
    dt = 2.0 * h / np.maximum(bound[:-1] + bound[1:], 1e-12)
    rows, cols, vals, lo, hi = [], [], [], [], []
    r = 0

    def add(idx: list[np.ndarray], coef: list[np.ndarray], lim: np.ndarray) -> None:
        nonlocal r
        k = lim.size
        ids = np.arange(r, r + k)
        for i, c in zip(idx, coef, strict=True):
            rows.append(ids)
            cols.append(i)
            vals.append(c * sc[i] / lim)                 # each row scaled to its bound
        lo.append(-np.ones(k))
        hi.append(np.ones(k))
        r += k

    i = np.arange(m - 1)
    # u_i = (x_{i+1} - x_i) / (2 h_i)
    add([i + 1, i], [1.0 / (2 * h), -1.0 / (2 * h)], np.full(m - 1, path_acc))
    for e_off in (0, 1):
        e = i + e_off
        need = (np.abs(dq[e]) * path_acc + np.abs(ddq[e]) * xr[e, None]
                > acceleration_limit[None, :] * (1 - 1e-6))
        for j in range(dq.shape[1]):
            k = np.flatnonzero(need[:, j])
            if not k.size:
                continue
            ie, ii = e[k], i[k]
            c_next = dq[ie, j] / (2 * h[ii])
            c_here = -dq[ie, j] / (2 * h[ii])
            # x_e's own term q''_j x_e joins the coefficient of x_i or x_{i+1}
            if e_off == 0:
                c_here = c_here + ddq[ie, j]
            else:
                c_next = c_next + ddq[ie, j]
            add([ii + 1, ii], [c_next, c_here], np.full(k.size, acceleration_limit[j]))
    # jerk: |u_i - u_{i-1}| <= J tau_i, interior nodes; from and to rest with zero acceleration
    if m > 2:
        n = np.arange(1, m - 1)
        tau = 0.5 * (dt[n - 1] + dt[n])
        a, b = 1.0 / (2 * h[n]), 1.0 / (2 * h[n - 1])
        add([n + 1, n, n - 1], [a, -a - b, b], path_jerk * tau)
    add([np.array([1]), np.array([0])], [np.array([1 / (2 * h[0])]), np.array([-1 / (2 * h[0])])],
        np.array([path_jerk * dt[0] / 2]))
    add([np.array([m - 1]), np.array([m - 2])],
        [np.array([1 / (2 * h[-1])]), np.array([-1 / (2 * h[-1])])],
        np.array([path_jerk * dt[-1] / 2]))
    a_mat = sp.csr_array((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                         shape=(r, m))
    w = np.zeros(m)
    w[:-1] += dt
    w[1:] += dt
    ub = np.where(xr > REST_SPEED**2, 1.0, 0.0)
    res = milp(-w / w.sum(), constraints=LinearConstraint(a_mat, np.concatenate(lo), np.concatenate(hi)),
               bounds=Bounds(np.zeros(m), ub))
    if res.x is None:
        raise TimingError(f"the feed profile's jerk pass failed ({res.message}); check "
                          "path_acc_max / path_jerk_max")
    x = np.clip(res.x, 0.0, ub) * sc * (1.0 - LP_MARGIN)
    return np.minimum(np.sqrt(x), bound), r, str(res.message)


def profile_path(s: np.ndarray, q: np.ndarray, ceiling: np.ndarray, velocity_limit: np.ndarray,
                 acceleration_limit: np.ndarray, path_acc: float, path_jerk: float,
                 jerk: bool = True) -> FeedProfile:
    """The feed profile of a path (module docstring).

    Args:
        s: tool-tip arc length per sample [m], (n,), non-decreasing.
        q: joints per sample [rad], (n, nq).
        ceiling: path-speed ceiling per sample [m/s], (n,), positive and finite.
        velocity_limit, acceleration_limit: joint limits [rad/s], [rad/s²], (nq,).
        path_acc: path acceleration limit [m/s²]; path_jerk: path jerk limit [m/s³].
        jerk: run the jerk pass (False: the pointwise bound is the profile).
    """
    if not np.all(np.isfinite(ceiling)) or np.any(ceiling <= 0):
        raise TimingError("every sample needs a positive finite feed ceiling")
    t0 = time.perf_counter()
    keep, ss, path = spline_grid(s, q)
    c = ceiling[keep]
    bound = pointwise_bound(ss, path, c, velocity_limit, acceleration_limit, path_acc)
    t1 = time.perf_counter()
    rows, status = 0, "not run"
    speed = bound
    if jerk:
        nq = q.shape[1]
        speed, rows, status = jerk_limited(ss, bound, path(ss, 1)[:, :nq], path(ss, 2)[:, :nq],
                                           acceleration_limit, path_acc, path_jerk)
    t2 = time.perf_counter()
    return FeedProfile(s=ss, speed=speed, bound_speed=bound,
                       cycle_time=float(cycle_of(ss, speed)[-1]),
                       bound_cycle_time=float(cycle_of(ss, bound)[-1]), lp_rows=rows,
                       lp_status=status, bound_time=t1 - t0, lp_time=t2 - t1)


def profile_timing(s: np.ndarray, q: np.ndarray, ceiling: np.ndarray, velocity_limit: np.ndarray,
                   acceleration_limit: np.ndarray, path_acc: float, path_jerk: float,
                   jerk: bool = True) -> tuple[Timing, FeedProfile]:
    """:func:`profile_path` as a :class:`planner.timing.Timing` on every sample (``bound`` the
    ceiling, ``speed`` the profile) and the profile itself."""
    t0 = time.perf_counter()
    prof = profile_path(s, q, ceiling, velocity_limit, acceleration_limit, path_acc, path_jerk,
                        jerk)
    _, ss, path = spline_grid(s, q)
    nq = q.shape[1]
    speed = np.minimum(np.interp(s, ss, prof.speed), ceiling)
    times = np.interp(s, ss, cycle_of(ss, prof.speed))
    joint_speed = np.abs(path(s, 1)[:, :nq]) * speed[:, None]
    timing = Timing(bound=ceiling.astype(float), speed=speed, time=times, joint_speed=joint_speed,
                    robot_limited=speed < ROBOT_LIMITED * ceiling, cycle_time=prof.cycle_time,
                    compute_time=time.perf_counter() - t0)
    return timing, prof
