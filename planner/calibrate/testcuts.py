"""Test cuts: short passes that make the calibration's data (docs/calibration.md).

:func:`identification_cuts` lays out the classic design for the coefficients and the stiffness:
feeds per tooth spread over the tool's range (slope and intercept of the mean forces), two radial
and two axial depths (they separate the six coefficients), at poses spread over the cell (they
separate the joints in the deflections). :func:`pose_cut_frame` gives the cutting frame at a pose
with the tool axis along Y_o. The records are ``planned`` (no verdict yet); a cell, or
:func:`planner.calibrate.truth.run_cuts`, turns them into measured ones.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np
import scipy.optimize

from models.errors import InputError, UnreachablePoseError
from planner.calibrate.context import CalibrationContext
from planner.calibrate.records import CutRecord

__all__ = [
    "IK_TOLERANCE",
    "along_job_cuts",
    "boundary_cuts",
    "identification_cuts",
    "imitate_section",
    "job_test_poses",
    "krl_program",
    "pose_at",
    "pose_cut_frame",
    "propose_along_job",
    "propose_cuts",
    "section_templates",
]

#: Largest TCP position error [m] of a test pose: a test pass is short, a tenth of a millimetre
#: off its intended spot does not matter, a centimetre means the point is out of reach.
IK_TOLERANCE = 1e-4
#: Weight [m] of the tool-axis error against the position error in the pose search.
_AXIS_WEIGHT = 0.3

#: Feeds per tooth of the identification design without a chip-load range in the tool data [mm]
#: (aluminium with a carbide end mill); with one, the design spans the tool's whole range: the edge
#: coefficients are the intercepts at c = 0, and a wide span shortens that extrapolation.
_FZ_DEFAULT_MM = (0.02, 0.12)


def pose_cut_frame(ctx: CalibrationContext, q: np.ndarray,
                   feed_hint: Sequence[float] = (0.0, 1.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """(feed_dir Z_o, radial_dir X_o) in base axes at joints ``q`` [rad]: Y_o along the tool axis
    from the tip towards the spindle (−TCP x, as :mod:`planner.cutting_frame` has it for a
    right-hand cutter turning M03), the feed ``feed_hint`` projected normal to it, X_o = Y_o × Z_o."""
    robot = ctx.load_robot()
    _, rot = robot.pose_function(np.asarray(q, float), np.asarray(ctx.tcp, float))
    axis = -np.asarray(rot, float)[:, 0]
    hint = np.asarray(feed_hint, float)
    z = hint - (hint @ axis) * axis
    if np.linalg.norm(z) < 1e-6:
        raise InputError("feed_hint", "is along the tool axis at this pose; give another")
    z /= np.linalg.norm(z)
    x = np.cross(axis, z)
    return z, x / np.linalg.norm(x)


def pose_at(ctx: CalibrationContext, point: Sequence[float], axis: Sequence[float] = (0, 0, -1),
            seed_deg: Sequence[float] = (0.0, -90.0, 90.0, 0.0, 90.0, 0.0)) -> np.ndarray:
    """Joints [rad] (6,) that put the TCP at ``point`` [m] (base axes) with the tool axis (TCP
    +x) along ``axis``, within the joint limits, nearest the seed [deg] in the least-squares sense.

    Raises:
        UnreachablePoseError: no pose within :data:`IK_TOLERANCE`.
    """
    robot = ctx.load_robot()
    target, a = np.asarray(point, float), np.asarray(axis, float) / np.linalg.norm(axis)
    tcp = np.asarray(ctx.tcp, float)

    def residual(q: np.ndarray) -> np.ndarray:
        p, rot = robot.pose_function(q, tcp)
        return np.concatenate([np.asarray(p, float).ravel() - target,
                               _AXIS_WEIGHT * (np.asarray(rot, float)[:, 0] - a)])

    lo, hi = robot.data.lower + 1e-3, robot.data.upper - 1e-3
    q0 = np.clip(np.radians(np.asarray(seed_deg, float)), lo, hi)
    sol = scipy.optimize.least_squares(residual, q0, bounds=(lo, hi), xtol=1e-12, ftol=1e-12)
    err = float(np.linalg.norm(residual(sol.x)))
    if err > IK_TOLERANCE:
        raise UnreachablePoseError(f"no pose puts the TCP at {np.round(target * 1e3, 1)} mm with "
                                   f"the tool along {np.round(a, 3)} (error {err * 1e3:.2f} mm)")
    return sol.x


def job_test_poses(job, inset_mm: float = 20.0) -> list[tuple[float, ...]]:
    """Test poses [deg] over the job's stock top: its four corners (``inset_mm`` inside) and its
    centre, the tool vertical (−z of the base), in the job's cell."""
    from planner.calibrate.context import CalibrationContext

    ctx = CalibrationContext.from_job(job)
    st = job.engagement.stock
    if st is None or st.box_mm is None:
        raise InputError("[engagement.stock]", "test poses need the job's stock box_mm")
    x0, y0, x1, y1 = st.box_mm
    d = inset_mm
    spots = [((x0 + x1) / 2, (y0 + y1) / 2), (x0 + d, y0 + d), (x1 - d, y0 + d),
             (x1 - d, y1 - d), (x0 + d, y1 - d)]
    base = job.base_frame()
    seed = job.kinematics.seed_joints_deg or (0.0, -90.0, 90.0, 0.0, 90.0, 0.0)
    out = []
    for x, y in spots:
        p = base @ np.array([x * 1e-3, y * 1e-3, st.z_top_mm * 1e-3, 1.0])
        q = pose_at(ctx, p[:3], axis=-base[:3, 2], seed_deg=seed)
        seed = tuple(np.degrees(q))
        out.append(tuple(round(float(v), 4) for v in np.degrees(q)))
    return out


def identification_cuts(ctx: CalibrationContext, poses_deg: Sequence[Sequence[float]], n: int,
                        rpm: float, ae_mm: Sequence[float] = (6.0, 12.0),
                        ap_mm: Sequence[float] = (3.0, 5.0), milling: str = "down",
                        pass_mm: float = 60.0, feeds: str = "spread",
                        fz_min_mm: float | None = None) -> list[CutRecord]:
    """``n`` planned test passes for the coefficient and stiffness fits.

    Feeds per tooth run over the tool's chip-load range (or 0.02-0.12 mm): log-spaced
    (``feeds="spread"``, which also shows whether the force is linear in the chip) or at its two
    ends, alternating (``feeds="ends"``: the D-optimal design for a straight line, which halves the
    edge coefficients' error -- they are intercepts at c = 0, extrapolated from the lowest feed;
    ``fz_min_mm`` below the tool's minimum shortens that extrapolation further). The radial and
    axial depths alternate so that every pair meets low and high feeds; the poses cycle.

    Args:
        ctx: the cell.
        poses_deg: joint angles A1..A6 [deg] of the test positions, each (6,).
        n: number of passes.
        rpm: spindle speed [rev/min]; ae_mm, ap_mm: the depths to alternate [mm].
        milling: up or down; pass_mm: pass length [mm] (its duration follows from the feed).
    """
    if n < 1 or not poses_deg:
        raise InputError("n", "need at least one pass and one pose")
    tool = ctx.tool
    if tool.feed_per_tooth_min is not None and tool.feed_per_tooth_max is not None:
        lo, hi = tool.feed_per_tooth_min * 1e3, tool.feed_per_tooth_max * 1e3
    else:
        lo, hi = _FZ_DEFAULT_MM
    if fz_min_mm is not None:
        if not 0.0 < fz_min_mm < hi:
            raise InputError("fz_min_mm", f"must lie in (0, {hi:g}) mm, the chip-load maximum")
        lo = float(fz_min_mm)
    if feeds == "ends":
        fz = np.where(np.arange(n) % 2 == 0, lo, hi).astype(float)
        order = np.arange(n)     # already alternating low, high
    elif feeds == "spread":
        fz = np.geomspace(lo, hi, n) if n > 1 else np.array([np.sqrt(lo * hi)])
        # Interleave so consecutive passes are far apart in feed (drift does not alias with feed).
        order = np.concatenate([np.arange(0, n, 2), np.arange(1, n, 2)[::-1]])
    else:
        raise InputError("feeds", f"unknown feed design {feeds!r}: spread or ends")
    out = []
    for k, i in enumerate(order):
        q_deg = tuple(float(v) for v in poses_deg[k % len(poses_deg)])
        z, x = pose_cut_frame(ctx, np.radians(q_deg))
        feed_mm_s = float(fz[i] * tool.flutes * rpm / 60.0)
        out.append(CutRecord(
            joints_deg=q_deg, feed_dir=tuple(round(float(v), 6) for v in z),
            radial_dir=tuple(round(float(v), 6) for v in x), ap_mm=float(ap_mm[(k // 2) % len(ap_mm)]),
            ae_mm=float(ae_mm[k % len(ae_mm)]), rpm=float(rpm), feed_mm_s=feed_mm_s,
            milling=milling, tool=tool.name, material=ctx.material.name, verdict="unknown",
            duration_s=pass_mm / feed_mm_s, id=f"T{k + 1:02d}",
            source={"kind": "planned", "design": "identification"}))
    return out


def boundary_cuts(ctx: CalibrationContext, poses_deg: Sequence[Sequence[float]], n: int,
                  rpm: tuple[float, float], ap_mm: tuple[float, float], ae_mm: float,
                  feed_per_tooth_mm: float = 0.1, milling: str = "down", pass_mm: float = 60.0,
                  seed: int = 0) -> list[CutRecord]:
    """``n`` planned passes spread over a_p × rpm (a Latin hypercube, seeded), cycling the poses:
    the first data of a stability boundary, before :func:`propose_cuts` can aim at it."""
    if n < 1 or not poses_deg:
        raise InputError("n", "need at least one pass and one pose")
    rng = np.random.default_rng(seed)
    u = (np.column_stack([rng.permutation(n), rng.permutation(n)]) + rng.random((n, 2))) / n
    out = []
    for k in range(n):
        speed = rpm[0] + u[k, 0] * (rpm[1] - rpm[0])
        depth = ap_mm[0] + u[k, 1] * (ap_mm[1] - ap_mm[0])
        out.append(_planned(ctx, poses_deg[k % len(poses_deg)], depth, ae_mm, speed,
                            feed_per_tooth_mm, milling, pass_mm, f"B{k + 1:02d}", "space-filling"))
    return out


def _planned(ctx: CalibrationContext, q_deg: Sequence[float], ap_mm: float, ae_mm: float | None,
             rpm: float, feed_per_tooth_mm: float, milling: str, pass_mm: float, name: str,
             design: str) -> CutRecord:
    q = tuple(float(v) for v in q_deg)
    z, x = pose_cut_frame(ctx, np.radians(q))
    feed_mm_s = float(feed_per_tooth_mm * ctx.tool.flutes * rpm / 60.0)
    return CutRecord(
        joints_deg=q, feed_dir=tuple(round(float(v), 6) for v in z),
        radial_dir=tuple(round(float(v), 6) for v in x), ap_mm=round(float(ap_mm), 4),
        ae_mm=None if milling == "slot" else float(ae_mm), rpm=round(float(rpm), 1),
        feed_mm_s=round(feed_mm_s, 4), milling=milling, tool=ctx.tool.name,
        material=ctx.material.name, verdict="unknown", duration_s=pass_mm / feed_mm_s, id=name,
        source={"kind": "planned", "design": design})


def propose_cuts(ctx: CalibrationContext, boundary, poses_deg: Sequence[Sequence[float]], n: int,
                 rpm: tuple[float, float], ap_mm: tuple[float, float], ae_mm: float,
                 feed_per_tooth_mm: float = 0.1, milling: str = "down", params=None,
                 grid: int = 7, pass_mm: float = 60.0) -> list[CutRecord]:
    """The ``n`` most informative next passes for the stability boundary (value of information).

    Candidates: every pose × a ``grid`` × ``grid`` lattice of (rpm, a_p). A candidate's value is
    the information its verdict would carry about the boundary's coefficients — for a logistic
    model with a Gaussian posterior, ½ log(1 + p(1 − p) xᵀΣx) with p its predicted P(chatter) and
    xᵀΣx the variance of its logit: largest where the boundary is both near (p ≈ ½) and uncertain
    (after Karandikar et al. 2014, who value a test cut by how much it changes the decision). After
    each pick the posterior is updated as if the cut had been run (Σ⁻¹ += p(1 − p) x xᵀ), so the
    next pick goes where the boundary is still unsure, not to the same spot.

    Args:
        boundary: a fitted :class:`planner.calibrate.fit_boundary.Boundary` (with covariance).
        params: model parameters for the margins (default: the job's).
        Others as :func:`boundary_cuts`.
    """
    from planner.calibrate.fit_boundary import criterion_margin

    if n < 1 or not poses_deg:
        raise InputError("n", "need at least one pass and one pose")
    candidates, features = [], []
    for q_deg in poses_deg:
        for speed in np.linspace(rpm[0], rpm[1], grid):
            for depth in np.linspace(ap_mm[0], ap_mm[1], grid):
                rec = _planned(ctx, q_deg, depth, ae_mm, speed, feed_per_tooth_mm, milling,
                               pass_mm, "candidate", "value of information")
                candidates.append(rec)
                features.append([criterion_margin(ctx, rec, params), rec.ap_mm, rec.rpm])
    return _voi_pick(boundary, candidates, features, n)


def _voi_pick(boundary, candidates: list[CutRecord], features: list[list[float]], n: int,
              ) -> list[CutRecord]:
    """The ``n`` candidates of most value of information, picked one by one with the posterior
    updated as if each pick had been run (see :func:`propose_cuts`)."""
    x = boundary._design(np.asarray(features, float))
    beta = np.concatenate([[boundary.intercept], boundary.coef])
    p = 1.0 / (1.0 + np.exp(-(x @ beta)))
    info = np.linalg.inv(boundary.covariance)
    chosen: list[int] = []
    # One pass per (rpm, a_p): another pose at the same speed and depth says little more.
    keys = [(r.rpm, r.ap_mm) for r in candidates]
    taken: set[tuple[float, float]] = set()
    for _ in range(min(n, len(candidates))):
        cov = np.linalg.inv(info)
        var = np.einsum("ij,jk,ik->i", x, cov, x)
        value = 0.5 * np.log1p(p * (1.0 - p) * var)
        value[[i for i, key in enumerate(keys) if key in taken]] = -np.inf
        best = int(np.argmax(value))
        if not np.isfinite(value[best]):
            break
        taken.add(keys[best])
        chosen.append(best)
        info = info + p[best] * (1.0 - p[best]) * np.outer(x[best], x[best])
    out = []
    for k, i in enumerate(chosen):
        r = candidates[i]
        src = {**r.source, "p_chatter": round(float(p[i]), 4)}
        out.append(replace(r, id=f"V{k + 1:02d}", source=src))
    return out


def section_templates(plan, tool: str) -> list[CutRecord]:
    """One planned record per cut section of a plan (its middle sample's pose, cut frame, a_e,
    a_p, milling and feed; :func:`planner.calibrate.supervisor_records.section_record`): the
    cuts a test pass should imitate when the question is how *this* job's sections behave."""
    from planner.calibrate.supervisor_records import section_record

    out = []
    for i in range(len(plan.sections)):
        r = section_record(plan, i, "unknown", tool)
        if r is not None:
            out.append(replace(r, source={"kind": "planned", "design": "job section",
                                          "section": r.source.get("section")}))
    return out


def along_job_cuts(templates: Sequence[CutRecord], n: int, ap_mm: tuple[float, float],
                   pass_mm: float = 60.0, seed: int = 0,
                   rpm: tuple[float, float] | None = None) -> list[CutRecord]:
    """``n`` passes that imitate the job's own sections (``templates``, spread evenly along the
    path) at axial depths spread over ``ap_mm`` and, with ``rpm``, spindle speeds over that
    range at the section's feed per tooth (a stratified sample, seeded): the space-filling start
    of a boundary for this job's poses, feed directions and engagement."""
    if n < 1 or not templates:
        raise InputError("n", "need at least one pass and one job section")
    rng = np.random.default_rng(seed)
    u = (np.column_stack([rng.permutation(n), rng.permutation(n)]) + rng.random((n, 2))) / n
    idx = np.linspace(0, len(templates) - 1, n).round().astype(int)
    return [imitate_section(templates[i], ap_mm[0] + float(v[0]) * (ap_mm[1] - ap_mm[0]),
                            pass_mm, f"J{k + 1:02d}", "space-filling along the job",
                            None if rpm is None else rpm[0] + float(v[1]) * (rpm[1] - rpm[0]))
            for k, (i, v) in enumerate(zip(idx, u, strict=True))]


def imitate_section(template: CutRecord, ap_mm: float, pass_mm: float, name: str, design: str,
                    rpm: float | None = None) -> CutRecord:
    """A pass like ``template`` at depth ``ap_mm`` (and spindle speed ``rpm``, the feed scaled to
    keep the feed per tooth)."""
    src = {"kind": "planned", "design": design}
    if template.source.get("section") is not None:
        src["section"] = template.source["section"]
    speed = template.rpm if rpm is None else round(float(rpm), 1)
    feed = round(template.feed_mm_s * speed / template.rpm, 4)
    return replace(template, ap_mm=round(float(ap_mm), 4), rpm=speed, feed_mm_s=feed,
                   verdict="unknown", force_n=None, chatter_hz=None, id=name,
                   duration_s=pass_mm / feed, source=src)


def propose_along_job(ctx: CalibrationContext, boundary, templates: Sequence[CutRecord], n: int,
                      ap_mm: tuple[float, float], params=None, grid_mm: float = 0.25,
                      every: int = 1, pass_mm: float = 60.0,
                      rpm: tuple[float, float] | None = None, rpm_grid: int = 5
                      ) -> list[CutRecord]:
    """The ``n`` most informative next passes among the job's own sections (every ``every``-th
    template) at axial depths on a ``grid_mm`` grid over ``ap_mm``, at the job's spindle speed
    and feed (with ``rpm``: at ``rpm_grid`` speeds over that range, the feed per tooth kept):
    value of information as :func:`propose_cuts`, where the planner's question is."""
    from planner.calibrate.fit_boundary import criterion_margin

    if n < 1 or not templates:
        raise InputError("n", "need at least one pass and one job section")
    depths = np.arange(ap_mm[0], ap_mm[1] + grid_mm / 2, grid_mm)
    candidates, features = [], []
    speeds = [None] if rpm is None else list(np.linspace(rpm[0], rpm[1], rpm_grid))
    for t in list(templates)[::max(1, every)]:
        for d in depths:
            margin = None     # the eigen and γ margins do not depend on the spindle speed
            for v in speeds:
                rec = imitate_section(t, d, pass_mm, "candidate",
                                      "value of information along the job", v)
                if margin is None or ctx.criterion == "floquet":
                    margin = criterion_margin(ctx, rec, params)
                candidates.append(rec)
                features.append([margin, rec.ap_mm, rec.rpm])
    return _voi_pick(boundary, candidates, features, n)


def krl_program(ctx: CalibrationContext, planned: Sequence[CutRecord], name: str = "TESTCUTS",
                retract_mm: float = 20.0, approach_mm_s: float = 20.0, controller: str = "krc4"):
    """The test passes as a KRL program (plain types of :mod:`robot_io.krl.spec`).

    Each pass: a joint PTP to the record's pose (the pass's middle, on the stock top), LIN to
    ``retract_mm`` above the pass's start, LIN down to the start at the cutting depth (the tool tip
    ``ap_mm`` below the pose, along the tool axis), the cut along the feed at the record's feed
    (one section per pass, named by the record's id), LIN up. ``$BASE`` is the robot base, the
    ``$TOOL`` the job's TCP. The radial engagement a_e is the operator's to present (a slot needs
    none; for up/down milling the pass must run along a wall of the stock ``ae_mm`` deep).

    Returns:
        (spec, sections, moves) for :func:`robot_io.krl.writer.write_krl`.
    """
    from robot_io.krl.frames import matrix_to_abc
    from robot_io.krl.spec import KrlFrame, KrlMove, KrlProgramSpec, KrlSection

    robot = ctx.load_robot()
    tcp = np.asarray(ctx.tcp, float)
    sections, moves = [], []
    for r in planned:
        p, rot = robot.pose_function(r.q(), tcp)
        p, rot = np.asarray(p, float).ravel(), np.asarray(rot, float)
        axis, feed = rot[:, 0], np.asarray(r.feed_dir, float)
        length = (r.duration_s or 3.0) * r.feed_mm_s * 1e-3
        deep = p + r.ap_mm * 1e-3 * axis
        start, end = deep - feed * length / 2, deep + feed * length / 2
        abc = tuple(float(v) for v in matrix_to_abc(rot))

        def pose(x: np.ndarray, abc=abc) -> tuple[float, ...]:
            return (*(float(v) * 1e3 for v in x), *abc)

        air = len(sections)
        sections.append(KrlSection(approach_mm_s * 1e-3, kind="air", comment=f"to {r.id}"))
        moves += [KrlMove("PTP", tuple(r.joints_deg), air),
                  KrlMove("LIN", pose(start - axis * retract_mm * 1e-3), air, approx=False),
                  KrlMove("LIN", pose(start), air, approx=False)]
        cut = len(sections)
        sections.append(KrlSection(r.feed_mm_s * 1e-3, kind="cut", binding="test cut",
                                   comment=f"{r.id}: {r.milling} ap {r.ap_mm:g} mm"
                                   + (f" ae {r.ae_mm:g} mm" if r.ae_mm else "")
                                   + f", {r.rpm:g} rpm (set the spindle)"))
        moves.append(KrlMove("LIN", pose(end), cut, approx=False))
        back = len(sections)
        sections.append(KrlSection(approach_mm_s * 1e-3, kind="air", comment=f"out of {r.id}"))
        moves.append(KrlMove("LIN", pose(end - axis * retract_mm * 1e-3), back, approx=False))
    spec = KrlProgramSpec(
        name=name, bco_axes_deg=tuple(planned[0].joints_deg), controller=controller,
        base=KrlFrame(), tool=KrlFrame(tuple(float(v) * 1e3 for v in tcp), (0.0, 0.0, 0.0)),
        comments=(f"cctmill test cuts: {len(planned)} passes", "records: planned.jsonl"))
    return spec, sections, moves
