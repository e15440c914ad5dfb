"""Every robot in models/data/robots (issue 21, "a test per shipped robot planning a small job"):
it loads with the source of every value, its kinematics are the URDF's through pinocchio and the
published numbers it cites, a small job plans and passes the independent checker, its static
deflection under a force is the compliance J K_θ⁻¹ Jᵀ of its cited joint stiffness and of the
order such arms show, a short simulated supervised run of its plan works, and the KRL export takes
a KUKA and refuses anything else with the reason.

Named problem: the small line job of tests/test_library.py (a 40 mm straight cut, 2 mm deep, em10_3f
in Al 6061) placed within reach of each robot (:data:`PLACEMENT_MM`).
"""

from __future__ import annotations

import math
import re
from dataclasses import replace

import numpy as np
import pinocchio as pin
import pytest
from _plans import ApplyingLink

from models import ModelParameters, load_material
from models import robot as robot_module
from models.deflection import deflection_of_force
from models.robot import DEFAULT_VENDOR, available_robots, load_robot, robot_data

ROBOTS = available_robots()

#: Where the small job sits for each robot: ($BASE origin, $TOOL origin) [mm]. A robot added to
#: models/data/robots needs its line here and in :data:`REFERENCE` (the tests say so).
PLACEMENT_MM = {
    "kr210_r2700_extra": ([1500.0, -60.0, 400.0], [320.0, 0.0, 0.0]),
    "kr270_r2700_ultra": ([1500.0, -60.0, 400.0], [320.0, 0.0, 0.0]),
    "kr500_r2830": ([2200.0, -60.0, 800.0], [320.0, 0.0, 0.0]),
}

#: What each data file must say, typed here from the sources its [sources] cites (not from the
#: file): the flange position at A = 0 [m], K_θ [N·m/rad], and the [sources] keys whose values
#: are assumptions (they must say so).
REFERENCE = {
    # ROS-Industrial kr210r2700extra_macro.xacro; the thesis, Table 2
    "kr210_r2700_extra": ((0.35 + 1.15 + 1.2 + 0.215, 0.0, 0.675 - 0.041),
                          (1.2e6, 2.74e6, 2.13e6, 0.396e6, 0.433e6, 0.285e6), set()),
    # ROS-Industrial kr270r2700_macro.xacro; K_θ borrowed from the KR 210 (an assumption)
    "kr270_r2700_ultra": ((0.35 + 1.15 + 1.2 + 0.24, 0.0, 0.675 - 0.041),
                          (1.2e6, 2.74e6, 2.13e6, 0.396e6, 0.433e6, 0.285e6),
                          {"joint_stiffness", "limits"}),
    # RobotKinematicsCatalogue's modified DH table; Jiao et al. 2022, Eq. (38), N·mm/rad / 1000
    "kr500_r2830": ((0.5 + 1.3 + 1.025 + 0.29, 0.0, 1.045 - 0.055),
                    (1.58e10 / 1e3, 6.12e9 / 1e3, 5.28e9 / 1e3, 4.66e8 / 1e3, 2.19e8 / 1e3,
                     3.49e8 / 1e3),
                    {"limits", "inertia"}),
}

#: The small job: a 40 mm straight cut, 2 mm deep (as tests/test_library.py's).
LINE_NC = "G21 G90\nG0 X-10 Y0 Z5\nG1 Z-2 F600\nG1 X30 F1200\nG0 Z5\nM30\n"
DEFLECTION_TOL_MM = 0.5

N_POSES = 12
#: Agreement of the symbolic (CasADi) kinematics with pinocchio's [m, rad]: both exact up to
#: rounding on a 3 m arm.
EXACT_TOL = 1e-12
#: Data files write positions to 0.1 mm at most and the published reach is a rounded figure [m].
REACH_TOL = 5e-3
#: Translational TCP stiffness of heavy machining arms at their working poses [N/m]: the thesis's
#: KR 210 shows about 0.5 N/µm at the demo job's pose (planner/data/demo), the shipped arms 0.4-1.6 N/µm
#: at the small job's; a unit slip (N·mm/rad read as N·m/rad) would move it by 1e3.
TCP_STIFFNESS_RANGE = (2e5, 1e7)
FORCE_N = 100.0
#: Signal sample rate of the simulated cut [Hz] and the length of the supervised runs [s].
FS_HZ = 10_000.0
RUN_S = 1.5
#: The chatter that the supervised run must catch: from ONSET_S on, a margin this far below zero
#: at the planned feed [N/m, s].
CHATTER_OFFSET_N_PER_M = 1e5
ONSET_S = 0.3

#: The modified DH table (α_{i-1} [rad], a_{i-1} [m], d_i [m], θ offset [rad]) of the KR 500 R2830
#: in RobotKinematicsCatalogue (KUKA_KR500_R2830.py) and the signs that turn KUKA axis values into
#: its θ (A1, A4, A6 turn about −z / −x in KUKA's convention).
KR500_DHM = ((0.0, 0.0, 1.045, 0.0), (-math.pi / 2, 0.5, 0.0, 0.0),
             (0.0, 1.3, 0.0, -math.pi / 2), (-math.pi / 2, -0.055, 1.025, 0.0),
             (math.pi / 2, 0.0, 0.0, 0.0), (-math.pi / 2, 0.0, 0.29, math.pi))
KR500_DH_SIGNS = np.array([-1.0, 1.0, 1.0, -1.0, 1.0, -1.0])


def _random_poses(name: str, seed: int) -> list[np.ndarray]:
    d = robot_data(name)
    rng = np.random.default_rng(seed)
    return [rng.uniform(d.lower, d.upper) for _ in range(N_POSES)]


def _tcp_m(name: str) -> np.ndarray:
    return np.asarray(PLACEMENT_MM[name][1], float) * 1e-3


# ------------------------------------------------------------------------------------ plans
@pytest.fixture(scope="module")
def planned(tmp_path_factory):
    """name -> (PlanResult of the small job, its saved and reloaded Plan), planned once."""
    from planner.job import parse_job
    from planner.plan import plan_job, plan_of_result
    from planner.plan_file import load_plan

    cache: dict = {}

    def get(name: str):
        if name not in cache:
            assert name in PLACEMENT_MM, f"add a placement of the small job for {name} here"
            folder = tmp_path_factory.mktemp(name)
            (folder / "line.nc").write_text(LINE_NC, encoding="utf-8")
            base, tcp = PLACEMENT_MM[name]
            doc = {"job": {"name": f"line_{name}", "toolpath": ["line.nc"]},
                   "cell": {"robot": name, "base_mm": base, "tcp_mm": tcp},
                   "tool": {"name": "em10_3f"}, "material": "al6061", "spindle": {"rpm": 4000.0},
                   "engagement": {"ae_mm": 3.0, "ap_mm": 2.0},
                   "limits": {"deflection_tol_mm": DEFLECTION_TOL_MM}}
            res = plan_job(parse_job(doc, "line.toml", folder), "optimize")
            plan_of_result(res).save(folder / "plan")
            cache[name] = (res, load_plan(folder / "plan"))
        return cache[name]

    return get


# ------------------------------------------------------------------------------------ data
def test_every_shipped_robot_has_a_reference_here() -> None:
    assert set(ROBOTS) >= {"kr210_r2700_extra", "kr270_r2700_ultra", "kr500_r2830"}
    missing = set(ROBOTS) - set(REFERENCE) - set(PLACEMENT_MM)
    assert not missing, f"add REFERENCE and PLACEMENT_MM lines for {sorted(missing)}"


@pytest.mark.parametrize("name", ROBOTS)
def test_the_robot_loads_with_the_source_of_every_value(name: str) -> None:
    d = robot_data(name)
    robot = load_robot(name)  # the loader's own checks: limits agree with the URDF, a flange
    assert robot.nq == 6 and d.joint_names == ("A1", "A2", "A3", "A4", "A5", "A6")
    assert d.description and d.vendor == d.vendor.lower()
    assert {"kinematics", "limits", "joint_stiffness", "inertia"} <= set(d.sources)
    assert all(len(text) > 20 for text in d.sources.values())
    for key in REFERENCE[name][2]:
        assert "ASSUMPTION" in d.sources[key], (name, key)
    np.testing.assert_allclose(d.joint_stiffness, REFERENCE[name][1], rtol=1e-12)
    assert np.all(d.lower < 0) and np.all(d.upper > d.lower)
    assert np.all(d.velocity > 0) and np.all(d.acceleration > 0)


# ------------------------------------------------------------------------------------ kinematics
@pytest.mark.parametrize("name", ROBOTS)
def test_forward_kinematics_is_the_urdf_through_pinocchio(name: str) -> None:
    robot = load_robot(name)
    model = pin.buildModelFromUrdf(str(robot.data.urdf_path))   # a fresh read, not the robot's
    data = model.createData()
    fid = model.getFrameId("flange")
    tcp = _tcp_m(name)
    for q in _random_poses(name, 21):
        pin.framesForwardKinematics(model, data, q)
        flange = data.oMf[fid]
        p, rot = robot.pose_function(q, tcp)
        np.testing.assert_allclose(np.asarray(rot, float), flange.rotation, atol=EXACT_TOL)
        np.testing.assert_allclose(np.asarray(p, float).reshape(3), flange.act(tcp),
                                   atol=EXACT_TOL)
        # the Jacobian the stiffness model uses is pinocchio's at the TCP
        tcp_model, tcp_frame = robot.pin_model(tcp=tcp)
        tcp_data = tcp_model.createData()
        pin.computeJointJacobians(tcp_model, tcp_data, q)
        pin.updateFramePlacements(tcp_model, tcp_data)
        jac = pin.getFrameJacobian(tcp_model, tcp_data, tcp_frame, pin.LOCAL_WORLD_ALIGNED)
        np.testing.assert_allclose(np.asarray(robot.jacobian_function(q, tcp), float), jac,
                                   atol=EXACT_TOL)


@pytest.mark.parametrize("name", ROBOTS)
def test_the_zero_pose_and_reach_are_the_cited_numbers(name: str) -> None:
    robot = load_robot(name)
    model, data = robot.model, robot.model.createData()
    pin.framesForwardKinematics(model, data, np.zeros(6))
    np.testing.assert_allclose(data.oMf[robot.flange_frame].translation, REFERENCE[name][0],
                               atol=1e-12)
    # at zero the flange faces +x of the base (the KUKA convention, docs/model.md §2)
    np.testing.assert_allclose(data.oMf[robot.flange_frame].rotation, np.eye(3), atol=1e-12)
    # KUKA's "R" number is the reach to the wrist point: A2's offset + upper arm + A3 to wrist
    a2, a3, a5 = (data.oMi[i].translation for i in (2, 3, 5))
    reach = a2[0] + np.linalg.norm(a3 - a2) + np.linalg.norm(a5 - a3)
    r_number = int(re.search(r"_r(\d{4})", name).group(1)) * 1e-3
    assert reach == pytest.approx(r_number, abs=REACH_TOL)


def _dhm_pose(q: np.ndarray) -> np.ndarray:
    """4×4 pose of the last frame of :data:`KR500_DHM` (Craig's modified DH), θ = signs · q."""
    out = np.eye(4)
    for (alpha, a, d, offset), theta in zip(KR500_DHM, KR500_DH_SIGNS * q, strict=True):
        ca, sa, ct, st = math.cos(alpha), math.sin(alpha), math.cos(theta + offset), math.sin(
            theta + offset)
        out = out @ np.array([[ct, -st, 0.0, a],
                              [st * ca, ct * ca, -sa, -sa * d],
                              [st * sa, ct * sa, ca, ca * d],
                              [0.0, 0.0, 0.0, 1.0]])
    return out


def test_the_kr500_is_its_published_dh_table() -> None:
    robot = load_robot("kr500_r2830")
    model, data = robot.model, robot.model.createData()
    # the DH table's last frame has z along the tool; the flange has x: one fixed rotation
    fixed = None
    for q in _random_poses("kr500_r2830", 5):
        pin.framesForwardKinematics(model, data, q)
        flange = data.oMf[robot.flange_frame]
        dh = _dhm_pose(q)
        np.testing.assert_allclose(dh[:3, 3], flange.translation, atol=1e-12)
        rel = flange.rotation.T @ dh[:3, :3]
        fixed = rel if fixed is None else fixed
        np.testing.assert_allclose(rel, fixed, atol=1e-12)
    np.testing.assert_allclose(fixed[:, 2], [1.0, 0.0, 0.0], atol=1e-12)


# ------------------------------------------------------------------------------------ planning
@pytest.mark.parametrize("name", ROBOTS)
def test_a_small_job_plans_and_passes_the_checker(planned, name: str) -> None:
    from planner.check import check_result
    from planner.sections import CUT

    res, plan = planned(name)
    assert res.solver.success and res.prep.kinematics.all_reachable
    assert res.prep.robot is load_robot(name)
    report = check_result(res)
    assert report.ok, report.violations[:5]
    assert report.samples_checked == int(np.sum(res.kinds == CUT)) > 10
    ev = res.evaluation
    assert np.all(np.isfinite(ev.deflection_norm)) and np.all(np.isfinite(ev.force))
    assert 0.0 < ev.deflection_norm.max() < DEFLECTION_TOL_MM * 1e-3
    assert plan.robot == name and any(s.kind == "cut" for s in plan.sections)
    assert 0.0 < plan.cycle_time < 60.0


@pytest.mark.parametrize("name", ROBOTS)
def test_static_deflection_is_the_cited_stiffness_and_of_the_expected_order(planned,
                                                                            name: str) -> None:
    from planner.sections import CUT

    res, _ = planned(name)
    robot = load_robot(name)
    q = res.prep.kinematics.q[np.flatnonzero(res.kinds == CUT)[0]]
    tcp = _tcp_m(name)
    params = ModelParameters(joint_stiffness=robot.data.joint_stiffness,
                             coefficients=load_material("al6061").coefficients(), cct=False,
                             tcp=tcp)
    jac = np.asarray(robot.jacobian_function(q, tcp), float)
    compliance = jac[:3] @ np.diag(1.0 / robot.data.joint_stiffness) @ jac[:3].T
    f = deflection_of_force(robot)
    for axis in range(3):
        force = np.zeros(3)
        force[axis] = FORCE_N
        delta = np.asarray(f(q, force, params.vector())[0], float).reshape(3)
        np.testing.assert_allclose(delta, compliance @ force, rtol=1e-9, atol=1e-15)
        stiffness = FORCE_N / np.linalg.norm(delta)
        assert TCP_STIFFNESS_RANGE[0] < stiffness < TCP_STIFFNESS_RANGE[1], (name, axis, stiffness)
    # with the CCT term (the planner's model) the deflection stays finite and close
    delta_cct = np.asarray(f(q, np.array([FORCE_N, 0.0, 0.0]), replace(params, cct=True).vector())[0],
                           float).reshape(3)
    assert np.all(np.isfinite(delta_cct))
    assert np.linalg.norm(delta_cct - compliance[:, 0] * FORCE_N) < 0.5 * np.linalg.norm(
        compliance[:, 0] * FORCE_N)


# ------------------------------------------------------------------------------------ supervision
def _supervise(plan, scenario):
    from planner.supervisor.loop import VirtualClock
    from planner.supervisor.policy import SupervisorConfig
    from planner.supervisor.session import SessionConfig, run_session, simulated_sigma
    from planner.supervisor.sim_cut import SimulatedCut

    cut_section = next(s for s in plan.sections if s.kind == "cut")
    clock, link = VirtualClock(), ApplyingLink()
    cut = SimulatedCut(plan, link.read_override, FS_HZ, scenario, clock=clock,
                       start_s=cut_section.s_start)
    config = SessionConfig(duration=RUN_S, start=cut_section.s_start,
                           sigma=simulated_sigma(plan, FS_HZ, scenario, SupervisorConfig()))
    summary = run_session(plan, cut, link, config, FS_HZ, cut=cut, scenario=scenario,
                          clock=clock, sleep=clock.sleep)
    return cut_section, summary.as_json()


@pytest.mark.parametrize("name", ROBOTS)
def test_a_short_supervised_run_of_the_plan_works(planned, name: str) -> None:
    from planner.supervisor.sim_cut import CutScenario

    _, plan = planned(name)
    # a stable cut: the loop runs every cycle, nothing alarms, the override stays at 100 %
    section, out = _supervise(plan, CutScenario())
    assert out["steps"] >= RUN_S / 0.004 * 0.99 and out["counts"]["errors"] == 0
    assert not out["episodes"] and not out["alarms"] and out["final_override"] == 100.0
    # chatter from ONSET_S on (the arm CHATTER_OFFSET_N_PER_M less stable than its plan at the
    # planned feed): detected in the cut section, the override lowered
    ch = section.characteristic
    offset = float(np.interp(section.feed, ch.feeds, ch.margin)) + CHATTER_OFFSET_N_PER_M
    section, out = _supervise(plan, CutScenario(onset_s=ONSET_S, boundary_shift=1.0,
                                                margin_offset_N_per_m=offset))
    (episode,) = out["episodes"]
    assert episode["section"] == section.number and episode["detection_delay_ms"] is not None
    assert out["final_override"] < 100.0


# ------------------------------------------------------------------------------------ KRL export
@pytest.mark.parametrize("name", ROBOTS)
def test_krl_export_takes_a_kuka_and_refuses_any_other_maker(planned, name: str) -> None:
    from planner.export import ExportError, plan_to_krl

    _, plan = planned(name)
    vendor = robot_data(name).vendor
    if vendor == DEFAULT_VENDOR:
        assert plan_to_krl(plan).moves
    else:
        with pytest.raises(ExportError, match=rf"for {name}, whose controller is '{vendor}', "
                                              r"not KUKA: KRL runs on KUKA controllers only"):
            plan_to_krl(plan)


def test_krl_export_refuses_a_new_robot_of_another_maker(planned, monkeypatch) -> None:
    from planner.export import ExportError, plan_to_krl

    _, plan = planned("kr500_r2830")
    real = robot_module.robot_data
    monkeypatch.setattr(robot_module, "robot_data", lambda n: replace(real(n), vendor="abb"))
    with pytest.raises(ExportError, match=r"for kr500_r2830, whose controller is 'abb', not KUKA: "
                                          r"KRL runs on KUKA controllers only and no abb program "
                                          r"writer ships"):
        plan_to_krl(plan)
