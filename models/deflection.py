"""Static deflection along a path, mirror compensation, and the online engagement estimate (docs/model.md §7).

**Deflection.** δ = C[0:3, 0:3] · F̄ at the TCP (with CCT when ``params.cct``): the point Function's
``deflection`` output mapped over the samples. The machined wall's error is the component normal to
the wall, along the radial direction X_o: ``normal`` = δ·X_o [m]. The material lies on +X_o in up
milling and on −X_o in down milling; ``wall_error`` = −δ·(material side) is > 0 where the tool was
pushed away from the wall and left material (the usual case: the radial force pushes the tool out),
< 0 where it dug in.

**Mirror compensation.** The commanded TCP is moved by −δ so that the deflected tool lands on the
nominal path. The shifted pose has its own stiffness and therefore its own δ: :func:`compensate`
solves the pose at the shifted position (Newton steps on the TCP position with the orientation
held, through the pseudo-inverse of the 6×n Jacobian) and re-evaluates δ there. With
``iterations = 1`` it is the plain mirror of the KRL exporter (δ from the nominal pose); more
iterations solve p(q) + δ(q) = p_nominal. The residual is what the model says the wall still
misses by; it assumes the force does not change (the real engagement changes with the error).

**Engagement estimate** (thesis Chapter 4, online). The thesis's ratio r = F̄_y/F̄_x of the measured
mean force, in docs/model.md §4 axes, is the in-plane ratio F̄_zo/F̄_xo (feed over radial): the axial depth
cancels, the feed per tooth c is known from the feed and spindle speed, so it depends only on the
exit angle (up milling; the entry angle in down milling) and hence on a_e = R(1 − cos φ_ex). F̄_xo
changes sign within the range in up milling, so the angle θ = atan2(F̄_zo, F̄_xo) is inverted
instead of the ratio (same information, finite everywhere), with a bracketed root solve.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cache

import casadi as ca
import numpy as np
import scipy.optimize

from models import cutting, stiffness
from models.analysis import N_PARAMS, PARAM_LAYOUT, ModelParameters, path_inputs, point_function
from models.errors import CctmillError, InputError
from models.robot import Robot

__all__ = [
    "COMPENSATION_TOL",
    "Compensation",
    "PathDeflection",
    "compensate",
    "deflection_of_force",
    "estimate_radial_depth",
    "inplane_force_angle",
    "inplane_force_angles",
    "path_deflection",
]

#: Position tolerance of the compensation's Newton solve [m] (0.1 µm, well below any wall
#: tolerance and above the floating-point noise of the kinematics).
COMPENSATION_TOL = 1e-7
#: Grid of the engagement estimate's bracket search [-]: a_e from this fraction of R to 2R.
_ESTIMATE_GRID = 400
_ESTIMATE_MIN_FRACTION = 1e-3


@dataclass(frozen=True)
class PathDeflection:
    """Static deflection at every sample. SI, base axes.

    Attributes:
        deflection: δ [m], shape (n, 3).
        normal: δ·X_o [m], shape (n,).
        wall_error: material left (> 0) or dug in (< 0) normal to the wall [m], shape (n,).
        force: mean cutting force on the tool [N], shape (n, 3).
    """

    deflection: np.ndarray
    normal: np.ndarray
    wall_error: np.ndarray
    force: np.ndarray


def _material_side(cuts: np.ndarray) -> np.ndarray:
    """+1 where the material lies on +X_o (up, slot), −1 (down), per cut vector row."""
    mode = cuts[:, 8]
    return np.where(np.isclose(mode, cutting.MILLING_MODES["down"]), -1.0, 1.0)


@cache
def _deflection_of_force(robot: Robot) -> ca.Function:
    sym = robot.symbolic
    f = ca.SX.sym("f", 3)
    params = ca.SX.sym("params", N_PARAMS)
    k_theta = params[PARAM_LAYOUT["joint_stiffness"][0]:PARAM_LAYOUT["joint_stiffness"][0] + 6]
    cct = params[PARAM_LAYOUT["cct"][0]]
    t0 = PARAM_LAYOUT["tcp"][0]
    jac = ca.substitute(sym.jacobian, sym.tcp, params[t0:t0 + 3])
    k_c = stiffness.cct_term(jac[0:3, :], sym.q, f) * cct
    c_tt = stiffness.translational_compliance(jac, k_theta, k_c)
    return ca.Function("deflection_of_force", [sym.q, f, params], [c_tt @ f, c_tt],
                       ["q", "f", "params"], ["delta", "compliance"])


def deflection_of_force(robot: Robot) -> ca.Function:
    """``(q [rad] (n,), f [N] (3,), params (23,)) -> (δ [m] (3,), C_tt [m/N] (3, 3))``: the static
    deflection δ = C_tt(q, f)·f under a *given* force on the tool (base axes, at the TCP; CCT when
    the ``cct`` parameter is 1), the same compliance as the point model's ``deflection`` output.
    The online compensation calls it with the measured or estimated force; built once per robot."""
    return _deflection_of_force(robot)


def path_deflection(robot: Robot, params: ModelParameters, q: np.ndarray, cuts: np.ndarray,
                    feeds: np.ndarray) -> PathDeflection:
    """δ along a path.

    Args:
        robot, params: the model.
        q: joints [rad], shape (n, nq).
        cuts: ``Cut.vector()`` rows, shape (n, 12).
        feeds: feed speed [m/s], shape (n,).
    """
    q, cuts, feeds, n = path_inputs(q, cuts, feeds)
    f = point_function(robot, "oriented", "isotropic", outputs=("deflection", "force_base"))
    fm = f.map(n)
    res = fm(q.T, cuts.T, feeds.reshape(1, -1), params.vector())
    delta = np.asarray(res[0], float).T
    force = np.asarray(res[1], float).T
    radial = cuts[:, 3:6] / np.linalg.norm(cuts[:, 3:6], axis=1, keepdims=True)
    normal = np.einsum("ij,ij->i", delta, radial)
    return PathDeflection(delta, normal, -normal * _material_side(cuts), force)


@dataclass(frozen=True)
class Compensation:
    """Result of :func:`compensate`. SI, base axes.

    Attributes:
        q: compensated joints [rad], shape (n, nq).
        offset: commanded minus nominal TCP position [m], shape (n, 3) (≈ −δ).
        residual: deflected compensated TCP minus nominal [m], shape (n, 3).
        residual_normal: residual·X_o [m], shape (n,).
        uncompensated_normal: δ·X_o at the nominal pose [m], shape (n,).
        iterations: compensation iterations used.
    """

    q: np.ndarray
    offset: np.ndarray
    residual: np.ndarray
    residual_normal: np.ndarray
    uncompensated_normal: np.ndarray
    iterations: int

    @property
    def reduction(self) -> float:
        """1 − max|residual normal| / max|uncompensated normal| [-]."""
        before = float(np.max(np.abs(self.uncompensated_normal)))
        return 1.0 - float(np.max(np.abs(self.residual_normal))) / before if before > 0 else 0.0


def _move_to(robot: Robot, params: ModelParameters, q: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Joints near ``q`` whose TCP is at ``target`` [m] with the orientation of ``q``'s TCP."""
    q = q.copy()
    for _ in range(20):
        p = np.asarray(robot.pose_function(q, params.tcp)[0], float).reshape(3)
        err = target - p
        if np.linalg.norm(err) < COMPENSATION_TOL:
            return q
        jac = np.asarray(robot.jacobian_function(q, params.tcp), float)
        q = q + np.linalg.pinv(jac) @ np.concatenate([err, np.zeros(3)])
    raise CctmillError(f"compensation: the TCP did not reach the shifted position within "
                       f"{COMPENSATION_TOL:g} m (singular pose?); plan without compensation here")


def compensate(robot: Robot, params: ModelParameters, q: np.ndarray, cuts: np.ndarray,
               feeds: np.ndarray, iterations: int = 1) -> Compensation:
    """Mirror pre-compensation of the static deflection (see the module docstring).

    Args:
        q: nominal joints [rad], shape (n, nq).
        cuts: ``Cut.vector()`` rows, shape (n, 12).
        feeds: [m/s], shape (n,).
        iterations: 1 = plain mirror (δ at the nominal pose); more = fixed point p + δ = nominal.
    """
    if iterations < 1:
        raise InputError("iterations", f"need at least 1, got {iterations}")
    q = np.atleast_2d(np.asarray(q, float))
    cuts = np.atleast_2d(np.asarray(cuts, float))
    nominal = np.array([np.asarray(robot.pose_function(qi, params.tcp)[0], float).reshape(3)
                        for qi in q])
    base = path_deflection(robot, params, q, cuts, feeds)
    delta = base.deflection
    qc = q.copy()
    for _ in range(iterations):
        target = nominal - delta
        qc = np.array([_move_to(robot, params, qi, ti) for qi, ti in zip(qc, target, strict=True)])
        delta = path_deflection(robot, params, qc, cuts, feeds).deflection
    commanded = np.array([np.asarray(robot.pose_function(qi, params.tcp)[0], float).reshape(3)
                          for qi in qc])
    residual = commanded + delta - nominal
    radial = cuts[:, 3:6] / np.linalg.norm(cuts[:, 3:6], axis=1, keepdims=True)
    return Compensation(q=qc, offset=commanded - nominal, residual=residual,
                        residual_normal=np.einsum("ij,ij->i", residual, radial),
                        uncompensated_normal=base.normal, iterations=iterations)


# --------------------------------------------------------------------------------------------------
# Engagement estimate
# --------------------------------------------------------------------------------------------------


@cache
def _angle_function() -> ca.Function:
    a_e, c, mode, flutes, radius = (ca.SX.sym(n) for n in ("a_e", "c", "mode", "N", "R"))
    coeffs = ca.SX.sym("coeffs", 6)
    f = cutting.average_force(c, a_e, 1.0, mode, flutes, radius, coeffs)
    return ca.Function("inplane_force_angle", [a_e, c, mode, flutes, radius, coeffs],
                       [ca.atan2(f[2], f[0])])


def _angles(a_e: np.ndarray, c: float, mode: str, flutes: int, radius: float,
            coefficients) -> np.ndarray:
    a_e = np.asarray(a_e, float).reshape(-1)
    k = (coefficients.coefficients() if isinstance(coefficients, cutting.Material)
         else np.asarray(coefficients, float).reshape(6))
    f = _angle_function().map(a_e.size)
    return np.asarray(f(a_e.reshape(1, -1), c, cutting.MILLING_MODES[mode], flutes, radius, k),
                      float).reshape(-1)


def inplane_force_angle(a_e: float, c: float, mode: str, flutes: int, radius: float,
                        coefficients) -> float:
    """θ = atan2(F̄_zo, F̄_xo) of the mean force [rad] (independent of a_p)."""
    if mode not in cutting.MILLING_MODES:
        raise InputError("mode", f"unknown milling mode {mode!r}")
    return float(_angles(np.array([a_e]), c, mode, flutes, radius, coefficients)[0])


def inplane_force_angles(a_e: np.ndarray, c: float, mode: str, flutes: int, radius: float,
                         coefficients) -> np.ndarray:
    """θ(a_e) = atan2(F̄_zo, F̄_xo) [rad] over radial depths ``a_e`` [m], shape (k,): the table an
    online estimate interpolates (one mapped call)."""
    if mode not in cutting.MILLING_MODES:
        raise InputError("mode", f"unknown milling mode {mode!r}")
    return _angles(np.asarray(a_e, float), c, mode, flutes, radius, coefficients)


def estimate_radial_depth(force_mean_o: np.ndarray, c: float, mode: str, flutes: int,
                          radius: float, coefficients, prior: float | None = None) -> float:
    """Radial depth a_e [m] from the measured mean force (thesis Chapter 4; docs/model.md §7).

    Solves θ(a_e) = atan2(F̄_zo, F̄_xo) for a_e = R(1 − cos φ_ex) in (0, 2R].

    Args:
        force_mean_o: measured mean force on the tool in (X_o, Y_o, Z_o) [N], shape (3,); only
            the in-plane components are used.
        c: feed per tooth [m].
        mode: ``"up"`` or ``"down"``.
        flutes, radius: the tool (N, R [m]).
        coefficients: cutting coefficients (6,) or a Material.
        prior: the planned a_e [m]; picks the nearest root if the angle is not monotone.

    Raises:
        InputError: no a_e in (0, 2R] explains the measurement, or several do and no prior is given.
    """
    if mode not in ("up", "down"):
        raise InputError("mode", f"the estimate needs up or down milling, got {mode!r}")
    f = np.asarray(force_mean_o, float).reshape(3)
    if math.hypot(f[0], f[2]) == 0.0:
        raise InputError("force", "the in-plane mean force is zero: the tool is not cutting")
    measured = math.atan2(f[2], f[0])
    grid = np.linspace(_ESTIMATE_MIN_FRACTION * radius, 2.0 * radius, _ESTIMATE_GRID)

    def residual_of(a: float) -> float:  # wrapped to (−π, π]
        d = inplane_force_angle(a, c, mode, flutes, radius, coefficients) - measured
        return math.atan2(math.sin(d), math.cos(d))

    d = _angles(grid, c, mode, flutes, radius, coefficients) - measured
    g = np.arctan2(np.sin(d), np.cos(d))
    roots = []
    for i in np.flatnonzero((np.sign(g[:-1]) * np.sign(g[1:]) <= 0)
                            & (np.abs(g[:-1] - g[1:]) < np.pi)):
        roots.append(scipy.optimize.brentq(residual_of, grid[i], grid[i + 1], xtol=1e-12))
    roots = sorted(set(np.round(roots, 12)))
    if not roots:
        raise InputError("force", f"no radial depth in (0, {2e3 * radius:.2f}] mm gives the measured"
                         f" force angle {math.degrees(measured):.1f} deg; check the cutting frame"
                         " and the milling mode")
    if len(roots) > 1:
        if prior is None:
            raise InputError("force", "several radial depths explain the measured force angle ("
                             + ", ".join(f"{1e3 * r:.3f}" for r in roots)
                             + " mm); give the planned a_e as prior")
        return float(min(roots, key=lambda r: abs(r - prior)))
    return float(roots[0])
