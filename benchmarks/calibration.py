"""Calibration from cuts on a simulated truth: are the hidden cutting coefficients and joint stiffness
recovered from a dozen test cuts? (docs/calibration.md, "Validation")

The cell
    The demo job (``planner/data/demo/demo_job.toml``: KR 210 R2700 extra, TCP 320 mm, the thesis's
    25.4 mm two-flute end mill in Al 6061) is the *nominal* model. The *true* cell differs in
    hidden parameters: joint stiffness ×0.7 (every joint), cutting coefficients +15 % (all six),
    process gain ×1.3 (recorded; the time-domain model has no such knob), regeneration on.

The test cuts
    12 slot passes (the classic Altintas identification), a_p 2 and 3 mm, at 12,000 rpm
    (well above the arm's 7-15 Hz modes: no chatter at these depths), feed per tooth alternating
    0.025 and 0.25 mm (10-100 mm/s; two levels, the D-optimal line design), at five poses over the demo's
    stock top (corners and centre, tool vertical). Each pass is simulated in the true cell with the
    time-domain model of docs/model.md §6 (0.6 s, 5 kHz, 8 axial slices, equilibrium chip,
    regeneration), and recorded as a real cell would: mean force over whole tooth periods plus a
    measurement error N(0, σ²) per component with σ = 0.5 N + 1 % of |F̄| (a dynamometer's
    calibration, cross-talk and drift over a pass), and the static deflection under it plus
    15 µm per component (a laser tracker). A second noise level, 1 N + 2 % (a strain-gauge
    spindle), is the what-if row.

What is reported, per noise level, over several seeds (the worst seed is what counts): the error of
each fitted coefficient against the truth, whether its 95 % interval covers the truth, the common
joint stiffness scale's error, and the mean force the calibrated model predicts for a job-like
cut (down milling, a_e 10 mm, a_p 10 mm, 0.1 mm per tooth) against the truth's — beside the
nominal model's error for the same cut (the baseline measured in the same run).

The stability boundary
    In the same true cell, at the job's spindle speeds ±50 % (2000-6000 rpm), a_p 1-6 mm, a_e 12.7
    mm down milling, 0.1 mm per tooth: 16 space-filling passes, a logistic boundary P(chatter |
    eigen margin, a_p, rpm) on the calibrated model's margin, 8 more passes chosen by value of
    information, the boundary refitted. Judged on 30 fresh random passes in the truth by accuracy
    (P > ½ called chatter) and Brier score, against the nominal model's own verdicts (eigen, the
    job's criterion; floquet) as the baseline.

The critical depth (full run only)
    At the job's spindle speed (the demo: 4000 rpm) at three poses: the truth's critical a_p by
    bisection in the time-domain model against where a boundary's P(chatter) crosses ½ — after
    12 and 20 passes, space-filling against a space-filling start of 8 plus passes proposed by
    value of information at the job's speed (target: within 10 %; the proposals must need fewer).

Run from the repository root: ``python benchmarks/calibration.py [--quick] [--json]``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from models import cutting  # noqa: E402
from planner.calibrate.context import CalibrationContext  # noqa: E402
from planner.calibrate.design_bound import best_design, coefficient_bound  # noqa: E402
from planner.calibrate.fit_boundary import criterion_margin, fit_boundary  # noqa: E402
from planner.calibrate.fit_coefficients import (  # noqa: E402
    COEFFICIENT_NAMES,
    FitRefused,
    fit_coefficients,
)
from planner.calibrate.fit_process import fit_process_gain  # noqa: E402
from planner.calibrate.fit_stiffness import fit_stiffness  # noqa: E402
from planner.calibrate.testcuts import (  # noqa: E402
    boundary_cuts,
    identification_cuts,
    job_test_poses,
    propose_cuts,
)
from planner.calibrate.truth import TruthCell, run_cut, run_cuts  # noqa: E402
from planner.job import load_job  # noqa: E402

JOB = ROOT / "planner" / "data" / "demo" / "demo_job.toml"
N_CUTS = 12
RPM = 12_000.0
AP_MM = (2.0, 3.0)
#: The feed per tooth of the passes: the two ends of a tenfold span (0.025 mm, below the tool's
#: 0.05 mm production minimum, to the tool's 0.25 mm) — the D-optimal design for a straight line.
FEEDS, FZ_MIN_MM = "ends", 0.025
#: (label, absolute σ [N], relative σ [-]) of the force measurement error.
NOISE = (("dynamometer 0.5 N + 1 %", 0.5, 0.01), ("strain gauge 1 N + 2 % (what-if)", 1.0, 0.02))
SEEDS, QUICK_SEEDS = 8, 2
#: Targets of the issue: coefficients within 5 %, stiffness scale within 10 %.
COEFFICIENT_TARGET, STIFFNESS_TARGET = 0.05, 0.10
#: The true cell's hidden parameters (the module docstring): what every fit is judged against.
TRUTH = {"joint_scale": 0.7, "coefficient_factor": 1.15, "process_gain": 1.3}
#: The job-like cut the force prediction is judged on (down milling).
JOB_CUT = {"a_e": 10e-3, "a_p": 10e-3, "c": 0.1e-3}


def _job_force(coefficients: np.ndarray, tool) -> np.ndarray:
    return np.asarray(cutting.average_force(JOB_CUT["c"], JOB_CUT["a_e"], JOB_CUT["a_p"], "down",
                                            tool.flutes, tool.radius, coefficients), float).ravel()


def run(log=None, quick: bool = False) -> dict:
    """The benchmark (``quick``: two seeds and the first noise level only)."""
    log = log or (lambda s: None)
    t0 = time.perf_counter()
    job = load_job(JOB)
    ctx = CalibrationContext.from_job(job)
    poses = job_test_poses(job)
    planned = identification_cuts(ctx, poses, N_CUTS, rpm=RPM, ae_mm=(25.4,), ap_mm=AP_MM,
                                  milling="slot", feeds=FEEDS, fz_min_mm=FZ_MIN_MM)
    seeds = QUICK_SEEDS if quick else SEEDS
    fz_mm = sorted({round(r.feed_mm_s * 60.0 / (ctx.tool.flutes * r.rpm), 6) for r in planned})
    out: dict = {"quick": quick, "n_cuts": N_CUTS, "rpm": RPM, "ap_mm": list(AP_MM),
                 "feed_per_tooth_mm": fz_mm,
                 "poses_deg": [list(p) for p in poses], "seeds": seeds, "levels": []}
    for label, sigma_abs, sigma_rel in NOISE[:1] if quick else NOISE:
        truth = TruthCell(ctx, **TRUTH,
                          force_noise_n=sigma_abs, force_noise_rel=sigma_rel)
        k_true = truth.coefficients()
        f_true = _job_force(k_true, ctx.tool)
        f_nominal_err = float(np.linalg.norm(_job_force(ctx.material.coefficients(), ctx.tool)
                                             - f_true) / np.linalg.norm(f_true))
        rows = []
        recovered = None
        for seed in range(seeds):
            t = time.perf_counter()
            records = run_cuts(truth, planned, seed=seed)
            t_sim = time.perf_counter() - t
            t = time.perf_counter()
            fit = fit_coefficients(records, ctx.tool, ctx.material)
            stiff = fit_stiffness(ctx, records)
            t_fit = time.perf_counter() - t
            if recovered is None:
                recovered = (stiff.scale, fit.values)
            err = fit.values / k_true - 1.0
            covered = (fit.ci_low <= k_true) & (k_true <= fit.ci_high)
            f_err = float(np.linalg.norm(_job_force(fit.values, ctx.tool) - f_true)
                          / np.linalg.norm(f_true))
            rows.append({
                "seed": seed, "verdicts": "".join(r.verdict[0] for r in records),
                "coefficient_error": dict(zip(COEFFICIENT_NAMES, err.tolist(), strict=True)),
                "ci_half_width": dict(zip(COEFFICIENT_NAMES, fit.relative_half_width().tolist(),
                                          strict=True)),
                "ci_covers": dict(zip(COEFFICIENT_NAMES, covered.tolist(), strict=True)),
                "stiffness_scale": stiff.scale, "stiffness_ci": list(stiff.scale_ci),
                "stiffness_error": stiff.scale / TRUTH["joint_scale"] - 1.0,
                "job_force_error": f_err, "sigma_n": fit.sigma_n,
                "time_sim_s": t_sim, "time_fit_s": t_fit})
            log(f"{label} seed {seed}: K err % {np.round(100 * err, 1)}, stiffness "
                f"{stiff.scale:.4f}, job force err {100 * f_err:.2f} %")
        worst = {n: max(abs(r["coefficient_error"][n]) for r in rows) for n in COEFFICIENT_NAMES}
        coverage = {n: float(np.mean([r["ci_covers"][n] for r in rows]))
                    for n in COEFFICIENT_NAMES}
        if "recovered" not in out:   # what the boundary study may use: the first fit, not the truth
            out["recovered"] = {"stiffness_scale": recovered[0],
                                "coefficients": recovered[1].tolist()}
        out["levels"].append({
            "label": label, "sigma_abs_n": sigma_abs, "sigma_rel": sigma_rel, "rows": rows,
            "worst_coefficient_error": worst, "ci_coverage": coverage,
            "worst_stiffness_error": max(abs(r["stiffness_error"]) for r in rows),
            "worst_job_force_error": max(r["job_force_error"] for r in rows),
            "nominal_job_force_error": f_nominal_err,
            "bound": _bounds(ctx, planned, k_true, sigma_abs, sigma_rel)})
    rec = out["recovered"]
    out["boundary"] = _boundary(ctx, poses, quick, log, rec["stiffness_scale"],
                                np.asarray(rec["coefficients"], float))
    if not quick:
        out["critical"] = _critical(ctx, poses, log, ctx.params(
            rec["stiffness_scale"], np.asarray(rec["coefficients"], float)), job.spindle.rpm)
    out["time_s"] = time.perf_counter() - t0
    return out


#: The candidate passes of the best-design search (the Cramér–Rao bound): slots at these a_p
#: and half-immersion up and down milling at the two extreme ones, each at the design's two feeds
#: per tooth. Chatter is not considered: the search's bound is what mean forces could give at best.
BOUND_AP_MM, BOUND_HALF_AP_MM = (1.0, 2.0, 3.0, 4.0, 6.0, 8.0, 10.0), (2.0, 10.0)


def _bounds(ctx: CalibrationContext, planned, k_true: np.ndarray, sigma_abs: float,
            sigma_rel: float) -> dict:
    """The relative Cramér–Rao standard errors (1σ) of this design and of the best N_CUTS passes
    among the candidates (:mod:`planner.calibrate.design_bound`), at the truth's coefficients."""
    lo, hi = planned[0], planned[1]                     # the design's low and high feed passes
    cands = [replace(r, ap_mm=a) for r in (lo, hi) for a in BOUND_AP_MM]
    cands += [replace(r, ap_mm=a, milling=m, ae_mm=ctx.tool.radius * 1e3)
              for r in (lo, hi) for a in BOUND_HALF_AP_MM for m in ("up", "down")]
    here = coefficient_bound(planned, ctx.tool, k_true, sigma_abs, sigma_rel)
    picked, best = best_design(cands, N_CUTS, ctx.tool, k_true, sigma_abs, sigma_rel, starts=6)
    kinds = [(cands[i].milling, cands[i].ap_mm,
              round(cands[i].feed_mm_s * 60.0 / (ctx.tool.flutes * cands[i].rpm), 4)) for i in picked]
    counts = {c: kinds.count(c) for c in sorted(set(kinds))}
    return {"design": dict(zip(COEFFICIENT_NAMES, here.tolist(), strict=True)),
            "best": dict(zip(COEFFICIENT_NAMES, best.tolist(), strict=True)),
            "best_passes": [f"{n} x {m} a_p {a:g} mm fz {fz:g} mm" for (m, a, fz), n in counts.items()]}


#: The boundary study: the job's spindle speeds ±50 %, a_p 1-6 mm, a_e = R, down milling,
#: 0.1 mm per tooth; a space-filling start, then value-of-information passes, validated on fresh
#: random passes in the truth.
BOUNDARY = {"rpm": (2000.0, 6000.0), "ap_mm": (1.0, 6.0), "ae_mm": 12.7, "start": 16, "voi": 8,
            "validation": 30}


def _brier_accuracy(p: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    return float(np.mean((p - y) ** 2)), float(np.mean((p > 0.5) == (y > 0.5)))


def _boundary(ctx: CalibrationContext, poses, quick: bool, log, stiffness_scale: float,
              coefficients: np.ndarray) -> dict:
    """Fit P(chatter | margin, a_p, rpm) in the true cell, the margin computed with the stiffness
    scale and coefficients the first part recovered (never the truth's); judge it on fresh cuts
    against the nominal model's own verdicts (eigen, the job's criterion; floquet)."""
    b = BOUNDARY
    n_start, n_voi, n_val = (10, 4, 12) if quick else (b["start"], b["voi"], b["validation"])
    truth = TruthCell(ctx, **TRUTH)
    cal_params = ctx.params(stiffness_scale, coefficients)   # recovered by the first part
    start = boundary_cuts(ctx, poses, n_start, b["rpm"], b["ap_mm"], b["ae_mm"], seed=11)
    records = run_cuts(truth, start, seed=11)
    fit0 = fit_boundary(ctx, records, cal_params)
    voi = propose_cuts(ctx, fit0, poses[:2], n_voi, b["rpm"], b["ap_mm"], b["ae_mm"],
                       params=cal_params, grid=5)
    records += run_cuts(truth, voi, seed=12)
    fit1 = fit_boundary(ctx, records, cal_params)
    val = run_cuts(truth, boundary_cuts(ctx, poses, n_val, b["rpm"], b["ap_mm"], b["ae_mm"],
                                        seed=99), seed=13)
    y = np.array([r.verdict == "chatter" for r in val], float)
    x = np.array([[criterion_margin(ctx, r, cal_params), r.ap_mm, r.rpm] for r in val])
    rows = {}
    for name, fit in (("boundary, space-filling start", fit0), ("boundary + value of information", fit1)):
        rows[name] = _brier_accuracy(fit.probability(x), y)
    for crit in ("eigen", "floquet"):
        nominal = ctx.with_(criterion=crit)
        said = np.array([criterion_margin(nominal, r) <= 0.0 for r in val], float)
        rows[f"nominal model, {crit} verdict"] = _brier_accuracy(said, y)
    gain = None
    try:   # the eigen criterion with the process gain fitted to the same training passes
        g = fit_process_gain(ctx, records, cal_params)
        p_g = replace(cal_params, process_gain=cal_params.process_gain * g.gain)
        said = np.array([criterion_margin(ctx, r, p_g) <= 0.0 for r in val], float)
        rows[f"calibrated eigen verdict, process gain x{g.gain:.3g}"] = _brier_accuracy(said, y)
        gain = {"gain": g.gain, "gain_ci": list(g.gain_ci), "training_accuracy": g.accuracy}
    except FitRefused as e:
        gain = {"refused": e.reason}
    log(f"boundary: {int(y.sum())}/{len(y)} validation cuts chatter; " + "; ".join(
        f"{k}: accuracy {v[1]:.0%}" for k, v in rows.items()))
    return {"n_start": n_start, "n_voi": n_voi, "n_validation": n_val,
            "validation_chatter": int(y.sum()), "training_chatter": fit1.n_chatter,
            "rows": {k: {"brier": v[0], "accuracy": v[1]} for k, v in rows.items()},
            "process_gain": gain,
            "voi_p_chatter": [r.source["p_chatter"] for r in voi]}

#: The boundary as the issue judges it: the critical a_p at the job's spindle speed at three poses
#: (a_e 12.7 mm down milling, 0.1 mm per tooth); the truth's by bisection in the time-domain
#: model, a boundary's where its P(chatter) crosses ½; N passes proposed (a space-filling third,
#: then value of information in two rounds) against N space-filling passes.
CRITICAL = {"poses": 3, "ap_mm": (1.0, 8.0), "grid_mm": 0.05, "counts": (12, 20)}


def _truth_critical_ap(truth: TruthCell, ctx: CalibrationContext, q, rpm: float, ae_mm: float,
                       lo: float = 0.5, hi: float = 12.0, tol: float = 0.05) -> float:
    """The true cell's smallest chattering a_p [mm] at a pose (bisection on the verdict)."""
    from planner.calibrate.testcuts import _planned

    rng = np.random.default_rng(0)

    def chatters(ap: float) -> bool:
        rec = _planned(ctx, q, ap, ae_mm, rpm, 0.1, "down", 60.0, "crit", "critical depth")
        return run_cut(truth, rec, rng).verdict == "chatter"

    if chatters(lo) or not chatters(hi):
        return float("nan")
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if chatters(mid) else (mid, hi)
    return 0.5 * (lo + hi)


def _model_critical_ap(ctx: CalibrationContext, q, rpm: float, ae_mm: float, said, top: float,
                       step: float) -> float:
    """The smallest a_p [mm] on a grid where ``said(records) -> P(chatter)`` exceeds ½; inf when
    none up to ``top``."""
    from planner.calibrate.testcuts import _planned

    depths = np.arange(0.5, top + step / 2, step)
    recs = [_planned(ctx, q, ap, ae_mm, rpm, 0.1, "down", 60.0, "crit", "critical depth")
            for ap in depths]
    p = np.asarray(said(recs), float)
    above = np.flatnonzero(p > 0.5)
    if not len(above):
        return float("inf")
    i = int(above[0])
    if i == 0:
        return float(depths[0])
    t = (0.5 - p[i - 1]) / (p[i] - p[i - 1])
    return float(depths[i - 1] + t * step)


def _critical(ctx: CalibrationContext, poses, log, cal_params, rpm: float) -> dict:
    """The critical-depth study at the job's spindle speed ``rpm`` [rev/min]."""
    c, b = {**CRITICAL, "rpm": float(rpm)}, BOUNDARY
    truth = TruthCell(ctx, **TRUTH)
    qs = poses[:c["poses"]]
    true_ap = [_truth_critical_ap(truth, ctx, q, c["rpm"], b["ae_mm"]) for q in qs]
    log(f"critical a_p at {c['rpm']:g} rpm in the truth: {np.round(true_ap, 2)} mm")

    def boundary_says(fit):
        def said(recs):
            x = np.array([[criterion_margin(ctx, r, cal_params), r.ap_mm, r.rpm] for r in recs])
            return fit.probability(x)
        return said

    def nominal_says(recs):
        return [1.0 if criterion_margin(ctx, r) <= 0.0 else 0.0 for r in recs]

    def errors(said):
        got = [_model_critical_ap(ctx, q, c["rpm"], b["ae_mm"], said, 12.0, c["grid_mm"])
               for q in qs]
        return got, [abs(g / t - 1.0) for g, t in zip(got, true_ap, strict=True)]

    rows = {}
    nominal = errors(nominal_says)
    rows["nominal model (eigen)"] = {"n": 0, "critical_ap_mm": nominal[0], "error": nominal[1]}
    for n in c["counts"]:
        n0 = max(8, n // 3)
        random_recs = run_cuts(truth, boundary_cuts(ctx, qs, n, b["rpm"], c["ap_mm"], b["ae_mm"],
                                                    seed=21), seed=21)
        start = run_cuts(truth, boundary_cuts(ctx, qs, n0, b["rpm"], c["ap_mm"], b["ae_mm"],
                                              seed=21), seed=21)
        recs = list(start)
        left, rnd = n - n0, 0
        while left > 0:
            k = (left + 1) // 2 if rnd == 0 else left
            fit = fit_boundary(ctx, recs, cal_params)
            # Proposed where the question is: at the job's spindle speed, a_p on a 0.25 mm grid.
            recs += run_cuts(truth, propose_cuts(ctx, fit, qs, k, (c["rpm"], c["rpm"]),
                                                 c["ap_mm"], b["ae_mm"], params=cal_params,
                                                 grid=29),
                             seed=30 + rnd)
            left, rnd = left - k, rnd + 1
        for name, data in ((f"{n} space-filling passes", random_recs),
                           (f"{n} passes: {n0} space-filling + {n - n0} proposed", recs)):
            try:
                got = errors(boundary_says(fit_boundary(ctx, data, cal_params)))
                rows[name] = {"n": n, "critical_ap_mm": got[0], "error": got[1]}
            except FitRefused as e:   # a refused fit is a result too (too few of one verdict)
                rows[name] = {"n": n, "refused": str(e)}
            log(f"critical a_p, {name}: {rows[name]}")
    return {"rpm": c["rpm"], "true_critical_ap_mm": true_ap, "rows": rows}


def markdown(r: dict) -> str:
    """The result as the Markdown section docs/calibration.md quotes."""
    lines = [f"{r['n_cuts']} slot test cuts (a_p {' / '.join(f'{a:g}' for a in r['ap_mm'])} mm, "
             f"{r['rpm']:g} rpm, feed per tooth "
             f"{' and '.join(f'{v:g}' for v in r['feed_per_tooth_mm'])} mm alternating) at "
             f"{len(r['poses_deg'])} poses over "
             f"the demo's stock; true cell: joint stiffness x{TRUTH['joint_scale']:g}, coefficients "
             f"{100 * (TRUTH['coefficient_factor'] - 1):+.0f} %, regeneration "
             f"on; {r['seeds']} seeds per noise level, worst seed shown.", ""]
    head = "| force noise | " + " | ".join(COEFFICIENT_NAMES) + \
        " | stiffness scale | job-cut force (nominal model) |"
    lines += [head, "|---" * (len(COEFFICIENT_NAMES) + 3) + "|"]
    for lv in r["levels"]:
        cells = [f"{100 * lv['worst_coefficient_error'][n]:.1f} % "
                 f"({100 * lv['ci_coverage'][n]:.0f} % CI cover)" for n in COEFFICIENT_NAMES]
        lines.append(f"| {lv['label']} | " + " | ".join(cells)
                     + f" | {100 * lv['worst_stiffness_error']:.1f} % | "
                     f"{100 * lv['worst_job_force_error']:.2f} % "
                     f"({100 * lv['nominal_job_force_error']:.1f} %) |")
    lines += ["", "Worst |error| over the seeds against the truth; in brackets the share of seeds "
              "whose 95 % interval covers the true value. Targets: coefficients within "
              f"{100 * COEFFICIENT_TARGET:.0f} %, stiffness scale within "
              f"{100 * STIFFNESS_TARGET:.0f} %."]
    lines += ["", "The Cramér–Rao bound (1σ, relative) of the mean-force fit at the truth's "
              "coefficients and the same noise: of this design, and of the best "
              f"{r['n_cuts']} passes among slots at a_p {', '.join(f'{a:g}' for a in BOUND_AP_MM)} mm "
              f"and half-immersion up/down milling at a_p "
              f"{' and '.join(f'{a:g}' for a in BOUND_HALF_AP_MM)} mm, at the design's two feeds "
              "(chatter not considered):", "",
              "| force noise | bound of | " + " | ".join(COEFFICIENT_NAMES) + " | passes |",
              "|---" * (len(COEFFICIENT_NAMES) + 3) + "|"]
    for lv in r["levels"]:
        b = lv["bound"]
        lines.append(f"| {lv['label']} | this design | "
                     + " | ".join(f"{100 * b['design'][n]:.1f} %" for n in COEFFICIENT_NAMES)
                     + " | the design above |")
        lines.append(f"| {lv['label']} | best design | "
                     + " | ".join(f"{100 * b['best'][n]:.1f} %" for n in COEFFICIENT_NAMES)
                     + f" | {'; '.join(b['best_passes'])} |")
    bd = r["boundary"]
    lines += ["", f"Stability boundary in the true cell: {bd['n_start']} space-filling passes, then "
              f"{bd['n_voi']} chosen by value of information; judged on {bd['n_validation']} fresh "
              f"passes ({bd['validation_chatter']} chatter):", "",
              "| predictor | accuracy | Brier score |", "|---|---|---|"]
    lines += [f"| {k} | {100 * v['accuracy']:.0f} % | {v['brier']:.3f} |"
              for k, v in bd["rows"].items()]
    g = bd.get("process_gain") or {}
    if "gain" in g:
        lines += ["", f"Process gain fitted to the {bd['n_start'] + bd['n_voi']} training passes "
                  f"(`--fit process`): x{g['gain']:.3g} (95 % CI {g['gain_ci'][0]:.3g} .. "
                  f"{g['gain_ci'][1]:.3g}), its eigen verdicts right for "
                  f"{100 * g['training_accuracy']:.0f} % of them; on the fresh passes the row "
                  "above."]
    elif "refused" in g:
        lines += ["", f"Process gain (`--fit process`): refused: {g['refused']}"]
    cr = r.get("critical")
    if cr:
        true_ap = cr["true_critical_ap_mm"]
        lines += ["", f"Critical a_p at the job's {cr['rpm']:g} rpm at three poses (a_e "
                  f"{BOUNDARY['ae_mm']:g} mm down milling, 0.1 mm per tooth); the truth's by "
                  f"bisection in the time-domain model: "
                  + ", ".join(f"{v:.2f}" for v in true_ap) + " mm. A boundary's is where its "
                  "P(chatter) crosses ½ (target: within 10 %):", "",
                  "| predictor | passes | critical a_p [mm] | error per pose | worst |",
                  "|---|---:|---|---|---:|"]
        for name, row in cr["rows"].items():
            if "refused" in row:
                lines.append(f"| {name} | {row['n']} | refused: {row['refused']} | | |")
                continue
            aps = ", ".join("none below 12" if not np.isfinite(v) else f"{v:.2f}"
                            for v in row["critical_ap_mm"])
            errs = [e for e in row["error"] if np.isfinite(e)]
            worst = f"{100 * max(errs):.0f} %" if len(errs) == len(row["error"]) else "—"
            per = ", ".join("—" if not np.isfinite(e) else f"{100 * e:.0f} %"
                            for e in row["error"])
            lines.append(f"| {name} | {row['n']} | {aps} | {per} | {worst} |")
    lines += ["", f"Run time {r['time_s']:.0f} s."]
    return "\n".join(lines) + "\n"


def _critical_rows(r: dict) -> list[tuple[str, str, str, str]]:
    cr = r.get("critical")
    if not cr:
        return []
    out = []
    for name, row in cr["rows"].items():
        if row["n"] != max(CRITICAL["counts"]) or "refused" in row:
            continue
        worst = max(row["error"])
        out.append((f"calibration: critical a_p at {cr['rpm']:g} rpm, three poses, {name}",
                    f"worst error {100 * worst:.1f} %", "within 10 %",
                    "met" if worst <= 0.10 else "NOT met"))
    return out


def summary_rows(r: dict) -> list[tuple[str, str, str, str]]:
    """(figure, this run, target, verdict) rows for benchmarks/run_all.py: the first noise level."""
    lv = r["levels"][0]
    worst = lv["worst_coefficient_error"]
    met = [n for n in COEFFICIENT_NAMES if abs(worst[n]) <= COEFFICIENT_TARGET]
    coeff = ", ".join(f"{n} {100 * abs(worst[n]):.1f} %" for n in COEFFICIENT_NAMES)
    bd = r["boundary"]["rows"]
    best = bd.get("boundary + value of information")
    return [
        (f"calibration: cutting coefficients from {r['n_cuts']} cuts, worst error ({lv['label']})",
         coeff, f"each within {100 * COEFFICIENT_TARGET:.0f} %",
         "met" if len(met) == len(COEFFICIENT_NAMES)
         else f"NOT met ({len(met)} of {len(COEFFICIENT_NAMES)}; not "
              f"{', '.join(n for n in COEFFICIENT_NAMES if n not in met)})"),
        ("calibration: joint stiffness scale, worst error", f"{100 * lv['worst_stiffness_error']:.1f} %",
         f"within {100 * STIFFNESS_TARGET:.0f} %",
         "met" if lv["worst_stiffness_error"] <= STIFFNESS_TARGET else "NOT met"),
        ("calibration: Cramér–Rao bound (1σ) of the best "
         f"{r['n_cuts']} mean-force passes ({lv['label']})",
         ", ".join(f"{n} {100 * lv['bound']['best'][n]:.1f} %" for n in ("k_te", "k_ae")),
         "well below 5 % for a worst of 8 seeds within 5 %", "measured"),
        *_critical_rows(r),
        ("calibration: stability boundary on fresh passes in the truth",
         f"accuracy {100 * best['accuracy']:.0f} % (nominal eigen "
         f"{100 * bd['nominal model, eigen verdict']['accuracy']:.0f} %)" if best else "n/a",
         "—", "measured"),
    ]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="two seeds, one noise level")
    ap.add_argument("--json", action="store_true", help="print the result as JSON")
    args = ap.parse_args(argv)
    r = run(log=lambda s: print(s, file=sys.stderr, flush=True), quick=args.quick)
    print(json.dumps(r, indent=2) if args.json else markdown(r))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
