"""Workspace map of the dynamic effect and the stability boundary with/without regeneration."""

from __future__ import annotations

import numpy as np
import pytest

from models import Cut, ModelParameters, load_material, load_robot, load_tool
from models.dynamic_map import STATIC_VALIDITY, critical_depth, cut_at_pose, dynamic_map
from models.errors import InputError

MAT = load_material("al6061")
TOOL = load_tool("em25_2f")
CASE1_Q = np.radians([-96.42, -29.26, 99.08, -9.95, 83.23, -160.5])


def _model():
    robot = load_robot()
    return robot, ModelParameters(joint_stiffness=robot.data.joint_stiffness,
                                  coefficients=MAT.coefficients(),
                                  spindle_mass=robot.data.spindle_mass,
                                  spindle_com=robot.data.spindle_com, tcp=np.array([0.32, 0, 0]))


def test_cut_follows_the_tool():
    robot, params = _model()
    # In the TCP frame the tool axis is +x: feed along y, radial along z gives Y_o = z × ... = x.
    cut_tcp = Cut(np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0]), 5e-3, 1e-3, "up",
                  4000 * np.pi / 30, 2, TOOL.radius)
    cut = cut_at_pose(robot, params, CASE1_Q, cut_tcp)
    axis = np.asarray(robot.pose_function(CASE1_Q, params.tcp)[1], float)[:, 0]
    np.testing.assert_allclose(cut.axial_dir, axis, atol=1e-12)


def test_dynamic_map_marks_where_the_static_model_holds():
    robot, params = _model()
    cut_tcp = Cut(np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0]), 6e-3, 1.5e-3, "up",
                  1000 * np.pi / 30, 2, TOOL.radius)
    q = np.array([CASE1_Q, CASE1_Q + np.radians([0, 20, -30, 0, 10, 0]),
                  CASE1_Q + np.radians([0, 0, 0, 0, -83.23, 0])])  # the last one: A5 = 0, singular
    feed = 0.1e-3 * 2 * 1000 / 60
    m = dynamic_map(robot, params, q, cut_tcp, feed, TOOL.helix_angle, duration=0.6)
    assert np.isnan(m.ratio[2]) and not m.valid[2]
    assert np.all(np.isfinite(m.ratio[:2]))
    np.testing.assert_allclose(m.ratio[:2], m.f_pv[:2] / m.f_peak[:2])
    np.testing.assert_array_equal(m.valid[:2], m.ratio[:2] < STATIC_VALIDITY)
    # the verdicts line up: a Floquet-unstable pose is one where the static model fails
    for i in range(2):
        if m.floquet_radius[i] > 1.05:
            assert not m.valid[i]


def test_regeneration_moves_the_stability_boundary():
    """Critical axial depth at one pose, 4000 rpm, up milling: the simulation without regeneration
    finds Floquet's boundary; the regenerative (real) surface lowers it."""
    robot, params = _model()
    cut = Cut(np.array([0.0, 1.0, 0.0]), np.array([1.0, 0.0, 0.0]), 6e-3, 1e-3, "up",
              4000 * np.pi / 30, 2, TOOL.radius)
    feed = 0.1e-3 * 2 * 4000 / 60
    kw = {"a_p_range": (2e-4, 4e-3), "tol": 0.06, "duration": 1.2}
    fl = critical_depth(robot, params, CASE1_Q, cut, feed, TOOL.helix_angle, "floquet", **kw)
    sim = critical_depth(robot, params, CASE1_Q, cut, feed, TOOL.helix_angle, "simulation", **kw)
    regen = critical_depth(robot, params, CASE1_Q, cut, feed, TOOL.helix_angle, "regeneration",
                           **kw)
    assert 2e-4 < fl < 4e-3
    assert sim == pytest.approx(fl, rel=0.12)
    assert regen < 0.8 * fl


def test_critical_depth_rejects_bad_judge():
    robot, params = _model()
    cut = Cut(np.array([0.0, 1.0, 0.0]), np.array([1.0, 0.0, 0.0]), 6e-3, 1e-3, "up",
              4000 * np.pi / 30, 2, TOOL.radius)
    with pytest.raises(InputError, match="judge"):
        critical_depth(robot, params, CASE1_Q, cut, 1e-2, TOOL.helix_angle, judge="eigen")
