"""Joint stiffness scale from measured static deflections (and chatter frequencies).

The static TCP deflection under the mean force F (base axes) is δ = J_v (S K_θ − K_c(F))⁻¹ J_vᵀ F
(docs/model.md §3, §7), S = diag(s₁..s₆) the joint stiffness scales relative to the job's. Without
the CCT term δ is linear in the compliance scales 1/sᵢ — δ = Σᵢ dᵢ/sᵢ with dᵢ = J_v,i (J_v,iᵀ F)/kᵢ —
so a joint is identifiable when its column dᵢ is not drowned by the others'. The fit is nonlinear
least squares in log s (CCT included when the job includes it), first with one common scale, then
per joint for the joints the data resolves (standard error of log sᵢ below
:data:`PER_JOINT_LOG_STD_MAX`); the others share one scale. Uncertainty: the Gauss-Newton covariance
s² (JᵀJ)⁻¹ with the residual variance, intervals with Student's t.

Chatter frequencies give a second, rougher estimate: the arm's 2-DOF natural frequencies scale with
√s, so s ≈ (f_meas / f_model)² with f_model the model's mode nearest the measured frequency
(mode-coupling chatter vibrates near the arm's modes, not at them: the estimate carries that bias,
and the report says it is the rougher one).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import cache

import casadi as ca
import numpy as np
import scipy.optimize
import scipy.stats

from models import stiffness
from models.analysis import Cut
from models.errors import CctmillError
from models.structure import pose_structure
from planner.calibrate.context import CalibrationContext
from planner.calibrate.fit_coefficients import CONFIDENCE, FitRefused
from planner.calibrate.records import CutRecord

__all__ = [
    "MIN_DEFLECTIONS",
    "MIN_FREQUENCIES",
    "PER_JOINT_LOG_STD_MAX",
    "StiffnessFit",
    "fit_stiffness",
    "joint_terms",
    "record_cut",
]

#: Fewest records with a measured deflection and force [-] (three components each).
MIN_DEFLECTIONS = 2
#: Fewest chatter records with a frequency for the frequency estimate [-].
MIN_FREQUENCIES = 3
#: A joint gets its own scale when the standard error of its log-scale is below this [-]
#: (about ±10 % at one sigma); the others share one.
PER_JOINT_LOG_STD_MAX = 0.1
#: A joint whose deflection column is below this fraction of the largest [-] has no influence.
INFLUENCE_MIN = 1e-6
#: Largest residual RMS over the RMS deflection [-] before the records count as contradicting the
#: linear-elastic model (a tracker measures to some 10-20 µm against deflections of 0.1-0.3 mm).
CONTRADICTION_RATIO = 0.5
#: Scales outside this range [-] are not a calibration but a wrong robot or unit.
SCALE_RANGE = (0.05, 20.0)


@cache
def _terms_function(robot_name: str) -> ca.Function:
    """(q, tcp, f) -> (J_v 3×n, K_c n×n) for a pure force at the TCP."""
    from models.robot import load_robot

    sym = load_robot(robot_name).symbolic
    f = ca.SX.sym("f", 3)
    jv = sym.jacobian[0:3, :]
    k_c = stiffness.cct_term(jv, sym.q, f)
    return ca.Function("stiffness_terms", [sym.q, sym.tcp, f], [jv, k_c])


def joint_terms(ctx: CalibrationContext, record: CutRecord) -> tuple[np.ndarray, np.ndarray]:
    """(J_v [m/rad] (3, 6), K_c [N·m/rad] (6, 6)) of a record's pose under its mean force."""
    jv, k_c = _terms_function(ctx.robot)(record.q(), np.asarray(ctx.tcp, float),
                                         record.force_base())
    return np.asarray(jv, float), np.asarray(k_c, float) if ctx.cct else np.zeros((6, 6))


def record_cut(ctx: CalibrationContext, record: CutRecord) -> Cut:
    """The record's cut as the models take it (SI)."""
    radius = ctx.tool.radius if record.diameter_mm is None else record.diameter_mm * 5e-4
    flutes = ctx.tool.flutes if record.flutes is None else record.flutes
    return Cut(feed_dir=np.asarray(record.feed_dir, float),
               radial_dir=np.asarray(record.radial_dir, float),
               a_e=2.0 * radius if record.milling == "slot" else record.ae_mm * 1e-3,
               a_p=record.ap_mm * 1e-3, mode=record.milling,
               spindle_speed=record.spindle_speed(), flutes=flutes, radius=radius)


@dataclass(frozen=True)
class StiffnessFit:
    """The joint stiffness scale relative to the job's, with uncertainty.

    Attributes:
        scale: common scale s [-] (all joints).
        scale_ci: its :data:`CONFIDENCE` interval (lo, hi).
        scale_log_std: standard error of log s [-].
        per_joint: per-joint scales (6,) [-]: the resolved joints' own, the others the shared one
            (None: no deflection data).
        per_joint_ci: (6, 2) intervals, or None; resolved: which joints got their own scale.
        residual_rms_mm, deflection_rms_mm: RMS residual and RMS measured deflection [mm].
        n_deflections: records used; dof: residual degrees of freedom.
        frequency_scale, frequency_scale_ci, n_frequencies: the chatter-frequency estimate
            (None without enough chatter records).
        method: ``"deflection"``, ``"frequency"`` (which one ``scale`` is).
    """

    scale: float
    scale_ci: tuple[float, float]
    scale_log_std: float
    per_joint: np.ndarray | None
    per_joint_ci: np.ndarray | None
    resolved: tuple[bool, ...]
    residual_rms_mm: float
    deflection_rms_mm: float
    n_deflections: int
    dof: int
    frequency_scale: float | None
    frequency_scale_ci: tuple[float, float] | None
    n_frequencies: int
    method: str

    def as_json(self) -> dict:
        return {
            "method": self.method, "scale": self.scale, "scale_ci95": list(self.scale_ci),
            "scale_log_std": self.scale_log_std,
            "per_joint": None if self.per_joint is None else self.per_joint.tolist(),
            "per_joint_ci95": None if self.per_joint_ci is None else self.per_joint_ci.tolist(),
            "resolved_joints": [f"A{i + 1}" for i, r in enumerate(self.resolved) if r],
            "residual_rms_mm": self.residual_rms_mm, "deflection_rms_mm": self.deflection_rms_mm,
            "n_deflections": self.n_deflections, "dof": self.dof,
            "frequency_scale": self.frequency_scale,
            "frequency_scale_ci95": (None if self.frequency_scale_ci is None
                                     else list(self.frequency_scale_ci)),
            "n_frequencies": self.n_frequencies,
        }


def _deflection(jv: np.ndarray, k_c: np.ndarray, k_theta: np.ndarray, f: np.ndarray) -> np.ndarray:
    return jv @ np.linalg.solve(np.diag(k_theta) - k_c, jv.T @ f)


def _groups_fit(data, k0: np.ndarray, groups: np.ndarray, n_groups: int,
                fixed: float = 0.0):
    """Least squares in log s per group (``groups[i] = −1``: joint i held at log s = ``fixed``);
    returns (log s (n_groups,), jacobian, residual)."""
    def residual(p: np.ndarray) -> np.ndarray:
        k = k0 * np.exp(np.where(groups >= 0, np.append(p, 0.0)[groups], fixed))
        return np.concatenate([_deflection(jv, kc, k, f) - d for jv, kc, f, d in data])

    sol = scipy.optimize.least_squares(residual, np.zeros(n_groups), method="lm", x_scale=1.0)
    return sol.x, sol.jac, sol.fun


def _deflection_fit(ctx: CalibrationContext, records: Sequence[CutRecord]):
    data = []
    for r in records:
        jv, k_c = joint_terms(ctx, r)
        data.append((jv, k_c, r.force_base(), r.deflection_base()))
    k0 = np.asarray(ctx.params().joint_stiffness, float)
    n_eq = 3 * len(data)
    common = np.zeros(6, int)
    p, jac, res = _groups_fit(data, k0, common, 1)
    dof = n_eq - 1
    s2 = float(res @ res) / dof
    log_std = float(np.sqrt(s2 / float(jac[:, 0] @ jac[:, 0])))
    d_rms = float(np.sqrt(np.mean(np.concatenate([d for *_, d in data]) ** 2)))
    r_rms = float(np.sqrt(np.mean(res**2)))
    # Which joints can the data resolve? A fit with a scale per joint, judged by its own
    # residual variance (the common fit's would count the joints' true differences as noise).
    # A joint that moves no record's TCP (A6 with the TCP on its axis) has a zero column: it is
    # held at the common scale and left out of the others' covariance.
    resolved = np.zeros(6, bool)
    alive = np.ones(6, bool)
    if n_eq - 6 >= 3:
        p6, jac6, res6 = _groups_fit(data, k0, np.arange(6), 6)
        s2_6 = float(res6 @ res6) / (n_eq - 6)
        norms = np.linalg.norm(jac6, axis=0)
        alive = norms > INFLUENCE_MIN * norms.max()
        live = np.flatnonzero(alive)
        try:
            cov = s2_6 * np.linalg.inv(jac6[:, live].T @ jac6[:, live])
            resolved[live] = np.sqrt(np.maximum(np.diag(cov), 0.0)) < PER_JOINT_LOG_STD_MAX
        except np.linalg.LinAlgError:
            resolved[:] = False
    # Resolved joints get a scale each; the other live ones (if any) share group 0; dead joints
    # are held at the common scale.
    shared = bool(np.any(alive & ~resolved))
    groups = np.where(alive, 0, -1)
    n_groups = 1 if shared else 0
    for i in np.flatnonzero(resolved):
        groups[i] = n_groups
        n_groups += 1
    pj, jac_j, res_j = _groups_fit(data, k0, groups, n_groups, fixed=p[0])
    dof_j = max(n_eq - n_groups, 1)
    s2_j = float(res_j @ res_j) / dof_j
    try:
        cov_j = s2_j * np.linalg.inv(jac_j.T @ jac_j)
    except np.linalg.LinAlgError:
        cov_j = np.full((n_groups, n_groups), np.inf)
    t_j = float(scipy.stats.t.ppf(0.5 + CONFIDENCE / 2.0, dof_j))
    std_j = np.sqrt(np.maximum(np.diag(cov_j), 0.0))
    log_per = np.where(groups >= 0, np.append(pj, 0.0)[groups], p[0])
    std_per = np.where(groups >= 0, np.append(std_j, 0.0)[groups], log_std)
    per = np.exp(log_per)
    per_ci = np.column_stack([np.exp(log_per - t_j * std_per), np.exp(log_per + t_j * std_per)])
    return p[0], log_std, dof, r_rms, d_rms, per, per_ci, tuple(bool(x) for x in resolved)


def _frequency_estimate(ctx: CalibrationContext, records: Sequence[CutRecord]
                        ) -> tuple[float, tuple[float, float]] | None:
    if len(records) < MIN_FREQUENCIES:
        return None
    robot, params = ctx.load_robot(), ctx.params()
    logs = []
    for r in records:
        structure = pose_structure(robot, params, r.q(), record_cut(ctx, r), r.feed())
        f_model = np.asarray(structure.natural_frequencies_hz, float)
        nearest = f_model[np.argmin(np.abs(np.log(f_model / r.chatter_hz)))]
        logs.append(2.0 * np.log(r.chatter_hz / nearest))
    logs = np.asarray(logs)
    m = float(np.mean(logs))
    se = float(np.std(logs, ddof=1) / np.sqrt(len(logs)))
    t = float(scipy.stats.t.ppf(0.5 + CONFIDENCE / 2.0, len(logs) - 1))
    return float(np.exp(m)), (float(np.exp(m - t * se)), float(np.exp(m + t * se)))


def fit_stiffness(ctx: CalibrationContext, records: Sequence[CutRecord]) -> StiffnessFit:
    """Fit the joint stiffness scale (relative to the job's) to the records.

    Uses records with both ``deflection_mm`` and ``force_n`` (any verdict but chatter), and, as a
    second estimate, chatter records with ``chatter_hz``.

    Raises:
        FitRefused: neither enough deflections nor enough chatter frequencies; a scale outside
            :data:`SCALE_RANGE`; residuals contradicting the linear-elastic model.
    """
    with_d = [r for r in records if r.deflection_mm is not None and r.force_n is not None
              and r.verdict != "chatter"]
    with_f = [r for r in records if r.chatter_hz is not None and r.verdict == "chatter"]
    freq = _frequency_estimate(ctx, with_f)
    if len(with_d) < MIN_DEFLECTIONS and freq is None:
        raise FitRefused("stiffness", f"{len(with_d)} record(s) with a measured deflection and "
                         f"force (need {MIN_DEFLECTIONS}) and {len(with_f)} chatter record(s) "
                         f"with a frequency (need {MIN_FREQUENCIES}); measure the deflection "
                         "(deflection_mm) of a few cuts")
    robot = ctx.load_robot()
    for r in with_d:
        try:
            robot.check_limits(r.q())
        except CctmillError as e:
            raise FitRefused("stiffness", f"record {r.name}: {e}; fix or leave out the record") from e
    if len(with_d) >= MIN_DEFLECTIONS:
        try:
            log_s, log_std, dof, r_rms, d_rms, per, per_ci, resolved = _deflection_fit(ctx, with_d)
        except (np.linalg.LinAlgError, CctmillError) as e:
            raise FitRefused("stiffness", f"the deflection fit failed: {e}") from e
        scale = float(np.exp(log_s))
        if r_rms > CONTRADICTION_RATIO * d_rms:
            raise FitRefused("stiffness", f"the records contradict the elastic model: residual "
                             f"RMS {r_rms * 1e3:.3g} mm against deflections of {d_rms * 1e3:.3g} "
                             "mm RMS; check the frame and units of deflection_mm and force_n")
        t = float(scipy.stats.t.ppf(0.5 + CONFIDENCE / 2.0, dof))
        ci = (float(np.exp(log_s - t * log_std)), float(np.exp(log_s + t * log_std)))
        method = "deflection"
    else:
        scale, ci = freq
        log_std = float((np.log(ci[1]) - np.log(ci[0])) / 4.0)
        per = per_ci = None
        resolved = (False,) * 6
        r_rms = d_rms = float("nan")
        dof = len(with_f) - 1
        method = "frequency"
    if not SCALE_RANGE[0] <= scale <= SCALE_RANGE[1]:
        raise FitRefused("stiffness", f"the fitted scale {scale:.3g} is outside {SCALE_RANGE}: "
                         "not a calibration but a wrong robot, TCP or unit (mm vs m)")
    return StiffnessFit(
        scale=scale, scale_ci=ci, scale_log_std=log_std, per_joint=per, per_joint_ci=per_ci,
        resolved=resolved, residual_rms_mm=r_rms * 1e3, deflection_rms_mm=d_rms * 1e3,
        n_deflections=len(with_d), dof=dof,
        frequency_scale=None if freq is None else freq[0],
        frequency_scale_ci=None if freq is None else freq[1], n_frequencies=len(with_f),
        method=method)
