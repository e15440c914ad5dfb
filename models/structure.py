"""The arm's structure at a pose for the time-domain models (docs/model.md §6): 2-DOF in the plane normal
to the tool axis, coordinates x = (x_Xo, x_Zo) [m] along the cutting frame's X_o (radial) and Z_o
(feed) axes (docs/model.md §4), M ẍ + C ẋ + K x = F(t).

M is the Cartesian translational mass at the TCP (CRBA of the URDF plus the spindle point mass,
Λ = (J_v M_q⁻¹ J_vᵀ)⁻¹) and K the CCT translational stiffness K_t under the mean cutting force
(:func:`models.analysis.point_function`'s ``stiffness``), both projected on (X_o, Z_o) and
symmetrised; C is modal (stiffness-and-mass proportional per mode) with one damping ratio ζ.
The simulation (:mod:`models.dynamics`) and the Floquet criterion (:mod:`models.floquet`) use it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cache

import casadi as ca
import numpy as np
import scipy.linalg

from models.analysis import Cut, ModelParameters, point_function
from models.errors import InputError
from models.robot import Robot

__all__ = [
    "DEFAULT_DAMPING_RATIO",
    "Structure",
    "modal_damping",
    "pose_structure",
    "tcp_mass",
    "tcp_mass_function",
]

#: Damping ratio of both arm modes when judging stability [-] (docs/model.md §6: an undamped run sits on
#: the margin; 2 % is a typical structural value for a robot arm).
DEFAULT_DAMPING_RATIO = 0.02


@dataclass(frozen=True)
class Structure:
    """The arm's 2-DOF structure in the plane (X_o, Z_o) at one pose. SI.

    Attributes:
        mass: M [kg], shape (2, 2), symmetric positive definite.
        stiffness: K [N/m], shape (2, 2), symmetric positive definite.
        damping: C [N·s/m], shape (2, 2).
        plane: the plane's axes X_o, Z_o in base axes, shape (3, 2).
        damping_ratio: ζ used to build ``damping`` [-] (NaN when C was given directly).
    """

    mass: np.ndarray
    stiffness: np.ndarray
    damping: np.ndarray
    plane: np.ndarray
    damping_ratio: float = float("nan")

    def __post_init__(self) -> None:
        for name in ("mass", "stiffness", "damping"):
            value = np.asarray(getattr(self, name), float)
            if value.shape != (2, 2) or not np.all(np.isfinite(value)):
                raise InputError(name, f"need a finite 2x2 matrix, got shape {value.shape}")
            object.__setattr__(self, name, value)
        for name in ("mass", "stiffness"):
            if np.linalg.eigvalsh(0.5 * (getattr(self, name) + getattr(self, name).T))[0] <= 0:
                raise InputError(name, "must be positive definite")

    @property
    def natural_frequencies_hz(self) -> np.ndarray:
        """Undamped natural frequencies [Hz], ascending, shape (2,)."""
        omega2 = scipy.linalg.eigh(self.stiffness, self.mass, eigvals_only=True)
        return np.sqrt(np.maximum(omega2, 0.0)) / (2.0 * np.pi)

    def state_matrix(self, process_stiffness: np.ndarray | None = None) -> np.ndarray:
        """ż = A z for z = (x, ẋ), with an optional process stiffness K_p [N/m] (F = K_p x), (4, 4)."""
        k = self.stiffness if process_stiffness is None else self.stiffness - process_stiffness
        m_inv = np.linalg.inv(self.mass)
        return np.block([[np.zeros((2, 2)), np.eye(2)], [-m_inv @ k, -m_inv @ self.damping]])


def modal_damping(mass: np.ndarray, stiffness: np.ndarray, ratio: float) -> np.ndarray:
    """C [N·s/m] with damping ratio ``ratio`` in both modes: C = M V diag(2ζω) Vᵀ M, VᵀMV = I."""
    if not (math.isfinite(ratio) and 0.0 <= ratio < 1.0):
        raise InputError("damping ratio", f"must lie in [0, 1), got {ratio!r}")
    omega2, v = scipy.linalg.eigh(stiffness, mass)
    omega = np.sqrt(np.maximum(omega2, 0.0))
    return mass @ v @ np.diag(2.0 * ratio * omega) @ v.T @ mass


@cache
def tcp_mass_function(robot: Robot) -> ca.Function:
    """Built once per robot: (joints q [rad], TCP offset [m] (3,), spindle mass [kg], spindle centre
    of mass [m] (3,), both offsets in the flange frame) -> the Cartesian translational mass at the
    TCP [kg], (3, 3), base axes. :func:`tcp_mass` evaluates it; the Floquet path maps it."""
    sym = robot.symbolic
    m_sp = ca.SX.sym("spindle_mass")
    com = ca.SX.sym("spindle_com", 3)
    mass = robot.mass_matrix_expr(m_sp, com)
    jv = sym.jacobian[0:3, :]
    lam = ca.inv(jv @ ca.solve(mass, jv.T))
    return ca.Function("tcp_mass", [sym.q, sym.tcp, m_sp, com], [0.5 * (lam + lam.T)],
                       ["q", "tcp", "spindle_mass", "spindle_com"], ["mass"])


def tcp_mass(robot: Robot, q: np.ndarray, params: ModelParameters) -> np.ndarray:
    """Cartesian translational mass at the TCP [kg], shape (3, 3), base axes (docs/model.md §5 `robot`)."""
    f = tcp_mass_function(robot)
    return np.asarray(f(np.asarray(q, float), np.asarray(params.tcp, float), params.spindle_mass,
                        np.asarray(params.spindle_com, float)), float)


def pose_structure(robot: Robot, params: ModelParameters, q: np.ndarray, cut: Cut, feed: float,
                   damping_ratio: float = DEFAULT_DAMPING_RATIO) -> Structure:
    """The 2-DOF structure at joints ``q`` [rad] for ``cut`` at ``feed`` [m/s].

    K is the (CCT, if ``params.cct``) translational stiffness under the mean cutting force at this
    feed, M the robot's Cartesian mass; both projected on (X_o, Z_o) and symmetrised.
    """
    f = point_function(robot, "oriented", "isotropic", outputs=("stiffness",))
    k_t = np.asarray(f(np.asarray(q, float), cut.vector(), feed, params.vector()), float)
    if not np.all(np.isfinite(k_t)):
        raise InputError("pose", "the stiffness is not finite here (singular pose)")
    plane = np.column_stack([cut.radial_dir, cut.feed_dir])
    k2 = plane.T @ k_t @ plane
    m2 = plane.T @ tcp_mass(robot, q, params) @ plane
    k2, m2 = 0.5 * (k2 + k2.T), 0.5 * (m2 + m2.T)
    return Structure(m2, k2, modal_damping(m2, k2, damping_ratio), plane, damping_ratio)
