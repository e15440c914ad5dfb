"""Online deflection compensation through RSI ``RKorr`` (thesis Chapter 4; docs/compensation.md).

Every cycle, :meth:`DeflectionCompensator.step` turns the measured mean cutting force and the
current joints into the Cartesian correction the RSI server sends
(:meth:`robot_io.links.rsi.RsiServer.set_correction`):

1. **engagement estimate**: the in-plane angle θ = atan2(F̄_zo, F̄_xo) of the mean force in the
   cut frame depends on the radial depth a_e only (the axial depth cancels, the feed per tooth is
   known), so a_e is solved from it (:func:`models.deflection.estimate_radial_depth`; here with θ
   tabulated over a_e and the feed per tooth once, :meth:`DeflectionCompensator.prepare`, so that
   a cycle costs a table look-up, not a root solve, whatever the override does to the feed);
2. **deflection**: δ = C_tt(q, F)·F with the model's compliance at the current pose (CCT), F the
   model's mean force at the estimated a_e (``force="engagement"``, the thesis's route: insensitive
   to a gain error of the force signal) or the measured force itself (``force="measured"``);
   when no a_e explains the measured angle, the measured force is used and the status says so;
3. **correction**: the commanded TCP must move by −δ; a path already mirror-compensated offline
   (``cctmill export --compensate-deflection``) moved by −δ_plan, so the online part is
   −(δ − δ_plan) (``offline_delta``). Expressed in the base or the tool (TCP) frame, the total is
   rate-limited (``max_rate_mm_s``, on its norm) and clamped per component (±5 mm / ±5° by
   default, KUKA's example POSCORR limits; orientation corrections are zero: δ is translational).

With ``RSI_ON(#RELATIVE)`` (what the KRL export writes) the controller adds every received
correction, so :attr:`CompensationResult.increment` (this cycle's change of the total) is what
the server is given; ``#ABSOLUTE`` takes :attr:`CompensationResult.total`.

The step never raises (ruckig's ``Result``): a NaN or missing force or joint value, an unknown
cut, or any internal failure holds the last total (zero increment) and returns a status saying
why. Below ``min_force_N`` the tool is taken as out of the cut: δ = 0 (the correction returns to
zero online, to +δ_plan on a mirror-compensated path) at the rate limit.

:class:`PlanCompensation` drives it along a plan inside the supervisor loop (``run_loop(on_cycle=…)``,
``cctmill supervise --compensate-rkorr``): joints, cut and planned δ from the plan's sample at the
dead-reckoned arc length, the correction to the link. Its model is the job's
(:func:`job_parameters`: the ``[cell] joint_stiffness_scale`` and ``[calibration]`` cutting
coefficients a calibration overlay sets), not the robot and material files' as shipped: the
compensation must use the calibrated model the plan's offline δ was computed with.
docs/compensation.md has the benchmark.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field

import numpy as np

from models import cutting
from models.analysis import CUT_LAYOUT, ModelParameters, point_function
from models.deflection import deflection_of_force, inplane_force_angles
from models.errors import InputError
from models.robot import Robot

__all__ = [
    "COMPENSATION_FORCES",
    "COMPENSATION_FRAMES",
    "CompensationConfig",
    "CompensationResult",
    "CompensationStatus",
    "DeflectionCompensator",
    "PlanCompensation",
    "job_parameters",
]

#: Frames a correction may be expressed in (the RSI POSCORR object's ``RefCorrSys``).
COMPENSATION_FRAMES = ("base", "tool")
#: Which force δ is computed from.
COMPENSATION_FORCES = ("engagement", "measured")
#: Grid of the tabulated force angle θ(a_e) [-]: from this fraction of R to 2R, this many points
#: (a 0.06 mm step for the 25.4 mm tool; θ is smooth, linear interpolation is sub-µm in a_e).
_GRID_MIN_FRACTION = 1e-3
_GRID_POINTS = 400
#: Feeds per tooth of the θ table, relative to the planned one [-], and how many (log-spaced: a
#: 7 % step; θ is smooth in c, the interpolation error is far below the noise of the angle).
_C_RANGE = (0.05, 1.25)
_C_POINTS = 48
_MM = 1e3
_MODE_NAMES = {int(v): k for k, v in cutting.MILLING_MODES.items()}


class CompensationStatus(enum.StrEnum):
    """What a compensation step did (a ``str``)."""

    OK = "ok"                      # δ from the estimated engagement (or the measured force)
    FALLBACK = "fallback"          # no a_e explains the force angle: δ from the measured force
    NOT_CUTTING = "not_cutting"    # force under min_force_N: δ = 0
    RATE_LIMITED = "rate_limited"  # the total moved by the rate limit, not to the target
    CLAMPED = "clamped"            # the target lies outside the bounds: the total is at a bound
    INVALID = "invalid"            # bad input (NaN force, joints, feed; no cut): total held
    ERROR = "error"                # internal failure: total held


@dataclass(frozen=True)
class CompensationConfig:
    """Tuning of the online compensation.

    Attributes:
        cycle_s: the controller cycle, one step a cycle [s] (0.004 KR C4 ``#IPO_FAST``, 0.012).
        max_position_mm: bound of each translational component of the total [mm] (KUKA ±5 mm).
        max_orientation_deg: bound of each rotational component [deg] (KUKA ±5°).
        max_rate_mm_s: largest speed of the total's translation [mm/s]: 10 mm/s is 0.04 mm a 4 ms
            cycle, so a deflection (tenths of a mm) is followed within tens of ms while the full
            ±5 mm range takes half a second — a wrong estimate cannot throw the tool.
        frame: ``"base"`` (the robot base axes, or ``$BASE``'s when the compensator is given its
            rotation) or ``"tool"`` (the TCP frame of the current pose).
        mode: ``"relative"`` (``RSI_ON(#RELATIVE)``) or ``"absolute"``: informs the caller which of
            :attr:`CompensationResult.increment` / ``total`` to send.
        force: ``"engagement"`` (δ from the model's force at the estimated a_e) or ``"measured"``.
        min_force_N: in-plane mean force under which the tool is taken as not cutting [N].
    """

    cycle_s: float = 0.004
    max_position_mm: float = 5.0
    max_orientation_deg: float = 5.0
    max_rate_mm_s: float = 10.0
    frame: str = "base"
    mode: str = "relative"
    force: str = "engagement"
    min_force_N: float = 5.0

    def __post_init__(self) -> None:
        if self.frame not in COMPENSATION_FRAMES:
            raise InputError("compensation frame",
                             f"{self.frame!r}: use one of {', '.join(COMPENSATION_FRAMES)}")
        if self.mode not in ("relative", "absolute"):
            raise InputError("compensation mode", f"{self.mode!r}: use relative or absolute")
        if self.force not in COMPENSATION_FORCES:
            raise InputError("compensation force",
                             f"{self.force!r}: use one of {', '.join(COMPENSATION_FORCES)}")
        for name in ("cycle_s", "max_position_mm", "max_orientation_deg", "max_rate_mm_s"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise InputError(name, f"must be a positive number, got {v!r}")
        if not (math.isfinite(self.min_force_N) and self.min_force_N >= 0):
            raise InputError("min_force_N", f"must be a non-negative number, got {self.min_force_N!r}")


@dataclass(frozen=True)
class CompensationResult:
    """One step's answer.

    Attributes:
        status: what the step did; reason: the same in words.
        total: the correction the controller should hold after this cycle, (X, Y, Z [mm], A, B, C
            [deg]) in the configured frame.
        increment: ``total`` minus the previous total (what ``#RELATIVE`` takes), same units.
        delta: the estimated deflection δ [m], base axes, shape (3,) (NaN when not computed).
        a_e: the estimated radial depth [m] (NaN when not estimated).
        force: the force δ was computed from [N], base axes, shape (3,).
    """

    status: CompensationStatus
    reason: str
    total: tuple[float, ...]
    increment: tuple[float, ...]
    delta: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    a_e: float = math.nan
    force: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))


class DeflectionCompensator:
    """Per-cycle RKorr correction from the measured mean force (see the module docstring).

    Args:
        robot, params: the model (its joint stiffness, TCP, cutting coefficients, CCT switch).
        cut: the planned cut at the current point, a :meth:`models.analysis.Cut.vector` (12,):
            cut frame, planned a_e (the estimate's prior), a_p, mode, spindle speed, tool;
            :meth:`set_cut` changes it (a new section); ``step(cut=…)`` for one step.
        config: limits, frame, mode.
        base_rotation: the ``$BASE`` frame's rotation in robot base axes (3, 3): a ``"base"``
            correction is then given in ``$BASE`` axes (POSCORR ``RefCorrSys`` #BASE); ``None``: in
            the robot's base axes. Inputs (force, δ) are in robot base axes either way.
    """

    def __init__(self, robot: Robot, params: ModelParameters, cut: np.ndarray,
                 config: CompensationConfig | None = None, base_rotation: np.ndarray | None = None) -> None:
        self.robot = robot
        rot = None if base_rotation is None else np.asarray(base_rotation, float).reshape(3, 3)
        if rot is not None and not np.allclose(rot @ rot.T, np.eye(3), atol=1e-6):
            raise InputError("base_rotation", "must be a rotation matrix")
        self._base_rot = rot
        self.config = config or CompensationConfig()
        self._params = np.asarray(params.vector(), float)
        self._tcp = np.asarray(params.tcp, float).reshape(3)
        self._coeffs = np.asarray(params.coefficients, float).reshape(6)
        self._point = point_function(robot, "oriented", "isotropic", outputs=("deflection", "force_base"))
        self._of_force = deflection_of_force(robot)
        self._pose = robot.pose_function
        self._total = np.zeros(6)
        self._table_key: tuple[float, ...] | None = None
        self._grid = np.zeros(0)
        self._theta = np.zeros((0, 0))
        self._logc = np.zeros(0)
        self._cut = self._check_cut(cut)
        c = self.config
        self._step_mm = c.max_rate_mm_s * c.cycle_s
        self._bounds = np.array([c.max_position_mm] * 3 + [c.max_orientation_deg] * 3)

    # -- state ---------------------------------------------------------------------------------
    @property
    def total(self) -> tuple[float, ...]:
        """The correction total so far (X, Y, Z [mm], A, B, C [deg])."""
        return tuple(float(v) for v in self._total)

    def reset(self) -> None:
        """Forget the total (a new RSI context starts from zero correction)."""
        self._total = np.zeros(6)

    def rollback(self, res: CompensationResult) -> None:
        """Undo ``res`` (the last step's result): its correction did not reach the controller, so
        the total goes back to what the controller holds."""
        self._total = np.asarray(res.total, float) - np.asarray(res.increment, float)

    def set_cut(self, cut: np.ndarray) -> None:
        """The planned cut from now on (raises :class:`InputError` on a bad vector: call it outside
        the loop, or pass ``cut=`` to :meth:`step`, which never raises)."""
        self._cut = self._check_cut(cut)

    @staticmethod
    def _check_cut(cut: np.ndarray) -> np.ndarray:
        v = np.asarray(cut, float).reshape(-1)
        if v.shape != (12,) or not np.all(np.isfinite(v)):
            raise InputError("cut", "need a Cut.vector() of 12 finite numbers")
        if not (np.linalg.norm(v[0:3]) > 0 and np.linalg.norm(v[3:6]) > 0 and np.all(v[6:8] > 0)
                and v[9] > 0 and v[10] >= 1 and v[11] > 0):
            raise InputError("cut", "need non-zero feed and radial directions and positive a_e, a_p, "
                                    "spindle speed, flutes and radius")
        mode = int(round(v[CUT_LAYOUT["mode"][0]]))
        if mode not in (cutting.MILLING_MODES["up"], cutting.MILLING_MODES["down"]):
            raise InputError("cut", "the engagement estimate needs up or down milling (a slot's a_e is "
                                    "the diameter: nothing to estimate)")
        return v

    # -- the step ------------------------------------------------------------------------------
    def step(self, force_base: np.ndarray, q: np.ndarray, feed: float,
             offline_delta: np.ndarray | None = None, cut: np.ndarray | None = None) -> CompensationResult:
        """One cycle (never raises).

        Args:
            force_base: measured mean force on the tool [N], base axes, shape (3,).
            q: current joints [rad], shape (n,) (e.g. ``<AIPos>`` in radians).
            feed: current feed speed [m/s] (planned feed × applied override).
            offline_delta: δ the exported path is already compensated by [m], base axes, shape
                (3,) (``None``: a path without mirror compensation).
            cut: the planned cut for this step (default: the one set).
        """
        try:
            return self._step(force_base, q, feed, offline_delta, cut)
        except Exception as e:  # noqa: BLE001 - the online step returns a status, never raises
            return self._hold(CompensationStatus.ERROR, f"internal error {type(e).__name__}: {e}")

    def _hold(self, status: CompensationStatus, reason: str) -> CompensationResult:
        return CompensationResult(status, reason + "; correction held", self.total, (0.0,) * 6)

    def _step(self, force_base, q, feed, offline_delta, cut) -> CompensationResult:
        try:
            f = np.asarray(force_base, float).reshape(3)
            qv = np.asarray(q, float).reshape(-1)
            fd = float(feed)
            off = np.zeros(3) if offline_delta is None else np.asarray(offline_delta, float).reshape(3)
            cv = self._cut if cut is None else self._check_cut(cut)
        except (TypeError, ValueError, InputError) as e:
            return self._hold(CompensationStatus.INVALID, f"bad input: {e}")
        if qv.shape != (self.robot.nq,):
            return self._hold(CompensationStatus.INVALID, f"need {self.robot.nq} joint values, got {qv.size}")
        if not (np.all(np.isfinite(f)) and np.all(np.isfinite(qv)) and np.all(np.isfinite(off))
                and math.isfinite(fd) and fd >= 0):
            return self._hold(CompensationStatus.INVALID, "non-finite force, joints, feed or offline δ")
        x_o = cv[3:6] / np.linalg.norm(cv[3:6])
        z_o = cv[0:3] / np.linalg.norm(cv[0:3])
        f_xo, f_zo = float(f @ x_o), float(f @ z_o)
        a_e = math.nan
        status = CompensationStatus.OK
        reason = ""
        if math.hypot(f_xo, f_zo) < self.config.min_force_N:
            delta = np.zeros(3)
            used = f
            status, reason = CompensationStatus.NOT_CUTTING, "force under the cutting threshold: δ = 0"
        else:
            a_e = self._estimate(cv, fd, math.atan2(f_zo, f_xo))
            if self.config.force == "engagement" and math.isfinite(a_e):
                c2 = cv.copy()
                c2[CUT_LAYOUT["a_e"][0]] = a_e
                d, fm = self._point(qv, c2, fd, self._params)
                delta = np.asarray(d, float).reshape(3)
                used = np.asarray(fm, float).reshape(3)
                reason = f"a_e {a_e * _MM:.3f} mm from the force angle"
            else:
                delta = np.asarray(self._of_force(qv, f, self._params)[0], float).reshape(3)
                used = f
                if self.config.force == "engagement":
                    status = CompensationStatus.FALLBACK
                    reason = "no a_e explains the force angle: δ from the measured force"
                else:
                    reason = "δ from the measured force"
        target = np.zeros(6)
        target[:3] = -(delta - off) * _MM
        if self.config.frame == "tool":
            rot = np.asarray(self._pose(qv, self._tcp)[1], float)
            target[:3] = rot.T @ target[:3]
        elif self._base_rot is not None:
            target[:3] = self._base_rot.T @ target[:3]
        if not np.all(np.isfinite(target)):
            return self._hold(CompensationStatus.ERROR, "the model gave a non-finite deflection")
        new = target.copy()
        move = new[:3] - self._total[:3]
        dist = float(np.linalg.norm(move))
        if dist > self._step_mm:
            new[:3] = self._total[:3] + move * (self._step_mm / dist)
            if status is CompensationStatus.OK:
                status = CompensationStatus.RATE_LIMITED
            reason += f"; rate-limited ({self.config.max_rate_mm_s:g} mm/s)"
        clamped = np.clip(new, -self._bounds, self._bounds)
        if np.any(clamped != new):
            status = CompensationStatus.CLAMPED
            reason += (f"; clamped at ±{self.config.max_position_mm:g} mm / "
                       f"±{self.config.max_orientation_deg:g} deg")
        inc = clamped - self._total
        self._total = clamped
        return CompensationResult(status, reason.lstrip("; "), self.total,
                                  tuple(float(v) for v in inc), delta, a_e, used)

    # -- engagement estimate -------------------------------------------------------------------
    def prepare(self, feed: float, cut: np.ndarray | None = None) -> None:
        """Tabulate θ(a_e, c) for the planned ``feed`` [m/s] (and ``cut``, default the one set):
        feeds per tooth from :data:`_C_RANGE` ``[0]`` to ``[1]`` × the planned one, so a step
        under any override up to 125 % interpolates and never tabulates. Costs tens of ms: call
        it before the loop (the first step does it otherwise); raises :class:`InputError`."""
        cv = self._cut if cut is None else self._check_cut(cut)
        fd = float(feed)
        if not (math.isfinite(fd) and fd > 0):
            raise InputError("feed", f"must be a positive number, got {feed!r}")
        flutes, radius, rpm = float(cv[10]), float(cv[11]), float(cv[9]) * 60.0 / (2.0 * math.pi)
        self._tabulate(fd / (flutes * rpm / 60.0), float(cv[8]), flutes, radius)

    def _estimate(self, cv: np.ndarray, feed: float, theta: float) -> float:
        """a_e [m] whose tabulated force angle is ``theta`` (the root nearest the planned a_e), NaN
        when none."""
        flutes, radius = float(cv[10]), float(cv[11])
        rpm = float(cv[9]) * 60.0 / (2.0 * math.pi)
        c = feed / (flutes * rpm / 60.0)
        if not c > 0:
            return math.nan
        mode = float(cv[8])
        if self._table_key is None or self._table_key != (mode, flutes, radius):
            self._tabulate(c, mode, flutes, radius)  # not prepared (or a new tool): once
        # θ row at c: linear in log c between the two tabulated rows (clamped at the table's ends)
        x = float(np.clip(math.log(c), self._logc[0], self._logc[-1]))
        j = int(min(max(np.searchsorted(self._logc, x) - 1, 0), self._logc.size - 2))
        w = (x - self._logc[j]) / (self._logc[j + 1] - self._logc[j])
        row = self._theta[j] + w * _wrap(self._theta[j + 1] - self._theta[j])
        g = _wrap(row - theta)
        cross = np.flatnonzero((np.sign(g[:-1]) * np.sign(g[1:]) <= 0) & (np.abs(g[:-1] - g[1:]) < np.pi))
        if cross.size == 0:
            return math.nan
        a0, a1 = self._grid[cross], self._grid[cross + 1]
        g0, g1 = g[cross], g[cross + 1]
        with np.errstate(divide="ignore", invalid="ignore"):
            w = np.where(g1 != g0, g0 / (g0 - g1), 0.0)
        roots = a0 + w * (a1 - a0)
        prior = float(cv[CUT_LAYOUT["a_e"][0]])
        return float(roots[np.argmin(np.abs(roots - prior))])

    def _tabulate(self, c: float, mode: float, flutes: float, radius: float) -> None:
        grid = np.linspace(_GRID_MIN_FRACTION * radius, 2.0 * radius, _GRID_POINTS)
        name = _MODE_NAMES[int(round(mode))]
        cs = c * np.geomspace(_C_RANGE[0], _C_RANGE[1], _C_POINTS)
        self._theta = np.stack([inplane_force_angles(grid, float(ci), name, int(flutes), radius,
                                                     self._coeffs) for ci in cs])
        self._logc = np.log(cs)
        self._grid = grid
        self._table_key = (mode, flutes, radius)


def job_parameters(job, robot: Robot | None = None) -> ModelParameters:
    """The model a job asks for, as the planner takes it (:func:`planner.ceilings.job_parameters`:
    the joint stiffness × ``[cell] joint_stiffness_scale``, a calibration overlay's cutting
    coefficients where the job has one, ...).

    Args:
        job: a validated :class:`planner.job.Job` (:func:`planner.job.load_job`).
        robot: the job's robot, when already loaded (default: loaded from ``[cell] robot``).
    """
    from models import load_robot
    from planner.ceilings import job_parameters as planner_parameters

    return planner_parameters(job, robot if robot is not None else load_robot(job.cell.robot))


def _plan_parameters(plan, robot: Robot) -> ModelParameters:
    """The model of a plan without its job: the robot data's joint stiffness and the material
    file's coefficients, each replaced by what the plan records of its job's calibration
    (``model.joint_stiffness_scale``, ``model.coefficients``: :meth:`Plan.model_coefficients`)."""
    from models.errors import DataFileError

    rec = plan.model or {}
    try:
        scale = float(rec.get("joint_stiffness_scale", 1.0))
        gain = float(rec.get("process_gain", 1.0))
        coeffs = plan.model_coefficients()
    except (TypeError, ValueError, DataFileError) as e:
        raise InputError("compensation", f"the plan's model record is malformed: {e}") from e
    if not (math.isfinite(scale) and scale > 0):
        raise InputError("compensation", f"the plan's joint_stiffness_scale {scale!r} is not positive")
    data = robot.data
    return ModelParameters(joint_stiffness=data.joint_stiffness * scale, coefficients=coeffs,
                           cct=bool(rec.get("cct", True)), process_gain=gain,
                           tcp=np.asarray(plan.tool_xyz, float),
                           spindle_mass=data.spindle_mass, spindle_com=data.spindle_com)


def _wrap(a: np.ndarray) -> np.ndarray:
    """Angles wrapped to (−π, π] [rad]."""
    return np.arctan2(np.sin(a), np.cos(a))


class PlanCompensation:
    """The compensator driven along a plan, one call a supervisor cycle (``run_loop(on_cycle=…)``).

    At the supervisor's dead-reckoned arc length it takes the plan's sample there: joints, cut
    (its frame from the path's tangent and tool axis, in robot base axes; a_e, a_p, mode as
    planned), the planned δ (for ``offline=True``: the program was exported with
    ``--compensate-deflection``) and the feed (planned × the override the controller reports);
    it asks ``force(s_m, feed, k)`` for the measured mean force [N] (base axes, or ``None``: no
    measurement this cycle), steps the compensator and gives the link the increment
    (``#RELATIVE``) or the total (``#ABSOLUTE``) with ``set_correction``. A sample that does not
    side-mill (air, rapid, slot, plunge) steps with zero force: the correction returns to zero at
    the rate limit. A correction the link refuses is rolled back (the controller's total is
    held, counted in ``link_failures``); nothing raises out of :meth:`__call__`.

    A ``"base"`` correction is given in the plan's ``$BASE`` axes (POSCORR ``RefCorrSys`` #BASE).
    The model, first given first: ``params``; the ``job`` the plan was made from
    (:func:`job_parameters`: its calibration overlay's joint stiffness scale and cutting
    coefficients, what the plan's offline δ was computed with); else the plan's robot, material
    and ``$TOOL`` with what the plan records of its job's calibration (``model.joint_stiffness_scale``,
    ``model.coefficients``; without them the robot and material files' values as shipped).
    """

    def __init__(self, plan, force, config: CompensationConfig | None = None, offline: bool = False,
                 robot: Robot | None = None, params: ModelParameters | None = None, job=None) -> None:
        from models import load_robot
        from robot_io.krl.frames import abc_to_matrix

        self.robot = robot if robot is not None else load_robot(plan.robot)
        smp = plan.samples
        if params is None:
            params = (job_parameters(job, self.robot) if job is not None
                      else _plan_parameters(plan, self.robot))
        self.params = params
        rot = abc_to_matrix(*np.degrees(np.asarray(plan.base_abc, float)))
        n = smp.s.size
        tangent = np.gradient(np.asarray(smp.position_wp, float), axis=0) if n > 1 else np.zeros((n, 3))
        f_dir = tangent @ rot.T
        axis = np.asarray(smp.tool_axis_wp, float) @ rot.T
        x_dir = np.cross(axis, f_dir)
        fn = np.linalg.norm(f_dir, axis=1)
        xn = np.linalg.norm(x_dir, axis=1)
        mode = np.asarray(smp.mode, float)
        side = np.isin(mode, (cutting.MILLING_MODES["up"], cutting.MILLING_MODES["down"]))
        ok = side & (np.asarray(smp.kind) == 0) & (fn > 0) & (xn > 1e-6 * np.maximum(fn, 1e-30))
        ok &= np.isfinite(smp.a_e) & (smp.a_e > 0) & np.isfinite(smp.a_p) & (smp.a_p > 0)
        ok &= np.all(np.isfinite(smp.q), axis=1)
        if not np.any(ok):
            raise InputError("compensation", "the plan has no side-milling sample (up or down milling "
                                             "with a feed across the tool axis): nothing to compensate")
        if not (plan.spindle_rpm and plan.flutes and plan.tool_diameter):
            raise InputError("compensation", "the plan records no spindle speed, flutes or tool diameter")
        cuts = np.zeros((n, 12))
        with np.errstate(invalid="ignore", divide="ignore"):
            cuts[:, 0:3] = f_dir / fn[:, None]
            cuts[:, 3:6] = x_dir / xn[:, None]
        cuts[:, 6], cuts[:, 7], cuts[:, 8] = smp.a_e, smp.a_p, mode
        cuts[:, 9] = float(plan.spindle_rpm) * math.pi / 30.0
        cuts[:, 10], cuts[:, 11] = float(plan.flutes), 0.5 * float(plan.tool_diameter)
        self.cuts, self.valid, self.s = cuts, ok, np.asarray(smp.s, float)
        self.q = np.asarray(smp.q, float)
        self.feed = np.asarray(smp.feed, float)
        self.offline = (np.nan_to_num(np.asarray(smp.deflection_wp, float)) @ rot.T) if offline else None
        k0 = int(np.flatnonzero(ok)[0])
        self.compensator = DeflectionCompensator(self.robot, params, cuts[k0], config, base_rotation=rot)
        self.compensator.prepare(float(self.feed[k0]) if self.feed[k0] > 0 else 1e-3)
        self._force = force
        self._last_valid = k0
        #: steps per compensation status; corrections the link refused or could not take
        self.counts: dict[str, int] = {}
        self.link_failures = 0
        self.last: CompensationResult | None = None
        self.last_link_reason = ""

    def set_force(self, force) -> None:
        """The measured-force callable from now on: ``force(s_m, feed, k) -> (3,) | None``."""
        self._force = force

    def model_force(self, s_m: float, feed: float, k: int) -> np.ndarray:
        """The model's mean force [N] (base axes) at sample ``k``'s planned cut and ``feed``
        [m/s]: the force sensor of a simulated session (a ``force`` for the constructor)."""
        c = self.compensator
        return np.asarray(c._point(self.q[k], self.cuts[k], feed, c._params)[1], float).reshape(3)

    def sample_at(self, s_m: float) -> int:
        """Index of the plan sample at arc length ``s_m`` [m] (the last one at or before it)."""
        return int(min(max(np.searchsorted(self.s, s_m, side="right") - 1, 0), self.s.size - 1))

    def __call__(self, now: float, res, applied: float | None, link) -> CompensationResult:
        """One cycle (``res`` the supervisor's step result, ``applied`` the override the
        controller reports [percent]); never raises."""
        comp = self.compensator
        try:
            k = self.sample_at(float(res.s_m))
            pct = float(applied) if applied is not None else float(res.override)
            feed = float(self.feed[k]) * pct / 100.0
            cutting_here = bool(self.valid[k])
            if cutting_here:
                self._last_valid = k
            kc = k if cutting_here else self._last_valid
            force = self._force(float(res.s_m), feed, k) if cutting_here else np.zeros(3)
            if force is None:
                out = comp._hold(CompensationStatus.INVALID, "no force measurement this cycle")
            else:
                off = self.offline[kc] if self.offline is not None and cutting_here else None
                out = comp.step(force, self.q[k], feed, offline_delta=off, cut=self.cuts[kc])
        except Exception as e:  # noqa: BLE001 - the loop's hook returns a status, never raises
            out = comp._hold(CompensationStatus.ERROR, f"internal error {type(e).__name__}: {e}")
        if comp.config.mode == "relative":
            values, send = out.increment, any(v != 0.0 for v in out.increment)
        else:
            values, send = out.total, True
        if send:
            try:
                st = link.set_correction(values, comp.config.mode)
                taken = st.percent is not None
                self.last_link_reason = str(st.reason)
            except Exception as e:  # noqa: BLE001 - a link without RKorr, or one that throws
                taken, self.last_link_reason = False, f"{type(e).__name__}: {e}"
            if not taken:
                self.link_failures += 1
                comp.rollback(out)
        key = str(out.status)
        self.counts[key] = self.counts.get(key, 0) + 1
        self.last = out
        return out

    def summary(self) -> dict:
        """What the compensation did (the session summary's ``compensation``)."""
        c = self.compensator.config
        return {"frame": c.frame, "mode": c.mode, "max_mm": c.max_position_mm, "rate_mm_s": c.max_rate_mm_s,
                "offline": self.offline is not None, "status_counts": dict(self.counts),
                "link_failures": self.link_failures, "last_link_reason": self.last_link_reason,
                "total": list(self.compensator.total),
                "last_reason": self.last.reason if self.last is not None else None}
