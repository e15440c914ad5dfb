"""Mode-coupling chatter: the 2-DOF eigenvalue criterion of docs/model.md §5, as CasADi expressions.

Pieces, in the order of docs/model.md §5:

1. :func:`force_frame` — Δ: Δ_o rotated by α about −Y_o (X along the in-plane force, Y = Y_o).
2./3. :func:`principal_2x2` — K_max, K_min and the K_max direction of the 2×2 stiffness block,
   optionally with a 2×2 mass block (generalised eigenproblem, Vᵀ M₂ V = m̄ I, Vᵀ K₂ V = diag).
4. :func:`wrap_direction` — γ wrapped to (−90°, 90°] (a stiffness direction has no sign).
5. :func:`thesis_process_stiffness` — K_p = [cos β; sin β]·[K_px, K_py] (the ``oriented`` model lives
   in :mod:`models.cutting`, beside the instantaneous force it is derived from).
6. :func:`stability_matrix`, :func:`eigen_2x2`, :func:`stability_margin`.

**Mass normalisation.** With a mass block the modal matrix V is scaled so that Vᵀ M₂ V = m̄ I with
m̄ = tr(M₂)/2 (the mean modal mass). Then Vᵀ K₂ V = diag(K_max, K_min) are still stiffnesses [N/m]
(K_i = m̄ ω_i²), A = Vᵀ K_p V − diag(K_max, K_min) is in N/m, and its eigenvalues are m̄ times those
of M₂⁻¹(K_p − K₂): the verdict is the mass-weighted one. With M₂ = m I (``isotropic``) V is
orthonormal and the verdict depends on stiffness only.

**Stability margin** [N/m] (ours; the thesis has none). A 2×2 A is stable iff both eigenvalues are
real and negative. Let λ_hi ≥ λ_lo be its eigenvalues when real. The margin is

    margin = min(−λ_hi, (λ_hi − λ_lo)/2)                         when (tr A)² − 4 det A ≥ 0,
    margin = min(−Re λ, −|Im λ|)                                   otherwise,

i.e. the distance of the least stable eigenvalue from zero (static divergence) or half the gap
between the two (the two modes coalesce before they flutter: mode coupling). margin > 0 ⇔ stable;
margin = 0 is the boundary. One closed form covers both cases:
``r = sign(disc)·√|disc|/2``, ``margin = min(−tr/2 − max(r, 0), r)``.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

__all__ = [
    "eigen_2x2",
    "force_frame",
    "gamma_window_margin",
    "principal_2x2",
    "stability_margin",
    "stability_matrix",
    "thesis_process_stiffness",
    "wrap_direction",
]

#: Below this |K₂ off-diagonal| + |K₂ diagonal difference| [N/m] the 2×2 stiffness is isotropic and
#: its principal direction undefined; atan2(0, 0) = 0 is then returned (X axis), harmless.


def force_frame(alpha: ca.SX, x_o: ca.SX, y_o: ca.SX, z_o: ca.SX) -> ca.SX:
    """Δ: columns (X, Y, Z) in base axes, Δ_o rotated by α about −Y_o.

    X = cos α X_o + sin α Z_o (along the force's X_o–Z_o component), Y = Y_o,
    Z = cos α Z_o − sin α X_o. Shape (3, 3).
    """
    ca_, sa = ca.cos(alpha), ca.sin(alpha)
    x = ca_ * x_o + sa * z_o
    z = ca_ * z_o - sa * x_o
    return ca.horzcat(x, y_o, z)


def wrap_direction(angle: ca.SX) -> ca.SX:
    """Wrap an angle between undirected lines [rad] to (−π/2, π/2]."""
    return np.pi / 2 - (np.pi / 2 - angle - np.pi * ca.floor((np.pi / 2 - angle) / np.pi))


def principal_2x2(k2: ca.SX, m2: ca.SX | None = None) -> dict[str, ca.SX]:
    """Principal stiffnesses of a symmetric 2×2 K₂, optionally mass-weighted.

    Args:
        k2: stiffness block [N/m], shape (2, 2), symmetric.
        m2: mass block [kg], shape (2, 2), symmetric positive definite; ``None`` = isotropic.

    Returns:
        dict with ``k_max``, ``k_min`` [N/m]; ``v`` (2, 2) modal matrix, column 0 the K_max mode;
        ``theta_max`` [rad] the K_max direction's angle from the plane's first axis;
        ``omega2`` (2,) [1/s²] the squared natural frequencies (only when ``m2`` is given).
    """
    if m2 is None:
        a, b, d = k2[0, 0], 0.5 * (k2[0, 1] + k2[1, 0]), k2[1, 1]
        half = 0.5 * (a - d)
        rad = ca.sqrt(half * half + b * b)
        mean = 0.5 * (a + d)
        theta = 0.5 * ca.atan2(2.0 * b, a - d)
        c, s = ca.cos(theta), ca.sin(theta)
        v = ca.vertcat(ca.horzcat(c, -s), ca.horzcat(s, c))
        return {"k_max": mean + rad, "k_min": mean - rad, "v": v, "theta_max": theta}
    # Generalised: M₂ = L Lᵀ, K̃ = L⁻¹ K₂ L⁻ᵀ (symmetric), K̃ = U Ω² Uᵀ, V = √m̄ L⁻ᵀ U.
    m_bar = 0.5 * (m2[0, 0] + m2[1, 1])
    l11 = ca.sqrt(m2[0, 0])
    l21 = 0.5 * (m2[0, 1] + m2[1, 0]) / l11
    l22 = ca.sqrt(m2[1, 1] - l21 * l21)
    l_inv = ca.vertcat(ca.horzcat(1.0 / l11, 0.0), ca.horzcat(-l21 / (l11 * l22), 1.0 / l22))
    kt = l_inv @ k2 @ l_inv.T
    inner = principal_2x2(kt)
    v = ca.sqrt(m_bar) * (l_inv.T @ inner["v"])
    theta = ca.atan2(v[1, 0], v[0, 0])
    return {"k_max": m_bar * inner["k_max"], "k_min": m_bar * inner["k_min"], "v": v,
            "theta_max": wrap_direction(theta),
            "omega2": ca.vertcat(inner["k_max"], inner["k_min"])}


def thesis_process_stiffness(beta: ca.SX, k_px: ca.SX, k_py: ca.SX) -> ca.SX:
    """K_p = [cos β; sin β]·[K_px, K_py] [N/m], shape (2, 2), in Δ's X–Y plane (docs/model.md §5, `thesis`).

    Rank one: the mean force changes along its own direction (angle β from X) when the engagement
    changes (x: radial, y: axial). Rows = force components, columns = displacement components.
    """
    return ca.vertcat(ca.cos(beta), ca.sin(beta)) @ ca.horzcat(k_px, k_py)


def stability_matrix(v: ca.SX, k_p: ca.SX, k_max: ca.SX, k_min: ca.SX) -> ca.SX:
    """A = Vᵀ K_p V − diag(K_max, K_min) [N/m], shape (2, 2)."""
    return v.T @ k_p @ v - ca.diag(ca.vertcat(k_max, k_min))


def eigen_2x2(a: ca.SX) -> dict[str, ca.SX]:
    """Eigenvalues of a real 2×2 matrix in closed form.

    Returns:
        dict with ``tr``, ``det``, ``disc`` = tr² − 4 det, ``re`` (2,), ``im`` (2,) (first the one
        with the larger real part, or the +i one for a complex pair).
    """
    tr = a[0, 0] + a[1, 1]
    det = a[0, 0] * a[1, 1] - a[0, 1] * a[1, 0]
    disc = tr * tr - 4.0 * det
    root = ca.sqrt(ca.fabs(disc))
    real_pair = disc >= 0
    re1 = ca.if_else(real_pair, 0.5 * (tr + root), 0.5 * tr)
    re2 = ca.if_else(real_pair, 0.5 * (tr - root), 0.5 * tr)
    im = ca.if_else(real_pair, 0.0, 0.5 * root)
    return {"tr": tr, "det": det, "disc": disc, "re": ca.vertcat(re1, re2),
            "im": ca.vertcat(im, -im)}


def stability_margin(tr: ca.SX, disc: ca.SX) -> ca.SX:
    """The scalar stability margin [N/m] of the module docstring (> 0 stable)."""
    r = ca.sign(disc) * ca.sqrt(ca.fabs(disc)) / 2.0
    return ca.fmin(-tr / 2.0 - ca.fmax(r, 0.0), r)


def gamma_window_margin(gamma: ca.SX, gamma_lo: ca.SX, gamma_hi: ca.SX) -> ca.SX:
    """Distance of γ inside the calibrated window [γ_lo, γ_hi] [rad] (> 0 stable; docs/model.md §5)."""
    return ca.fmin(gamma - gamma_lo, gamma_hi - gamma)
