"""Inverse kinematics along the path, using the free rotation about the tool axis.

Milling fixes five of the TCP's six degrees of freedom: its position and the direction of the tool
axis. The rotation about the tool axis is free (docs/model.md §8). Each sample is solved by damped least
squares (Levenberg–Marquardt) on that 5-D task with pinocchio's Jacobian, seeded from the previous
sample — so the solution is continuous and never flips configuration — while the null space of the
task (the free rotation, plus any slack) pushes joints away from their limits.

The first sample is seeded from the job's ``seed_joints_deg`` if given, else from a small set of
elbow-up/wrist-tilted configurations facing the target; optionally (``choose_for_stiffness``) the
free rotation at the first sample is chosen to maximise the smallest translational stiffness.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from models.errors import UnreachablePoseError
from models.robot import Robot
from planner._progress import bar
from planner.path import PathSamples

__all__ = ["IKOptions", "PathKinematics", "solve_path"]

#: Position tolerance of a converged IK solution [m] (far below machining tolerances).
POSITION_TOL = 1e-7
#: Tool-axis direction tolerance [rad].
AXIS_TOL = 1e-7
#: Length [m] that weighs the orientation rows against the position rows (about the wrist-to-TCP
#: distance, so that 1 rad of axis error counts like 0.5 m of position error).
ORIENTATION_WEIGHT = 0.5
#: A sample counts as reached when its position [m] and tool-axis [rad] errors are below these
#: (the LM tolerances above are tighter; these allow for a last iteration that stopped short).
CONVERGED_POSITION = 1e-6
CONVERGED_AXIS = 1e-6
#: A joint that moves more than this between neighbouring samples [rad] is reported as a jump
#: (a configuration flip); with seeded solves this should never happen.
JUMP_TOL = math.radians(20.0)
#: The first sample keeps the best (most clearance from joint limits) of this many converged seeds.
FIRST_CANDIDATES = 6
#: Fraction of a joint's range near each limit where the null-space push starts.
LIMIT_MARGIN = 0.1

_EYE3 = np.eye(3)
_EYE6 = np.eye(6)


@dataclass(frozen=True)
class IKOptions:
    """Options of :func:`solve_path`.

    Attributes:
        seed: first-sample seed joints [rad], shape (n,); ``None`` = automatic.
        choose_for_stiffness: pick the free rotation at the first sample for the largest smallest
            translational stiffness (CCT-free, K_θ of the robot).
        tool_rotation: hold the rotation about the tool axis at this angle [rad] (measured from the
            TCP y axis lying in the horizontal plane, see ``_frame_about``) instead of leaving it free.
        max_iterations: LM iterations per sample.
        damping: LM damping λ [-] (relative to the task Jacobian scale).
        limit_gain: null-space gain of the joint-limit push [-].
    """

    seed: np.ndarray | None = None
    choose_for_stiffness: bool = False
    tool_rotation: float | None = None
    max_iterations: int = 60
    damping: float = 1e-4
    limit_gain: float = 0.5


@dataclass(frozen=True)
class PathKinematics:
    """Joint angles along the path and what could not be reached.

    Attributes:
        q: joint angles [rad], shape (n, nq); rows of unreachable samples hold the best attempt.
        reachable: shape (n,), bool.
        position_error: [m], shape (n,).
        axis_error: [rad], shape (n,).
        limiting_joint: per sample, the joint name that stops it (or ``"reach"`` when the position
            is out of the arm's reach, or ``None`` when reachable).
        iterations: LM iterations per sample, shape (n,).
        jumps: sample indices where a joint moved more than :data:`JUMP_TOL` from the previous one.
        joint_names: the joint names.
        problems: one readable line per unreachable stretch (first sample, file:line, joint).
    """

    q: np.ndarray
    reachable: np.ndarray
    position_error: np.ndarray
    axis_error: np.ndarray
    limiting_joint: list
    iterations: np.ndarray
    jumps: np.ndarray
    joint_names: tuple[str, ...]
    problems: list[str] = field(default_factory=list)

    @property
    def all_reachable(self) -> bool:
        """True when every sample is reachable."""
        return bool(np.all(self.reachable))

    def raise_if_unreachable(self) -> None:
        """Raise :class:`UnreachablePoseError` naming the first unreachable sample and its joint."""
        bad = np.flatnonzero(~self.reachable)
        if bad.size:
            i = int(bad[0])
            joint = self.limiting_joint[i]
            more = f" ({len(self.problems) - 1} more stretches)" if len(self.problems) > 1 else ""
            raise UnreachablePoseError(
                self.problems[0] + more + "; move $BASE, change the TCP or the seed",
                joint=None if joint == "reach" else joint, sample=i)


class _Solver:
    def __init__(self, robot: Robot, tool: np.ndarray, options: IKOptions) -> None:
        self.robot = robot
        self.model, self.fid = robot.pin_model(tcp=tool[:3, 3], tcp_rotation=tool[:3, :3])
        self.data = self.model.createData()
        self.lo = robot.data.lower
        self.hi = robot.data.upper
        self.mid = 0.5 * (self.lo + self.hi)
        self.span = self.hi - self.lo
        self.opt = options

    def pose(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        jac = pin.computeFrameJacobian(self.model, self.data, q, self.fid,
                                       pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        pin.updateFramePlacement(self.model, self.data, self.fid)
        m = self.data.oMf[self.fid]
        return m.translation.copy(), m.rotation.copy(), jac

    def _limit_gradient(self, q: np.ndarray) -> np.ndarray:
        """Push away from limits inside the margin band, zero elsewhere."""
        band = LIMIT_MARGIN * self.span
        g = np.zeros_like(q)
        low = q < self.lo + band
        high = q > self.hi - band
        g[low] = (self.lo + band - q)[low] / band[low]
        g[high] = (self.hi - band - q)[high] / band[high]
        return g

    def solve(self, q0: np.ndarray, p: np.ndarray, d: np.ndarray,
              rot: np.ndarray | None = None) -> tuple[np.ndarray, float, float, int]:
        """LM from ``q0`` to TCP position ``p`` with TCP +x along ``d`` (or full rotation ``rot``)."""
        q = q0.copy()
        w = ORIENTATION_WEIGHT
        ep_n = er_n = math.inf
        for it in range(1, self.opt.max_iterations + 1):
            pos, r, jac = self.pose(q)
            x = r[:, 0]
            e_p = p - pos
            if rot is None:
                e_r = _cross(x, d)
                proj = _EYE3 - np.outer(x, x)
                jt = np.vstack([jac[:3], w * proj @ jac[3:]])
            else:
                e_r = 0.5 * (_cross(r[:, 0], rot[:, 0]) + _cross(r[:, 1], rot[:, 1])
                             + _cross(r[:, 2], rot[:, 2]))
                jt = np.vstack([jac[:3], w * jac[3:]])
            ep_n, er_n = float(np.linalg.norm(e_p)), float(np.linalg.norm(e_r))
            if rot is None:
                er_n = float(math.atan2(er_n, float(x @ d)))
            if ep_n < POSITION_TOL and er_n < AXIS_TOL:
                return q, ep_n, er_n, it
            g = self._limit_gradient(q)
            e = np.concatenate([e_p, w * e_r])
            jjt = jt @ jt.T
            lam = self.opt.damping * (np.trace(jjt) / 6.0) + 1e-12
            reg = jjt + lam * _EYE6
            dq = jt.T @ np.linalg.solve(reg, e)
            if g.any():
                pinv = jt.T @ np.linalg.solve(reg, jt)
                dq += self.opt.limit_gain * (np.eye(q.size) - pinv) @ (g * self.span * 0.05)
            step = np.max(np.abs(dq))
            if step > 0.3:  # keep steps small: stay on the seeded branch
                dq *= 0.3 / step
            q = q + dq
        return q, ep_n, er_n, self.opt.max_iterations

    def within_limits(self, q: np.ndarray) -> str | None:
        names = self.robot.data.joint_names
        for i in range(q.size):
            if not self.lo[i] - 1e-9 <= q[i] <= self.hi[i] + 1e-9:
                return names[i]
        return None

    def k_min(self, q: np.ndarray) -> float:
        _, _, jac = self.pose(q)
        c = jac[:3] @ np.diag(1.0 / self.robot.data.joint_stiffness) @ jac[:3].T
        return float(1.0 / np.linalg.eigvalsh(c)[-1])


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """3-vector cross product (np.cross's generality costs ~20 µs a call here)."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2],
                     a[0] * b[1] - a[1] * b[0]])


def _seeds(p: np.ndarray) -> list[np.ndarray]:
    a1 = -math.atan2(p[1], p[0])  # A1 turns the arm towards −Y (docs/model.md §2)
    out = []
    for a2 in (-90.0, -60.0, -120.0, -40.0):
        for a3 in (90.0, 60.0, 120.0, 30.0):
            for a5 in (60.0, -60.0, 90.0, 30.0):
                for a4 in (0.0, 90.0, -90.0):
                    out.append(np.array([a1, math.radians(a2), math.radians(a3), math.radians(a4),
                                         math.radians(a5), 0.0]))
    return out


def _frame_about(d: np.ndarray, psi: float) -> np.ndarray:
    """A rotation with x = d and y turned by ψ about d from a reference ⟂ d."""
    ref = np.array([0.0, 0.0, 1.0]) if abs(d[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    y0 = np.cross(ref, d)
    y0 /= np.linalg.norm(y0)
    z0 = np.cross(d, y0)
    y = math.cos(psi) * y0 + math.sin(psi) * z0
    return np.column_stack([d, y, np.cross(d, y)])


def _first(solver: _Solver, p: np.ndarray, d: np.ndarray, opt: IKOptions) -> np.ndarray:
    seeds = [np.asarray(opt.seed, float)] if opt.seed is not None else []
    seeds += _seeds(p)
    best, best_key = None, None
    found = 0
    for s in seeds:
        if found >= FIRST_CANDIDATES:
            break
        q, ep, er, _ = solver.solve(s, p, d)
        if ep > CONVERGED_POSITION or er > CONVERGED_AXIS or solver.within_limits(q) is not None:
            continue
        # Prefer the given seed, then the configuration farthest from its limits.
        clearance = float(np.min(np.minimum(q - solver.lo, solver.hi - q) / solver.span))
        key = (0 if (opt.seed is not None and s is seeds[0]) else 1, -clearance)
        found += 1
        if best_key is None or key < best_key:
            best, best_key = q, key
        if opt.seed is not None and s is seeds[0]:
            break
    if best is None:
        return seeds[0]
    if opt.choose_for_stiffness:
        cands = []
        for psi in np.radians(np.arange(-180.0, 180.0, 15.0)):
            q, ep, er, _ = solver.solve(best, p, d, rot=_frame_about(d, psi))
            if ep < CONVERGED_POSITION and er < CONVERGED_AXIS and solver.within_limits(q) is None:
                cands.append((solver.k_min(q), q))
        if cands:
            best = max(cands, key=lambda c: c[0])[1]
    return best


def solve_path(robot: Robot, path: PathSamples, tool: np.ndarray,
               options: IKOptions | None = None, progress: bool = False) -> PathKinematics:
    """Joint angles for every path sample.

    Args:
        robot: the robot.
        path: the samples (TCP positions and tool axes in the robot base).
        tool: ``$TOOL`` 4×4 (TCP in the flange frame, SI); the tool axis is the TCP's +x.
        options: solver options.
        progress: show a progress bar on stderr (long paths).

    Returns:
        :class:`PathKinematics` (never raises for unreachable samples: call
        :meth:`PathKinematics.raise_if_unreachable` to make that an error).
    """
    opt = options or IKOptions()
    solver = _Solver(robot, np.asarray(tool, float), opt)
    n = len(path)
    nq = robot.nq
    q_out = np.zeros((n, nq))
    ok = np.zeros(n, bool)
    ep_out = np.zeros(n)
    er_out = np.zeros(n)
    its = np.zeros(n, int)
    limiting: list = [None] * n
    direction = -path.tool_axis  # TCP +x points from the spindle to the tip
    q = _first(solver, path.position[0], direction[0], opt)
    if opt.tool_rotation is not None:
        q, *_ = solver.solve(q, path.position[0], direction[0],
                             rot=_frame_about(direction[0], opt.tool_rotation))
    pbar = bar(n, "inverse kinematics", progress)
    for i in range(n):
        if i % 256 == 0:
            pbar.update(min(256, n - i))
        rot = (None if opt.tool_rotation is None
               else _frame_about(direction[i], opt.tool_rotation))
        q_new, ep, er, it = solver.solve(q, path.position[i], direction[i], rot=rot)
        converged = ep < CONVERGED_POSITION and er < CONVERGED_AXIS
        joint = solver.within_limits(q_new)
        good = converged and joint is None
        q_out[i], ep_out[i], er_out[i], its[i], ok[i] = q_new, ep, er, it, good
        if not good:
            # The solve does not clamp joints: a converged pose outside the limits names its joint;
            # a pose the arm cannot reach at all (even ignoring limits) is "reach".
            limiting[i] = joint if converged else "reach"
        else:
            q = q_new
    pbar.close()
    jumps = np.flatnonzero(np.max(np.abs(np.diff(q_out, axis=0)), axis=1) > JUMP_TOL) + 1 \
        if n > 1 else np.zeros(0, int)
    problems = []
    bad = np.flatnonzero(~ok)
    if bad.size:
        starts = [int(bad[0])] + [int(b) for a, b in zip(bad[:-1], bad[1:], strict=True)
                                  if b != a + 1]
        for i in starts:
            end = i
            while end + 1 < n and not ok[end + 1]:
                end += 1
            j = limiting[i]
            why = ("out of the arm's reach" if j == "reach" else
                   f"{j} would be at {math.degrees(q_out[i][robot.data.joint_names.index(j)]):.1f}"
                   " deg, outside its limits")
            problems.append(f"samples {i}..{end} ({path.where(i)}, s = {path.s[i]:.4f} m): {why}")
    return PathKinematics(q=q_out, reachable=ok, position_error=ep_out, axis_error=er_out,
                          limiting_joint=limiting, iterations=its, jumps=jumps,
                          joint_names=robot.data.joint_names, problems=problems)
