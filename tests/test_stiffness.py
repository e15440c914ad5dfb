"""Tests of models/stiffness.py: the CCT term, conventional and CCT Cartesian stiffness against
independent numpy computations, and the symbolic principal stiffnesses against numpy.eigh."""

from __future__ import annotations

import dataclasses

import casadi as ca
import numpy as np
import pinocchio as pin
import pytest

from models.point import PointModel
from models.stiffness import (
    cct_term,
    compliance,
    principal_stiffness,
    principal_stiffness_np,
    translational_compliance,
    translational_stiffness,
)

N_POSES = 15
FD_STEP = 1e-5  # [rad], see tests/test_robot.py
#: A force well above cutting levels [N], so that the CCT term is large enough to be seen.
HEAVY_FORCE = 5000.0


@pytest.fixture(scope="module")
def sym(robot):
    """Numeric Functions of the symbolic stiffness chain, all of (q, tcp, K_θ diag, f or W)."""
    s = robot.symbolic
    f = ca.SX.sym("f", 3)
    w = ca.SX.sym("w", 6)
    k_theta = ca.SX.sym("k_theta", 6)
    k_c_force = cct_term(s.jacobian[0:3, :], s.q, f)
    k_c_wrench = cct_term(s.jacobian, s.q, w)
    hess, _ = ca.hessian(ca.dot(f, s.position), s.q)
    c_tt_cct = translational_compliance(s.jacobian, k_theta, k_c_force)
    c_tt_conv = translational_compliance(s.jacobian, k_theta)
    args, names = [s.q, s.tcp, k_theta, f], ["q", "tcp", "k_theta", "f"]
    return {
        "k_c_force": ca.Function("kc", args, [k_c_force], names, ["out"]),
        "hessian": ca.Function("h", args, [hess], names, ["out"]),
        "k_c_wrench": ca.Function("kcw", [s.q, s.tcp, w], [k_c_wrench]),
        "c6_conv": ca.Function("c6", [s.q, s.tcp, k_theta], [compliance(s.jacobian, k_theta)]),
        "c6_cct": ca.Function("c6cct", [s.q, s.tcp, k_theta, w],
                              [compliance(s.jacobian, ca.diag(k_theta), k_c_wrench)]),
        "c_tt_cct": ca.Function("ctt", args, [c_tt_cct], names, ["out"]),
        "c_tt_conv": ca.Function("ctt0", args[:3], [c_tt_conv]),
        "k_t_cct": ca.Function("kt", args, [translational_stiffness(c_tt_cct)], names, ["out"]),
        "k_t_conv": ca.Function("kt0", args[:3], [translational_stiffness(c_tt_conv)]),
    }


def _np(x) -> np.ndarray:
    return np.asarray(x, float)


def _random_force(rng, magnitude):
    v = rng.normal(size=3)
    return magnitude * v / np.linalg.norm(v)


def _pin_jacobian(model, data, fid, q):
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    return pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED).copy()


# ----------------------------------------------------------------------------- the CCT term


def test_cct_term_is_symmetric_hessian_of_work_for_pure_force(robot, tcp, random_poses, rng, sym):
    """For a pure force at the TCP, K_c = ∂(J_vᵀ f)/∂θ is the Hessian of fᵀp(θ): symmetric."""
    k_theta = robot.data.joint_stiffness
    for q in random_poses(N_POSES, tcp=tcp):
        f = _random_force(rng, HEAVY_FORCE)
        k_c = _np(sym["k_c_force"](q, tcp, k_theta, f))
        hess = _np(sym["hessian"](q, tcp, k_theta, f))
        scale = HEAVY_FORCE * 3.0  # |f| × arm length [N·m/rad]
        np.testing.assert_allclose(k_c, k_c.T, rtol=0, atol=1e-12 * scale)
        np.testing.assert_allclose(k_c, hess, rtol=0, atol=1e-12 * scale)
        assert np.max(np.abs(k_c)) > 0.01 * scale  # not trivially zero


def test_cct_term_matches_finite_differences_with_moment(robot, tcp, random_poses, rng, sym):
    """Column i of K_c is ∂Jᵀ/∂θ_i · W, also for a wrench with a moment, against pinocchio's J."""
    model, fid = robot.pin_model(tcp=tcp)
    data = model.createData()
    for q in random_poses(5, tcp=tcp):
        w = np.concatenate([_random_force(rng, HEAVY_FORCE), _random_force(rng, 500.0)])
        fd = np.empty((6, 6))
        for i in range(6):
            e = np.zeros(6)
            e[i] = FD_STEP
            fd[:, i] = (_pin_jacobian(model, data, fid, q + e).T @ w
                        - _pin_jacobian(model, data, fid, q - e).T @ w) / (2 * FD_STEP)
        np.testing.assert_allclose(_np(sym["k_c_wrench"](q, tcp, w)), fd, rtol=0,
                                   atol=1e-6 * HEAVY_FORCE)


def test_cct_term_holds_a_pose_dependent_wrench_constant(robot):
    """If W depends on θ, cct_term still differentiates J only (W substituted afterwards)."""
    s = robot.symbolic
    w_of_q = 1000.0 * ca.vertcat(ca.sin(s.q[0]), ca.cos(s.q[1]), s.q[2])
    held = ca.Function("held", [s.q, s.tcp], [cct_term(s.jacobian[0:3, :], s.q, w_of_q)])
    f = ca.SX.sym("f", 3)
    free = ca.Function("free", [s.q, s.tcp, f], [cct_term(s.jacobian[0:3, :], s.q, f)])
    q = np.deg2rad([20.0, -60.0, 80.0, 30.0, 45.0, -10.0])
    tcp = np.array([0.3, 0.0, 0.0])
    w = 1000.0 * np.array([np.sin(q[0]), np.cos(q[1]), q[2]])
    np.testing.assert_allclose(_np(held(q, tcp)), _np(free(q, tcp, w)), rtol=1e-12, atol=1e-9)


# ------------------------------------------------------------------------ conventional stiffness


def test_zero_force_gives_conventional_stiffness(robot, tcp, random_poses, sym):
    """With W = 0: C = J K_θ⁻¹ Jᵀ, C_tt its translational block, and K_t = C_tt⁻¹ is the Schur
    complement of the conventional K = J⁻ᵀ K_θ J⁻¹ (pure force, rotations free)."""
    k_theta = robot.data.joint_stiffness
    for q in random_poses(N_POSES, tcp=tcp):
        jac = _np(robot.jacobian_function(q, tcp))
        c_np = jac @ np.linalg.solve(np.diag(k_theta), jac.T)
        k_np = np.linalg.inv(jac).T @ np.diag(k_theta) @ np.linalg.inv(jac)
        schur = k_np[:3, :3] - k_np[:3, 3:] @ np.linalg.solve(k_np[3:, 3:], k_np[3:, :3])

        c6 = _np(sym["c6_conv"](q, tcp, k_theta))
        c_tt = _np(sym["c_tt_conv"](q, tcp, k_theta))
        c_tt_zero = _np(sym["c_tt_cct"](q, tcp, k_theta, np.zeros(3)))
        k_t = _np(sym["k_t_conv"](q, tcp, k_theta))
        k_t_zero = _np(sym["k_t_cct"](q, tcp, k_theta, np.zeros(3)))

        np.testing.assert_allclose(c6, c_np, rtol=1e-10, atol=1e-10 * np.abs(c_np).max())
        np.testing.assert_allclose(c_tt, c_np[:3, :3], rtol=1e-10,
                                   atol=1e-10 * np.abs(c_tt).max())
        np.testing.assert_allclose(c_tt_zero, c_tt, rtol=1e-12, atol=0)
        np.testing.assert_allclose(k_t, schur, rtol=1e-7, atol=1e-7 * np.abs(k_t).max())
        np.testing.assert_allclose(k_t_zero, k_t, rtol=1e-12, atol=0)
        np.testing.assert_allclose(k_t, k_t.T, rtol=0, atol=1e-12 * np.abs(k_t).max())
        assert np.linalg.eigvalsh(k_t)[0] > 0.0


def test_translational_stiffness_with_cct_matches_numpy(robot, tcp, random_poses, rng, sym):
    """K_t = (J_v (K_θ − K_c)⁻¹ J_vᵀ)⁻¹ with K_c from finite differences of pinocchio's Jacobian,
    solved with numpy; at 5 kN the CCT part is visible, so dropping it would fail this test."""
    k_theta = robot.data.joint_stiffness
    model, fid = robot.pin_model(tcp=tcp)
    data = model.createData()
    for q in random_poses(N_POSES, tcp=tcp):
        f = _random_force(rng, HEAVY_FORCE)
        jv = _pin_jacobian(model, data, fid, q)[:3, :]
        k_c = np.empty((6, 6))
        for i in range(6):
            e = np.zeros(6)
            e[i] = FD_STEP
            k_c[:, i] = (_pin_jacobian(model, data, fid, q + e)[:3, :].T @ f
                         - _pin_jacobian(model, data, fid, q - e)[:3, :].T @ f) / (2 * FD_STEP)
        c_tt = jv @ np.linalg.solve(np.diag(k_theta) - k_c, jv.T)
        k_t_np = np.linalg.solve(c_tt, np.eye(3))
        k_t_conv_np = np.linalg.solve(jv @ np.linalg.solve(np.diag(k_theta), jv.T), np.eye(3))

        k_t = _np(sym["k_t_cct"](q, tcp, k_theta, f))
        scale = np.abs(k_t).max()
        np.testing.assert_allclose(k_t, 0.5 * (k_t_np + k_t_np.T), rtol=0, atol=1e-7 * scale)
        # the CCT part is resolved: at least 100× the tolerance above
        assert np.abs(k_t_np - k_t_conv_np).max() > 1e-5 * scale


def test_compliance_with_cct_wrench(robot, tcp, random_poses, rng, sym):
    """compliance(J, K_θ, K_c) = J (K_θ − K_c)⁻¹ Jᵀ for a full wrench (numpy solve)."""
    k_theta = robot.data.joint_stiffness
    for q in random_poses(5, tcp=tcp):
        w = np.concatenate([_random_force(rng, HEAVY_FORCE), _random_force(rng, 500.0)])
        jac = _np(robot.jacobian_function(q, tcp))
        k_c = _np(sym["k_c_wrench"](q, tcp, w))
        expected = jac @ np.linalg.solve(np.diag(k_theta) - k_c, jac.T)
        np.testing.assert_allclose(_np(sym["c6_cct"](q, tcp, k_theta, w)), expected, rtol=1e-9,
                                   atol=1e-9 * np.abs(expected).max())


def test_cct_effect_is_small_at_cutting_force_levels(robot, point_model, case1_q, case1_cut,
                                                     case1_feed):
    """docs/model.md §5 honest-model rule: CCT moves γ by far less than a degree for Case 1 (≈ 71 N), but
    it does change K_t (the switch is live)."""
    conventional = PointModel(robot, dataclasses.replace(point_model.params, cct=False))
    with_cct = point_model.analyze(case1_q, case1_cut, case1_feed)
    without = conventional.analyze(case1_q, case1_cut, case1_feed)
    assert abs(np.degrees(with_cct.gamma - without.gamma)) < 1.0
    rel = np.abs(with_cct.stiffness - without.stiffness).max() / np.abs(without.stiffness).max()
    assert 1e-7 < rel < 1e-2
    np.testing.assert_allclose(with_cct.force_o, without.force_o, rtol=1e-14)


# ----------------------------------------------------------------------------- principal stiffness


def _random_spd(rng, values):
    q_mat, _ = np.linalg.qr(rng.normal(size=(len(values), len(values))))
    return q_mat @ np.diag(values) @ q_mat.T


@pytest.fixture(scope="module")
def principal():
    k = ca.SX.sym("k", 3, 3)
    values, directions = principal_stiffness(k)
    return ca.Function("principal", [k], [values, directions])


def test_principal_stiffness_matches_eigh(rng, principal):
    """Values (descending) and unit directions (up to sign) of random SPD matrices, 1e5…1e7 N/m."""
    checked = 0
    for _ in range(200):
        values = np.sort(10.0 ** rng.uniform(5.0, 7.0, size=3))[::-1]
        if np.min(-np.diff(values) / values[:-1]) < 0.02:  # keep the eigenvalues distinct
            continue
        checked += 1
        k = _random_spd(rng, values)
        got_values, got_dirs = (_np(x) for x in principal(k))
        ref_values, ref_dirs = principal_stiffness_np(k)
        np.testing.assert_allclose(ref_values, values, rtol=1e-10)
        np.testing.assert_allclose(got_values.reshape(3), ref_values, rtol=1e-9)
        np.testing.assert_allclose(np.linalg.norm(got_dirs, axis=0), 1.0, rtol=1e-12)
        np.testing.assert_allclose(np.abs(np.sum(got_dirs * ref_dirs, axis=0)), 1.0, atol=1e-7)
        np.testing.assert_allclose(k @ got_dirs, got_dirs * got_values.reshape(1, 3),
                                   atol=1e-6 * values[0])
    assert checked > 150


@pytest.mark.parametrize("values", [(2e6, 2e6, 2e6), (3e6, 1e6, 1e6), (3e6, 3e6, 1e6)])
def test_principal_stiffness_repeated_values_stay_finite(rng, principal, values):
    """Repeated eigenvalues: the values are still right and nothing is NaN."""
    k = _random_spd(rng, np.array(values))
    got_values, got_dirs = (_np(x) for x in principal(k))
    np.testing.assert_allclose(got_values.reshape(3), values, rtol=1e-6)
    assert np.all(np.isfinite(got_dirs))


def test_principal_stiffness_np_orders_descending(rng):
    k = _random_spd(rng, np.array([1e5, 5e6, 2e6]))
    values, dirs = principal_stiffness_np(k)
    np.testing.assert_allclose(values, [5e6, 2e6, 1e5], rtol=1e-10)
    np.testing.assert_allclose(k @ dirs, dirs * values, atol=1e-6 * 5e6)
