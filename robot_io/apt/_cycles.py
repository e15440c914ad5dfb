"""Drilling cycles of the APT/CL interpreter (private): ``CYCLE`` definitions and the moves of
each hole a ``GOTO`` makes while one is on; conventions in :mod:`robot_io.apt.reader`."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from robot_io.apt import _records as rc
from robot_io.toolpath import MoveKind

if TYPE_CHECKING:
    from robot_io.apt._interp import Run

__all__ = ["NX_DRILL_SUBTYPES", "RETRACT_MODES", "cycle_", "hole"]

#: NX writes peck drilling as ``CYCLE/DRILL,DEEP,…`` and ``CYCLE/DRILL,BRKCHP,…``.
NX_DRILL_SUBTYPES = frozenset({"DEEP", "BRKCHP"})
#: NX's retract modes: ``RTRCTO,AUTO`` (to the RAPTO point), ``RTRCTO,r,MANUAL``.
RETRACT_MODES = frozenset({"AUTO", "MANUAL"})


def cycle_(run: Run, rec: rc.Record) -> None:
    toks = run.tokens(rec)
    if not toks or not isinstance(toks[0][0], str):
        run.bad(run.field_offset(rec, 0), f"CYCLE needs a type (DRILL, DEEP2, …, OFF); "
                f"{rc.fix_or_skip()}")
    kind = toks[0][0]
    if kind == "OFF":
        run.cycle = None
        return
    if kind == "INIT":
        return
    if kind == "ON":
        if run.last_cycle is None:
            run.bad(run.field_offset(rec, 0), f"CYCLE/ON without an earlier cycle "
                    f"definition; {rc.fix_or_skip()}")
        run.cycle = run.last_cycle
        return
    i = 1
    if kind == "DRILL" and len(toks) > 1 and toks[1][0] in NX_DRILL_SUBTYPES:
        kind = toks[1][0]   # NX: CYCLE/DRILL,DEEP,… / CYCLE/DRILL,BRKCHP,… (peck drilling)
        i = 2
    if kind not in rc.DRILL_CYCLES:
        run.cycle = None   # lenient: the GOTOs until CYCLE/OFF are read as plain moves
        run.bad(run.field_offset(rec, 0), f"CYCLE/{rc.short(kind)} is not a drilling cycle this "  # type: ignore[arg-type]
                f"reader expands ({', '.join(sorted(rc.DRILL_CYCLES))}): it may move the tool in "
                f"ways not modelled; {rc.fix_or_skip()}", "unsupported_cycle")
    params: dict[str, float | str] = {}
    feed: tuple[float, bool] | None = None
    while i < len(toks):
        key, idx = toks[i]
        if key in RETRACT_MODES:   # NX: RTRCTO,r,MANUAL — the mode after the value
            i += 1
            continue
        if not isinstance(key, str) or i + 1 >= len(toks):
            run.bad(run.field_offset(rec, idx), f"CYCLE/{kind}: expected keyword,value "
                    f"pairs (FEDTO,depth,MMPM,feed,RAPTO,clearance,RTRCTO,retract); {rc.fix_or_skip()}")
        val = toks[i + 1][0]
        if key in rc.FEED_WORDS:
            if not isinstance(val, float) or not val > 0:
                run.bad(run.field_offset(rec, toks[i + 1][1]), f"CYCLE/{kind}: {key} "
                        f"needs a positive feed; {rc.fix_or_skip()}")
            unit, per_rev = rc.FEED_WORDS[key]
            feed = (val * unit / (1.0 if per_rev else 60.0), per_rev)  # type: ignore[operator]
        elif key == "RTRCTO" and val == "AUTO":
            params.pop(key, None)   # NX: retract to the RAPTO point (as without RTRCTO)
        else:
            params[key] = val
        i += 2
    s = run.length_scale()

    def dist(key: str, default: float | None) -> float | None:
        v = params.get(key, default)
        if isinstance(v, str):
            run.bad(run.field_offset(rec, next(j for t, j in toks if t == key) + 1),
                    f"CYCLE/{kind}: {key} needs a number, got {v!r}; {rc.fix_or_skip()}")
        return None if v is None else float(v) * s

    fedto = dist("FEDTO", None)
    if fedto is None:
        run.bad(run.field_offset(rec, 0), f"CYCLE/{kind} needs FEDTO,depth (measured from the "
                f"hole point against the tool axis); {rc.fix_or_skip()}")
    depth = abs(fedto)   # type: ignore[arg-type]   # > 0 SolidWorks CAM, < 0 NX: the same depth
    if depth == 0:
        run.warn(rec.col, "zero_depth_cycle", f"CYCLE/{kind} has FEDTO 0: each hole is a feed "
                 "from the RAPTO point to the hole point and back, no deeper; check the "
                 "operation's depth")
    if feed is None:
        run.bad(run.field_offset(rec, 0), f"CYCLE/{kind} needs its feed (MMPM,f / IPM,f / "
                f"MMPR,f / IPR,f); {rc.fix_or_skip()}")
    clear = dist("RAPTO", 0.0)
    retract = dist("RTRCTO", None)
    info = {"line": rec.line, "type": kind, "depth_m": depth, "fedto_m": fedto, "rapto_m": clear,
            "rtrcto_m": retract, "feed": feed[0], "feed_per_rev": feed[1],  # type: ignore[index]
            "pecks_ignored": any(w in params for w in rc.PECK_WORDS),
            "dwell_ignored": bool(params.get("DWELL")), "holes": 0}
    run.meta["cycles"].append(info)
    run.cycle = {"type": kind, "depth": depth, "clear": clear,
                 "retract": clear if retract is None else retract, "feed": feed,
                 "line": rec.line, "info": info}
    run.last_cycle = run.cycle


def hole(run: Run, rec: rc.Record, p: rc.Vec) -> None:
    """The moves of one hole of the cycle in force at the hole point ``p`` [m]."""
    cyc = run.cycle
    assert cyc is not None
    a = run.axis if run.axis is not None else (0.0, 0.0, 1.0)
    value, per_rev = cyc["feed"]
    if per_rev:
        if run.rpm is None or not run.spindle_on or run.rpm <= 0:
            run.bad(None, f"CYCLE/{cyc['type']} (line {cyc['line']}) feed per revolution "
                    "but no spindle speed in force: add SPINDL/rpm,RPM,CLW before it",
                    "feed_per_rev_without_spindle")
        feed = value * run.rpm / 60.0   # type: ignore[operator]
    else:
        feed = value
    extra = {"cycle": cyc["type"]}

    def at(d: float) -> rc.Vec:
        return (p[0] + d * a[0], p[1] + d * a[1], p[2] + d * a[2])

    top, clear, bottom = at(cyc["retract"]), at(cyc["clear"]), at(-cyc["depth"])
    for kind, target, f in ((MoveKind.RAPID, top, None), (MoveKind.RAPID, clear, None),
                            (MoveKind.LINEAR, bottom, feed)):
        if run.pos is not None and math.dist(run.pos, target) < rc.CYCLE_POSITION_TOL:
            continue
        run.emit(rec, kind, target, f, axis=a, extra=extra)
    back = cyc["type"] in rc.FEED_RETRACT_CYCLES
    run.emit(rec, MoveKind.LINEAR if back else MoveKind.RAPID, top, feed if back else None,
             axis=a, extra=extra)
    cyc["info"]["holes"] += 1
