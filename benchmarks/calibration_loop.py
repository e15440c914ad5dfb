"""The calibration loop on a simulated truth: plan with the nominal model, cut test passes in the
true cell, calibrate, replan, and simulate the plans' sections in the truth (docs/calibration.md,
"The loop"; issue 19, must-show 3).

The cell and the truth are those of ``benchmarks/calibration.py`` (the demo job; the true cell:
joint stiffness ×0.7, coefficients +15 %, regeneration on). The loop:

1. plan the demo job with the nominal model (its criterion: eigen, the thesis's process model);
2. simulate every cut section of that plan in the truth (the section's middle sample: pose, cut
   frame, a_e, a_p, planned feed; :func:`planner.calibrate.testcuts.section_templates`);
3. test passes in the truth: 12 identification slots (coefficients, stiffness), then 8 passes
   imitating the job's own sections at a_p 2-12 mm and 12 more proposed by value of information
   among them (:func:`~planner.calibrate.testcuts.propose_along_job`);
4. ``calibrate`` them (coefficients, stiffness, boundary) into an overlay, exactly as the CLI does,
   and replan the job with it and ``[model] chatter_probability_max = 0.1``;
5. the same job planned with the truth's parameters (stiffness ×0.7, coefficients +15 %) under the
   nominal criterion, its sections simulated in the truth;
6. whether a slower feed would have helped: the chattering sections rerun in the truth at the
   job's ``feed_min_mm_s``.

Run from the repository root: ``python benchmarks/calibration_loop.py [--json]``.
"""

from __future__ import annotations

import argparse
import json
import math
import shutil
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from models.errors import CctmillError  # noqa: E402
from planner.calibrate.context import CalibrationContext  # noqa: E402
from planner.calibrate.fit_boundary import fit_boundary  # noqa: E402
from planner.calibrate.fit_coefficients import fit_coefficients  # noqa: E402
from planner.calibrate.fit_stiffness import fit_stiffness  # noqa: E402
from planner.calibrate.records import write_records  # noqa: E402
from planner.calibrate.run import calibrate, write_calibration  # noqa: E402
from planner.calibrate.suggest import chatter_probabilities, rank_settings  # noqa: E402
from planner.calibrate.testcuts import (  # noqa: E402
    along_job_cuts,
    identification_cuts,
    imitate_section,
    job_test_poses,
    propose_along_job,
    section_templates,
)
from planner.calibrate.truth import TruthCell, run_cuts  # noqa: E402
from planner.job import load_job  # noqa: E402
from planner.plan import plan_job, plan_of_result  # noqa: E402

JOB = ROOT / "planner" / "data" / "demo" / "demo_job.toml"
TRUTH = {"joint_scale": 0.7, "coefficient_factor": 1.15, "process_gain": 1.3}
P_MAX = 0.1
#: Boundary passes along the job: a space-filling start, then value of information in rounds.
START, ROUNDS, AP_MM = 8, (6, 6), (2.0, 12.0)
#: The contour's total depth [mm] (the demo: two levels of 10 mm), passes confirming a suggestion.
DEPTH_MM, CONFIRM = 20.0, 6
#: Rounds of passes aimed at the depth/speed decision, passes per round, most levels considered.
DECISION_ROUNDS, DECISION_PASSES, MAX_LEVELS = 3, 6, 4


def _job_copy(folder: Path, extra_model: str = "", overlay: str | None = None,
              name: str = "", program: str | None = None, rpm: float | None = None) -> Path:
    """The demo job (and its toolpath) in ``folder``, with ``extra_model`` lines in [model], an
    overlay named, another toolpath ``program`` and spindle speed ``rpm``."""
    text = JOB.read_text(encoding="utf-8")
    for f in JOB.parent.iterdir():
        if f.suffix != ".toml" and not (folder / f.name).exists():
            shutil.copy(f, folder / f.name)
    text = text.replace('chatter_criterion = "eigen"', 'chatter_criterion = "eigen"' + extra_model)
    if program:
        text = text.replace('toolpath = ["bracket_contour.nc"]', f'toolpath = ["{program}"]')
    if rpm:
        text = text.replace("rpm = 4000.0", f"rpm = {rpm:.1f}")
    if overlay:
        text += f'\n[calibration]\noverlay = "{overlay}"\n'
    path = folder / (f"job{name}.toml" if not overlay else f"job_{Path(overlay).stem}{name}.toml")
    path.write_text(text, encoding="utf-8")
    return path


def levels_program(levels: int, rpm: float) -> str:
    """The demo's bracket contour in ``levels`` equal depth levels to Z-20 at ``rpm``: the demo's
    own program (two levels of 10 mm, S4000) with its level block repeated, blocks renumbered."""
    lines = (JOB.parent / "bracket_contour.nc").read_text(encoding="utf-8").splitlines()
    first = next(i for i, ln in enumerate(lines) if "Z-10.0 F300." in ln)
    second = next(i for i, ln in enumerate(lines) if "Z-20.0 F300." in ln)
    head, block, tail = lines[:first], lines[first:second], lines[second + (second - first):]
    body = []
    for k in range(1, levels + 1):
        z = -20.0 * k / levels
        body += [block[0].replace("Z-10.0", f"Z{z:.3f}")] + block[1:]
    out, n = [], 0
    for ln in head + body + tail:
        if ln.startswith("N"):
            n += 5
            ln = f"N{n}" + ln[ln.index(" "):]
        out.append(ln.replace("S4000", f"S{rpm:.0f}"))
    return "\n".join(out) + "\n"


def _in_truth(truth: TruthCell, plan, tool: str, seed: int) -> dict:
    """Every cut section of a plan simulated in the truth at its planned feed."""
    templates = section_templates(plan, tool)
    recs = run_cuts(truth, templates, seed=seed)
    chatter = [r for r in recs if r.verdict == "chatter"]
    return {"sections": len(recs), "chatter": len(chatter),
            "chatter_sections": [r.source.get("section") for r in chatter], "records": recs,
            "templates": templates}


def run(log=None) -> dict:
    log = log or (lambda s: None)
    t0 = time.perf_counter()
    tmp = Path(tempfile.mkdtemp(prefix="cctmill-loop-"))
    try:
        return _run(tmp, log, t0)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def _plan_row(job_file: Path, truth: TruthCell, tool: str, seed: int, log, label: str,
              true_job: Path | None = None) -> dict:
    job = load_job(job_file)
    try:
        res = plan_job(job)
    except CctmillError as e:
        why = str(e).replace(f"{job_file.parent}/", "")   # the temporary folder says nothing
        log(f"{label}: refused: {why}")
        return {"label": label, "refused": why}
    sim = _in_truth(truth, plan_of_result(res), tool, seed)
    row = {"label": label, "cycle_time_s": float(res.timing.cycle_time), **sim}
    if true_job is not None:
        row["true_limits"] = _true_limits(res, true_job)
    log(f"{label}: cycle {res.timing.cycle_time:.1f} s, {sim['chatter']}/{sim['sections']} "
        f"sections chatter in the truth; under the truth's parameters {row.get('true_limits')}")
    return row


def _true_limits(res, true_job: Path) -> dict:
    """The plan's feeds checked against the job's limits under the truth's parameters (force,
    deflection, ...): per constraint, the samples over the limit and the worst value / limit."""
    from planner.check import check_plan
    from planner.prepare import prepare

    prep = prepare(load_job(true_job))
    rep = check_plan(prep, res.feed, res.kinds, res.timing.speed,
                     [(s.start, s.stop, s.kind, s.feed) for s in res.sections], res.limits)
    over: dict[str, int] = {}
    for v in rep.violations:
        over[v.constraint] = over.get(v.constraint, 0) + 1
    return {"violations": over, "worst_ratio": {k: round(float(v), 3)
                                                for k, v in rep.worst_ratio.items()}}


def _calibrate(tmp: Path, job_file: Path, ident, boundary, log, tag: str):
    files = [write_records(tmp / "identification.jsonl", ident),
             write_records(tmp / f"boundary{tag}.jsonl", boundary)]
    cal = calibrate(files, job_file, fits=("coefficients", "stiffness", "process", "boundary"))
    log(cal.summary())
    write_calibration(cal, tmp / f"cell{tag}.overlay.toml")
    return cal, f"cell{tag}.overlay.toml"


def _run(tmp: Path, log, t0: float) -> dict:
    job_file = _job_copy(tmp)
    job = load_job(job_file)
    ctx = CalibrationContext.from_job(job)
    tool = job.tool.name
    truth = TruthCell(ctx, **TRUTH)
    (tmp / "truth.overlay.toml").write_text(
        f"[cell]\njoint_stiffness_scale = {TRUTH['joint_scale']}\n\n[calibration]\n"
        + "".join(f"{n} = {v!r}\n" for n, v in zip(
            ("k_tc", "k_rc", "k_ac", "k_te", "k_re", "k_ae"), truth.coefficients().tolist(),
            strict=True)), encoding="utf-8")
    true_job = _job_copy(tmp, "", "truth.overlay.toml")
    rows = []
    nominal = _plan_row(job_file, truth, tool, 1, log, "nominal model (eigen, thesis K_p)",
                        true_job)
    rows.append(nominal)
    # The test passes, in the truth: identification slots, then passes along the job's own
    # sections over a_p and the tool's speed range.
    poses = job_test_poses(job)
    ident = run_cuts(truth, identification_cuts(ctx, poses, 12, rpm=12_000.0, ae_mm=(25.4,),
                                                ap_mm=(2.0, 3.0), milling="slot", feeds="ends",
                                                fz_min_mm=0.025), seed=2)
    co, st = fit_coefficients(ident, ctx.tool, ctx.material), fit_stiffness(ctx, ident)
    params = ctx.params(st.scale, co.values)
    templates = nominal["templates"]   # the nominal plan's sections, the passes' models
    top = ctx.tool.spindle_speed_max * 60.0 / (2.0 * math.pi)
    speeds = (job.spindle.rpm, top)
    boundary = run_cuts(truth, along_job_cuts(templates, START, AP_MM, seed=5, rpm=speeds), seed=3)
    for k, n in enumerate(ROUNDS):
        fit = fit_boundary(ctx, boundary, params)
        boundary += run_cuts(truth, propose_along_job(ctx, fit, templates, n, AP_MM,
                                                      params=params, every=4, rpm=speeds),
                             seed=10 + k)
    log(f"test passes: {len(ident)} identification, {len(boundary)} along the job "
        f"({sum(r.verdict == 'chatter' for r in boundary)} chatter: "
        + ", ".join(f"{r.ap_mm:g} mm {r.rpm:g} rpm {r.verdict[0]}" for r in boundary) + ")")
    cal, overlay = _calibrate(tmp, job_file, ident, boundary, log, "")
    rows.append(_plan_row(_job_copy(tmp, "", overlay), truth, tool, 7, log,
                          "calibrated coefficients and stiffness, no chatter requirement",
                          true_job))
    rows.append(_plan_row(_job_copy(tmp, f"\nchatter_probability_max = {P_MAX:g}", overlay,
                                    "_pmax"), truth, tool, 4, log,
                          f"calibrated (overlay from {len(ident) + len(boundary)} passes, "
                          f"P(chatter) <= {P_MAX:g})"))
    rows.append(_plan_row(true_job, truth, tool, 5, log,
                          "true parameters (stiffness x0.7, coefficients +15 %), eigen", true_job))
    # Would a slower feed have helped? The nominal plan's chattering sections at feed_min.
    chattering = [r for r in nominal.get("records", ()) if r.verdict == "chatter"]
    slow = run_cuts(truth, [replace(r, feed_mm_s=job.limits.feed_min_mm_s, verdict="unknown",
                                    force_n=None, deflection_mm=None, chatter_hz=None,
                                    duration_s=None) for r in chattering[::3]], seed=6)
    slow_row = {"rerun": len(slow), "still_chatter": sum(r.verdict == "chatter" for r in slow),
                "feed_mm_s": job.limits.feed_min_mm_s}
    log(f"at feed_min {slow_row['feed_mm_s']:g} mm/s: {slow_row['still_chatter']}/"
        f"{slow_row['rerun']} of the nominal plan's chattering sections still chatter")
    out = {"p_max": P_MAX, "n_identification": len(ident), "n_boundary": len(boundary),
           "boundary_chatter": sum(r.verdict == "chatter" for r in boundary),
           "stiffness_scale": st.scale, "rows": rows, "slow_feed": slow_row}
    out["replan"] = _way_out(tmp, ident, boundary, cal, overlay, templates, speeds, truth, tool,
                             log)
    for r in rows + out["replan"].get("rows", []):
        r.pop("records", None)
        r.pop("templates", None)
    out["time_s"] = time.perf_counter() - t0
    return out


def _way_out(tmp: Path, ident, boundary, cal, overlay: str, templates, speeds, truth, tool,
             log) -> dict:
    """The depth split and spindle speed the calibrated boundary accepts for every section
    (:func:`planner.calibrate.suggest.suggest_levels_and_speed`); confirming passes there, a
    recalibration, and the new job planned three ways and simulated in the truth."""
    cal_ctx = CalibrationContext.from_job(load_job(_job_copy(tmp, "", overlay, "_probe")))
    fit, decision, pick = cal.boundary, [], None
    for rnd in range(DECISION_ROUNDS + 1):
        ranked = rank_settings(cal_ctx, fit, templates, DEPTH_MM, speeds, max_levels=MAX_LEVELS)
        pick = next((c for c in ranked if c.p_worst <= P_MAX), None)
        if pick is not None or rnd == DECISION_ROUNDS:
            break
        # Passes where the decision is: the setting closest to acceptable, at the sections the
        # boundary is least sure of there (value of information for the decision, Karandikar).
        best = min(ranked, key=lambda c: (c.p_worst, c.levels, c.rpm))
        p = chatter_probabilities(cal_ctx, fit, templates, best.ap_mm, [best.rpm])[0]
        worst = np.argsort(-p)[:DECISION_PASSES]
        runs = run_cuts(truth, [imitate_section(templates[i], best.ap_mm, 60.0,
                                                f"D{rnd + 1}{k + 1}", "decision", best.rpm)
                                for k, i in enumerate(worst)], seed=30 + rnd)
        log(f"decision round {rnd + 1}: best setting {best.line()}; passes there: "
            + "".join(r.verdict[0] for r in runs))
        decision += runs
        fit = fit_boundary(cal_ctx, boundary + decision)
    if pick is None:
        log("the calibrated boundary accepts no depth split and speed for this contour")
        return {"suggestion": None, "decision_passes": len(decision)}
    log(f"the calibrated boundary suggests {pick.line()}")
    program = f"bracket_contour_{pick.levels}x.nc"
    (tmp / program).write_text(levels_program(pick.levels, pick.rpm), encoding="utf-8")
    new_job = _job_copy(tmp, "", None, f"_{pick.levels}x", program, pick.rpm)
    truth_overlay = "truth.overlay.toml"
    true_new = _job_copy(tmp, "", truth_overlay, f"_{pick.levels}x", program, pick.rpm)
    nominal_new = _plan_row(new_job, truth, tool, 8, log, f"{pick.levels} levels at {pick.rpm:g} "
                            "rpm: nominal model", true_new)
    if "refused" in nominal_new:
        return {"suggestion": pick.as_json(), "decision_passes": len(decision),
                "rows": [nominal_new]}
    new_templates = nominal_new["templates"]
    fit = cal.boundary
    near = (max(AP_MM[0], 0.6 * pick.ap_mm), min(AP_MM[1], 1.4 * pick.ap_mm))
    confirm = run_cuts(truth, propose_along_job(cal_ctx, fit, new_templates, CONFIRM, near,
                                                every=4), seed=20)
    log(f"confirming passes at {pick.rpm:g} rpm: "
        + ", ".join(f"{r.ap_mm:g} mm {r.verdict[0]}" for r in confirm))
    cal2, overlay2 = _calibrate(tmp, new_job, ident, boundary + decision + confirm, log, "_2")
    rows = [
        nominal_new,
        _plan_row(_job_copy(tmp, f"\nchatter_probability_max = {P_MAX:g}", overlay2,
                            f"_{pick.levels}x_pmax", program, pick.rpm), truth, tool, 9, log,
                  f"{pick.levels} levels at {pick.rpm:g} rpm: calibrated, P(chatter) <= "
                  f"{P_MAX:g}", true_new),
        _plan_row(true_new, truth, tool, 10, log, f"{pick.levels} levels at {pick.rpm:g} rpm: "
                  "true parameters", true_new),
    ]
    return {"suggestion": pick.as_json(), "decision_passes": len(decision),
            "decision_chatter": sum(r.verdict == "chatter" for r in decision),
            "confirming_passes": len(confirm),
            "confirming_chatter": sum(r.verdict == "chatter" for r in confirm), "rows": rows}


def _table(rows: list[dict]) -> list[str]:
    out = ["| plan | cycle time | sections chattering in the truth | its feeds under the "
           "truth's parameters (worst value / limit) |", "|---|---:|---|---|"]
    for row in rows:
        if "refused" in row:
            out.append(f"| {row['label']} | refused | — | {row['refused']} |")
            continue
        tl = row.get("true_limits")
        lim = "—" if tl is None else ", ".join(
            f"{k} {v:.2f}" for k, v in tl["worst_ratio"].items() if k in ("force", "deflection"))
        if tl and tl["violations"]:
            lim += " (samples over: " + ", ".join(f"{k} {v}" for k, v in
                                                 tl["violations"].items()) + ")"
        out.append(f"| {row['label']} | {row['cycle_time_s']:.1f} s | "
                   f"{row['chatter']} of {row['sections']} | {lim} |")
    return out


def markdown(r: dict) -> str:
    s = r["slow_feed"]
    lines = [f"The demo job as programmed (two levels of 10 mm, a_e 3 mm, 4000 rpm). Test passes: "
             f"{r['n_identification']} identification slots, {r['n_boundary']} along the job "
             f"({r['boundary_chatter']} chatter).", "", *_table(r["rows"]), "",
             f"The nominal plan's chattering sections rerun at feed_min {s['feed_mm_s']:g} mm/s: "
             f"{s['still_chatter']} of {s['rerun']} still chatter."]
    rp = r.get("replan") or {}
    pick = rp.get("suggestion")
    if pick is None:
        lines += ["", "The calibrated boundary accepts no depth split and spindle speed."]
    else:
        lines += ["", f"What the calibrated boundary accepts for every section "
                  f"(`suggest_levels_and_speed`): {pick['levels']} levels of {pick['ap_mm']:.3g} "
                  f"mm at {pick['rpm']:g} rpm (worst P(chatter) {pick['p_worst']:.2f}); "
                  f"after {rp['decision_passes']} passes aimed at the decision "
                  f"({rp['decision_chatter']} chatter); {rp['confirming_passes']} confirming "
                  "passes there "
                  f"({rp['confirming_chatter']} chatter), recalibrated, replanned:", "",
                  *_table(rp["rows"])]
    lines += ["", f"Run time {r['time_s']:.0f} s."]
    return "\n".join(lines) + "\n"


def summary_rows(r: dict) -> list[tuple[str, str, str, str]]:
    """(figure, this run, target, verdict) for benchmarks/run_all.py."""
    nominal = r["rows"][0]
    rp = r.get("replan") or {}
    if not rp.get("rows"):
        return [("calibration loop: replanned job simulated in the truth",
                 f"no depth/speed accepted; nominal {nominal.get('chatter')}/"
                 f"{nominal.get('sections')} sections chatter",
                 "no chattering section, cycle within 10 % of the true plan", "NOT met")]
    cal, true = rp["rows"][1], rp["rows"][2]
    if "refused" in cal or "refused" in true:
        return [("calibration loop: replanned job simulated in the truth", "refused", "—",
                 "NOT met")]
    ratio = cal["cycle_time_s"] / true["cycle_time_s"] - 1.0
    pick = rp["suggestion"]
    got = (f"{pick['levels']} x {pick['ap_mm']:.3g} mm at {pick['rpm']:g} rpm: "
           f"{cal['chatter']}/{cal['sections']} chatter, {cal['cycle_time_s']:.0f} s "
           f"({100 * ratio:+.1f} % of the true plan); the programmed job's nominal plan "
           f"{nominal['chatter']}/{nominal['sections']} chatter")
    met = cal["chatter"] == 0 and abs(ratio) <= 0.10
    return [("calibration loop: replanned job simulated in the truth", got,
             "no chattering section, cycle within 10 % of the true plan",
             "met" if met else "NOT met")]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--json", action="store_true", help="print the result as JSON")
    args = ap.parse_args(argv)
    r = run(log=lambda s: print(s, file=sys.stderr, flush=True))
    print(json.dumps(r, indent=2) if args.json else markdown(r))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
