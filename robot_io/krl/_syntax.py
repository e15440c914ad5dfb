"""Lexing and value parsing of single KUKA KRL lines (private helper of ``robot_io.krl.reader``).

KRL is line-oriented: a statement never continues on the next line, so every function here works
on one line and reports problems as :class:`LineError` (1-based column, reason, category); the
caller adds the file and line. Keywords and identifiers are case-insensitive (``Token.upper``).

Values parsed here are plain Python: ``float`` for INT/REAL, ``bool``, ``str`` (strings and
``#ENUM`` literals), ``int`` for bit strings (``'B0110'``, ``'H1F'``) and :class:`Aggregate` for
``{X 1,Y 2,...}`` literals. Aggregate components must be constants in KRL, so a name where a number
belongs is a syntax error, not a variable look-up.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from models.errors import CctmillError

__all__ = [
    "Aggregate",
    "Cursor",
    "FastData",
    "LineError",
    "MAX_KRL_NESTING",
    "MAX_KRL_VALUE",
    "Ref",
    "Token",
    "fast_data",
    "fast_motion",
    "parse_aggregate",
    "parse_ref",
    "parse_value",
    "split_comment",
    "tokenize",
]

#: Largest magnitude of a number the reader accepts (mm, deg, m/s alike); anything larger is a typo
#: and would only overflow the geometry later.
MAX_KRL_VALUE = 1e9
#: Deepest nesting of braces/parentheses/unary signs in one statement (guards the recursive parser).
MAX_KRL_NESTING = 32

_TOKEN = re.compile(r"""
    (?P<ws>[ \t\f\v]+)
  | (?P<num>(?:[0-9]|\.[0-9])(?:[A-Za-z0-9_.]|(?<=[eE])[+-])*)
  | (?P<name>[A-Za-z_$][A-Za-z0-9_$]*)
  | (?P<str>"[^"]*")
  | (?P<bits>'[^']*')
  | (?P<enum>\#[A-Za-z_$][A-Za-z0-9_$]*)
  | (?P<sym><=|>=|==|<>|[{}\[\](),:=+\-*/<>.])
""", re.VERBOSE)

_OPEN = {"{": "}", "[": "]", "(": ")"}
_CLOSE = {v: k for k, v in _OPEN.items()}


class LineError(CctmillError):
    """A problem in one line: 1-based ``col``, ``reason`` (with the fix), counting ``category``;
    a ``fatal`` one (a limit) ends lenient reading too."""

    def __init__(self, col: int, reason: str, category: str = "syntax",
                 fatal: bool = False) -> None:
        super().__init__(reason)
        self.col = col
        self.reason = reason
        self.category = category
        self.fatal = fatal


class Token:
    """One lexeme: ``kind`` is ``name``, ``num``, ``str``, ``bits``, ``enum`` or ``sym``; ``upper``
    is the text in upper case (KRL is case-insensitive), ``value`` the number of ``num`` tokens.
    (A plain slotted class: a program has millions of tokens.)"""

    __slots__ = ("col", "kind", "text", "upper", "value")

    def __init__(self, kind: str, text: str, col: int, value: float = 0.0) -> None:
        self.kind = kind
        self.text = text
        self.col = col
        self.value = value
        self.upper = text.upper()

    def __repr__(self) -> str:
        return f"Token({self.kind!r}, {self.text!r}, {self.col})"


@dataclass
class Aggregate:
    """A KRL aggregate literal ``{[TYPE:] NAME value, ...}``; field names upper case."""

    type_name: str | None
    fields: dict[str, Any] = field(default_factory=dict)
    col: int = 0


@dataclass(frozen=True)
class Ref:
    """A variable reference ``NAME[i, j].FIELD...`` (names upper case).

    ``index`` is ``None`` without brackets and ``()`` for the empty ``NAME[]`` of KRL strings.
    """

    name: str
    index: tuple[int, ...] | None
    fields: tuple[str, ...]
    col: int
    text: str


# Every pattern below matches each position of a line in one way only (possessive blanks, an
# atomic literal body), so a line that finally fails costs time linear in its length: the old
# separator ``[ \t]+|[ \t]*(?=[-+])`` matched the blank before a signed number two ways and a
# failing LIN literal of n signed components backtracked 2**n times (issue 22).
_BLANK = r"[ \t]*+"
_NUM = r"[-+]?+(?:[0-9]++(?:\.[0-9]*+)?+|\.[0-9]++)(?:[eE][-+]?+[0-9]++)?+"
_FIELD_NAME = r"(?:[XYZABCST]|E[1-6])"
#: Between a component name and its value: blanks, or nothing before a sign (``X-1``).
_SEP = r"(?:[ \t]++|(?=[-+]))"
_FIELD = re.compile(rf"({_FIELD_NAME}){_SEP}({_NUM})", re.IGNORECASE)
#: The components of a Cartesian literal, ``X 1.5, Y -2, ...`` (atomic: matched once, greedily).
_BODY = (rf"(?>{_FIELD_NAME}{_SEP}{_NUM}"
         rf"(?:{_BLANK},{_BLANK}{_FIELD_NAME}{_SEP}{_NUM})*+)")
_FAST_MOTION = re.compile(
    rf"{_BLANK}(LIN|PTP){_BLANK}(\{{){_BLANK}(?:(?:E6POS|POS|FRAME){_BLANK}:{_BLANK})?"
    rf"({_BODY}){_BLANK}\}}{_BLANK}(?:(C_DIS|C_PTP|C_VEL|C_ORI){_BLANK})?$", re.IGNORECASE)


def fast_motion(code: str) -> tuple[str, dict[str, float], int, str | None] | None:
    """``(keyword, components, column of '{', approximation)`` of the commonest line of a CAM
    program, ``LIN|PTP {X 1.5,Y -2,...} [C_DIS]`` with a Cartesian literal of plain numbers, read
    with one regular expression; ``None`` for anything else (or anything doubtful, such as a
    repeated component or a number out of range), which then goes through :func:`tokenize`."""
    m = _FAST_MOTION.match(code)
    if m is None:
        return None
    fields = _FIELD.findall(m.group(3))
    comps = {name.upper(): float(v) for name, v in fields}
    if len(comps) != len(fields) or any(abs(v) > MAX_KRL_VALUE for v in comps.values()):
        return None
    approx = m.group(4)
    return m.group(1).upper(), comps, m.start(2) + 1, approx.upper() if approx else None


#: Position types whose ``DECL`` lines with a literal take the data fast path.
_POS_TYPES = r"(?:E6POS|POS|FRAME)"
_FAST_DATA = re.compile(
    rf"{_BLANK}(?:(DECL)[ \t]++(?:(GLOBAL)[ \t]++)?({_POS_TYPES})[ \t]++)?"
    rf"([A-Za-z_][A-Za-z0-9_]*+){_BLANK}(?:\[{_BLANK}([0-9]++){_BLANK}\]{_BLANK})?="
    rf"{_BLANK}(\{{){_BLANK}(?:({_POS_TYPES}){_BLANK}:{_BLANK})?({_BODY}){_BLANK}\}}{_BLANK}$",
    re.IGNORECASE)
#: Names that are keywords, never the variable of a data line.
_KEYWORDS = frozenset({"DECL", "GLOBAL", "CONST", "DEF", "DEFDAT", "DEFFCT", "END", "ENDDAT",
                       "IF", "FOR", "WHILE", "REPEAT", "LOOP", "SWITCH", "PTP", "LIN", "CIRC"})

#: ``(declared type or None, global, name, index or None, components, column of '{', literal
#: type or None)`` of a data line (see :func:`fast_data`).
FastData = tuple[str | None, bool, str, int | None, dict[str, float], int, str | None]


def fast_data(code: str) -> FastData | None:
    """The commonest line of a converter's ``.dat``, ``NAME[i]={X 1.5,Y -2,...}`` or
    ``DECL [GLOBAL] E6POS|POS|FRAME NAME={...}``, with a Cartesian literal of plain numbers, read
    with one regular expression (names upper case); ``None`` for anything else or anything
    doubtful (a repeated component, a number out of range, a declared array with a value), which
    then goes through :func:`tokenize`."""
    if "{" not in code:
        return None
    m = _FAST_DATA.match(code)
    if m is None:
        return None
    decl, glob, typ, name, index, _, lit_type, body = m.groups()
    if (decl is not None and index is not None) or name.upper() in _KEYWORDS:
        return None
    fields = _FIELD.findall(body)
    comps = {k.upper(): float(v) for k, v in fields}
    if len(comps) != len(fields) or any(abs(v) > MAX_KRL_VALUE for v in comps.values()):
        return None
    return (typ.upper() if typ else None, glob is not None, name.upper(),
            None if index is None else int(index), comps, m.start(6) + 1,
            lit_type.upper() if lit_type else None)


def split_comment(raw: str) -> str:
    """The line without its ``;`` comment (a ``;`` inside ``"..."`` is text); columns unchanged."""
    if ";" not in raw:
        return raw
    in_str = False
    for i, ch in enumerate(raw):
        if ch == '"':
            in_str = not in_str
        elif ch == ";" and not in_str:
            return raw[:i]
    return raw


def _number(text: str, col: int) -> float:
    try:
        v = float(text)
    except ValueError:
        raise LineError(col, f"bad number {text!r}: write digits with at most one decimal point "
                        "and an optional exponent, e.g. 12.5, -0.25 or 1.5E-3") from None
    if not math.isfinite(v) or abs(v) > MAX_KRL_VALUE:
        raise LineError(col, f"number {text!r} is out of range (|value| <= {MAX_KRL_VALUE:g}); "
                        "check for a missing decimal point or separator")
    return v


def tokenize(code: str) -> list[Token]:
    """Tokens of one comment-free line; brackets must balance on the line."""
    toks: list[Token] = []
    pos, n = 0, len(code)
    match = _TOKEN.match
    stack: list[Token] = []
    while pos < n:
        m = match(code, pos)
        col = pos + 1
        if m is None:
            ch = code[pos]
            if ch in "\"'":
                what = "string" if ch == '"' else "bit string"
                raise LineError(col, f"unterminated {what} starting with {ch}: close it with "
                                f"{ch} on the same line")
            raise LineError(col, f"unexpected character {ch!r}: KRL statements use ASCII letters, "
                            "digits and _ $ # { } [ ] ( ) , : = + - * / < > . (comments start "
                            "with ;)")
        kind = m.lastgroup or ""
        pos = m.end()
        if kind == "ws":
            continue
        text = m.group()
        if kind == "num":
            toks.append(Token(kind, text, col, _number(text, col)))
            continue
        tok = Token(kind, text, col)
        toks.append(tok)
        if kind == "sym":
            if text in _OPEN:
                stack.append(tok)
                if len(stack) > MAX_KRL_NESTING:
                    raise LineError(col, f"brackets nested deeper than {MAX_KRL_NESTING}")
            elif text in _CLOSE:
                if not stack:
                    raise LineError(col, f"unexpected {text!r} with no matching "
                                    f"{_CLOSE[text]!r}: remove it or add the opening bracket")
                top = stack.pop()
                if top.text != _CLOSE[text]:
                    raise LineError(col, f"{text!r} closes {top.text!r} opened at column "
                                    f"{top.col}: close it with {_OPEN[top.text]!r} first")
    if stack:
        top = stack[-1]
        raise LineError(top.col, f"unbalanced {top.text!r}: close it with {_OPEN[top.text]!r} on "
                        "the same line (a KRL statement never continues on the next line)")
    return toks


class Cursor:
    """Reads the tokens of one statement left to right."""

    def __init__(self, tokens: list[Token], end_col: int, start: int = 0) -> None:
        self.toks = tokens
        self.i = start
        self.end_col = end_col
        self.depth = 0

    def peek(self, k: int = 0) -> Token | None:
        """The token ``k`` ahead, or ``None`` past the end."""
        j = self.i + k
        return self.toks[j] if j < len(self.toks) else None

    def at_end(self) -> bool:
        """True when every token has been read."""
        return self.i >= len(self.toks)

    @property
    def col(self) -> int:
        """Column of the next token (or just past the line's end)."""
        t = self.peek()
        return t.col if t is not None else self.end_col

    def next(self, what: str) -> Token:
        """The next token; at the end, a :class:`LineError` saying ``what`` was expected."""
        t = self.peek()
        if t is None:
            raise LineError(self.end_col, f"the statement ends where {what} was expected")
        self.i += 1
        return t

    def accept(self, text: str) -> Token | None:
        """Consume and return the next token if its upper-case text is ``text``."""
        t = self.peek()
        if t is not None and t.kind != "str" and t.upper == text:
            self.i += 1
            return t
        return None

    def expect(self, text: str, what: str) -> Token:
        """Consume ``text`` or fail saying ``what`` was expected."""
        t = self.accept(text)
        if t is None:
            got = self.peek()
            if got is None:
                raise LineError(self.end_col, f"the statement ends where {what} was expected")
            raise LineError(got.col, f"expected {what}, found {got.text!r}")
        return t

    def enter(self) -> None:
        """One level deeper in the recursive parser."""
        self.depth += 1
        if self.depth > MAX_KRL_NESTING:
            raise LineError(self.col, f"expression nested deeper than {MAX_KRL_NESTING}")


def _bits(tok: Token) -> int:
    body = tok.text[1:-1].strip().upper()
    base = {"B": 2, "H": 16}.get(body[:1])
    try:
        if base is None:
            raise ValueError
        return int(body[1:], base)
    except ValueError:
        raise LineError(tok.col, f"bad bit string {tok.text}: write 'B0110' (binary) or 'H1F' "
                        "(hex)") from None


def _constant(cur: Cursor, fname: str) -> Any:
    """A constant aggregate component: signed number, bits, string, enum, TRUE/FALSE, aggregate."""
    t = cur.next(f"a value for {fname}")
    if t.kind == "sym" and t.text in "+-" and len(t.text) == 1:
        u = cur.next(f"a number after {t.text!r}")
        if u.kind != "num":
            raise LineError(u.col, f"expected a number after {fname} {t.text}, found {u.text!r}")
        return -u.value if t.text == "-" else u.value
    if t.kind == "num":
        return t.value
    if t.kind == "bits":
        return _bits(t)
    if t.kind == "str":
        return t.text[1:-1]
    if t.kind == "enum":
        return t.upper
    if t.kind == "name" and t.upper in ("TRUE", "FALSE"):
        return t.upper == "TRUE"
    if t.text == "{":
        cur.i -= 1
        return parse_aggregate(cur)
    raise LineError(t.col, f"expected a number after {fname}, found {t.text!r} (components of a "
                    "{...} literal must be constants: write the value, not a variable)")


def parse_aggregate(cur: Cursor) -> Aggregate:
    """``{[TYPE:] NAME value, ...}`` at the cursor."""
    open_tok = cur.expect("{", "'{'")
    cur.enter()
    agg = Aggregate(None, {}, open_tok.col)
    t0, t1 = cur.peek(), cur.peek(1)
    if t0 is not None and t0.kind == "name" and t1 is not None and t1.text == ":":
        agg.type_name = t0.upper
        cur.i += 2
    if cur.accept("}"):
        cur.depth -= 1
        return agg
    while True:
        name = cur.next("a component name")
        if name.kind != "name":
            raise LineError(name.col, f"expected a component name such as X or A1, found "
                            f"{name.text!r}")
        key = name.upper
        if cur.accept("["):
            cur.expect("]", "']' (only NAME[] is allowed inside a literal)")
        if key in agg.fields:
            raise LineError(name.col, f"component {key} is given twice in this literal; keep one")
        agg.fields[key] = _constant(cur, key)
        if cur.accept("}"):
            cur.depth -= 1
            return agg
        if cur.accept(",") is None:
            raise LineError(cur.col, f"expected ',' or '}}' after the value of {key}")


def parse_ref(cur: Cursor, index_value: Callable[[Cursor], Any]) -> Ref:
    """``NAME[i, ...].FIELD...``; indices are evaluated by ``index_value`` and must be integers."""
    t = cur.next("a name")
    if t.kind != "name":
        raise LineError(t.col, f"expected a name, found {t.text!r}")
    index: tuple[int, ...] | None = None
    fields: list[str] = []
    if cur.accept("["):
        idx: list[int] = []
        if cur.accept("]") is None:
            while True:
                col = cur.col
                v = index_value(cur)
                if not isinstance(v, float) or v != int(v):
                    raise LineError(col, "an array index must be a whole number")
                idx.append(int(v))
                if cur.accept("]"):
                    break
                cur.expect(",", "',' or ']' in the array index")
        index = tuple(idx)
    while cur.accept("."):
        f = cur.next("a field name after '.'")
        if f.kind != "name":
            raise LineError(f.col, f"expected a field name after '.', found {f.text!r}")
        fields.append(f.upper)
    text = t.upper + ("" if index is None else "[" + ",".join(map(str, index)) + "]")
    text += "".join("." + f for f in fields)
    return Ref(t.upper, index, tuple(fields), t.col, text)


def _checked(v: float, col: int) -> float:
    if not math.isfinite(v) or abs(v) > MAX_KRL_VALUE:
        raise LineError(col, f"the expression's value is out of range (|value| <= "
                        f"{MAX_KRL_VALUE:g})")
    return v


def parse_value(cur: Cursor, resolve: Callable[[Ref], Any]) -> Any:
    """An arithmetic expression (``+ - * /``, parentheses, unary signs) or an aggregate literal.

    Names are looked up through ``resolve``. Comparisons, logic and function calls raise
    :class:`LineError` with category ``unsupported``.
    """
    col = cur.col
    v = _term(cur, resolve)
    while True:
        t = cur.peek()
        if t is None or t.text not in ("+", "-"):
            return v
        cur.i += 1
        w = _term(cur, resolve)
        v = _checked(_num(v, col) + _num(w, t.col) if t.text == "+"
                     else _num(v, col) - _num(w, t.col), t.col)


def _num(v: Any, col: int) -> float:
    if isinstance(v, bool) or not isinstance(v, float):
        raise LineError(col, "arithmetic needs numbers here", "unsupported")
    return v


def _term(cur: Cursor, resolve: Callable[[Ref], Any]) -> Any:
    col = cur.col
    v = _unary(cur, resolve)
    while True:
        t = cur.peek()
        if t is None or t.text not in ("*", "/"):
            return v
        cur.i += 1
        w = _num(_unary(cur, resolve), t.col)
        if t.text == "/":
            if w == 0.0:
                raise LineError(t.col, "division by zero")
            v = _checked(_num(v, col) / w, t.col)
        else:
            v = _checked(_num(v, col) * w, t.col)


def _unary(cur: Cursor, resolve: Callable[[Ref], Any]) -> Any:
    t = cur.peek()
    if t is not None and t.text in ("+", "-") and t.kind == "sym":
        cur.i += 1
        cur.enter()
        v = _num(_unary(cur, resolve), t.col)
        cur.depth -= 1
        return -v if t.text == "-" else v
    return _primary(cur, resolve)


def _primary(cur: Cursor, resolve: Callable[[Ref], Any]) -> Any:
    t = cur.peek()
    if t is None:
        raise LineError(cur.end_col, "the statement ends where a value was expected")
    if t.kind == "num":
        cur.i += 1
        return t.value
    if t.text == "(":
        cur.i += 1
        cur.enter()
        v = parse_value(cur, resolve)
        cur.expect(")", "')'")
        cur.depth -= 1
        return v
    if t.text == "{":
        return parse_aggregate(cur)
    if t.kind == "str":
        cur.i += 1
        return t.text[1:-1]
    if t.kind == "enum":
        cur.i += 1
        return t.upper
    if t.kind == "bits":
        cur.i += 1
        return float(_bits(t))
    if t.kind == "name":
        if t.upper in ("TRUE", "FALSE"):
            cur.i += 1
            return t.upper == "TRUE"
        if t.upper in ("NOT", "B_NOT"):
            raise LineError(t.col, f"{t.upper} is not evaluated by the reader", "unsupported")
        nxt = cur.peek(1)
        if nxt is not None and nxt.text == "(":
            raise LineError(t.col, f"function call {t.text}(...) is not evaluated by the reader",
                            "unsupported")
        ref = parse_ref(cur, lambda c: parse_value(c, resolve))
        return resolve(ref)
    raise LineError(t.col, f"expected a value, found {t.text!r}")
