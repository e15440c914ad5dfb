"""The APT/CL interpreter behind :mod:`robot_io.apt` (private): modal state, records, moves.

Conventions are documented in :mod:`robot_io.apt`. The hot path keeps plain floats and tuples;
numpy arrays are made once per move in :meth:`_Run.build_moves`.
"""

from __future__ import annotations

import math
from collections import Counter
from typing import TYPE_CHECKING, Any

import numpy as np

from robot_io.apt import _records as rc
from robot_io.toolpath import Move, MoveKind, SourceRef, Toolpath, ToolpathError, ToolpathWarning

if TYPE_CHECKING:
    from robot_io.apt import AptOptions

__all__ = ["run_program"]


def run_program(text: str, file: str, strict: bool, opts: AptOptions) -> Toolpath:
    """Interpret ``text`` as one CL file."""
    return _Run(file, strict, opts).run(text)


def _norm(v: tuple[float, ...]) -> float:
    return math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])


def _rot(r: tuple[rc.Vec, rc.Vec, rc.Vec], v: tuple[float, ...]) -> rc.Vec:
    """R·v for R given by rows."""
    return (r[0][0] * v[0] + r[0][1] * v[1] + r[0][2] * v[2],
            r[1][0] * v[0] + r[1][1] * v[1] + r[1][2] * v[2],
            r[2][0] * v[0] + r[2][1] * v[1] + r[2][2] * v[2])


class _Run:
    """One reading of one CL file."""

    def __init__(self, file: str, strict: bool, opts: AptOptions) -> None:
        self.file = file
        self.strict = strict
        self.opts = opts
        self.warnings: list[ToolpathWarning] = []
        self.warn_counts: Counter = Counter()
        self.skipped: Counter = Counter()
        self.record_counts: Counter = Counter()
        self.meta: dict[str, Any] = {
            "program": None, "units_declared": [], "frames": [], "trntyp": None,
            "cutters": [], "selected_tools": [], "cycles": [], "multax": None,
            "apply_frames": opts.apply_frames,
        }
        self.units: str | None = None
        self.scale = rc.MM if opts.default_units == "mm" else rc.INCH
        self.default_units_line: int | None = None
        self.pos: rc.Vec | None = None
        self.axis: rc.Vec | None = None
        self.frame: tuple[tuple[rc.Vec, rc.Vec, rc.Vec], rc.Vec] | None = None   # (R rows, t)
        self.feed: tuple[float, bool, int] | None = None   # (m/s or m/rev, per_rev, line)
        self.missing_feed_warned = False
        self.rapid = False
        self.circle: tuple | None = None    # (rec, centre, axis, radius|None, turns)
        self.cycle: dict | None = None
        self.last_cycle: dict | None = None
        self.rpm: float | None = None
        self.spindle_on = False
        self.tool: int | None = None
        self.ended_line: int | None = None
        self.rec: rc.Record | None = None
        # pending moves: (kind, end, start|None, line, col, feed, arc, axis, rpm, tool, extra)
        self.moves: list[tuple] = []
        self.handlers = {
            "GOTO": self.goto, "FROM": self.from_, "RAPID": self.rapid_, "FEDRAT": self.fedrat,
            "CIRCLE": self.circle_, "TLAXIS": self.tlaxis, "MULTAX": self.multax,
            "UNITS": self.units_, "UNIT": self.units_, "CSYS": self.frame_, "MSYS": self.frame_,
            "TRNTYP": self.trntyp, "SPINDL": self.spindl, "CUTTER": self.cutter,
            "TLDATA": self.tldata, "CSI_SET_FLUTE_LENGTH": self.cutter_length,
            "CSI_SET_EXTENSION_LENGTH": self.cutter_length, "LOAD": self.load,
            "TOOLNO": self.toolno, "SELECT": self.select, "CUTCOM": self.cutcom,
            "CYCLE": self.cycle_, "PARTNO": self.partno, "FINI": self.fini,
        }

    # ------------------------------------------------------------------ problems and warnings
    def locate(self, rec: rc.Record, offset: int) -> tuple[int, str]:
        """Physical column of ``offset`` in ``rec.text`` and a note naming its continuation
        line (empty on the first line)."""
        if rec.pieces is None:
            return offset + 1, ""
        start, line = rec.pieces[0]
        for s, ln in rec.pieces:
            if s > offset:
                break
            start, line = s, ln
        note = "" if line == rec.line else f" (on continuation line {line})"
        return offset - start + 1, note

    def warn(self, col: int, category: str, message: str, line: int | None = None) -> None:
        """Record a warning (kept up to ``MAX_WARNINGS_PER_CATEGORY`` per category)."""
        self.warn_counts[category] += 1
        n = self.warn_counts[category]
        if n <= rc.MAX_WARNINGS_PER_CATEGORY:
            if n == rc.MAX_WARNINGS_PER_CATEGORY:
                message += " (further warnings of this kind are only counted)"
            ln = line if line is not None else (self.rec.line if self.rec is not None else 0)
            self.warnings.append(ToolpathWarning(SourceRef(self.file, ln, col), message,
                                                 category))

    def bad(self, offset: int | None, reason: str, category: str = "malformed_record",
            rec: rc.Record | None = None) -> None:
        """A malformed known record. Strict: raise. Lenient: warn, count, abandon the record."""
        rec = rec or self.rec
        assert rec is not None
        col, note = self.locate(rec, rec.col - 1 if offset is None else offset)
        if self.strict:
            raise ToolpathError(self.file, rec.line, col, reason + note)
        self.warn(col, category, reason + note, line=rec.line)
        self.skipped[category] += 1
        raise rc.Skip

    # ------------------------------------------------------------------ fields
    def field_offset(self, rec: rc.Record, idx: int) -> int:
        """Offset in ``rec.text`` of field ``idx`` (first non-blank character)."""
        args = rec.args or ""
        k = 0
        for _ in range(idx):
            j = args.find(",", k)
            if j < 0:
                return rec.args_at + len(args)
            k = j + 1
        while k < len(args) and args[k] in " \t":
            k += 1
        return rec.args_at + k

    def fields(self, rec: rc.Record) -> list[str]:
        """The comma-separated fields, stripped (``[]`` for none)."""
        args = rec.args
        if args is None or not args.strip(" \t"):
            return []
        if args.count(",") >= rc.MAX_RECORD_FIELDS:
            self.bad(self.field_offset(rec, rc.MAX_RECORD_FIELDS),
                     f"{rec.word} has more than {rc.MAX_RECORD_FIELDS} fields; a CL record is short "
                     f"— is a line break missing? {rc.FIX}")
        return [f.strip(" \t") for f in args.split(",")]

    def number(self, rec: rc.Record, f: str, idx: int) -> float:
        """Field ``f`` (index ``idx``) as a finite float, or a located error."""
        if len(f) <= rc.MAX_NUMBER_CHARS and rc.NUMBER.fullmatch(f):
            v = float(f)
            if math.isfinite(v):
                return v
            reason = f"number {rc.short(f)!r} is out of range"
        elif not f:
            reason = "missing number (empty field)"
        elif len(f) > rc.MAX_NUMBER_CHARS:
            reason = f"number {rc.short(f)!r} is longer than {rc.MAX_NUMBER_CHARS} characters"
        elif f.upper() in rc.NONFINITE:
            reason = f"{f!r} is not a finite number"
        else:
            reason = f"bad number {rc.short(f)!r}: write a plain decimal such as -12.5 or .984808"
        self.bad(self.field_offset(rec, idx), f"{rec.word}: {reason}; {rc.FIX}")
        raise AssertionError  # pragma: no cover  (bad() raised)

    def numbers(self, rec: rc.Record, counts: tuple[int, ...], usage: str) -> list[float]:
        """All fields as numbers, their count one of ``counts``."""
        args = rec.args or ""
        if args.count(",") < rc.MAX_RECORD_FIELDS and rc.NUMBERS.fullmatch(args):
            parts = args.split(",")
            if len(parts) in counts and max(map(len, parts)) <= rc.MAX_NUMBER_CHARS:
                vals = [float(f) for f in parts]
                # without an exponent, <= MAX_NUMBER_CHARS digits are always finite
                if ("e" not in args and "E" not in args) or all(map(math.isfinite, vals)):
                    return vals
        fields = self.fields(rec)
        vals = [self.number(rec, f, i) for i, f in enumerate(fields)]
        if len(vals) not in counts:
            at = (self.field_offset(rec, max(counts)) if len(vals) > max(counts)
                  else len(rec.text.rstrip(" \t")))
            self.bad(at, f"{rec.word} takes {usage}, got {len(vals)} number"
                     f"{'' if len(vals) == 1 else 's'}; complete the record (truncated line?) "
                     f"or {rc.FIX}")
        return vals

    def tokens(self, rec: rc.Record) -> list[tuple[float | str, int]]:
        """Fields as numbers or upper-case words, with their indices."""
        out: list[tuple[float | str, int]] = []
        for i, f in enumerate(self.fields(rec)):
            if len(f) <= rc.MAX_NUMBER_CHARS and rc.NUMBER.fullmatch(f):
                out.append((self.number(rec, f, i), i))
            elif (len(f) <= rc.MAX_NUMBER_CHARS and rc.WORD.fullmatch(f)
                  and f.upper() not in rc.NONFINITE):
                out.append((f.upper(), i))
            else:
                self.number(rec, f, i)   # raises with the best reason
        return out

    # ------------------------------------------------------------------ the record loop
    def run(self, text: str) -> Toolpath:
        if text.startswith("\ufeff"):
            text = text[1:]
        handlers = self.handlers
        nrec = 0
        for body, line, pieces in rc.records(text):
            nrec += 1
            rec = self.head(body, line, pieces)
            if rec is None:
                continue
            self.rec = rec
            word = rec.word
            self.record_counts[word] += 1
            if self.ended_line is not None:
                self.skipped["after_fini"] += 1
                if self.skipped["after_fini"] == 1:
                    self.warn(rec.col, "after_fini", f"records after FINI (line "
                              f"{self.ended_line}) are ignored")
                continue
            if self.circle is not None and word != "GOTO":
                try:
                    self.orphan_circle(f"{rc.short(word)} at line {line}")
                except rc.Skip:
                    pass
            try:
                handler = handlers.get(word)
                if handler is not None:
                    handler(rec)
                elif word not in rc.SILENT_RECORDS:
                    self.skipped["unknown_record"] += 1
                    self.warn(rec.col, "unknown_record", f"unknown record {rc.short(word)!r} "
                              "skipped")
            except rc.Skip:
                pass
        self.rec = None
        if self.circle is not None:
            try:
                self.orphan_circle("the end of the file")
            except rc.Skip:
                pass
        return self.finish(nrec)

    def head(self, body: str, line: int, pieces: list | None) -> rc.Record | None:
        """Parse the major word; None (after a lenient warning) when there is none."""
        k = body.find("/")
        if 0 < k <= 8:   # fast path: "GOTO/…", "FEDRAT/…" written from column 1
            w = body[:k]
            if w.isalpha() and w.isupper() and w not in rc.TEXT_WORDS:
                return rc.Record(w, body[k + 1:], k + 1, body, line, 1, pieces)
        m = rc.TEXT_HEAD.match(body)
        if m is not None:
            word = m.group(1).upper()
            k = m.end()
            while k < len(body) and body[k] in " \t":
                k += 1
            if k < len(body) and body[k] == "/":
                k += 1
            return rc.Record(word, body[k:], k, body, line, m.start(1) + 1, pieces)
        m = rc.HEAD.match(body)
        if m is None:
            k = len(body) - len(body.lstrip())
            rec = rc.Record("", None, 0, body, line, k + 1, pieces)
            try:
                self.bad(k, f"not an APT record: {rc.short(body.strip())!r} does not start with a "
                         f"major word such as GOTO; {rc.FIX}", rec=rec)
            except rc.Skip:
                pass
            return None
        word = " ".join(m.group(1).upper().split())
        if m.group(2):
            return rc.Record(word, body[m.end():], m.end(), body, line, m.start(1) + 1, pieces)
        rest = body[m.end():]
        rec = rc.Record(word, None, m.end(), body, line, m.start(1) + 1, pieces)
        if rest.strip(" \t"):
            if word in self.handlers:
                self.record_counts[word] += 1
                try:
                    self.bad(m.end(), f"{word}: expected '/' after the major word, found "
                             f"{rc.short(rest.strip())!r}; {rc.FIX}", rec=rec)
                except rc.Skip:
                    pass
                return None
            rec.args = rest   # an unknown record: warned about as such
        return rec

    def orphan_circle(self, found: str) -> None:
        crec = self.circle[0]   # type: ignore[index]
        self.circle = None
        self.bad(None, f"CIRCLE is not followed by its end point GOTO (found {found}); the arc "
                 f"ends at the GOTO right after the CIRCLE — add it, or {rc.FIX}",
                 category="circle_without_goto", rec=crec)

    # ------------------------------------------------------------------ coordinates and frames
    def length_scale(self) -> float:
        if self.units is None and self.default_units_line is None and self.rec is not None:
            self.default_units_line = self.rec.line
        return self.scale

    def point(self, vals: list[float]) -> rc.Vec:
        s = self.length_scale()
        p = (vals[0] * s, vals[1] * s, vals[2] * s)
        if self.opts.apply_frames and self.frame is not None:
            r, t = self.frame
            q = _rot(r, p)
            p = (q[0] + t[0], q[1] + t[1], q[2] + t[2])
        return p

    def direction(self, vals: list[float], first: int, what: str) -> rc.Vec:
        v = (vals[first], vals[first + 1], vals[first + 2])
        n = _norm(v)
        if not n > 1e-9:
            self.bad(self.field_offset(self.rec, first),   # type: ignore[arg-type]
                     f"{self.rec.word}: {what} {v} is a zero vector; give a unit vector")  # type: ignore[union-attr]
        if abs(n - 1.0) > rc.TOOL_AXIS_NORM_TOL:
            self.warn(self.locate(self.rec, self.field_offset(self.rec, first))[0],  # type: ignore[arg-type]
                      "axis_not_unit", f"{what} has norm {n:.6g}, not 1; normalised")
        v = (v[0] / n, v[1] / n, v[2] / n)
        if self.opts.apply_frames and self.frame is not None:
            v = _rot(self.frame[0], v)
        return v

    def frame_(self, rec: rc.Record) -> None:
        if rec.word == "CSYS":
            vals = self.numbers(rec, (12,), "12 numbers (the APT matrix [R | t], row by row)")
        else:
            vals = self.numbers(rec, (9, 12), "9 numbers (origin, x axis, y axis) or 12 (the "
                                "APT matrix [R | t], row by row)")
        s = self.length_scale()
        if len(vals) == 12:
            rows = ((vals[0], vals[1], vals[2]), (vals[4], vals[5], vals[6]),
                    (vals[8], vals[9], vals[10]))
            t = (vals[3] * s, vals[7] * s, vals[11] * s)
        else:
            x = np.array(vals[3:6])
            y = np.array(vals[6:9])
            z = np.cross(x, y)
            rows = tuple(tuple(float(c) for c in row)
                         for row in np.column_stack([x, y, z]))  # type: ignore[assignment]
            t = (vals[0] * s, vals[1] * s, vals[2] * s)
        rm = np.array(rows, dtype=float)
        err = float(np.abs(rm.T @ rm - np.eye(3)).max())
        if err > rc.FRAME_ORTHONORMAL_TOL or np.linalg.det(rm) < 0:
            self.bad(self.field_offset(rec, 0), f"{rec.word}: the rotation part is not a proper "
                     f"rotation (|RᵀR − I| = {err:.2g}, det = {np.linalg.det(rm):.3g}); the "
                     f"columns of R must be orthonormal axes; {rc.FIX}")
        if self.opts.apply_frames:
            if self.meta["trntyp"] == "WORLD":
                self.warn(rec.col, "frames_on_world_data", "apply_frames=True on a file that "
                          "declares TRNTYP/WORLD: its points are already in the world frame and "
                          "are moved a second time; read without apply_frames")
            self.frame = (rows, t)  # type: ignore[assignment]
        zn = _norm((rows[0][2], rows[1][2], rows[2][2]))
        z_axis = (rows[0][2] / zn, rows[1][2] / zn, rows[2][2] / zn)
        if rec.word == "CSYS" or self.opts.apply_frames:
            self.axis = z_axis
        self.meta["frames"].append({
            "record": rec.word, "line": rec.line,
            "rotation": [list(r) for r in rows], "origin_m": list(t)})

    def trntyp(self, rec: rc.Record) -> None:
        toks = self.tokens(rec)
        self.meta["trntyp"] = toks[0][0] if toks else None

    # ------------------------------------------------------------------ motion
    def goto(self, rec: rc.Record) -> None:
        circle, self.circle = self.circle, None   # a malformed end GOTO takes its CIRCLE along
        vals = self.numbers(rec, (3, 6), "3 numbers (x,y,z) or 6 (x,y,z,i,j,k)")
        p = self.point(vals)
        if len(vals) == 6:
            self.axis = self.direction(vals, 3, "tool axis i,j,k")
        if circle is not None:
            self.arc(rec, p, circle)
        elif self.cycle is not None:
            self.rapid = False
            self.hole(rec, p)
        else:
            kind = MoveKind.RAPID if self.rapid else MoveKind.LINEAR
            self.rapid = False
            self.emit(rec, kind, p, None if kind == MoveKind.RAPID else self.move_feed(rec))

    def from_(self, rec: rc.Record) -> None:
        vals = self.numbers(rec, (3, 6), "3 numbers (x,y,z) or 6 (x,y,z,i,j,k)")
        self.pos = self.point(vals)
        if len(vals) == 6:
            self.axis = self.direction(vals, 3, "tool axis i,j,k")

    def rapid_(self, rec: rc.Record) -> None:
        if self.fields(rec):
            self.bad(rec.args_at, f"RAPID takes no arguments; {rc.FIX}")
        self.rapid = True

    def tlaxis(self, rec: rc.Record) -> None:
        vals = self.numbers(rec, (3,), "3 numbers (i,j,k)")
        self.axis = self.direction(vals, 0, "tool axis i,j,k")

    def multax(self, rec: rc.Record) -> None:
        toks = self.tokens(rec)
        if toks and toks[0][0] not in ("ON", "OFF"):
            self.bad(self.field_offset(rec, 0), f"MULTAX takes ON or OFF; {rc.FIX}")
        self.meta["multax"] = not toks or toks[0][0] == "ON"

    def move_feed(self, rec: rc.Record) -> float | None:
        """Feed [m/s] for a feed move now, or a problem."""
        if self.feed is None:
            if self.strict:
                raise ToolpathError(self.file, rec.line, rec.col, "feed move before any FEDRAT: "
                                    "add FEDRAT/f,MMPM before the first cutting GOTO (or make "
                                    "it a RAPID)")
            if not self.missing_feed_warned:
                self.missing_feed_warned = True
                self.warn(rec.col, "missing_feed", "feed move before any FEDRAT: Move.feed is "
                          "None until the first FEDRAT")
            return None
        value, per_rev, fline = self.feed
        if not per_rev:
            return value
        if self.rpm is None or not self.spindle_on or self.rpm <= 0:
            reason = (f"feed per revolution (FEDRAT at line {fline}) but no spindle speed in "
                      "force: add SPINDL/rpm,RPM,CLW before this move, or give the feed per "
                      "minute (MMPM/IPM)")
            if self.strict:
                raise ToolpathError(self.file, rec.line, rec.col, reason)
            self.warn(rec.col, "feed_per_rev_without_spindle", reason)
            return None
        return value * self.rpm / 60.0

    def emit(self, rec: rc.Record, kind: MoveKind, end: rc.Vec, feed: float | None,
             arc: tuple | None = None, axis: rc.Vec | None = None,
             extra: dict | None = None, col: int | None = None) -> None:
        rpm = None if self.rpm is None else (self.rpm if self.spindle_on else 0.0)
        self.moves.append((kind, end, self.pos, rec.line,
                           rec.col if col is None else col, feed, arc,
                           self.axis if axis is None else axis, rpm, self.tool, extra))
        self.pos = end

    # ------------------------------------------------------------------ arcs
    def circle_(self, rec: rc.Record) -> None:
        fields = self.fields(rec)
        turns = 0
        if len(fields) >= 2 and fields[-2].upper() == "TIMES":
            n = self.number(rec, fields[-1], len(fields) - 1)
            if n != int(n) or not 1 <= n <= rc.MAX_ARC_TURNS:
                self.bad(self.field_offset(rec, len(fields) - 1), f"CIRCLE TIMES must be an "
                         f"integer 1…{rc.MAX_ARC_TURNS}, got {n:g}; {rc.FIX}")
            turns = int(n) - 1
            self.warn(rec.col, "helix_turns", f"CIRCLE …,TIMES,{int(n)} read as {turns} extra "
                      "full turn(s) beyond the sweep from start to end; check the helix")
            fields = fields[:-2]
        if len(fields) not in (6, 11):
            at = (self.field_offset(rec, 11) if len(fields) > 11
                  else len(rec.text.rstrip(" \t")))
            for i, f in enumerate(fields):
                self.number(rec, f, i)
            self.bad(at, f"CIRCLE takes 6 numbers (xc,yc,zc,i,j,k) or 11 (…,r,tol,ratio,"
                     f"diameter,corner) plus an optional TIMES,n; got {len(fields)}; {rc.FIX}")
        vals = [self.number(rec, f, i) for i, f in enumerate(fields)]
        centre = self.point(vals)
        axis = self.direction(vals, 3, "circle axis i,j,k")
        radius = None
        if len(vals) == 11:
            radius = vals[6] * self.scale
            if not radius > 0:
                self.bad(self.field_offset(rec, 6), f"CIRCLE radius must be positive; {rc.FIX}")
        self.circle = (rec, centre, axis, radius, turns)

    def arc(self, rec: rc.Record, end: rc.Vec, circle: tuple) -> None:
        crec, c, n, radius, turns = circle
        self.rapid = False
        start = self.pos
        if start is None:
            self.pos = end
            self.bad(None, "CIRCLE from an unknown position: the arc needs its start point; "
                     "add a GOTO or FROM before it, or read with strict=False", "bad_arc", crec)
        s = start
        h = (s[0] - c[0]) * n[0] + (s[1] - c[1]) * n[1] + (s[2] - c[2]) * n[2]
        c = (c[0] + h * n[0], c[1] + h * n[1], c[2] + h * n[2])   # centre in the start plane
        rs = self.radius(s, c, n)
        re_ = self.radius(end, c, n)
        tol = max(self.opts.arc_radius_tol, self.opts.arc_radius_rtol * rs)
        s_mm = 1.0 / self.scale
        unit = "mm" if self.scale == rc.MM else "in"
        if rs < rc.ARC_MIN_RADIUS:
            self.pos = end
            self.bad(None, "CIRCLE centre coincides with the arc's start point (zero radius); "
                     f"fix the centre, or {rc.FIX}", "bad_arc", crec)
        for what, r in ((f"end point (GOTO at line {rec.line})", re_),
                        ("given radius", radius)):
            if r is not None and abs(r - rs) > tol:
                self.pos = end
                self.bad(None, f"CIRCLE {what} is off the circle: radius {r * s_mm:.6g} {unit} "
                         f"against {rs * s_mm:.6g} {unit} at the start (tolerance "
                         f"{tol * s_mm:.3g} {unit}); fix the centre or the end point, or widen "
                         "arc_radius_tol", "arc_off_circle", crec)
        ref = self.axis if self.axis is not None else (0.0, 0.0, 1.0)
        if n[0] * ref[0] + n[1] * ref[1] + n[2] * ref[2] < 0:
            kind, normal = MoveKind.ARC_CW, (-n[0], -n[1], -n[2])
        else:
            kind, normal = MoveKind.ARC_CCW, n
        self.emit(crec, kind, end, self.move_feed(crec), arc=(c, normal, turns))

    @staticmethod
    def radius(p: rc.Vec, c: rc.Vec, n: rc.Vec) -> float:
        d = (p[0] - c[0], p[1] - c[1], p[2] - c[2])
        a = d[0] * n[0] + d[1] * n[1] + d[2] * n[2]
        return math.sqrt(max(d[0] * d[0] + d[1] * d[1] + d[2] * d[2] - a * a, 0.0))

    # ------------------------------------------------------------------ cycles
    def cycle_(self, rec: rc.Record) -> None:
        toks = self.tokens(rec)
        if not toks or not isinstance(toks[0][0], str):
            self.bad(self.field_offset(rec, 0), f"CYCLE needs a type (DRILL, DEEP2, …, OFF); "
                     f"{rc.FIX}")
        kind = toks[0][0]
        if kind == "OFF":
            self.cycle = None
            return
        if kind == "INIT":
            return
        if kind == "ON":
            if self.last_cycle is None:
                self.bad(self.field_offset(rec, 0), f"CYCLE/ON without an earlier cycle "
                         f"definition; {rc.FIX}")
            self.cycle = self.last_cycle
            return
        params: dict[str, float | str] = {}
        feed: tuple[float, bool] | None = None
        i = 1
        while i < len(toks):
            key, idx = toks[i]
            if not isinstance(key, str) or i + 1 >= len(toks):
                self.bad(self.field_offset(rec, idx), f"CYCLE/{kind}: expected keyword,value "
                         f"pairs (FEDTO,depth,MMPM,feed,RAPTO,clearance,RTRCTO,retract); {rc.FIX}")
            val = toks[i + 1][0]
            if key in rc.FEED_WORDS:
                if not isinstance(val, float) or not val > 0:
                    self.bad(self.field_offset(rec, toks[i + 1][1]), f"CYCLE/{kind}: {key} "
                             f"needs a positive feed; {rc.FIX}")
                unit, per_rev = rc.FEED_WORDS[key]
                feed = (val * unit / (1.0 if per_rev else 60.0), per_rev)  # type: ignore[operator]
            else:
                params[key] = val
            i += 2
        s = self.length_scale()

        def dist(key: str, default: float | None) -> float | None:
            v = params.get(key, default)
            if isinstance(v, str):
                self.bad(self.field_offset(rec, next(j for t, j in toks if t == key) + 1),
                         f"CYCLE/{kind}: {key} needs a number, got {v!r}; {rc.FIX}")
            return None if v is None else float(v) * s

        depth = dist("FEDTO", None)
        if depth is None or not depth > 0:
            self.bad(self.field_offset(rec, 0), f"CYCLE/{kind} needs FEDTO,depth (> 0, measured "
                     f"from the hole point against the tool axis); {rc.FIX}")
        if feed is None:
            self.bad(self.field_offset(rec, 0), f"CYCLE/{kind} needs its feed (MMPM,f / IPM,f / "
                     f"MMPR,f / IPR,f); {rc.FIX}")
        clear = dist("RAPTO", 0.0)
        retract = dist("RTRCTO", None)
        info = {"line": rec.line, "type": kind, "depth_m": depth, "rapto_m": clear,
                "rtrcto_m": retract, "feed": feed[0], "feed_per_rev": feed[1],  # type: ignore[index]
                "pecks_ignored": any(w in params for w in rc.PECK_WORDS),
                "dwell_ignored": bool(params.get("DWELL")), "holes": 0}
        self.meta["cycles"].append(info)
        self.cycle = {"type": kind, "depth": depth, "clear": clear,
                      "retract": clear if retract is None else retract, "feed": feed,
                      "line": rec.line, "info": info}
        self.last_cycle = self.cycle

    def hole(self, rec: rc.Record, p: rc.Vec) -> None:
        cyc = self.cycle
        assert cyc is not None
        a = self.axis if self.axis is not None else (0.0, 0.0, 1.0)
        value, per_rev = cyc["feed"]
        if per_rev:
            if self.rpm is None or not self.spindle_on or self.rpm <= 0:
                self.bad(None, f"CYCLE/{cyc['type']} (line {cyc['line']}) feed per revolution "
                         "but no spindle speed in force: add SPINDL/rpm,RPM,CLW before it",
                         "feed_per_rev_without_spindle")
            feed = value * self.rpm / 60.0   # type: ignore[operator]
        else:
            feed = value
        extra = {"cycle": cyc["type"]}

        def at(d: float) -> rc.Vec:
            return (p[0] + d * a[0], p[1] + d * a[1], p[2] + d * a[2])

        top, clear, bottom = at(cyc["retract"]), at(cyc["clear"]), at(-cyc["depth"])
        for kind, target, f in ((MoveKind.RAPID, top, None), (MoveKind.RAPID, clear, None),
                                (MoveKind.LINEAR, bottom, feed)):
            if self.pos is not None and math.dist(self.pos, target) < rc.CYCLE_POSITION_TOL:
                continue
            self.emit(rec, kind, target, f, axis=a, extra=extra)
        back = cyc["type"] in rc.FEED_RETRACT_CYCLES
        self.emit(rec, MoveKind.LINEAR if back else MoveKind.RAPID, top, feed if back else None,
                  axis=a, extra=extra)
        cyc["info"]["holes"] += 1

    # ------------------------------------------------------------------ modal words
    def units_(self, rec: rc.Record) -> None:
        toks = self.tokens(rec)
        if len(toks) != 1 or toks[0][0] not in rc.UNIT_WORDS:
            self.bad(self.field_offset(rec, 0), f"{rec.word} takes MM or INCHES; {rc.FIX}")
        name, scale = rc.UNIT_WORDS[toks[0][0]]  # type: ignore[index]
        if self.units is None:
            self.units = name
        elif name != self.units:
            self.warn(rec.col, "units_changed", f"units change to {name} in mid-file; the "
                      "following records are read in it")
        self.scale = scale
        self.meta["units_declared"].append((rec.line, name))

    def fedrat(self, rec: rc.Record) -> None:
        toks = self.tokens(rec)
        nums = [(v, i) for v, i in toks if isinstance(v, float)]
        words = [(v, i) for v, i in toks if isinstance(v, str)]
        if len(nums) != 1:
            self.bad(self.field_offset(rec, nums[1][1]) if len(nums) > 1
                     else len(rec.text.rstrip(" \t")),
                     f"FEDRAT takes one feed value and at most one unit word (FEDRAT/125.,MMPM or "
                     f"FEDRAT/MMPM,125.); {rc.FIX}")
        value, vidx = nums[0]
        if not value > 0:   # type: ignore[operator]
            self.bad(self.field_offset(rec, vidx), f"FEDRAT must be positive, got {value:g}; "
                     f"{rc.FIX}")
        if len(words) > 1:
            self.bad(self.field_offset(rec, words[1][1]), f"FEDRAT takes one unit word, got "
                     f"{[w for w, _ in words]}; {rc.FIX}")
        if words:
            w, widx = words[0]
            if w not in rc.FEED_WORDS:
                self.bad(self.field_offset(rec, widx), f"FEDRAT unit {rc.short(w)!r} is unknown: "  # type: ignore[arg-type]
                         f"use MMPM, IPM (per minute), MMPR or IPR (per revolution); {rc.FIX}")
            unit, per_rev = rc.FEED_WORDS[w]  # type: ignore[index]
        else:
            unit, per_rev = self.length_scale(), False
        si = value * unit if per_rev else value * unit / 60.0   # type: ignore[operator]
        self.feed = (si, per_rev, rec.line)
        self.missing_feed_warned = False

    def spindl(self, rec: rc.Record) -> None:
        toks = self.tokens(rec)
        rpm = None
        on = True
        for v, i in toks:
            if isinstance(v, float):
                if rpm is not None or v < 0:
                    self.bad(self.field_offset(rec, i), f"SPINDL takes one speed >= 0 "
                             f"(SPINDL/1000,RPM,CLW); {rc.FIX}")
                rpm = v
            elif v == "OFF":
                on = False
            elif v in ("RPM", "CLW", "CCLW", "ON"):
                pass
            elif v in ("SFM", "SMM"):
                self.bad(self.field_offset(rec, i), f"SPINDL surface speed ({v}) is not "
                         "supported: give the speed in RPM; " + rc.FIX)
            else:
                self.bad(self.field_offset(rec, i), f"SPINDL word {rc.short(v)!r} is unknown "
                         f"(RPM, CLW, CCLW, ON, OFF); {rc.FIX}")
        if on and rpm is None and self.rpm is None:
            self.bad(self.field_offset(rec, 0), f"SPINDL without a speed and none set before; "
                     f"{rc.FIX}")
        if rpm is not None:
            self.rpm = rpm
        self.spindle_on = on

    def cutter(self, rec: rc.Record) -> None:
        vals = self.numbers(rec, tuple(range(1, 8)), "1 to 7 numbers (d,r,e,f,α,β,h)")
        s = self.length_scale()
        if not vals[0] > 0:
            self.bad(self.field_offset(rec, 0), f"CUTTER diameter must be positive; {rc.FIX}")
        self.meta["cutters"].append({
            "line": rec.line, "tool": None, "diameter_m": vals[0] * s,
            "corner_radius_m": vals[1] * s if len(vals) > 1 else 0.0,
            "height_m": vals[6] * s if len(vals) > 6 else None,
            "apt_params": vals, "units": self.units or self.opts.default_units})

    def cutter_length(self, rec: rc.Record) -> None:
        vals = self.numbers(rec, (1,), "1 number (a length)")
        key = "flute_length_m" if rec.word == "CSI_SET_FLUTE_LENGTH" else "extension_length_m"
        if self.meta["cutters"]:
            self.meta["cutters"][-1][key] = vals[0] * self.length_scale()

    def tldata(self, rec: rc.Record) -> None:
        toks = self.tokens(rec)
        self.meta["cutters"].append({"line": rec.line, "tool": None, "tldata": [v for v, _ in toks],
                                     "units": self.units or self.opts.default_units})

    def tool_number(self, rec: rc.Record, v: float | str, idx: int) -> int:
        if not isinstance(v, float) or v != int(v) or not 0 <= v < 1e9:
            self.bad(self.field_offset(rec, idx), f"{rec.word}: tool number must be an integer "
                     f">= 0; {rc.FIX}")
        return int(v)   # type: ignore[arg-type]

    def load(self, rec: rc.Record) -> None:
        toks = self.tokens(rec)
        if len(toks) < 2 or toks[0][0] != "TOOL":
            self.bad(self.field_offset(rec, 0), f"LOAD takes TOOL,n; {rc.FIX}")
        self.tool = self.tool_number(rec, toks[1][0], toks[1][1])
        for c in reversed(self.meta["cutters"]):
            if c["tool"] is None:
                c["tool"] = self.tool
            else:
                break

    def toolno(self, rec: rc.Record) -> None:
        toks = self.tokens(rec)
        if not toks:
            self.bad(None, f"TOOLNO takes a tool number; {rc.FIX}")
        self.tool = self.tool_number(rec, toks[0][0], toks[0][1])

    def select(self, rec: rc.Record) -> None:
        toks = self.tokens(rec)
        if len(toks) >= 2 and toks[0][0] == "TOOL":
            self.meta["selected_tools"].append(self.tool_number(rec, toks[1][0], toks[1][1]))

    def cutcom(self, rec: rc.Record) -> None:
        toks = self.tokens(rec)
        side = toks[0][0] if toks else None
        if side in ("LEFT", "RIGHT"):
            self.warn(rec.col, "cutter_compensation", f"CUTCOM/{side}: the controller would "
                      "offset the path; the CL data are read as the tool-centre path as written")

    def partno(self, rec: rc.Record) -> None:
        if self.meta["program"] is None:
            self.meta["program"] = (rec.args or "").strip()

    def fini(self, rec: rc.Record) -> None:
        self.ended_line = rec.line

    # ------------------------------------------------------------------ the result
    def finish(self, nrec: int) -> Toolpath:
        if self.units is None and self.default_units_line is not None:
            self.warn(0, "no_units", f"no UNITS record before the first coordinate: read as "
                      f"{self.opts.default_units} (pass default_units='inch' if the data are in "
                      "inches)", line=self.default_units_line)
        self.meta["warning_counts"] = dict(self.warn_counts)
        self.meta["record_counts"] = dict(self.record_counts)
        self.meta["records"] = nrec
        return Toolpath(file=self.file, format="apt", units=self.units or self.opts.default_units,
                        moves=self.build_moves(), warnings=self.warnings, skipped=self.skipped,
                        meta=self.meta)

    def build_moves(self) -> list[Move]:
        """The pending records as :class:`Move` objects; end points are rows of one read-only
        array, repeated tool axes share one array."""
        ends = np.array([m[1] for m in self.moves], dtype=float).reshape(-1, 3)
        ends.flags.writeable = False
        rows = list(ends)
        moves: list[Move] = []
        prev: np.ndarray | None = None
        prev_t: rc.Vec | None = None
        file = self.file
        axes: dict[rc.Vec, np.ndarray] = {}   # tool axes repeat: share one read-only array
        for i, (kind, end, start, line, col, feed, arc, axis, rpm, tool,
                extra) in enumerate(self.moves):
            e = rows[i]
            if start is None:
                s = None
            elif start == prev_t:
                s = prev
            else:
                s = _frozen(start)
            center = normal = None
            turns = 0
            if arc is not None:
                center, normal, turns = _frozen(arc[0]), _frozen(arc[1]), arc[2]
            moves.append(Move(kind=kind, start=s, end=e,
                              source=SourceRef(file, line, col), feed=feed, center=center,
                              normal=normal, turns=turns,
                              tool_axis=None if axis is None else (
                                  axes.get(axis) if axis in axes
                                  else axes.setdefault(axis, _frozen(axis))),
                              spindle_rpm=rpm, tool=tool, extra={} if extra is None else extra))
            prev, prev_t = e, end
        return moves


def _frozen(v: Any) -> np.ndarray:
    a = np.array(v, dtype=float)
    a.flags.writeable = False
    return a

