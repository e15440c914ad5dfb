"""KRL conditions (``IF … THEN``) evaluated where the program itself decides them (private helper
of ``robot_io.krl.reader``).

A condition is worked out only from what the program states: literals, declared constants and
variables whose values the reader knows, and the counters of the loops it is unrolling. Anything
decided on the robot — inputs (``$IN``), system variables, function calls, variables set by
statements the reader skips — raises :class:`~robot_io.krl._syntax.LineError` of category
``unsupported``/``unknown_value``/``undeclared``, and the caller treats the condition as run-time.

Operator priority follows KRL (highest first): ``NOT``; ``* /``; ``+ -``; ``AND``; ``EXOR``; ``OR``;
then the comparisons ``== <> < > <= >=``, so ``(A > 0) AND (B < 1)`` needs its parentheses as on
the controller. A mixture the types do not allow (``1 AND TRUE``) is ``unsupported``, never a
guess. Bit operators (``B_AND`` …) are not evaluated.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from robot_io.krl._syntax import (
    MAX_KRL_VALUE,
    Cursor,
    LineError,
    Ref,
    parse_ref,
    parse_value,
)

__all__ = ["condition", "evaluate"]

Resolve = Callable[[Ref], Any]

_COMPARE = {"==", "<>", "<", ">", "<=", ">="}
#: Logic levels from the loosest: OR, then EXOR, then AND (KRL priorities 6, 5, 4).
_LOGIC = ("OR", "EXOR", "AND")


def condition(cur: Cursor, resolve: Resolve) -> bool:
    """The truth value of the condition at the cursor (it must be BOOL)."""
    col = cur.col
    v = evaluate(cur, resolve)
    if not isinstance(v, bool):
        raise LineError(col, "the condition is not TRUE or FALSE", "unsupported")
    return v


def evaluate(cur: Cursor, resolve: Resolve) -> Any:
    """A KRL expression with comparisons and logic: ``float``, ``bool`` or ``str`` (enum)."""
    col = cur.col
    left = _logic(cur, resolve, 0)
    t = cur.peek()
    if t is None or t.kind != "sym" or t.text not in _COMPARE:
        return left
    cur.i += 1
    right = _logic(cur, resolve, 0)
    nxt = cur.peek()
    if nxt is not None and nxt.kind == "sym" and nxt.text in _COMPARE:
        raise LineError(nxt.col, "chained comparisons are not KRL: use parentheses and AND",
                        "unsupported")
    return _compare(t.text, left, right, col)


def _compare(op: str, a: Any, b: Any, col: int) -> bool:
    numbers = all(isinstance(x, float) and not isinstance(x, bool) for x in (a, b))
    if op in ("==", "<>"):
        if not (numbers or type(a) is type(b)):
            raise LineError(col, "a comparison of values of different types", "unsupported")
        return (a == b) == (op == "==")
    if not numbers:
        raise LineError(col, f"'{op}' needs numbers", "unsupported")
    return {"<": a < b, ">": a > b, "<=": a <= b, ">=": a >= b}[op]


def _logic(cur: Cursor, resolve: Resolve, level: int) -> Any:
    if level == len(_LOGIC):
        return _sum(cur, resolve)
    op = _LOGIC[level]
    v = _logic(cur, resolve, level + 1)
    while (t := cur.accept(op)) is not None:
        w = _logic(cur, resolve, level + 1)
        if not (isinstance(v, bool) and isinstance(w, bool)):
            raise LineError(t.col, f"{op} needs TRUE/FALSE on both sides (in KRL {op} binds "
                            "tighter than a comparison: write (N > 3) AND B)", "unsupported")
        v = (v or w) if op == "OR" else (v != w) if op == "EXOR" else (v and w)
    return v


def _number(v: Any, col: int) -> float:
    if isinstance(v, bool) or not isinstance(v, float):
        raise LineError(col, "arithmetic needs numbers here", "unsupported")
    return v


def _checked(v: float, col: int) -> float:
    if not math.isfinite(v) or abs(v) > MAX_KRL_VALUE:
        raise LineError(col, f"the expression's value is out of range (|value| <= "
                        f"{MAX_KRL_VALUE:g})")
    return v


def _sum(cur: Cursor, resolve: Resolve) -> Any:
    col = cur.col
    v = _product(cur, resolve)
    while (t := cur.peek()) is not None and t.kind == "sym" and t.text in ("+", "-"):
        cur.i += 1
        w = _number(_product(cur, resolve), t.col)
        v = _checked(_number(v, col) + (w if t.text == "+" else -w), t.col)
    return v


def _product(cur: Cursor, resolve: Resolve) -> Any:
    col = cur.col
    v = _unary(cur, resolve)
    while (t := cur.peek()) is not None and t.kind == "sym" and t.text in ("*", "/"):
        cur.i += 1
        w = _number(_unary(cur, resolve), t.col)
        if t.text == "/" and w == 0.0:
            raise LineError(t.col, "division by zero", "unsupported")
        v = _checked(_number(v, col) * w if t.text == "*" else _number(v, col) / w, t.col)
    return v


def _unary(cur: Cursor, resolve: Resolve) -> Any:
    t = cur.peek()
    if t is None:
        raise LineError(cur.end_col, "the statement ends where a value was expected")
    if t.kind == "name" and t.upper == "NOT":
        cur.i += 1
        cur.enter()
        v = _unary(cur, resolve)
        cur.depth -= 1
        if not isinstance(v, bool):
            raise LineError(t.col, "NOT needs TRUE or FALSE", "unsupported")
        return not v
    if t.kind == "sym" and t.text in ("+", "-"):
        cur.i += 1
        cur.enter()
        v = _number(_unary(cur, resolve), t.col)
        cur.depth -= 1
        return -v if t.text == "-" else v
    if t.kind == "sym" and t.text == "(":
        cur.i += 1
        cur.enter()
        v = evaluate(cur, resolve)
        cur.expect(")", "')'")
        cur.depth -= 1
        return v
    if t.kind == "name" and t.upper.startswith("B_"):
        raise LineError(t.col, f"the bit operator {t.text} is not evaluated by the reader",
                        "unsupported")
    if t.kind == "name" and t.upper not in ("TRUE", "FALSE"):
        nxt = cur.peek(1)
        if nxt is not None and nxt.text == "(":
            raise LineError(t.col, f"function call {t.text}(...) is not evaluated by the "
                            "reader", "unsupported")
        ref = parse_ref(cur, lambda c: parse_value(c, resolve))
        return resolve(ref)
    # numbers, TRUE/FALSE, enums, strings, bit strings: the arithmetic parser's primaries
    start = cur.i
    v = parse_value(Cursor(cur.toks[: start + 1], cur.end_col, start), resolve)
    cur.i = start + 1
    return v
