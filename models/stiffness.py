"""Cartesian stiffness of a serial arm: conventional (congruence) and CCT (docs/model.md §3).

All functions build CasADi expressions (SX) so the planner can differentiate and map them; the few
``*_np`` helpers are numeric conveniences for reports.

- Conventional (Mason–Salisbury): K = J⁻ᵀ K_θ J⁻¹.
- CCT (Chen & Kao): K = J⁻ᵀ (K_θ − K_c) J⁻¹ with K_c(θ, W) = ∂(J(θ)ᵀ W)/∂θ, W = [f; m] the wrench
  acting on the tool at the TCP, base axes, held constant while differentiating. (The thesis prints
  ∂J⁻ᵀ/∂θᵢ·F, which is dimensionally wrong; docs/model.md §3 fixes it to this form.)
- J is never inverted: the Cartesian compliance C = J (K_θ − K_c)⁻¹ Jᵀ, and the translational
  stiffness used everywhere (pure force at the TCP, rotations free) is K_t = (C[0:3, 0:3])⁻¹.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

__all__ = [
    "cct_term",
    "compliance",
    "principal_stiffness",
    "principal_stiffness_np",
    "translational_compliance",
    "translational_stiffness",
]


def cct_term(jacobian: ca.SX, q: ca.SX, wrench: ca.SX) -> ca.SX:
    """K_c = ∂(Jᵀ W)/∂θ [N·m/rad], shape (n, n); column i is ∂Jᵀ/∂θᵢ · W.

    Args:
        jacobian: J(q), shape (6, n) (or (3, n) with a pure force ``wrench`` of shape (3,)).
        q: the joint symbols J depends on, shape (n,).
        wrench: W acting on the tool [N; N·m], base axes, shape (6,) or (3,); must not depend on q
            (if it does, the derivative is taken with it held constant anyway: it is substituted).
    """
    w = ca.SX.sym("w_const", wrench.shape[0])
    k_c = ca.jacobian(jacobian.T @ w, q)
    return ca.substitute(k_c, w, wrench)


def compliance(jacobian: ca.SX, joint_stiffness: ca.SX, k_c: ca.SX | None = None) -> ca.SX:
    """Cartesian compliance C = J (K_θ − K_c)⁻¹ Jᵀ, shape (6, 6) [m/N, rad/(N·m) blocks].

    Args:
        jacobian: J, shape (6, n).
        joint_stiffness: K_θ [N·m/rad], shape (n, n) (or (n,) for a diagonal).
        k_c: the CCT term [N·m/rad], shape (n, n); ``None`` for the conventional model.
    """
    k = _joint_matrix(joint_stiffness)
    if k_c is not None:
        k = k - k_c
    return jacobian @ ca.solve(k, jacobian.T)


def translational_compliance(jacobian: ca.SX, joint_stiffness: ca.SX,
                             k_c: ca.SX | None = None) -> ca.SX:
    """C_tt = J_v (K_θ − K_c)⁻¹ J_vᵀ [m/N], shape (3, 3): the TCP's translational compliance.

    Same arguments as :func:`compliance`; only the linear rows of J are used (cheaper).
    """
    k = _joint_matrix(joint_stiffness)
    if k_c is not None:
        k = k - k_c
    jv = jacobian[0:3, :]
    c = jv @ ca.solve(k, jv.T)
    return 0.5 * (c + c.T)


def translational_stiffness(c_tt: ca.SX) -> ca.SX:
    """K_t = C_tt⁻¹ [N/m], shape (3, 3), symmetric (closed-form 3×3 inverse)."""
    k = ca.inv(c_tt)
    return 0.5 * (k + k.T)


def _joint_matrix(joint_stiffness: ca.SX) -> ca.SX:
    k = joint_stiffness
    if k.shape[1] == 1:
        k = ca.diag(k)
    return k


def principal_stiffness(k: ca.SX) -> tuple[ca.SX, ca.SX]:
    """Principal stiffnesses and directions of a symmetric 3×3 K, symbolically.

    Eigenvalues by the trigonometric (Smith) formula, eigenvectors as the largest cross product of two
    rows of K − λI (robust for distinct eigenvalues; for a repeated eigenvalue any vector of its
    eigenspace is a valid answer and the one returned may be arbitrary).

    Returns:
        (values [N/m] shape (3,), descending; directions shape (3, 3), column i unit for value i).
    """
    q = ca.trace(k) / 3.0
    b = k - q * ca.SX.eye(3)
    p2 = ca.sumsqr(b) / 6.0
    p = ca.sqrt(p2)
    # Guard the isotropic case p = 0: every direction is principal.
    p_safe = ca.fmax(p, 1e-300)
    r = ca.det(b / p_safe) / 2.0
    phi = ca.acos(ca.fmin(ca.fmax(r, -1.0), 1.0)) / 3.0
    l1 = q + 2.0 * p * ca.cos(phi)
    l3 = q + 2.0 * p * ca.cos(phi + 2.0 * np.pi / 3.0)
    l2 = 3.0 * q - l1 - l3
    values = ca.vertcat(l1, l2, l3)
    cols = []
    for lam in (l1, l2, l3):
        m = k - lam * ca.SX.eye(3)
        c01 = ca.cross(m[0, :].T, m[1, :].T)
        c02 = ca.cross(m[0, :].T, m[2, :].T)
        c12 = ca.cross(m[1, :].T, m[2, :].T)
        n01, n02, n12 = ca.sumsqr(c01), ca.sumsqr(c02), ca.sumsqr(c12)
        best = ca.if_else(n01 >= ca.fmax(n02, n12), c01, ca.if_else(n02 >= n12, c02, c12))
        cols.append(best / ca.sqrt(ca.fmax(ca.sumsqr(best), 1e-300)))
    return values, ca.horzcat(*cols)


def principal_stiffness_np(k: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Numeric principal stiffnesses (descending) [N/m] and unit directions (columns) of symmetric K."""
    w, v = np.linalg.eigh(0.5 * (np.asarray(k, float) + np.asarray(k, float).T))
    order = np.argsort(w)[::-1]
    return w[order], v[:, order]
