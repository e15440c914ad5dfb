"""Online deflection compensation through RSI RKorr: wall error on a simulated cut, and the step's cost.

The simulated cut
    A straight wall along base +X (400 mm at 10 mm/s: 10,000 cycles of 4 ms), the KR 210 with a
    vertical tool (TCP 250 mm below the flange), the thesis's 25.4 mm two-flute end mill in
    Al 6061, down milling, planned a_e 3 mm, a_p 10 mm, 4000 rpm. The *plan* (the model) knows the
    arm's joint stiffness from the robot file and the planned stock. The *true* cell differs:
    its joint stiffness is 20 % below the model's (K_θ,true = 0.8 K_θ,model, every joint) and its
    stock is 1 mm more than planned over the first half of the wall and 1 mm less over the second
    (a_e 4 mm, then 2 mm). The true arm deflects under the true mean force (same cutting
    coefficients), δ_true = C_true(q, F)·F; the deflection feeds back into the engagement (a tool
    pushed off the wall by e cuts a_e − e; three fixed-point passes per cycle).

    The force sensor reports the true mean force of the previous cycle plus white noise (1 N per
    axis); a correction computed in cycle k reaches the path in cycle k + 1 (the reply of cycle
    k is applied at the controller's next interpolation). The controller applies RKorr like the
    simulated RSI controller (``robot_io.links.rsi_sim.SimulatedCorrection``: ``#RELATIVE``, total
    capped at POSCORR ±5 mm / ±5°).

    Wall error = the true TCP's deviation from the nominal path along the wall normal (> 0:
    material left), every cycle. The commanded pose moves by the corrections (≤ 0.5 mm here); the
    stiffness is evaluated at the nominal joints (the change of C over 0.5 mm is below 0.1 %).

Four cases: no compensation; the offline mirror only (the exported path moved by −δ_plan, what
``cctmill export --compensate-deflection`` writes: δ from the plan's engagement and the model's
stiffness); online RKorr only (:class:`planner.supervisor.compensation.DeflectionCompensator`,
defaults: engagement estimate, 10 mm/s, base frame); both (the online part corrects only
δ − δ_plan). A fifth row is a reference, not a case: an oracle that knows the true force exactly and
compensates with the model's compliance — what any feed-forward compensation with a 20 % stiffness
error can reach at best. The step's cost is timed per call (``perf_counter`` wall time and
``thread_time`` CPU time, garbage collector frozen as in the supervisor loop) over every online
case (the two above, the calibrated and the what-if ones).

Calibrate, then compensate (the real workflow, issue 19 then issue 20): before the wall, the cell
runs identification test cuts in the *same* true cell (:func:`planner.calibrate.testcuts.identification_cuts`,
the design of ``benchmarks/calibration.py``: 12 slot passes of the wall's tool at 12,000 rpm, a_p 2
and 3 mm, feed per tooth alternating 0.025 and 0.25 mm, here at five points along the wall), each
simulated with the time-domain model (:func:`planner.calibrate.truth.run_cuts`) and measured as a
cell would: the mean force with N(0, σ²) per component, σ = 0.5 N + 1 % of |F̄| (a dynamometer),
and the static deflection with 15 µm per component (a laser tracker). The joint stiffness scale is
fitted to them (:func:`planner.calibrate.fit_stiffness.fit_stiffness`), written into a calibration
overlay (:func:`planner.calibrate.run.write_calibration`, what ``cctmill calibrate`` writes), a job
naming the overlay is loaded and its model (:func:`planner.supervisor.compensation.job_parameters`)
is what the mirror's δ_plan and the online compensation use. The calibrated rows share the
uncalibrated rows' no-compensation baseline (the true cell is the same). The rows use the first
noise seed's fit; the full run fits four seeds and repeats "both" with the worst seed's fit (when
that is not the first), and with the cutting coefficients fitted too (``cctmill calibrate``'s
default; the truth's coefficients are the material file's, the fitted ones bring their own error).

The target is judged on the RMS wall error over the whole wall; the max is reported with where it
lies (the entry, the stock step, or the steady cut). What-if rows (labelled as such) repeat the
wall with the model's stiffness within 10 % and 5 % of the truth.

Run from the repository root: ``python benchmarks/compensation.py [--quick] [--json]``.
"""

from __future__ import annotations

import argparse
import gc
import json
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from models import Cut, ModelParameters, load_material, load_robot, load_tool  # noqa: E402
from models.analysis import point_function  # noqa: E402
from planner.calibrate.context import CalibrationContext  # noqa: E402
from planner.calibrate.fit_coefficients import FitRefused, fit_coefficients  # noqa: E402
from planner.calibrate.fit_stiffness import fit_stiffness  # noqa: E402
from planner.calibrate.run import CalibrationResult, write_calibration  # noqa: E402
from planner.calibrate.testcuts import identification_cuts  # noqa: E402
from planner.calibrate.truth import TruthCell, run_cuts  # noqa: E402
from planner.job import parse_job  # noqa: E402
from planner.supervisor.compensation import (  # noqa: E402
    CompensationConfig,
    DeflectionCompensator,
    job_parameters,
)
from robot_io.links.rsi_sim import SimulatedCorrection  # noqa: E402

#: The benchmark's figures of merit (issue 20 and the thesis, Chapter 4).
TARGET_REDUCTION = 0.85
THESIS_REDUCTION = 0.70
CYCLE_S = 0.004
#: Joint stiffness of the true arm relative to the model's [-].
TRUE_STIFFNESS_SCALE = 0.8
STOCK_ERROR = 1e-3          # true stock minus planned [m], + then − along the wall
FORCE_NOISE_N = 1.0
FEED = 10e-3                # [m/s]
LENGTH = 0.4                # [m]
START = np.array([1.60, 0.0])   # TCP x, y at the start [m]; z from the start pose
Q_START_DEG = (0.0, -60.0, 100.0, 0.0, 50.0, 0.0)
TCP = np.array([0.25, 0.0, 0.0])
A_E_PLAN, A_P, RPM = 3e-3, 10e-3, 4000.0
FIXED_POINT_PASSES = 3
#: What-if rows: the true joint stiffness relative to the model's when the model is calibrated
#: from the cell's own cuts (within 10 % and 5 %) [-].
WHAT_IF_SCALES = (0.90, 0.95)
#: Length after the entry and after the stock step that counts as a transient [m] (5 mm: 0.5 s).
TRANSIENT_M = 5e-3
#: The quick wall (tests): 80 mm.
QUICK_LENGTH = 0.08
_IK_TOL = 1e-9  # [m]

#: Calibrate, then compensate (the module docstring): the identification design of
#: benchmarks/calibration.py — slot passes at CAL_RPM (far above the arm's modes: no chatter),
#: a_p CAL_AP_MM, feed per tooth alternating CAL_FZ_MIN_MM and the tool's maximum — at CAL_POSES
#: points along the wall; the quick path runs fewer, shorter passes.
CAL_CUTS, QUICK_CAL_CUTS = 12, 4
CAL_RPM = 12_000.0
CAL_AP_MM = (2.0, 3.0)
CAL_FZ_MIN_MM = 0.025
CAL_POSES = 5
#: Measurement error of the test cuts: mean force σ = abs [N] + rel × |F̄| per component (a
#: dynamometer), static deflection σ [mm] per component (a laser tracker).
CAL_FORCE_NOISE_N, CAL_FORCE_NOISE_REL, CAL_DEFLECTION_NOISE_MM = 0.5, 0.01, 0.015
#: Noise seeds of the test cuts in the full run (the rows use the first; the worst is a row too).
CAL_SEEDS = 4
#: Simulated time of a test pass [s] (the mean force is over whole tooth periods of its second
#: half: 2.5 ms each at 12,000 rpm).
CAL_DURATION_S, QUICK_CAL_DURATION_S = 0.6, 0.3
#: The wall's job as a job file would say it (the calibration overlay is merged into it).
WALL_JOB = {"job": {"name": "wall", "toolpath": ["wall.nc"]}, "material": "al6061",
            "cell": {"tcp_mm": [float(v) * 1e3 for v in TCP]}, "tool": {"name": "em25_2f"},
            "spindle": {"rpm": RPM},
            "engagement": {"source": "fixed", "ae_mm": A_E_PLAN * 1e3, "ap_mm": A_P * 1e3,
                           "milling": "down"}}


def _ik_path(robot, q0: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """Joints along ``targets`` [m] (n, 3) with the start orientation held (Newton, pseudo-inverse)."""
    out = np.zeros((len(targets), robot.nq))
    q = q0.copy()
    for i, p_goal in enumerate(targets):
        for _ in range(30):
            p = np.asarray(robot.pose_function(q, TCP)[0], float).reshape(3)
            err = p_goal - p
            if np.linalg.norm(err) < _IK_TOL:
                break
            jac = np.asarray(robot.jacobian_function(q, TCP), float)
            q = q + np.linalg.pinv(jac) @ np.concatenate([err, np.zeros(3)])
        else:
            raise RuntimeError(f"the wall's path point {i} is not reachable")
        out[i] = q
    return out


def setup(length: float = LENGTH) -> dict:
    robot = load_robot()
    mat, tool = load_material("al6061"), load_tool("em25_2f")
    model = ModelParameters(joint_stiffness=robot.data.joint_stiffness, coefficients=mat.coefficients(),
                            tcp=TCP, spindle_mass=robot.data.spindle_mass, spindle_com=robot.data.spindle_com)
    true = ModelParameters(joint_stiffness=robot.data.joint_stiffness * TRUE_STIFFNESS_SCALE,
                           coefficients=mat.coefficients(), tcp=TCP, spindle_mass=robot.data.spindle_mass,
                           spindle_com=robot.data.spindle_com)
    cut = Cut([1.0, 0.0, 0.0], [0.0, 1.0, 0.0], A_E_PLAN, A_P, "down", RPM * math.pi / 30.0,
              tool.flutes, tool.radius)
    n = int(round(length / (FEED * CYCLE_S)))
    s = np.arange(n) * FEED * CYCLE_S
    q0 = np.radians(Q_START_DEG)
    p0 = np.asarray(robot.pose_function(q0, TCP)[0], float).reshape(3)
    targets = np.column_stack([START[0] + s, np.full(n, START[1]), np.full(n, p0[2])])
    # IK on every 20th cycle, joints interpolated between (the path is straight and short)
    knots = np.arange(0, n + 19, 20).clip(max=n - 1)
    qk = _ik_path(robot, q0, targets[knots])
    q = np.column_stack([np.interp(np.arange(n), knots, qk[:, j]) for j in range(robot.nq)])
    a_true = A_E_PLAN + np.where(s < length / 2, STOCK_ERROR, -STOCK_ERROR)
    point = point_function(robot, "oriented", "isotropic", outputs=("deflection", "force_base"))
    cv = cut.vector()
    plan_delta = np.array([np.asarray(point(qi, cv, FEED, model.vector())[0], float).reshape(3) for qi in q])
    # material side: down milling, material on −X_o; wall error > 0 = pushed off the wall (+X_o)
    wall_dir = cut.radial_dir.copy()
    return {"robot": robot, "model": model, "true": true, "cut": cv, "q": q, "s": s, "a_true": a_true,
            "length": length,
            "plan_delta": plan_delta, "point": point, "wall_dir": wall_dir, "n": n}


def _true_cut(st: dict, i: int, offset_mm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(true force [N], wall error [m]) at cycle ``i`` with the commanded offset ``offset_mm`` (base)."""
    cv = st["cut"].copy()
    wall = 0.0
    f = np.zeros(3)
    offset_wall = float(offset_mm[:3] @ st["wall_dir"]) * 1e-3
    for _ in range(FIXED_POINT_PASSES):
        a_e = min(max(st["a_true"][i] - wall, 1e-5), 2 * cv[11])
        cv[6] = a_e
        d, fb = st["point"](st["q"][i], cv, FEED, st["true"].vector())
        f = np.asarray(fb, float).reshape(3)
        wall = offset_wall + float(np.asarray(d, float).reshape(3) @ st["wall_dir"])
    return f, np.array(wall)


def run_case(st: dict, mirror: bool, online: bool, oracle: bool = False, seed: int = 0) -> dict:
    rng = np.random.default_rng(seed)
    n = st["n"]
    comp = DeflectionCompensator(st["robot"], st["model"], st["cut"], CompensationConfig(cycle_s=CYCLE_S))
    comp.prepare(FEED)  # the θ table, before the loop (as PlanCompensation does)
    ctl = SimulatedCorrection("relative")
    pending = np.zeros(6)            # the increment computed last cycle, applied this cycle
    measured = None
    wall = np.zeros(n)
    wall_t, cpu_t = [], []
    statuses: dict[str, int] = {}
    of_force = None
    if oracle:
        from models.deflection import deflection_of_force
        of_force = deflection_of_force(st["robot"])
    was = gc.isenabled()
    gc.collect()
    gc.freeze()
    gc.disable()
    try:
        for i in range(n):
            ctl.apply(tuple(pending))
            pending = np.zeros(6)
            offset = np.array(ctl.total)
            if mirror:
                offset[:3] -= st["plan_delta"][i] * 1e3
            if oracle:
                # the exact true force of this cycle, the model's compliance: the feed-forward bound
                for _ in range(FIXED_POINT_PASSES):
                    f_true, _ = _true_cut(st, i, offset)
                    d = np.asarray(of_force(st["q"][i], f_true, st["model"].vector())[0], float).reshape(3)
                    offset = np.concatenate([-d * 1e3, np.zeros(3)])
            f_true, e = _true_cut(st, i, offset)
            wall[i] = float(e)
            if online and measured is not None:
                c0, t0 = time.thread_time(), time.perf_counter()
                res = comp.step(measured, st["q"][i], FEED,
                                offline_delta=st["plan_delta"][i] if mirror else None)
                wall_t.append(time.perf_counter() - t0)
                cpu_t.append(time.thread_time() - c0)
                pending = np.asarray(res.increment, float)
                statuses[str(res.status)] = statuses.get(str(res.status), 0) + 1
            measured = f_true + rng.normal(0.0, FORCE_NOISE_N, 3)
            if i % 250 == 249:
                gc.collect(1)
    finally:
        gc.unfreeze()
        if was:
            gc.enable()
    k = int(np.argmax(np.abs(wall)))
    step = int(np.searchsorted(st["s"], st["length"] / 2))
    # the steady part: away from the entry and the stock step by TRANSIENT_M each
    steady = np.ones(n, bool)
    steady[:int(TRANSIENT_M / (FEED * CYCLE_S))] = False
    steady[step:step + int(TRANSIENT_M / (FEED * CYCLE_S))] = False
    return {"rms_mm": float(np.sqrt(np.mean(wall ** 2)) * 1e3), "max_mm": float(np.max(np.abs(wall)) * 1e3),
            "mean_mm": float(np.mean(wall) * 1e3), "max_at_mm": float(st["s"][k] * 1e3),
            "max_where": _where(k, step, n), "steady_max_mm": float(np.max(np.abs(wall[steady])) * 1e3),
            "step_wall_s": wall_t, "step_cpu_s": cpu_t, "statuses": statuses, "poscorr_capped": ctl.capped}


def _where(k: int, step: int, n: int) -> str:
    w = int(TRANSIENT_M / (FEED * CYCLE_S))
    if k < w:
        return "entry"
    if step <= k < step + w:
        return "stock step"
    return "steady"


def _stats_us(a: list[float]) -> dict:
    x = np.asarray(a, float) * 1e6
    return {"n": int(x.size), "p50_us": float(np.percentile(x, 50)), "p99_us": float(np.percentile(x, 99)),
            "max_us": float(x.max())}


def _reductions(cases: dict, base: dict | None = None) -> None:
    """Each case's reduction against ``base`` (default: the block's own no-compensation row)."""
    base = base or cases["no compensation"]
    for r in cases.values():
        r["reduction_rms"] = 1.0 - r["rms_mm"] / base["rms_mm"]
        r["reduction_max"] = 1.0 - r["max_mm"] / base["max_mm"]


def _with_model(st: dict, params: ModelParameters) -> dict:
    """The wall planned with another model: the compensation's model and the mirror's δ_plan."""
    v = params.vector()
    plan_delta = np.array([np.asarray(st["point"](qi, st["cut"], FEED, v)[0], float).reshape(3)
                           for qi in st["q"]])
    return dict(st, model=params, plan_delta=plan_delta)


def _job_model(folder: Path, robot, result: CalibrationResult | None = None) -> ModelParameters:
    """The model of the wall's job (:func:`job_parameters`), with ``result``'s calibration overlay
    written into ``folder`` (:func:`write_calibration`, what ``cctmill calibrate -o`` writes) and
    named by the job (``[calibration] overlay``)."""
    doc = dict(WALL_JOB)
    if result is not None:
        overlay, _ = write_calibration(result, folder / "wall.overlay.toml")
        doc["calibration"] = {"overlay": overlay.name}
    return job_parameters(parse_job(doc, "the wall's job", folder), robot)


def calibrate_first(st: dict, quick: bool = False, log=None) -> dict:
    """Test cuts in the wall's true cell, the fits, and the calibrated job's model (the module
    docstring): the design, ``fits`` (one per noise seed: scale, its interval and error),
    ``worst_seed``, and the calibrated job's models: ``model`` (the first seed's stiffness),
    ``model_worst`` (the worst seed's, when not the first), ``model_coefficients`` (the first
    seed's stiffness and cutting coefficients; full run only)."""
    robot = st["robot"]
    ctx = CalibrationContext(tcp=tuple(float(v) for v in TCP), tool=load_tool("em25_2f"),
                             material=load_material("al6061"))
    n = st["n"]
    poses = [tuple(float(v) for v in np.degrees(st["q"][i]))
             for i in np.linspace(0, n - 1, CAL_POSES).round().astype(int)]
    n_cuts = QUICK_CAL_CUTS if quick else CAL_CUTS
    planned = identification_cuts(ctx, poses, n_cuts, rpm=CAL_RPM, ae_mm=(2e3 * ctx.tool.radius,),
                                  ap_mm=CAL_AP_MM, milling="slot", feeds="ends", fz_min_mm=CAL_FZ_MIN_MM)
    truth = TruthCell(ctx, joint_scale=TRUE_STIFFNESS_SCALE, coefficient_factor=1.0, process_gain=1.0,
                      force_noise_n=CAL_FORCE_NOISE_N, force_noise_rel=CAL_FORCE_NOISE_REL,
                      deflection_noise_mm=CAL_DEFLECTION_NOISE_MM,
                      duration_s=QUICK_CAL_DURATION_S if quick else CAL_DURATION_S)
    k_true = truth.coefficients()
    fits, results = [], []
    t0 = time.perf_counter()
    for seed in range(1 if quick else CAL_SEEDS):
        records = run_cuts(truth, planned, seed=seed)
        stiff = fit_stiffness(ctx, records)
        coef = None
        if not quick:
            try:
                coef = fit_coefficients(records, ctx.tool, ctx.material)
            except FitRefused as e:
                if log:
                    log(f"  compensation: the coefficient fit of seed {seed} is refused: {e}")
        results.append((records, stiff, coef))
        fits.append({"seed": seed, "scale": stiff.scale, "scale_ci": list(stiff.scale_ci),
                     "scale_error": stiff.scale / TRUE_STIFFNESS_SCALE - 1.0,
                     "chatter": sum(r.verdict == "chatter" for r in records),
                     "coefficient_error_max": (None if coef is None
                                               else float(np.max(np.abs(coef.values / k_true - 1.0))))})
        if log:
            log(f"  compensation: calibration seed {seed}: scale {stiff.scale:.4f} "
                f"({100 * fits[-1]['scale_error']:+.2f} % off the truth)")
    worst = int(np.argmax([abs(f["scale_error"]) for f in fits]))
    out = {"n_cuts": n_cuts, "poses": len(poses), "rpm": CAL_RPM, "ap_mm": list(CAL_AP_MM),
           "feed_per_tooth_mm": sorted({round(r.feed_mm_s * 60.0 / (ctx.tool.flutes * r.rpm), 6)
                                        for r in planned}),
           "duration_s": truth.duration_s, "fits": fits, "worst_seed": worst,
           "time_s": time.perf_counter() - t0}
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        nominal = _job_model(folder, robot)
        if not np.allclose(nominal.vector(), st["model"].vector(), rtol=1e-12, atol=0.0):
            raise RuntimeError("the wall's job does not give the benchmark's model: fix WALL_JOB")

        def model(k: int, coefficients: bool = False) -> ModelParameters:
            records, stiff, coef = results[k]
            res = CalibrationResult(ctx, tuple(records), (), "the wall's job",
                                    coef if coefficients else None, stiff)
            return _job_model(folder, robot, res)

        out["model"] = model(0)
        out["scale_in_job"] = float(out["model"].joint_stiffness[0] / nominal.joint_stiffness[0])
        if worst != 0:
            out["model_worst"] = model(worst)
        if results[0][2] is not None:
            out["model_coefficients"] = model(0, coefficients=True)
    return out


def _with_truth(st: dict, scale: float) -> dict:
    m = st["model"]
    true = ModelParameters(joint_stiffness=m.joint_stiffness * scale, coefficients=m.coefficients, tcp=m.tcp,
                           spindle_mass=m.spindle_mass, spindle_com=m.spindle_com)
    return dict(st, true=true)


ORACLE = "reference: exact force, model compliance (oracle)"
BOTH = "mirror + online RKorr"
CALIBRATED = "calibrated first: "
CAL_BOTH = CALIBRATED + BOTH
CAL_ORACLE = CALIBRATED + "reference: exact force, calibrated compliance (oracle)"


def run(log=None, quick: bool = False) -> dict:
    """The benchmark (``quick``: an 80 mm wall, the no-compensation, both and oracle rows only,
    calibrated first with 4 shorter test cuts and one seed: its both row only; no what-if rows)."""
    st = setup(QUICK_LENGTH if quick else LENGTH)
    cases = {"no compensation": (False, False, False), "offline mirror only": (True, False, False),
             "online RKorr only": (False, True, False), BOTH: (True, True, False),
             ORACLE: (False, False, True)}
    if quick:
        cases = {k: v for k, v in cases.items() if k in ("no compensation", BOTH, ORACLE)}
    out: dict = {"cycles": st["n"], "length_mm": st["length"] * 1e3, "quick": quick, "cases": {},
                 "what_if": {}}
    wall_t: list[float] = []
    cpu_t: list[float] = []
    for name, (mirror, online, oracle) in cases.items():
        if log:
            log(f"  compensation: {name} ...")
        r = run_case(st, mirror, online, oracle)
        wall_t += r.pop("step_wall_s")
        cpu_t += r.pop("step_cpu_s")
        out["cases"][name] = r
    _reductions(out["cases"])
    if log:
        log("  compensation: calibrating first (test cuts in the true cell) ...")
    cal = calibrate_first(st, quick, log)
    cal_cases = {CALIBRATED + k: (cal["model"], v) for k, v in cases.items()
                 if k != "no compensation" and not v[2]}
    cal_cases[CAL_ORACLE] = (cal["model"], cases[ORACLE])
    if quick:
        cal_cases = {CAL_BOTH: cal_cases[CAL_BOTH]}
    worst = cal["fits"][cal["worst_seed"]]
    if "model_worst" in cal:
        cal_cases[f"calibrated first, the worst of {len(cal['fits'])} seeds' fits (seed {worst['seed']}, "
                  f"scale {100 * worst['scale_error']:+.1f} % off): {BOTH}"] = (cal["model_worst"],
                                                                                cases[BOTH])
    if "model_coefficients" in cal:
        cal_cases[f"calibrated first, the cutting coefficients fitted too: {BOTH}"] = (
            cal["model_coefficients"], cases[BOTH])
    planned: dict[int, dict] = {}
    out["calibrated"] = {k: v for k, v in cal.items() if not k.startswith("model")}
    out["calibrated"]["cases"] = {}
    for name, (params, (mirror, online, oracle)) in cal_cases.items():
        if log:
            log(f"  compensation: {name} ...")
        if id(params) not in planned:   # the wall planned with this model once (its δ_plan)
            planned[id(params)] = _with_model(st, params)
        r = run_case(planned[id(params)], mirror, online, oracle)
        wall_t += r.pop("step_wall_s")
        cpu_t += r.pop("step_cpu_s")
        out["calibrated"]["cases"][name] = r
    _reductions(out["calibrated"]["cases"], out["cases"]["no compensation"])
    for scale in () if quick else WHAT_IF_SCALES:
        sw = _with_truth(st, scale)
        rows = {}
        for name in ("no compensation", BOTH, ORACLE):
            if log:
                log(f"  compensation what-if (true stiffness {scale:.2f} x model): {name} ...")
            mirror, online, oracle = cases[name]
            r = run_case(sw, mirror, online, oracle)
            wall_t += r.pop("step_wall_s")
            cpu_t += r.pop("step_cpu_s")
            rows[name] = r
        _reductions(rows)
        out["what_if"][f"{scale:.2f}"] = rows
    out["step_wall"] = _stats_us(wall_t)
    out["step_cpu"] = _stats_us(cpu_t)
    both, bound = out["cases"][BOTH], out["cases"][ORACLE]
    cb = out["calibrated"]["cases"][CAL_BOTH]
    cbound = out["calibrated"]["cases"].get(CAL_ORACLE)
    out["verdict"] = {"measure": "RMS of the wall error over the whole wall",
                      "both_reduction": both["reduction_rms"], "both_reduction_max": both["reduction_max"],
                      "target_met": both["reduction_rms"] >= TARGET_REDUCTION,
                      "thesis_met": both["reduction_rms"] >= THESIS_REDUCTION,
                      "bound_reduction": bound["reduction_rms"],
                      "calibrated_reduction": cb["reduction_rms"],
                      "calibrated_reduction_max": cb["reduction_max"],
                      "calibrated_target_met": cb["reduction_rms"] >= TARGET_REDUCTION,
                      "calibrated_bound_reduction": None if cbound is None else cbound["reduction_rms"],
                      "fits_4ms": out["step_wall"]["max_us"] < CYCLE_S * 1e6,
                      "fits_4ms_cpu": out["step_cpu"]["max_us"] < CYCLE_S * 1e6}
    return out


def _row(name: str, c: dict) -> str:
    return (f"| {name} | {c['rms_mm']:.4f} | {c['max_mm']:.4f} | {c['max_where']} "
            f"({c['max_at_mm']:.2f} mm) | {c['steady_max_mm']:.4f} | {c['mean_mm']:+.4f} | "
            f"{100 * c['reduction_rms']:.1f} % | {100 * c['reduction_max']:.1f} % |")


_HEAD = ["| case | wall error RMS [mm] | max [mm] | max where (at) | max off transients [mm] | mean [mm] | "
         "reduction RMS | reduction max |", "|---|---:|---:|---|---:|---:|---:|---:|"]


def markdown(r: dict) -> str:
    lines = [f"Simulated wall: {r['length_mm']:.0f} mm, {r['cycles']:,} cycles of {CYCLE_S * 1e3:.0f} ms; "
             f"true joint stiffness {TRUE_STIFFNESS_SCALE:.1f} × the model's, true stock "
             f"±{STOCK_ERROR * 1e3:.0f} mm off the plan's (a_e 4 mm, then 2 mm, planned 3 mm). "
             "\"max off transients\" leaves out "
             f"{TRANSIENT_M * 1e3:.0f} mm after the entry and after the stock step. The \"calibrated "
             "first\" rows share the no-compensation baseline above them (the same true cell).", "",
             *_HEAD]
    lines += [_row(name, c) for name, c in r["cases"].items()]
    lines += [_row(name, c) for name, c in r["calibrated"]["cases"].items()]
    cal = r["calibrated"]
    f0 = cal["fits"][0]
    lines += ["", f"| calibration before the cut: {cal['n_cuts']} test cuts, noise seed | fitted joint "
                  f"stiffness scale (95 % CI) | off the truth ({TRUE_STIFFNESS_SCALE:g}) | cutting "
                  "coefficients, worst error | used by |", "|---|---:|---:|---:|---|"]
    for f in cal["fits"]:
        ce = f["coefficient_error_max"]
        used = ("the calibrated rows" if f["seed"] == f0["seed"] else
                "the worst-seed row" if f["seed"] == cal["fits"][cal["worst_seed"]]["seed"] else "—")
        coef = "not fitted" if ce is None else f"{100 * ce:.1f} %"
        lines.append(f"| seed {f['seed']} | {f['scale']:.4f} ({f['scale_ci'][0]:.4f} … "
                     f"{f['scale_ci'][1]:.4f}) | {100 * f['scale_error']:+.2f} % | {coef} | {used} |")
    if r["what_if"]:
        lines += ["", "**What-if, not the case**: the same wall with the model's joint stiffness closer to "
                      "the truth, as a calibration from the cell's own cuts (docs/model.md §11) would give "
                      "it. Each block has its own no-compensation baseline.", "", *_HEAD]
        for scale, rows in r["what_if"].items():
            for name, c in rows.items():
                lines.append(_row(f"true stiffness {float(scale):.2f} × model: {name}", c))
    w, cpu, v = r["step_wall"], r["step_cpu"], r["verdict"]
    lines += ["", "| RKorr step cost (online cases) | steps | p50 | p99 | worst | worst / 4 ms |",
              "|---|---:|---:|---:|---:|---:|",
              f"| wall time (perf_counter) | {w['n']:,} | {w['p50_us']:.0f} µs | {w['p99_us']:.0f} µs | "
              f"{w['max_us']:.0f} µs | {w['max_us'] / (CYCLE_S * 1e6):.2f} |",
              f"| CPU time (thread_time) | {cpu['n']:,} | {cpu['p50_us']:.0f} µs | {cpu['p99_us']:.0f} µs | "
              f"{cpu['max_us']:.0f} µs | {cpu['max_us'] / (CYCLE_S * 1e6):.2f} |", ""]
    red, red_max, bound = (100 * v["both_reduction"], 100 * v["both_reduction_max"],
                           100 * v["bound_reduction"])
    head = (f"The target is judged on the RMS wall error over the whole wall. Both together remove "
            f"{red:.1f} % of it (the max: {red_max:.1f} %; the table says where each max lies)")
    if v["target_met"]:
        lines.append(head + f": the ≥ {100 * TARGET_REDUCTION:.0f} % target is met "
                            f"(thesis > {100 * THESIS_REDUCTION:.0f} %).")
    else:
        lines.append(
            head + f": the ≥ {100 * TARGET_REDUCTION:.0f} % target is NOT met"
            + (f" (the thesis figure, > {100 * THESIS_REDUCTION:.0f} %, is)" if v["thesis_met"]
               else f", nor the thesis figure (> {100 * THESIS_REDUCTION:.0f} %)") + ". "
            f"It cannot be with this model: the correction is a feed-forward of the *model's* compliance, "
            f"and the true arm is {100 * (1 / TRUE_STIFFNESS_SCALE - 1):.0f} % more compliant. The oracle, "
            f"which knows the true force exactly and has no delay, removes {bound:.1f} %: that is the bound "
            "of any feed-forward compensation with this stiffness error, and nothing in the loop measures "
            "the tool's position to close the gap: a better model does, which the calibrated rows give.")
    cr, cr_max, cbound = (100 * v["calibrated_reduction"], 100 * v["calibrated_reduction_max"],
                          v["calibrated_bound_reduction"])
    lines += [
        "", f"Calibrate, then compensate: {cal['n_cuts']} identification test cuts in the same true cell "
        f"(slot passes at {cal['rpm']:,.0f} rpm, a_p {' and '.join(f'{a:g}' for a in cal['ap_mm'])} mm, feed "
        f"per tooth {' and '.join(f'{x:g}' for x in cal['feed_per_tooth_mm'])} mm, at {cal['poses']} "
        f"points along the wall; force noise {CAL_FORCE_NOISE_N:g} N + {100 * CAL_FORCE_NOISE_REL:g} %, "
        f"deflection noise {CAL_DEFLECTION_NOISE_MM * 1e3:g} µm) give a joint stiffness scale of "
        f"{f0['scale']:.4f} ({100 * f0['scale_error']:+.2f} % off the truth's "
        f"{TRUE_STIFFNESS_SCALE:g}); with the calibrated model mirror + online RKorr remove {cr:.1f} % "
        f"of the RMS wall error (the max: {cr_max:.1f} %)"
        + (f"; the oracle with the calibrated compliance, {100 * cbound:.1f} %" if cbound is not None else "")
        + (f": the ≥ {100 * TARGET_REDUCTION:.0f} % target is met with a calibrated model."
           if v["calibrated_target_met"] else
           f": the ≥ {100 * TARGET_REDUCTION:.0f} % target is NOT met even with a calibrated model.")]
    if len(cal["fits"]) > 1:
        wf = cal["fits"][cal["worst_seed"]]
        lines[-1] += (f" Of {len(cal['fits'])} noise seeds of the test cuts, seed {wf['seed']} fits worst "
                      f"({100 * wf['scale_error']:+.2f} %)" + (": the rows are its." if wf is f0 else
                                                                 ": its row is in the table."))
    if not v["fits_4ms"]:
        lines.append(f"The worst step's wall time ({w['max_us']:.0f} µs) exceeds the 4 ms cycle; its CPU "
                     f"time is {cpu['max_us']:.0f} µs: the excess is preemption by other processes."
                     if v["fits_4ms_cpu"] else
                     f"The worst step ({w['max_us']:.0f} µs wall, {cpu['max_us']:.0f} µs CPU) exceeds the "
                     "4 ms cycle.")
    return "\n".join(lines)


def summary_rows(r: dict) -> list[tuple[str, str, str, str]]:
    v, c, w = r["verdict"], r["cases"], r["step_wall"]

    def rms(name: str) -> str:
        return f"{100 * c[name]['reduction_rms']:.1f} %" if name in c else "n/a"

    cal = r["calibrated"]

    def crms(name: str) -> str:
        got = [x for k, x in cal["cases"].items() if k.startswith(CALIBRATED + name)]
        return f"{100 * got[0]['reduction_rms']:.1f} %" if got else "n/a"

    return [("compensation: wall error RMS, mirror + online RKorr (20 % stiffness, ±1 mm stock error)",
             f"{100 * v['both_reduction']:.1f} % less (mirror only {rms('offline mirror only')}, "
             f"online only {rms('online RKorr only')}; oracle bound {100 * v['bound_reduction']:.1f} %)",
             f"≥ {100 * TARGET_REDUCTION:.0f} % (thesis > {100 * THESIS_REDUCTION:.0f} %)",
             "met" if v["target_met"] else ("NOT met (thesis figure met; bound "
                                            f"{100 * v['bound_reduction']:.0f} %)" if v["thesis_met"]
                                            else "NOT met")),
            (f"compensation: calibrate first ({cal['n_cuts']} test cuts in the same cell, stiffness scale "
             f"{100 * cal['fits'][0]['scale_error']:+.1f} % off), then mirror + online RKorr",
             f"{100 * v['calibrated_reduction']:.1f} % less (mirror only {crms('offline mirror only')}, "
             f"online only {crms('online RKorr only')}; oracle bound {crms('reference')})",
             f"≥ {100 * TARGET_REDUCTION:.0f} %",
             "met" if v["calibrated_target_met"] else "NOT met"),
            ("compensation: RKorr step cost, worst",
             f"{w['max_us']:.0f} µs wall (p99 {w['p99_us']:.0f} µs; CPU worst "
             f"{r['step_cpu']['max_us']:.0f} µs) over {w['n']:,} steps", "inside the 4 ms cycle",
             "met" if v["fits_4ms"] else ("CPU met, wall NOT (preemption)" if v["fits_4ms_cpu"]
                                          else "NOT met"))]


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true", help="print JSON instead of Markdown")
    ap.add_argument("--quick", action="store_true",
                    help=f"an {QUICK_LENGTH * 1e3:.0f} mm wall, {QUICK_CAL_CUTS} shorter test cuts, "
                         "no what-if rows")
    args = ap.parse_args(argv)
    r = run(log=lambda s: print(s, file=sys.stderr, flush=True), quick=args.quick)
    print(json.dumps(r, indent=2) if args.json else markdown(r))
    return r


if __name__ == "__main__":
    main()
