"""The bundled demo job, end to end: what ``make demo`` (``cctmill demo``) shows after Case 1.

:func:`run_demo_job` places the demo job (``planner/data/demo/demo_job.toml``: the outside contour
of an Al 6061 bracket on the KR 210) in its cell, plans it with the optimiser and the thesis
baseline, writes the plan, its report (and, where Chromium is installed, a screenshot of it) and
the KRL program, and returns the written files and the headline numbers.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

from planner._atomic import write_text_atomic

__all__ = ["DemoResult", "demo_job_file", "run_demo_job"]


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
    from planner.plots import plot_path_kinematics
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
    ev = res.evaluation
    thesis_time = plans["thesis"].cycle_time
    res_out.headline = {
        "cycle_time_s": res.cycle_time, "thesis_cycle_time_s": thesis_time,
        "cycle_time_gain_vs_thesis": 1.0 - res.cycle_time / thesis_time,
        "deflection_max_mm": float(ev.deflection_norm.max() * 1e3),
        "deflection_normal_max_mm": float(abs(ev.deflection_normal).max() * 1e3),
        "force_max_N": float(ev.force.max()), "sections": len(res.section_rows),
    }
    res_out.lines.append(
        f"== Plan of the demo job (optimize): cycle {res.cycle_time:.1f} s vs thesis baseline "
        f"{thesis_time:.1f} s ({100 * (1 - res.cycle_time / thesis_time):.1f} % shorter); "
        f"{len(res.section_rows)} sections; worst force {ev.force.max():.0f} N, worst deflection "
        f"{ev.deflection_norm.max() * 1e3:.3f} mm")
    return res_out
