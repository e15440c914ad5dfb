"""Inverse kinematics along a path: accurate, continuous, honest about what it cannot reach."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from models.errors import UnreachablePoseError
from models.robot import load_robot
from planner.ik import IKOptions, solve_path
from planner.path import sample_toolpath
from robot_io.krl.frames import frame_from_mm_deg as frame_matrix
from robot_io.toolpath import Move, MoveKind, SourceRef, Toolpath

TOOL = frame_matrix([320.0, 0.0, 0.0], [0.0, 0.0, 0.0])


def _square(size=0.2, z=-0.01):
    pts = [np.array(p) for p in ([0, 0, 0.02], [0, 0, z], [size, 0, z], [size, size, z],
                                 [0, size, z], [0, 0, z])]
    moves = [Move(MoveKind.RAPID, None, pts[0], SourceRef("sq.nc", 1))]
    for i in range(1, len(pts)):
        moves.append(Move(MoveKind.LINEAR, pts[i - 1], pts[i], SourceRef("sq.nc", i + 1),
                          feed=0.01))
    return Toolpath("sq.nc", "gcode", "mm", moves)


@pytest.fixture(scope="module")
def robot():
    return load_robot()


def _fk(robot, q):
    model, fid = robot.pin_model(tcp=TOOL[:3, 3], tcp_rotation=TOOL[:3, :3])
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    return data.oMf[fid]


def test_solutions_hit_the_path_and_stay_continuous(robot):
    base = frame_matrix([1500.0, -60.0, 400.0], [0.0, 0.0, 0.0])
    path = sample_toolpath([_square()], base, 1e-5, 5e-3)
    kin = solve_path(robot, path, TOOL)
    assert kin.all_reachable and kin.problems == []
    assert kin.jumps.size == 0
    assert np.max(np.abs(np.diff(kin.q, axis=0))) < np.radians(5.0)
    for i in (0, len(path) // 3, len(path) - 1):
        m = _fk(robot, kin.q[i])  # independent check with pinocchio's forward kinematics
        assert np.linalg.norm(m.translation - path.position[i]) < 1e-6
        # tool axis = −TCP x (the TCP's +x points from the spindle to the tip)
        assert np.allclose(-m.rotation[:, 0], path.tool_axis[i], atol=1e-6)
    lo, hi = robot.data.lower, robot.data.upper
    assert np.all((kin.q >= lo - 1e-9) & (kin.q <= hi + 1e-9))


def test_choose_for_stiffness_is_no_less_stiff(robot):
    base = frame_matrix([1500.0, -60.0, 400.0], [0.0, 0.0, 0.0])
    path = sample_toolpath([_square(0.05)], base, 1e-5, 1e-2)
    plain = solve_path(robot, path, TOOL)
    stiff = solve_path(robot, path, TOOL, IKOptions(choose_for_stiffness=True))

    def k_min(q):
        jac = np.asarray(robot.jacobian_function(q, TOOL[:3, 3]))
        c = jac[:3] @ np.diag(1 / robot.data.joint_stiffness) @ jac[:3].T
        return 1 / np.linalg.eigvalsh(c)[-1]

    assert stiff.all_reachable
    assert k_min(stiff.q[0]) >= k_min(plain.q[0]) - 1.0


def test_out_of_reach_is_named(robot):
    base = frame_matrix([3200.0, 0.0, 400.0], [0.0, 0.0, 0.0])  # beyond a 2.7 m arm
    path = sample_toolpath([_square()], base, 1e-5, 2e-2)
    kin = solve_path(robot, path, TOOL)
    assert not kin.reachable.any()
    assert kin.limiting_joint[0] == "reach"
    assert "samples 0.." in kin.problems[0] and "sq.nc:1" in kin.problems[0]
    with pytest.raises(UnreachablePoseError, match=r"samples 0\.\..*out of the arm's reach"):
        kin.raise_if_unreachable()


def test_partly_unreachable_path_names_the_first_sample(robot):
    """A line running from inside the workspace to far outside: the report starts where it fails."""
    base = frame_matrix([1800.0, 0.0, 400.0], [0.0, 0.0, 0.0])
    tp = Toolpath("line.nc", "gcode", "mm", [
        Move(MoveKind.RAPID, None, np.zeros(3), SourceRef("line.nc", 1)),
        Move(MoveKind.LINEAR, np.zeros(3), np.array([1.5, 0.0, 0.0]), SourceRef("line.nc", 2),
             feed=0.01),
    ])
    path = sample_toolpath([tp], base, 1e-5, 2e-2)
    kin = solve_path(robot, path, TOOL)
    assert kin.reachable[0] and not kin.reachable[-1]
    first_bad = int(np.flatnonzero(~kin.reachable)[0])
    assert np.all(kin.reachable[:first_bad]) and not np.any(kin.reachable[first_bad:])
    assert kin.problems[0].startswith(f"samples {first_bad}..{len(path) - 1} (line.nc:2")


def test_fixed_tool_rotation_holds_the_tcp_y_axis(robot):
    from planner.ik import _frame_about

    base = frame_matrix([1500.0, -60.0, 400.0], [0.0, 0.0, 0.0])
    path = sample_toolpath([_square(0.1)], base, 1e-5, 1e-2)
    psi = np.radians(30.0)
    kin = solve_path(robot, path, TOOL, IKOptions(tool_rotation=psi))
    assert kin.all_reachable
    for i in (0, len(path) // 2, len(path) - 1):
        m = _fk(robot, kin.q[i])
        want = _frame_about(-path.tool_axis[i], psi)
        assert np.allclose(m.rotation, want, atol=1e-6)
