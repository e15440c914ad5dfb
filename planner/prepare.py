"""From a job file to everything known along the path before planning feeds.

:func:`prepare` reads the toolpath files, places them in the cell (``$BASE``), samples them, solves
the inverse kinematics of every sample, and finds the engagement (per operation from the job, or
from the stock model). :func:`inspect_job` turns that into the ``cctmill inspect JOB.toml`` summary.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from models.cutting import MILLING_MODES, Tool
from models.robot import Robot, load_robot
from planner._progress import MIN_TOTAL, bar
from planner.engagement import (
    SLIVER_TOL,
    Engagement,
    Stock,
    fixed_engagement,
    stock_engagement,
    zmap_engagement,
)
from planner.ik import IKOptions, PathKinematics, solve_path
from planner.job import Job, JobError
from planner.path import PathSamples, sample_toolpath
from planner.tool_limits import PlanWarning, job_tool
from robot_io.options import OPTION_FORMATS, option_name, speaking
from robot_io.readers import detect_format, read_toolpath
from robot_io.toolpath import Toolpath, summarize

__all__ = ["Prepared", "inspect_job", "prepare", "read_job_toolpaths", "tool_of"]


@dataclass(frozen=True)
class Prepared:
    """A job read, sampled, solved and engaged.

    Attributes:
        job: the validated job.
        robot: the robot.
        tool: the cutter (job overrides applied).
        toolpaths: the read toolpaths.
        path: the samples.
        kinematics: joint angles along the path.
        engagement: a_e, a_p, mode and radial direction per sample (radial direction in the robot
            base).
        warnings: what preparing noticed that the plan must carry (a tool override that drops
            the tool file's limits).
        wall_times: wall time of its stages [s]: ``read_s`` (toolpaths read and sampled),
            ``ik_s`` (inverse kinematics), ``engagement_s``, and with a path posture
            ``posture_s`` (and its stages, ``posture_*``).
        posture: the posture chosen along the path (:class:`planner.posture.Posture`) when the
            job asks for ``[kinematics] posture = "path"``, else ``None``; ``kinematics`` then
            holds its joint angles.
    """

    job: Job
    robot: Robot
    tool: Tool
    toolpaths: tuple[Toolpath, ...]
    path: PathSamples
    kinematics: PathKinematics
    engagement: Engagement
    warnings: tuple[PlanWarning, ...] = ()
    wall_times: dict[str, float] = field(default_factory=dict)
    posture: Any = None


def tool_of(job: Job) -> Tool:
    """The job's cutter: the tool data file with the job's overrides."""
    return job_tool(job.tool.name, job.to_si().tool_radius, job.tool.flutes)[0]


def read_job_toolpaths(job: Job, chord_tol: float | None = None) -> tuple[Toolpath, ...]:
    """Read the job's toolpath files with its ``[job]`` reader options, each file given the
    options its format has; messages name the job's keys (``[job] strict = false``).

    Args:
        job: the job.
        chord_tol: chord tolerance [m] for curves the reader samples (APT splines).

    Raises:
        ToolpathError: a file cannot be read as written.
        JobError: a ``[job]`` reader option applies to none of the job's files (it would be
            ignored).
    """
    options = job.job.reader_options()
    if chord_tol is not None:
        options["chord_tol"] = chord_tol
    files = job.toolpath_files()
    with speaking("job"):
        formats = [job.job.format or detect_format(p) for p in files]
        for k in options:
            applies = OPTION_FORMATS.get(k, ())
            if k != "chord_tol" and not any(f in applies for f in formats):
                raise JobError(f"job {job.job.name!r}", [
                    f"{option_name(k)} applies to {' and '.join(applies)} toolpaths, and this "
                    "job has none; leave it out"])
        return tuple(
            read_toolpath(p, strict=job.job.strict, format=fmt,
                          **{k: v for k, v in options.items() if fmt in OPTION_FORMATS.get(k, ())})
            for p, fmt in zip(files, formats, strict=True))


def prepare(job: Job, progress: bool = False, posture: str | None = None) -> Prepared:
    """Read, sample, solve and engage a job (offline: raises on bad input).

    Args:
        job: the validated job.
        progress: show progress on stderr (long paths).
        posture: ``"first_sample"`` or ``"path"`` (the rotation about the tool axis chosen along
            the whole path, :mod:`planner.posture`); default the job's ``[kinematics] posture``.

    Raises:
        JobError: ``posture = "path"`` with ``tool_rotation = "fixed"`` (the rotation cannot be
            both held and chosen).
    """
    t = time.perf_counter()
    robot = load_robot(job.cell.robot)
    tool, warnings = job_tool(job.tool.name, job.to_si().tool_radius, job.tool.flutes)
    si = job.to_si()
    toolpaths = read_job_toolpaths(job, si.chord_tol)
    base = si.base
    path = sample_toolpath(list(toolpaths), base, si.chord_tol, si.step_max)
    walls = {"read_s": time.perf_counter() - t}
    t = time.perf_counter()
    fixed = job.kinematics.tool_rotation == "fixed"
    posture = job.kinematics.posture if posture is None else posture
    if posture not in ("first_sample", "path"):
        raise JobError(f"job {job.job.name!r}", [
            f"[kinematics] posture = {posture!r}: use \"first_sample\" or \"path\""])
    if posture == "path" and fixed:
        raise JobError(f"job {job.job.name!r}", [
            "[kinematics] posture = \"path\" chooses the rotation about the tool axis, "
            "tool_rotation = \"fixed\" holds it: leave one out"])
    kin = solve_path(robot, path, si.tool, IKOptions(
        seed=si.seed_joints, choose_for_stiffness=job.kinematics.choose_for_stiffness and not fixed,
        tool_rotation=si.tool_rotation if fixed else None),
        progress=progress)
    walls["ik_s"] = time.perf_counter() - t
    t = time.perf_counter()
    eng = job.engagement
    feed_dir_wp = path.feed_dir_wp
    # the stock's engagement is one call of seconds on a long path: a bar names the step
    with bar(1, f"engagement ({eng.source})", progress and eng.source != "fixed"
             and len(path) >= MIN_TOTAL, unit="step", min_total=1):
        if eng.source == "fixed":
            a_e = (2 * tool.radius if eng.milling == "slot" else si.a_e)
            e = fixed_engagement(len(path), a_e, si.a_p, eng.milling, feed_dir_wp,
                                 path.tool_axis_wp, path.cutting, tool_radius=tool.radius)
        else:
            z0, z1 = si.stock_z  # type: ignore[misc]
            if si.stock_box is not None:
                x0, y0, x1, y1 = si.stock_box
                stock = Stock.box(x0, y0, x1, y1, z0, z1)
            else:
                stock = Stock(si.stock_outline, z0, z1)
            if eng.source == "zmap":
                e = zmap_engagement(path.position_wp, path.tool_axis_wp, path.cutting, tool.radius,
                                    stock, cell=eng.stock.zmap_cell(),  # type: ignore[union-attr]
                                    where=path.where, sliver=max(SLIVER_TOL, 2.0 * si.chord_tol))
            else:
                e = stock_engagement(path.position_wp, path.tool_axis_wp, path.cutting, tool.radius,
                                     stock, where=path.where)
    rot = base[:3, :3]
    engagement = Engagement(a_e=e.a_e, a_p=e.a_p, mode=e.mode, radial_dir=e.radial_dir @ rot.T,
                            engaged_angle=e.engaged_angle,
                            feed_dir=None if e.feed_dir is None else e.feed_dir @ rot.T,
                            plunge=e.plunge, warnings=e.warnings)
    walls["engagement_s"] = time.perf_counter() - t
    prep = Prepared(job=job, robot=robot, tool=tool, toolpaths=toolpaths, path=path,
                    kinematics=kin, engagement=engagement, warnings=tuple(warnings),
                    wall_times=walls)
    if posture == "path" and kin.all_reachable:
        from planner.posture import PostureOptions, apply_posture, choose_posture

        t = time.perf_counter()
        chosen = choose_posture(prep, PostureOptions(
            rate_deg_per_mm=job.kinematics.posture_rate_deg_per_mm))
        prep = apply_posture(prep, chosen)
        prep.wall_times["posture_s"] = time.perf_counter() - t
    return prep


def inspect_job(prep: Prepared) -> dict[str, Any]:
    """The ``cctmill inspect JOB.toml`` summary: toolpaths, reachability, engagement (SI/mm named)."""
    kin, e, path = prep.kinematics, prep.engagement, prep.path
    codes = {v: k for k, v in MILLING_MODES.items()}
    engaged = e.mode >= 0
    modes = {codes.get(int(c), "air"): int(np.sum(e.mode == c)) for c in np.unique(e.mode)}

    def stats(v: np.ndarray) -> dict[str, float] | None:
        v = v[engaged]
        if v.size == 0:
            return None
        return {"min": float(v.min() * 1e3), "mean": float(v.mean() * 1e3),
                "max": float(v.max() * 1e3)}

    # joint ranges over the samples reached (a failed solve's best attempt is no pose)
    q = np.degrees(kin.q[kin.reachable]) if np.any(kin.reachable) else np.degrees(kin.q[:0])
    ranges = ({name: [float(q[:, i].min()), float(q[:, i].max())]
               for i, name in enumerate(kin.joint_names)} if q.size else {})
    from robot_io.diagnostics import group_warnings

    return {
        "job": prep.job.job.name,
        "toolpaths": [{**summarize(tp), "warning_groups": [g.as_json() for g in
                                                           group_warnings([tp])]}
                      for tp in prep.toolpaths],
        "samples": len(path),
        "path_length_m": float(path.s[-1]),
        "reachability": {
            "all_reachable": kin.all_reachable,
            "unreachable_samples": int(np.sum(~kin.reachable)),
            "problems": kin.problems,
            "configuration_jumps": kin.jumps.tolist(),
            "joint_range_deg": ranges,
        },
        "engagement": {
            "source": prep.job.engagement.source,
            "modes": modes,
            "ae_mm": stats(e.a_e),
            "ap_mm": stats(e.a_p),
            "warnings": list(e.warnings),
        },
        "warnings": [str(w) for w in prep.warnings],
    }
