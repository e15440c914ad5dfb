"""Modal words of the APT/CL interpreter (private): ``UNITS``, ``FEDRAT``, ``SPINDL``, the tool
records (``CUTTER``, ``TLDATA``, ``LOAD``, ``TOOLNO``, ``SELECT``), ``CUTCOM``, ``PARTNO`` and
``FINI``; conventions in :mod:`robot_io.apt.reader`."""

from __future__ import annotations

from typing import TYPE_CHECKING

from robot_io.apt import _records as rc

if TYPE_CHECKING:
    from robot_io.apt._interp import Run

__all__ = [
    "cutcom",
    "cutter",
    "cutter_length",
    "fedrat",
    "fini",
    "load",
    "partno",
    "select",
    "spindl",
    "tldata",
    "toolno",
    "units_",
]


def units_(run: Run, rec: rc.Record) -> None:
    toks = run.tokens(rec)
    if len(toks) != 1 or toks[0][0] not in rc.UNIT_WORDS:
        run.bad(run.field_offset(rec, 0), f"{rec.word} takes MM or INCHES; {rc.fix_or_skip()}")
    name, scale = rc.UNIT_WORDS[toks[0][0]]  # type: ignore[index]
    if run.units is None:
        run.units = name
    elif name != run.units:
        run.warn(rec.col, "units_changed", f"units change to {name} in mid-file; the "
                 "following records are read in it")
    run.scale = scale
    run.meta["units_declared"].append((rec.line, name))


def fedrat(run: Run, rec: rc.Record) -> None:
    toks = run.tokens(rec)
    nums = [(v, i) for v, i in toks if isinstance(v, float)]
    words = [(v, i) for v, i in toks if isinstance(v, str)]
    if len(nums) != 1:
        run.bad(run.field_offset(rec, nums[1][1]) if len(nums) > 1
                else len(rec.text.rstrip(" \t")),
                f"FEDRAT takes one feed value and at most one unit word (FEDRAT/125.,MMPM or "
                f"FEDRAT/MMPM,125.); {rc.fix_or_skip()}")
    value, vidx = nums[0]
    if not value > 0:   # type: ignore[operator]
        run.bad(run.field_offset(rec, vidx), f"FEDRAT must be positive, got {value:g}; "
                f"{rc.fix_or_skip()}")
    if len(words) > 1:
        run.bad(run.field_offset(rec, words[1][1]), f"FEDRAT takes one unit word, got "
                f"{[w for w, _ in words]}; {rc.fix_or_skip()}")
    if words:
        w, widx = words[0]
        if w not in rc.FEED_WORDS:
            run.bad(run.field_offset(rec, widx), f"FEDRAT unit {rc.short(w)!r} is unknown: "  # type: ignore[arg-type]
                    f"use MMPM, IPM (per minute), MMPR or IPR (per revolution); {rc.fix_or_skip()}")
        unit, per_rev = rc.FEED_WORDS[w]  # type: ignore[index]
    else:
        unit, per_rev = run.length_scale(), False
    si = value * unit if per_rev else value * unit / 60.0   # type: ignore[operator]
    run.feed = (si, per_rev, rec.line)
    run.missing_feed_warned = False


def spindl(run: Run, rec: rc.Record) -> None:
    toks = run.tokens(rec)
    rpm = None
    on = True
    for v, i in toks:
        if isinstance(v, float):
            if rpm is not None or v < 0:
                run.bad(run.field_offset(rec, i), f"SPINDL takes one speed >= 0 "
                        f"(SPINDL/1000,RPM,CLW); {rc.fix_or_skip()}")
            rpm = v
        elif v == "OFF":
            on = False
        elif v in ("RPM", "CLW", "CCLW", "ON"):
            pass
        elif v in ("SFM", "SMM"):
            run.bad(run.field_offset(rec, i), f"SPINDL surface speed ({v}) is not "
                    "supported: give the speed in RPM; " + rc.fix_or_skip())
        else:
            run.bad(run.field_offset(rec, i), f"SPINDL word {rc.short(v)!r} is unknown "
                    f"(RPM, CLW, CCLW, ON, OFF); {rc.fix_or_skip()}")
    if on and rpm is None and run.rpm is None:
        run.bad(run.field_offset(rec, 0), f"SPINDL without a speed and none set before; "
                f"{rc.fix_or_skip()}")
    if rpm is not None:
        run.rpm = rpm
    run.spindle_on = on


def cutter(run: Run, rec: rc.Record) -> None:
    vals = run.numbers(rec, tuple(range(1, 8)), "1 to 7 numbers (d,r,e,f,α,β,h)")
    s = run.length_scale()
    if not vals[0] > 0:
        run.bad(run.field_offset(rec, 0), f"CUTTER diameter must be positive; {rc.fix_or_skip()}")
    run.meta["cutters"].append({
        "line": rec.line, "tool": None, "diameter_m": vals[0] * s,
        "corner_radius_m": vals[1] * s if len(vals) > 1 else 0.0,
        "height_m": vals[6] * s if len(vals) > 6 else None,
        "apt_params": vals, "units": run.units or run.opts.default_units})


def cutter_length(run: Run, rec: rc.Record) -> None:
    vals = run.numbers(rec, (1,), "1 number (a length)")
    key = "flute_length_m" if rec.word == "CSI_SET_FLUTE_LENGTH" else "extension_length_m"
    if run.meta["cutters"]:
        run.meta["cutters"][-1][key] = vals[0] * run.length_scale()


def tldata(run: Run, rec: rc.Record) -> None:
    toks = run.tokens(rec)
    run.meta["cutters"].append({"line": rec.line, "tool": None, "tldata": [v for v, _ in toks],
                                "units": run.units or run.opts.default_units})


def _tool_number(run: Run, rec: rc.Record, v: float | str, idx: int) -> int:
    if not isinstance(v, float) or v != int(v) or not 0 <= v < 1e9:
        run.bad(run.field_offset(rec, idx), f"{rec.word}: tool number must be an integer "
                f">= 0; {rc.fix_or_skip()}")
    return int(v)   # type: ignore[arg-type]


def load(run: Run, rec: rc.Record) -> None:
    toks = run.tokens(rec)
    if len(toks) < 2 or toks[0][0] != "TOOL":
        run.bad(run.field_offset(rec, 0), f"LOAD takes TOOL,n; {rc.fix_or_skip()}")
    run.tool = _tool_number(run, rec, toks[1][0], toks[1][1])
    for c in reversed(run.meta["cutters"]):
        if c["tool"] is None:
            c["tool"] = run.tool
        else:
            break


def toolno(run: Run, rec: rc.Record) -> None:
    toks = run.tokens(rec)
    if not toks:
        run.bad(None, f"TOOLNO takes a tool number; {rc.fix_or_skip()}")
    run.tool = _tool_number(run, rec, toks[0][0], toks[0][1])


def select(run: Run, rec: rc.Record) -> None:
    toks = run.tokens(rec)
    if len(toks) >= 2 and toks[0][0] == "TOOL":
        run.meta["selected_tools"].append(_tool_number(run, rec, toks[1][0], toks[1][1]))


#: The words a CUTCOM record may carry besides numbers (register, distance).
_CUTCOM_WORDS = frozenset({"LEFT", "RIGHT", "OFF", "ON", "ADJUST", "XYPLAN", "YZPLAN", "ZXPLAN"})


def cutcom(run: Run, rec: rc.Record) -> None:
    toks = run.tokens(rec)
    for v, i in toks:
        if isinstance(v, str) and v not in _CUTCOM_WORDS:
            run.bad(run.field_offset(rec, i), f"CUTCOM word {rc.short(v)!r} is unknown (LEFT, "
                    f"RIGHT, OFF, ON, ADJUST, XYPLAN, YZPLAN, ZXPLAN): it may change how the "
                    f"path is offset; {rc.fix_or_skip()}")
    side = next((v for v, _ in toks if v in ("LEFT", "RIGHT")), None)
    if side is not None:
        run.warn(rec.col, "cutter_compensation", f"CUTCOM/{side}: the controller would "
                 "offset the path; the CL data are read as the tool-centre path as written")


def partno(run: Run, rec: rc.Record) -> None:
    if run.meta["program"] is None:
        run.meta["program"] = (rec.args or "").strip()


def fini(run: Run, rec: rc.Record) -> None:
    run.ended_line = rec.line
