"""Motion records of the APT/CL interpreter (private): ``GOTO``, ``GODLTA``, ``FROM``, ``RAPID``,
``TLAXIS``, ``MULTAX`` and ``CIRCLE`` with the arc its end point ``GOTO`` closes; conventions in
:mod:`robot_io.apt.reader`."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from robot_io.apt import _records as rc
from robot_io.apt._cycles import hole
from robot_io.apt._frames import direction, point, vector
from robot_io.options import fix
from robot_io.toolpath import MoveKind

if TYPE_CHECKING:
    from robot_io.apt._interp import Run

__all__ = ["circle_", "from_", "godlta", "goto", "multax", "orphan_circle", "rapid_", "tlaxis"]


def goto(run: Run, rec: rc.Record) -> None:
    circle, run.circle = run.circle, None   # a malformed end GOTO takes its CIRCLE along
    vals = run.numbers(rec, (3, 6), "3 numbers (x,y,z) or 6 (x,y,z,i,j,k)")
    p = point(run, vals)
    if len(vals) == 6:
        run.axis = direction(run, vals, 3, "tool axis i,j,k")
    if circle is not None:
        _arc(run, rec, p, circle)
    elif run.cycle is not None:
        run.rapid = False
        hole(run, rec, p)
    else:
        kind = MoveKind.RAPID if run.rapid else MoveKind.LINEAR
        run.rapid = False
        run.emit(rec, kind, p, None if kind == MoveKind.RAPID else run.move_feed(rec))


def godlta(run: Run, rec: rc.Record) -> None:
    """``GODLTA/d`` (d along the tool axis) or ``GODLTA/dx,dy,dz``: a move by a delta."""
    vals = run.numbers(rec, (1, 3), "1 number (a distance along the tool axis) or 3 (dx,dy,dz)")
    if run.pos is None:
        run.bad(None, "GODLTA from an unknown position: it moves by a delta from where the tool "
                f"is; add a GOTO or FROM before it, or {rc.fix_or_skip()}")
    if run.cycle is not None:
        run.bad(None, f"GODLTA inside a drilling cycle (CYCLE at line {run.cycle['line']}): "
                f"end the cycle with CYCLE/OFF first, or {rc.fix_or_skip()}")
    if len(vals) == 1:
        a = run.axis if run.axis is not None else (0.0, 0.0, 1.0)
        d = vals[0] * run.length_scale()
        delta = (d * a[0], d * a[1], d * a[2])
    else:
        delta = vector(run, vals)
    s = run.pos
    p = (s[0] + delta[0], s[1] + delta[1], s[2] + delta[2])   # type: ignore[index]
    kind = MoveKind.RAPID if run.rapid else MoveKind.LINEAR
    run.rapid = False
    run.emit(rec, kind, p, None if kind == MoveKind.RAPID else run.move_feed(rec))


def from_(run: Run, rec: rc.Record) -> None:
    vals = run.numbers(rec, (3, 6), "3 numbers (x,y,z) or 6 (x,y,z,i,j,k)")
    run.pos = point(run, vals)
    if len(vals) == 6:
        run.axis = direction(run, vals, 3, "tool axis i,j,k")


def rapid_(run: Run, rec: rc.Record) -> None:
    if run.fields(rec):
        run.bad(rec.args_at, f"RAPID takes no arguments; {rc.fix_or_skip()}")
    run.rapid = True


def tlaxis(run: Run, rec: rc.Record) -> None:
    vals = run.numbers(rec, (3,), "3 numbers (i,j,k)")
    run.axis = direction(run, vals, 0, "tool axis i,j,k")


def multax(run: Run, rec: rc.Record) -> None:
    toks = run.tokens(rec)
    if toks and toks[0][0] not in ("ON", "OFF"):
        run.bad(run.field_offset(rec, 0), f"MULTAX takes ON or OFF; {rc.fix_or_skip()}")
    run.meta["multax"] = not toks or toks[0][0] == "ON"


def circle_(run: Run, rec: rc.Record) -> None:
    fields = run.fields(rec)
    turns = 0
    if len(fields) >= 2 and fields[-2].upper() == "TIMES":
        n = run.number(rec, fields[-1], len(fields) - 1)
        if n != int(n) or not 1 <= n <= rc.MAX_ARC_TURNS:
            run.bad(run.field_offset(rec, len(fields) - 1), f"CIRCLE TIMES must be an "
                    f"integer 1…{rc.MAX_ARC_TURNS}, got {n:g}; {rc.fix_or_skip()}")
        turns = int(n) - 1
        run.warn(rec.col, "helix_turns", f"CIRCLE …,TIMES,{int(n)} read as {turns} extra "
                 "full turn(s) beyond the sweep from start to end; check the helix")
        fields = fields[:-2]
    if len(fields) not in (6, 11):
        at = (run.field_offset(rec, 11) if len(fields) > 11
              else len(rec.text.rstrip(" \t")))
        for i, f in enumerate(fields):
            run.number(rec, f, i)
        run.bad(at, f"CIRCLE takes 6 numbers (xc,yc,zc,i,j,k) or 11 (…,r,tol,ratio,"
                f"diameter,corner) plus an optional TIMES,n; got {len(fields)}; {rc.fix_or_skip()}")
    vals = [run.number(rec, f, i) for i, f in enumerate(fields)]
    centre = point(run, vals)
    axis = direction(run, vals, 3, "circle axis i,j,k")
    if _clockwise(run, rec, len(vals)):
        axis = (-axis[0], -axis[1], -axis[2])   # clockwise about i,j,k = counter-clockwise about −i,j,k
    radius = None
    if len(vals) == 11:
        radius = vals[6] * run.scale
        if not radius > 0:
            run.bad(run.field_offset(rec, 6), f"CIRCLE radius must be positive; {rc.fix_or_skip()}")
    run.circle = (rec, centre, axis, radius, turns)


def _clockwise(run: Run, rec: rc.Record, n_fields: int) -> bool:
    """Whether the CIRCLE turns clockwise about its i,j,k (the reader docstring's evidence):
    ``circle_direction`` when given, else by layout — 11 fields (NX) clockwise, 6 (SolidWorks
    CAM) counter-clockwise — unless the file's setup frame is the other system's (a 6-field
    CIRCLE after an NX ``MSYS``, an 11-field one after a SolidWorks ``CSYS``): no sample decides
    that, so it is refused."""
    rule = run.opts.circle_direction
    if rule == "auto":
        rule = "cw" if n_fields == 11 else "ccw"
        other = "CSYS" if n_fields == 11 else "MSYS"
        frame = next((f for f in run.meta["frames"] if f["record"] == other), None)
        if frame is not None:
            run.bad(run.field_offset(rec, 3), f"CIRCLE with {n_fields} fields after the "
                    f"{other} at line {frame['line']}: the {n_fields}-field layout is "
                    f"{'NX' if n_fields == 11 else 'SolidWorks CAM'}'s ("
                    f"{'clockwise' if rule == 'cw' else 'counter-clockwise'} about i,j,k) but "
                    f"{other} is {'SolidWorks CAM' if other == 'CSYS' else 'NX'}'s, and no sample "
                    "shows which way such an arc turns; check the arcs join the moves around "
                    f"them and state the direction ({fix('circle_direction', 'ccw')} or "
                    f"{fix('circle_direction', 'cw')}), or {rc.fix_or_skip()}",
                    "circle_direction_unknown")
    run.circle_directions[rule] += 1
    return rule == "cw"


def _arc(run: Run, rec: rc.Record, end: rc.Vec, circle: tuple) -> None:
    crec, c, n, radius, turns = circle
    run.rapid = False
    start = run.pos
    if start is None:
        run.pos = end
        run.bad(None, "CIRCLE from an unknown position: the arc needs its start point; "
                f"add a GOTO or FROM before it, or read leniently ({fix('strict', False)})",
                "bad_arc", crec)
    s = start
    h = (s[0] - c[0]) * n[0] + (s[1] - c[1]) * n[1] + (s[2] - c[2]) * n[2]
    c = (c[0] + h * n[0], c[1] + h * n[1], c[2] + h * n[2])   # centre in the start plane
    rs = _radius(s, c, n)
    re_ = _radius(end, c, n)
    tol = max(run.opts.arc_radius_tol, run.opts.arc_radius_rtol * rs)
    s_mm = 1.0 / run.scale
    unit = "mm" if run.scale == rc.MM else "in"
    if rs < rc.ARC_MIN_RADIUS:
        run.pos = end
        run.bad(None, "CIRCLE centre coincides with the arc's start point (zero radius); "
                f"fix the centre, or {rc.fix_or_skip()}", "bad_arc", crec)
    for what, r in ((f"end point (GOTO at line {rec.line})", re_),
                    ("given radius", radius)):
        if r is not None and abs(r - rs) > tol:
            run.pos = end
            wider = float(f"{abs(r - rs) * 1.1:.2g}")
            run.bad(None, f"CIRCLE {what} is off the circle: radius {r * s_mm:.6g} {unit} "
                    f"against {rs * s_mm:.6g} {unit} at the start (tolerance "
                    f"{tol * s_mm:.3g} {unit}); fix the centre or the end point, or widen the "
                    f"tolerance ({fix('arc_radius_tol', wider)}), or read leniently "
                    f"({fix('strict', False)}) to skip the arc", "arc_off_circle", crec)
    ref = run.axis if run.axis is not None else (0.0, 0.0, 1.0)
    if n[0] * ref[0] + n[1] * ref[1] + n[2] * ref[2] < 0:
        kind, normal = MoveKind.ARC_CW, (-n[0], -n[1], -n[2])
    else:
        kind, normal = MoveKind.ARC_CCW, n
    run.emit(crec, kind, end, run.move_feed(crec), arc=(c, normal, turns))


def orphan_circle(run: Run, found: str) -> None:
    """The pending ``CIRCLE`` was not followed by its ``GOTO`` (``found`` says what came)."""
    crec = run.circle[0]   # type: ignore[index]
    run.circle = None
    run.bad(None, f"CIRCLE is not followed by its end point GOTO (found {found}); the arc "
            f"ends at the GOTO right after the CIRCLE — add it, or {rc.fix_or_skip()}",
            category="circle_without_goto", rec=crec)


def _radius(p: rc.Vec, c: rc.Vec, n: rc.Vec) -> float:
    d = (p[0] - c[0], p[1] - c[1], p[2] - c[2])
    a = d[0] * n[0] + d[1] * n[1] + d[2] * n[2]
    return math.sqrt(max(d[0] * d[0] + d[1] * d[1] + d[2] * d[2] - a * a, 0.0))
