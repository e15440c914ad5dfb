"""Mechanistic cutting forces of a flat end mill (docs/model.md §4), `oriented` process stiffness (§5).

Frames and signs follow docs/model.md §4. The cutting frame Δ_o sits at the TCP: ``Z_o`` along the feed,
``X_o`` radial (the cutting edge at immersion φ = 0), ``Y_o = Z_o × X_o`` along the axial depth. The
edge angle φ runs from +X_o towards +Z_o; the edge's outward direction and direction of motion are

    n(φ) = (cos φ, 0, sin φ),   t(φ) = (−sin φ, 0, cos φ)      in (X_o, Y_o, Z_o) components.

Every force here is the force **on the tool**, in newtons.

The symbolic building blocks accept CasADi ``SX``/``MX`` expressions as well as plain floats
(then they return ``DM``) and contain no Python branching on symbolic values, so one expression
graph serves every milling mode and can sit inside an optimiser. The milling mode is a numeric code
(:data:`MILLING_MODES`: 0 up, 1 down, 2 slot) that may itself be symbolic; the names ``"up"``,
``"down"``, ``"slot"`` are accepted wherever a concrete mode is given.

Derivatives (cutting stiffness, oriented process stiffness) are produced by CasADi's algorithmic
differentiation from the same expressions that give the forces; the hand-derived closed forms are
kept only as test oracles.

Tools and materials (:class:`Tool`, :class:`Material` and their data files) are in
:mod:`models.tooling`; they are re-exported here.
"""

from __future__ import annotations

import math
from functools import cache
from typing import Any

import casadi as ca
import numpy as np

from .errors import InputError
from .tooling import (
    Material,
    Tool,
    available_materials,
    available_tools,
    load_material,
    load_tool,
)

__all__ = [
    "MILLING_MODES",
    "Material",
    "Tool",
    "available_materials",
    "available_tools",
    "average_force",
    "average_torque",
    "coefficient_design_function",
    "cutting_stiffness",
    "edge_forces",
    "feed_per_tooth",
    "immersion_angles",
    "instantaneous_force",
    "load_material",
    "load_tool",
    "oriented_process_stiffness",
    "oriented_process_stiffness_closed_form",
]

MILLING_MODES: dict[str, int] = {"up": 0, "down": 1, "slot": 2}
"""Numeric codes of the milling modes, as used by the symbolic functions."""

_MODE_UP, _MODE_DOWN, _MODE_SLOT = MILLING_MODES["up"], MILLING_MODES["down"], MILLING_MODES["slot"]

_MODE_SPLIT = 0.5
"""Half the spacing of the mode codes [-]: a symbolic mode m is 'down' for |m − 1| < this and 'slot'
for m > 2 − this, so a code that went through floating point still selects its mode."""

Scalar = Any
"""A float, or a CasADi ``SX``/``MX``/``DM`` scalar expression."""


# --------------------------------------------------------------------------------------------------
# Input handling
# --------------------------------------------------------------------------------------------------


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool)


def _mode_code(mode: Any) -> Any:
    """Turn a mode name or number into its numeric code; symbolic codes pass through unchanged."""
    if isinstance(mode, str):
        if mode not in MILLING_MODES:
            raise InputError(
                "mode", f"unknown milling mode {mode!r}; use one of {sorted(MILLING_MODES)}"
            )
        return MILLING_MODES[mode]
    if isinstance(mode, ca.DM) and mode.is_scalar():
        mode = float(mode)
    if _is_number(mode):
        if mode not in MILLING_MODES.values():
            raise InputError("mode", f"unknown milling mode code {mode!r}; use {MILLING_MODES}")
        return int(mode)
    return mode


def _check_engagement(a_e: Any, radius: Any, mode: Any) -> None:
    """Range checks that are possible when the values are concrete numbers."""
    if _is_number(radius) and not radius > 0:
        raise InputError("radius", f"tool radius must be > 0 [m], got {radius!r}")
    if _is_number(a_e) and _is_number(radius) and _is_number(mode) and mode != _MODE_SLOT:
        if not 0.0 < a_e <= 2.0 * radius:
            raise InputError(
                "a_e", f"radial depth must lie in (0, 2R] = (0, {2.0 * radius:g}] m, got {a_e!r}"
            )


def _coefficients(coeffs: Any) -> list[Any]:
    """Split a 6-vector of cutting coefficients (or a :class:`Material`) into its entries."""
    if isinstance(coeffs, Material):
        return [float(value) for value in coeffs.coefficients()]
    if isinstance(coeffs, (ca.SX, ca.MX, ca.DM)):
        if coeffs.numel() != 6:
            raise InputError("coeffs", f"need 6 cutting coefficients, got shape {coeffs.shape}")
        return [coeffs[i] for i in range(6)]
    if isinstance(coeffs, np.ndarray):
        coeffs = coeffs.ravel()
    if len(coeffs) != 6:
        raise InputError("coeffs", f"need 6 cutting coefficients, got {len(coeffs)}")
    return list(coeffs)


def _as_vector(coeffs: Any) -> Any:
    """A 6-vector argument for a CasADi Function call."""
    entries = _coefficients(coeffs)
    if all(_is_number(value) for value in entries):
        return np.array(entries, dtype=float)
    return ca.vertcat(*entries)


# --------------------------------------------------------------------------------------------------
# Kinematics of the cut
# --------------------------------------------------------------------------------------------------


def feed_per_tooth(feed: Scalar, flutes: Scalar, spindle_rpm: Scalar) -> Scalar:
    """Feed per tooth c = v_f / (N · n/60) [m].

    Args:
        feed: feed speed v_f [m/s].
        flutes: number of flutes N [-].
        spindle_rpm: spindle speed n [rev/min].
    """
    if _is_number(spindle_rpm) and not spindle_rpm > 0:
        raise InputError("spindle_rpm", f"spindle speed must be > 0 rpm, got {spindle_rpm!r}")
    return feed / (flutes * spindle_rpm / 60.0)


def _immersion(a_e: Scalar, radius: Scalar, code: Any) -> tuple[Scalar, Scalar, Scalar]:
    """(φ_st, φ_ex, pinned): ``pinned`` is true where the arc does not move with a_e (slot,
    a_e ≥ 2R, a_e ≤ 0), so that ∂φ/∂a_e is 0 there and every branch stays finite under AD."""
    is_down = ca.fabs(code - _MODE_DOWN) < _MODE_SPLIT
    ratio = 1.0 - a_e / radius
    full = ca.logic_or(code > _MODE_SLOT - _MODE_SPLIT, ratio <= -1.0)
    empty = ca.logic_and(ca.logic_not(full), ratio >= 1.0)
    pinned = ca.logic_or(full, empty)
    # arccos' derivative −1/√(1 − u²) is infinite at u = ±1: feed it a harmless 0 where unused.
    arc = ca.if_else(full, ca.pi, ca.if_else(empty, 0.0, ca.acos(ca.if_else(pinned, 0.0, ratio))))
    return ca.if_else(is_down, ca.pi - arc, 0.0), ca.if_else(is_down, ca.pi, arc), pinned


def immersion_angles(a_e: Scalar, radius: Scalar, mode: Any) -> tuple[Scalar, Scalar]:
    """Entry and exit immersion angles (φ_st, φ_ex) [rad] of the engaged arc (docs/model.md §4).

    up: 0 … arccos(1 − a_e/R); down: π − arccos(1 − a_e/R) … π; slot: 0 … π (``a_e`` is ignored).

    Args:
        a_e: radial depth of cut [m], in (0, 2R] for up and down milling.
        radius: tool radius R [m].
        mode: ``"up"``/``"down"``/``"slot"`` or the numeric code of :data:`MILLING_MODES`, possibly
            symbolic.

    Concrete numbers are range-checked (:class:`InputError`); symbolic ones cannot be, and are
    saturated instead: a_e ≥ 2R is the full arc 0 … π (up and down milling at a_e = 2R *are* a
    slot), a_e ≤ 0 the empty arc. Both branches of every selection are evaluated and differentiated
    by CasADi; arccos is never evaluated at ±1, so all derivatives stay finite (∂φ/∂a_e = 0 on the
    saturated parts). As a_e → 2R or a_e → 0 from inside, ∂φ/∂a_e grows without bound (a property
    of the geometry, not of the code).
    """
    code = _mode_code(mode)
    _check_engagement(a_e, radius, code)
    phi_st, phi_ex, _ = _immersion(a_e, radius, code)
    return phi_st, phi_ex


# --------------------------------------------------------------------------------------------------
# Instantaneous forces
# --------------------------------------------------------------------------------------------------


def _edge_magnitudes(h: Scalar, b: Scalar, k: list[Any]) -> tuple[Scalar, Scalar, Scalar]:
    k_tc, k_rc, k_ac, k_te, k_re, k_ae = k
    return k_tc * b * h + k_te * b, k_rc * b * h + k_re * b, k_ac * b * h + k_ae * b


def edge_forces(phi: Scalar, h: Scalar, b: Scalar, coeffs: Any) -> tuple[Scalar, Scalar, Scalar]:
    """Per-flute force magnitudes (F_t, F_r, F_a) [N] of one engaged edge slice (docs/model.md §4, §6).

    F_t = K_tc b h + K_te b, F_r = K_rc b h + K_re b, F_a = K_ac b h + K_ae b. ``phi`` is accepted
    for symmetry with :func:`instantaneous_force` and not used: once h is given the magnitudes do
    not depend on the angle. No engagement test (h ≤ 0, φ outside the arc) is made: the caller
    decides.

    Args:
        phi: immersion angle φ [rad] (unused).
        h: chip thickness [m].
        b: axial width of the slice [m].
        coeffs: [k_tc, k_rc, k_ac, k_te, k_re, k_ae] (N/m², N/m), shape (6,), or a
            :class:`Material`.
    """
    del phi
    return _edge_magnitudes(h, b, _coefficients(coeffs))


def _edge_force_xz(cos_phi: Scalar, sin_phi: Scalar, h: Scalar, b: Scalar, k: list[Any]) -> Any:
    """F = −F_t t − F_r n + F_a Y_o on the tool, (X_o, Y_o, Z_o) [N], 3x1; the single integrand."""
    f_t, f_r, f_a = _edge_magnitudes(h, b, k)
    return ca.vertcat(f_t * sin_phi - f_r * cos_phi, f_a, -f_t * cos_phi - f_r * sin_phi)


def instantaneous_force(phi: Scalar, h: Scalar, b: Scalar, coeffs: Any) -> Any:
    """Force on the tool from one engaged edge slice, (F_xo, F_yo, F_zo) [N], CasADi 3x1.

    F = −(K_tc b h + K_te b) t − (K_rc b h + K_re b) n + (K_ac b h + K_ae b) Y_o (docs/model.md §4). The
    rigid chip is h = c sin φ. No engagement test is made; the caller decides.

    Args:
        phi: immersion angle φ [rad].
        h: chip thickness [m].
        b: axial width of the slice [m].
        coeffs: [k_tc, k_rc, k_ac, k_te, k_re, k_ae] (N/m², N/m), shape (6,), or a
            :class:`Material`.
    """
    return _edge_force_xz(ca.cos(phi), ca.sin(phi), h, b, _coefficients(coeffs))


# --------------------------------------------------------------------------------------------------
# Tooth-period averages
# --------------------------------------------------------------------------------------------------


def _brackets(phi: Scalar, c: Scalar, k: list[Any]) -> tuple[Scalar, Scalar, Scalar]:
    """The bracketed antiderivatives of docs/model.md §4 (without the N a/8π, N a/2π factors)."""
    k_tc, k_rc, k_ac, k_te, k_re, k_ae = k
    cos_phi, sin_phi = ca.cos(phi), ca.sin(phi)
    cos_2phi, sweep = ca.cos(2.0 * phi), 2.0 * phi - ca.sin(2.0 * phi)
    b_x = c * (k_tc * sweep + k_rc * cos_2phi) - 4.0 * (k_te * cos_phi + k_re * sin_phi)
    b_y = -c * k_ac * cos_phi + k_ae * phi
    b_z = c * (k_tc * cos_2phi - k_rc * sweep) - 4.0 * (k_te * sin_phi - k_re * cos_phi)
    return b_x, b_y, b_z


def average_force(
    c: Scalar, a_e: Scalar, a_p: Scalar, mode: Any, flutes: Scalar, radius: Scalar, coeffs: Any
) -> Any:
    """Tooth-period average force on the tool (F_xo, F_yo, F_zo) [N], CasADi 3x1 (docs/model.md §4).

    The closed forms of docs/model.md §4 (the brackets evaluated from φ_st to φ_ex).

    Args:
        c: feed per tooth [m].
        a_e: radial depth of cut [m] (ignored in slot mode).
        a_p: axial depth of cut [m].
        mode: ``"up"``/``"down"``/``"slot"`` or its numeric code, possibly symbolic.
        flutes: number of flutes N [-].
        radius: tool radius R [m].
        coeffs: [k_tc, k_rc, k_ac, k_te, k_re, k_ae] (N/m², N/m), shape (6,), or a
            :class:`Material`.
    """
    k = _coefficients(coeffs)
    phi_st, phi_ex = immersion_angles(a_e, radius, mode)
    ex_x, ex_y, ex_z = _brackets(phi_ex, c, k)
    st_x, st_y, st_z = _brackets(phi_st, c, k)
    scale = flutes * a_p / (8.0 * ca.pi)
    return ca.vertcat(scale * (ex_x - st_x), 4.0 * scale * (ex_y - st_y), scale * (ex_z - st_z))


@cache
def coefficient_design_function() -> ca.Function:
    """Built once: (c, a_e, a_p, mode, N, R) -> ∂F̄/∂K, 3×6 (N/(N/m²) then N/(N/m)).

    The tooth-period average force is linear in the six coefficients, F̄ = A K, and A is affine
    in the feed per tooth c: the calibration's least squares and the planner's confidence bounds
    (:mod:`planner.limit_confidence`) both use it.
    """
    c, a_e, a_p, mode, flutes, radius = _symbols("c", "a_e", "a_p", "mode", "flutes", "radius")
    coeffs = ca.SX.sym("coeffs", 6)
    force = average_force(c, a_e, a_p, mode, flutes, radius, coeffs)
    return ca.Function("coefficient_design", [c, a_e, a_p, mode, flutes, radius],
                       [ca.jacobian(force, coeffs)], ["c", "a_e", "a_p", "mode", "flutes", "radius"],
                       ["design"])


def average_torque(
    c: Scalar, a_e: Scalar, a_p: Scalar, mode: Any, flutes: Scalar, radius: Scalar, coeffs: Any
) -> Any:
    """Tooth-period average cutting torque about the tool axis [N·m] (spindle load).

    Each engaged edge carries the tangential force F_t = K_tc b h + K_te b (h = c sin φ) at the
    radius R, so T̄ = (N/2π) ∫ R F_t dφ over [φ_st, φ_ex] with b = a_p:
    T̄ = (N a_p R / 2π) [K_tc c (cos φ_st − cos φ_ex) + K_te (φ_ex − φ_st)].
    The spindle power is T̄ Ω. Arguments as :func:`average_force`.
    """
    k = _coefficients(coeffs)
    phi_st, phi_ex = immersion_angles(a_e, radius, mode)
    k_tc, k_te = k[0], k[3]
    return (flutes * a_p * radius / (2.0 * ca.pi)) * (
        k_tc * c * (ca.cos(phi_st) - ca.cos(phi_ex)) + k_te * (phi_ex - phi_st))


# --------------------------------------------------------------------------------------------------
# Cutting stiffness (thesis Appendix A)
# --------------------------------------------------------------------------------------------------


def _symbols(*names: str) -> list[Any]:
    return [ca.SX.sym(name) for name in names]


@cache
def _cutting_stiffness_function() -> ca.Function:
    """Built once: (c, a_e, a_p, mode, N, R, coeffs) -> (k_pxo, k_pyo, k_px, k_py, alpha)."""
    c, a_e, a_p, mode, flutes, radius = _symbols("c", "a_e", "a_p", "mode", "flutes", "radius")
    coeffs = ca.SX.sym("coeffs", 6)
    force = average_force(c, a_e, a_p, mode, flutes, radius, coeffs)
    _, _, pinned = _immersion(a_e, radius, mode)
    # Radial: d/da_e of each component (for up milling a_e = x_o = R(1 − cos φ_ex) exactly). Where
    # the arc is pinned (slot, a_e >= 2R, a_e <= 0) it is 0 by definition; the sum of squares is
    # replaced by 1 there so that the square root's derivative stays finite in the unused branch.
    radial_sq = ca.sumsqr(ca.jacobian(force, a_e))
    k_pxo = ca.if_else(pinned, 0.0, ca.sqrt(ca.if_else(pinned, 1.0, radial_sq)))
    # Axial: d/da_p of each component (= component / a_p); |F| falls when the tool leaves the cut.
    # With no engagement at all (a symbolic a_e <= 0) there is no force: K_pyo = 0 and α = 0 there,
    # with the same guard against the infinite derivatives of √ and atan2 at the origin.
    axial_sq = ca.sumsqr(ca.jacobian(force, a_p))
    no_axial = axial_sq == 0.0
    k_pyo = ca.if_else(no_axial, 0.0, -ca.sqrt(ca.if_else(no_axial, 1.0, axial_sq)))
    no_force = ca.logic_and(force[0] == 0.0, force[2] == 0.0)
    alpha = ca.if_else(no_force, 0.0, ca.atan2(force[2], ca.if_else(no_force, 1.0, force[0])))
    return ca.Function(
        "cutting_stiffness",
        [c, a_e, a_p, mode, flutes, radius, coeffs],
        [k_pxo, k_pyo, k_pxo * ca.cos(alpha), k_pyo, alpha],
        ["c", "a_e", "a_p", "mode", "flutes", "radius", "coeffs"],
        ["k_pxo", "k_pyo", "k_px", "k_py", "alpha"],
    )


def cutting_stiffness(
    c: Scalar, a_e: Scalar, a_p: Scalar, mode: Any, flutes: Scalar, radius: Scalar, coeffs: Any
) -> dict[str, Any]:
    """Cutting stiffness of the thesis (Appendix A, docs/model.md §4), by algorithmic differentiation.

    - ``k_pxo`` = +√(KX² + KY² + KZ²) [N/m], (KX, KY, KZ) = ∂F̄/∂a_e. For up milling a_e is exactly
      x_o = R(1 − cos φ_ex), the SPEC's variable; down milling uses the same ∂/∂a_e. In slot mode
      (and for up/down milling at a_e = 2R, which is a slot) it is 0 by definition: a radial
      displacement does not change the engaged arc 0…π (one side gains what the other loses), and
      ∂arccos is infinite at a_e = 2R. Approaching a_e = 2R from below in up/down milling it grows
      without bound (the edge-force terms jump in at the arc's end).
    - ``k_pyo`` = −|∂F̄/∂a_p| = −|F̄|/a_p [N/m].
    - ``alpha`` = atan2(F_zo, F_xo) [rad]; ``k_px`` = k_pxo cos α, ``k_py`` = k_pyo [N/m].

    With no engagement (possible only for a symbolic a_e <= 0) everything is 0. All first and second
    derivatives are finite in every mode, including the unused branches.

    Values are CasADi scalars (``DM`` for numeric inputs). Arguments as for :func:`average_force`.
    """
    code = _mode_code(mode)
    _check_engagement(a_e, radius, code)
    outputs = _cutting_stiffness_function()(c, a_e, a_p, code, flutes, radius, _as_vector(coeffs))
    return dict(zip(("k_pxo", "k_pyo", "k_px", "k_py", "alpha"), outputs, strict=True))


# --------------------------------------------------------------------------------------------------
# Oriented process stiffness (docs/model.md §5 step 5, `oriented`)
# --------------------------------------------------------------------------------------------------


def _oriented_integrand() -> tuple[Any, Any, Any, Any, Any]:
    """∂F_(X_o,Z_o)/∂x of one edge, h = c sin φ + n(φ)·x, as a polynomial in (cos φ, sin φ).

    Returns (jacobian 2x2, cs = [cos φ; sin φ] symbols, b, c, coeffs) with F from
    :func:`_edge_force_xz`, the integrand of the simulation, evaluated at x = 0.
    """
    cs = ca.SX.sym("cs", 2)
    x = ca.SX.sym("x", 2)
    b, c = _symbols("b", "c")
    coeffs = ca.SX.sym("coeffs", 6)
    chip = c * cs[1] + ca.dot(cs, x)
    force = _edge_force_xz(cs[0], cs[1], chip, b, _coefficients(coeffs))
    jac = ca.jacobian(ca.vertcat(force[0], force[2]), x)
    return ca.substitute(jac, x, ca.DM.zeros(2)), cs, b, c, coeffs


@cache
def _oriented_function() -> ca.Function:
    """Built once: (a_e, a_p, mode, N, R, coeffs) -> K_p (2x2)."""
    jac, cs, b, c, coeffs = _oriented_integrand()
    a_e, mode, flutes, radius = _symbols("a_e", "mode", "flutes", "radius")
    # The integrand is a polynomial of degree <= 2 in (u, v) = (cos φ, sin φ): its Taylor expansion
    # at (0, 0) is exact. Take the coefficients by AD and integrate the monomials exactly.
    entries = ca.vec(jac)
    zero = ca.DM.zeros(2)
    grad = ca.jacobian(entries, cs)
    d_uu = ca.jacobian(grad[:, 0], cs[0])
    d_uv = ca.jacobian(grad[:, 0], cs[1])
    d_vv = ca.jacobian(grad[:, 1], cs[1])
    at_origin = [ca.substitute(expr, cs, zero) for expr in (entries, grad[:, 0], grad[:, 1])]
    const, d_u, d_v = at_origin
    d_uu, d_uv, d_vv = (ca.substitute(expr, cs, zero) for expr in (d_uu, d_uv, d_vv))
    phi_st, phi_ex = immersion_angles(a_e, radius, mode)

    def antiderivatives(phi: Any) -> tuple[Any, ...]:
        sin_phi, sin_2phi = ca.sin(phi), ca.sin(2.0 * phi)
        # ∫1, ∫cos, ∫sin, ∫cos², ∫sin·cos, ∫sin²
        return (
            phi,
            sin_phi,
            -ca.cos(phi),
            phi / 2 + sin_2phi / 4,
            sin_phi**2 / 2,
            phi / 2 - sin_2phi / 4,
        )

    i_1, i_c, i_s, i_cc, i_sc, i_ss = (
        hi - lo for hi, lo in zip(antiderivatives(phi_ex), antiderivatives(phi_st), strict=True)
    )
    integral = const * i_1 + d_u * i_c + d_v * i_s + d_uu / 2 * i_cc + d_uv * i_sc + d_vv / 2 * i_ss
    k_p = flutes / (2.0 * ca.pi) * ca.reshape(integral, 2, 2)
    # The integrand is linear in the chip, so its x-derivative holds no feed: c is a dummy here.
    k_p = ca.substitute(k_p, c, ca.DM(0.0))
    return ca.Function(
        "oriented_process_stiffness",
        [a_e, b, mode, flutes, radius, coeffs],
        [k_p],
        ["a_e", "a_p", "mode", "flutes", "radius", "coeffs"],
        ["k_p"],
    )


def oriented_process_stiffness(
    a_e: Scalar, a_p: Scalar, mode: Any, flutes: Scalar, radius: Scalar, coeffs: Any
) -> Any:
    """Oriented process stiffness K_p [N/m], CasADi 2x2, in (X_o, Z_o) (docs/model.md §5 step 5, `oriented`).

    K_p = (N/2π) ∫_{φ_st}^{φ_ex} ∂F(φ, h)/∂x dφ with h = c sin φ + n(φ)·x, x = (x_Xo, x_Zo) the tool
    displacement [m] in the plane normal to the tool axis: rows are force components (X_o, Z_o),
    columns displacement components (X_o, Z_o). The derivative is taken by AD from the same
    edge-force expression as :func:`instantaneous_force`, then integrated exactly. It equals
    −(N a_p/2π) ∫ (K_tc t + K_rc n) nᵀ dφ, is not symmetric in general and does not depend on the
    feed.
    Sign anchor: its Z_o column is ∂(F̄_xo, F̄_zo)/∂c.

    Arguments as for :func:`average_force` (no feed).
    """
    code = _mode_code(mode)
    _check_engagement(a_e, radius, code)
    return _oriented_function()(a_e, a_p, code, flutes, radius, _as_vector(coeffs))


def oriented_process_stiffness_closed_form(
    a_e: float, a_p: float, mode: Any, flutes: float, radius: float, coeffs: Any
) -> np.ndarray:
    """Hand-derived closed form of :func:`oriented_process_stiffness` [N/m], shape (2, 2).

    The test oracle of the AD version: K_p = −(N a_p/2π) [K_tc ∫ t nᵀ dφ + K_rc ∫ n nᵀ dφ], with
    t = (−sin φ, cos φ), n = (cos φ, sin φ) in (X_o, Z_o), and ∫cos² = φ/2 + sin 2φ/4,
    ∫sin² = φ/2 − sin 2φ/4, ∫sin cos = sin²φ/2. Numbers only.
    """
    k_tc, k_rc = (float(value) for value in _coefficients(coeffs)[:2])
    phi_st, phi_ex = (float(angle) for angle in immersion_angles(a_e, radius, mode))

    def integrals(phi: float) -> np.ndarray:  # [∫cos², ∫sin cos, ∫sin²]
        return np.array(
            [
                phi / 2 + math.sin(2 * phi) / 4,
                math.sin(phi) ** 2 / 2,
                phi / 2 - math.sin(2 * phi) / 4,
            ]
        )

    cc, sc, ss = integrals(phi_ex) - integrals(phi_st)
    t_n = np.array([[-sc, -ss], [cc, sc]])
    n_n = np.array([[cc, sc], [sc, ss]])
    return -(flutes * a_p / (2 * math.pi)) * (k_tc * t_n + k_rc * n_n)
