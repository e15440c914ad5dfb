"""Plan a job: feed ceilings, sections and feeds (optimize / thesis / constant), timing, plan file.

:func:`plan_job` is the library face of ``cctmill plan``::

    job = load_job("job.toml")
    result = plan_job(job, method="optimize")      # raises on an infeasible or unsolved plan
    plan = Plan.from_result(result)                # the typed plan, SI (planner.plan_file)

(:func:`planner.outputs.run_plan_job` is what ``cctmill plan`` calls: plan, files, report, KRL.)

Every sample of the path gets a kind (cut / air / rapid, :mod:`planner.sections`). ``cut`` samples
are evaluated with the full point model (:mod:`planner.ceilings`); their feed ceilings feed the
chosen method:

* ``optimize`` — the sections of ``sections``, then a *feed profile* (:mod:`planner.feed_profile`):
  a path speed per sample under every sample's ceiling, the path acceleration and jerk and the
  joints' limits; each section's planned feed is the base its profile is a multiple of (the KRL
  ``.dat`` value that retunes it);
* ``sections`` — CasADi + IPOPT (:mod:`planner.optimize`), warm-started from the thesis baseline,
  one feed per section;
* ``thesis`` — the thesis's section algorithm (:mod:`planner.thesis_sections`);
* ``constant`` — one feed for the whole cut: the lowest ceiling (the safe constant feed).

``air`` sections run at ``feed_max`` (plunges keep their programmed feed, capped), ``rapid``
sections at ``rapid_mm_s``. toppra and ruckig then time the path (:mod:`planner.timing`); the
profile is its own timing.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from models.errors import CctmillError, InputError
from models.tooling import load_material
from planner._progress import MIN_TOTAL, bar
from planner.cam_feed import apply_cam_feed, cam_feed_caps, check_rapid_above_feed, non_cut_sections
from planner.ceilings import CONSTRAINTS, Ceilings, Evaluation, PathModel
from planner.feed_profile import REST_SPEED, FeedProfile, profile_timing
from planner.job import Job
from planner.limits import Limits
from planner.optimize import NOT_SOLVED, SolveResult, optimize_sections
from planner.partition import cut_time_bound, fastest_splits
from planner.plan_file import KINDS, Plan, PlanSamples, PlanSection, SectionCharacteristic, SolverRecord
from planner.plan_floor import floor_problem
from planner.prepare import Prepared, prepare
from planner.sections import (
    CUT,
    RAPID,
    Section,
    kind_runs,
    merge_empty_sections,
    sample_kinds,
    section_of_samples,
    step_lengths,
)
from planner.thesis_sections import thesis_sections
from planner.timing import ROBOT_LIMITED_SECTION, Timing, time_path
from planner.tool_limits import (
    TOOL_BINDING,
    PlanWarning,
    check_spindle_speed,
    rubbing_warnings,
    tool_feed_cap,
    tool_warnings,
)
from robot_io.diagnostics import group_warnings
from robot_io.krl.reader import matrices_to_abc

__all__ = [
    "CHARACTERISTIC_FEEDS",
    "JOINT_RELAX",
    "METHODS",
    "PlanInfeasibleError",
    "PlanResult",
    "check_feasible",
    "limit_confidence_summary",
    "limit_confidence_text",
    "plan_job",
    "plan_of_result",
    "plan_prepared",
    "summary",
]

METHODS = ("optimize", "sections", "thesis", "constant")
#: Factor on the joints' speed and acceleration limits for the commanded profile (the process's
#: own profile: the controller, not the program, slows where the joints bind; see ``_profiled``).
JOINT_RELAX = 1e3
#: Methods whose plan is a feed profile (a speed per sample) rather than one feed per section.
PROFILED = ("optimize",)
#: Threads of the ceilings' evaluation by default (:class:`planner.ceilings.PathModel`).
DEFAULT_THREADS = 2
#: The steps the ``planning`` bar counts after the ceilings': sections, timing, evaluation, rows.
_PLAN_STEPS = 4
#: What a method that solves no NLP does instead, in words (the report and ``cctmill plan``).
_NO_OPTIMISATION = {
    "optimize": "no optimisation needed: the path has no cut samples",
    "sections": "no optimisation needed: the path has no cut samples",
    "thesis": "no optimisation: the thesis section algorithm sets the feeds",
    "constant": "no optimisation: one constant feed, the lowest ceiling of the cut",
}
#: Feeds of each cut section's stored stability characteristic (log-spaced over the feed range).
CHARACTERISTIC_FEEDS = 25


class PlanInfeasibleError(CctmillError):
    """No feed meets the limits somewhere on the path.

    Attributes:
        section: position (from 0) of the section — a cell of ``section_length_min`` — that cannot
            be planned; the message numbers it from 1, as plan.json and the KRL program do.
        constraint: the constraint that fails at the lowest feed.
        sample: the first failing sample.
    """

    def __init__(self, message: str, section: int, constraint: str, sample: int) -> None:
        self.section = section
        self.constraint = constraint
        self.sample = sample
        super().__init__(message)


@dataclass
class PlanResult:
    """A finished plan with everything it was made from, in memory (SI); :func:`plan_of_result`
    (:meth:`planner.plan_file.Plan.from_result`) is the plan itself.

    Attributes:
        method: the method used.
        prep: the prepared job.
        model: the path model (its ``index`` are the cut samples).
        ceilings: feed ceilings of the cut samples.
        sections: the sections in path order (all kinds).
        feed: planned path-speed bound per sample [m/s], (n,).
        kinds: kind code per sample, (n,).
        evaluation: the model at the planned feeds (cut samples).
        timing: toppra/ruckig timing.
        solver: the solver record.
        limits: the limits used.
        safety_factor: the thesis safety factor used.
        wall_times: wall time of each stage [s].
        plan_sections: the plan's sections with what they hold (:class:`PlanSection`, SI).
        cut_time_bound: the least cut time Σ L/f any plan with sections of at least
            ``section_length_min`` can have under these limits [s]
            (:func:`planner.partition.cut_time_bound`).
        warnings: what the plan's user must know that did not stop it (tool data that do not
            apply, coefficients identified with another tool, rubbing, engagement).
        profile: the feed profile and its pointwise bound (profiled methods), else ``None``;
            ``feed`` is then the profile, a speed per sample.
    """

    method: str
    prep: Prepared
    model: PathModel
    ceilings: Ceilings
    sections: list[Section]
    feed: np.ndarray
    kinds: np.ndarray
    evaluation: Evaluation
    timing: Timing
    solver: SolveResult
    limits: Limits
    safety_factor: float
    wall_times: dict[str, float] = field(default_factory=dict)
    plan_sections: tuple[PlanSection, ...] = ()
    cut_time_bound: float = float("nan")
    warnings: tuple[PlanWarning, ...] = ()
    profile: FeedProfile | None = None

    @property
    def profiled(self) -> bool:
        """The plan is a feed profile (a speed per sample), not one feed per section."""
        return self.profile is not None

    @property
    def section_rows(self) -> list[dict[str, Any]]:
        """The sections as plan.json writes them (units in the key names; for reports). Built on
        every access: take it once per use."""
        return [s.as_json() for s in self.plan_sections]

    @property
    def cut_time(self) -> float:
        """Time over the cut samples' steps [s]: Σ ds/feed for a section plan; for a feed profile
        the timed time of those steps (the profile dips towards rest at sharp corners, where
        ds/feed at one sample would count the whole step at the dip's speed)."""
        sel = self.kinds == CUT
        if self.profile is not None:
            t = np.asarray(self.timing.time, float)
            return float(np.sum(np.diff(t, prepend=t[:1])[sel]))
        ds = step_lengths(self.prep.path.s)
        return float(np.sum(ds[sel] / self.feed[sel]))

    @property
    def cycle_time(self) -> float:
        """toppra-timed cycle [s]."""
        return self.timing.cycle_time

    @property
    def process_time(self) -> float:
        """Σ ds/feed over feed moves (no robot limits) [s]."""
        ds = step_lengths(self.prep.path.s)
        sel = self.kinds != RAPID
        return float(np.sum(ds[sel] / self.feed[sel]))


def _ceiling_arrays(n: int, model: PathModel, ceil: Ceilings) -> tuple[np.ndarray, np.ndarray]:
    c = np.full(n, np.nan)
    b = np.full(n, "", dtype=object)
    c[model.index] = ceil.feed
    b[model.index] = ceil.binding
    return c, b.astype(str)


def _check_floor(prep: Prepared, model: PathModel, ceil: Ceilings, runs, ds, limits: Limits) -> None:
    problem = floor_problem(prep, model, ceil, runs, ds, limits)
    if problem is not None:
        message, cell, what, sample = problem
        raise PlanInfeasibleError(message, section=cell, constraint=what, sample=sample)


def _ceilings(prep: Prepared, limits: Limits | None, progress: bool,
              threads: int = DEFAULT_THREADS) -> tuple[PathModel, Ceilings]:
    """The path model and the feed ceilings of every cut sample (the process limits, the tool's
    chip load, the programmed feed), after the checks that need no ceiling (reach, rapid speed,
    spindle)."""
    prep.kinematics.raise_if_unreachable()
    model = PathModel(prep, limits=limits, threads=threads, progress=progress)
    check_rapid_above_feed(model.limits)
    spindle_speed = prep.job.to_si().spindle_speed
    check_spindle_speed(prep.tool, spindle_speed)
    caps = cam_feed_caps(prep.path, model.index, model.limits)
    tool_cap = np.full(len(model), tool_feed_cap(prep.tool, spindle_speed))
    return model, apply_cam_feed(apply_cam_feed(model.ceilings(), tool_cap, TOOL_BINDING), caps)


def check_feasible(prep: Prepared, limits: Limits | None = None, progress: bool = False) -> None:
    """Raise what :func:`plan_prepared` would raise before it optimises: an unreachable sample,
    limits that contradict one another, or a limit no feed meets (:class:`PlanInfeasibleError`,
    naming the section, the constraint and the sample). ``cctmill inspect`` runs it, so that a job
    that cannot be cut fails there as it fails in ``plan``."""
    model, ceil = _ceilings(prep, limits, progress)
    path = prep.path
    runs = kind_runs(sample_kinds(len(path), model.index, path.cutting))
    _check_floor(prep, model, ceil, runs, step_lengths(path.s), model.limits)


def plan_prepared(prep: Prepared, method: str = "optimize", safety_factor: float | None = None,
                  limits: Limits | None = None, f_ref: float | None = None,
                  thesis_every_sample: bool = True, progress: bool = False,
                  threads: int = DEFAULT_THREADS) -> PlanResult:
    """Plan an already prepared job (see :func:`plan_job`).

    Args:
        prep: the prepared job.
        method: ``optimize`` (sections + feed profile), ``sections``, ``thesis`` or ``constant``.
        safety_factor: the thesis safety factor (default: the job's).
        limits: override the job's limits.
        f_ref: feed scale of the optimiser's variables [m/s] (default feed_max).
        thesis_every_sample: the thesis baseline also holds at every sample (default); False
            runs it exactly as published (midpoints only), for comparison.
        progress: show progress bars on stderr (long jobs).
        threads: threads of the ceilings' evaluation (the path model's mapped function).
    """
    if method not in METHODS:
        raise InputError("method", f"{method!r} is not one of {', '.join(METHODS)}")
    job = prep.job
    sf = job.plan.safety_factor if safety_factor is None else float(safety_factor)
    if not (np.isfinite(sf) and sf >= 1.0):
        raise InputError("safety_factor", f"must be a number >= 1, got {sf:g}")
    walls: dict[str, float] = {}
    t = time.perf_counter()
    model, ceil = _ceilings(prep, limits, progress, threads)
    limits = model.limits
    walls["ceilings_s"] = time.perf_counter() - t
    path = prep.path
    n = len(path)
    ds = step_lengths(path.s)
    kinds = sample_kinds(n, model.index, path.cutting)
    runs = kind_runs(kinds)
    _check_floor(prep, model, ceil, runs, ds, limits)
    # after the ceilings' bar: the sections, the timing, the evaluation (seconds on a long path)
    steps = bar(_PLAN_STEPS, "planning", progress and n >= MIN_TOTAL, unit="step",
                min_total=1)
    ceiling, binding = _ceiling_arrays(n, model, ceil)
    pos = np.full(n, -1)
    pos[model.index] = np.arange(len(model))

    def gamma_at(samples: np.ndarray, feeds: np.ndarray) -> np.ndarray:
        return model.evaluate(feeds, pos[samples]).gamma

    steps.set_postfix_str("sections")
    t = time.perf_counter()
    splits = fastest_splits(runs, ds, ceiling, limits.section_length_min)
    solver = SolveResult(NOT_SOLVED, True, 0, 0.0, 0.0, 0.0, _NO_OPTIMISATION[method])
    if method == "constant":
        f = float(np.nanmin(ceiling)) if len(model) else limits.feed_max
        tight = int(np.nanargmin(ceiling)) if len(model) else 0
        cut = [Section(a, b, CUT, f, str(binding[tight]) if len(model) else "feed_max",
                       "one feed for the whole cut: the lowest ceiling")
               for a, b, kind in runs if kind == CUT]
    else:
        cut = thesis_sections(runs, path.s, ceiling, binding, gamma_at,
                              job.to_si().thesis_section_length, limits.section_length_min,
                              sf, limits.feed_min,
                              every_sample=thesis_every_sample or method != "thesis")
        if method in ("optimize", "sections"):
            warm = np.full(n, np.nan)
            for sec in cut:
                warm[sec.start:sec.stop] = sec.feed
            cut, solver = optimize_sections(
                runs, ds, ceiling, binding, limits.feed_min, limits.feed_max,
                limits.section_length_min, limits.feed_change_max,
                job.plan.section_change_cost_s, warm=warm, f_ref=f_ref, cells=splits)
    walls["sections_s"] = time.perf_counter() - t
    steps.update()
    steps.set_postfix_str("timing")
    sections = merge_empty_sections(
        sorted(cut + non_cut_sections(runs, path, prep.engagement.plunge, limits),
               key=lambda x: x.start), ds)
    feed = np.empty(n)
    for sec in sections:
        feed[sec.start:sec.stop] = sec.feed
    data = prep.robot.data
    profile = None
    if method in PROFILED:
        sections, feed, timing, profile = _profiled(sections, feed, model, ceil, prep, limits)
        walls["profile_lp_s"] = profile.lp_time
    else:
        timing = time_path(path.s, prep.kinematics.q, feed, data.velocity, data.acceleration,
                           limits.path_acc_max, limits.path_jerk_max)
    walls["timing_s"] = timing.compute_time
    steps.update()
    steps.set_postfix_str("evaluation")
    t = time.perf_counter()
    evaluation = model.evaluate(feed[model.index])
    walls["evaluation_s"] = time.perf_counter() - t
    steps.update()
    steps.set_postfix_str("section rows")
    cut_secs = [sec for sec in sections if sec.kind == CUT]
    warnings = [*prep.warnings, *getattr(prep.engagement, "warnings", ()),
                *tool_warnings(prep.tool, load_material(job.material)),
                *rubbing_warnings(prep.tool, job.to_si().spindle_speed, np.array([c.feed for c in cut_secs]),
                                  [(int(path.line[c.start]), int(path.line[c.stop - 1]))
                                   for c in cut_secs])]
    result = PlanResult(method=method, prep=prep, model=model, ceilings=ceil, sections=sections,
                        feed=feed, kinds=kinds, evaluation=evaluation, timing=timing,
                        solver=solver, limits=limits, safety_factor=sf, wall_times=walls,
                        profile=profile,
                        warnings=tuple(w if isinstance(w, PlanWarning)
                                       else PlanWarning("engagement", str(w)) for w in warnings))
    t = time.perf_counter()
    result.plan_sections = _plan_sections(result, ceiling, pos)
    result.cut_time_bound = cut_time_bound(splits, ds, ceiling)
    walls["report_rows_s"] = time.perf_counter() - t
    steps.close()
    return result


def _profiled(sections: list[Section], feed: np.ndarray, model: PathModel, ceil: Ceilings,
              prep: Prepared, limits: Limits
              ) -> tuple[list[Section], np.ndarray, Timing, FeedProfile]:
    """The feed profile under every sample's ceiling (cut: the process ceiling; air and rapid:
    their sections' feeds). The sections keep their planned feeds: each is the base its samples'
    profile is a multiple of (the KRL ``.dat`` value that retunes the section)."""
    ceiling = feed.copy()
    ceiling[model.index] = ceil.feed
    data = prep.robot.data
    timing, prof = profile_timing(prep.path.s, prep.kinematics.q, ceiling, data.velocity,
                                  data.acceleration, limits.path_acc_max, limits.path_jerk_max)
    # The commanded feed is the profile the *process* allows: the same ceilings, path
    # acceleration and jerk, without the joints' limits (relaxed by JOINT_RELAX). Where the joints
    # slow the robot (a sharp corner: ṡ dips towards rest at one sample) the controller slows by
    # itself, as it does in a section plan; commanding the dip would run the whole LIN into the
    # corner at the dip's speed. The timing (cycle, robot-limited samples) keeps the joints.
    free, _ = profile_timing(prep.path.s, prep.kinematics.q, ceiling,
                             np.asarray(data.velocity, float) * JOINT_RELAX,
                             np.asarray(data.acceleration, float) * JOINT_RELAX,
                             limits.path_acc_max, limits.path_jerk_max)
    speed = np.minimum(np.maximum(free.speed, timing.speed), ceiling)
    # at the path's two rest points (ṡ = 0, the controller starts and stops there by itself) the
    # command is the nearest moving sample's, under the ceiling
    moving = np.flatnonzero(speed > REST_SPEED)
    cmd = speed.copy()
    if moving.size:
        rest = np.flatnonzero(speed <= REST_SPEED)
        near = moving[np.clip(np.searchsorted(moving, rest), 0, moving.size - 1)]
        cmd[rest] = np.minimum(speed[near], ceiling[rest])
    out = [sec if sec.kind != CUT else
           replace(sec, note=(sec.note + "; " if sec.note else "") + "feed profile: its samples "
                   "run at the profile, this feed the base it scales")
           for sec in sections]
    return out, cmd, timing, prof


def plan_job(job: Job, method: str | None = None, safety_factor: float | None = None,
             progress: bool = False, threads: int = DEFAULT_THREADS) -> PlanResult:
    """Prepare and plan a job.

    Args:
        job: the validated job.
        method: ``optimize``, ``sections``, ``thesis`` or ``constant`` (default: the job's
            ``[plan] method``).
        safety_factor: the thesis safety factor (default: the job's).
        progress: show progress on stderr.
        threads: threads of the ceilings' evaluation (1 in a study's worker process, which has
            one core to itself).

    Raises:
        PlanInfeasibleError: a limit cannot be met at any feed (names the section and constraint).
        PlanSolverError: IPOPT did not converge.
        UnreachablePoseError: a sample cannot be reached.
    """
    t = time.perf_counter()
    prep = prepare(job, progress=progress)
    prep_time = time.perf_counter() - t
    result = plan_prepared(prep, method or job.plan.method, safety_factor, progress=progress,
                           threads=threads)
    result.wall_times = {"prepare_s": prep_time, **prep.wall_times, **result.wall_times}
    return result


def _plan_sections(res: PlanResult, ceiling: np.ndarray,
                   pos: np.ndarray) -> tuple[PlanSection, ...]:
    prep, ev, model, timing = res.prep, res.evaluation, res.model, res.timing
    path = prep.path
    ds = step_lengths(path.s)
    rows: list[dict[str, Any]] = []
    lim = res.limits
    bound = timing.bound
    grid = np.geomspace(lim.feed_min, lim.feed_max, CHARACTERISTIC_FEEDS)
    pending: list[tuple[dict[str, Any], int]] = []
    for i, sec in enumerate(res.sections):
        a, b = sec.start, sec.stop
        length = float(ds[a:b].sum())
        t_sec = float(timing.time[b - 1] - (timing.time[a - 1] if a > 0 else 0.0))
        # a profile's sections are judged against their samples' ceilings, a section plan's
        # against its feed (the same formula: Σ ds / planned bound)
        ideal = float(np.sum(ds[a:b] / bound[a:b])) if res.profiled else length / sec.feed
        robot_limited = bool(length > 0 and t_sec > 0 and ideal < ROBOT_LIMITED_SECTION * t_sec)
        process_time = float(np.sum(ds[a:b] / res.feed[a:b])) if res.profiled else length / sec.feed
        row: dict[str, Any] = {
            "index": i, "kind": KINDS[sec.kind], "sample_start": a, "sample_stop": b,
            "s_start": float(path.s[a - 1] if a > 0 else path.s[0]),
            "s_end": float(path.s[b - 1]), "length": length, "feed": sec.feed,
            "binding": "robot" if robot_limited else sec.binding, "process_binding": sec.binding,
            "note": sec.note, "line_start": int(path.line[a]), "line_end": int(path.line[b - 1]),
            "file": path.files[int(path.file[a])], "time": t_sec,
            "process_time": process_time, "robot_limited": robot_limited,
            "tooth_frequency": model.tooth_frequency,
        }
        if sec.kind == CUT:
            k = pos[a:b]
            k = k[k >= 0]
            tight = int(k[np.argmin(ceiling[model.index[k]])])
            nat = ev.natural_frequencies[tight]
            row.update({
                "margin": float(ev.margin[k].min()),
                "force_max": float(ev.force[k].max()),
                "deflection_max": float(ev.deflection_norm[k].max()),
                "deflection_normal_max": float(np.abs(ev.deflection_normal[k]).max()),
                "power_max": float(ev.power[k].max()),
                "gamma": float(ev.gamma[tight]),
                "gamma_range": (float(ev.gamma[k].min()), float(ev.gamma[k].max())),
                "natural_frequencies": None if not np.all(np.isfinite(nat)) else tuple(nat.tolist()),
                "ceiling_min": float(ceiling[model.index[tight]]),
                "tightest_sample": int(model.index[tight]),
            })
            pending.append((row, tight))
        rows.append(row)
    # every cut section's characteristic at its tightest sample, in one mapped evaluation
    if pending:
        g = grid.size
        ch = model.evaluate(np.tile(grid, len(pending)), np.repeat([t for _, t in pending], g))
        for j, (row, tight) in enumerate(pending):
            sl = slice(j * g, (j + 1) * g)
            row["characteristic"] = SectionCharacteristic(
                sample=int(model.index[tight]), feeds=grid, margin=ch.margin[sl],
                gamma=ch.gamma[sl], force=ch.force[sl], stable=ch.stable[sl],
                deflection=ch.deflection_norm[sl], ok=ch.all_ok[sl])
    return tuple(PlanSection(**row) for row in rows)


def _plan_samples(res: PlanResult) -> PlanSamples:
    prep, ev, model = res.prep, res.evaluation, res.model
    path, job = prep.path, prep.job
    n = len(path)
    tool = job.tool_frame()
    f = prep.robot.pose_function.map(n)
    _, rot = f(prep.kinematics.q.T, tool[:3, 3])
    rot = np.asarray(rot, float).reshape(3, n, 3).transpose(1, 0, 2) @ tool[:3, :3]
    base = path.base
    rot_wp = base[:3, :3].T @ rot

    def spread(v: np.ndarray, shape: tuple = ()) -> np.ndarray:
        out = np.full((n, *shape), np.nan)
        out[model.index] = v
        return out

    e = prep.engagement
    return PlanSamples(
        s=path.s, q=prep.kinematics.q, position_wp=path.position_wp,
        abc_wp=np.radians(matrices_to_abc(rot_wp)), tool_axis_wp=path.tool_axis_wp,
        section=section_of_samples(res.sections, n), kind=res.kinds,
        arc=np.array([m.is_arc for m in path.moves])[path.move], move=path.move, line=path.line,
        source_file=path.file, feed=res.feed, speed=res.timing.speed, time=res.timing.time,
        force=spread(ev.force), deflection=spread(ev.deflection_norm),
        deflection_wp=spread(ev.deflection, (3,)) @ base[:3, :3],  # base → workpiece axes
        deflection_normal=spread(ev.deflection_normal), gamma=spread(ev.gamma),
        margin=spread(ev.margin), power=spread(ev.power), a_e=e.a_e, a_p=e.a_p,
        mode=e.mode.astype(int), ceiling=_spread_ceiling(res),
        robot_limited=res.timing.robot_limited, bound=res.timing.bound,
        joint_speed=res.timing.joint_speed)


def _spread_ceiling(res: PlanResult) -> np.ndarray:
    out = np.full(len(res.prep.path), np.nan)
    out[res.model.index] = res.ceilings.feed
    return out


def plan_of_result(res: PlanResult) -> Plan:
    """The typed plan (SI) of a result, in memory: what the exporter and the supervisor take."""
    job = res.prep.job
    tool = res.prep.tool
    si = job.to_si()
    return Plan(
        method=res.method, job_name=job.job.name, job_folder=str(job.folder), robot=job.cell.robot,
        files=tuple(res.prep.path.files), base_xyz=si.base_xyz, base_abc=si.base_abc,
        tool_xyz=si.tool_xyz, tool_abc=si.tool_abc,
        spindle_rpm=job.spindle.rpm, flutes=tool.flutes, tool_diameter=tool.radius * 2.0,
        material=job.material,
        model={"process_model": job.model.process_model, "mass_model": job.model.mass_model,
               "criterion": job.model.chatter_criterion, "cct": job.model.cct,
               # what the supervisor's compensation models the cell with (a calibration's)
               "joint_stiffness_scale": job.cell.joint_stiffness_scale,
               "process_gain": job.model.process_gain,
               "coefficients": [float(v) for v in job.material_coefficients()]},
        limits=res.limits, safety_factor=res.safety_factor, sections=res.plan_sections,
        samples=_plan_samples(res), cycle_time=res.cycle_time, process_time=res.process_time,
        solver=SolverRecord.from_json(res.solver.as_json()),
        wall_times=dict(res.wall_times), summary=summary(res),
        import_warnings=group_warnings(res.prep.toolpaths), warnings=res.warnings)


def summary(res: PlanResult) -> dict[str, Any]:
    """Headline numbers of a plan (units in names)."""
    ev = res.evaluation
    secs = res.plan_sections
    counts: dict[str, int] = {}
    for s in secs:
        counts[s.binding] = counts.get(s.binding, 0) + 1
    return {
        "samples": len(res.prep.path), "cut_samples": len(res.model),
        "sections": len(secs), "cut_sections": sum(s.kind == "cut" for s in secs),
        "binding_counts": counts,
        "cut_time_s": res.cut_time,
        "cut_time_bound_s": res.cut_time_bound,
        "pointwise_bound_cycle_s": (res.profile.bound_cycle_time if res.profile is not None
                                    else None),
        "robot_limited_sections": sum(1 for s in secs if s.robot_limited),
        "force_max_N": float(ev.force.max()) if ev.force.size else None,
        "deflection_max_mm": float(ev.deflection_norm.max() * 1e3) if ev.force.size else None,
        "deflection_normal_max_mm": (float(np.abs(ev.deflection_normal).max() * 1e3)
                                     if ev.force.size else None),
        "margin_min_N_per_m": float(ev.margin.min()) if ev.force.size else None,
        "feed_range_mm_s": [float(res.feed[res.kinds == CUT].min() * 1e3),
                            float(res.feed[res.kinds == CUT].max() * 1e3)] if ev.force.size else None,
        "constraints": list(CONSTRAINTS),
        "limit_confidence": limit_confidence_summary(res),
    }


def limit_confidence_summary(res: PlanResult) -> dict[str, float] | None:
    """How the calibration's uncertainty tightened the force and deflection limits (None: the job
    states none): the probability and the largest factors at the planned feeds
    (:mod:`planner.limit_confidence`)."""
    conf, k = res.model.confidence, res.evaluation.confidence_factors
    if conf is None or k.size == 0:
        return None
    return {"probability": conf.probability, "z": conf.z,
            "force_factor_max": float(k[:, 0].max()), "deflection_factor_max": float(k[:, 1].max())}


def limit_confidence_text(res: PlanResult) -> str | None:
    """:func:`limit_confidence_summary` as one sentence (the CLI and the report), or None."""
    conf = limit_confidence_summary(res)
    if conf is None:
        return None
    return (f"force and deflection limits held with probability {conf['probability']:g}: bounds up "
            f"to +{100 * (conf['force_factor_max'] - 1):.1f} % (force), "
            f"+{100 * (conf['deflection_factor_max'] - 1):.1f} % (deflection) over the fitted model")
