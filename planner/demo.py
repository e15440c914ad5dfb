"""The bundled example, end to end: what ``make demo`` (``cctmill demo``) shows.

:func:`run_demo` runs :func:`run_case1` (the physics core on the thesis's Case 1) and then
:func:`run_demo_job`, which places the demo job (``planner/data/demo/demo_job.toml``: the outside contour
of an Al 6061 bracket on the KR 210) in its cell, plans it with the optimiser and the thesis
baseline, writes the plan, its report (and, where Chromium is installed, a screenshot of it) and
the KRL program, runs the online supervisor on a simulated cut against a simulated controller
over loopback (:func:`supervise_demo`), and returns the written files and the headline numbers.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field, replace
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from models.errors import CctmillError
from planner._atomic import OutputError, write_text_atomic
from planner.plan_file import Plan, PlanSection
from planner.point_setup import CASE1

__all__ = ["CASE1_FEED_MM_S", "CASE1_FEED_RANGE_MM_S", "CASE1_FORCE_LIMIT_N", "DemoError",
           "DemoResult", "demo_job_file", "run_case1", "run_demo", "run_demo_job", "supervise_demo"]

#: Case 1's feed [mm/s], its characteristic's feed range (start, stop, count) [mm/s] and force
#: limit [N] (the thesis's).
CASE1_FEED_MM_S = 1.0
CASE1_FEED_RANGE_MM_S = (0.5, 8.0, 31)
CASE1_FORCE_LIMIT_N = 300.0


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


class DemoError(CctmillError):
    """The bundled demo job no longer shows what the demo is for (the message says what)."""


def run_case1(out: Path) -> DemoResult:
    """The physics core on the thesis's Case 1 for both process and both mass models: analysis
    JSON and stability characteristic plot of each, into ``out``."""
    from models.analysis import MASS_MODELS, PROCESS_MODELS
    from planner.report.plots import plot_characteristic
    from planner.report.tables import analysis_json, analysis_table

    res = DemoResult()
    for process in PROCESS_MODELS:
        for mass in MASS_MODELS:
            model, q, cut = replace(CASE1, mass_model=mass, process_model=process).build()
            a = model.analyze(q, cut, CASE1_FEED_MM_S * 1e-3)
            stem = f"case1_{process}_{mass}"
            path = out / f"{stem}_analysis.json"
            write_text_atomic(path, json.dumps(analysis_json(a, True), indent=2) + "\n")
            res.written.append(path)
            feeds = np.linspace(*CASE1_FEED_RANGE_MM_S) * 1e-3
            ch = model.characteristic(q, cut, feeds, CASE1_FORCE_LIMIT_N)
            png = out / f"{stem}_stability.png"
            plot_characteristic(ch, png, title="Thesis Case 1")
            res.written.append(png)
            res.lines.append(f"== Thesis Case 1: {process} process model, {mass} mass ==\n"
                             + analysis_table(a, True)
                             + f"\nfeed limit {ch.feed_limit * 1e3:.2f} mm/s, bound by {ch.binding}")
    return res


def run_demo(out: str | Path) -> DemoResult:
    """Everything ``make demo`` shows: Case 1 (:func:`run_case1`), then the demo job
    (:func:`run_demo_job`); ``headline`` is the demo job's."""
    out = Path(out)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise OutputError(out, e.strerror or str(e)) from e
    res = run_case1(out)
    job = run_demo_job(out)
    res.written += job.written
    res.lines += job.lines
    res.notes += job.notes
    res.headline = job.headline
    return res


def run_demo_job(out: Path) -> DemoResult:
    """Inspect, plan (optimize and thesis), report and export the demo job into ``out``, then
    supervise a simulated cut of it (:func:`supervise_demo`)."""
    from planner.job import load_job
    from planner.outputs import KrlOptions, write_plan_outputs
    from planner.plan import plan_prepared
    from planner.prepare import inspect_job, prepare
    from planner.report.browser import ReportRenderError, render_screenshot
    from planner.report.plots import plot_path_kinematics
    from planner.supervisor.metrics import episode_outcome_text, episode_timing_text

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
    outputs = write_plan_outputs(res, out)
    files = outputs.files
    res_out.written += [p for p in files.values() if isinstance(p, Path)]
    try:
        res_out.written.append(render_screenshot(files["report"], out / "report.png"))
    except ReportRenderError as err:
        res_out.notes.append(f"report screenshot skipped: {err}")
    from planner.export import export_plan

    res_out.written += export_plan(outputs.plan, out / "krl", **KrlOptions(controller="krc4").kwargs())
    sup = supervise_demo(outputs.plan, out)
    res_out.written += [out / SUPERVISE_LOG, out / SUPERVISE_PLOT]
    episodes = sup["summary"].episodes
    ev = res.evaluation
    thesis_time = plans["thesis"].cycle_time
    res_out.headline = {
        "cycle_time_s": res.cycle_time, "thesis_cycle_time_s": thesis_time,
        "cycle_time_gain_vs_thesis": 1.0 - res.cycle_time / thesis_time,
        "deflection_max_mm": float(ev.deflection_norm.max() * 1e3),
        "deflection_normal_max_mm": float(abs(ev.deflection_normal).max() * 1e3),
        "force_max_N": float(ev.force.max()), "sections": len(res.plan_sections),
        "chatter_episodes_caught": len(episodes),
        "chatter_episodes_escalated": sum(e.get("outcome") == "escalated" for e in episodes),
        "operator_alarms": len(sup["summary"].alarms),
        "chatter_detection_delay_ms": [e.get("detection_delay_ms") for e in episodes],
        "chatter_settling_ms": [e.get("settling_ms") for e in episodes],
    }
    res_out.lines.append(
        f"== Plan of the demo job (optimize): cycle {res.cycle_time:.1f} s vs thesis baseline "
        f"{thesis_time:.1f} s ({100 * (1 - res.cycle_time / thesis_time):.1f} % shorter); "
        f"{len(res.plan_sections)} sections; worst force {ev.force.max():.0f} N, worst deflection "
        f"{ev.deflection_norm.max() * 1e3:.3f} mm")
    res_out.lines.append(
        f"== Supervised run (simulated KukaVarProxy controller over loopback, simulated cut from "
        f"s = {sup['start_mm']:.0f} mm, in section {sup['section']} as the model error starts): "
        f"{sup['scenario']}; "
        f"{len(episodes)} chatter episode(s) caught"
        + "".join(f"; section {e['section']}: override {e['override_start']:.0f} -> "
                  f"{e['override_min']:.0f} % (direction {e['direction']:+d}), "
                  f"{episode_timing_text(e)}; {episode_outcome_text(e)}" for e in episodes)
        + f"; {len(sup['summary'].alarms)} operator alarm(s)")
    return res_out


#: Files of the supervised run, in the demo's output folder.
SUPERVISE_LOG = "supervise_events.jsonl"
SUPERVISE_PLOT = "supervise.png"
#: The demo's model error: from this time on [s] the simulated arm is less stable than the plan
#: says, so that its planned feed chatters and this fraction of it does not.
DEMO_ONSET_S = 1.5
DEMO_STABLE_FRACTION = 0.7
#: Long enough for every episode of the demo's scenario to end by the policy itself (resolved, or
#: escalated at the floor about 1 s after a reversal), not by the end of the run [s].
DEMO_DURATION_S = 6.5
#: The demo's chatter section runs at least this fast [m/s].
DEMO_FEED_MIN = 5e-3


#: The simulated cut reaches the chosen section this long before the model error's onset [s].
DEMO_LEAD_S = 0.3


def _demo_section(plan: Plan) -> tuple[PlanSection, float]:
    """The longest-running cut section (at least 5 mm/s, margin falling with feed there) and the
    margin offset that puts its stability boundary at :data:`DEMO_STABLE_FRACTION` of its feed."""
    best: tuple[float, PlanSection, float] | None = None
    for sec in plan.sections:
        ch = sec.characteristic
        if sec.kind != "cut" or ch is None or sec.feed < DEMO_FEED_MIN:
            continue
        at = float(np.interp(sec.feed, ch.feeds, ch.margin))
        below = float(np.interp(DEMO_STABLE_FRACTION * sec.feed, ch.feeds, ch.margin))
        if below > at and (best is None or (sec.time or 0.0) > best[0]):
            best = (sec.time or 0.0, sec, below)
    if best is None:
        raise DemoError("the demo plan has no cut section to simulate chatter on (none of at "
                        f"least {DEMO_FEED_MIN * 1e3:g} mm/s whose margin falls with feed)")
    return best[1], best[2]


def _start_before(plan: Plan, sec: PlanSection, lead_s: float) -> float:
    """Arc length [m] from which the planned motion reaches ``sec`` after ``lead_s`` (walking back
    through the cut sections before it, at their planned speed)."""
    s, left = sec.s_start, lead_s
    for prev in reversed(plan.sections[: sec.index]):
        if prev.kind != "cut" or prev.s_end < s - 1e-9 or left <= 0:
            break
        t = float(prev.time or 0.0)
        if t >= left:
            return s - left / t * (s - prev.s_start)
        left -= t
        s = prev.s_start
    return s


def supervise_demo(plan: Plan, out: Path) -> dict[str, Any]:
    """Supervise the demo plan against a simulated controller and cut (what ``cctmill supervise
    --signal sim --robot sim`` does).

    The simulated cut is told (model error) that from :data:`DEMO_ONSET_S` on the arm is less
    stable than the plan by the margin the plan gives at 70 % of the section's feed: the planned
    feed then chatters — as the Floquet criterion says this 10 mm deep cut at 4000 rpm does while
    the averaged thesis model calls it stable — and the supervisor has to find a feed that does
    not. Writes the event log and the band/limit/override plot.
    """
    from planner.supervisor.session import SessionConfig, supervise
    from planner.supervisor.sim_cut import CutScenario

    sec, offset = _demo_section(plan)
    start = _start_before(plan, sec, DEMO_ONSET_S - DEMO_LEAD_S)
    log = out / SUPERVISE_LOG
    if log.exists():
        log.unlink()  # the event log appends: a fresh demo starts a fresh log
    config = SessionConfig(start=start, duration=DEMO_DURATION_S, log=str(log),
                           plot=str(out / SUPERVISE_PLOT))
    scenario = CutScenario(onset_s=DEMO_ONSET_S, boundary_shift=1.0, margin_offset_N_per_m=offset)
    summary = supervise(plan, "sim", "sim", config, scenario)
    return {"summary": summary, "section": sec.number, "start_mm": start * 1e3,
            "scenario": f"from t = {DEMO_ONSET_S:g} s the arm is {offset:.3g} N/m less stable "
                        f"than the model (which puts the boundary at {DEMO_STABLE_FRACTION:.0%} of "
                        f"the planned feed in section {sec.number}; the sections after it "
                        "have margins of their own)"}
