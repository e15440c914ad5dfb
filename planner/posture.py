"""The posture along the path: the rotation about the tool axis chosen for the whole path.

Milling fixes five of the TCP's six degrees of freedom; the sixth, the rotation ψ about the tool
axis, is free (docs/model.md §8). With the spindle on the A6 axis it moves A6 alone and changes
nothing the cut sees; with the spindle mounted off that axis it swings the whole arm, and with it
the stiffness and the mass at the TCP — the ceilings of the feed (docs/posture.md).

:func:`choose_posture` picks ψ at every sample to raise the binding ceiling along the whole path:

1. **Stations.** The path is thinned to stations at least ``station_mm`` apart (4 mm: 374 of the
   demo contour's 892 samples, about every 27th of a 0.15 mm path); ψ is measured as an *offset*
   from today's posture (:func:`planner.ik.solve_path`, which is the row of offset 0).
2. **Rows.** For every offset of an IK grid (``ik_step_deg`` apart, within ±``span_deg``) the
   arm is solved at every station with the full TCP rotation (today's, turned by the offset about
   the tool axis), each solve seeded from the previous station of its row, or else from the
   neighbouring row at the same station — so every row stays on today's branch. A (station, row)
   counts only when it converged, is inside the joint limits, moved no joint more than
   :data:`planner.ik.JUMP_TOL` from its seed and keeps today's wrist configuration (the sign of A5).
3. **Ceilings.** The feed ceiling of every feasible (station, row) that cuts, with the full
   point model (:meth:`planner.ceilings.PathModel.ceilings`, the planner's own), capped by the
   programmed feed and the tool's chip load as the plan caps it.
4. **Dynamic programming.** Over a fine grid of offsets (``rate × station_mm`` apart; costs
   interpolated linearly between the IK rows, a state feasible only between two feasible rows)
   a Viterbi pass minimises Σ L_k / ceiling_k (the cut time the stations stand for) plus a small
   cost per change of ψ, subject to |Δψ| ≤ rate × Δs — so ψ(s) is continuous with a bounded rate
   per mm of path.
5. **Every sample.** ψ(s) is interpolated linearly to every sample (which keeps the rate bound)
   and the arm solved once more at each, seeded from the sample before; the result is checked
   (reach, limits, jumps, wrist configuration). Should a sample fail there, the path falls back to
   today's posture and says so (:attr:`Posture.fallback`).

Today's posture is a feasible path of the DP (offset 0 everywhere, no change cost), so the choice
is never worse than today's on the DP's objective.
"""

from __future__ import annotations

import copy
import math
import time
from dataclasses import dataclass, field, replace

import numpy as np

from planner.cam_feed import cam_feed_caps
from planner.ceilings import PathModel, engaged_samples, model_parameters
from planner.ik import (
    CONVERGED_AXIS,
    CONVERGED_POSITION,
    JUMP_TOL,
    IKOptions,
    PathKinematics,
    _Solver,
)
from planner.prepare import Prepared
from planner.tool_limits import tool_feed_cap

#: LM iterations of a full-rotation solve from a neighbouring pose (it converges in a few; one
#: that does not in this many is out of reach).
ROW_ITERATIONS = 25
#: Relative bracket of the search's ceilings [-] (the plan's own are 0.1 %; 1 % tells poses apart
#: at two thirds of the cost).
SEARCH_RTOL = 1e-2
#: Preference for today's posture among equal ones, as a fraction of the cut time per station
#: and half turn [-] (far below any real difference of ceilings).
TIE_COST = 1e-6
#: A tool axis and a TCP this close to the A6 axis [m, -] are on it: the rotation about the tool
#: axis is then A6 alone and changes no ceiling.
ON_AXIS_TOL = 1e-9
#: Slack of the posture check's rate [rad]: the solves hold the rotation to 1e-7 rad and less.
RATE_TOL = 1e-6
#: Shortest step [m] whose joint change seeds the next solve by extrapolation (a shorter one,
#: e.g. a repeated point, says nothing about the direction).
EXTRAPOLATE_MIN_STEP = 1e-6

__all__ = [
    "Posture",
    "PostureCheck",
    "PostureOptions",
    "apply_posture",
    "check_posture",
    "choose_posture",
    "on_a6_axis",
    "posture_by_section",
    "tool_rotation_offsets",
]


@dataclass(frozen=True)
class PostureOptions:
    """Options of :func:`choose_posture`.

    Attributes:
        rate_deg_per_mm: largest change of ψ per mm of path [deg/mm] (1 deg/mm: a quarter turn
            takes 90 mm of path; the plan's timing holds the joints' speeds on top).
        span_deg: offsets from today's posture considered, ±this [deg].
        ik_step_deg: offset step of the IK rows [deg].
        station_mm: least path length between stations [mm]; the DP's offset step is
            ``rate_deg_per_mm × station_mm``.
        change_cost: cost of changing ψ, as a fraction of the time the station stands for, per
            DP step moved [-] (it removes dithering; it never outweighs a real gain).
        threads: threads of the ceilings' evaluation.
        skip_on_axis: keep today's posture without a search when the tool and the spindle's
            centre of mass are on the A6 axis (:func:`on_a6_axis`).
    """

    rate_deg_per_mm: float = 1.0
    span_deg: float = 180.0
    ik_step_deg: float = 10.0
    station_mm: float = 4.0
    change_cost: float = 1e-3
    threads: int = 2
    skip_on_axis: bool = True


@dataclass(frozen=True)
class Posture:
    """The chosen posture and what it gained.

    Attributes:
        kinematics: the joint angles with the chosen posture (today's on a fallback).
        offset: ψ − ψ_today per sample [rad], (n,) (zeros on a fallback).
        stations: the station sample indices, (k,).
        station_offset: the DP's offset per station [rad], (k,).
        weight: cut length each station stands for [m], (k,).
        ceiling_today: the ceiling at each station with today's posture [m/s], (k,) (NaN where
            the station stands for no cut).
        ceiling_chosen: the ceiling with the chosen offset (interpolated between IK rows) [m/s].
        time_today: Σ weight / ceiling_today [s] (the DP's cut-time estimate, today).
        time_chosen: the same with the chosen posture [s].
        rate_max: the largest |dψ/ds| of the offset over the samples [rad/m].
        fallback: why today's posture was kept ("" when the chosen one is used).
        wall_times: ``ik_rows_s``, ``ceilings_s``, ``dp_s``, ``ik_path_s``.
        rows: the IK rows' offsets [rad]; ``feasible``: (k, rows) bool.
        reference: today's joint angles, the posture the offsets are measured from (what
            :func:`check_posture` measures the rotation against); ``None`` on a fallback.
        rate_bound: the rate bound the posture was chosen under [rad/m].
    """

    kinematics: PathKinematics
    offset: np.ndarray
    stations: np.ndarray
    station_offset: np.ndarray
    weight: np.ndarray
    ceiling_today: np.ndarray
    ceiling_chosen: np.ndarray
    time_today: float
    time_chosen: float
    rate_max: float
    fallback: str = ""
    wall_times: dict[str, float] = field(default_factory=dict)
    rows: np.ndarray = field(default_factory=lambda: np.zeros(0))
    feasible: np.ndarray = field(default_factory=lambda: np.zeros((0, 0), bool))
    reference: PathKinematics | None = None
    rate_bound: float = math.inf

    @property
    def gain(self) -> float:
        """1 − time_chosen / time_today: the share of the DP's cut-time estimate saved [-]."""
        return 0.0 if self.time_today <= 0 else 1.0 - self.time_chosen / self.time_today


@dataclass(frozen=True)
class PostureCheck:
    """What :func:`check_posture` found (every list empty: the posture holds).

    Attributes:
        rate_max: largest |Δψ / Δs| between neighbouring samples [rad/m].
        jumps: samples where a joint moved more than :data:`planner.ik.JUMP_TOL`.
        rate_violations: samples where |Δψ| > rate × Δs (+ tolerance).
        limit_violations: samples outside the joint limits.
        wrist_flips: samples where A5 changes sign.
    """

    rate_max: float
    jumps: list[int]
    rate_violations: list[int]
    limit_violations: list[int]
    wrist_flips: list[int]

    @property
    def ok(self) -> bool:
        return not (self.jumps or self.rate_violations or self.limit_violations or self.wrist_flips)


def on_a6_axis(prep: Prepared) -> bool:
    """True when the tool axis is the A6 axis (flange x), the TCP on it and the spindle's centre
    of mass too: the rotation about the tool axis is then A6 alone, and no ceiling depends on it
    (the point model sees the TCP's position Jacobian and the spindle as a point mass)."""
    tool = prep.job.tool_frame()
    com = model_parameters(prep.job, prep).spindle_com
    axis = tool[:3, 0]
    return bool(np.linalg.norm(np.cross(axis, [1.0, 0.0, 0.0])) < ON_AXIS_TOL
                and np.linalg.norm(tool[1:3, 3]) < ON_AXIS_TOL
                and np.linalg.norm(np.asarray(com, float)[1:3]) < ON_AXIS_TOL)


def _rx(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _stations(s: np.ndarray, step: float) -> np.ndarray:
    """Sample indices at least ``step`` [m] of path apart; the first and the last sample."""
    out = [0]
    last = s[0]
    for i in range(1, s.size):
        if s[i] - last >= step - 1e-12:
            out.append(i)
            last = s[i]
    if out[-1] != s.size - 1:
        out.append(s.size - 1)
    return np.asarray(out, int)


def _wrist(q: np.ndarray) -> float:
    return float(np.sign(q[4]))


def _good(solver: _Solver, q: np.ndarray, ep: float, er: float, seed: np.ndarray,
          wrist: float) -> bool:
    return (ep < CONVERGED_POSITION and er < CONVERGED_AXIS and solver.within_limits(q) is None
            and float(np.max(np.abs(q - seed))) < JUMP_TOL and _wrist(q) == wrist)


def _rotations(solver: _Solver, q: np.ndarray) -> np.ndarray:
    """TCP rotations of joint rows ``q`` (n, nq), (n, 3, 3)."""
    import pinocchio as pin

    out = np.empty((q.shape[0], 3, 3))
    for i in range(q.shape[0]):
        pin.framesForwardKinematics(solver.model, solver.data, q[i])
        out[i] = solver.data.oMf[solver.fid].rotation
    return out


def tool_rotation_offsets(prep: Prepared, kin: PathKinematics, reference: PathKinematics
                          ) -> np.ndarray:
    """ψ of ``kin`` relative to ``reference`` per sample [rad], (n,): the angle about the tool
    axis from the reference's TCP y axis to ``kin``'s."""
    solver = _Solver(prep.robot, prep.job.tool_frame(), IKOptions())
    r0 = _rotations(solver, reference.q)
    r1 = _rotations(solver, kin.q)
    y0, z0, y1 = r0[:, :, 1], r0[:, :, 2], r1[:, :, 1]
    return np.arctan2(np.einsum("ij,ij->i", y1, z0), np.einsum("ij,ij->i", y1, y0))


def _rows(solver: _Solver, prep: Prepared, st: np.ndarray, rows: np.ndarray,
          r0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """IK of every (station, row): joints (k, r, nq) and feasibility (k, r)."""
    kin = prep.kinematics
    pos = prep.path.position
    k, r = st.size, rows.size
    q = np.zeros((k, r, prep.robot.nq))
    ok = np.zeros((k, r), bool)
    zero = int(np.argmin(np.abs(rows)))
    # outward from today's row: each row leans on the one nearer today's at the same station
    order = [zero] + [j for d in range(1, r) for j in (zero + d, zero - d) if 0 <= j < r]
    inner = {j: (j - 1 if j > zero else j + 1) for j in order[1:]}
    turns = [_rx(a) for a in rows]
    for a in range(k):
        i = int(st[a])
        q[a, zero] = kin.q[i]
        wrist = _wrist(kin.q[i])
        ok[a, zero] = bool(kin.reachable[i])
        for j in order[1:]:
            seeds = []
            if a > 0 and ok[a - 1, j]:
                seeds.append(q[a - 1, j])
            if ok[a, inner[j]]:
                seeds.append(q[a, inner[j]])
            target = r0[a] @ turns[j]
            for seed in seeds:
                qj, ep, er, _ = solver.solve(seed, pos[i], target[:, 0], rot=target)
                if _good(solver, qj, ep, er, seed, wrist):
                    q[a, j], ok[a, j] = qj, True
                    break
                q[a, j] = qj
    return q, ok


def _ceiling_table(prep: Prepared, q: np.ndarray, ok: np.ndarray, rep: np.ndarray,
                   rows: np.ndarray, threads: int) -> np.ndarray:
    """Capped feed ceilings per (station, row) [m/s]; NaN where the station stands for no cut
    (``rep`` < 0), the row is infeasible, or a limit breaks even at feed_min (but today's row)."""
    base = PathModel(prep, threads=threads)
    k, r = ok.shape
    out = np.full((k, r), np.nan)
    pos = np.full(len(prep.path), -1)
    pos[base.index] = np.arange(len(base))
    cols = pos[np.maximum(rep, 0)]
    use = ok & (rep >= 0)[:, None] & (cols >= 0)[:, None]
    aa, jj = np.nonzero(use)
    if aa.size == 0:
        return out
    m = copy.copy(base)
    m._maps = base._maps  # share the mapped Functions
    kk = cols[aa]
    m.index = base.index[kk]
    m.q = q[aa, jj].T.copy()
    m.cut = base.cut[:, kk]
    m.radial_dir = base.radial_dir[kk]
    m._floquet_rho = None
    m.previous = np.full(kk.size, -1)  # rows are no path: no change of δ along a LIN
    m.progress = False
    ceil = m.ceilings(rtol=SEARCH_RTOL)
    lim = base.limits
    caps = np.minimum(cam_feed_caps(prep.path, base.index[kk], lim),
                      tool_feed_cap(prep.tool, prep.job.to_si().spindle_speed))
    capped = np.minimum(ceil.feed, caps)
    # a pose where a limit breaks even at feed_min is no choice (today's stays: the plan says so)
    zero = int(np.argmin(np.abs(rows)))
    out[aa, jj] = np.where((ceil.floor_violation != "") & (jj != zero), np.nan, capped)
    return out


def _dp(cost: np.ndarray, feasible: np.ndarray, moves: np.ndarray,
        change: np.ndarray) -> np.ndarray:
    """Viterbi over stations × states: min Σ cost + change·|step|, |step| ≤ moves[k] between
    station k−1 and k. Returns the state per station."""
    k, g = cost.shape
    big = np.inf
    val = np.where(feasible[0], cost[0], big)
    if not np.any(np.isfinite(val)):
        raise RuntimeError("no feasible posture at the first station")
    back = np.zeros((k, g), np.int32)
    idx = np.arange(g)
    for a in range(1, k):
        mv = int(min(moves[a], g - 1))
        best = val.copy()
        arg = idx.copy()
        for d in range(1, mv + 1):
            c = change[a] * d
            # from j - d
            cand = np.full(g, big)
            cand[d:] = val[:-d] + c
            better = cand < best
            best[better], arg[better] = cand[better], idx[better] - d
            cand = np.full(g, big)
            cand[:-d] = val[d:] + c
            better = cand < best
            best[better], arg[better] = cand[better], idx[better] + d
        val = np.where(feasible[a], best + cost[a], big)
        back[a] = arg
        if not np.any(np.isfinite(val)):
            raise RuntimeError(f"no feasible posture at station {a}")
    out = np.zeros(k, int)
    out[-1] = int(np.argmin(val))
    for a in range(k - 1, 0, -1):
        out[a - 1] = back[a, out[a]]
    return out


def _solve_samples(solver: _Solver, prep: Prepared, r0: np.ndarray, offset: np.ndarray,
                   q_first: np.ndarray) -> tuple[np.ndarray, np.ndarray, list, np.ndarray]:
    """IK of every sample at today's rotation turned by ``offset``; each solve seeded from the
    sample before, extrapolated along the last step (one LM iteration fewer on dense paths).
    Returns the joints, whether each sample holds, why not, and the (position [m], rotation
    [rad]) errors, (n, 2)."""
    kin = prep.kinematics
    pos = prep.path.position
    s = prep.path.s
    n = pos.shape[0]
    q_out = np.zeros_like(kin.q)
    ok = np.zeros(n, bool)
    why: list = [None] * n
    err = np.column_stack([kin.position_error, kin.axis_error]).astype(float)
    q = q_first
    step = np.zeros_like(q)  # the last step's joint change per metre of path
    for i in range(n):
        if offset[i] == 0.0:
            qi, good = kin.q[i], bool(kin.reachable[i])
            good = good and float(np.max(np.abs(qi - q))) < JUMP_TOL
        else:
            target = r0[i] @ _rx(float(offset[i]))
            ds = s[i] - s[i - 1] if i else 0.0
            qi, ep, er, _ = solver.solve(q + step * ds, pos[i], target[:, 0], rot=target)
            good = _good(solver, qi, ep, er, q, _wrist(kin.q[i]))
            if not good and ds > 0.0:  # the plain seed, should the extrapolation mislead
                qi, ep, er, _ = solver.solve(q, pos[i], target[:, 0], rot=target)
                good = _good(solver, qi, ep, er, q, _wrist(kin.q[i]))
            if not good:
                why[i] = (solver.within_limits(qi) or "reach") if ep < CONVERGED_POSITION \
                    else "reach"
            err[i] = ep, er
        q_out[i], ok[i] = qi, good
        if good:
            ds = s[i] - s[i - 1] if i else 0.0
            step = (qi - q) / ds if ds > EXTRAPOLATE_MIN_STEP else np.zeros_like(q)
            q = qi
        else:
            step = np.zeros_like(q)
    return q_out, ok, why, err


def choose_posture(prep: Prepared, options: PostureOptions | None = None) -> Posture:
    """The posture of the whole path (module docstring); ``prep.kinematics`` is today's.

    Returns:
        :class:`Posture`; apply it with :func:`apply_posture`.
    """
    opt = options or PostureOptions()
    walls: dict[str, float] = {}
    kin = prep.kinematics
    path = prep.path
    n = len(path)
    if opt.skip_on_axis and on_a6_axis(prep):
        z = np.zeros(0)
        return Posture(kinematics=kin, offset=np.zeros(n), stations=np.zeros(0, int),
                       station_offset=z, weight=z, ceiling_today=z, ceiling_chosen=z,
                       time_today=0.0, time_chosen=0.0, rate_max=0.0,
                       fallback="the tool axis and the spindle are on the A6 axis: turning about "
                                "the tool axis moves A6 alone and changes no ceiling; today's "
                                "posture kept")
    # the full rotation leaves no null space: no joint-limit push (it would fight the task)
    solver = _Solver(prep.robot, prep.job.tool_frame(),
                     IKOptions(limit_gain=0.0, max_iterations=ROW_ITERATIONS))
    t = time.perf_counter()
    st = _stations(path.s, opt.station_mm * 1e-3)
    k = st.size
    step = math.radians(opt.ik_step_deg)
    span = math.radians(opt.span_deg)
    top = int(math.floor(span / step + 1e-9))
    if top * step >= math.pi - 1e-9:
        top -= 1  # ±180 deg would be the same rotation twice
    rows = step * np.arange(-top, top + 1)
    r0 = _rotations(solver, kin.q)
    q_rows, ok = _rows(solver, prep, st, rows, r0[st])
    walls["ik_rows_s"] = time.perf_counter() - t

    # the cut each station stands for: engaged samples in [station, next station)
    t = time.perf_counter()
    e = prep.engagement
    engaged = engaged_samples(path.s, path.cutting & (e.mode >= 0) & kin.reachable)
    ds = np.diff(path.s, prepend=path.s[0])
    bounds = np.append(st, n)
    weight = np.zeros(k)
    rep = np.full(k, -1)
    for a in range(k):
        sl = slice(bounds[a], bounds[a + 1])
        w = ds[sl] * engaged[sl]
        weight[a] = float(w.sum())
        hit = np.flatnonzero(engaged[sl])
        if hit.size:
            rep[a] = bounds[a] + int(hit[0])
    ceiling = _ceiling_table(prep, q_rows, ok, rep, rows, opt.threads)
    walls["ceilings_s"] = time.perf_counter() - t

    # the DP's fine grid: rate × station step apart, costs interpolated between the rows
    t = time.perf_counter()
    h = math.radians(opt.rate_deg_per_mm) * opt.station_mm
    sub = max(1, int(math.ceil(step / h - 1e-9)))  # the DP step: at most rate × station
    h = step / sub
    grid = rows[0] + h * np.arange((rows.size - 1) * sub + 1)
    lo = np.minimum(np.arange(grid.size) // sub, rows.size - 1)
    hi = np.minimum(lo + 1, rows.size - 1)
    frac = (grid - rows[lo]) / step
    frac[lo == hi] = 0.0
    inv = np.where(np.isfinite(ceiling), 1.0 / np.where(np.isfinite(ceiling), ceiling, 1.0), 0.0)
    on_row = frac < 1e-9
    feas = ok[:, lo] & (ok[:, hi] | on_row[None, :])
    cut = weight > 0
    feas_cut = feas & (~cut[:, None] | (np.isfinite(ceiling[:, lo])
                                        & (np.isfinite(ceiling[:, hi]) | on_row[None, :])))
    cost = weight[:, None] * ((1.0 - frac) * inv[:, lo] + frac * inv[:, hi])
    moves = np.zeros(k, int)
    dst = np.diff(path.s[st])
    moves[1:] = np.floor(math.radians(opt.rate_deg_per_mm) * 1e3 * dst / h + 1e-9).astype(int)
    scale = float(np.sum(weight * np.nan_to_num(inv[:, int(np.argmin(np.abs(rows)))])))
    change = np.full(k, opt.change_cost * max(scale, 1e-9) / max(k, 1))
    # of equal postures the one nearest today's (a constant turn that gains nothing is no choice)
    tie = TIE_COST * max(scale, 1e-9) / max(k, 1) * np.abs(grid)[None, :] / math.pi
    state = _dp(cost + tie, feas_cut, moves, change)
    station_offset = grid[state]
    walls["dp_s"] = time.perf_counter() - t

    zero_row = int(np.argmin(np.abs(rows)))
    with np.errstate(divide="ignore", invalid="ignore"):
        c_today = np.where(cut, ceiling[:, zero_row], np.nan)
        c_inv = np.where(cut, cost[np.arange(k), state] / np.where(cut, weight, 1.0), np.nan)
        c_chosen = 1.0 / c_inv
    time_today = float(np.nansum(weight / c_today))
    time_chosen = float(np.nansum(weight * c_inv))

    # every sample: the offset interpolated in s, then one seeded solve per sample
    t = time.perf_counter()
    offset = np.interp(path.s, path.s[st], station_offset)
    offset[np.abs(offset) < 1e-12] = 0.0
    near = np.flatnonzero(ok[0])
    r = int(near[np.argmin(np.abs(rows[near] - station_offset[0]))])
    q_all, good, why, err = _solve_samples(solver, prep, r0, offset, q_rows[0, r])
    walls["ik_path_s"] = time.perf_counter() - t
    with np.errstate(divide="ignore", invalid="ignore"):
        rate = np.abs(np.diff(offset)) / np.diff(path.s)
    rate_max = float(np.max(rate[np.isfinite(rate)], initial=0.0))
    fallback = ""
    bad = np.flatnonzero(~good & kin.reachable)
    if bad.size:
        i = int(bad[0])
        fallback = (f"sample {i} ({path.where(i)}) cannot be reached with the chosen posture "
                    f"({why[i]}); today's posture kept")
        new_kin = kin
        offset = np.zeros(n)
        c_chosen, time_chosen = c_today, time_today
    else:
        jumps = (np.flatnonzero(np.max(np.abs(np.diff(q_all, axis=0)), axis=1) > JUMP_TOL) + 1
                 if n > 1 else np.zeros(0, int))
        new_kin = replace(kin, q=q_all, jumps=jumps, position_error=err[:, 0],
                          axis_error=err[:, 1])
    return Posture(kinematics=new_kin, offset=offset, stations=st, station_offset=station_offset,
                   weight=weight, ceiling_today=c_today, ceiling_chosen=c_chosen,
                   time_today=time_today, time_chosen=time_chosen, rate_max=rate_max,
                   fallback=fallback, wall_times=walls, rows=rows, feasible=ok,
                   reference=None if fallback else kin,
                   rate_bound=math.radians(opt.rate_deg_per_mm) * 1e3)


def apply_posture(prep: Prepared, posture: Posture) -> Prepared:
    """``prep`` with the posture's joint angles (the engagement does not depend on them)."""
    walls = {**prep.wall_times, **{f"posture_{k}": v for k, v in posture.wall_times.items()}}
    return replace(prep, kinematics=posture.kinematics, wall_times=walls, posture=posture)


def check_posture(prep: Prepared, offset: np.ndarray | None = None,
                  rate_deg_per_mm: float | None = None, rate_tol: float = RATE_TOL) -> PostureCheck:
    """Check the posture of a prepared job on its own: continuity (no joint jumps, no wrist
    flips), joint limits, and |Δψ| ≤ rate × Δs at every sample.

    Args:
        prep: the prepared job (its kinematics are checked).
        offset: ψ − ψ_today per sample [rad]; default: *measured* from the joint angles against
            the posture's reference (``prep.posture.reference``, :func:`tool_rotation_offsets`),
            when ``prep`` has a path posture; else the rate is not checked.
        rate_deg_per_mm: the bound [deg/mm]; default the posture's (``prep.posture.rate_bound``).
        rate_tol: slack of the rate check [rad].
    """
    posture = getattr(prep, "posture", None)
    if offset is None and posture is not None and posture.reference is not None:
        offset = np.unwrap(tool_rotation_offsets(prep, prep.kinematics, posture.reference))
    if rate_deg_per_mm is None and posture is not None and math.isfinite(posture.rate_bound):
        rate_deg_per_mm = math.degrees(posture.rate_bound) * 1e-3
    kin = prep.kinematics
    q = kin.q[kin.reachable]
    idx = np.flatnonzero(kin.reachable)
    lo, hi = prep.robot.data.lower, prep.robot.data.upper
    limit = idx[np.any((q < lo - 1e-9) | (q > hi + 1e-9), axis=1)].tolist()
    dq = np.max(np.abs(np.diff(q, axis=0)), axis=1) if q.shape[0] > 1 else np.zeros(0)
    jumps = (idx[1:][dq > JUMP_TOL]).tolist()
    flips = (idx[1:][np.sign(q[1:, 4]) * np.sign(q[:-1, 4]) < 0]).tolist()
    rate_bad: list[int] = []
    rate_max = 0.0
    if offset is not None:
        ds = np.diff(prep.path.s)
        d = np.abs(np.diff(offset))
        with np.errstate(divide="ignore", invalid="ignore"):
            r = d / ds
        rate_max = float(np.max(r[np.isfinite(r)], initial=0.0))
        if rate_deg_per_mm is not None:
            bound = math.radians(rate_deg_per_mm) * 1e3 * ds + rate_tol
            rate_bad = (np.flatnonzero(d > bound) + 1).tolist()
    return PostureCheck(rate_max=rate_max, jumps=jumps, rate_violations=rate_bad,
                        limit_violations=limit, wrist_flips=flips)


def posture_by_section(posture: Posture, sections) -> list[dict]:
    """Per section (anything with ``start``/``stop`` sample indices, e.g. the plan's sections):
    the chosen offset (mean, min, max [deg]) and the DP's estimate of the cut time today and with
    the chosen posture [s] and the gain [-] (stations inside the section)."""
    st = posture.stations
    off = np.degrees(posture.offset)
    out = []
    for sec in sections:
        a, b = int(sec.start), int(sec.stop)
        inside = (st >= a) & (st < b) & (posture.weight > 0)
        t0 = float(np.nansum(posture.weight[inside] / posture.ceiling_today[inside]))
        t1 = float(np.nansum(posture.weight[inside] / posture.ceiling_chosen[inside]))
        seg = off[a:b]
        out.append({"sample_start": a, "sample_stop": b,
                    "offset_deg_mean": float(seg.mean()) if seg.size else 0.0,
                    "offset_deg_min": float(seg.min()) if seg.size else 0.0,
                    "offset_deg_max": float(seg.max()) if seg.size else 0.0,
                    "time_today_s": t0, "time_chosen_s": t1,
                    "gain": 0.0 if t0 <= 0 else 1.0 - t1 / t0})
    return out
