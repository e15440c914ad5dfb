"""Tests of models/robot.py: symbolic kinematics and inertia against pinocchio and finite
differences, the docs/model.md §2 check pose, and the robot data files."""

from __future__ import annotations

import dataclasses

import casadi as ca
import numpy as np
import pinocchio as pin
import pytest

from models.errors import DataFileError, InputError, UnknownDataError, UnreachablePoseError
from models.robot import available_robots, load_robot

N_POSES = 20
#: Central-difference step [rad]: truncation ~ h² · |third derivative| (≈ 1e-10 for a 2.7 m arm)
#: and rounding ~ 1e-16 · 3 m / h (≈ 3e-11) both stay far below the tolerances used.
FD_STEP = 1e-5
#: Agreement of symbolic and pinocchio quantities [m/rad, rad/rad]: both are exact up to rounding.
EXACT_TOL = 1e-12
#: Agreement with central finite differences [same units as the derivative].
FD_TOL = 1e-8


# ----------------------------------------------------------------------------- helpers


def _pin_jacobian(model, data, fid, q):
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    return pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)


@pytest.fixture(scope="module")
def jacobian_derivative(robot):
    """``dJ(q, tcp)`` → array (6, n, n) with [a, i, j] = ∂J[a, i]/∂q_j, from casadi.jacobian."""
    s = robot.symbolic
    n = robot.nq
    f = ca.Function("dJ", [s.q, s.tcp], [ca.jacobian(ca.vec(s.jacobian), s.q)])

    def evaluate(q, tcp):
        # vec() is column-major: row a + 6 i of the (6n, n) result holds ∂J[a, i]/∂q.
        return np.asarray(f(q, tcp), float).reshape(6, n, n, order="F")

    return evaluate


def _jac(robot, q, tcp):
    return np.asarray(robot.jacobian_function(q, tcp), float)


def _pose(robot, q, tcp):
    p, rot = robot.pose_function(q, tcp)
    return np.asarray(p, float).reshape(3), np.asarray(rot, float)


# ----------------------------------------------------------------------------- Jacobian


def test_jacobian_matches_pinocchio_with_tcp_offset(robot, tcp, random_poses):
    """Symbolic J equals pinocchio's LOCAL_WORLD_ALIGNED frame Jacobian of the 'tcp' frame."""
    model, fid = robot.pin_model(tcp=tcp)
    data = model.createData()
    for q in random_poses(N_POSES, tcp=tcp):
        np.testing.assert_allclose(_jac(robot, q, tcp), _pin_jacobian(model, data, fid, q),
                                   rtol=0, atol=EXACT_TOL)


def test_tcp_pose_matches_pinocchio_frame_placement(robot, tcp, random_poses):
    model, fid = robot.pin_model(tcp=tcp)
    data = model.createData()
    for q in random_poses(N_POSES, tcp=tcp):
        pin.framesForwardKinematics(model, data, q)
        p, rot = _pose(robot, q, tcp)
        np.testing.assert_allclose(p, data.oMf[fid].translation, rtol=0, atol=EXACT_TOL)
        np.testing.assert_allclose(rot, data.oMf[fid].rotation, rtol=0, atol=EXACT_TOL)


def test_jacobian_linear_rows_match_finite_differences_of_position(robot, tcp, random_poses):
    for q in random_poses(N_POSES, tcp=tcp):
        fd = np.empty((3, robot.nq))
        for i in range(robot.nq):
            e = np.zeros(robot.nq)
            e[i] = FD_STEP
            fd[:, i] = (_pose(robot, q + e, tcp)[0] - _pose(robot, q - e, tcp)[0]) / (2 * FD_STEP)
        np.testing.assert_allclose(_jac(robot, q, tcp)[0:3, :], fd, rtol=0, atol=FD_TOL)


def test_jacobian_angular_rows_match_finite_differences_of_rotation(robot, tcp, random_poses):
    """ω_i = log(R(q + h e_i) R(q − h e_i)ᵀ) / 2h, in base axes (skew part of the log)."""
    for q in random_poses(N_POSES, tcp=tcp):
        fd = np.empty((3, robot.nq))
        for i in range(robot.nq):
            e = np.zeros(robot.nq)
            e[i] = FD_STEP
            r_plus, r_minus = _pose(robot, q + e, tcp)[1], _pose(robot, q - e, tcp)[1]
            fd[:, i] = pin.log3(r_plus @ r_minus.T) / (2 * FD_STEP)
            # The same from the skew part alone: (R₊R₋ᵀ − R₋R₊ᵀ)/2 ≈ [2h ω]×.
            skew = 0.5 * (r_plus @ r_minus.T - r_minus @ r_plus.T) / (2 * FD_STEP)
            np.testing.assert_allclose([skew[2, 1], skew[0, 2], skew[1, 0]], fd[:, i],
                                       rtol=0, atol=FD_TOL)
        np.testing.assert_allclose(_jac(robot, q, tcp)[3:6, :], fd, rtol=0, atol=FD_TOL)


def test_tool_axis_is_first_column_of_tcp_rotation(robot, tcp, random_poses):
    """The TCP frame is the flange frame shifted by ``tcp`` (flange axes): p_tcp = p_fl + R tcp."""
    for q in random_poses(5):
        p0, r0 = _pose(robot, q, np.zeros(3))
        p1, r1 = _pose(robot, q, tcp)
        np.testing.assert_allclose(r1, r0, atol=EXACT_TOL)
        np.testing.assert_allclose(p1, p0 + r0 @ tcp, atol=EXACT_TOL)
        assert np.linalg.det(r1) == pytest.approx(1.0, abs=1e-12)


# ----------------------------------------------------------------------------- ∂J/∂θ


def test_jacobian_derivative_matches_pinocchio_kinematic_hessian(robot, random_poses,
                                                                 jacobian_derivative):
    """casadi.jacobian of J equals pinocchio's joint kinematic Hessian of A6 (origin = flange, so
    tcp = 0). pinocchio 4.1's Python binding returns the axes reversed: H.transpose(2, 1, 0)."""
    model, _ = robot.pin_model(tcp=np.zeros(3))
    data = model.createData()
    last = model.njoints - 1
    for q in random_poses(N_POSES):
        pin.computeJointJacobians(model, data, q)
        pin.computeJointKinematicHessians(model, data, q)
        hess = pin.getJointKinematicHessian(model, data, last, pin.LOCAL_WORLD_ALIGNED)
        np.testing.assert_allclose(jacobian_derivative(q, np.zeros(3)), hess.transpose(2, 1, 0),
                                   rtol=0, atol=EXACT_TOL)


def test_pinocchio_hessian_axes_really_are_reversed(robot, case1_q, jacobian_derivative):
    """Guard for the docs/model.md §3 note: without the transpose the comparison fails. If pinocchio ever
    fixes its binding, this test says so and the transpose above must go."""
    model, _ = robot.pin_model(tcp=np.zeros(3))
    data = model.createData()
    pin.computeJointJacobians(model, data, case1_q)
    pin.computeJointKinematicHessians(model, data, case1_q)
    hess = pin.getJointKinematicHessian(model, data, model.njoints - 1, pin.LOCAL_WORLD_ALIGNED)
    assert np.max(np.abs(jacobian_derivative(case1_q, np.zeros(3)) - hess)) > 1e-2


def test_jacobian_derivative_matches_finite_differences(robot, tcp, random_poses,
                                                        jacobian_derivative):
    for q in random_poses(N_POSES, tcp=tcp):
        fd = np.empty((6, robot.nq, robot.nq))
        for j in range(robot.nq):
            e = np.zeros(robot.nq)
            e[j] = FD_STEP
            fd[:, :, j] = (_jac(robot, q + e, tcp) - _jac(robot, q - e, tcp)) / (2 * FD_STEP)
        np.testing.assert_allclose(jacobian_derivative(q, tcp), fd, rtol=0, atol=FD_TOL)


# ----------------------------------------------------------------------------- docs/model.md §2 check pose


def test_flange_check_pose(robot):
    """Axes (0, −90, 90, 0, 0, 0) deg → flange at (1.765, 0, 1.784) m, flange x pointing away from
    the robot (radially outwards, horizontal)."""
    p, rot = _pose(robot, np.deg2rad([0.0, -90.0, 90.0, 0.0, 0.0, 0.0]), np.zeros(3))
    np.testing.assert_allclose(p, [1.765, 0.0, 1.784], atol=1e-12)
    x_axis = rot[:, 0]
    radial = np.array([p[0], p[1], 0.0]) / np.hypot(p[0], p[1])
    np.testing.assert_allclose(x_axis, radial, atol=1e-12)
    np.testing.assert_allclose(rot, np.eye(3), atol=1e-12)


def test_positive_a1_turns_arm_towards_negative_y(robot):
    q = np.deg2rad([30.0, -90.0, 90.0, 0.0, 0.0, 0.0])
    p, rot = _pose(robot, q, np.zeros(3))
    assert p[1] < -0.5
    # A pure rotation about the vertical: radius and height unchanged, angle −30°.
    assert np.hypot(p[0], p[1]) == pytest.approx(1.765, abs=1e-12)
    assert p[2] == pytest.approx(1.784, abs=1e-12)
    assert np.degrees(np.arctan2(p[1], p[0])) == pytest.approx(-30.0, abs=1e-9)
    # The flange still points away from the robot.
    assert rot[:, 0] @ np.array([p[0], p[1], 0.0]) > 0.0


# ----------------------------------------------------------------------------- mass matrix


@pytest.mark.parametrize("spindle_mass, spindle_com", [
    (100.0, (0.15, 0.0, 0.0)),
    (0.0, (0.0, 0.0, 0.0)),
    (63.0, (0.22, 0.03, -0.04)),
])
def test_mass_matrix_matches_pinocchio_crba(robot, random_poses, spindle_mass, spindle_com):
    m_sym = ca.SX.sym("m")
    com_sym = ca.SX.sym("com", 3)
    mass = ca.Function("M", [robot.symbolic.q, m_sym, com_sym],
                       [robot.mass_matrix_expr(m_sym, com_sym)])
    model, _ = robot.pin_model(spindle_mass=spindle_mass, spindle_com=np.array(spindle_com))
    data = model.createData()
    for q in random_poses(10):
        upper = pin.crba(model, data, q)
        reference = np.triu(upper) + np.triu(upper, 1).T  # crba fills the upper triangle
        ours = np.asarray(mass(q, spindle_mass, spindle_com), float)
        np.testing.assert_allclose(ours, reference, rtol=1e-12, atol=1e-9)
        np.testing.assert_allclose(ours, ours.T, rtol=0, atol=1e-9)
        assert np.linalg.eigvalsh(ours)[0] > 0.0


def test_spindle_mass_changes_mass_matrix(robot, case1_q):
    """The spindle is really added (guards a test that would pass with the spindle ignored)."""
    m_sym = ca.SX.sym("m")
    com_sym = ca.SX.sym("com", 3)
    mass = ca.Function("M", [robot.symbolic.q, m_sym, com_sym],
                       [robot.mass_matrix_expr(m_sym, com_sym)])
    with_spindle = np.asarray(mass(case1_q, 100.0, [0.15, 0, 0]))
    without = np.asarray(mass(case1_q, 0.0, [0.15, 0, 0]))
    assert with_spindle[0, 0] - without[0, 0] > 10.0  # ≥ 100 kg at > 0.3 m from A1 [kg·m²]


# ----------------------------------------------------------------------------- robot data


SPEC_LOWER_DEG = [-185.0, -140.0, -120.0, -350.0, -125.0, -350.0]
SPEC_UPPER_DEG = [185.0, -5.0, 155.0, 350.0, 125.0, 350.0]


def test_robot_data_matches_spec(robot):
    d = robot.data
    assert d.joint_names == ("A1", "A2", "A3", "A4", "A5", "A6")
    np.testing.assert_allclose(np.rad2deg(d.lower), SPEC_LOWER_DEG, atol=1e-9)
    np.testing.assert_allclose(np.rad2deg(d.upper), SPEC_UPPER_DEG, atol=1e-9)
    np.testing.assert_allclose(d.joint_stiffness,
                               [1.2e6, 2.74e6, 2.13e6, 0.396e6, 0.433e6, 0.285e6])
    np.testing.assert_allclose(np.rad2deg(d.velocity), [116.8, 111.4, 112, 179, 172, 220])
    np.testing.assert_allclose(d.acceleration, [1.98, 1.26, 2.57, 7.04, 1.76, 1.87])
    assert d.spindle_mass == 100.0
    assert robot.nq == 6


def test_urdf_and_toml_limits_agree(robot):
    np.testing.assert_allclose(robot.model.lowerPositionLimit, robot.data.lower, rtol=0, atol=1e-6)
    np.testing.assert_allclose(robot.model.upperPositionLimit, robot.data.upper, rtol=0, atol=1e-6)


@pytest.mark.parametrize("key", ["lower", "upper"])
def test_loader_rejects_limits_that_disagree_with_urdf(robot, key):
    shifted = getattr(robot.data, key).copy()
    shifted[2] += np.deg2rad(1.0)
    bad = dataclasses.replace(robot.data, **{key: shifted})
    with pytest.raises(DataFileError, match=f"{key} joint limits differ"):
        type(robot)(bad)


def test_unknown_robot_lists_available_ones():
    assert "kr210_r2700_extra" in available_robots()
    with pytest.raises(UnknownDataError, match=r"unknown robot 'nope'.*kr210_r2700_extra") as info:
        load_robot("nope")
    assert info.value.available == available_robots()


def test_load_robot_is_cached():
    assert load_robot() is load_robot("kr210_r2700_extra")


# ----------------------------------------------------------------------------- limits


@pytest.mark.parametrize("joint, value_deg", [
    ("A1", 186.0), ("A1", -186.0), ("A2", -4.0), ("A2", -141.0), ("A3", 156.0),
    ("A3", -121.0), ("A4", 351.0), ("A5", 126.0), ("A5", -126.0), ("A6", -351.0),
])
def test_check_limits_names_the_joint(robot, case1_q, joint, value_deg):
    q = case1_q.copy()
    i = robot.data.joint_names.index(joint)
    q[i] = np.deg2rad(value_deg)
    with pytest.raises(UnreachablePoseError, match=rf"sample 7: {joint} = .* outside its limits"):
        robot.check_limits(q, sample=7)
    with pytest.raises(UnreachablePoseError) as info:
        robot.check_limits(q)
    assert info.value.joint == joint
    assert info.value.value_deg == pytest.approx(value_deg)
    assert info.value.sample is None


def test_check_limits_accepts_limits_themselves(robot):
    robot.check_limits(robot.data.lower)
    robot.check_limits(robot.data.upper)


@pytest.mark.parametrize("q", [np.zeros(5), np.zeros(7), np.zeros((2, 3))])
def test_check_limits_rejects_wrong_shape(robot, q):
    with pytest.raises(InputError, match="need 6 joint values"):
        robot.check_limits(q)
