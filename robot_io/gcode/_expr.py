"""LinuxCNC (RS274/NGC) expressions of the G-code reader (private): the value of a word such as
``X[#1*2]``, ``Z#<depth>`` or ``F-SIN[30]``.

The grammar is the interpreter's (LinuxCNC ``interp_read.cc``, "G-code overview: Expressions"):
a value is a number, ``[expression]``, a parameter ``#n`` / ``##n`` / ``#[n]`` / ``#<name>``, a
sign in front of a value, or a function ``ABS ACOS ASIN COS EXP FIX FUP LN ROUND SIN SQRT TAN`` of
a bracketed expression, ``ATAN[y]/[x]`` or ``EXISTS[#<name>]``. Inside brackets values are
joined by binary operators in five precedence groups, each left to right: ``**``; ``* / MOD``;
``+ -``; ``EQ NE GT GE LT LE``; ``AND OR XOR``. A sign or ``#`` applies to the one value after
it, so ``[-2**2]`` is 4 and ``#1+2`` is (#1) + 2, as in LinuxCNC. Angles are in degrees;
comparisons and logic give 1.0 or 0.0 (zero is false); ``EQ``/``NE`` compare within
:data:`EQUAL_TOL`; ``MOD`` is never negative and ``ROUND`` rounds half away from zero, as in
LinuxCNC. Blanks may stand between the parts of an expression, not inside a number or a name.

:func:`read_value` evaluates with explicit stacks, not recursion, so a 10 MB line of brackets
is read in linear time and cannot overflow the Python stack. Errors are
:class:`ExpressionError` with the 1-based column of the offending character; the caller turns
them into reader problems.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable

__all__ = [
    "EQUAL_TOL",
    "FUNCTIONS",
    "INTEGER_TOL",
    "ExpressionError",
    "as_integer",
    "read_name",
    "read_value",
    "skip_blanks",
    "starts_value",
]

#: ``EQ``/``NE`` treat numbers closer than this [-] as equal: LinuxCNC's ``TOLERANCE_EQUAL``
#: (floating-point results such as ``[0.1*3]`` are then equal to 0.3).
EQUAL_TOL = 1e-6
#: A value within this [-] of an integer counts as that integer where an integer is needed (a
#: parameter number, a G/M code): LinuxCNC's "close enough to an integer" rule.
INTEGER_TOL = 1e-4

#: The functions of a value (each is recognised only with its ``[``, so ``EXP``/``EXISTS`` and
#: ``SIN``/``SQRT`` cannot be confused).
FUNCTIONS = ("ABS", "ACOS", "ASIN", "ATAN", "COS", "EXISTS", "EXP", "FIX", "FUP", "LN", "ROUND",
             "SIN", "SQRT", "TAN")
#: first letter → the functions starting with it
_BY_LETTER = {c: tuple(f for f in FUNCTIONS if f[0] == c) for c in {f[0] for f in FUNCTIONS}}

#: Binary operators → precedence (higher binds tighter); ``**`` is tried before ``*``.
_BINARY = {"**": 5, "*": 4, "/": 4, "MOD": 4, "+": 3, "-": 3, "EQ": 2, "NE": 2, "GT": 2,
           "GE": 2, "LT": 2, "LE": 2, "AND": 1, "OR": 1, "XOR": 1}
_OPERATORS = ("**", "*", "/", "+", "-", "MOD", "EQ", "NE", "GT", "GE", "LT", "LE", "AND", "OR",
              "XOR")
#: A number as the reader writes it: digits with at most one point, at least one digit.
_NUMBER = re.compile(r"(?>\d+(?:\.\d*+)?|\.\d++)(?![\d.])")
_BLANKS = " \t"
_DEG = math.pi / 180.0

#: ``lookup(key, col)``: the value of parameter ``key`` (an ``int`` number or a normalised
#: name) used at ``col``; raises :class:`ExpressionError` when it has none.
Lookup = Callable[[int | str, int], float]
#: ``exists(name, col)``: whether the named parameter exists (``EXISTS[#<name>]``).
Exists = Callable[[str, int], bool]


class ExpressionError(Exception):
    """An expression that cannot be evaluated.

    Attributes:
        col: 1-based column of the offending character.
        category: the reader's warning category (``bad_expression``, ``unset_parameter``, …).
        message: what is wrong and how to fix it.
    """

    def __init__(self, col: int, message: str, category: str = "bad_expression") -> None:
        super().__init__(message)
        self.col = col
        self.category = category
        self.message = message


def skip_blanks(u: str, i: int) -> int:
    """The index of the first character at or after ``i`` that is not a blank."""
    n = len(u)
    while i < n and u[i] in _BLANKS:
        i += 1
    return i


def _shown(u: str, i: int) -> str:
    """The code at ``i`` for a message: up to the next blank, bracket or comment (≤ 12 chars)."""
    j = i
    n = min(len(u), i + 12)
    while j < n and u[j] not in " \t[]();":
        j += 1
    return u[i:max(j, i + 1)]


def as_integer(v: float, col: int, what: str) -> int:
    """``v`` as an integer (within :data:`INTEGER_TOL`), else :class:`ExpressionError`."""
    k = round(v)
    if abs(v - k) > INTEGER_TOL:
        raise ExpressionError(col, f"{what} must be an integer, got {v:.6g}")
    return int(k)


def read_name(u: str, i: int) -> tuple[str, int]:
    """The parameter name of ``<name>`` at ``u[i] == "<"``: blanks removed, lower case (as
    LinuxCNC, so ``#<P a R am>`` is ``#<param>``); returns (name, index after ``>``)."""
    j = u.find(">", i + 1)
    if j < 0:
        raise ExpressionError(i + 1, "parameter name '<…' is not closed with '>'")
    name = u[i + 1:j].replace(" ", "").replace("\t", "").lower()
    if not name:
        raise ExpressionError(i + 1, "empty parameter name '<>'")
    return name, j + 1


def starts_value(u: str, j: int) -> bool:
    """Whether a word's value at ``u[j]`` (after blanks) is one only an expression reader can
    read: ``#``, ``[``, a sign before one of those or before a function, or a function."""
    n = len(u)
    if j >= n:
        return False
    c = u[j]
    if c == "#" or c == "[":
        return True
    if c == "+" or c == "-":
        k = skip_blanks(u, j + 1)
        if k >= n:
            return False
        c = u[k]
        if c == "#" or c == "[":
            return True
        j = k
    return _function_at(u, j) is not None


def _function_at(u: str, i: int) -> str | None:
    """The function name at ``i`` when a ``[`` follows it (blanks allowed), else ``None``."""
    for name in _BY_LETTER.get(u[i:i + 1], ()):
        if u.startswith(name, i):
            k = skip_blanks(u, i + len(name))
            if u[k:k + 1] == "[":
                return name
    return None


def _unary(name: str, v: float, col: int) -> float:
    if name == "ABS":
        return abs(v)
    if name == "ACOS" or name == "ASIN":
        if not -1.0 <= v <= 1.0:
            raise ExpressionError(col, f"{name} of {v:.6g}: the argument must be in -1…1")
        return (math.acos(v) if name == "ACOS" else math.asin(v)) / _DEG
    if name == "COS":
        return math.cos(v * _DEG)
    if name == "SIN":
        return math.sin(v * _DEG)
    if name == "TAN":
        return math.tan(v * _DEG)
    if name == "EXP":
        return math.exp(v)
    if name == "FIX":
        return float(math.floor(v))
    if name == "FUP":
        return float(math.ceil(v))
    if name == "ROUND":   # LinuxCNC: half away from zero
        return float(math.trunc(v + (-0.5 if v < 0.0 else 0.5)))
    if name == "LN":
        if v <= 0.0:
            raise ExpressionError(col, f"LN of {v:.6g}: the argument must be > 0")
        return math.log(v)
    # SQRT
    if v < 0.0:
        raise ExpressionError(col, f"SQRT of {v:.6g}: the argument must be >= 0")
    return math.sqrt(v)


def _binary(op: str, a: float, b: float, col: int) -> float:
    if op == "+":
        return a + b
    if op == "-":
        return a - b
    if op == "*":
        return a * b
    if op == "/":
        if b == 0.0:
            raise ExpressionError(col, f"division by zero ({a:.6g} / 0)")
        return a / b
    if op == "**":
        if a < 0.0 and b != math.floor(b):
            raise ExpressionError(col, f"{a:.6g} ** {b:.6g}: a negative number to a "
                                  "non-integer power")
        if a == 0.0 and b < 0.0:
            raise ExpressionError(col, f"0 ** {b:.6g}: zero to a negative power")
        return a ** b
    if op == "MOD":   # LinuxCNC: fmod, made non-negative
        if b == 0.0:
            raise ExpressionError(col, f"{a:.6g} MOD 0: modulus by zero")
        r = math.fmod(a, b)
        return r + abs(b) if r < 0.0 else r
    if op == "EQ":
        return 1.0 if abs(a - b) < EQUAL_TOL else 0.0
    if op == "NE":
        return 1.0 if abs(a - b) >= EQUAL_TOL else 0.0
    if op == "GT":
        return 1.0 if a > b else 0.0
    if op == "GE":
        return 1.0 if a >= b else 0.0
    if op == "LT":
        return 1.0 if a < b else 0.0
    if op == "LE":
        return 1.0 if a <= b else 0.0
    if op == "AND":
        return 1.0 if (a != 0.0 and b != 0.0) else 0.0
    if op == "OR":
        return 1.0 if (a != 0.0 or b != 0.0) else 0.0
    return 1.0 if ((a != 0.0) != (b != 0.0)) else 0.0   # XOR


def _finite(v: float, col: int) -> float:
    if not math.isfinite(v):
        raise ExpressionError(col, "the result is not a finite number (overflow)")
    return v


def read_value(u: str, i: int, lookup: Lookup, exists: Exists) -> tuple[float, int]:
    """Evaluate the value starting at ``u[i]`` (``u`` upper-cased, blanks before ``i`` skipped);
    returns (value, index just after it). Parameters are read with ``lookup``."""
    n = len(u)
    vals: list[float] = []
    # operator stack: ("(", function or "" or "ATAN2", col, first ATAN argument),
    # ("b", precedence, operator, col) or ("u", "-" / "+" / "#", col)
    ops: list[tuple] = []
    depth = 0
    operand = True
    while True:
        if depth:
            i = skip_blanks(u, i)
        if i >= n:
            if not depth:
                raise ExpressionError(n + 1, "the line ends where a value is needed")
            opened = next(o[2] for o in reversed(ops) if o[0] == "(")
            raise ExpressionError(opened, "'[' is not closed with ']'")
        c = u[i]
        if operand:
            col = i + 1
            if "0" <= c <= "9" or c == ".":
                m = _NUMBER.match(u, i)
                if m is None:
                    raise ExpressionError(col, f"malformed number {_shown(u, i)!r}")
                vals.append(_finite(float(m.group()), col))
                i = m.end()
                operand = False
            elif c == "+" or c == "-":
                ops.append(("u", c, col))
                i = skip_blanks(u, i + 1)
                continue
            elif c == "#":
                j = skip_blanks(u, i + 1)
                if u[j:j + 1] == "<":
                    name, i = read_name(u, j)
                    vals.append(lookup(name, col))
                    operand = False
                else:
                    ops.append(("u", "#", col))
                    i = j
                    continue
            elif c == "[":
                ops.append(("(", "", col, 0.0))
                depth += 1
                i += 1
                continue
            else:
                name = _function_at(u, i)
                if name is None:
                    raise ExpressionError(col, f"expected a number, a parameter '#', '[' or a "
                                          f"function, found {_shown(u, i)!r}")
                i = skip_blanks(u, i + len(name)) + 1
                if name == "EXISTS":
                    j = skip_blanks(u, i)
                    k = skip_blanks(u, j + 1)
                    if u[j:j + 1] != "#" or u[k:k + 1] != "<":
                        raise ExpressionError(j + 1, "EXISTS takes one named parameter, e.g. "
                                              "EXISTS[#<depth>]")
                    pname, k = read_name(u, k)
                    k = skip_blanks(u, k)
                    if u[k:k + 1] != "]":
                        raise ExpressionError(k + 1, "EXISTS[#<name>] needs its ']'")
                    vals.append(1.0 if exists(pname, col) else 0.0)
                    i = k + 1
                    operand = False
                else:
                    ops.append(("(", name, col, 0.0))
                    depth += 1
                    continue
            _prefixes(ops, vals, lookup)   # a value is complete: apply the signs and '#'
            if not depth:
                return vals[-1], i
            continue
        # an operator or ']' is expected
        if c == "]":
            while ops[-1][0] == "b":
                _reduce(ops, vals)
            _, name, ocol, first = ops.pop()
            depth -= 1
            i += 1
            if name == "ATAN":
                j = skip_blanks(u, i)
                k = skip_blanks(u, j + 1)
                if u[j:j + 1] != "/" or u[k:k + 1] != "[":
                    raise ExpressionError(j + 1, "ATAN needs two arguments: ATAN[y]/[x]")
                ops.append(("(", "ATAN2", ocol, vals.pop()))
                depth += 1
                i = k + 1
                operand = True
                continue
            if name == "ATAN2":
                vals[-1] = math.atan2(first, vals[-1]) / _DEG
            elif name:
                try:
                    vals[-1] = _finite(_unary(name, vals[-1], ocol), ocol)
                except OverflowError as e:
                    raise ExpressionError(ocol, f"{name} overflows (the result is too large)") from e
            _prefixes(ops, vals, lookup)   # the bracket closes a value
            if not depth:
                return vals[-1], i
            continue
        op = None
        for cand in _OPERATORS:
            if u.startswith(cand, i):
                op = cand
                break
        if op is None:
            raise ExpressionError(i + 1, f"expected an operator or ']', found {_shown(u, i)!r}")
        prec = _BINARY[op]
        while ops[-1][0] == "b" and ops[-1][1] >= prec:
            _reduce(ops, vals)
        ops.append(("b", prec, op, i + 1))
        i += len(op)
        operand = True


def _prefixes(ops: list, vals: list[float], lookup: Lookup) -> None:
    """Apply the signs and ``#`` written in front of the value just completed."""
    while ops and ops[-1][0] == "u":
        _, what, col = ops.pop()
        if what == "-":
            vals[-1] = -vals[-1]
        elif what == "#":
            vals[-1] = lookup(as_integer(vals[-1], col, "a parameter number"), col)


def _reduce(ops: list, vals: list[float]) -> None:
    _, _prec, op, col = ops.pop()
    b = vals.pop()
    try:
        vals[-1] = _finite(_binary(op, vals[-1], b, col), col)
    except OverflowError as e:
        raise ExpressionError(col, "the result is not a finite number (overflow)") from e
