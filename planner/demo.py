"""The bundled demo job, end to end: what ``make demo`` (``cctmill demo``) shows after Case 1.

:func:`run_demo_job` places the demo job (``planner/data/demo/demo_job.toml``: the outside contour
of an Al 6061 bracket on the KR 210) in its cell, plans it with the optimiser and the thesis
baseline, writes the plan, its report (and, where Chromium is installed, a screenshot of it) and
the KRL program, runs the online supervisor on a simulated cut against a simulated controller
over loopback (:func:`supervise_demo`), and returns the written files and the headline numbers.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

from planner._atomic import write_text_atomic

__all__ = ["DemoResult", "demo_job_file", "run_demo_job", "supervise_demo"]


def demo_job_file() -> Path:
    """The bundled demo job file."""
    return Path(str(resources.files("planner").joinpath("data/demo/demo_job.toml")))


@dataclass
class DemoResult:
    """What the demo wrote and found.

    Attributes:
        written: every file written, in order.
        headline: the numbers the demo ends with (units in names).
        notes: lines for the user (e.g. a skipped screenshot and why).
        lines: the progress report, line by line.
    """

    written: list[Path] = field(default_factory=list)
    headline: dict[str, Any] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    lines: list[str] = field(default_factory=list)


def run_demo_job(out: Path) -> DemoResult:
    """Inspect, plan (optimize and thesis), report and export the demo job into ``out``."""
    from planner.export import export_plan
    from planner.job import load_job
    from planner.plan import plan_prepared, write_plan_outputs
    from planner.report.plots import plot_path_kinematics
    from planner.prepare import inspect_job, prepare
    from planner.report import ReportRenderError, render_screenshot

    res_out = DemoResult()
    job = load_job(demo_job_file())
    prep = prepare(job)
    prep.kinematics.raise_if_unreachable()
    summary = inspect_job(prep)
    path = out / "demo_job_inspect.json"
    write_text_atomic(path, json.dumps(summary, indent=2) + "\n")
    res_out.written.append(path)
    e, k = prep.engagement, prep.kinematics
    png = out / "demo_path_kinematics.png"
    plot_path_kinematics(prep.path.s, k.q, prep.robot.data.lower, prep.robot.data.upper,
                         k.joint_names, k.reachable, e.a_e, e.a_p, e.mode, png,
                         title=f"Demo job {job.job.name}: joints and engagement along the path")
    res_out.written.append(png)
    res_out.lines.append(
        f"== Demo job {job.job.name}: {summary['samples']} samples over "
        f"{summary['path_length_m']:.3f} m, all reachable; engagement "
        + ", ".join(f"{m} {n}" for m, n in summary["engagement"]["modes"].items()))
    plans = {m: plan_prepared(prep, m) for m in ("thesis", "optimize")}
    res = plans["optimize"]
    plan_files = write_plan_outputs(res, out)
    res_out.written += [p for p in plan_files.values() if isinstance(p, Path)]
    try:
        res_out.written.append(render_screenshot(plan_files["report"], out / "report.png"))
    except ReportRenderError as err:
        res_out.notes.append(f"report screenshot skipped: {err}")
    res_out.written += export_plan(plan_files["plan"], out / "krl", controller="krc4")
    sup = supervise_demo(plan_files["plan"], out)
    res_out.written += [out / SUPERVISE_LOG, out / SUPERVISE_PLOT]
    episodes = sup["summary"]["episodes"]
    ev = res.evaluation
    thesis_time = plans["thesis"].cycle_time
    res_out.headline = {
        "cycle_time_s": res.cycle_time, "thesis_cycle_time_s": thesis_time,
        "cycle_time_gain_vs_thesis": 1.0 - res.cycle_time / thesis_time,
        "deflection_max_mm": float(ev.deflection_norm.max() * 1e3),
        "deflection_normal_max_mm": float(abs(ev.deflection_normal).max() * 1e3),
        "force_max_N": float(ev.force.max()), "sections": len(res.section_rows),
        "chatter_episodes_caught": len(episodes),
        "chatter_detection_delay_ms": [e.get("detection_delay_ms") for e in episodes],
        "chatter_settling_ms": [e.get("settling_ms") for e in episodes],
    }
    res_out.lines.append(
        f"== Plan of the demo job (optimize): cycle {res.cycle_time:.1f} s vs thesis baseline "
        f"{thesis_time:.1f} s ({100 * (1 - res.cycle_time / thesis_time):.1f} % shorter); "
        f"{len(res.section_rows)} sections; worst force {ev.force.max():.0f} N, worst deflection "
        f"{ev.deflection_norm.max() * 1e3:.3f} mm")
    res_out.lines.append(
        f"== Supervised run (simulated KukaVarProxy controller over loopback, simulated cut from "
        f"s = {sup['start_mm']:.0f} mm, in section {sup['section']} as the model error starts): "
        f"{sup['scenario']}; "
        f"{len(episodes)} chatter episode(s) caught"
        + "".join(f"; section {e['section']}: override {e['override_start']:.0f} -> "
                  f"{e['override_min']:.0f} %, " + _episode_timing(e) for e in episodes))
    return res_out


def _episode_timing(e: dict[str, Any]) -> str:
    delay, settle = e.get("detection_delay_ms"), e.get("settling_ms")
    seen = ("alarm before the simulated chatter reached the visible amplitude (a transient, "
            "not chatter)" if delay is None
            else f"detected {delay:.0f} ms after the chatter became visible")
    gone = "" if settle is None else f", gone {settle:.0f} ms after the alarm"
    return seen + gone


#: Files of the supervised run, in the demo's output folder.
SUPERVISE_LOG = "supervise_events.jsonl"
SUPERVISE_PLOT = "supervise.png"
#: The demo's model error: from this time on [s] the simulated arm is less stable than the plan
#: says, so that its planned feed chatters and this fraction of it does not.
DEMO_ONSET_S = 1.5
DEMO_STABLE_FRACTION = 0.7
DEMO_DURATION_S = 5.0


#: The simulated cut reaches the chosen section this long before the model error's onset [s].
DEMO_LEAD_S = 0.3


def _demo_section(sections: list[dict[str, Any]]) -> tuple[dict[str, Any], float]:
    """The longest-running cut section (at least 5 mm/s, margin falling with feed there) and the
    margin offset that puts its stability boundary at :data:`DEMO_STABLE_FRACTION` of its feed."""
    import numpy as np

    best: tuple[float, dict[str, Any], float] | None = None
    for sec in sections:
        ch = sec.get("characteristic")
        if sec["kind"] != "cut" or not ch or sec["feed_mm_s"] < 5.0:
            continue
        f = np.asarray(ch["feeds_mm_s"])
        m = np.asarray(ch["margin_N_per_m"])
        at = float(np.interp(sec["feed_mm_s"], f, m))
        below = float(np.interp(DEMO_STABLE_FRACTION * sec["feed_mm_s"], f, m))
        if below > at and (best is None or sec["time_s"] > best[0]):
            best = (float(sec["time_s"]), sec, below)
    if best is None:
        raise RuntimeError("the demo plan has no cut section to simulate chatter on")
    return best[1], best[2]


def _start_before(sections: list[dict[str, Any]], sec: dict[str, Any], lead_s: float) -> float:
    """Arc length [m] from which the planned motion reaches ``sec`` after ``lead_s`` (walking back
    through the cut sections before it, at their planned speed)."""
    s, left = float(sec["s_start_m"]), lead_s
    for prev in reversed(sections[: sec["index"]]):
        if prev["kind"] != "cut" or prev["s_end_m"] < s - 1e-9 or left <= 0:
            break
        t = float(prev["time_s"])
        if t >= left:
            return s - left / t * (s - float(prev["s_start_m"]))
        left -= t
        s = float(prev["s_start_m"])
    return s


def supervise_demo(plan_path: Path, out: Path) -> dict[str, Any]:
    """Run ``cctmill supervise`` on the demo plan against a simulated controller and cut.

    The simulated cut is told (model error) that from :data:`DEMO_ONSET_S` on the arm is less
    stable than the plan by the margin the plan gives at 70 % of the section's feed: the planned
    feed then chatters — as the Floquet criterion says this 10 mm deep cut at 4000 rpm does while
    the averaged thesis model calls it stable — and the supervisor has to find a feed that does
    not. Writes the event log and the band/limit/override plot.
    """
    from planner.cli import build_parser
    from planner.cli.supervise import supervise
    from planner.plan_file import load_plan

    plan = load_plan(plan_path)
    sec, offset = _demo_section(plan.sections)
    start_mm = _start_before(plan.sections, sec, DEMO_ONSET_S - DEMO_LEAD_S) * 1e3
    args = build_parser().parse_args([
        "supervise", "--plan", str(plan_path), "--signal", "sim", "--robot", "sim",
        "--log", str(out / SUPERVISE_LOG), "--plot", str(out / SUPERVISE_PLOT),
        f"--start-mm={start_mm:.3f}", f"--chatter-onset-s={DEMO_ONSET_S}", "--boundary-shift=1",
        f"--margin-offset-n-per-m={offset:.1f}", f"--duration-s={DEMO_DURATION_S}"])
    log = out / SUPERVISE_LOG
    if log.exists():
        log.unlink()  # the event log appends: a fresh demo starts a fresh log
    summary = supervise(args)
    return {"summary": summary, "section": sec["index"], "start_mm": start_mm,
            "scenario": f"from t = {DEMO_ONSET_S:g} s the arm is {offset:.3g} N/m less stable "
                        f"than the model (which puts the boundary at {DEMO_STABLE_FRACTION:.0%} of "
                        f"the planned feed in section {sec['index']}; the sections after it "
                        "have margins of their own)"}
