"""Online deflection compensation through RSI RKorr (planner.supervisor.compensation): δ against the
model, the limits, the holds, the increments, the RSI loopback to the simulated controller, the
supervisor loop's wiring, the job's calibrated model (overlay) and the benchmark's quick wall
(calibrated first and not)."""

from __future__ import annotations

import math
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from _plans import ONE_SECTION, make_plan
from _threads import no_leaked_threads, wait_for  # noqa: F401  (autouse fixture)

from models import Cut, ModelParameters, load_material, load_robot, load_tool
from models.analysis import point_function
from models.deflection import deflection_of_force
from models.errors import InputError
from planner.plan_file import load_plan
from planner.supervisor import (
    CompensationConfig,
    CompensationStatus,
    DeflectionCompensator,
    PlanCompensation,
)
from planner.supervisor.compensation import job_parameters
from robot_io.links.base import LinkStatus
from robot_io.links.rsi import RsiServer
from robot_io.links.rsi_sim import _START_POSE, RsiSimController

BENCH = str(Path(__file__).resolve().parents[1] / "benchmarks")
if BENCH not in sys.path:
    sys.path.insert(0, BENCH)

Q_DEG = (0.0, -60.0, 100.0, 0.0, 50.0, 0.0)   # the benchmark's wall pose (vertical tool)
TCP = np.array([0.25, 0.0, 0.0])
FEED = 10e-3


@pytest.fixture(scope="module")
def model():
    robot = load_robot()
    tool = load_tool("em25_2f")
    params = ModelParameters(joint_stiffness=robot.data.joint_stiffness,
                             coefficients=load_material("al6061").coefficients(), tcp=TCP,
                             spindle_mass=robot.data.spindle_mass, spindle_com=robot.data.spindle_com)
    cut = Cut([1.0, 0.0, 0.0], [0.0, 1.0, 0.0], 3e-3, 10e-3, "down", 4000 * math.pi / 30, tool.flutes,
              tool.radius).vector()
    q = np.radians(Q_DEG)
    d, f = point_function(robot, "oriented", "isotropic", outputs=("deflection", "force_base"))(
        q, cut, FEED, params.vector())
    return robot, params, cut, q, np.asarray(d, float).reshape(3), np.asarray(f, float).reshape(3)


def _comp(model, **kw) -> DeflectionCompensator:
    robot, params, cut, *_ = model
    c = DeflectionCompensator(robot, params, cut, CompensationConfig(**kw))
    c.prepare(FEED)
    return c


def test_delta_is_the_models_deflection_at_the_estimated_engagement(model):
    robot, params, cut, q, delta, force = model
    # δ = C_tt(q, F)·F of models.deflection is the point model's deflection under the same force
    d2 = np.asarray(deflection_of_force(robot)(q, force, params.vector())[0], float).reshape(3)
    np.testing.assert_allclose(d2, delta, rtol=1e-9, atol=1e-12)
    comp = _comp(model, max_rate_mm_s=1e4)  # no rate limit: one step reaches the target
    res = comp.step(force, q, FEED)
    assert res.status is CompensationStatus.OK, res.reason
    assert res.a_e == pytest.approx(3e-3, abs=5e-6)         # the force angle gives the planned a_e back
    np.testing.assert_allclose(res.delta, delta, rtol=2e-3, atol=1e-9)
    np.testing.assert_allclose(res.total[:3], -delta * 1e3, rtol=2e-3, atol=1e-6)
    assert res.total[3:] == (0.0, 0.0, 0.0)
    # a measured force at another engagement: the estimate follows it (the stock differs from the plan)
    f4 = np.asarray(point_function(robot, "oriented", "isotropic", outputs=("force_base",))(
        q, np.r_[cut[:6], 4e-3, cut[7:]], FEED, params.vector()), float).reshape(3)
    assert comp.step(f4, q, FEED).a_e == pytest.approx(4e-3, abs=1e-5)
    # the tool frame: the same correction in the TCP's axes
    tool = _comp(model, max_rate_mm_s=1e4, frame="tool")
    rt = tool.step(force, q, FEED)
    rot = np.asarray(robot.pose_function(q, TCP)[1], float)
    np.testing.assert_allclose(rot @ np.array(rt.total[:3]), res.total[:3], atol=1e-9)
    assert np.linalg.norm(res.total[:3]) > 0.01
    # "base" with the plan's $BASE rotation: the same correction in $BASE axes (POSCORR #BASE)
    from robot_io.krl.frames import abc_to_matrix

    r_base = abc_to_matrix(90.0, 0.0, 0.0)
    wp = DeflectionCompensator(robot, params, cut, CompensationConfig(max_rate_mm_s=1e4),
                               base_rotation=r_base)
    wp.prepare(FEED)
    np.testing.assert_allclose(r_base @ np.array(wp.step(force, q, FEED).total[:3]), res.total[:3], atol=1e-9)


def test_rate_limit_and_bound_hold(model):
    *_, q, _delta, force = model
    comp = _comp(model, force="measured", max_rate_mm_s=10.0)
    step_mm = 10.0 * 0.004
    huge = force * 400.0   # δ of tens of mm: beyond the ±5 mm bound
    seen = set()
    for _ in range(400):
        res = comp.step(huge, q, FEED)
        seen.add(res.status)
        assert np.linalg.norm(res.increment[:3]) <= step_mm * (1 + 1e-9)
        assert max(abs(v) for v in res.total[:3]) <= 5.0 + 1e-12
    assert CompensationStatus.RATE_LIMITED in seen and res.status is CompensationStatus.CLAMPED
    assert "clamped" in res.reason
    assert max(abs(v) for v in res.total[:3]) == pytest.approx(5.0)
    # out of the cut: back towards zero, at the same rate
    before = np.array(res.total[:3])
    res = comp.step(np.zeros(3), q, FEED)
    assert res.status is CompensationStatus.NOT_CUTTING
    assert np.linalg.norm(np.array(res.total[:3]) - before) == pytest.approx(step_mm)


def test_bad_input_holds_and_says_why(model):
    *_, q, _delta, force = model
    comp = _comp(model)
    first = comp.step(force, q, FEED)
    for bad, why in (((math.nan, 0.0, 0.0), "non-finite"), (force, "joint")):
        res = comp.step(bad, q[:5] if why == "joint" else q, FEED)
        assert res.status is CompensationStatus.INVALID
        assert why in res.reason and "held" in res.reason
        assert res.increment == (0.0,) * 6 and res.total == first.total
    assert comp.step(force, q, math.inf).status is CompensationStatus.INVALID
    assert comp.step(force, q, FEED, cut=np.zeros(12)).status is CompensationStatus.INVALID
    with pytest.raises(InputError):
        CompensationConfig(frame="flange")


def test_relative_increments_sum_to_the_total(model):
    *_, q, _delta, force = model
    comp = _comp(model)
    rng = np.random.default_rng(3)
    acc = np.zeros(6)
    for k in range(300):
        f = force * (1.0 + 0.5 * math.sin(k / 20.0)) + rng.normal(0, 2.0, 3)
        if k % 50 == 7:
            f = np.full(3, math.nan)
        acc += comp.step(f, q, FEED).increment
    np.testing.assert_allclose(acc, comp.total, atol=1e-12)


def test_rsi_loopback_applies_rkorr_to_the_controllers_path():
    with RsiServer() as srv, RsiSimController(srv.address) as sim:
        assert wait_for(lambda: srv.connected)
        st = srv.set_correction((0.5, -0.25, 0.0, 0.0, 0.0, 0.0))
        assert st.ok and st.percent == 0
        for _ in range(30):   # one increment a reply, each below the telegram's 0.1 µm resolution
            n = srv.stats.replies
            assert srv.set_correction((3e-5, 0.0, 0.0, 0.0, 0.0, 0.0)).percent == 0
            assert wait_for(lambda n=n: srv.stats.replies > n + 1)
        want = (0.5009, -0.25, 0.0, 0.0, 0.0, 0.0)   # the remainders are carried, not lost
        assert wait_for(lambda: np.allclose(sim.correction.total, want, atol=6e-5))
        assert np.allclose(srv.correction_sent, sim.correction.total, atol=1e-12)
        # RIst, what the controller reports, is the programmed path plus the correction
        assert wait_for(lambda: abs(srv.last_telegram.poses["RIST"]["Y"] - sim.path_pose()[1]) < 1e-6)
        assert sim.path_pose()[1] == pytest.approx(_START_POSE[1] - 0.25)
        refused = srv.set_correction((math.nan,) * 6)
        assert not refused.ok and refused.percent is None
        assert srv.set_correction((1.0,) * 5).percent is None
        assert srv.set_correction((0.0,) * 6, mode="sideways").percent is None
    # #ABSOLUTE: the controller holds the last values; a total beyond POSCORR is capped there
    with RsiServer() as srv, RsiSimController(srv.address, correction_mode="absolute") as sim:
        assert wait_for(lambda: srv.connected)
        srv.set_correction((1.0, 2.0, 9.0, 0.0, 0.0, 0.0), mode="absolute")
        assert wait_for(lambda: sim.correction.total == (1.0, 2.0, 5.0, 0.0, 0.0, 0.0))
        assert sim.correction.capped > 0


class _SlowServer(RsiServer):
    """Replies to every 7th telegram two cycles late (the controller drops them)."""

    n = 0

    def _handle(self, data, addr, t_rx):
        self.n += 1
        if self.n > 20 and self.n % 7 == 0:
            import time

            time.sleep(0.01)
        super()._handle(data, addr, t_rx)


def test_a_correction_in_a_late_reply_is_sent_again():
    with _SlowServer() as srv, RsiSimController(srv.address) as sim:
        assert wait_for(lambda: srv.connected)
        for _ in range(60):
            n = srv.stats.replies
            srv.set_correction((0.01, 0.0, -0.01, 0.0, 0.0, 0.0))
            assert wait_for(lambda n=n: srv.stats.replies > n)
        want = (0.6, 0.0, -0.6, 0.0, 0.0, 0.0)
        assert wait_for(lambda: np.allclose(sim.correction.total, want, atol=1e-9))
        assert sim.stats.late > 0 and srv.corrections_resent > 0
        assert np.allclose(srv.correction_sent, want, atol=1e-9)


def test_process_server_sends_the_correction_through_its_child():
    from robot_io.links.rsi_process import SYNC_PERIOD_S, RsiProcessServer

    with RsiProcessServer() as srv:
        assert srv.set_correction((0.1, 0.0, 0.0, 0.0, 0.0, 0.0)).percent == 0   # kept for the first reply
        with RsiSimController(srv.address) as sim:
            assert wait_for(lambda: srv.connected)
            for _ in range(10):
                assert srv.set_correction((0.0, 0.02, -0.01, 0.0, 0.0, 0.0)).ok
            want = (0.1, 0.2, -0.1, 0.0, 0.0, 0.0)
            assert wait_for(lambda: np.allclose(sim.correction.total, want, atol=1e-9))
            assert wait_for(lambda: np.allclose(srv.correction_sent, want, atol=1e-9), 10 * SYNC_PERIOD_S + 1)
            assert srv.set_correction((math.inf,) * 6).percent is None
    assert not srv.set_correction((0.0,) * 6).ok   # closed


def _wall_plan(tmp_path: Path, model):
    """The synthetic one-section plan with the benchmark's wall in its samples."""
    robot, params, cut, q, *_ = model
    plan = load_plan(make_plan(tmp_path, ONE_SECTION))
    smp = plan.samples
    n = smp.s.size
    pos = np.column_stack([1.6 + smp.s, np.zeros(n), np.zeros(n)])
    smp = replace(smp, q=np.tile(q, (n, 1)), position_wp=pos, tool_axis_wp=np.tile([0.0, 0.0, 1.0], (n, 1)),
                  mode=np.ones(n, int), a_e=np.full(n, 3e-3), a_p=np.full(n, 10e-3), kind=np.zeros(n, int),
                  feed=np.full(n, FEED))
    return replace(plan, samples=smp, spindle_rpm=4000.0, tool_xyz=tuple(TCP))


class _Res:
    def __init__(self, s_m: float) -> None:
        self.s_m, self.override = s_m, 100.0


class _Link:
    def __init__(self, fail: bool = False) -> None:
        self.fail, self.sum = fail, np.zeros(6)

    def set_correction(self, values, mode="relative"):
        if self.fail:
            raise OSError("socket gone")
        self.sum += values
        return LinkStatus(True, "sent in next reply", 0)


def test_plan_compensation_follows_the_plan_and_holds_on_a_link_failure(tmp_path, model):
    _robot, _params, cut, q, delta, force = model
    plan = _wall_plan(tmp_path, model)
    pc = PlanCompensation(plan, None, CompensationConfig())
    pc.set_force(pc.model_force)
    np.testing.assert_allclose(pc.cuts[5], cut, atol=1e-9)   # the cut frame from the path and tool axis
    np.testing.assert_allclose(pc.model_force(0.01, FEED, 5), force, rtol=1e-9)
    link = _Link()
    for k in range(100):
        pc(0.004 * k, _Res(0.01 + 4e-5 * k), 100.0, link)
    np.testing.assert_allclose(link.sum, pc.compensator.total, atol=1e-12)
    np.testing.assert_allclose(link.sum[:3], -delta * 1e3, rtol=5e-3)
    held = pc.compensator.total
    bad = _Link(fail=True)
    for k in range(5):
        pc(1.0 + k, _Res(0.02), 50.0, bad)                   # never raises; the total is held
    assert pc.link_failures == 5 and pc.compensator.total == held
    pc.set_force(lambda *a: None)
    assert pc(2.0, _Res(0.02), 100.0, link).status is CompensationStatus.INVALID
    assert pc.summary()["status_counts"]["invalid"] == 1


def test_supervised_session_sends_rkorr_to_the_simulated_controller(tmp_path, model):
    from planner.supervisor.session import SessionConfig, supervise

    plan = _wall_plan(tmp_path, model)
    cfg = SessionConfig(duration=1.0, sim_protocol="rsi", compensation=CompensationConfig())
    s = supervise(plan, "sim", "sim", cfg)
    comp = s.as_json()["compensation"]
    assert comp["link_failures"] == 0 and "errors" not in comp
    assert sum(comp["status_counts"].values()) == s.loop.steps
    np.testing.assert_allclose(comp["controller_applied"], comp["sent"], atol=1e-3)
    np.testing.assert_allclose(comp["sent"], comp["total"], atol=1e-3)
    assert np.linalg.norm(comp["total"][:3]) > 0.01
    with pytest.raises(InputError, match="RSI"):
        supervise(plan, "sim", "sim", replace(cfg, sim_protocol="kvp"))


#: The wall's job (the benchmark's cell) as a job document: TCP 250 mm, the planned cut.
_WALL_JOB = {"job": {"name": "wall", "toolpath": ["wall.nc"]}, "cell": {"tcp_mm": [250.0, 0.0, 0.0]},
             "spindle": {"rpm": 4000.0}, "engagement": {"ae_mm": 3.0, "ap_mm": 10.0, "milling": "down"}}


def test_a_calibration_overlay_changes_the_compensations_force_and_compliance(tmp_path, model):
    from types import SimpleNamespace

    from planner.calibrate.fit_coefficients import COEFFICIENT_NAMES
    from planner.calibrate.overlay import write_overlay
    from planner.ceilings import model_parameters
    from planner.job import parse_job

    robot, params, cut, q, _delta, force = model
    k_fit = params.coefficients * 1.2
    write_overlay(tmp_path / "cell.overlay.toml", {"joint_stiffness_scale": 0.8}, {},
                  dict(zip(COEFFICIENT_NAMES, (float(v) for v in k_fit), strict=True)))
    plain_job = parse_job(dict(_WALL_JOB), "job", tmp_path)
    cal_job = parse_job({**_WALL_JOB, "calibration": {"overlay": "cell.overlay.toml"}}, "job", tmp_path)
    plain, cal = job_parameters(plain_job, robot), job_parameters(cal_job, robot)
    np.testing.assert_allclose(plain.vector(), params.vector(), rtol=1e-12)   # no overlay: the files' model
    np.testing.assert_allclose(cal.joint_stiffness, 0.8 * params.joint_stiffness, rtol=1e-12)
    np.testing.assert_allclose(cal.coefficients, k_fit, rtol=1e-12)
    # the same model the planner's ceilings (and so the plan's offline δ) use
    np.testing.assert_allclose(cal.vector(), model_parameters(cal_job, SimpleNamespace(robot=robot)).vector())
    # the compensation follows the overlay: the same measured force, the same force angle (all six
    # coefficients × 1.2) and so the same a_e, but 1.2 × the model's force and 1/0.8 × the compliance
    cfg = CompensationConfig(max_rate_mm_s=1e4)
    r0 = DeflectionCompensator(robot, plain, cut, cfg).step(force, q, FEED)
    r1 = DeflectionCompensator(robot, cal, cut, cfg).step(force, q, FEED)
    assert r0.status is r1.status is CompensationStatus.OK
    assert r1.a_e == pytest.approx(r0.a_e, abs=1e-6)
    np.testing.assert_allclose(r1.force, 1.2 * r0.force, rtol=1e-9)
    np.testing.assert_allclose(r1.delta, 1.2 / 0.8 * r0.delta, rtol=2e-2)   # CCT: not exactly linear
    np.testing.assert_allclose(r1.total[:3], 1.5 * np.asarray(r0.total[:3]), rtol=2e-2)
    # along a plan: the job's overlay (job=) or what the plan records of it, else the files'
    plan = _wall_plan(tmp_path, model)
    np.testing.assert_allclose(PlanCompensation(plan, None).params.vector(), params.vector(), rtol=1e-12)
    np.testing.assert_allclose(PlanCompensation(plan, None, job=cal_job).params.vector(), cal.vector(),
                               rtol=1e-12)
    recorded = replace(plan, model={**plan.model, "joint_stiffness_scale": 0.8,
                                    "coefficients": [float(v) for v in k_fit]})
    got = PlanCompensation(recorded, None).params
    np.testing.assert_allclose(got.joint_stiffness, cal.joint_stiffness, rtol=1e-12)
    np.testing.assert_allclose(got.coefficients, cal.coefficients, rtol=1e-12)
    with pytest.raises(InputError, match="coefficients"):
        PlanCompensation(replace(plan, model={"coefficients": [1.0, 2.0]}), None)


@pytest.fixture(scope="module")
def quick_bench():
    import compensation as bench

    return bench, bench.run(quick=True)


def test_benchmark_quick_wall_reduces_the_error(quick_bench):
    bench, r = quick_bench
    both = r["cases"]["mirror + online RKorr"]
    assert both["reduction_rms"] > 0.5
    assert both["reduction_rms"] <= r["cases"][bench.ORACLE]["reduction_rms"] + 0.02
    assert "NOT met" in bench.markdown(r) or r["verdict"]["target_met"]


def test_benchmark_calibrating_first_reduces_the_error_more(quick_bench):
    bench, r = quick_bench
    cal = r["calibrated"]
    assert cal["n_cuts"] == bench.QUICK_CAL_CUTS and len(cal["fits"]) == 1
    # the test cuts recover the true cell's stiffness (0.8 × the model's) and the job reads it
    assert abs(cal["fits"][0]["scale_error"]) < 0.05
    assert cal["scale_in_job"] == pytest.approx(cal["fits"][0]["scale"], rel=1e-5)
    calibrated = cal["cases"][bench.CAL_BOTH]["reduction_rms"]
    assert calibrated > r["cases"][bench.BOTH]["reduction_rms"]
    assert calibrated > r["cases"][bench.ORACLE]["reduction_rms"]   # beyond the uncalibrated bound
    assert r["verdict"]["calibrated_reduction"] == calibrated
    text = bench.markdown(r)
    assert "calibrated first: mirror + online RKorr" in text and "Calibrate, then compensate" in text


def test_cli_flags_make_the_compensation_config():
    from planner.cli import build_parser
    from planner.cli.supervise import session_config

    base = ["supervise", "--plan", "p", "--signal", "sim", "--robot", "sim"]
    assert session_config(build_parser().parse_args(base)).compensation is None   # off by default
    args = build_parser().parse_args(base + ["--compensate-rkorr", "--rkorr-frame", "tool", "--rkorr-max-mm",
                                             "2", "--rkorr-rate-mm-s", "4", "--rkorr-offline",
                                             "--cycle-ms", "12"])
    cfg = session_config(args)
    assert cfg.compensation == CompensationConfig(cycle_s=0.012, max_position_mm=2.0, max_rate_mm_s=4.0,
                                                  frame="tool")
    assert cfg.compensation_offline
