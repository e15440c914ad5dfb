"""The whole point model as one CasADi ``Function``: pose + cut + feed + parameters → every quantity.

``point(q, cut, feed, params)`` returns the average cutting force, the CCT (or conventional)
translational stiffness, the static deflection, α, β, γ, the cutting stiffnesses, the process
stiffness of the chosen model, the 2×2 stability matrix A with its eigenvalues, the scalar stability
margin and the verdict, the γ-window margin, and (``robot`` mass model) the 2-DOF natural
frequencies. The planner maps the very same Function over path samples (``Function.map``).

Inputs (column vectors, SI):
    q      [rad], (n,)                   joint angles (KUKA axis values)
    cut    (12,)  see :data:`CUT_LAYOUT`   Z_o, X_o (base axes), a_e, a_p, mode, spindle speed, N, R
    feed   [m/s], (1,)                    feed speed v_f
    params (23,)  see :data:`PARAM_LAYOUT` K_θ, CCT switch, cutting coefficients, K_p gain, TCP,
                  γ window, spindle

Build-time choices (they change the graph, so each combination is its own Function, cached):
``process_model`` ∈ {``thesis``, ``oriented``} and ``mass_model`` ∈ {``isotropic``, ``robot``}.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cache

import casadi as ca
import numpy as np

from models import chatter, cutting, stiffness
from models.errors import InputError
from models.robot import Robot

__all__ = [
    "CUT_LAYOUT",
    "MASS_MODELS",
    "OUTPUTS",
    "PARAM_LAYOUT",
    "PROCESS_MODELS",
    "Cut",
    "ModelParameters",
    "path_inputs",
    "point_function",
]

PROCESS_MODELS = ("thesis", "oriented")
MASS_MODELS = ("isotropic", "robot")

#: name → (offset, size) of the ``cut`` input vector.
CUT_LAYOUT: dict[str, tuple[int, int]] = {
    "feed_dir": (0, 3), "radial_dir": (3, 3), "a_e": (6, 1), "a_p": (7, 1), "mode": (8, 1),
    "spindle_speed": (9, 1), "flutes": (10, 1), "radius": (11, 1),
}
#: name → (offset, size) of the ``params`` input vector.
PARAM_LAYOUT: dict[str, tuple[int, int]] = {
    "joint_stiffness": (0, 6), "cct": (6, 1), "coefficients": (7, 6), "process_gain": (13, 1),
    "tcp": (14, 3), "gamma_window": (17, 2), "spindle_mass": (19, 1), "spindle_com": (20, 3),
}
N_CUT = 12
N_PARAMS = 23

#: Directions given by the user must be unit and orthogonal to this tolerance [-] (cosine).
ORTHOGONALITY_TOL = 1e-3


def _unit(v, name: str) -> np.ndarray:
    v = np.asarray(v, dtype=float).reshape(-1)
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise InputError(name, "need three finite numbers X,Y,Z")
    norm = np.linalg.norm(v)
    if norm == 0.0:
        raise InputError(name, "direction is the zero vector")
    return v / norm


@dataclass(frozen=True)
class Cut:
    """One cutting condition at one point. SI.

    Attributes:
        feed_dir: Z_o, the feed direction in base axes, shape (3,) (normalised on construction).
        radial_dir: X_o, the radial direction (cutting edge at φ = 0) in base axes, shape (3,);
            must be orthogonal to ``feed_dir``. Y_o = Z_o × X_o runs along the axial depth.
        a_e: radial depth of cut [m].
        a_p: axial depth of cut [m].
        mode: ``"up"``, ``"down"`` or ``"slot"`` (docs/model.md §4: which side of X_o the material is on).
        spindle_speed: [rad/s].
        flutes: number of flutes N.
        radius: tool radius R [m].
    """

    feed_dir: np.ndarray
    radial_dir: np.ndarray
    a_e: float
    a_p: float
    mode: str
    spindle_speed: float
    flutes: int
    radius: float

    def __post_init__(self) -> None:
        z = _unit(self.feed_dir, "feed direction")
        x = _unit(self.radial_dir, "radial direction")
        if abs(float(z @ x)) > ORTHOGONALITY_TOL:
            raise InputError("radial direction", f"must be orthogonal to the feed direction "
                             f"(angle {np.degrees(np.arccos(np.clip(z @ x, -1, 1))):.2f} deg)")
        x = x - (z @ x) * z
        object.__setattr__(self, "feed_dir", z)
        object.__setattr__(self, "radial_dir", x / np.linalg.norm(x))
        if self.mode not in cutting.MILLING_MODES:
            raise InputError("milling", f"{self.mode!r} is not one of up, down, slot")
        if not self.radius > 0.0:
            raise InputError("tool radius", "must be positive")
        try:
            whole = int(self.flutes) == self.flutes
        except (TypeError, ValueError, OverflowError):  # NaN, ±inf, non-numbers
            whole = False
        if not whole or self.flutes < 1:
            raise InputError("flutes", "must be a positive integer")
        if self.mode == "slot":
            if not np.isclose(self.a_e, 2.0 * self.radius, rtol=1e-6):
                raise InputError("radial depth", f"a slot engages the full diameter "
                                 f"({2e3 * self.radius:.3f} mm), got {1e3 * self.a_e:.3f} mm")
        elif not 0.0 < self.a_e <= 2.0 * self.radius:
            raise InputError("radial depth", f"{1e3 * self.a_e:.3f} mm must lie in "
                             f"(0, {2e3 * self.radius:.3f}] mm (the tool diameter)")
        if not self.a_p > 0.0:
            raise InputError("axial depth", "must be positive")
        if not self.spindle_speed > 0.0:
            raise InputError("spindle speed", "must be positive")

    @property
    def axial_dir(self) -> np.ndarray:
        """Y_o = Z_o × X_o in base axes, shape (3,)."""
        return np.cross(self.feed_dir, self.radial_dir)

    def vector(self) -> np.ndarray:
        """The ``cut`` input of :func:`point_function`, shape (12,)."""
        return np.concatenate([self.feed_dir, self.radial_dir,
                               [self.a_e, self.a_p, cutting.MILLING_MODES[self.mode],
                                self.spindle_speed, float(self.flutes), self.radius]])


@dataclass(frozen=True)
class ModelParameters:
    """Every tunable of the point model, explicit so a user can calibrate it (docs/model.md §5). SI.

    Attributes:
        joint_stiffness: K_θ diagonal [N·m/rad], shape (6,).
        coefficients: cutting coefficients [K_tc, K_rc, K_ac (N/m²), K_te, K_re, K_ae (N/m)].
        cct: include the CCT term K_c (False = conventional stiffness).
        process_gain: multiplies K_p (1 = the model as printed).
        tcp: TCP offset in the flange frame [m], shape (3,).
        gamma_window: (γ_lo, γ_hi) [rad] of the ``gamma_window`` criterion; the default full range
            means "not calibrated" (always stable).
        spindle_mass: [kg] (``robot`` mass model).
        spindle_com: spindle centre of mass in the flange frame [m], shape (3,).
    """

    joint_stiffness: np.ndarray
    coefficients: np.ndarray
    cct: bool = True
    process_gain: float = 1.0
    tcp: np.ndarray = field(default_factory=lambda: np.zeros(3))
    gamma_window: tuple[float, float] = (-np.pi / 2, np.pi / 2)
    spindle_mass: float = 100.0
    spindle_com: np.ndarray = field(default_factory=lambda: np.array([0.15, 0.0, 0.0]))

    def vector(self) -> np.ndarray:
        """The ``params`` input of :func:`point_function`, shape (23,)."""
        v = np.concatenate([
            np.asarray(self.joint_stiffness, float).reshape(6), [1.0 if self.cct else 0.0],
            np.asarray(self.coefficients, float).reshape(6), [self.process_gain],
            np.asarray(self.tcp, float).reshape(3), np.asarray(self.gamma_window, float),
            [self.spindle_mass], np.asarray(self.spindle_com, float).reshape(3)])
        assert v.shape == (N_PARAMS,)  # layout guard for developers, not input validation
        return v


def _part(vec: ca.SX, layout: dict[str, tuple[int, int]], name: str) -> ca.SX:
    offset, size = layout[name]
    return vec[offset:offset + size]


#: Output names of the full point Function, in order.
OUTPUTS = (
    "force_o", "force_base", "alpha", "beta", "gamma", "k_pxo", "k_px", "k_py", "k_max", "k_min",
    "k_p", "a", "eig_re", "eig_im", "tr", "det", "disc", "margin", "stable", "gamma_margin",
    "stiffness", "compliance", "deflection", "omega2", "tool_axis_angle", "plane", "tcp_position",
    "tool_axis", "feed_per_tooth", "principal_values", "principal_directions", "power",
)


def _build_outputs(robot: Robot, process_model: str, mass_model: str) -> tuple[list, dict]:
    sym = robot.symbolic
    q = sym.q
    cut = ca.SX.sym("cut", N_CUT)
    feed = ca.SX.sym("feed")
    params = ca.SX.sym("params", N_PARAMS)

    def c_(name):
        return _part(cut, CUT_LAYOUT, name)

    def p_(name):
        return _part(params, PARAM_LAYOUT, name)

    z_o = c_("feed_dir") / ca.norm_2(c_("feed_dir"))
    x_o = c_("radial_dir") / ca.norm_2(c_("radial_dir"))
    y_o = ca.cross(z_o, x_o)
    a_e, a_p, mode = c_("a_e"), c_("a_p"), c_("mode")
    flutes, radius = c_("flutes"), c_("radius")
    coeffs = p_("coefficients")
    c = cutting.feed_per_tooth(feed, flutes, c_("spindle_speed") * 60.0 / (2.0 * np.pi))

    f_o = cutting.average_force(c, a_e, a_p, mode, flutes, radius, coeffs)
    power = cutting.average_torque(c, a_e, a_p, mode, flutes, radius, coeffs) * c_("spindle_speed")
    f_base = x_o * f_o[0] + y_o * f_o[1] + z_o * f_o[2]
    ks = cutting.cutting_stiffness(c, a_e, a_p, mode, flutes, radius, coeffs)
    alpha = ks["alpha"]

    # Stiffness at the TCP under the average cutting force (pure force, no moment).
    jac = ca.substitute(sym.jacobian, sym.tcp, p_("tcp"))
    k_c = stiffness.cct_term(jac[0:3, :], q, f_base) * p_("cct")
    c_tt = stiffness.translational_compliance(jac, p_("joint_stiffness"), k_c)
    k_t = stiffness.translational_stiffness(c_tt)
    deflection = c_tt @ f_base
    principal_values, principal_directions = stiffness.principal_stiffness(k_t)

    # The 2-DOF plane.
    if process_model == "thesis":
        delta = chatter.force_frame(alpha, x_o, y_o, z_o)
        plane = delta[:, 0:2]
        f_inplane = ca.sqrt(f_o[0] ** 2 + f_o[2] ** 2)
        force_angle = ca.atan2(f_o[1], f_inplane)  # β
        k_p = chatter.thesis_process_stiffness(force_angle, ks["k_px"], ks["k_py"])
    elif process_model == "oriented":
        plane = ca.horzcat(x_o, z_o)
        force_angle = alpha
        k_p = cutting.oriented_process_stiffness(a_e, a_p, mode, flutes, radius, coeffs)
    else:
        raise InputError("process model", f"{process_model!r} is not one of {PROCESS_MODELS}")
    k_p = k_p * p_("process_gain")
    k2 = plane.T @ k_t @ plane
    k2 = 0.5 * (k2 + k2.T)

    if mass_model == "isotropic":
        m2 = None
    elif mass_model == "robot":
        mass = robot.mass_matrix_expr(p_("spindle_mass"), p_("spindle_com"))
        jv = jac[0:3, :]
        lam = ca.inv(jv @ ca.solve(mass, jv.T))  # Cartesian translational mass at the TCP [kg]
        m2 = plane.T @ (0.5 * (lam + lam.T)) @ plane
    else:
        raise InputError("mass model", f"{mass_model!r} is not one of {MASS_MODELS}")
    pr = chatter.principal_2x2(k2, m2)
    gamma = chatter.wrap_direction(pr["theta_max"] - force_angle)

    a = chatter.stability_matrix(pr["v"], k_p, pr["k_max"], pr["k_min"])
    eig = chatter.eigen_2x2(a)
    margin = chatter.stability_margin(eig["tr"], eig["disc"])
    stable = (eig["tr"] < 0) * (eig["det"] > 0) * (eig["disc"] >= 0)
    window = p_("gamma_window")
    gamma_margin = chatter.gamma_window_margin(gamma, window[0], window[1])

    tool_axis = sym.rotation[:, 0]
    cos_axis = ca.fabs(ca.dot(tool_axis, y_o))
    tool_axis_angle = ca.acos(ca.fmin(cos_axis, 1.0))
    omega2 = pr.get("omega2", ca.SX.zeros(2))
    tcp_pos = ca.substitute(sym.position, sym.tcp, p_("tcp"))

    values = {
        "force_o": f_o, "force_base": f_base, "alpha": alpha, "beta": force_angle,
        "gamma": gamma, "k_pxo": ks["k_pxo"], "k_px": ks["k_px"], "k_py": ks["k_py"],
        "k_max": pr["k_max"], "k_min": pr["k_min"], "k_p": k_p, "a": a, "eig_re": eig["re"],
        "eig_im": eig["im"], "tr": eig["tr"], "det": eig["det"], "disc": eig["disc"],
        "margin": margin, "stable": stable, "gamma_margin": gamma_margin, "stiffness": k_t,
        "compliance": c_tt, "deflection": deflection, "omega2": omega2,
        "tool_axis_angle": tool_axis_angle, "plane": plane, "tcp_position": tcp_pos,
        "tool_axis": tool_axis, "feed_per_tooth": c, "principal_values": principal_values,
        "principal_directions": principal_directions, "power": power,
    }
    return [q, cut, feed, params], values


@cache
def _cached_point_function(robot: Robot, process_model: str, mass_model: str,
                           outputs: tuple[str, ...]) -> ca.Function:
    # Keyed on the Robot object itself (identity): a Robot built from other data must not be
    # swapped for the shipped robot of the same name. load_robot() caches, so shipped robots hit.
    inputs, values = _build_outputs(robot, process_model, mass_model)
    return ca.Function(f"point_{process_model}_{mass_model}", inputs,
                       [values[k] for k in outputs], ["q", "cut", "feed", "params"],
                       list(outputs))


def point_function(robot: Robot, process_model: str = "thesis", mass_model: str = "isotropic",
                   outputs: tuple[str, ...] | None = None) -> ca.Function:
    """The point model as a CasADi Function ``(q, cut, feed, params) -> outputs``.

    Args:
        robot: the robot (its symbolic kinematics are reused).
        process_model: ``"thesis"`` (default) or ``"oriented"`` (docs/model.md §5 step 5).
        mass_model: ``"isotropic"`` (default) or ``"robot"`` (CRBA + spindle, docs/model.md §5).
        outputs: subset of :data:`OUTPUTS` (a smaller graph is faster); default all.

    The Function is built once per (robot, choices, outputs) and cached. Map it over many points with
    ``f.map(n)`` (inputs with a single column are broadcast) or ``f.map(n, "thread", 2)``.
    """
    if process_model not in PROCESS_MODELS:
        raise InputError("process model", f"{process_model!r} is not one of {', '.join(PROCESS_MODELS)}")
    if mass_model not in MASS_MODELS:
        raise InputError("mass model", f"{mass_model!r} is not one of {', '.join(MASS_MODELS)}")
    outs = tuple(outputs) if outputs is not None else OUTPUTS
    unknown = [o for o in outs if o not in OUTPUTS]
    if unknown:
        raise InputError("outputs", f"unknown {unknown}; choose from {OUTPUTS}")
    return _cached_point_function(robot, process_model, mass_model, outs)


def path_inputs(q, cuts, feeds) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Check and shape the per-sample inputs of a path evaluation.

    Args:
        q: joints [rad], shape (n, nq) (or (nq,) for one sample).
        cuts: :meth:`Cut.vector` rows, shape (n, 12).
        feeds: feed speed [m/s], shape (n,).

    Returns:
        ``(q, cuts, feeds, n)`` as float arrays.
    """
    q = np.atleast_2d(np.asarray(q, float))
    cuts = np.atleast_2d(np.asarray(cuts, float))
    feeds = np.asarray(feeds, float).reshape(-1)
    n = q.shape[0]
    if cuts.shape != (n, N_CUT) or feeds.shape != (n,):
        raise InputError("path", f"need q (n, nq), cuts (n, {N_CUT}), feeds (n,); got {q.shape}, "
                         f"{cuts.shape}, {feeds.shape}")
    return q, cuts, feeds, n
