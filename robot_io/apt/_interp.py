"""The APT/CL interpreter behind :mod:`robot_io.apt` (private): modal state, records, moves.

Conventions are documented in :mod:`robot_io.apt.reader`. This module holds a reading's state
(:class:`Run`), the record loop and the field parsers, the emission of moves and the result; the
records are handled in :mod:`robot_io.apt._motion` (GOTO, GODLTA, FROM, RAPID, TLAXIS, MULTAX,
CIRCLE), :mod:`robot_io.apt._spline` (NURBS, KNOT, CNTRL), :mod:`robot_io.apt._cycles` (CYCLE),
:mod:`robot_io.apt._frames` (CSYS, MSYS, TRNTYP), :mod:`robot_io.apt._modal` (units, feed, spindle,
tools and the other modal words) and :mod:`robot_io.apt._words` (the records refused by name,
unknown records, the path-neutral words). The hot path keeps plain floats and tuples; numpy arrays
are made once per move in :meth:`Run.build_moves`.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Collection
from typing import TYPE_CHECKING, Any

import numpy as np

from robot_io.apt import _records as rc
from robot_io.apt._cycles import cycle_
from robot_io.apt._frames import frame_, trntyp
from robot_io.apt._modal import (
    cutcom,
    cutter,
    cutter_length,
    fedrat,
    fini,
    load,
    partno,
    select,
    spindl,
    tldata,
    toolno,
    units_,
)
from robot_io.apt._motion import (
    circle_,
    from_,
    godlta,
    goto,
    multax,
    orphan_circle,
    rapid_,
    tlaxis,
)
from robot_io.apt._spline import SPLINE_PARTS, Spline, close_spline, cntrl, knot, nurbs_
from robot_io.apt._words import PATH_NEUTRAL, REFUSED, refuse, unknown
from robot_io.options import fix, without_lenient_hint
from robot_io.toolpath import Move, MoveKind, SourceRef, Toolpath, ToolpathError, ToolpathWarning

if TYPE_CHECKING:
    from robot_io.apt import AptOptions

__all__ = ["HANDLERS", "Run", "run_program"]

#: The record handlers by major word, the refused words (``_words.REFUSED``) included; a word
#: that is not here is path-neutral (``_words.PATH_NEUTRAL``, passed over) or unknown (refused in
#: strict mode, skipped with a warning in lenient mode).
HANDLERS: dict[str, Callable[[Run, rc.Record], None]] = {
    "GOTO": goto, "FROM": from_, "RAPID": rapid_, "FEDRAT": fedrat, "GODLTA": godlta,
    "CIRCLE": circle_, "TLAXIS": tlaxis, "MULTAX": multax,
    "NURBS": nurbs_, "KNOT": knot, "CNTRL": cntrl,
    "UNITS": units_, "UNIT": units_, "CSYS": frame_, "MSYS": frame_,
    "TRNTYP": trntyp, "SPINDL": spindl, "CUTTER": cutter,
    "TLDATA": tldata, "CSI_SET_FLUTE_LENGTH": cutter_length,
    "CSI_SET_EXTENSION_LENGTH": cutter_length, "LOAD": load,
    "TOOLNO": toolno, "LOADTL": toolno, "SELECT": select, "CUTCOM": cutcom,
    "CYCLE": cycle_, "PARTNO": partno, "FINI": fini,
    **{w: refuse for w in REFUSED},
}


def run_program(text: str, file: str, strict: bool, opts: AptOptions) -> Toolpath:
    """Interpret ``text`` as one CL file."""
    return Run(file, strict, opts).run(text)


class Run:
    """One reading of one CL file: the modal state, the pending moves, the problems found."""

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
            "apply_frames": opts.apply_frames, "splines": [], "listing_header": [],
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
        self.circle_directions: Counter = Counter()   # CIRCLEs read by rule: "ccw" / "cw"
        self.spline: Spline | None = None   # the spline whose KNOT/CNTRL records are being read
        self.spline_count = 0
        self.cycle: dict | None = None
        self.last_cycle: dict | None = None
        self.rpm: float | None = None
        self.spindle_on = False
        self.tool: int | None = None
        self.ended_line: int | None = None
        self.rec: rc.Record | None = None
        # pending moves: (kind, end, start|None, line, col, feed, arc, axis, rpm, tool, extra)
        self.moves: list[tuple] = []

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
            self.warnings.append(ToolpathWarning(SourceRef(self.file, ln, col),
                                                 without_lenient_hint(message), category))

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
                     f"— is a line break missing? {rc.fix_or_skip()}")
        return [f.strip(" \t") for f in args.split(",")]

    def number(self, rec: rc.Record, f: str, idx: int) -> float:
        """Field ``f`` (index ``idx``) as a finite float, or a located error."""
        if len(f) <= rc.MAX_NUMBER_CHARS and rc.NUMBER.fullmatch(f):
            v = float(f)
            if -rc.MAX_NUMBER_VALUE <= v <= rc.MAX_NUMBER_VALUE:
                return v
            reason = (f"number {rc.short(f)!r} is out of range (|value| <= "
                      f"{rc.MAX_NUMBER_VALUE:g}): check for a missing decimal point or separator")
        elif not f:
            reason = "missing number (empty field)"
        elif len(f) > rc.MAX_NUMBER_CHARS:
            reason = f"number {rc.short(f)!r} is longer than {rc.MAX_NUMBER_CHARS} characters"
        elif f.upper() in rc.NONFINITE:
            reason = f"{f!r} is not a finite number"
        else:
            reason = f"bad number {rc.short(f)!r}: write a plain decimal such as -12.5 or .984808"
        self.bad(self.field_offset(rec, idx), f"{rec.word}: {reason}; {rc.fix_or_skip()}")
        raise AssertionError  # pragma: no cover  (bad() raised)

    def numbers(self, rec: rc.Record, counts: Collection[int], usage: str) -> list[float]:
        """All fields as numbers, their count one of ``counts``."""
        args = rec.args or ""
        if args.count(",") < rc.MAX_RECORD_FIELDS and rc.NUMBERS.fullmatch(args):
            parts = args.split(",")
            if len(parts) in counts and max(map(len, parts)) <= rc.MAX_NUMBER_CHARS:
                vals = [float(f) for f in parts]
                if -rc.MAX_NUMBER_VALUE <= min(vals) and max(vals) <= rc.MAX_NUMBER_VALUE:
                    return vals   # (NUMBER never matches nan, so min and max are exact)
        fields = self.fields(rec)
        vals = [self.number(rec, f, i) for i, f in enumerate(fields)]
        if len(vals) not in counts:
            at = (self.field_offset(rec, max(counts)) if len(vals) > max(counts)
                  else len(rec.text.rstrip(" \t")))
            self.bad(at, f"{rec.word} takes {usage}, got {len(vals)} number"
                     f"{'' if len(vals) == 1 else 's'}; complete the record (truncated line?) "
                     f"or {rc.fix_or_skip()}")
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
        first, self.meta["listing_header"] = rc.listing_header(text)
        handlers = HANDLERS
        neutral = PATH_NEUTRAL
        nrec = 0
        for body, line, pieces in rc.records(text, first):
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
                    orphan_circle(self, f"{rc.short(word)} at line {line}")
                except rc.Skip:
                    pass
            if self.spline is not None and word not in SPLINE_PARTS:
                try:
                    close_spline(self)
                except rc.Skip:
                    pass
            try:
                handler = handlers.get(word)
                if handler is not None:
                    handler(self, rec)
                elif word not in neutral:
                    unknown(self, rec)
            except rc.Skip:
                pass
        self.rec = None
        if self.circle is not None:
            try:
                orphan_circle(self, "the end of the file")
            except rc.Skip:
                pass
        if self.spline is not None:
            try:
                close_spline(self)
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
                         f"major word such as GOTO; {rc.fix_or_skip()}", rec=rec)
            except rc.Skip:
                pass
            return None
        word = " ".join(m.group(1).upper().split())
        if m.group(2):
            return rc.Record(word, body[m.end():], m.end(), body, line, m.start(1) + 1, pieces)
        rest = body[m.end():]
        rec = rc.Record(word, None, m.end(), body, line, m.start(1) + 1, pieces)
        if rest.strip(" \t"):
            if word in HANDLERS and word not in REFUSED:
                self.record_counts[word] += 1
                try:
                    self.bad(m.end(), f"{word}: expected '/' after the major word, found "
                             f"{rc.short(rest.strip())!r}; {rc.fix_or_skip()}", rec=rec)
                except rc.Skip:
                    pass
                return None
            rec.args = rest   # an unknown record: warned about as such
        return rec

    # ------------------------------------------------------------------ units
    def length_scale(self) -> float:
        if self.units is None and self.default_units_line is None and self.rec is not None:
            self.default_units_line = self.rec.line
        return self.scale


    # ------------------------------------------------------------------ moves
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

    # ------------------------------------------------------------------ the result
    def finish(self, nrec: int) -> Toolpath:
        if self.units is None and self.default_units_line is not None:
            self.warn(0, "no_units", f"no UNITS record before the first coordinate: read as "
                      f"{self.opts.default_units} (give {fix('default_units', 'inch')} if the "
                      "data are in inches)", line=self.default_units_line)
        self.meta["warning_counts"] = dict(self.warn_counts)
        self.meta["record_counts"] = dict(self.record_counts)
        self.meta["circle_directions"] = dict(self.circle_directions)
        self.meta["ignored_records"] = {w: n for w, n in self.record_counts.items()
                                        if w in PATH_NEUTRAL}
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

