"""KRL files as statements: ``.src`` routines and ``.dat`` data lists (private helper of
``robot_io.krl.reader``).

A ``.src`` is split into ``DEF … END`` routines (``DEFFCT … ENDFCT`` functions are kept but never
run); a ``.dat`` into the statements between ``DEFDAT`` and ``ENDDAT``. ``&`` header lines and
``;`` comments (``;FOLD``/``;ENDFOLD`` included — the statements inside folds are kept) are dropped
here. Control blocks (IF/FOR/WHILE/REPEAT/LOOP/SWITCH/SPLINE) are matched — and each IF's ELSE —
so the interpreter can run, skip or inspect a whole block. Problems go to
``report(file, line, col, reason, category)``, which raises in strict mode and records a warning
in lenient mode (then the reader goes on as described at each call).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from robot_io.krl._syntax import (
    FastData,
    LineError,
    Token,
    fast_data,
    fast_motion,
    split_comment,
    tokenize,
)

__all__ = [
    "BLOCKS",
    "MOTIONS",
    "SPLINE_MOTIONS",
    "DatFile",
    "Report",
    "Routine",
    "SrcFile",
    "Stmt",
    "find_beside",
    "parse_dat",
    "parse_src",
    "read_text",
]

#: Control-block openers and the keyword that closes each.
BLOCKS = {
    "IF": "ENDIF", "FOR": "ENDFOR", "WHILE": "ENDWHILE", "REPEAT": "UNTIL", "LOOP": "ENDLOOP",
    "SWITCH": "ENDSWITCH", "SPLINE": "ENDSPLINE", "PTP_SPLINE": "ENDSPLINE",
}
_CLOSERS = set(BLOCKS.values())
#: Motion statements the reader carries out.
MOTIONS = frozenset({"PTP", "LIN", "CIRC", "PTP_REL", "LIN_REL", "CIRC_REL"})
#: Motion statements it does not (spline and asynchronous motion).
SPLINE_MOTIONS = frozenset({
    "SPLINE", "PTP_SPLINE", "ENDSPLINE", "SPL", "SLIN", "SCIRC", "SPTP", "SPTP_REL", "SLIN_REL",
    "SCIRC_REL", "ASYPTP", "ASYCONT", "ASYSTOP", "ASYCANCEL", "MOVE_EMI",
})

Report = Callable[[str, int, int, str, str], None]


class Stmt:
    """One statement: where it is, its first keyword (upper case), the column just past its end,
    and either its tokens or — for a plain ``LIN|PTP {literal}`` line — the pre-parsed ``fast``
    form of :func:`~robot_io.krl._syntax.fast_motion`, or — for a plain ``NAME[i]={literal}`` /
    ``DECL E6POS NAME={literal}`` line — the ``data`` form of :func:`~robot_io.krl._syntax.fast_data`
    (tokens are then made only when asked for).
    """

    __slots__ = ("_tokens", "code", "data", "end_col", "fast", "file", "keyword", "line")

    def __init__(self, file: str, line: int, code: str, tokens: list[Token] | None,
                 fast: tuple[str, dict[str, float], int, str | None] | None = None,
                 data: FastData | None = None) -> None:
        self.file = file
        self.line = line
        self.code = code
        self.end_col = len(code.rstrip()) + 1
        self._tokens = tokens
        self.fast = fast
        self.data = data
        if fast is not None:
            self.keyword = fast[0]
        elif data is not None:
            self.keyword = "DECL" if data[0] is not None else data[2]
        else:
            self.keyword = tokens[0].upper if tokens else ""

    @property
    def tokens(self) -> list[Token]:
        """The tokens (made on demand for a fast-path line, which always tokenizes)."""
        if self._tokens is None:
            self._tokens = tokenize(self.code)
        return self._tokens


@dataclass
class Routine:
    """A ``DEF``/``DEFFCT`` routine: name as written, its statements, matched blocks (opener
    index → closer index), each IF's ELSE (IF index → ELSE index), and a cache the interpreter
    keeps per block (what a loop body holds, worked out once however often the loop runs)."""

    name: str
    file: str
    line: int
    body: list[Stmt] = field(default_factory=list)
    block_end: dict[int, int] = field(default_factory=dict)
    is_function: bool = False
    else_at: dict[int, int] = field(default_factory=dict)
    cache: dict[int, Any] = field(default_factory=dict)


@dataclass
class SrcFile:
    """A parsed ``.src``: its routines in file order (the first is the module's main routine)."""

    path: str
    routines: list[Routine]
    header_lines: int
    lines: int

    def routine(self, name: str) -> Routine | None:
        """The routine (not function) called ``name`` (case-insensitive), if any."""
        up = name.upper()
        for r in self.routines:
            if r.name.upper() == up and not r.is_function:
                return r
        return None


@dataclass
class DatFile:
    """A parsed ``.dat``: its name after ``DEFDAT`` and its statements."""

    path: str
    name: str | None
    body: list[Stmt]
    header_lines: int
    lines: int


def read_text(path: str) -> tuple[str, str]:
    """Text and encoding of a KRL file (UTF-8, else Windows-1252, else Latin-1); OSError passes."""
    with open(path, "rb") as fh:
        data = fh.read()
    for enc in ("utf-8-sig", "cp1252"):
        try:
            return data.decode(enc), enc.removesuffix("-sig")
        except UnicodeDecodeError:
            continue
    return data.decode("latin-1"), "latin-1"


def find_beside(folder: str | None, stem: str, ext: str) -> str | None:
    """Path of ``stem + ext`` in ``folder``, matching the name case-insensitively (controller file
    systems are case-insensitive), or ``None``."""
    if folder is None or not os.path.isdir(folder):
        return None
    want = (stem + ext).lower()
    try:
        names = sorted(os.listdir(folder))
    except OSError:
        return None
    for name in names:
        if name.lower() == want and os.path.isfile(os.path.join(folder, name)):
            return os.path.join(folder, name)
    return None


def _statements(text: str, file: str, report: Report) -> tuple[list[Stmt], int, int]:
    """Statements of a file, the number of ``&`` header lines and of lines."""
    out: list[Stmt] = []
    headers = 0
    lines = text.split("\n")
    for no, raw in enumerate(lines, start=1):
        raw = raw.rstrip("\r")
        stripped = raw.lstrip()
        if not stripped or stripped.startswith(";"):
            continue
        if stripped.startswith("&"):
            headers += 1
            continue
        code = split_comment(raw)
        if not code.strip():
            continue
        fast = fast_motion(code)
        if fast is not None:
            out.append(Stmt(file, no, code, None, fast))
            continue
        data = fast_data(code)
        if data is not None:
            out.append(Stmt(file, no, code, None, None, data))
            continue
        try:
            toks = tokenize(code)
        except LineError as e:
            report(file, no, e.col, e.reason, e.category)
            continue
        out.append(Stmt(file, no, code, toks))
    return out, headers, len(lines)


def _match_blocks(r: Routine, report: Report) -> None:
    stack: list[int] = []
    for i, st in enumerate(r.body):
        kw = st.keyword
        if kw in BLOCKS:
            stack.append(i)
        elif kw == "ELSE" and stack and r.body[stack[-1]].keyword == "IF":
            if stack[-1] in r.else_at:
                report(st.file, st.line, st.tokens[0].col, f"a second ELSE in the IF of line "
                       f"{r.body[stack[-1]].line}; an IF has at most one ELSE", "syntax")
            else:
                r.else_at[stack[-1]] = i
        elif kw in _CLOSERS:
            if stack and BLOCKS[r.body[stack[-1]].keyword] == kw:
                r.block_end[stack.pop()] = i
            else:
                want = (f"{BLOCKS[r.body[stack[-1]].keyword]} (closing the "
                        f"{r.body[stack[-1]].keyword} of line {r.body[stack[-1]].line})"
                        if stack else "no closing keyword here")
                report(st.file, st.line, st.tokens[0].col, f"{kw} without a matching opening "
                       f"statement; expected {want}", "syntax")
    for i in stack:
        st = r.body[i]
        report(st.file, st.line, st.tokens[0].col, f"{st.keyword} at line {st.line} has no "
               f"{BLOCKS[st.keyword]} before the END of {r.name}; close the block", "syntax")
        r.block_end[i] = len(r.body) - 1


def _def_name(st: Stmt, report: Report) -> tuple[str, bool] | None:
    """(name, is_function) when ``st`` opens a routine, else None."""
    if st.keyword not in ("DEF", "DEFFCT", "GLOBAL"):
        return None
    toks = st.tokens
    k = 1 if toks[0].upper == "GLOBAL" and len(toks) > 1 else 0
    kw = toks[k].upper
    if kw not in ("DEF", "DEFFCT"):
        return None
    j = k + (1 if kw == "DEF" else 2)     # DEFFCT has the return type first
    if j >= len(toks) or toks[j].kind != "name":
        col = toks[j].col if j < len(toks) else st.end_col
        report(st.file, st.line, col, f"{kw} needs a routine name, e.g. {kw} "
               f"{'REAL ' if kw == 'DEFFCT' else ''}NAME( )", "syntax")
        return (f"<unnamed line {st.line}>", kw == "DEFFCT")
    return toks[j].text, kw == "DEFFCT"


def parse_src(text: str, file: str, report: Report) -> SrcFile:
    """Split a ``.src`` into routines; statements outside ``DEF … END`` are reported and dropped."""
    stmts, headers, nlines = _statements(text, file, report)
    routines: list[Routine] = []
    cur: Routine | None = None
    for st in stmts:
        kw = st.keyword
        opened = _def_name(st, report)
        if cur is None:
            if opened is not None:
                cur = Routine(opened[0], file, st.line, is_function=opened[1])
            else:
                report(file, st.line, st.tokens[0].col, "statement outside DEF … END: move it "
                       "into the routine (only & header lines and comments may stand outside)",
                       "structure")
            continue
        if opened is not None:
            report(file, st.line, st.tokens[0].col, f"{kw} inside {cur.name} (line {cur.line}): "
                   f"{cur.name} needs its {'ENDFCT' if cur.is_function else 'END'} first",
                   "structure")
            _close(cur, routines, report)
            cur = Routine(opened[0], file, st.line, is_function=opened[1])
            continue
        if kw == ("ENDFCT" if cur.is_function else "END") and len(st.tokens) == 1:
            _close(cur, routines, report)
            cur = None
            continue
        cur.body.append(st)
    if cur is not None:
        report(file, nlines, 0, f"{cur.name} (line {cur.line}) has no "
               f"{'ENDFCT' if cur.is_function else 'END'}; add it at the end of the routine",
               "structure")
        _close(cur, routines, report)
    return SrcFile(file, routines, headers, nlines)


def _close(r: Routine, routines: list[Routine], report: Report) -> None:
    if not r.is_function:
        _match_blocks(r, report)
    routines.append(r)


def parse_dat(text: str, file: str, report: Report) -> DatFile:
    """Statements between ``DEFDAT NAME [PUBLIC]`` and ``ENDDAT``."""
    stmts, headers, nlines = _statements(text, file, report)
    name: str | None = None
    body: list[Stmt] = []
    state = "before"
    for st in stmts:
        kw = st.keyword
        if state == "before":
            if kw == "DEFDAT" and len(st.tokens) > 1 and st.tokens[1].kind == "name":
                name, state = st.tokens[1].text, "in"
            else:
                report(file, st.line, st.tokens[0].col, "a .dat must start with DEFDAT NAME "
                       "[PUBLIC] (after optional & header lines)", "structure")
            continue
        if state == "after":
            report(file, st.line, st.tokens[0].col, "statement after ENDDAT: move it before "
                   "ENDDAT", "structure")
            continue
        if kw == "ENDDAT":
            state = "after"
            continue
        body.append(st)
    if state == "in":
        report(file, nlines, 0, "the .dat has no ENDDAT; add it as the last line", "structure")
    return DatFile(file, name, body, headers, nlines)
