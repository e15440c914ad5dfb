"""What ``cctmill calibrate`` and ``cctmill testcuts`` run.

:func:`calibrate` (records + job → fits) makes the fits asked for and returns them with the reason
for every fit it refused; :func:`write_calibration` writes the overlay (TOML) and the fit-quality
report (JSON, beside it); :func:`testcuts` proposes test passes, writes them as KRL and planned
records and, given a truth file, the records the simulated true cell gives.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from models.errors import InputError
from planner._atomic import write_text_atomic
from planner.calibrate.context import CalibrationContext
from planner.calibrate.fit_boundary import Boundary, fit_boundary
from planner.calibrate.fit_coefficients import (
    COEFFICIENT_NAMES,
    CoefficientFit,
    FitRefused,
    fit_coefficients,
)
from planner.calibrate.fit_process import ProcessGainFit, fit_process_gain
from planner.calibrate.fit_stiffness import StiffnessFit, fit_stiffness
from planner.calibrate.overlay import write_overlay
from planner.calibrate.records import CutRecord, load_records

__all__ = ["DESIGNS", "FITS", "CalibrationResult", "TestCutsResult", "calibrate", "testcuts",
           "write_calibration"]

#: The fits ``--fit`` may name, in the order they run.
FITS = ("coefficients", "stiffness", "process", "boundary")
#: The test-pass designs of :func:`testcuts`.
DESIGNS = ("boundary", "identification", "along-job")


@dataclass(frozen=True)
class CalibrationResult:
    """The fits of one calibration.

    Attributes:
        context: the nominal cell (from the job).
        records: the records read; record_files: where from.
        job_file: the job.
        coefficients, stiffness, process, boundary: the fits (None: not asked for, or refused).
        refused: fit name → the reason it was not made.
    """

    context: CalibrationContext
    records: tuple[CutRecord, ...]
    record_files: tuple[str, ...]
    job_file: str
    coefficients: CoefficientFit | None = None
    stiffness: StiffnessFit | None = None
    boundary: Boundary | None = None
    refused: dict[str, str] = field(default_factory=dict)
    process: ProcessGainFit | None = None

    def report(self) -> dict:
        """The fit-quality report (JSON-able, SI)."""
        verdicts = {v: sum(r.verdict == v for r in self.records)
                    for v in ("stable", "chatter", "unknown")}
        return {
            "job": self.job_file, "records": list(self.record_files),
            "n_records": len(self.records), "verdicts": verdicts,
            "coefficients": None if self.coefficients is None else self.coefficients.as_json(),
            "stiffness": None if self.stiffness is None else self.stiffness.as_json(),
            "process": None if self.process is None else self.process.as_json(),
            "boundary": None if self.boundary is None else self.boundary.as_json(),
            "refused": dict(self.refused),
        }

    def summary(self) -> str:
        """A few lines for the terminal."""
        out = [f"{len(self.records)} records from {len(self.record_files)} file(s)"]
        c = self.coefficients
        if c is not None:
            out.append(f"coefficients ({c.n_cuts} cuts, {c.n_feeds} feeds, residual "
                       f"{c.residual_rms_n:.3g} N RMS of {c.force_rms_n:.3g} N):")
            for i, name in enumerate(COEFFICIENT_NAMES):
                out.append(f"  {name} = {c.values[i]:.4g}  95 % CI [{c.ci_low[i]:.4g}, "
                           f"{c.ci_high[i]:.4g}]  ({c.values[i] / c.nominal[i]:.3f} x nominal)")
        s = self.stiffness
        if s is not None:
            out.append(f"joint stiffness scale ({s.method}, {s.n_deflections} deflections): "
                       f"{s.scale:.4g}  95 % CI [{s.scale_ci[0]:.4g}, {s.scale_ci[1]:.4g}]")
            if any(s.resolved):
                joints = ", ".join(f"A{i + 1} {v:.3g}" for i, v in enumerate(s.per_joint)
                                   if s.resolved[i])
                out.append(f"  per joint (resolved): {joints}")
        g = self.process
        if g is not None:
            out.append(f"process gain (eigen criterion, {g.n} cuts, {g.n_chatter} chatter): "
                       f"{g.gain:.4g} x the job's  95 % CI [{g.gain_ci[0]:.4g}, "
                       f"{g.gain_ci[1]:.4g}]; the criterion's verdicts right for "
                       f"{g.accuracy:.0%} of the cuts (the job's gain: {g.nominal_accuracy:.0%})")
        b = self.boundary
        if b is not None:
            out.append(f"stability boundary on the {b.criterion} margin, a_p, rpm: {b.n} cuts "
                       f"({b.n_chatter} chatter), leave-one-out accuracy {b.loo_accuracy:.0%}"
                       + ("" if b.margin_orders else "; the margin does NOT order the cuts "
                          "(P(chatter) rises with it): the criterion disagrees with this cell"))
        out += [f"{name}: refused: {why}" for name, why in self.refused.items()]
        return "\n".join(out)


def calibrate(record_files: Sequence[str | Path], job_file: str | Path,
              fits: Sequence[str] = ("coefficients", "stiffness"),
              progress: bool = False) -> CalibrationResult:
    """Read the records and the job, make the fits named in ``fits`` (see :data:`FITS`).

    A fit the data cannot support is not made; its reason is in ``refused``. ``progress``:
    progress bars on stderr for the long steps (the boundary's margins and refits), on a
    terminal only.

    Raises:
        RecordError, JobError: unreadable or invalid records or job.
        InputError: an unknown fit name, or no fit could be made at all.
    """
    from planner.job import load_job

    unknown = [f for f in fits if f not in FITS]
    if unknown or not fits:
        raise InputError("--fit", f"unknown fit(s) {unknown}; choose from {', '.join(FITS)}")
    if not record_files:
        raise InputError("RECORDS", "give at least one records file (JSON Lines)")
    job = load_job(job_file)
    ctx = CalibrationContext.from_job(job)
    records = tuple(load_records(*record_files))
    refused: dict[str, str] = {}
    coefficients = stiffness = None
    if "coefficients" in fits:
        try:
            coefficients = fit_coefficients(records, ctx.tool, ctx.material)
        except FitRefused as e:
            refused["coefficients"] = e.reason
    if "stiffness" in fits:
        try:
            stiffness = fit_stiffness(ctx, records)
        except FitRefused as e:
            refused["stiffness"] = e.reason
    boundary = process = None
    params = ctx.params(
        joint_scale=1.0 if stiffness is None else (
            stiffness.per_joint if stiffness.per_joint is not None else stiffness.scale),
        coefficients=None if coefficients is None else coefficients.values)
    if "process" in fits:
        try:
            process = fit_process_gain(ctx, records, params, progress=progress)
            params = replace(params, process_gain=ctx.process_gain * process.gain)
        except FitRefused as e:
            refused["process"] = e.reason
    if "boundary" in fits:
        try:
            boundary = fit_boundary(ctx, records, params, progress=progress)
        except FitRefused as e:
            refused["boundary"] = e.reason
    result = CalibrationResult(ctx, records, tuple(str(p) for p in record_files), str(job_file),
                               coefficients, stiffness, boundary, refused, process)
    if coefficients is None and stiffness is None and boundary is None and process is None:
        raise FitRefused("every", "; ".join(f"{k}: {v}" for k, v in refused.items()))
    return result


def write_calibration(result: CalibrationResult, overlay: str | Path) -> tuple[Path, Path]:
    """Write the overlay (TOML) and its report (``<overlay stem>.report.json``); return both."""
    overlay = Path(overlay)
    report_path = overlay.with_name(overlay.stem + ".report.json")
    ctx = result.context
    cell, model, cal = {}, {}, {}
    comments = [f"cctmill calibration overlay for {result.job_file}",
                f"from {len(result.records)} records: {', '.join(result.record_files)}",
                "use it with [calibration] overlay = \"<this file>\" in the job (docs/calibration.md)"]
    if result.stiffness is not None:
        s = result.stiffness
        cell["joint_stiffness_scale"] = round(ctx.joint_stiffness_scale * s.scale, 6)
        comments.append(f"joint_stiffness_scale: the job's {ctx.joint_stiffness_scale:g} x fitted "
                        f"{s.scale:.4g} (95 % CI {s.scale_ci[0]:.4g} .. {s.scale_ci[1]:.4g}, "
                        f"{s.method})")
        cal["joint_stiffness_scale_std"] = float(f"{s.scale_log_std:.4g}")
        if any(s.resolved):
            comments.append("per joint (in the report; the job has one common scale): " + ", ".join(
                f"A{i + 1} {v:.3g}" for i, v in enumerate(s.per_joint) if s.resolved[i]))
    if result.coefficients is not None:
        c = result.coefficients
        for i, name in enumerate(COEFFICIENT_NAMES):
            cal[name] = float(f"{c.values[i]:.6g}")
        cal["coefficient_covariance"] = [float(f"{v:.6g}") for v in
                                         np.asarray(c.covariance, float).ravel()]
        comments.append(f"k_tc .. k_ae: {c.n_cuts} cuts, {c.n_feeds} feeds per tooth "
                        f"{c.feed_per_tooth_range[0] * 1e3:.3g} .. "
                        f"{c.feed_per_tooth_range[1] * 1e3:.3g} mm; 95 % CIs in the report")
    if result.process is not None:
        g = result.process
        model["process_gain"] = float(f"{ctx.process_gain * g.gain:.6g}")
        comments.append(f"process_gain: the job's {ctx.process_gain:g} x fitted {g.gain:.4g} "
                        f"(95 % CI {g.gain_ci[0]:.4g} .. {g.gain_ci[1]:.4g}; eigen verdicts right "
                        f"for {g.accuracy:.0%} of {g.n} cuts, {g.nominal_accuracy:.0%} before)")
    if result.boundary is not None:
        cal.update(result.boundary.as_overlay())
        comments.append(f"boundary_*: logistic P(chatter) over the {result.boundary.criterion} "
                        f"margin, ap_mm, rpm from {result.boundary.n} cuts")
    cal["records"] = [str(Path(p).resolve()) for p in result.record_files]
    cal["report"] = report_path.name
    write_text_atomic(report_path, json.dumps(result.report(), indent=2) + "\n")
    write_overlay(overlay, cell, model, cal, comments)
    return overlay, report_path


@dataclass(frozen=True)
class TestCutsResult:
    """What :func:`testcuts` made.

    Attributes:
        planned: the proposed passes (``planned`` records); design: how they were chosen.
        files: the files written (KRL, planned records, simulated records).
        simulated: the records of the simulated truth (None without one).
    """

    planned: tuple[CutRecord, ...]
    design: str
    files: tuple[Path, ...]
    simulated: tuple[CutRecord, ...] | None = None

    def summary(self) -> str:
        lines = [f"{len(self.planned)} test passes ({self.design}):"]
        sim = {r.id: r for r in self.simulated or ()}
        for r in self.planned:
            p = r.source.get("p_chatter")
            lines.append(f"  {r.id}: {r.milling} ap {r.ap_mm:g} mm"
                         + (f" ae {r.ae_mm:g} mm" if r.ae_mm else "")
                         + f", {r.rpm:g} rpm, {r.feed_mm_s:g} mm/s"
                         + ("" if p is None else f", P(chatter) {p:.2f} now")
                         + (f" -> {sim[r.id].verdict}" if r.id in sim else ""))
        lines += [f"wrote {f}" for f in self.files]
        return "\n".join(lines)


def testcuts(job_file: str | Path, n: int, out_dir: str | Path,
             records: Sequence[str | Path] = (), truth_file: str | Path | None = None,
             design: str = "boundary", rpm: tuple[float, float] | None = None,
             ap_mm: tuple[float, float] | None = None, ae_mm: float | None = None,
             seed: int = 0, progress: bool = False) -> TestCutsResult:
    """Propose ``n`` test passes in the job's cell; write them as KRL and planned records; with a
    truth file, run them in the simulated true cell and write the records it gives.

    ``design``: ``identification`` (slots over the tool's chip-load range, for the coefficients
    and stiffness) or ``boundary``: with ``records`` whose verdicts support a boundary, the most
    informative passes for it (value of information); without, a space-filling start; or
    ``along-job``: the same, but each pass imitates one of the job's own planned sections (its
    pose, feed direction, a_e and feed, at the job's spindle speed), only a_p varying.
    """
    from planner.calibrate.testcuts import (
        boundary_cuts,
        identification_cuts,
        job_test_poses,
        krl_program,
        propose_cuts,
    )
    from planner.calibrate.truth import load_truth, run_cuts
    from planner.job import load_job
    from robot_io.krl.writer import write_krl

    if design not in DESIGNS:
        raise InputError("--design", f"{design!r} is not one of {', '.join(DESIGNS)}")
    if not 1 <= n <= 200:
        raise InputError("-n", f"propose 1 to 200 passes, got {n}")
    job = load_job(job_file)
    ctx = CalibrationContext.from_job(job)
    poses = job_test_poses(job)
    job_rpm = job.spindle.rpm
    top = ctx.tool.spindle_speed_max * 60 / (2 * np.pi) if ctx.tool.spindle_speed_max else 3 * job_rpm
    rpm = rpm or (0.5 * job_rpm, min(1.5 * job_rpm, top))
    ap_mm = ap_mm or (0.5, job.engagement.ap_mm or 8.0)
    ae = ae_mm or job.engagement.ae_mm or ctx.tool.radius * 1e3
    milling = job.engagement.milling if job.engagement.milling != "slot" else "down"
    if design == "identification":
        planned = identification_cuts(ctx, poses, n, rpm=rpm[1], ae_mm=(2 * ctx.tool.radius * 1e3,),
                                      ap_mm=(ap_mm[0], (ap_mm[0] + ap_mm[1]) / 2), milling="slot",
                                      feeds="ends")
        from planner.calibrate.design_bound import FORCE_NOISE_N, FORCE_NOISE_REL, coefficient_bound

        bound = coefficient_bound(planned, ctx.tool, ctx.material.coefficients())
        how = (f"identification slots; the fit's best 1σ at {FORCE_NOISE_N:g} N + "
               f"{100 * FORCE_NOISE_REL:g} % force noise "
               "(Cramér–Rao, docs/calibration.md): "
               + ", ".join(f"{name} {100 * b:.1f} %" for name, b in zip(COEFFICIENT_NAMES, bound,
                                                                      strict=True)))
    elif design == "along-job":
        planned, how = _along_job(job, ctx, n, records, ap_mm, seed, progress)
    else:
        boundary = None
        if records:
            try:
                boundary = fit_boundary(ctx, load_records(*records), progress=progress)
            except FitRefused as e:
                how = f"space-filling (no boundary yet: {e.reason})"
        if boundary is not None:
            planned = propose_cuts(ctx, boundary, poses, n, rpm, ap_mm, ae, milling=milling)
            how = "value of information on the current boundary"
        else:
            planned = boundary_cuts(ctx, poses, n, rpm, ap_mm, ae, milling=milling, seed=seed)
            how = how if records else "space-filling (no records given)"
    out = Path(out_dir)
    from planner.calibrate.records import write_records

    files = [write_records(out / "planned.jsonl", planned)]
    spec, sections, moves = krl_program(ctx, planned)
    files += write_krl(spec, sections, moves, out)
    simulated = None
    if truth_file is not None:
        truth = load_truth(truth_file, CalibrationContext.nominal_of(job_file))
        simulated = tuple(run_cuts(truth, list(planned), seed=seed, progress=progress))
        files.append(write_records(out / "records.jsonl", simulated))
    return TestCutsResult(tuple(planned), how, tuple(files), simulated)


def _along_job(job, ctx: CalibrationContext, n: int, records, ap_mm, seed: int, progress: bool
               ) -> tuple[list[CutRecord], str]:
    """Passes imitating the job's planned sections: value of information on the boundary the
    records give, else a space-filling start (see :func:`testcuts`)."""
    from planner.calibrate.testcuts import along_job_cuts, propose_along_job, section_templates
    from planner.plan import plan_job, plan_of_result

    templates = section_templates(plan_of_result(plan_job(job, progress=progress)), job.tool.name)
    if not templates:
        raise InputError("--design along-job", "the job's plan has no cut section to imitate")
    deepest = max(r.ap_mm for r in templates)
    span = ap_mm or (max(0.5, 0.2 * deepest), 1.2 * deepest)
    if records:
        try:
            boundary = fit_boundary(ctx, load_records(*records), progress=progress)
        except FitRefused as e:
            return (along_job_cuts(templates, n, span, seed=seed),
                    f"space-filling along the job (no boundary yet: {e.reason})")
        every = max(1, len(templates) // 40)   # some 40 sections x the depth grid
        return (propose_along_job(ctx, boundary, templates, n, span, every=every),
                "value of information along the job's sections")
    return along_job_cuts(templates, n, span, seed=seed), "space-filling along the job's sections"
