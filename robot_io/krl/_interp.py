"""The KRL interpreter behind ``robot_io.krl.reader`` (private; conventions are documented there).

It runs a program the way the controller's advance run would see it, statement by statement:
``.dat`` data and declarations (:mod:`robot_io.krl._values`), ``$VEL.CP``/``$BASE``/``$TOOL``,
``BAS(...)`` (:mod:`robot_io.krl._bas`), motions (carried out by
:class:`robot_io.krl._motion.RobotState`), control blocks (:mod:`robot_io.krl._loops`: FOR
unrolled, IF decided, the rest skipped or refused), and calls into local routines and sibling
modules, with a call stack for cycle protection. Everything it does not model but knows cannot move
the robot is counted in ``Toolpath.skipped`` by category.
"""

from __future__ import annotations

import os
from collections import Counter
from functools import partial

from robot_io.krl._bas import run_bas
from robot_io.krl._loops import loop_context, run_block
from robot_io.krl._motion import RobotState, frame_from
from robot_io.krl._program import (
    BLOCKS,
    MOTIONS,
    SPLINE_MOTIONS,
    Routine,
    SrcFile,
    Stmt,
    find_beside,
    parse_dat,
    parse_src,
    read_text,
)
from robot_io.krl._syntax import Aggregate, Cursor, LineError, Ref, parse_ref, parse_value
from robot_io.krl._values import (
    CART,
    Ctx,
    Current,
    Module,
    Var,
    Variables,
    expect_end,
)
from robot_io.options import fix, without_lenient_hint
from robot_io.toolpath import SourceRef, Toolpath, ToolpathError, ToolpathWarning

__all__ = [
    "EXECUTED_FLOOR",
    "EXECUTED_PER_LINE",
    "MAX_CALL_DEPTH",
    "MAX_EXECUTED_STATEMENTS",
    "MAX_WARNINGS_PER_CATEGORY",
    "Runner",
]

#: Deepest chain of routine calls the reader follows.
MAX_CALL_DEPTH = 64
#: Statements executed in one reading before the reader gives up (a cascade of sub-module calls
#: could otherwise run for ever); a 2 500-line page run 2 000 times is 5 M, and so is a FOR loop
#: of 1 M points (``robot_io.krl._loops.MAX_UNROLLED_MOVES``) with five statements per point.
MAX_EXECUTED_STATEMENTS = 5_000_000
#: Below that, the work a reading may do grows with what it read: at most
#: ``EXECUTED_PER_LINE`` statements per line of the .src and .dat files read, and never fewer than
#: ``EXECUTED_FLOOR`` (about 0.7 s of interpretation). A converter's FOR loop over a 28,000-point
#: .dat array runs one statement per point, far inside; a 300-byte program whose loop runs a
#: hundred thousand times (the fuzz campaign's 7 s input) is stopped with the reason, as the
#: G-code reader stops O-word loops (``MAX_FLOW_LINES``).
EXECUTED_PER_LINE = 20
EXECUTED_FLOOR = 20_000
#: Warnings kept per category; further ones are only counted (``meta["warning_counts"]``).
MAX_WARNINGS_PER_CATEGORY = 50

_AXES = tuple(f"A{i}" for i in range(1, 7))
_EXT = tuple(f"E{i}" for i in range(1, 7))
_POS_KEYS = frozenset(CART + _AXES + _EXT + ("S", "T"))

#: Keywords of statements that run on the controller but never move the robot → skip category.
_SKIP = {
    "HALT": "halt", "WAIT": "wait", "INTERRUPT": "interrupt", "BRAKE": "interrupt",
    "RESUME": "interrupt", "TRIGGER": "trigger", "PULSE": "io", "ANOUT": "io", "ANIN": "io",
    "CWRITE": "io", "CREAD": "io", "SREAD": "io", "SWRITE": "io", "COPEN": "io", "CCLOSE": "io",
    "CIOCTL": "io", "CONTINUE": "advance_stop", "ON_ERROR_PROCEED": "system",
    "EXT": "declaration", "EXTFCT": "declaration", "EXTP": "declaration",
    "EXTFCTP": "declaration", "SIGNAL": "declaration", "ENUM": "declaration",
    "STRUC": "declaration", "IMPORT": "declaration",
}
_TYPES = frozenset({"INT", "REAL", "BOOL", "CHAR", "FRAME", "POS", "E6POS", "AXIS", "E6AXIS"})
#: KUKA system routines that run without moving the robot (called as statements).
_BUILTIN_CALLS = frozenset({
    "SET_CD_PARAMS", "USE_CD_PARAMS", "MSGNOTIFY", "MSGQUIT", "MSGLOOP", "MSGDIALOG", "STRCLEAR",
    "STRCOPY", "STRADD", "STRCOMP", "STRFIND", "STRLEN", "STRDECLLEN", "SET_KRLMSG",
    "CLEAR_KRLMSG", "EXISTS_KRLMSG", "VARSTATE", "WAIT_FOR_ON", "PULSE",
})
_BUILTIN_PREFIXES = ("EKI_", "RSI_", "ST_")
#: System routines with those prefixes that *do* move the robot (sensor-guided motion).
_MOVING_BUILTINS = frozenset({"RSI_MOVECORR", "ST_SKIPSENS", "ST_MOVECORR"})
#: Keywords of statements after whose failure the robot's position is no longer known.
_MOVING_KEYWORDS = MOTIONS | SPLINE_MOTIONS | frozenset(BLOCKS)
#: Keywords that only make sense inside a block or file structure the parser already matched.
_STRAY = frozenset(BLOCKS.values()) | frozenset({"ELSE", "CASE", "DEFAULT", "DEFDAT", "ENDDAT",
                                                 "END", "ENDFCT", "THEN"})

Target = tuple[str, dict[str, float], int, str]   # kind, components, column, name


class _Problem(ToolpathError):
    """A ToolpathError with the warning category lenient reading counts it under."""

    def __init__(self, file: str, line: int, column: int, reason: str, category: str,
                 fatal: bool = False) -> None:
        super().__init__(file, line, column, reason)
        self.category = category
        self.fatal = fatal


def _src(st: Stmt, col: int) -> str:
    return str(SourceRef(st.file, st.line, col))


def _is_call(st: Stmt) -> bool:
    if st.fast is not None:
        return False
    t = st.tokens
    return len(t) > 1 and t[0].kind == "name" and t[1].text == "("


def _builtin(name: str) -> bool:
    return name in _BUILTIN_CALLS or (name.startswith(_BUILTIN_PREFIXES)
                                      and name not in _MOVING_BUILTINS)


class Runner:
    """One reading of one program."""

    def __init__(self, file: str, strict: bool, ignore_calls: tuple[str, ...],
                 folder: str | None) -> None:
        self.strict = strict
        self.ignore_calls = frozenset(n.upper() for n in ignore_calls)
        self.folder = folder
        self.tp = Toolpath(file=file, format="krl", units="mm")
        self.meta = self.tp.meta
        self.meta.update({
            "program": None, "modules": [], "encoding": None, "lines": 0, "joint_moves": [],
            "base": None, "tool": None, "base_changes": [], "tool_changes": [],
            "unknown_start_moves": 0, "advance": None, "ipo_mode": None,
        })
        self.warn_counts: Counter = Counter()
        self.modules: dict[str, Module] = {}
        self.vars = Variables()
        self.robot = RobotState(self.tp, self.soft, self.warn)
        self.stack: list[tuple[tuple[str, str], str]] = []   # (key, routine name as written)
        self.executed = 0
        self.loops: list[tuple[str, int, int, Var]] = []    # FOR loops running: name, k, line

    # ------------------------------------------------------------------ problems and warnings
    def warn(self, file: str, line: int, col: int, message: str, category: str) -> None:
        """Record a warning (kept up to ``MAX_WARNINGS_PER_CATEGORY`` per category)."""
        self.warn_counts[category] += 1
        n = self.warn_counts[category]
        if n <= MAX_WARNINGS_PER_CATEGORY:
            if n == MAX_WARNINGS_PER_CATEGORY:
                message += " (further warnings of this kind are only counted)"
            self.tp.warnings.append(ToolpathWarning(SourceRef(file, line, col),
                                                    without_lenient_hint(message), category))

    def report(self, file: str, line: int, col: int, reason: str, category: str) -> None:
        """Strict: raise. Lenient: warn and count ``category`` as skipped."""
        if self.strict:
            raise _Problem(file, line, col, reason, category)
        self.warn(file, line, col, reason, category)
        self.tp.skipped[category] += 1

    def soft(self, st: Stmt, col: int, reason: str, category: str) -> None:
        """Strict: raise. Lenient: warn and go on with the statement (nothing skipped)."""
        if self.strict:
            raise _Problem(st.file, st.line, col, reason, category)
        self.warn(st.file, st.line, col, reason, category)

    # ------------------------------------------------------------------ modules
    def load(self, path: str, src_text: str | None = None, dat_text: str | None = None,
             at: tuple[Stmt, int] | None = None) -> Module:
        """Parse a module (``.src`` and its ``.dat``) once; run its ``.dat`` declarations."""
        key = path if src_text is not None else os.path.normcase(os.path.abspath(path))
        if key in self.modules:
            return self.modules[key]
        stem = os.path.splitext(os.path.basename(path))[0]
        dat_path: str | None = None
        if src_text is None:
            src_text, encoding = self._read(path, at)
            if self.meta["encoding"] is None:
                self.meta["encoding"] = encoding
            dat_path = find_beside(os.path.dirname(path) or ".", stem, ".dat")
            if dat_path is not None:
                dat_text, _ = self._read(dat_path, at)
        src = parse_src(src_text, path, self.report)
        if not src.routines or src.routines[0].is_function:
            raise _Problem(path, 1, 0, "no DEF NAME( ) … END routine in the file: a .src module "
                           "starts with DEF (after optional & header lines)", "structure",
                           at is None)
        main = src.routines[0]
        if path != "<string>" and main.name.upper() != stem.upper():
            self.warn(path, main.line, 1, f"DEF {main.name} does not match the file name "
                      f"{stem!r}; the controller requires them equal (rename one)", "module_name")
        mod = Module(main.name, path, src)
        self.modules[key] = mod
        self.meta["modules"].append(path)
        self.meta["lines"] += src.lines
        self.tp.skipped["header"] += src.header_lines
        if dat_text is not None:
            self.run_dat(mod, dat_text, dat_path or (os.path.splitext(path)[0] + ".dat"),
                         main.name if path == "<string>" else stem)
        return mod

    def _read(self, path: str, at: tuple[Stmt, int] | None) -> tuple[str, str]:
        try:
            return read_text(path)
        except OSError as e:
            st_file, line, col = (at[0].file, at[0].line, at[1]) if at else (path, 0, 0)
            raise _Problem(st_file, line, col, f"cannot read {path} ({e.strerror}); check the "
                           "path", "missing_module", at is None) from e

    def run_dat(self, mod: Module | None, text: str, path: str, stem: str | None) -> None:
        """Execute a ``.dat``'s declarations into ``mod.vars``; without a module (``global_dat``)
        every item is a global."""
        if mod is None:
            mod = Module(os.path.splitext(os.path.basename(path))[0], path,
                         SrcFile(path, [], 0, 0), self.vars.globals)
        dat = parse_dat(text, path, self.report)
        self.meta["lines"] += dat.lines
        self.tp.skipped["header"] += dat.header_lines
        if stem is not None and dat.name is not None and dat.name.upper() != stem.upper():
            self.warn(path, 1, 1, f"DEFDAT {dat.name} does not match the module name {stem!r}; "
                      "the controller requires them equal", "module_name")
        ctx = Ctx(mod, None)
        for st in dat.body:
            try:
                if st.data is not None:         # NAME[i]={X …} / DECL E6POS NAME={X …}
                    self.vars.set_data(ctx, mod.vars, mod.vars, st)
                    continue
                kw = st.keyword
                toks = st.tokens
                if kw == "DECL" or (kw in _TYPES and len(toks) > 1 and toks[1].kind == "name"):
                    self.vars.declare(ctx, mod.vars, st)
                elif _SKIP.get(kw) == "declaration":
                    self.tp.skipped["declaration"] += 1
                elif toks[0].kind == "name" and len(toks) > 1 and toks[1].text in ("[", "=", "."):
                    cur = Cursor(toks, st.end_col)
                    ref = parse_ref(cur, partial(self.vars.index, ctx))
                    cur.expect("=", "'=' (a .dat holds declarations and NAME = value lines)")
                    self.vars.assign(ctx, st, ref, cur, mod.vars)
                else:
                    raise LineError(toks[0].col, f"unexpected {toks[0].text!r} in a .dat: it "
                                    "holds only DECL, EXT and NAME = value lines", "structure")
            except LineError as e:
                self.report(st.file, st.line, e.col, e.reason, e.category)

    # ------------------------------------------------------------------ running
    def run_main(self, mod: Module) -> Toolpath:
        """Run the module's first routine and finish the toolpath."""
        main = mod.src.routines[0]
        self.meta["program"] = main.name
        try:
            self.run_routine(mod, main)
        except _Problem as p:
            raise ToolpathError(p.file, p.line, p.column, p.reason) from None
        if self.meta["base"] is None:
            self.meta["base"] = self.robot.base.as_meta()
            self.meta["tool"] = self.robot.tool.as_meta()
        self.meta["warning_counts"] = dict(self.warn_counts)
        return self.tp

    def run_routine(self, mod: Module, routine: Routine) -> None:
        """Execute a routine's statements in order (lenient mode recovers per statement)."""
        self.stack.append(((mod.path.upper(), routine.name.upper()), routine.name))
        try:
            self.run_range(Ctx(mod, routine), 0, len(routine.body))
        finally:
            self.stack.pop()

    def run_range(self, ctx: Ctx, start: int, stop: int) -> bool:
        """Execute the routine's statements ``start`` … ``stop - 1`` (a routine, a loop body, a
        branch); False after a RETURN."""
        routine = ctx.routine
        if routine is None:
            raise ValueError("run_range needs a routine")
        body = routine.body
        i = start
        while i < stop:
            st = body[i]
            self.executed += 1
            if self.executed > EXECUTED_FLOOR and self.executed > min(
                    MAX_EXECUTED_STATEMENTS, EXECUTED_PER_LINE * self.meta["lines"]):
                budget = max(EXECUTED_FLOOR, min(MAX_EXECUTED_STATEMENTS,
                                                 EXECUTED_PER_LINE * self.meta["lines"]))
                raise _Problem(st.file, st.line, 0, f"more than {budget} statements executed "
                               f"for {self.meta['lines']} lines read (EXECUTED_PER_LINE = "
                               f"{EXECUTED_PER_LINE}, at least {EXECUTED_FLOOR}, at most "
                               f"{MAX_EXECUTED_STATEMENTS}): the sub-module calls or loops run "
                               "far longer than the program is (check the page calls and the "
                               "loop bounds)", "limit", True)
            try:
                nxt = self.execute(ctx, st, i)
            except LineError as e:
                reason = e.reason + loop_context(self)
                if self.strict or e.fatal:
                    raise _Problem(st.file, st.line, e.col, reason, e.category,
                                   e.fatal) from None
                self.report(st.file, st.line, e.col, reason, e.category)
                nxt = self._recover(st, i, routine)
            except _Problem as p:
                if self.strict or p.fatal:
                    raise
                self.warn(p.file, p.line, p.column, p.reason, p.category)
                self.tp.skipped[p.category] += 1
                nxt = self._recover(st, i, routine)
            if nxt < 0:
                return False
            i = nxt
        return True

    def may_move(self, st: Stmt) -> bool:
        """Whether a statement may move the robot (a motion, or a call that is not a known
        non-moving routine)."""
        kw = st.keyword
        return (kw in MOTIONS or kw in SPLINE_MOTIONS
                or (_is_call(st) and self._call_may_move(st.tokens[0].upper)))

    def _recover(self, st: Stmt, i: int, routine: Routine) -> int:
        """After a skipped statement (lenient): forget the position if it may have moved."""
        if st.keyword in _MOVING_KEYWORDS or _is_call(st):
            self.robot.lose_position(f"after the skipped statement at {st.file}:{st.line}")
        return routine.block_end.get(i, i) + 1

    def execute(self, ctx: Ctx, st: Stmt, i: int) -> int:
        """Run one statement; the index of the next one (-1 after RETURN)."""
        kw = st.keyword
        if kw in MOTIONS:
            self.motion(ctx, st)
            return i + 1
        if st.data is not None:                 # NAME[i]={X …} / DECL E6POS NAME={X …}
            self.vars.set_data(ctx, ctx.locals, None, st)
            return i + 1
        toks = st.tokens
        t0 = toks[0]
        if kw in SPLINE_MOTIONS:
            raise LineError(t0.col, f"{t0.text} (spline motion) is not supported by the reader: "
                            "write the path as LIN/CIRC motions (a CAM post option), or read with "
                            f"{fix('strict', False)} to skip it", "unsupported_motion")
        if kw in BLOCKS:
            return run_block(self, ctx, st, i)
        if kw == "RETURN":
            return -1
        if kw == "DECL" or (kw in _TYPES and len(toks) > 1 and toks[1].kind == "name"):
            self.vars.declare(ctx, ctx.locals, st)
        elif kw in _SKIP:
            self.tp.skipped[_SKIP[kw]] += 1
        elif kw == "GLOBAL" and len(toks) > 1 and toks[1].upper == "INTERRUPT":
            self.tp.skipped["interrupt"] += 1
        elif kw in ("GOTO", "EXIT"):
            raise LineError(t0.col, f"{t0.text} is not followed by the reader: rewrite the "
                            "program as straight-line code", "control_flow")
        elif _is_call(st):
            self.call(ctx, st)
        elif t0.kind == "name" and len(toks) == 2 and toks[1].text == ":":
            self.tp.skipped["label"] += 1
        elif t0.kind == "name" and kw not in _STRAY:
            cur = Cursor(toks, st.end_col)
            ref = parse_ref(cur, partial(self.vars.index, ctx))
            if cur.accept("=") is None:
                self._unknown_statement(t0.text, t0.col)
            self.assign(ctx, st, ref, cur)
        else:
            self._unknown_statement(t0.text, t0.col)
        return i + 1

    @staticmethod
    def _unknown_statement(text: str, col: int) -> None:
        hint = " (a bare INI is not KRL: write BAS(#INITMOV,0))" if text.upper() == "INI" else ""
        raise LineError(col, f"unknown statement {text!r}{hint}: the reader runs PTP/LIN/CIRC, "
                        "assignments, NAME( ) calls, DECL, WAIT, HALT, FOR loops and the like; "
                        f"remove it, or read with {fix('strict', False)} to skip it",
                        "unknown_statement")

    # ------------------------------------------------------------------ assignments
    def assign(self, ctx: Ctx, st: Stmt, ref: Ref, cur: Cursor) -> None:
        """``ref = value``: the system variables the reader uses, else a user variable."""
        name, fields = ref.name, ref.fields
        if name == "$VEL" and ref.index is None and fields in ((), ("CP",)):
            col = cur.col
            v = parse_value(cur, partial(self.vars.resolve, ctx))
            expect_end(cur)
            if not fields:
                if not isinstance(v, Aggregate) or "CP" not in v.fields:
                    self.tp.skipped["system_variable"] += 1
                    return
                v = v.fields["CP"]
            self.robot.set_feed(st, col, v, "$VEL.CP")
        elif name in ("$BASE", "$TOOL") and ref.index is None and not fields:
            self.select_frame(ctx, st, name[1:], cur)
        elif name.startswith("$"):
            if name in ("$OUT", "$ANOUT", "$OUT_C"):
                self.tp.skipped["io"] += 1
                return
            self.tp.skipped["system_variable"] += 1
            if name in ("$APO", "$ADVANCE", "$IPO_MODE"):
                v = self.vars.value_or_unknown(ctx, cur, st)
                if name == "$APO" and fields == ("CDIS",) and isinstance(v, float):
                    self.robot.apo_cdis = v * 1e-3            # mm → m
                elif name == "$ADVANCE" and not fields and isinstance(v, float):
                    self.meta["advance"] = int(v)
                elif name == "$IPO_MODE" and not fields:
                    self.meta["ipo_mode"] = v if isinstance(v, str) else None
                    if v == "#TCP":
                        raise LineError(st.tokens[0].col, "$IPO_MODE = #TCP (external, "
                                        "stationary tool) is not supported: the program's "
                                        "positions would be the workpiece held by the robot",
                                        "unsupported_motion")
        else:
            self.vars.assign(ctx, st, ref, cur, None)

    # ------------------------------------------------------------------ frames
    def select_frame(self, ctx: Ctx, st: Stmt, which: str, cur: Cursor) -> None:
        """``$BASE = …`` / ``$TOOL = …`` (literal, FRAME variable, BASE_DATA[n], $NULLFRAME)."""
        col = cur.col
        probe = Cursor(cur.toks, cur.end_col, cur.i)
        name = "literal"
        index = None
        t = probe.peek()
        if t is not None and t.kind == "name":
            try:
                r = parse_ref(probe, partial(self.vars.index, ctx))
                if probe.at_end():
                    name = r.text
                    if r.name in ("BASE_DATA", "TOOL_DATA") and r.index and len(r.index) == 1:
                        index = r.index[0]
            except LineError:
                name = "expression"
        value = self.vars.value_or_unknown(ctx, cur, st)
        expect_end(cur)
        self.robot.apply_frame(st, col, which, frame_from(value, name, _src(st, col), col, index))

    # ------------------------------------------------------------------ calls
    def _call_may_move(self, name: str) -> bool:
        return not (name == "BAS" or name in self.ignore_calls or _builtin(name))

    def call(self, ctx: Ctx, st: Stmt) -> None:
        """``NAME(args)``: BAS, a local routine, a sibling module, or a known system routine."""
        tok = st.tokens[0]
        name = tok.upper
        cur = Cursor(st.tokens, st.end_col, 2)
        if name == "BAS":
            run_bas(self, ctx, st, cur)
            return
        depth = 1
        while depth:                          # brackets balance on the line
            t = cur.next("')'")
            if t.kind == "sym":
                depth += (t.text == "(") - (t.text == ")")
        expect_end(cur)
        if name in self.ignore_calls:
            self.tp.skipped["ignored_call"] += 1
            return
        mod, routine = ctx.module, ctx.module.src.routine(name)
        if routine is None:
            path = find_beside(self.folder, tok.text, ".src")
            if path is not None:
                mod = self.load(path, at=(st, tok.col))
                routine = mod.src.routines[0]
        if routine is None:
            if _builtin(name):
                self.tp.skipped["builtin_call"] += 1
                return
            if name in _MOVING_BUILTINS:
                raise LineError(tok.col, f"{tok.text} moves the robot under sensor control; "
                                "the reader cannot follow it", "unsupported_motion")
            where = self.folder if self.folder is not None else "(no folder: text input)"
            raise LineError(tok.col, f"{tok.text}( ) is called but {tok.text}.src is not in "
                            f"{where}: put the sub-module beside the main program, or pass "
                            f"{fix('ignore_calls', [tok.text])} if it does not move the robot",
                            "missing_module")
        key = (mod.path.upper(), routine.name.upper())
        keys = [k for k, _ in self.stack]
        if key in keys:
            chain = " → ".join(n for _, n in self.stack[keys.index(key):])
            raise LineError(tok.col, f"recursive call {chain} → {routine.name}: the reader "
                            "follows each call and cannot unroll recursion; a page must not call "
                            "itself or an earlier page", "recursive_call")
        if len(self.stack) >= MAX_CALL_DEPTH:
            raise LineError(tok.col, f"calls nested deeper than {MAX_CALL_DEPTH}", "limit")
        self.run_routine(mod, routine)

    # ------------------------------------------------------------------ motion
    def _target(self, ctx: Ctx, cur: Cursor) -> Target:
        """(kind, components, column, name) of a motion target; kind ``cart``/``axes``/``current``."""
        col = cur.col
        t = cur.peek()
        name = t.text if t is not None and t.kind == "name" else "literal"
        v = parse_value(cur, partial(self.vars.resolve, ctx))
        if isinstance(v, Current):
            return "current", {}, col, v.name
        if not isinstance(v, Aggregate):
            raise LineError(col, "expected a position: a {X …,Y …,Z …,A …,B …,C …} literal or a "
                            "declared E6POS/POS/FRAME (or E6AXIS/AXIS for PTP) variable")
        f = v.fields
        at = v.col or col
        for k, val in f.items():
            if k not in _POS_KEYS:
                raise LineError(at, f"unknown component {k} in a position: use X, Y, Z, A, B, "
                                "C, S, T, E1–E6 (Cartesian) or A1–A6, E1–E6 (axes)")
            if isinstance(val, bool) or not isinstance(val, (int, float)):
                raise LineError(at, f"component {k} of the position must be a number")
        axes = any(k in f for k in _AXES)
        cart = any(k in f for k in CART + ("S", "T"))
        if axes and cart:
            raise LineError(at, "a position mixes axis values (A1–A6) with Cartesian ones (X…C); "
                            "use one kind")
        if axes or (not cart and v.type_name in ("AXIS", "E6AXIS")):
            return "axes", {k: float(x) for k, x in f.items()}, col, name
        if not cart:
            raise LineError(at, "the position has no coordinates; give X, Y, Z (and A, B, C)")
        return "cart", {k: float(x) for k, x in f.items()}, col, name

    def motion(self, ctx: Ctx, st: Stmt) -> None:
        """PTP, LIN, CIRC and their _REL forms: parse, then hand to the robot state."""
        kw = st.keyword
        if kw == "CIRC_REL":
            raise LineError(st.tokens[0].col, "CIRC_REL is not supported: write the absolute "
                            "CIRC aux, end", "unsupported_motion")
        if st.fast is not None:      # LIN|PTP {X …} [C_DIS], pre-parsed
            _, comps, col, approx = st.fast
            self.robot.move(st, "cart", comps, col, "literal", SourceRef(st.file, st.line, col),
                            None, None, approx, "#BASE")
            return
        cur = Cursor(st.tokens, st.end_col, 1)
        target = self._target(ctx, cur)
        first_col = target[2]
        aux: Target | None = None
        ca: float | None = None
        if kw == "CIRC":
            aux = target
            cur.expect(",", "',' and the end point (CIRC aux, end)")
            target = self._target(ctx, cur)
            if cur.accept(","):
                cur.expect("CA", "CA and the circular angle after ','")
                ca_col = cur.col
                v = parse_value(cur, partial(self.vars.resolve, ctx))
                if isinstance(v, bool) or not isinstance(v, float):
                    raise LineError(ca_col, "CA needs an angle in degrees")
                if v == 0.0:
                    raise LineError(ca_col, "CA 0 makes no motion; remove the CIRC or give the "
                                    "angle", "bad_arc")
                ca = v
        approx: str | None = None
        rel_frame = "#BASE"
        while not cur.at_end():
            t = cur.next("")
            if t.kind == "name" and t.upper in ("C_DIS", "C_PTP", "C_VEL", "C_ORI"):
                approx = t.upper
            elif t.kind == "enum" and t.upper in ("#BASE", "#TOOL") and kw.endswith("_REL"):
                rel_frame = t.upper
            elif t.text == ":":
                raise LineError(t.col, "the geometric operator ':' in a motion is not supported: "
                                "compute the target and write it as a literal",
                                "unsupported_motion")
            else:
                raise LineError(t.col, f"unexpected {t.text!r} after the target of {kw}: "
                                "expected C_DIS, C_VEL, C_ORI or C_PTP (or the end of the line)")
        kind, comps, col, name = target
        self.robot.move(st, kind, comps, col, name, SourceRef(st.file, st.line, first_col), aux,
                        ca, approx, rel_frame)
