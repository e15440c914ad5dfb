"""The G-code interpreter behind :mod:`robot_io.gcode` (private): the line loop, blocks, codes, moves.

Conventions are documented in :mod:`robot_io.gcode`. The work is shared out:

* :mod:`robot_io.gcode._plain` scans the whole program once (numpy) for *plain* lines — only
  N/G0/G1/X/Y/Z/F words — and executes long runs of them in bulk while the modal state allows it
  (absolute, G94, no rotary kinematics, position known): that is most of a 3-axis CAM program;
* every other line goes through this module one at a time (:meth:`_Run.read_line`): one compiled regex
  per line (:data:`robot_io.gcode._words.TOKEN`), plain floats, tuples and dicts; lines with
  comments, problems, parameters, expressions or O-words are tokenised by
  :mod:`robot_io.gcode._line` (parameters in :mod:`robot_io.gcode._params`, expressions in
  :mod:`robot_io.gcode._expr`, O-words in :mod:`robot_io.gcode._oword`);
* arcs are in :mod:`robot_io.gcode._arcs`, homing/G53 and canned cycles in
  :mod:`robot_io.gcode._cycles`, the modal state in :mod:`robot_io.gcode._state`;
* moves go into the columns of :mod:`robot_io.gcode._moves`; ``Move`` objects are only made when
  ``Toolpath.moves`` is read;
* O-word flow control (loops, calls) raises :class:`robot_io.gcode._oword.Jump`, and
  :meth:`_Run.run` goes on reading at its target line (:meth:`_Run.read_from`).

Reading with ``plain=False`` runs every line through the interpreter; ``test_gcode`` checks that
both ways give the same toolpath, warnings and errors.
"""

from __future__ import annotations

import bisect
from collections import Counter
from typing import TYPE_CHECKING, Any

import numpy as np

from robot_io.gcode import _oword
from robot_io.gcode import _words as W
from robot_io.gcode._arcs import arc
from robot_io.gcode._cycles import canned_cycle, group0_move
from robot_io.gcode._line import percent_or_slash, slow_tokens
from robot_io.gcode._moves import START_GIVEN, START_PREVIOUS, START_UNKNOWN, MoveStore
from robot_io.gcode._params import Parameters
from robot_io.gcode._plain import (
    MIN_RUN,
    PlainLines,
    execute_plain,
    plain_spans,
    scan_plain_lines,
)
from robot_io.gcode._state import DEG, PLANES, ModalState
from robot_io.options import fix, without_lenient_hint
from robot_io.rotary import TrunnionKinematics, make_rotary_kinematics
from robot_io.toolpath import SourceRef, Toolpath, ToolpathError, ToolpathWarning

if TYPE_CHECKING:
    from robot_io.gcode import GcodeOptions

__all__ = ["run_program"]

_MOTION = W.CANNED_CYCLES | set(W.MOTION_G)
_MODAL = frozenset({170, 180, 190, 200, 210, 900, 910, 901, 911, 930, 940}) | (
    W.HARMLESS_G | W.WORK_OFFSETS_G | W.CUTTER_COMP_G)
_AXES = frozenset("XYZABC")
_ARC = frozenset("IJKR")
_FIRST_COL = frozenset("XYZABCIJKR")


def run_program(text: str, file: str, strict: bool, opts: GcodeOptions,
                plain: bool = True) -> Toolpath:
    """Interpret ``text`` as one G-code program; ``plain=False`` reads every line with the
    line-by-line interpreter (the reference the bulk path is tested against)."""
    return _Run(file, strict, opts).run(text, plain)


class _Run:
    """One reading of one program."""

    def __init__(self, file: str, strict: bool, opts: GcodeOptions) -> None:
        self.file = file
        self.strict = strict
        self.opts = opts
        self.kin: TrunnionKinematics | None = (
            None if opts.rotary == "none"
            else make_rotary_kinematics(opts.rotary, opts.pivot, opts.c_offset))
        self.st = ModalState(scale=W.MM if opts.default_units == "mm" else W.INCH)
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
        self.store = MoveStore(file)
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
        self.after_end = 0   # lines after M2/M30
        self.line = 0
        self.keys: dict[str, int | None] = {}   # G/M number text → code key
        self.first_line = 0                      # first line that is not blank
        self.raw = ""                            # the line being tokenised, as written
        self.params = Parameters()               # LinuxCNC #1 … and #<name> parameters
        self.started = False                     # a block has been read (O number or not)
        self.lines: list[str] = []               # the program, for O-word flow control
        self.flow: _oword.Flow | None = None     # its O-lines and state, from the first one
        self.cycle_repeats = 0                   # canned-cycle repeats beyond each first (L)

    # ------------------------------------------------------------------ problems and warnings
    def warn(self, col: int, category: str, message: str, line: int | None = None) -> None:
        """Record a warning (kept up to ``MAX_WARNINGS_PER_CATEGORY`` per category)."""
        self.warn_counts[category] += 1
        n = self.warn_counts[category]
        if n <= W.MAX_WARNINGS_PER_CATEGORY:
            if n == W.MAX_WARNINGS_PER_CATEGORY:
                message += " (further warnings of this kind are only counted)"
            src = SourceRef(self.file, self.line if line is None else line, col)
            self.warnings.append(ToolpathWarning(src, without_lenient_hint(message), category))

    def problem(self, col: int, category: str, reason: str, skip: str | None = None) -> None:
        """Strict: raise :class:`ToolpathError`. Lenient: warn and count ``skip``."""
        if self.strict:
            raise ToolpathError(self.file, self.line, col, reason)
        self.warn(col, category, reason)
        if skip is not None:
            self.skipped[skip] += 1

    # ------------------------------------------------------------------ the line loop
    def run(self, text: str, plain: bool = True) -> Toolpath:
        lines = self.lines = text.split("\n")
        nlines = len(lines)
        # the bulk path needs runs of MIN_RUN lines and no rotary kinematics (see _plain)
        bulk = plain and nlines >= MIN_RUN and self.kin is None
        scan = scan_plain_lines(text, nlines, MIN_RUN) if bulk else None
        spans = [] if scan is None else plain_spans(scan, MIN_RUN)
        start = 0
        while True:   # O-word flow control jumps: go on at the target line
            try:
                self.read_from(start, lines, scan, spans)
                break
            except _oword.Jump as jump:
                start = jump.target
        if self.after_end and self.flow is not None:   # subroutines written after M2/M30
            self.after_end -= self.flow.definitions_after(self.end_line - 1, lines)
        if self.after_end:
            self.skipped["after_program_end"] += self.after_end
            self.warn(0, "after_program_end", f"{self.after_end} line(s) after M2/M30 ignored "
                      "(the machine stops at the program end)", line=self.end_line)
        return self.finish(nlines)

    def read_from(self, start: int, lines: list[str], scan: PlainLines | None,
                  spans: list[tuple[int, int]]) -> None:
        """Read from line index ``start`` to the end: runs of plain lines in bulk, the lines
        between them (and any line a run stops at) one by one."""
        k = bisect.bisect_left(spans, (start, 0))   # the first run at or after start …
        if k and spans[k - 1][1] > start:            # … or the one start is in
            k -= 1
        done = start
        for a, b in spans[k:]:
            for i in range(done, a):
                self.read_line(i + 1, lines[i])
            a = max(a, done)
            while a < b:
                c = execute_plain(self, scan, a, b) if b - a >= MIN_RUN else a
                if c < b:   # the bulk path stopped: this line needs the interpreter
                    self.read_line(c + 1, lines[c])
                    c += 1
                a = c
            done = b
        for i in range(done, len(lines)):
            self.read_line(i + 1, lines[i])

    def read_line(self, number: int, raw: str) -> None:
        """Read and execute line ``number`` (1-based) as written."""
        findall = W.TOKEN.findall
        keys = self.keys
        first_col = _FIRST_COL
        line = raw.rstrip()
        if not line:
            return
        if self.ended:
            self.after_end += line.strip() != "%"
            return
        self.line = number
        if not self.first_line:
            self.first_line = number
        u = line.upper() if line.isascii() else line.translate(W.ASCII_UPPER)
        first = u[0]
        if first == " " or first == "\t":
            first = u.lstrip()[0]
        if first == "%" or first == "/":
            u = percent_or_slash(self, u, first)
            if u is None:
                return
        # Words only (the common case): every letter on the line starts a word, so a word's
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
            return
        self.raw = line
        parsed = slow_tokens(self, u)
        if parsed is not None and (parsed[0] or parsed[1]):
            self.block(*parsed)

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
                self.started = True
                return
        end_program = self.m_codes(mcodes) if mcodes else False
        if "O" in words:
            _oword.program_number(self, *words.pop("O"), not self.started)
        self.started = True
        if "E" in words or "U" in words or "V" in words or "W" in words:
            for letter in "EUVW":
                if letter in words:
                    hint = " — exponents like X1E5 are no G-code" if letter == "E" else ""
                    self.problem(words.pop(letter)[1], "unknown_word", f"word {letter} is not "
                                 f"read by cctmill (extra axis or vendor word{hint}); "
                                 f"{W.fix_hint()}",
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
            group0_move(self, group0[0], group0[1], words)
        elif st.motion is not None and (has_axes or (st.motion >= 20 and st.motion <= 30
                                                      and not _ARC.isdisjoint(words))):
            code = st.motion
            if code in W.CANNED_CYCLES:
                canned_cycle(self, code, col0, words)
            else:
                pos, rot = self.target(words) if has_axes else (st.pos, st.rot)
                if code >= 20:
                    arc(self, code, col0, words, pos, rot, line_f)
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
                        if takes_axes and not self.strict else "") + f"; {W.fix_hint()}",
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
            elif key == 980 or key == 990:
                _oword.fanuc_subprogram(self, key, col)
            else:
                self.problem(col, "unknown_m", f"unknown M code M{num}; {W.fix_hint()}",
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
            if key in PLANES:
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
                             f"(I/J/K tool-axis vectors on G1 are not read); {W.fix_hint()}",
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
                                 f"kinematics for it{hint}: choose one with "
                                 f"{fix('rotary', 'xyzac-trunnion')} (or "
                                 f"{fix('rotary', 'xyzbc-trunnion')}), or read with "
                                 f"{fix('strict', False)} to keep the raw angle in Move.extra",
                                 skip="rotary_word")
                if absolute:
                    rot[letter] = w[0] * DEG
                elif rot[letter] is not None:
                    rot[letter] += w[0] * DEG
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
        sparse: dict[str, Any] | None = None
        if start is None:
            self.meta["unknown_start_moves"] += 1
            flag = START_UNKNOWN
        elif start is self.initial_tip and not self.store.count:
            flag = START_GIVEN
            sparse = {"start": _frozen(start)}
        else:
            flag = START_PREVIOUS
        if arc is not None:
            sparse = sparse or {}
            sparse.update(center=_frozen(arc[0]), normal=_frozen(arc[1]), turns=arc[2])
        if self.rot_used:
            sparse = sparse or {}
            sparse["extra"] = {k: v for k, v in rot.items() if v is not None}
            if self.kin is not None:
                tilt, c = rot[self.kin.tilt], rot["C"]
                if tilt is not None and c is not None:
                    sparse["tool_axis"] = _frozen(self.kin.tool_axis(tilt, c))
        spindle = None if st.spindle_s is None else (st.spindle_s if st.spindle_on else 0.0)
        self.store.add(code, self.line, col, tip, flag, feed, duration, spindle, st.tool, sparse)
        self.last_tip = tip

    def unknown_end(self, col: int, pos: list, rot: dict) -> None:
        missing = [k for k, v in zip("XYZ", pos, strict=True) if v is None]
        if not missing and self.kin is not None:
            missing = [k for k in (self.kin.tilt, "C") if rot[k] is None]
        self.last_tip = None
        self.skipped["unknown_position"] += 1
        given = (f"give the start with {fix('initial_position')}" if not self.meta["homing_blocks"]
                 else f"give the home with {fix('home_position')}")
        self.warn(col, "unknown_position", f"move skipped: position of {'/'.join(missing)} not "
                  "known yet (program start, G28/G30 or G53); program every axis absolutely "
                  f"first, or {given}")

    # ------------------------------------------------------------------ the result
    def finish(self, nlines: int) -> Toolpath:
        if self.units is None:
            other = "inch" if self.opts.default_units == "mm" else "mm"
            self.warn(0, "no_units", f"no G20/G21 in the program: read as "
                      f"{self.opts.default_units} (use {fix('default_units', other)} if the "
                      f"machine starts in {other})", line=self.default_units_line or 1)
        elif self.default_units_line is not None:
            self.warn(0, "moves_before_units", f"moves before the first G20/G21 were read in "
                      f"{self.opts.default_units}", line=self.default_units_line)
        self.meta["warning_counts"] = dict(self.warn_counts)
        self.meta["lines"] = nlines
        self.meta["work_offsets"] = sorted(set(self.meta["work_offsets"]))
        return Toolpath(file=self.file, format="gcode",
                        units=self.units or self.opts.default_units, moves=self.store.finish(),
                        warnings=self.warnings, skipped=self.skipped, meta=self.meta)


def _frozen(v: Any) -> np.ndarray:
    a = np.array(v, dtype=float)
    a.flags.writeable = False
    return a
