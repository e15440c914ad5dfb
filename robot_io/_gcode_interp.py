"""The G-code interpreter behind :mod:`robot_io.gcode` (private): modal state, blocks, moves.

Conventions are documented in :mod:`robot_io.gcode`. This module keeps the hot path lean: plain
floats, tuples and dicts per line; numpy arrays are made once per program in :meth:`_Run.finish`.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from robot_io import _gcode_words as W
from robot_io.rotary import TrunnionKinematics, make_rotary_kinematics
from robot_io.toolpath import Move, MoveKind, SourceRef, Toolpath, ToolpathError, ToolpathWarning

if TYPE_CHECKING:
    from robot_io.gcode import GcodeOptions

__all__ = ["run_program"]

_DEG = math.pi / 180.0
_PLANES = {  # plane → (p axis, q axis, normal axis, offset letters (p, q), word along normal)
    170: (0, 1, 2, ("I", "J"), "K"),
    180: (2, 0, 1, ("K", "I"), "J"),
    190: (1, 2, 0, ("J", "K"), "I"),
}
_UNIT = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
_KINDS = {0: MoveKind.RAPID, 10: MoveKind.LINEAR, 20: MoveKind.ARC_CW, 30: MoveKind.ARC_CCW}
_MOTION = W.CANNED_CYCLES | set(W.MOTION_G)
_MODAL = frozenset({170, 180, 190, 200, 210, 900, 910, 901, 911, 930, 940}) | (
    W.HARMLESS_G | W.WORK_OFFSETS_G | W.CUTTER_COMP_G)
_AXES = frozenset("XYZABC")
_ARC = frozenset("IJKR")
_FIRST_COL = frozenset("XYZABCIJKR")
_FIX = "read with strict=False to skip it, or remove it"
_OBJ_NEW = object.__new__
_OBJ_SET = object.__setattr__


def run_program(text: str, file: str, strict: bool, opts: GcodeOptions) -> Toolpath:
    """Interpret ``text`` as one G-code program."""
    return _Run(file, strict, opts).run(text)


@dataclass
class _State:
    """Modal state of the machine while reading (program coordinates, SI)."""

    pos: list[float | None] = field(default_factory=lambda: [None, None, None])
    rot: dict[str, float | None] = field(
        default_factory=lambda: {"A": None, "B": None, "C": None})
    motion: int | None = None
    plane: int = 170
    absolute: bool = True
    arc_absolute: bool = False
    scale: float = W.MM
    inverse_time: bool = False
    feed_raw: float | None = None
    spindle_s: float | None = None
    spindle_on: bool = False
    tool: int | None = None
    tcp: bool = False
    retract_r_plane: bool = False
    cycle_r: float | None = None   # sticky canned-cycle R and Z (absolute, program frame) [m]
    cycle_z: float | None = None


class _Run:
    """One reading of one program."""

    def __init__(self, file: str, strict: bool, opts: GcodeOptions) -> None:
        self.file = file
        self.strict = strict
        self.opts = opts
        self.kin: TrunnionKinematics | None = (
            None if opts.rotary == "none"
            else make_rotary_kinematics(opts.rotary, opts.pivot, opts.c_offset))
        self.st = _State(scale=W.MM if opts.default_units == "mm" else W.INCH)
        if opts.tcp is not None:
            self.st.tcp = opts.tcp
        self.warnings: list[ToolpathWarning] = []
        self.warn_counts: Counter = Counter()
        self.skipped: Counter = Counter()
        self.meta: dict[str, Any] = {
            "program": None, "work_offsets": [], "tcp_switches": [], "homing_blocks": 0,
            "unknown_start_moves": 0, "block_delete_lines": 0, "dwell_s": 0.0,
            "rotary_kinematics": None if self.kin is None else {
                "name": self.kin.name, "pivot_m": list(self.kin.pivot),
                "c_offset_m": list(self.kin.c_offset), "tcp_option": opts.tcp},
        }
        # Pending moves: tips (tuples) and records; numpy and Move objects are built in finish().
        self.tips: list[tuple[float, float, float]] = []
        self.recs: list[tuple] = []
        self.last_tip: tuple[float, float, float] | None = None
        self.initial_tip: tuple[float, float, float] | None = None
        if opts.initial_position is not None:
            self.st.pos = list(opts.initial_position)
            self.last_tip = self.initial_tip = tuple(opts.initial_position)  # type: ignore
        self.rot_used = False
        self.units: str | None = None
        self.default_units_line: int | None = None
        self.tcp_hint: int | None = None
        self.ended = False
        self.end_line = 0
        self.line = 0
        self.keys: dict[str, int | None] = {}   # G/M number text → code key
        self.first_line = 0                      # first line that is not blank
        self.raw = ""                            # the line being tokenised, as written

    # ------------------------------------------------------------------ problems and warnings
    def warn(self, col: int, category: str, message: str, line: int | None = None) -> None:
        """Record a warning (kept up to ``MAX_WARNINGS_PER_CATEGORY`` per category)."""
        self.warn_counts[category] += 1
        n = self.warn_counts[category]
        if n <= W.MAX_WARNINGS_PER_CATEGORY:
            if n == W.MAX_WARNINGS_PER_CATEGORY:
                message += " (further warnings of this kind are only counted)"
            src = SourceRef(self.file, self.line if line is None else line, col)
            self.warnings.append(ToolpathWarning(src, message, category))

    def problem(self, col: int, category: str, reason: str, skip: str | None = None) -> None:
        """Strict: raise :class:`ToolpathError`. Lenient: warn and count ``skip``."""
        if self.strict:
            raise ToolpathError(self.file, self.line, col, reason)
        self.warn(col, category, reason)
        if skip is not None:
            self.skipped[skip] += 1

    # ------------------------------------------------------------------ the line loop
    def run(self, text: str) -> Toolpath:
        findall = W.TOKEN.findall
        table = W.ASCII_UPPER
        keys = self.keys
        first_col = _FIRST_COL
        after_end = 0
        nlines = 0
        for nlines, raw in enumerate(text.split("\n"), 1):  # noqa: B007 (nlines used after)
            line = raw.rstrip()
            if not line:
                continue
            if self.ended:
                after_end += line.strip() != "%"
                continue
            self.line = nlines
            if not self.first_line:
                self.first_line = nlines
            u = line.upper() if line.isascii() else line.translate(table)
            first = u[0]
            if first == " " or first == "\t":
                first = u.lstrip()[0]
            if first == "%" or first == "/":
                u = self.percent_or_slash(u, first)
                if u is None:
                    continue
            # Fast path: a line of words only. Every letter on it starts a word, so a word's
            # column is where its letter is found (G and M searched onwards from the previous).
            words: dict[str, tuple[float, int]] = {}
            codes: list[tuple[str, int | None, int, str]] | None = None
            col0 = gpos = mpos = 0
            for letter, num, _c, _e, _o, _g in findall(u):
                if not letter:
                    break
                if letter == "G" or letter == "M":
                    key = keys.get(num, -1)
                    if key == -1:
                        key = keys[num] = W.code_key(num) if len(num) < 12 else None
                    if letter == "G":
                        col = gpos = u.find("G", gpos) + 1
                    else:
                        col = mpos = u.find("M", mpos) + 1
                    if codes is None:
                        codes = [(letter, key, col, num)]
                    else:
                        codes.append((letter, key, col, num))
                elif letter != "N":
                    if letter in words or (len(num) > 10 and abs(float(num)) > W.MAX_WORD_VALUE):
                        break   # let the slow path say what is wrong, with the column
                    col = u.find(letter) + 1
                    if not col0 and letter in first_col:
                        col0 = col
                    words[letter] = (float(num), col)
            else:
                if words or codes:
                    self.block(words, codes, col0)
                continue
            self.raw = line
            parsed = self.slow_tokens(u)
            if parsed is not None and (parsed[0] or parsed[1]):
                self.block(*parsed)
        if after_end:
            self.skipped["after_program_end"] += after_end
            self.warn(0, "after_program_end", f"{after_end} line(s) after M2/M30 ignored (the "
                      "machine stops at the program end)", line=self.end_line)
        return self.finish(nlines)

    def percent_or_slash(self, u: str, first: str) -> str | None:
        """A ``%`` line (``None``: nothing to read) or a ``/`` block-delete line (read it)."""
        if first == "%":
            if u.strip() != "%":
                self.skipped["percent_line"] += 1
                self.warn(1, "percent_line", "text after '%' ignored (a '%' line only delimits "
                          "the program)")
            return None
        i = u.index("/")
        self.meta["block_delete_lines"] += 1
        self.warn(i + 1, "block_delete", "block delete '/' ignored: the block is read as "
                  "executed (block delete switch off)")
        return u[:i] + " " + u[i + 1:]

    def slow_tokens(self, u: str) -> tuple[dict, list, int] | None:
        """Tokenise a line with comments or problems, with exact columns; ``None`` if the block
        is to be skipped (lenient) after a malformed word."""
        keys = self.keys
        words: dict[str, tuple[float, int]] = {}
        codes: list[tuple[str, int | None, int, str]] = []
        col0 = 0
        for m in W.TOKEN.finditer(u):
            letter, num, com, eol, opn, _garbage = m.groups()
            if letter is not None:
                col = m.start(1) + 1
                if letter == "G" or letter == "M":
                    key = keys.get(num, -1)
                    if key == -1:
                        key = keys[num] = W.code_key(num) if len(num) < 12 else None
                    codes.append((letter, key, col, num))
                    continue
                if letter == "N":
                    continue
                value = float(num)
                if len(num) > 10 and abs(value) > W.MAX_WORD_VALUE:
                    self.problem(col, "malformed_word", f"{letter}{num[:20]} is out of range "
                                 f"(|value| > {W.MAX_WORD_VALUE:g}); fix the number",
                                 skip="malformed_block")
                    return None
                if letter in words:
                    self.problem(col, "duplicate_word", f"second {letter} word in one block "
                                 f"(first at column {words[letter][1]}); keep one of them",
                                 skip="duplicate_word")
                elif not col0 and letter in _FIRST_COL:
                    col0 = col
                words[letter] = (value, col)
            elif com is not None or eol is not None:
                i = 3 if com is not None else 4
                self.comment(self.raw[m.start(i):m.end(i)])
            elif opn is not None:
                self.problem(m.start(5) + 1, "unclosed_comment", "comment '(' is not closed on "
                             "this line; add ')'", skip="unclosed_comment")
            else:
                col = m.start(6) + 1
                self.problem(col, "malformed_word", _garbage_reason(u, col),
                             skip="malformed_block")
                return None
        return words, codes, col0

    def comment(self, text: str) -> None:
        """Remember a TCP announcement, and a program name on the first program line."""
        if "TCP:" in text and self.tcp_hint is None:
            self.tcp_hint = self.line
        if self.line == self.first_line and text[0] == "(" and self.meta["program"] is None:
            self.meta["program"] = text[1:-1].strip()

    # ------------------------------------------------------------------ one block
    def block(self, words: dict, codes: list | None, col0: int) -> None:
        """Execute one block: ``words`` letter → (value, column), ``codes`` the G/M codes as
        (letter, key, column, number text), ``col0`` the column of the first axis/arc word."""
        st = self.st
        motion: int | None = None
        motion_col = 0
        group0: tuple[int, int] | None = None
        cancel_cycle = False
        modal: list[tuple[int, int]] = []
        mcodes: list[tuple[int | None, int, str]] = []
        for letter, key, col, num in codes or ():
            if letter == "M":
                mcodes.append((key, col, num))
            elif key in _MOTION:
                if motion is not None:
                    self.problem(col, "modal_conflict", f"two motion codes in one block (G{num} "
                                 f"and {W.code_name('G', motion)}); keep one",
                                 skip="modal_conflict")
                    continue
                motion, motion_col = key, col
            elif key in _MODAL:
                if key == 800:
                    cancel_cycle = True
                else:
                    modal.append((key, col))
            elif key in (40, 280, 300, 530):
                group0 = (key, col)
            elif not self.unknown_g(key, col, num, words):
                return
        end_program = self.m_codes(mcodes) if mcodes else False
        if "O" in words:
            self.meta["program"] = f"O{words.pop('O')[0]:g}"
        if "E" in words or "U" in words or "V" in words or "W" in words:
            for letter in "EUVW":
                if letter in words:
                    hint = " — exponents like X1E5 are no G-code" if letter == "E" else ""
                    self.problem(words.pop(letter)[1], "unknown_word", f"word {letter} is not "
                                 f"read by cctmill (extra axis or vendor word{hint}); {_FIX}",
                                 skip="unknown_word")
        # RS274NGC order of execution: feed mode, F, S, T, M6, spindle, coolant, dwell, plane,
        # units, compensation, work offset, path control, distance mode, retract mode, G28/G53,
        # motion, stop.
        if modal:
            for key, _col in modal:
                if key == 930:
                    st.inverse_time = True
                elif key == 940:
                    if st.inverse_time:
                        st.feed_raw = None
                    st.inverse_time = False
        line_f = None
        if "F" in words:
            line_f = self.f_word(words["F"])
        if "S" in words or "T" in words:
            self.s_t_words(words)
        if group0 is not None and group0[0] == 40 and "P" in words:
            self.meta["dwell_s"] += max(words["P"][0], 0.0)
        if modal:
            self.modal_codes(modal)
        if cancel_cycle:
            if st.motion in W.CANNED_CYCLES:
                st.motion = None
            st.cycle_r = st.cycle_z = None
        if motion is not None:
            if motion != st.motion:
                st.cycle_r = st.cycle_z = None
            st.motion = motion
            col0 = col0 or motion_col
        has_axes = not _AXES.isdisjoint(words)
        if group0 is not None and group0[0] != 40:
            self.group0_move(group0[0], group0[1], words)
        elif st.motion is not None and (has_axes or (st.motion >= 20 and st.motion <= 30
                                                      and not _ARC.isdisjoint(words))):
            code = st.motion
            if code in W.CANNED_CYCLES:
                self.cycle(code, col0, words)
            else:
                pos, rot = self.target(words) if has_axes else (st.pos, st.rot)
                if code >= 20:
                    self.arc(code, col0, words, pos, rot, line_f)
                else:
                    self.emit(code, col0, pos, rot, line_f)
                    if not _ARC.isdisjoint(words):
                        self.unused_arc_words(words)
        elif has_axes:
            self.problem(col0, "no_motion_mode", "axis words but no motion mode in force "
                         "(G0/G1/G2/G3); add a motion code", skip="no_motion_mode")
        elif not _ARC.isdisjoint(words):
            self.unused_arc_words(words)
        if end_program:
            self.ended = True
            self.end_line = self.line

    def unknown_g(self, key: int | None, col: int, num: str, words: dict) -> bool:
        """Handle an unknown/unsupported G code; False when the whole block is to be skipped."""
        takes_axes = key in W.UNSUPPORTED_AXIS_G or not _AXES.isdisjoint(words)
        what = "unsupported" if key in W.UNSUPPORTED_AXIS_G else "unknown"
        self.problem(col, "unknown_g", f"{what} G code G{num}"
                     + ("; the whole block was skipped (its axis words may belong to it)"
                        if takes_axes and not self.strict else "") + f"; {_FIX}",
                     skip="unknown_g_block" if takes_axes else "unknown_g")
        return not takes_axes

    def m_codes(self, mcodes: list) -> bool:
        """Spindle, tool change, kinematics switches, program end; True at M2/M30."""
        st = self.st
        end_program = False
        for key, col, num in mcodes:
            if key in (30, 40):
                st.spindle_on = True
            elif key == 50:
                st.spindle_on = False
            elif key in (20, 300):
                end_program = True
            elif key in W.HARMLESS_M:
                pass
            elif key in W.LINUXCNC_SWITCHKINS_M:
                mode = W.LINUXCNC_SWITCHKINS_M[key]
                self.meta["tcp_switches"].append((self.line, mode))
                if mode == "user":
                    self.warn(col, "user_kinematics", "M430 selects a LinuxCNC user kinematics "
                              "cctmill does not know; positions are read with the current one")
                elif self.opts.tcp is None:
                    st.tcp = mode == "tcp"
            elif key is not None and key in W.USER_M_RANGE:
                self.skipped["user_mcode"] += 1
                self.warn(col, "user_mcode", f"user M code M{num} skipped (LinuxCNC M100–M199 "
                          "runs a user program; it cannot move the axes)")
            else:
                self.problem(col, "unknown_m", f"unknown M code M{num}; {_FIX}",
                             skip="unknown_m")
        return end_program

    def f_word(self, word: tuple[float, int]) -> float | None:
        """Apply F; returns the line's inverse-time F under G93."""
        f, col = word
        if f <= 0:
            self.problem(col, "bad_feed", f"F must be positive, got F{f:g}; fix the feed",
                         skip="bad_feed")
            return None
        if self.st.inverse_time:
            return f
        self.st.feed_raw = f
        return None

    def s_t_words(self, words: dict) -> None:
        st = self.st
        if "S" in words:
            s, col = words["S"]
            if s < 0:
                self.problem(col, "bad_word", f"S must be >= 0, got S{s:g}", skip="bad_word")
            else:
                st.spindle_s = s
        if "T" in words:
            t, col = words["T"]
            if t != int(t) or t < 0:
                self.problem(col, "bad_word", f"T must be a tool number, got T{t:g}",
                             skip="bad_word")
            else:
                st.tool = int(t)   # the tool in force: posts for machines without changer
                #                   write T alone, without M6

    def modal_codes(self, modal: list) -> None:
        st = self.st
        for key, col in modal:
            if key in _PLANES:
                st.plane = key
            elif key == 200 or key == 210:
                self.units = self.units or ("inch" if key == 200 else "mm")
                st.scale = W.INCH if key == 200 else W.MM
            elif key == 900 or key == 910:
                st.absolute = key == 900
            elif key == 901 or key == 911:
                st.arc_absolute = key == 901
            elif key == 980 or key == 990:
                st.retract_r_plane = key == 990
            elif key in W.WORK_OFFSETS_G:
                self.meta["work_offsets"].append(W.code_name("G", key))
            elif key in W.CUTTER_COMP_G:
                self.warn(col, "cutter_compensation", f"{W.code_name('G', key)} cutter "
                          "compensation: the path is read as programmed (uncompensated)")

    def unused_arc_words(self, words: dict) -> None:
        for letter in "IJKR":
            if letter in words:
                self.problem(words[letter][1], "unused_word", f"{letter} word without G2/G3 "
                             f"(I/J/K tool-axis vectors on G1 are not read); {_FIX}",
                             skip="unused_word")

    # ------------------------------------------------------------------ positions and moves
    def target(self, words: dict) -> tuple[list, dict]:
        """Program position and rotary angles after this block's axis words."""
        st = self.st
        x, y, z = st.pos
        scale = st.scale
        absolute = st.absolute
        if "X" in words:
            v = words["X"][0] * scale
            x = v if absolute else (None if x is None else x + v)
        if "Y" in words:
            v = words["Y"][0] * scale
            y = v if absolute else (None if y is None else y + v)
        if "Z" in words:
            v = words["Z"][0] * scale
            z = v if absolute else (None if z is None else z + v)
        pos = [x, y, z]
        rot = st.rot
        if "A" in words or "B" in words or "C" in words:
            self.rot_used = True
            rot = dict(rot)
            for letter in "ABC":
                w = words.get(letter)
                if w is None:
                    continue
                if self.kin is None or (letter != "C" and letter != self.kin.tilt):
                    hint = "" if self.tcp_hint is None else (
                        f" (line {self.tcp_hint} announces TCP kinematics)")
                    self.problem(w[1], "rotary_ignored", f"rotary word {letter} but no rotary "
                                 f"kinematics for it{hint}: pass rotary='xyzac-trunnion' (or "
                                 "'xyzbc-trunnion'), or read with strict=False to keep the raw "
                                 "angle in Move.extra", skip="rotary_word")
                if absolute:
                    rot[letter] = w[0] * _DEG
                elif rot[letter] is not None:
                    rot[letter] += w[0] * _DEG
        return pos, rot

    def tip(self, pos: list, rot: dict) -> tuple[float, float, float] | None:
        """Workpiece-frame tool tip of a program position, ``None`` if not known."""
        x, y, z = pos
        if x is None or y is None or z is None:
            return None
        if self.kin is None or self.st.tcp:
            return (x, y, z)
        tilt, c = rot[self.kin.tilt], rot["C"]
        if tilt is None or c is None:
            return None
        return self.kin.tip((x, y, z), tilt, c)

    def emit(self, code: int, col: int, pos: list, rot: dict, line_f: float | None,
             arc: tuple | None = None) -> None:
        """Record the move to ``pos``/``rot`` (program coordinates); make it the new state."""
        st = self.st
        tip = self.tip(pos, rot)
        start = self.last_tip
        st.pos = pos
        st.rot = rot
        if tip is None:
            self.unknown_end(col, pos, rot)
            return
        feed = duration = None
        if code:
            if st.inverse_time:
                if line_f is None:
                    self.problem(col, "missing_feed", "G93 (inverse time) feed move without F: "
                                 "every G1/G2/G3 line needs its own F (1/min) in G93",
                                 skip="missing_feed")
                else:
                    duration = 60.0 / line_f
            elif st.feed_raw is None:
                self.problem(col, "missing_feed", "feed move without a feed rate: no F since "
                             "the program start (or since G93 → G94); add an F word",
                             skip="missing_feed")
            else:
                feed = st.feed_raw * st.scale / 60.0
        if self.units is None and self.default_units_line is None:
            self.default_units_line = self.line
        if start is None:
            self.meta["unknown_start_moves"] += 1
        elif start is self.initial_tip and not self.tips:
            start = self.initial_tip
        else:
            start = True   # the previous move's end
        axis = None
        extra = None
        if self.rot_used:
            extra = {k: v for k, v in rot.items() if v is not None}
            if self.kin is not None:
                tilt, c = rot[self.kin.tilt], rot["C"]
                if tilt is not None and c is not None:
                    axis = self.kin.tool_axis(tilt, c)
        spindle = None if st.spindle_s is None else (st.spindle_s if st.spindle_on else 0.0)
        self.tips.append(tip)
        self.recs.append((code, self.line, col, start, feed, duration, arc, axis, spindle,
                          st.tool, extra))
        self.last_tip = tip

    def unknown_end(self, col: int, pos: list, rot: dict) -> None:
        missing = [k for k, v in zip("XYZ", pos, strict=True) if v is None]
        if not missing and self.kin is not None:
            missing = [k for k in (self.kin.tilt, "C") if rot[k] is None]
        self.last_tip = None
        self.skipped["unknown_position"] += 1
        self.warn(col, "unknown_position", f"move skipped: position of {'/'.join(missing)} not "
                  "known yet (program start, G28/G30 or G53); program every axis absolutely "
                  "first, or pass initial_position=")

    # ------------------------------------------------------------------ arcs
    def arc(self, code: int, col: int, words: dict, pos: list, rot: dict,
            line_f: float | None) -> None:
        st = self.st
        p, q, n, (lp, lq), lnormal = _PLANES[st.plane]
        start = st.pos
        if None in start or None in pos:
            self.arc_skip(col, "arc skipped: it starts from a position not known yet (program "
                          "start, G28/G30 or G53); move there absolutely first", pos, rot,
                          unknown=True)
            return
        sp, sq, ep, eq = start[p], start[q], pos[p], pos[q]
        wn = words.get(lnormal)
        if wn is not None and wn[0] != 0.0:
            self.problem(wn[1], "arc_normal_word", f"{lnormal}{wn[0]:g} on a "
                         f"{W.code_name('G', st.plane)} arc: the offset along the plane normal "
                         f"must be 0 (a helix gives its travel as the axis word, e.g. Z in G17); "
                         f"{_FIX}", skip="arc_normal_word")
        scale = st.scale
        tol_a, tol_r = self.opts.arc_radius_tol, self.opts.arc_radius_rtol
        if "R" in words:
            r, rcol = words["R"]
            if lp in words or lq in words:
                self.problem(rcol, "arc_format", "arc with both R and I/J/K: use one format",
                             skip="arc_format")
            r *= scale
            dp, dq = ep - sp, eq - sq
            d = math.hypot(dp, dq)
            if d <= W.ARC_MIN_RADIUS:
                self.arc_skip(rcol, "R-format arc with end = start: R cannot describe a full "
                              "circle; use I/J/K", pos, rot)
                return
            half = 0.5 * d
            if abs(r) < half - max(tol_a, tol_r * abs(r)):
                self.arc_skip(rcol, f"R {abs(r) / scale:g} is smaller than half the chord "
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
                self.arc_skip(col, f"arc without centre: give {lp}/{lq} (or R) for "
                              f"{W.code_name('G', st.plane)}", pos, rot)
                return
            if st.arc_absolute:
                if wp is None or wq is None:
                    self.arc_skip(col, f"G90.1 (absolute arc centre) needs both {lp} and {lq}",
                                  pos, rot)
                    return
                cp, cq = wp[0] * scale, wq[0] * scale
            else:
                cp = sp + (wp[0] * scale if wp is not None else 0.0)
                cq = sq + (wq[0] * scale if wq is not None else 0.0)
            r0 = math.hypot(sp - cp, sq - cq)
            r1 = math.hypot(ep - cp, eq - cq)
            if r0 < W.ARC_MIN_RADIUS:
                self.arc_skip(col, "arc of zero radius (centre = start); fix I/J/K", pos, rot)
                return
            tol = max(tol_a, tol_r * r0)
            if abs(r1 - r0) > tol:
                self.problem(col, "arc_radius", f"arc radius differs at start ({r0 / scale:.6g})"
                             f" and end ({r1 / scale:.6g}) by more than the tolerance "
                             f"({tol / scale:.3g}); fix the centre or the end point, or widen "
                             "arc_radius_tol")
        turns = 0
        if "P" in words:
            pv, pcol = words["P"]
            if pv != int(pv) or not 1 <= pv <= W.MAX_ARC_TURNS:
                self.arc_skip(pcol, f"arc P (turns) must be an integer 1…{W.MAX_ARC_TURNS}, "
                              f"got P{pv:g}", pos, rot)
                return
            turns = int(pv) - 1
        center = [0.0, 0.0, 0.0]
        center[p], center[q], center[n] = cp, cq, start[n]
        normal = _UNIT[n]
        if self.kin is not None and not st.tcp:
            t0, c0 = st.rot[self.kin.tilt], st.rot["C"]
            t1, c1 = rot[self.kin.tilt], rot["C"]
            if (t0, c0) != (t1, c1) and t0 is not None and c0 is not None:
                self.arc_skip(col, "arc while the table turns (A/B/C change) in identity "
                              "kinematics is no planar arc in the workpiece frame; turn the "
                              "table in a separate block or use TCP (M428)", pos, rot)
                return
            if t1 is not None and c1 is not None:
                center = list(self.kin.tip((center[0], center[1], center[2]), t1, c1))
                normal = self.kin.rotate_to_workpiece(normal, t1, c1)
        self.emit(code, col, pos, rot, line_f, arc=(tuple(center), normal, turns))

    def arc_skip(self, col: int, reason: str, pos: list, rot: dict,
                 unknown: bool = False) -> None:
        """An arc that cannot be built: strict raises (unless only its start is unknown);
        otherwise it is skipped, counted, and the position still moves to its end."""
        if unknown:
            self.skipped["unknown_position"] += 1
            self.warn(col, "unknown_position", reason)
        else:
            self.problem(col, "bad_arc", reason, skip="bad_arc")
        self.st.pos, self.st.rot = pos, rot
        self.last_tip = None

    # ------------------------------------------------------------------ G28 / G30 / G53
    def group0_move(self, key: int, col: int, words: dict) -> None:
        st = self.st
        named = [i for i, k in enumerate("XYZ") if k in words]
        named_rot = [k for k in "ABC" if k in words]
        if key == 530:
            if st.motion not in (0, 10):
                self.problem(col, "machine_coordinates", "G53 needs G0 or G1 in force; add G0",
                             skip="machine_coordinates")
            pos, rot = list(st.pos), dict(st.rot)
            for i in named:
                pos[i] = None
            for k in named_rot:
                rot[k] = None
            st.pos, st.rot, self.last_tip = pos, rot, None
            self.skipped["machine_coordinates"] += 1
            self.warn(col, "machine_coordinates", "G53 move in machine coordinates skipped: its "
                      "end is unknown in the workpiece frame until the axes are programmed again")
            return
        self.meta["homing_blocks"] += 1
        pos, rot = self.target(words)
        if pos != st.pos or rot != st.rot:   # the intermediate point
            self.emit(0, col, pos, rot, None)
        home = self.opts.home_position
        if not named and not named_rot:
            named, named_rot = [0, 1, 2], ["A", "B", "C"]
        pos, rot = list(st.pos), dict(st.rot)
        for i in named:
            pos[i] = None if home is None else home[i]
        for k in named_rot:
            rot[k] = None if home is None else 0.0
        if home is not None:
            self.emit(0, col, pos, rot, None)
        else:
            st.pos, st.rot, self.last_tip = pos, rot, None

    # ------------------------------------------------------------------ canned cycles
    def cycle(self, code: int, col: int, words: dict) -> None:
        st = self.st
        name = W.code_name("G", code)
        z0 = st.pos[2]
        reason = None
        if st.plane != 170:
            reason = f"{name} outside G17 is not supported; program the moves"
        elif st.inverse_time:
            reason = f"{name} in G93 inverse time: give the cycle a G94 feed"
        elif z0 is None:
            reason = f"{name} from an unknown Z: move Z absolutely before the cycle"
        if reason is not None:
            self.problem(col, "canned_cycle", f"{reason}, or {_FIX}", skip="canned_cycle")
            return
        scale = st.scale
        r_abs, z_abs = st.cycle_r, st.cycle_z
        if "R" in words:
            r_abs = words["R"][0] * scale + (0.0 if st.absolute else z0)
        if "Z" in words and r_abs is not None:
            z_abs = words["Z"][0] * scale + (0.0 if st.absolute else r_abs)
        reps = 1
        if "L" in words:
            lv = words["L"][0]
            reps = int(lv) if lv == int(lv) and 1 <= lv <= 10000 else 0
        if r_abs is None or z_abs is None or reps == 0:
            self.problem(col, "canned_cycle", f"{name} needs R (retract plane), Z (bottom) and "
                         f"an integer L in 1…10000 if any; add them, or {_FIX}",
                         skip="canned_cycle")
            return
        st.cycle_r, st.cycle_z = r_abs, z_abs
        clear = r_abs if st.retract_r_plane else max(z0, r_abs)
        expand = code in W.EXPANDED_CYCLES
        if not expand:
            self.skipped["canned_cycle_not_expanded"] += 1
            self.warn(col, "canned_cycle_not_expanded", f"canned cycle {name} not expanded: its "
                      "moves are missing from the toolpath (the position after it is kept)")
        elif st.feed_raw is None:
            self.problem(col, "missing_feed", f"{name} without a feed rate; add an F word",
                         skip="missing_feed")
        rot = st.rot
        x, y = st.pos[0], st.pos[1]
        for rep in range(reps):
            if "X" in words:
                v = words["X"][0] * scale
                x = v if st.absolute else (None if x is None else x + v)
            if "Y" in words:
                v = words["Y"][0] * scale
                y = v if st.absolute else (None if y is None else y + v)
            # (kind, x, y, z); z None = stay at the current height
            steps = [(0, x, y, None), (0, x, y, r_abs), (10, x, y, z_abs), (0, x, y, clear)]
            if rep == 0 and z0 < r_abs:
                steps.insert(0, (0, st.pos[0], st.pos[1], r_abs))
            for kind, sx, sy, sz in steps:
                target = [sx, sy, st.pos[2] if sz is None else sz]
                if target == st.pos:
                    continue
                if expand:
                    self.emit(kind, col, target, rot, None)
                else:
                    st.pos = target
                    self.last_tip = None
            if expand and code == 820 and "P" in words:
                self.meta["dwell_s"] += max(words["P"][0], 0.0)

    # ------------------------------------------------------------------ the result
    def finish(self, nlines: int) -> Toolpath:
        if self.units is None:
            self.warn(0, "no_units", f"no G20/G21 in the program: read as "
                      f"{self.opts.default_units} (pass default_units='inch' if the machine "
                      "starts in inch)", line=self.default_units_line or 1)
        elif self.default_units_line is not None:
            self.warn(0, "moves_before_units", f"moves before the first G20/G21 were read in "
                      f"{self.opts.default_units}", line=self.default_units_line)
        self.meta["warning_counts"] = dict(self.warn_counts)
        self.meta["lines"] = nlines
        self.meta["work_offsets"] = sorted(set(self.meta["work_offsets"]))
        return Toolpath(file=self.file, format="gcode",
                        units=self.units or self.opts.default_units, moves=self.build_moves(),
                        warnings=self.warnings, skipped=self.skipped, meta=self.meta)

    def build_moves(self) -> list[Move]:
        """The pending records as :class:`Move` objects sharing one read-only end array.

        Moves are made without the frozen-dataclass ``__init__`` (13 ``object.__setattr__``
        calls, ~5 µs per move — most of the reading time); ``test_gcode`` checks that the result
        equals ``Move(**fields)``.
        """
        ends = np.array(self.tips, dtype=float).reshape(-1, 3)
        ends.flags.writeable = False
        rows = list(ends)
        file = self.file
        kinds = _KINDS
        moves: list[Move] = []
        append = moves.append
        prev = None
        for i, (code, line, col, start, feed, duration, arc, axis, spindle, tool,
                extra) in enumerate(self.recs):
            end = rows[i]
            src = _OBJ_NEW(SourceRef)
            _OBJ_SET(src, "__dict__", {"file": file, "line": line, "column": col})
            if start is True:
                start = prev
            elif start is not None:
                start = _frozen(start)
            center = normal = None
            turns = 0
            if arc is not None:
                center, normal, turns = _frozen(arc[0]), _frozen(arc[1]), arc[2]
            mv = _OBJ_NEW(Move)
            _OBJ_SET(mv, "__dict__", {
                "kind": kinds[code], "start": start, "end": end, "source": src, "feed": feed,
                "duration": duration, "center": center, "normal": normal, "turns": turns,
                "tool_axis": None if axis is None else _frozen(axis), "spindle_rpm": spindle,
                "tool": tool, "extra": {} if extra is None else extra})
            append(mv)
            prev = end
        return moves


def _garbage_reason(u: str, col: int) -> str:
    """Why the text at ``col`` (1-based) is not a word, and what to do."""
    ch = u[col - 1]
    snippet = u[col - 1:col + 11].rstrip()
    if u.lstrip()[:1] == "O" and "A" <= ch <= "Z":
        return (f"O-word subroutines and control flow ({snippet!r}) are not supported; let the "
                "CAM post write the moves out")
    if "A" <= ch <= "Z":
        rest = u[col:col + 40].lstrip(" \t")
        if rest[:1] in ("#", "["):
            return (f"parameters and expressions ({snippet!r}) are not supported; let the CAM "
                    "post write plain numbers")
        if rest.lstrip("+-.").lstrip(" \t")[:1] in ("", ";", "("):
            return (f"word {snippet!r} without a number (truncated word?); give it a number or "
                    "remove it")
        return (f"malformed number in {snippet!r}: one plain decimal number per word, e.g. "
                f"{ch}1.25 (no exponents, NaN/inf or repeated points)")
    if ch in "#[":
        return (f"parameters and expressions ({snippet!r}) are not supported; let the CAM post "
                "write plain numbers")
    return f"unexpected character {ch!r} in {snippet!r}; remove it"


def _frozen(v: Any) -> np.ndarray:
    a = np.array(v, dtype=float)
    a.flags.writeable = False
    return a
