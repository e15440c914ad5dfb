"""A plan → KUKA KRL: the planner's samples and sections as the KRL writer's plain moves.

:func:`plan_to_krl` turns a plan (:class:`planner.plan_file.Plan`, SI) into :mod:`robot_io.krl`'s types;
:func:`export_plan` also writes the files (atomically, all or nothing). What is emitted:

* the BCO run to the first sample's joint angles (``q_rad[0]``), as a joint-space PTP;
* per plan section (in order; the fold titles, feed names and comments number them 1, 2, … as
  plan.json, the report and the supervisor's log do): its
  feed as ``$VEL.CP`` [m/s], rounded **down** to :data:`FEED_RESOLUTION_M_S` (exactly, on the
  float's decimal value) so the ``.dat`` literal stays short and the feed never exceeds the plan's;
  then one LIN to every
  sample of the section — the first sample included, so the first LIN after the BCO PTP goes to
  where the PTP already is (a null move that fixes the Cartesian start);
* a *feed profile* (a plan whose samples' feeds vary inside a section, ``--method optimize``):
  the section's ``.dat`` feed is its planned feed (the section optimiser's, under every ceiling of
  the section), and ``$VEL.CP = NAME_F003 * 1.083100`` is written
  before a move only where the profile leaves the band of :data:`PROFILE_STEP` (2 %) above the
  speed last written: each run of moves runs at the lowest profiled speed of the samples its
  moves reach (their targets and, for a CIRC, the samples it absorbs), rounded down to the
  scale's 1e-6 grid, so no sample is reached faster than planned and no move runs more than
  :data:`PROFILE_STEP` below its samples' profile; arcs are cut into CIRCs where the profile leaves
  that band too. Retuning a section's ``.dat`` value scales its whole profile;
* a run of samples of one arc move inside one section (``arc`` true, same ``move``) becomes CIRC
  moves when its points lie on one circle to :data:`CIRC_FIT_TOL` and the tool axis stays within
  :data:`CIRC_AXIS_TOL_DEG` (helices, 5-axis arcs and compensated paths do not, and stay LINs —
  the samples already are chords within the job's chord tolerance). Inside a CIRC the controller
  interpolates the orientation from start to end, so the rotation about the tool axis at the
  absorbed samples is the controller's, not the plan's:
  pieces of at most :data:`CIRC_MAX_SWEEP_DEG`, the auxiliary point the middle sample, the end the
  last; pieces shorter than :data:`CIRC_MIN_SWEEP_DEG` stay LINs;
* rapid sections as LIN at the plan's feed for them (or :data:`RAPID_FEED_M_S` when it has none):
  a Cartesian PTP would need the status and turn bits, which the plan does not carry;
* ``--compensate-deflection``: every position minus the predicted static deflection
  ``deflection_wp_m`` (mirror compensation, docs/model.md §7), orientations unchanged; the program's comment
  header says so. Air and rapid samples without a prediction (NaN) are not moved.

Plans whose solve did not converge (``solver.success`` false) are refused: an unconverged
optimisation never reaches the controller.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path
from typing import Any

import numpy as np

from models.errors import CctmillError
from planner.plan_file import KINDS, Plan, load_plan
from robot_io.krl import (
    CONTROLLERS,
    KrlFrame,
    KrlMove,
    KrlProgramSpec,
    KrlSection,
    render_krl,
    sanitize_identifier,
    write_krl,
)
from robot_io.krl.frames import circle_through, x_axes

__all__ = [
    "CIRC_AXIS_TOL_DEG",
    "CIRC_FIT_TOL",
    "CIRC_MAX_SWEEP_DEG",
    "CIRC_MIN_SWEEP_DEG",
    "FEED_RESOLUTION_M_S",
    "PROFILE_STEP",
    "RAPID_FEED_M_S",
    "ExportError",
    "KrlProgram",
    "export_plan",
    "krl_summary",
    "plan_to_krl",
]

#: Feeds are written to this resolution [m/s] (1 nm/s = 0.000001 mm/s), rounded down so the
#: written feed never exceeds the plan's; a KRL REAL (32-bit) holds about 7 significant digits,
#: i.e. ~1e-10 m/s at 2 mm/s, so nothing the controller can use is lost.
FEED_RESOLUTION_M_S = 1e-9
#: A feed profile's written speed is renewed where the profile rises above (1 + this) × the
#: speed in force or falls below it [-]: fewer ``$VEL.CP`` lines against at most this much slower
#: moves (2 %: a new statement every few millimetres where the profile ramps).
PROFILE_STEP = 0.02
#: Steps of a feed scale per unit (its decimals: robot_io.krl.writer.SCALE_DECIMALS).
_SCALE_STEPS = 10**6
#: Path speed of rapid sections without a planned feed [m/s] (the KUKA posts' default $VEL.CP).
RAPID_FEED_M_S = 0.2
#: Samples of an arc run must lie this close to the fitted circle [m] to become a CIRC.
CIRC_FIT_TOL = 1e-6
#: Largest sweep of one CIRC [deg]; longer arcs are cut into pieces.
CIRC_MAX_SWEEP_DEG = 180.0
#: The tool axis must stay within this of its start along an arc run [deg] for a CIRC (the
#: controller interpolates the orientation between the CIRC's start and end only).
CIRC_AXIS_TOL_DEG = 0.1
#: Smallest sweep of a CIRC [deg]; below it the arc stays LINs (a CIRC over a tiny angle is
#: nearly collinear and its circle is ill-defined after rounding to 0.1 µm).
CIRC_MIN_SWEEP_DEG = 1.0

_MM = 1e3
#: Feed resolution steps per m/s (the integer form of :data:`FEED_RESOLUTION_M_S`).
_STEPS_PER_M_S = 10**9


class ExportError(CctmillError):
    """A plan cannot be exported as it is (the message says why and what to do)."""


@dataclass(frozen=True)
class KrlProgram:
    """A plan as the KRL writer's input.

    Attributes:
        spec: the program settings.
        sections: one per plan section, in order.
        moves: the motions.
        notes: comment lines for every ``.src`` (compensation).
        sample_of_move: for each move, the plan sample its target is (``-1``: none).
        move_feeds: for each move, the ``$VEL.CP`` it runs at [m/s] (its section's feed, or that
            times its run's scale: what the KRL reader reads back, exactly).
    """

    spec: KrlProgramSpec
    sections: tuple[KrlSection, ...]
    moves: tuple[KrlMove, ...]
    notes: tuple[str, ...]
    sample_of_move: tuple[int, ...]
    move_feeds: tuple[float, ...] = ()


#: Toolpath warning kinds listed in the program's comment header (the rest: plan.json).
_WARNING_COMMENTS = 8

def _feed_m_s(feed: float, kind: str) -> float:
    """The section's ``$VEL.CP`` [m/s]: the planned feed rounded down to whole resolution steps,
    exactly (on the float's own decimal value, so 0.005 stays 0.005), as the nearest float to
    that decimal (so the ``.dat`` literal is short and exact)."""
    v = float(feed)
    if kind == "rapid" and not (math.isfinite(v) and v > 0):
        return RAPID_FEED_M_S
    if not math.isfinite(v):
        return v             # the writer refuses it with the section's number
    k = math.floor(Fraction(v) * _STEPS_PER_M_S)
    return k / _STEPS_PER_M_S if k > 0 else v


def _profile_runs(need: np.ndarray, base: float) -> tuple[list[float | None], list[float]]:
    """A section's moves' scales (``None``: keep the speed in force) and the speed each runs at
    [m/s], for the lowest speed ``need`` [m/s] each move may run at (module docstring)."""
    scales: list[float | None] = []
    feeds: list[float] = []
    i, n = 0, need.size
    while i < n:
        lo = hi = float(need[i])
        j = i + 1
        while j < n and max(hi, need[j]) <= min(lo, need[j]) * (1.0 + PROFILE_STEP):
            lo, hi = min(lo, float(need[j])), max(hi, float(need[j]))
            j += 1
        k = max(1, math.floor(Fraction(lo) / Fraction(base) * _SCALE_STEPS))
        while k > 1 and base * (k / _SCALE_STEPS) > lo:     # the double product, as read back
            k -= 1
        scale = k / _SCALE_STEPS
        scales += [scale] + [None] * (j - i - 1)
        feeds += [base * scale] * (j - i)
        i = j
    return scales, feeds


def _arc_moves(p: np.ndarray, abc: np.ndarray, start: int,
               stop: int) -> list[tuple[int, int]] | None:
    """Moves ``(aux, end)`` (sample indices; ``aux == -1`` for a LIN) along the arc run whose
    points are ``p[start..stop]`` (``start`` the sample before the run), or ``None`` when the
    points are not on one circle or the tool axis turns along them."""
    n = stop - start
    if n < 2:
        return None
    x = x_axes(abc[start:stop + 1])
    if np.degrees(np.arccos(np.clip(x @ x[0], -1.0, 1.0))).max() > CIRC_AXIS_TOL_DEG:
        return None
    idx = (start, start + max(1, n // 3), start + max(2, (2 * n) // 3))
    try:
        centre, normal = circle_through(p[idx[0]], p[idx[1]], p[idx[2]])
    except ValueError:
        return None
    rel = p[start:stop + 1] - centre
    in_plane = rel - np.outer(rel @ normal, normal)
    radius = float(np.linalg.norm(in_plane[0]))
    if (np.abs(rel @ normal).max() > CIRC_FIT_TOL
            or np.abs(np.linalg.norm(in_plane, axis=1) - radius).max() > CIRC_FIT_TOL):
        return None
    u = in_plane[0] / radius
    theta = np.unwrap(np.arctan2(in_plane @ np.cross(normal, u), in_plane @ u))
    if np.any(np.diff(theta) <= 0):      # not monotonic about the normal: not one arc
        return None
    out: list[tuple[int, int]] = []
    max_sweep, min_sweep = math.radians(CIRC_MAX_SWEEP_DEG), math.radians(CIRC_MIN_SWEEP_DEG)
    a = 0
    while a < n:
        b = a + 1
        while b + 1 <= n and theta[b + 1] - theta[a] <= max_sweep:
            b += 1
        if b - a >= 2 and theta[b] - theta[a] >= min_sweep:
            out.append((start + (a + b) // 2, start + b))
            a = b
        else:
            out.append((-1, start + a + 1))
            a += 1
    return out


def _check_krl_robot(robot: str, where: str) -> None:
    """Refuse a plan for a robot whose data file names a maker other than KUKA (KRL runs on KUKA
    controllers only). A plan naming no robot, or one not shipped, is left to the writer."""
    # here, not at the top: reading a plan and writing KRL load no physics (models.robot
    # imports CasADi and pinocchio); robot_data itself parses only the TOML
    from models.robot import DEFAULT_VENDOR, available_robots, robot_data

    if not robot or robot not in available_robots():
        return
    vendor = robot_data(robot).vendor
    if vendor != DEFAULT_VENDOR:
        raise ExportError(f"{where}: the plan is for {robot}, whose controller is {vendor!r}, "
                          f"not KUKA: KRL runs on KUKA controllers only and no {vendor} program "
                          "writer ships; plan the job for a KUKA robot to export KRL (cctmill "
                          "robots lists each robot's vendor)")


def plan_to_krl(plan: Plan | str | os.PathLike, name: str | None = None,
                controller: str = "krc4", compensate: bool = False,
                override_hook: str = "none", base_index: int | None = None,
                tool_index: int | None = None, apo_cdis_mm: float = 0.1,
                advance: int = 3) -> KrlProgram:
    """The plan as KRL writer input (see the module docstring).

    Args:
        plan: a loaded plan, or the path of ``plan.json`` or its folder.
        name: program name (a KRL module name); default: the job name made into one.
        controller: ``"krc2"`` or ``"krc4"``.
        compensate: mirror-compensate the predicted static deflection.
        override_hook: ``"none"``, ``"kvp"`` or ``"rsi"`` (see ``robot_io.krl``).
        base_index: write ``$BASE = BASE_DATA[n]`` instead of the plan's frame literal.
        tool_index: write ``$TOOL = TOOL_DATA[n]`` instead of the plan's frame literal.
        apo_cdis_mm: approximation distance ``$APO.CDIS`` [mm].
        advance: ``$ADVANCE``.

    Raises:
        ExportError: the plan is unconverged or inconsistent, or for a robot that is not a
            KUKA (its data file's ``vendor``); ``robot_io.krl.KrlError`` for what KRL cannot
            hold.
    """
    if not isinstance(plan, Plan):
        plan = load_plan(plan)
    smp, where = plan.samples, plan.label
    _check_krl_robot(plan.robot, where)
    if plan.limits.compensate_deflection and not compensate:
        raise ExportError(f"{where}: the plan holds the deflection tolerance for a compensated "
                          "path only ([export] compensate_deflection = true: u·|δ| plus the change "
                          "of δ along a LIN); export it with --compensate-deflection, or re-plan "
                          "without compensation")
    if plan.solver.success is False:
        raise ExportError(f"{where}: the plan's solve did not converge (status "
                          f"{plan.solver.status!r}); re-plan the job (e.g. --method thesis) — "
                          "an unconverged plan is never exported")
    n = len(smp)
    pos = np.asarray(smp.position_wp, float).copy()
    abc = np.degrees(np.asarray(smp.abc_wp, float))
    kinds = np.asarray(smp.kind)
    notes: list[str] = []
    if compensate:
        d = np.asarray(smp.deflection_wp, float)
        bad = ~np.all(np.isfinite(d), axis=1)
        cut_bad = np.flatnonzero(bad & (kinds == KINDS.index("cut")))
        if cut_bad.size:
            raise ExportError(f"{where}: no predicted deflection at cut sample "
                              f"{int(cut_bad[0])}; export without --compensate-deflection or "
                              "re-plan")
        pos -= np.where(bad[:, None], 0.0, d)
        dmax = float(np.nanmax(np.linalg.norm(np.where(bad[:, None], 0.0, d), axis=1))) if n else 0.0
        notes.append(f"path pre-compensated: every position minus the predicted static "
                     f"deflection (mirror, docs/model.md §7); largest shift {dmax * _MM:.4f} mm")
    if not (np.all(np.isfinite(pos)) and np.all(np.isfinite(abc))):
        i = int(np.flatnonzero(~np.all(np.isfinite(np.hstack([pos, abc])), axis=1))[0])
        raise ExportError(f"{where}: sample {i} has no finite pose; re-plan the job")
    q0 = np.degrees(np.asarray(smp.q, float)[0]) if n else np.full(6, np.nan)
    secs = plan.sections
    hook_len = 4 if override_hook != "none" else 0
    digits = max(3, len(str(len(secs))))
    limit = 24 - max(2 + digits, 4, hook_len)
    prog = name if name is not None else sanitize_identifier(plan.job_name or "job", max_len=limit)
    arc = np.asarray(smp.arc, bool)
    move_id = np.asarray(smp.move)
    pose = np.hstack([pos * _MM, abc])
    sections: list[KrlSection] = []
    moves: list[KrlMove] = []
    sample_of: list[int] = []
    move_feeds: list[float] = []
    feed = np.asarray(smp.feed, float)
    expect = 0
    for k, sec in enumerate(secs):
        a, b = sec.sample_start, sec.sample_stop
        if a != expect or b <= a or b > n:
            raise ExportError(f"{where}: section {sec.number} covers samples "
                              f"{a}..{b}, expected to start at {expect} and end by {n}; the "
                              "sections must partition the samples")
        expect = b
        place = ""
        if sec.line_start is not None:
            place = f"source lines {sec.line_start}-{sec.line_end}"
            if sec.file:
                place += f" of {os.path.basename(sec.file)}"
        extra = []
        for v, label, unit in ((sec.margin, "margin", "N/m"), (sec.force_max, "F max", "N"),
                               (None if sec.deflection_max is None else sec.deflection_max * _MM,
                                "defl max", "mm")):
            if v is not None and math.isfinite(v):
                extra.append(f"{label} {v:.4g} {unit}")
        comment = "; ".join(x for x in (f"plan section {sec.number}", place, ", ".join(extra)) if x)
        base = _feed_m_s(sec.feed, sec.kind)
        sections.append(KrlSection(base, sec.kind, sec.binding or "", comment))
        first = len(moves)
        f_sec = feed[a:b]
        profiled = bool(math.isfinite(sec.feed) and sec.feed > 0 and np.all(np.isfinite(f_sec))
                        and np.any(f_sec != sec.feed))       # a feed profile: the speed varies
        i = a
        while i < b:
            if arc[i] and i > 0:
                j = i
                lo = hi = feed[i]
                while j + 1 < b and arc[j + 1] and move_id[j + 1] == move_id[i]:
                    if profiled:    # a CIRC runs at one speed: cut the arc where the profile moves
                        lo, hi = min(lo, feed[j + 1]), max(hi, feed[j + 1])
                        if hi > lo * (1.0 + PROFILE_STEP):
                            break
                    j += 1
                pieces = _arc_moves(pos, abc, i - 1, j)
                if pieces is None:          # not one circle: the whole run as LINs
                    pieces = [(-1, e) for e in range(i, j + 1)]
                for aux, end in pieces:
                    if aux < 0:
                        moves.append(KrlMove("LIN", tuple(pose[end]), k))
                    else:
                        moves.append(KrlMove("CIRC", tuple(pose[end]), k, aux=tuple(pose[aux])))
                    sample_of.append(end)
                i = j + 1
                continue
            moves.append(KrlMove("LIN", tuple(pose[i]), k))
            sample_of.append(i)
            i += 1
        if profiled:
            ends = sample_of[first:]
            starts = [sample_of[first - 1] + 1 if first else 0, *(e + 1 for e in ends[:-1])]
            need = np.array([feed[p:e + 1].min() for p, e in zip(starts, ends, strict=True)])
            scales, feeds = _profile_runs(need, base)
            for j, sc in enumerate(scales):
                if sc is not None:
                    m = moves[first + j]
                    moves[first + j] = KrlMove(m.kind, m.target, m.section, m.aux, m.approx, sc)
            move_feeds += feeds
        else:
            move_feeds += [base] * (len(moves) - first)
    if expect != n:
        raise ExportError(f"{where}: the sections end at sample {expect} of {n}")
    if moves and moves[0].kind == "CIRC":      # cannot happen: the first sample is a LIN target
        raise ExportError(f"{where}: the path starts with an arc")
    if moves:
        last = moves[-1]
        moves[-1] = KrlMove(last.kind, last.target, last.section, last.aux, approx=False,
                            feed_scale=last.feed_scale)
    comments = [f"cctmill KRL export of job {plan.job_name} "
                f"(plan method {plan.method}, {len(secs)} sections, {n} samples)",
                f"plan: {where}",
                "poses: TCP in $BASE [mm, deg]; $VEL.CP [m/s]; feeds in the .dat, retune there",
                f"cycle time (planned) {plan.cycle_time:.1f} s at $OV_PRO 100"]
    for g in plan.import_warnings[:_WARNING_COMMENTS]:
        comments.append(f"toolpath warning ({g.kind} x{g.count}): {g.first}: {g.message}")
    if len(plan.import_warnings) > _WARNING_COMMENTS:
        comments.append(f"... {len(plan.import_warnings) - _WARNING_COMMENTS} more kinds of "
                        "toolpath warning: see plan.json import_warnings")
    spec = KrlProgramSpec(
        name=prog, bco_axes_deg=tuple(float(x) for x in q0), controller=controller,
        base=KrlFrame(*plan.frame_mm_deg("base")) if base_index is None else base_index,
        tool=KrlFrame(*plan.frame_mm_deg("tool")) if tool_index is None else tool_index,
        advance=advance, apo_cdis_mm=apo_cdis_mm, override_hook=override_hook,
        comments=tuple(comments))
    return KrlProgram(spec, tuple(sections), tuple(moves), tuple(notes), tuple(sample_of),
                      tuple(move_feeds))


def export_plan(plan_or_path: Plan | str | os.PathLike, outdir: str | os.PathLike,
                name: str | None = None, controller: str = "krc4", compensate: bool = False,
                override_hook: str = "none", **options: Any) -> list[Path]:
    """Write the plan as a KRL program into ``outdir``; return the files written (main ``.src``
    and ``.dat`` first, then the pages). ``options`` go to :func:`plan_to_krl` (``base_index``,
    ``tool_index``, ``apo_cdis_mm``, ``advance``). All or nothing: an error leaves ``outdir``
    as it was."""
    if controller not in CONTROLLERS:
        raise ExportError(f"unknown controller {controller!r}; use one of {', '.join(CONTROLLERS)}")
    prog = plan_to_krl(plan_or_path, name, controller, compensate, override_hook, **options)
    return write_krl(prog.spec, prog.sections, prog.moves, outdir, prog.notes)


def krl_summary(prog: KrlProgram) -> dict[str, Any]:
    """Counts for the CLI: sections, moves by kind, pages."""
    out = render_krl(prog.spec, prog.sections, prog.moves, prog.notes)
    kinds: dict[str, int] = {}
    for m in prog.moves:
        kinds[m.kind] = kinds.get(m.kind, 0) + 1
    return {"sections": len(prog.sections), "moves": len(prog.moves), "by_kind": kinds,
            "pages": len(out.pages), "files": list(out.files)}
