"""Static deflection along a path, mirror compensation, engagement estimate (models/deflection.py)."""

from __future__ import annotations

import numpy as np
import pytest

from models import Cut, ModelParameters, PointModel, cutting, load_material, load_robot, load_tool
from models.deflection import compensate, estimate_radial_depth, path_deflection
from models.dynamics import pose_structure, simulate
from models.errors import InputError

MAT = load_material("al6061")
TOOL = load_tool("em25_2f")
CASE1_Q = np.radians([-96.42, -29.26, 99.08, -9.95, 83.23, -160.5])


def _model():
    robot = load_robot()
    params = ModelParameters(joint_stiffness=robot.data.joint_stiffness,
                             coefficients=MAT.coefficients(), spindle_mass=robot.data.spindle_mass,
                             spindle_com=robot.data.spindle_com, tcp=np.array([0.32, 0.0, 0.0]))
    return robot, params


def _path(n=5):
    """A short straight wall near Case 1: the joints move a little, the cut stays the same."""
    robot, params = _model()
    q = CASE1_Q + np.linspace(0.0, 1.0, n)[:, None] * np.radians([3.0, 2.0, -2.0, 0, 1.0, 0])
    rot = np.asarray(robot.pose_function(CASE1_Q, params.tcp)[1], float)
    axis = rot[:, 0]
    feed_dir = np.cross(axis, [0.0, 0.0, 1.0])
    feed_dir /= np.linalg.norm(feed_dir)
    radial = np.cross(axis, feed_dir)
    cuts = []
    for i in range(n):
        mode = "up" if i % 2 == 0 else "down"
        cuts.append(Cut(feed_dir, radial, 12e-3, 5e-3, mode, 1000 * np.pi / 30, 2, TOOL.radius))
    return robot, params, q, cuts, np.full(n, 5e-3)


def test_path_deflection_is_the_point_models_deflection_and_wall_sign():
    robot, params, q, cuts, feeds = _path()
    d = path_deflection(robot, params, q, np.array([c.vector() for c in cuts]), feeds)
    pm = PointModel(robot, params)
    for i, cut in enumerate(cuts):
        a = pm.analyze(q[i], cut, feeds[i])
        np.testing.assert_allclose(d.deflection[i], a.deflection, rtol=1e-9, atol=1e-15)
        np.testing.assert_allclose(d.force[i], a.force_base, rtol=1e-9)
        assert d.normal[i] == pytest.approx(a.deflection @ cut.radial_dir, rel=1e-9)
        side = 1.0 if cut.mode == "up" else -1.0
        assert d.wall_error[i] == pytest.approx(-side * d.normal[i], rel=1e-12)
    assert np.max(np.abs(d.normal)) > 1e-5  # tens of micrometres: the effect is real


def test_mirror_compensation_reduces_and_iteration_removes_the_wall_error():
    robot, params, q, cuts, feeds = _path(3)
    vecs = np.array([c.vector() for c in cuts])
    plain = compensate(robot, params, q, vecs, feeds, iterations=1)
    solved = compensate(robot, params, q, vecs, feeds, iterations=4)
    before = np.abs(plain.uncompensated_normal)
    # The stiffness hardly changes over 0.1 mm: the plain mirror already removes all but ~1e-4 of
    # the modelled error; the iterated one solves p + δ = nominal to the Newton tolerance.
    assert np.all(np.abs(plain.residual_normal) < 1e-3 * before)
    assert np.all(np.linalg.norm(solved.residual, axis=1) < 2e-7)
    assert solved.reduction >= plain.reduction - 1e-9 and plain.reduction > 0.99
    # the commanded offset is about −δ
    delta = path_deflection(robot, params, q, vecs, feeds).deflection
    np.testing.assert_allclose(plain.offset, -delta, rtol=0, atol=2e-7)  # Newton tolerance
    # orientation is held
    for q0, qc in zip(q, solved.q, strict=True):
        r0 = np.asarray(robot.pose_function(q0, params.tcp)[1], float)
        rc = np.asarray(robot.pose_function(qc, params.tcp)[1], float)
        np.testing.assert_allclose(rc, r0, atol=1e-9)


@pytest.mark.parametrize("mode", ["up", "down"])
def test_engagement_estimate_from_simulated_forces_within_2_percent(mode):
    """The mean force of a simulated stable cut (regeneration on) gives back a_e within 2 %."""
    robot, params = _model()
    rpm, c = 4000.0, 0.1e-3
    feed = c * 2 * rpm / 60
    for a_e_mm in (1.0, 3.0, 6.0, 10.0, 15.0, 20.0):
        cut = Cut(np.array([0.0, 1.0, 0.0]), np.array([1.0, 0.0, 0.0]), a_e_mm * 1e-3, 1e-3, mode,
                  rpm * np.pi / 30, 2, TOOL.radius)
        st = pose_structure(robot, params, CASE1_Q, cut, feed)
        sim = simulate(st, cut, feed, MAT, TOOL.helix_angle, duration=0.6)
        mean = sim.force[len(sim.time) // 2:].mean(axis=0)
        est = estimate_radial_depth(mean, c, mode, 2, TOOL.radius, MAT, prior=a_e_mm * 1e-3)
        assert est == pytest.approx(a_e_mm * 1e-3, rel=0.02)


def test_engagement_estimate_is_exact_on_the_closed_form_and_independent_of_a_p():
    for mode in ("up", "down"):
        for a_e in (2e-3, 8e-3, 16e-3, 24e-3):
            for a_p in (1e-3, 6e-3):
                f = np.asarray(cutting.average_force(5e-5, a_e, a_p, mode, 2, TOOL.radius, MAT))
                est = estimate_radial_depth(f.ravel(), 5e-5, mode, 2, TOOL.radius, MAT)
                assert est == pytest.approx(a_e, rel=1e-8)


@pytest.mark.parametrize(("force", "mode", "match"), [
    (np.zeros(3), "up", "not cutting"),
    (np.array([10.0, 0.0, 10.0]), "slot", "up or down"),
    (np.array([-10.0, 0.0, 0.0]), "down", "no radial depth"),
])
def test_engagement_estimate_rejects(force, mode, match):
    with pytest.raises(InputError, match=match):
        estimate_radial_depth(force, 1e-4, mode, 2, TOOL.radius, MAT)


def test_compensate_rejects_zero_iterations():
    robot, params, q, cuts, feeds = _path(2)
    with pytest.raises(InputError, match="at least 1"):
        compensate(robot, params, q, np.array([c.vector() for c in cuts]), feeds, iterations=0)
