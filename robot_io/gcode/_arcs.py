"""Arcs of the G-code interpreter (private): G2/G3 in G17/G18/G19, I/J/K or R form, helical, ``P``
turns; conventions in :mod:`robot_io.gcode`."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from robot_io.gcode import _words as W
from robot_io.gcode._state import PLANES, UNIT_AXES

if TYPE_CHECKING:
    from robot_io.gcode._interp import _Run

__all__ = ["arc", "arc_skip"]


def arc(run: _Run, code: int, col: int, words: dict, pos: list, rot: dict,
        line_f: float | None) -> None:
    st = run.st
    p, q, n, (lp, lq), lnormal = PLANES[st.plane]
    start = st.pos
    if None in start or None in pos:
        arc_skip(run, col, "arc skipped: it starts from a position not known yet (program "
                 "start, G28/G30 or G53); move there absolutely first", pos, rot,
                 unknown=True)
        return
    sp, sq, ep, eq = start[p], start[q], pos[p], pos[q]
    wn = words.get(lnormal)
    if wn is not None and wn[0] != 0.0:
        run.problem(wn[1], "arc_normal_word", f"{lnormal}{wn[0]:g} on a "
                    f"{W.code_name('G', st.plane)} arc: the offset along the plane normal "
                    f"must be 0 (a helix gives its travel as the axis word, e.g. Z in G17); "
                    f"{W.fix_hint()}", skip="arc_normal_word")
    scale = st.scale
    tol_a, tol_r = run.opts.arc_radius_tol, run.opts.arc_radius_rtol
    if "R" in words:
        r, rcol = words["R"]
        if lp in words or lq in words:
            run.problem(rcol, "arc_format", "arc with both R and I/J/K: use one format",
                        skip="arc_format")
        r *= scale
        dp, dq = ep - sp, eq - sq
        d = math.hypot(dp, dq)
        if d <= W.ARC_MIN_RADIUS:
            arc_skip(run, rcol, "R-format arc with end = start: R cannot describe a full "
                     "circle; use I/J/K", pos, rot)
            return
        half = 0.5 * d
        if abs(r) < half - max(tol_a, tol_r * abs(r)):
            arc_skip(run, rcol, f"R {abs(r) / scale:g} is smaller than half the chord "
                     f"({half / scale:g}): no arc fits; fix R or the end point",
                     pos, rot)
            return
        h = math.sqrt(max(r * r - half * half, 0.0))
        # centre left of the chord (seen along the normal) for a short CCW or long CW arc
        side = (1.0 if code == 30 else -1.0) * (1.0 if r > 0 else -1.0)
        cp = sp + 0.5 * dp - side * h * dq / d
        cq = sq + 0.5 * dq + side * h * dp / d
    else:
        wp, wq = words.get(lp), words.get(lq)
        if wp is None and wq is None:
            arc_skip(run, col, f"arc without centre: give {lp}/{lq} (or R) for "
                     f"{W.code_name('G', st.plane)}", pos, rot)
            return
        if st.arc_absolute:
            if wp is None or wq is None:
                arc_skip(run, col, f"G90.1 (absolute arc centre) needs both {lp} and {lq}",
                         pos, rot)
                return
            cp, cq = wp[0] * scale, wq[0] * scale
        else:
            cp = sp + (wp[0] * scale if wp is not None else 0.0)
            cq = sq + (wq[0] * scale if wq is not None else 0.0)
        r0 = math.hypot(sp - cp, sq - cq)
        r1 = math.hypot(ep - cp, eq - cq)
        if r0 < W.ARC_MIN_RADIUS:
            arc_skip(run, col, "arc of zero radius (centre = start); fix I/J/K", pos, rot)
            return
        tol = max(tol_a, tol_r * r0)
        if abs(r1 - r0) > tol:
            run.problem(col, "arc_radius", f"arc radius differs at start ({r0 / scale:.6g})"
                        f" and end ({r1 / scale:.6g}) by more than the tolerance "
                        f"({tol / scale:.3g}); fix the centre or the end point, or widen "
                        "arc_radius_tol")
    turns = 0
    if "P" in words:
        pv, pcol = words["P"]
        if pv != int(pv) or not 1 <= pv <= W.MAX_ARC_TURNS:
            arc_skip(run, pcol, f"arc P (turns) must be an integer 1…{W.MAX_ARC_TURNS}, "
                     f"got P{pv:g}", pos, rot)
            return
        turns = int(pv) - 1
    center = [0.0, 0.0, 0.0]
    center[p], center[q], center[n] = cp, cq, start[n]
    normal = UNIT_AXES[n]
    if run.kin is not None and not st.tcp:
        t0, c0 = st.rot[run.kin.tilt], st.rot["C"]
        t1, c1 = rot[run.kin.tilt], rot["C"]
        if (t0, c0) != (t1, c1) and t0 is not None and c0 is not None:
            arc_skip(run, col, "arc while the table turns (A/B/C change) in identity "
                     "kinematics is no planar arc in the workpiece frame; turn the "
                     "table in a separate block or use TCP (M428)", pos, rot)
            return
        if t1 is not None and c1 is not None:
            center = list(run.kin.tip((center[0], center[1], center[2]), t1, c1))
            normal = run.kin.rotate_to_workpiece(normal, t1, c1)
    run.emit(code, col, pos, rot, line_f, arc=(tuple(center), normal, turns))


def arc_skip(run: _Run, col: int, reason: str, pos: list, rot: dict,
             unknown: bool = False) -> None:
    """An arc that cannot be built: strict raises (unless only its start is unknown);
    otherwise it is skipped, counted, and the position still moves to its end."""
    if unknown:
        run.skipped["unknown_position"] += 1
        run.warn(col, "unknown_position", reason)
    else:
        run.problem(col, "bad_arc", reason, skip="bad_arc")
    run.st.pos, run.st.rot = pos, rot
    run.last_tip = None
