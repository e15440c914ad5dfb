"""Tests of models/chatter.py against numpy: 2×2 eigenvalues, the stability verdict and margin
(brute force, including near the boundary), principal directions with and without a mass block,
angle wrapping, the force frame Δ and the thesis process stiffness."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pinocchio as pin
import pytest

from models.chatter import (
    eigen_2x2,
    force_frame,
    gamma_window_margin,
    principal_2x2,
    stability_margin,
    stability_matrix,
    thesis_process_stiffness,
    wrap_direction,
)

#: Typical stiffness scale of the 2-DOF problem [N/m].
SCALE = 1e6


def _np(x) -> np.ndarray:
    return np.asarray(x, float)


def _f(x) -> float:
    return np.asarray(x, float).item()


@pytest.fixture(scope="module")
def eig_fn():
    """A (2×2) → (tr, det, disc, re, im, margin, verdict); verdict as in models.analysis."""
    a = ca.SX.sym("a", 2, 2)
    e = eigen_2x2(a)
    margin = stability_margin(e["tr"], e["disc"])
    verdict = (e["tr"] < 0) * (e["det"] > 0) * (e["disc"] >= 0)
    return ca.Function("eig", [a], [e["tr"], e["det"], e["disc"], e["re"], e["im"], margin,
                                    verdict])


def _evaluate(eig_fn, a):
    tr, det, disc, re, im, margin, verdict = (_np(x) for x in eig_fn(a))
    return {"tr": _f(tr), "det": _f(det), "disc": _f(disc), "re": re.reshape(2),
            "im": im.reshape(2), "margin": _f(margin), "stable": bool(_f(verdict) > 0.5)}


def _evaluate_many(eig_fn, mats):
    """The same as :func:`_evaluate` for many A at once (Function.map), arrays of length n."""
    n = len(mats)
    tr, det, disc, re, im, margin, verdict = (_np(x) for x in eig_fn.map(n)(np.hstack(mats)))
    return {"tr": tr.reshape(n), "det": det.reshape(n), "disc": disc.reshape(n), "re": re.T,
            "im": im.T, "margin": margin.reshape(n), "stable": verdict.reshape(n) > 0.5}


def _similar(rng, block):
    """P · block · P⁻¹ with a well-conditioned random P (rotation × mild scaling)."""
    angle = rng.uniform(-np.pi, np.pi)
    rot = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    p = rot @ np.diag([1.0, rng.uniform(0.5, 2.0)])
    return p @ block @ np.linalg.inv(p)


# ----------------------------------------------------------------------------- eigenvalues


def test_eigen_2x2_matches_numpy_real_case(rng, eig_fn):
    for _ in range(300):
        lam = SCALE * rng.uniform(-3.0, 3.0, size=2)
        a = _similar(rng, np.diag(lam))
        got = _evaluate(eig_fn, a)
        ref = np.linalg.eigvals(a)
        assert got["disc"] >= 0.0
        np.testing.assert_allclose(got["im"], 0.0, atol=0)
        np.testing.assert_allclose(got["re"], np.sort(ref.real)[::-1], rtol=0, atol=1e-8 * SCALE)
        assert got["tr"] == pytest.approx(np.trace(a), rel=1e-12, abs=1e-6)
        assert got["det"] == pytest.approx(np.linalg.det(a), rel=1e-9, abs=1e-3 * SCALE)


def test_eigen_2x2_matches_numpy_complex_case(rng, eig_fn):
    for _ in range(300):
        re, im = SCALE * rng.uniform(-3.0, 3.0), SCALE * rng.uniform(0.01, 3.0)
        a = _similar(rng, np.array([[re, im], [-im, re]]))
        got = _evaluate(eig_fn, a)
        ref = np.linalg.eigvals(a)
        assert got["disc"] < 0.0
        ref_plus = ref[np.argmax(ref.imag)]
        np.testing.assert_allclose(got["re"], [ref_plus.real, ref_plus.real], atol=1e-8 * SCALE)
        np.testing.assert_allclose(got["im"], [ref_plus.imag, -ref_plus.imag], atol=1e-8 * SCALE)


def test_eigen_2x2_matches_numpy_on_gaussian_matrices(rng, eig_fn):
    for _ in range(500):
        a = SCALE * rng.normal(size=(2, 2))
        got = _evaluate(eig_fn, a)
        ref = np.linalg.eigvals(a)
        ours = got["re"] + 1j * got["im"]
        ours = ours[np.lexsort((ours.imag, ours.real))]
        ref = ref[np.lexsort((ref.imag, ref.real))]
        np.testing.assert_allclose(ours, ref, rtol=0, atol=1e-7 * SCALE)


# ----------------------------------------------------------------------------- verdict and margin


def _numpy_margin(a):
    """The margin of the chatter module docstring, from numpy's eigenvalues."""
    lam = np.linalg.eigvals(a)
    if np.all(np.abs(lam.imag) == 0.0):
        hi, lo = np.max(lam.real), np.min(lam.real)
        return min(-hi, (hi - lo) / 2.0)
    return min(-lam[0].real, -abs(lam[0].imag))


def test_margin_formula_matches_eigenvalues(rng, eig_fn):
    """margin = min(−λ_hi, (λ_hi − λ_lo)/2) (real) or min(−Re λ, −|Im λ|) (complex pair)."""
    mats = [SCALE * rng.normal(size=(2, 2)) for _ in range(1000)]
    got = _evaluate_many(eig_fn, mats)
    np.testing.assert_allclose(got["margin"], [_numpy_margin(a) for a in mats], rtol=1e-9,
                               atol=1e-7 * SCALE)
    n_real = int(np.sum(got["disc"] >= 0.0))
    assert 100 < n_real < 900  # both the real and the complex branch are exercised


def _boundary_cases(rng):
    """(A, stable) pairs whose verdict is known by construction; many sit within 1e-6·SCALE of
    the boundary: an eigenvalue at ∓ε, a complex pair with Im = ±ε, a nearly double root."""
    eps = 1e-6 * SCALE
    cases = []
    for _ in range(200):
        far = -SCALE * rng.uniform(0.1, 3.0)
        sign = rng.choice([-1.0, 1.0])
        cases += [
            (_similar(rng, np.diag([-eps, far])), True),                  # both negative, barely
            (_similar(rng, np.diag([eps, far])), False),                  # divergence, barely
            (_similar(rng, np.diag([far, far + sign * eps])), True),      # nearly double, real
            (_similar(rng, np.array([[far, eps], [-eps, far]])), False),  # barely complex
            (_similar(rng, np.array([[-eps, SCALE], [-SCALE, -eps]])), False),  # flutter
            (_similar(rng, np.diag([-far, far])), False),                 # saddle
        ]
    return cases


def test_stable_iff_real_negative_iff_positive_margin_brute_force(rng, eig_fn):
    """Random and near-boundary A: verdict ⇔ both eigenvalues real and negative ⇔ margin > 0."""
    cases = _boundary_cases(rng)
    for _ in range(3000):
        a = SCALE * rng.normal(size=(2, 2)) + SCALE * rng.uniform(-2, 2) * np.eye(2)
        lam = np.linalg.eigvals(a)
        if np.max(np.abs(lam.imag)) < 1e-3 * SCALE and np.abs(lam.real).min() < 1e-3 * SCALE:
            continue  # numpy's own rounding could decide these; the constructed ones cover them
        cases.append((a, bool(np.all(lam.imag == 0.0) and np.all(lam.real < 0.0))))
    mats = [a for a, _ in cases]
    expected = np.array([e for _, e in cases])
    got = _evaluate_many(eig_fn, mats)
    wrong = np.flatnonzero(got["stable"] != expected)
    assert wrong.size == 0, [mats[i] for i in wrong[:3]]
    wrong = np.flatnonzero((got["margin"] > 0.0) != expected)
    assert wrong.size == 0, [mats[i] for i in wrong[:3]]
    assert 0.2 < np.mean(expected) < 0.8  # both verdicts are well represented


def test_margin_is_zero_at_a_double_root(eig_fn):
    """A double negative root (a Jordan block) sits on the boundary: docs/model.md §5's three inequalities
    (disc ≥ 0) still call it stable, the margin is exactly 0."""
    got = _evaluate(eig_fn, np.array([[-2.0, 1.0], [0.0, -2.0]]) * SCALE)
    assert got["disc"] == 0.0
    np.testing.assert_array_equal(got["re"], [-2.0 * SCALE, -2.0 * SCALE])
    np.testing.assert_array_equal(got["im"], [0.0, 0.0])
    assert got["margin"] == 0.0
    assert got["stable"]


def test_stability_matrix_formula(rng):
    v, k_p = ca.SX.sym("v", 2, 2), ca.SX.sym("k_p", 2, 2)
    k_max, k_min = ca.SX.sym("k_max"), ca.SX.sym("k_min")
    fn = ca.Function("A", [v, k_p, k_max, k_min], [stability_matrix(v, k_p, k_max, k_min)])
    vv, kp = rng.normal(size=(2, 2)), SCALE * rng.normal(size=(2, 2))
    np.testing.assert_allclose(_np(fn(vv, kp, 3e6, 1e6)),
                               vv.T @ kp @ vv - np.diag([3e6, 1e6]), rtol=1e-14)


@pytest.mark.parametrize("gamma, lo, hi, expected", [
    (0.0, -0.5, 0.5, 0.5),
    (0.4, -0.5, 0.5, 0.1),
    (-0.6, -0.5, 0.5, -0.1),
    (1.2, -0.5, 0.5, -0.7),
    (0.0, -np.pi / 2, np.pi / 2, np.pi / 2),
])
def test_gamma_window_margin(gamma, lo, hi, expected):
    assert _f(gamma_window_margin(ca.DM(gamma), ca.DM(lo), ca.DM(hi))) == pytest.approx(expected)


# ----------------------------------------------------------------------------- principal 2×2


def _random_spd2(rng, lo, hi):
    angle = rng.uniform(-np.pi, np.pi)
    rot = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    return rot @ np.diag(rng.uniform(lo, hi, size=2)) @ rot.T


@pytest.fixture(scope="module")
def principal_fns():
    k2, m2 = ca.SX.sym("k2", 2, 2), ca.SX.sym("m2", 2, 2)
    iso = principal_2x2(k2)
    mass = principal_2x2(k2, m2)
    return (ca.Function("iso", [k2], [iso["k_max"], iso["k_min"], iso["v"], iso["theta_max"]]),
            ca.Function("mass", [k2, m2], [mass["k_max"], mass["k_min"], mass["v"],
                                           mass["theta_max"], mass["omega2"]]))


def test_principal_2x2_isotropic_mass(rng, principal_fns):
    iso, _ = principal_fns
    for _ in range(200):
        k = _random_spd2(rng, 1e5, 1e7)
        k_max, k_min, v, theta = (_np(x) for x in iso(k))
        ref = np.linalg.eigvalsh(k)
        assert _f(k_max) == pytest.approx(ref[1], rel=1e-10)
        assert _f(k_min) == pytest.approx(ref[0], rel=1e-10)
        np.testing.assert_allclose(v.T @ v, np.eye(2), atol=1e-14)
        np.testing.assert_allclose(v.T @ k @ v, np.diag([_f(k_max), _f(k_min)]),
                                   atol=1e-9 * ref[1])
        theta = _f(theta)
        assert -np.pi / 2 < theta <= np.pi / 2
        np.testing.assert_allclose(v[:, 0], [np.cos(theta), np.sin(theta)], atol=1e-14)


def test_principal_2x2_with_mass_block(rng, principal_fns):
    """Vᵀ M V = m̄ I (m̄ = tr M / 2), Vᵀ K V = diag(K_max, K_min), ω² = eig(M⁻¹ K) descending."""
    _, with_mass = principal_fns
    for _ in range(200):
        k = _random_spd2(rng, 1e5, 1e7)
        m = _random_spd2(rng, 50.0, 800.0)
        k_max, k_min, v, theta, omega2 = (_np(x) for x in with_mass(k, m))
        k_max, k_min, theta = _f(k_max), _f(k_min), _f(theta)
        m_bar = 0.5 * np.trace(m)
        ref = np.sort(np.linalg.eigvals(np.linalg.inv(m) @ k).real)[::-1]
        np.testing.assert_allclose(omega2.reshape(2), ref, rtol=1e-10)
        assert k_max == pytest.approx(m_bar * ref[0], rel=1e-10)
        assert k_min == pytest.approx(m_bar * ref[1], rel=1e-10)
        np.testing.assert_allclose(v.T @ m @ v, m_bar * np.eye(2), rtol=0, atol=1e-10 * m_bar)
        np.testing.assert_allclose(v.T @ k @ v, np.diag([k_max, k_min]), rtol=0,
                                   atol=1e-9 * k_max)
        assert -np.pi / 2 < theta <= np.pi / 2
        direction = v[:, 0] / np.linalg.norm(v[:, 0])
        assert abs(direction @ [np.cos(theta), np.sin(theta)]) == pytest.approx(1.0, abs=1e-12)


def test_principal_2x2_with_scalar_mass_equals_isotropic(rng, principal_fns):
    """M = m I: the mass-weighted answer is the stiffness-only one (same V up to sign, same θ)."""
    iso, with_mass = principal_fns
    for _ in range(50):
        k = _random_spd2(rng, 1e5, 1e7)
        k_max, k_min, v, theta = (_np(x) for x in iso(k))
        k_max_m, k_min_m, v_m, theta_m, omega2 = (_np(x) for x in with_mass(k, 120.0 * np.eye(2)))
        assert _f(k_max_m) == pytest.approx(_f(k_max), rel=1e-12)
        assert _f(k_min_m) == pytest.approx(_f(k_min), rel=1e-12)
        np.testing.assert_allclose(np.abs(np.sum(v * v_m, axis=0)), 1.0, atol=1e-12)
        assert _f(theta_m) == pytest.approx(_f(theta), abs=1e-12)
        np.testing.assert_allclose(omega2.reshape(2), [_f(k_max) / 120, _f(k_min) / 120],
                                   rtol=1e-12)


def test_principal_2x2_isotropic_stiffness_is_finite(principal_fns):
    iso, with_mass = principal_fns
    for out in (iso(2e6 * np.eye(2)), with_mass(2e6 * np.eye(2), 100.0 * np.eye(2))):
        assert all(np.all(np.isfinite(_np(x))) for x in out)


# ----------------------------------------------------------------------------- angles and frames


@pytest.fixture(scope="module")
def wrap_fn():
    x = ca.SX.sym("x")
    return ca.Function("wrap", [x], [wrap_direction(x)])


def test_wrap_direction_range_and_period(rng, wrap_fn):
    angles = rng.uniform(-10 * np.pi, 10 * np.pi, size=2000)
    wrapped = _np(wrap_fn.map(angles.size)(angles.reshape(1, -1))).reshape(-1)
    assert np.all(wrapped > -np.pi / 2) and np.all(wrapped <= np.pi / 2)
    turns = (wrapped - angles) / np.pi  # wrapping only adds whole half turns
    np.testing.assert_allclose(turns, np.round(turns), atol=1e-9)
    shifts = rng.integers(-5, 6, size=angles.size)
    shifted = _np(wrap_fn.map(angles.size)((angles + np.pi * shifts).reshape(1, -1))).reshape(-1)
    np.testing.assert_allclose(shifted, wrapped, atol=1e-9)


@pytest.mark.parametrize("angle, expected", [
    (0.0, 0.0), (np.pi / 2, np.pi / 2), (-np.pi / 2, np.pi / 2), (np.pi, 0.0),
    (0.75 * np.pi, -0.25 * np.pi), (-0.75 * np.pi, 0.25 * np.pi), (3 * np.pi / 2, np.pi / 2),
])
def test_wrap_direction_values(wrap_fn, angle, expected):
    assert _f(wrap_fn(angle)) == pytest.approx(expected, abs=1e-12)


def _random_frame(rng):
    q_mat, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    if np.linalg.det(q_mat) < 0:
        q_mat[:, 2] *= -1.0
    return q_mat[:, 0], q_mat[:, 1], q_mat[:, 2]


def test_force_frame_is_proper_rotation_with_x_along_inplane_force(rng):
    alpha = ca.SX.sym("alpha")
    xs, ys, zs = ca.SX.sym("x", 3), ca.SX.sym("y", 3), ca.SX.sym("z", 3)
    fn = ca.Function("delta", [alpha, xs, ys, zs], [force_frame(alpha, xs, ys, zs)])
    for _ in range(100):
        x_o, y_o, z_o = _random_frame(rng)
        f_o = rng.normal(size=3) * 50.0
        a = np.arctan2(f_o[2], f_o[0])
        delta = _np(fn(a, x_o, y_o, z_o))
        np.testing.assert_allclose(delta.T @ delta, np.eye(3), atol=1e-14)
        assert np.linalg.det(delta) == pytest.approx(1.0, abs=1e-14)
        f_base = f_o[0] * x_o + f_o[1] * y_o + f_o[2] * z_o
        inplane = f_o[0] * x_o + f_o[2] * z_o
        np.testing.assert_allclose(delta[:, 0], inplane / np.linalg.norm(inplane), atol=1e-14)
        np.testing.assert_allclose(delta[:, 1], y_o, atol=0)
        # the force lies in Δ's X–Y plane: (|F_inplane|, F_yo, 0)
        np.testing.assert_allclose(delta.T @ f_base, [np.hypot(f_o[0], f_o[2]), f_o[1], 0.0],
                                   atol=1e-12)
        # Δ is Δ_o rotated by α about −Y_o
        rotation = pin.exp3(-a * y_o)
        np.testing.assert_allclose(delta, rotation @ np.column_stack([x_o, y_o, z_o]),
                                   atol=1e-14)


def test_thesis_process_stiffness_rank_one_rows_and_columns(rng):
    """K_p = [cos β; sin β]·[K_px, K_py]: row = force component, column = displacement component.
    A radial displacement (column 0) changes the force by K_px along the force direction β."""
    beta, kpx, kpy = ca.SX.sym("beta"), ca.SX.sym("kpx"), ca.SX.sym("kpy")
    fn = ca.Function("kp", [beta, kpx, kpy], [thesis_process_stiffness(beta, kpx, kpy)])
    for _ in range(50):
        b = rng.uniform(-np.pi, np.pi)
        k_px, k_py = rng.uniform(1e3, 5e3), -rng.uniform(5e3, 5e4)
        k_p = _np(fn(b, k_px, k_py))
        np.testing.assert_allclose(
            k_p, [[np.cos(b) * k_px, np.cos(b) * k_py], [np.sin(b) * k_px, np.sin(b) * k_py]],
            rtol=1e-14, atol=1e-10)
        sv = np.linalg.svd(k_p, compute_uv=False)
        assert sv[1] < 1e-12 * sv[0]
        np.testing.assert_allclose(k_p @ [1.0, 0.0], k_px * np.array([np.cos(b), np.sin(b)]),
                                   rtol=1e-14, atol=1e-10)
        np.testing.assert_allclose(k_p @ [0.0, 1.0], k_py * np.array([np.cos(b), np.sin(b)]),
                                   rtol=1e-14, atol=1e-10)
