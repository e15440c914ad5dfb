"""A KRL lint: check a set of ``.src``/``.dat`` files against the rules of KUKA_IO.md §1.

It is written apart from the writer (``robot_io.krl``) and shares none of its code, so that it can
judge the writer's output: the test suite runs it over everything the writer produces, and a user
can run it over a program before copying it to a controller. It is deliberately stricter than the
controller where our rules are (CRLF, ≥ 6 feed decimals, a ``.dat`` beside every ``.src``).

Rules (the ``rule`` of a :class:`LintProblem`):

``ascii``        bytes are printable ASCII (plus CR, LF, TAB)
``crlf``         every line ends with CR LF, the last one too
``header``       ``&`` lines only before ``DEF``/``DEFDAT``
``identifier``   declared, defined, called and assigned names: ≤ 24 characters, letters, digits,
                 ``_``, ``$``, no leading digit, not a keyword
``structure``    a ``.src`` holds ``DEF NAME( ) … END`` blocks, balanced, the first named like the
                 file; a ``.dat`` is ``DEFDAT NAME … ENDDAT`` named like the file
``pair``         every ``.src`` has a ``.dat`` of the same name
``fold``         ``;FOLD`` / ``;ENDFOLD`` balanced in each file
``motion``       LIN targets ``{X,Y,Z,A,B,C}`` numbers, CIRC two of them, PTP ``{A1..A6}`` or
                 ``$AXIS_ACT``; only ``C_DIS`` (LIN/CIRC) or ``C_PTP`` (PTP) after them
``vel_cp``       every ``$VEL.CP`` value (a literal, a REAL declared in a ``.dat``, or such a REAL
                 times a literal scale, ``NAME_F003 * 0.873100``) has at least 6 decimals (the
                 scale too) and lies in (0, max] (the product)
``feed_first``   every ``.src`` with a LIN/CIRC sets ``$VEL.CP`` before the first of them
``approx``       ``C_DIS`` only after ``$APO.CDIS`` was set (in this file or the calling main)
``page_size``    a ``.src`` has at most the controller's page lines (2000 KR C2, 1400 KR C4)
``circ_break``   a called page does not begin with a CIRC (no page break inside an arc pair)
``call``         a called module exists and is declared ``EXT`` (or defined) in the caller
``undeclared``   every name used is declared (routine ``DECL``, its ``.dat``, a ``GLOBAL`` of any
                 ``.dat``), a module, or a known system name
"""

from __future__ import annotations

import os
import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

__all__ = ["LINT_PAGE_LINES", "LintProblem", "MIN_FEED_DECIMALS", "lint_krl"]

#: Page limit [lines] by controller (KUKA_IO.md §1.5).
LINT_PAGE_LINES = {"krc2": 2000, "krc4": 1400}
#: Fewest decimals of a $VEL.CP value (KUKA_IO.md §1.3).
MIN_FEED_DECIMALS = 6
_MAX_NAME = 24

_KEYWORDS = frozenset("""
AND ANIN ANOUT AXIS B_AND B_EXOR B_NOT B_OR BOOL BRAKE C_DIS C_ORI C_PTP C_VEL CA CASE CHAR CIRC
CIRC_REL CONST CONTINUE DECL DEF DEFAULT DEFDAT DEFFCT DELAY DISTANCE DO E6AXIS E6POS ELSE END
ENDDAT ENDFCT ENDFOR ENDIF ENDLOOP ENDSWITCH ENDWHILE ENUM EXIT EXOR EXT EXTFCT FALSE FOR FRAME
GLOBAL GOTO HALT IF IMPORT IN INT INTERRUPT IS LIN LIN_REL LOOP NOT OFF ON OR OUT POS PRIO PTP
PTP_REL PUBLIC PULSE REAL REPEAT RESUME RETURN SEC SIGNAL STEP STRUC SWITCH THEN TO TRIGGER TRUE
UNTIL WAIT WHEN WHILE
""".split())
#: Names the controller provides (system routines, $config.dat items, RSI constants).
_KNOWN = frozenset({"BAS", "BAS_COMMAND", "IR_STOPM", "BASE_DATA", "TOOL_DATA", "RSI_CREATE",
                    "RSI_ON", "RSI_OFF", "RSIOK", "XHOME"})
_TYPES = frozenset({"INT", "REAL", "BOOL", "CHAR", "FRAME", "POS", "E6POS", "AXIS", "E6AXIS"})
_NAME_RE = re.compile(r"[A-Za-z_$][A-Za-z0-9_$]*\Z")
_TOKEN = re.compile(r'"[^"]*"|#[A-Za-z_$][A-Za-z0-9_$]*|[A-Za-z_$][A-Za-z0-9_$]*'
                    r"|[0-9]+(?:\.[0-9]*)?|\.[0-9]+|<>|==|\S")
_NUM = r"-?[0-9]+(?:\.[0-9]+)?"
_CART = re.compile(rf"\{{X ({_NUM}),Y ({_NUM}),Z ({_NUM}),A ({_NUM}),B ({_NUM}),C ({_NUM})\}}")
_AXES = re.compile(r"\{" + ",".join(rf"A{i} {_NUM}" for i in range(1, 7)) + r"\}")
_REAL_LIT = re.compile(r"[0-9]+\.([0-9]+)\Z")


@dataclass(frozen=True)
class LintProblem:
    """One broken rule: file name, 1-based line (0: the whole file), rule key, what is wrong."""

    file: str
    line: int
    rule: str
    message: str

    def __str__(self) -> str:
        return f"{self.file}:{self.line}: [{self.rule}] {self.message}"


@dataclass
class _File:
    name: str
    stem: str
    ext: str
    lines: list[str]              # code and comments, line endings removed
    codes: list[str]              # code only (comment stripped), stripped


def _strip_comment(line: str) -> str:
    in_str = False
    for i, ch in enumerate(line):
        if ch == '"':
            in_str = not in_str
        elif ch == ";" and not in_str:
            return line[:i].strip()
    return line.strip()


def _name_problem(name: str) -> str | None:
    if len(name) > _MAX_NAME:
        return f"{name!r} is {len(name)} characters long (at most {_MAX_NAME})"
    if not _NAME_RE.match(name):
        return f"{name!r} is not a valid KRL name"
    if name.upper() in _KEYWORDS:
        return f"{name!r} is a keyword"
    return None


def _load(files: Mapping[str, str | bytes] | str | os.PathLike) -> dict[str, bytes]:
    if isinstance(files, (str, os.PathLike)):
        folder = Path(files)
        return {p.name: p.read_bytes() for p in sorted(folder.iterdir())
                if p.suffix.lower() in (".src", ".dat")}
    return {k: (v if isinstance(v, bytes) else v.encode("utf-8")) for k, v in files.items()}


def _bytes_rules(name: str, data: bytes, out: list[LintProblem]) -> str:
    for i, line in enumerate(data.split(b"\n"), 1):
        bad = [b for b in line if b >= 0x7F or (b < 0x20 and b not in (9, 13))]
        if bad:
            out.append(LintProblem(name, i, "ascii", f"byte 0x{bad[0]:02x} is not printable "
                                   "ASCII"))
    text = data.decode("latin-1")
    lone_lf = len(re.findall(r"(?<!\r)\n", text))
    lone_cr = len(re.findall(r"\r(?!\n)", text))
    if lone_lf or lone_cr:
        out.append(LintProblem(name, 0, "crlf", f"{lone_lf} LF and {lone_cr} CR without their "
                               "pair: every line must end with CR LF"))
    if text and not text.endswith("\r\n"):
        out.append(LintProblem(name, 0, "crlf", "the last line does not end with CR LF"))
    return text


def _parse(name: str, text: str) -> _File:
    stem, ext = os.path.splitext(name)
    lines = text.replace("\r\n", "\n").replace("\r", "\n").split("\n")
    if lines and lines[-1] == "":
        lines.pop()
    return _File(name, stem, ext.lower(), lines, [_strip_comment(x) for x in lines])


def _structure(f: _File, out: list[LintProblem]) -> list[tuple[str, int, int]]:
    """Header and DEF/END (or DEFDAT/ENDDAT) structure; the routines as (name, first, last)."""
    started = False
    routines: list[tuple[str, int, int]] = []
    open_def: tuple[str, int] | None = None
    depth = 0
    for i, (raw, code) in enumerate(zip(f.lines, f.codes, strict=True), 1):
        if raw.startswith("&"):
            if started:
                out.append(LintProblem(f.name, i, "header", "& header line after DEF/DEFDAT"))
            continue
        if raw.strip().upper().startswith(";FOLD"):
            depth += 1
        elif raw.strip().upper().startswith(";ENDFOLD"):
            depth -= 1
            if depth < 0:
                out.append(LintProblem(f.name, i, "fold", ";ENDFOLD without ;FOLD"))
                depth = 0
        if not code:
            continue
        toks = code.split()
        kw = toks[0].upper()
        if f.ext == ".src":
            m = re.match(r"(?:GLOBAL\s+)?DEF\s+([^\s(]+)\s*\(", code, re.IGNORECASE)
            if m:
                started = True
                if open_def is not None:
                    out.append(LintProblem(f.name, i, "structure", f"DEF inside DEF "
                                           f"{open_def[0]} (line {open_def[1]})"))
                open_def = (m.group(1), i)
            elif kw == "END" and len(toks) == 1:
                if open_def is None:
                    out.append(LintProblem(f.name, i, "structure", "END without DEF"))
                else:
                    routines.append((open_def[0], open_def[1], i))
                    open_def = None
            elif open_def is None:
                out.append(LintProblem(f.name, i, "structure", f"{toks[0]!r} outside DEF … END"))
        else:
            if kw == "DEFDAT":
                started = True
                if len(toks) < 2 or toks[1].upper() != f.stem.upper():
                    out.append(LintProblem(f.name, i, "structure", f"DEFDAT name "
                                           f"{toks[1] if len(toks) > 1 else ''!r} differs from "
                                           f"the file name {f.stem!r}"))
            elif not started:
                out.append(LintProblem(f.name, i, "structure", "statement before DEFDAT"))
    if depth:
        out.append(LintProblem(f.name, 0, "fold", f"{depth} ;FOLD without ;ENDFOLD"))
    if f.ext == ".src":
        if open_def is not None:
            out.append(LintProblem(f.name, open_def[1], "structure", f"DEF {open_def[0]} has "
                                   "no END"))
        if not routines:
            out.append(LintProblem(f.name, 0, "structure", "no DEF … END routine"))
        elif routines[0][0].upper() != f.stem.upper():
            out.append(LintProblem(f.name, routines[0][1], "structure", f"DEF {routines[0][0]} "
                                   f"differs from the file name {f.stem!r}"))
    else:
        codes = [c for c in f.codes if c]
        if not codes or codes[-1].upper() != "ENDDAT":
            out.append(LintProblem(f.name, 0, "structure", "a .dat must end with ENDDAT"))
    return routines


def _decl(code: str) -> tuple[str, str, bool, str | None] | None:
    """``(type, name, global, value text)`` of a ``DECL`` line."""
    m = re.match(r"DECL\s+(GLOBAL\s+)?(CONST\s+)?([A-Za-z_$][\w$]*)\s+([A-Za-z_$][\w$]*)"
                 r"(?:\s*\[[^\]]*\])?\s*(?:=\s*(.*))?$", code, re.IGNORECASE)
    if m is None:
        return None
    return m.group(3).upper(), m.group(4), bool(m.group(1)), m.group(5)


def _used_names(code: str) -> list[str]:
    """Names a statement uses, outside braces, strings, enums and after '.'."""
    names = []
    depth = 0
    prev = ""
    for tok in _TOKEN.findall(code):
        if tok == "{":
            depth += 1
        elif tok == "}":
            depth -= 1
        elif depth == 0 and re.match(r"[A-Za-z_$]", tok) and prev != ".":
            names.append(tok)
        prev = tok
    return names


def lint_krl(files: Mapping[str, str | bytes] | str | os.PathLike, controller: str = "krc4",
             vel_cp_max: float = 2.0) -> list[LintProblem]:
    """Check a program's files; an empty list means every rule holds.

    Args:
        files: file name → content (text or bytes), or a folder whose ``.src``/``.dat`` files
            are checked together.
        controller: ``"krc2"`` or ``"krc4"`` (page size).
        vel_cp_max: largest allowed ``$VEL.CP`` [m/s].
    """
    out: list[LintProblem] = []
    parsed: dict[str, _File] = {}
    for name, data in _load(files).items():
        parsed[name] = _parse(name, _bytes_rules(name, data, out))
    srcs = {f.stem.upper(): f for f in parsed.values() if f.ext == ".src"}
    dats = {f.stem.upper(): f for f in parsed.values() if f.ext == ".dat"}
    limit = LINT_PAGE_LINES[controller]
    routines: dict[str, list[tuple[str, int, int]]] = {}
    for f in parsed.values():
        routines[f.name] = _structure(f, out)
    # declarations of the .dat files
    dat_names: dict[str, dict[str, tuple[str, str | None]]] = {}
    globals_: dict[str, tuple[str, str | None]] = {}
    for stem, f in dats.items():
        names: dict[str, tuple[str, str | None]] = {}
        for i, code in enumerate(f.codes, 1):
            if code.upper().startswith("DECL"):
                d = _decl(code)
                if d is None:
                    out.append(LintProblem(f.name, i, "structure", f"unreadable DECL {code!r}"))
                    continue
                typ, nm, glob, val = d
                p = _name_problem(nm)
                if p:
                    out.append(LintProblem(f.name, i, "identifier", p))
                names[nm.upper()] = (typ, val)
                if glob:
                    globals_[nm.upper()] = (typ, val)
                    if not re.search(r"\bPUBLIC\b", " ".join(f.codes).upper()):
                        out.append(LintProblem(f.name, i, "structure", f"GLOBAL {nm} needs "
                                               "DEFDAT … PUBLIC"))
        dat_names[stem] = names
    called_by: dict[str, str] = {}
    apo_files: set[str] = set()
    for stem, f in srcs.items():      # who calls whom, who sets $APO.CDIS (before the rules)
        for code in f.codes:
            m = re.match(r"([A-Za-z_$][\w$]*)\s*\(\s*\)\s*$", code)
            if m and m.group(1).upper() in srcs:
                called_by.setdefault(m.group(1).upper(), stem)
            if re.match(r"\$APO\.CDIS\s*=", code, re.IGNORECASE):
                apo_files.add(stem)
    for stem, f in srcs.items():
        if stem not in dats:
            out.append(LintProblem(f.name, 0, "pair", f"no {f.stem}.dat beside {f.name}"))
        if len(f.lines) > limit:
            out.append(LintProblem(f.name, 0, "page_size", f"{len(f.lines)} lines; "
                                   f"{controller} pages hold at most {limit}"))
        local: set[str] = set()
        exts: set[str] = set()
        defs = {r[0].upper() for r in routines[f.name]}
        feed_set = False
        first_motion: str | None = None
        for i, code in enumerate(f.codes, 1):
            if not code or code.startswith("&"):
                continue
            up = code.upper()
            kw = up.split()[0].split("(")[0]
            if kw == "DEF":
                continue
            if kw == "DECL":
                d = _decl(code)
                if d is None:
                    out.append(LintProblem(f.name, i, "structure", f"unreadable DECL {code!r}"))
                    continue
                p = _name_problem(d[1])
                if p:
                    out.append(LintProblem(f.name, i, "identifier", p))
                local.add(d[1].upper())
                continue
            if kw == "EXT":
                m = re.match(r"EXT\s+([A-Za-z_$][\w$]*)", code, re.IGNORECASE)
                if m:
                    p = _name_problem(m.group(1))
                    if p:
                        out.append(LintProblem(f.name, i, "identifier", p))
                    exts.add(m.group(1).upper())
                continue
            if kw in ("LIN", "CIRC", "PTP"):
                _motion(f, i, code, kw, out)
                if first_motion is None and kw != "PTP":
                    first_motion = kw
                if kw in ("LIN", "CIRC") and not feed_set:
                    out.append(LintProblem(f.name, i, "feed_first", f"{kw} before any $VEL.CP "
                                           "in this file"))
                    feed_set = True
                if up.endswith("C_DIS") and stem not in apo_files and not _apo_inherited(
                        stem, called_by, apo_files):
                    out.append(LintProblem(f.name, i, "approx", "C_DIS before $APO.CDIS is set"))
                    apo_files.add(stem)
                continue
            m = re.match(r"\$VEL\.CP\s*=\s*(.+)$", code, re.IGNORECASE)
            if m:
                feed_set = True
                _vel_cp(f, i, m.group(1).strip(), stem, dat_names, globals_, vel_cp_max, out)
            m = re.match(r"([A-Za-z_$][\w$]*)\s*\(\s*\)\s*$", code)
            if m and m.group(1).upper() not in _KNOWN:
                callee = m.group(1).upper()
                p = _name_problem(m.group(1))
                if p:
                    out.append(LintProblem(f.name, i, "identifier", p))
                if callee in srcs:
                    if callee not in exts and callee not in defs:
                        out.append(LintProblem(f.name, i, "call", f"{m.group(1)}( ) is not "
                                               "declared EXT in this module"))
                elif callee not in defs:
                    out.append(LintProblem(f.name, i, "call", f"{m.group(1)}.src does not "
                                           "exist"))
                continue
            m = re.match(r"([A-Za-z_$][\w$]*)\s*=", code)
            if m and not m.group(1).startswith("$"):
                p = _name_problem(m.group(1))
                if p:
                    out.append(LintProblem(f.name, i, "identifier", p))
            for nm in _used_names(code):
                u = nm.upper()
                if (u.startswith("$") or u in _KEYWORDS or u in _KNOWN or u in local
                        or u in dat_names.get(stem, {}) or u in globals_ or u in srcs
                        or u in defs):
                    continue
                out.append(LintProblem(f.name, i, "undeclared", f"{nm} is not declared"))
        if first_motion == "CIRC" and stem in called_by:
            out.append(LintProblem(f.name, 0, "circ_break", "the page begins with a CIRC: a page "
                                   "break inside an arc"))
    return out


def _apo_inherited(stem: str, called_by: dict[str, str], apo_files: set[str]) -> bool:
    seen = set()
    while stem in called_by and stem not in seen:
        seen.add(stem)
        stem = called_by[stem]
        if stem in apo_files:
            return True
    return False


def _motion(f: _File, i: int, code: str, kw: str, out: list[LintProblem]) -> None:
    rest = code[len(kw):].strip()
    if kw == "PTP":
        body = re.sub(r"\s*C_PTP$", "", rest, flags=re.IGNORECASE)
        if body.upper() != "$AXIS_ACT" and not _AXES.fullmatch(body) and not _CART.fullmatch(body):
            out.append(LintProblem(f.name, i, "motion", f"PTP target {body!r} is not "
                                   "{A1 …,…,A6 …} or $AXIS_ACT"))
        return
    body = re.sub(r"\s*C_DIS$", "", rest, flags=re.IGNORECASE)
    if kw == "LIN":
        ok = _CART.fullmatch(body) is not None
    else:
        parts = body.split("},{")
        ok = (len(parts) == 2 and _CART.fullmatch(parts[0] + "}") is not None
              and _CART.fullmatch("{" + parts[1]) is not None)
    if not ok:
        out.append(LintProblem(f.name, i, "motion", f"{kw} target {body[:60]!r}… is not "
                               "{X …,Y …,Z …,A …,B …,C …}" + (" twice" if kw == "CIRC" else "")))


def _vel_cp(f: _File, i: int, value: str, stem: str,
            dat_names: dict[str, dict[str, tuple[str, str | None]]],
            globals_: dict[str, tuple[str, str | None]], vmax: float,
            out: list[LintProblem]) -> None:
    scaled = re.fullmatch(r"([A-Za-z_$][A-Za-z0-9_$]*)\s*\*\s*(\S+)", value)
    scale = 1.0
    if scaled is not None:
        value, s_text = scaled.group(1), scaled.group(2)
        ms = _REAL_LIT.match(s_text)
        if ms is None or len(ms.group(1)) < MIN_FEED_DECIMALS or not float(s_text) > 0:
            out.append(LintProblem(f.name, i, "vel_cp", f"$VEL.CP scale {s_text!r} must be a "
                                   f"decimal > 0 with at least {MIN_FEED_DECIMALS} decimals"))
            return
        scale = float(s_text)
    text = value
    if re.match(r"[A-Za-z_$]", value):
        decl = dat_names.get(stem, {}).get(value.upper()) or globals_.get(value.upper())
        if decl is None:
            out.append(LintProblem(f.name, i, "vel_cp", f"$VEL.CP = {value}: {value} is not a "
                                   "REAL declared in a .dat"))
            return
        typ, val = decl
        if typ != "REAL" or val is None:
            out.append(LintProblem(f.name, i, "vel_cp", f"{value} must be a REAL with a value"))
            return
        text = _strip_comment(val)
    m = _REAL_LIT.match(text)
    if m is None:
        out.append(LintProblem(f.name, i, "vel_cp", f"$VEL.CP value {text!r} is not a plain "
                               "decimal number"))
        return
    if len(m.group(1)) < MIN_FEED_DECIMALS:
        out.append(LintProblem(f.name, i, "vel_cp", f"$VEL.CP value {text} has "
                               f"{len(m.group(1))} decimals (at least {MIN_FEED_DECIMALS})"))
    v = float(text) * scale
    if not 0 < v <= vmax:
        out.append(LintProblem(f.name, i, "vel_cp", f"$VEL.CP value {text}"
                               + (f" x {scale:g}" if scaled else "") + f" m/s is not in "
                               f"(0, {vmax:g}]"))
