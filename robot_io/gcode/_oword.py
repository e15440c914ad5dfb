"""O-words of the G-code reader (private): the program number and LinuxCNC O-word flow control.

* ``O1001`` (or ``O1001 (PART NAME)``, ``:1001``) before the first block of the program is the
  Fanuc/ISO program number: ``meta["program"] = "O1001"``, ``meta["program_number"] = 1001``.
* LinuxCNC flow control ("O Codes") is run as LinuxCNC runs it: ``o100 sub`` … ``o100 endsub``
  defines a subroutine (its body is not run where it is written; it may come before or after its
  calls), ``o100 call [a] [b]`` runs it with ``#1 = a``, ``#2 = b`` … (local parameters, see
  :mod:`robot_io.gcode._params`), ``o100 return [v]`` / ``endsub [v]`` set ``#<_value>``;
  ``if``/``elseif``/``else``/``endif``, ``while``/``endwhile``, ``do``/``while``,
  ``repeat [n]``/``endrepeat``, ``break`` and ``continue``. Conditions are expressions
  (:mod:`robot_io.gcode._expr`), non-zero is true. A loop body runs at most
  :data:`MAX_LOOP_ITERATIONS` times per entry, calls nest at most :data:`MAX_CALL_DEPTH` deep,
  and a reading runs at most :data:`MAX_FLOW_STEPS` loop iterations and calls and reads at most
  :data:`MAX_FLOW_LINES` lines again through them, in all.
* Refused in strict mode, skipped with a counted warning ``o_word`` saying what the skipping may
  change in lenient mode: a call of a subroutine not in the file (LinuxCNC would look for
  ``o100.ngc``), a construct without its closing line, a loop over its limit, a bare O-number
  later in the program (a Fanuc subprogram or a second program) and Fanuc's ``M98``/``M99``.

Jumps (a loop going round, a call, a return) raise :class:`Jump`, which the line loop of
:meth:`robot_io.gcode._interp._Run.run` catches to go on at the target line; forward skips over a
branch or a subroutine body are jumps too. The O-lines of the program are indexed once, at the
first flow-control line.
"""

from __future__ import annotations

import bisect
import re
from typing import TYPE_CHECKING

from robot_io.gcode import _expr as E
from robot_io.gcode import _params as P
from robot_io.options import fix

if TYPE_CHECKING:
    from robot_io.gcode._interp import _Run

__all__ = ["KEYWORDS", "MAX_CALL_DEPTH", "MAX_FLOW_LINES", "MAX_FLOW_STEPS", "MAX_LOOP_ITERATIONS",
           "Flow",
           "Jump", "fanuc_subprogram", "flow", "keyword_at", "label_at", "program_number"]

#: The LinuxCNC O-word keywords, longest first where one starts another.
KEYWORDS = ("ENDREPEAT", "ENDWHILE", "ENDSUB", "ENDIF", "ELSEIF", "ELSE", "CONTINUE", "BREAK",
            "RETURN", "REPEAT", "WHILE", "CALL", "SUB", "DO", "IF")
#: Most times one loop's body runs per entry: beyond it the loop is surely endless (a condition
#: that never turns false), and reading it would only fill memory.
MAX_LOOP_ITERATIONS = 100_000
#: Deepest nesting of subroutine calls (recursion included); deeper is runaway recursion.
MAX_CALL_DEPTH = 100
#: Most loop iterations and calls of one reading in all (nested loops multiply): about ten
#: seconds of reading and a GB of moves at most.
MAX_FLOW_STEPS = 1_000_000
#: Most lines one reading reads again through loop rounds and calls (each counts its body and
#: one line more: the loop's test or end, the call) [lines]: a line read by the interpreter costs
#: 10-40 µs (expressions, rotary kinematics), so this bounds a reading's loops to under a second.
#: The fuzzing found a 717-byte program whose endless while loop read 400,000 lines in 8 s before
#: the loop limit stopped it, and 200-byte ones that took 2-4 s under a budget of 50,000 lines on a
#: loaded machine. Hand-written loops (a facing program's passes, a pattern of pockets) read a few
#: thousand lines; a program whose loops really expand to more is one to post from CAM without
#: O-word loops.
MAX_FLOW_LINES = 20_000
#: Most arguments of a call (LinuxCNC ``INTERP_SUB_PARAMS``, the local ``#1``–``#30``).
_MAX_ARGS = P.LOCAL_NUMBERED
#: An O-line: optional block delete and line number, then O and a label and a keyword.
_O_LINE = re.compile(r"[ \t]*/?[ \t]*(?:N[ \t]*\d+(?:\.\d*)?[ \t]*)?O[ \t]*(\d+|<[^>]*>)[ \t]*"
                     r"(" + "|".join(KEYWORDS) + r")(?![A-Z])")


class Jump(Exception):
    """Go on reading at line index ``target`` (0-based)."""

    def __init__(self, target: int) -> None:
        super().__init__(target)
        self.target = target


def label_at(u: str, i: int) -> tuple[str, int] | None:
    """The O-word label at ``u[i]`` (just after the ``O``): ``"100"`` for ``O0100``, ``"<name>"``
    for ``O<name>``; returns (label, index after it) or ``None``."""
    j = E.skip_blanks(u, i)
    if u[j:j + 1] == "<":
        try:
            name, k = E.read_name(u, j)
        except E.ExpressionError:
            return None
        return f"<{name}>", k
    k = j
    while k < len(u) and "0" <= u[k] <= "9":
        k += 1
    return (str(int(u[j:k])), k) if k > j else None


def keyword_at(u: str, i: int) -> str | None:
    """The O-word keyword at ``u[i]`` (blanks skipped), when one starts there."""
    j = E.skip_blanks(u, i)
    for kw in KEYWORDS:
        if u.startswith(kw, j):
            after = u[j + len(kw):j + len(kw) + 1]
            if not ("A" <= after <= "Z"):
                return kw
    return None


def _label(raw: str) -> str:
    if raw[0] == "<":
        return "<" + raw[1:-1].replace(" ", "").replace("\t", "").lower() + ">"
    return str(int(raw))


class Flow:
    """The O-lines of a program and the flow-control state of one reading.

    Attributes:
        lines: label → sorted [(line index, keyword)] of the program's O-lines.
        calls: the call stack: (label, return line index, the caller's local parameters).
        loops: (call depth, label) → [kind, line index of its head, iterations, repeats left].
        arriving: (call depth, label) of the if whose elseif/else/endif is jumped to.
        steps: loop iterations and calls so far.
        reread: lines read again by those iterations and calls so far (their bodies).
    """

    def __init__(self, program: list[str]) -> None:
        self.lines: dict[str, list[tuple[int, str]]] = {}
        for i, line in enumerate(program):
            if "o" in line or "O" in line:
                m = _O_LINE.match(line.upper())
                if m is not None:
                    self.lines.setdefault(_label(m.group(1)), []).append((i, m.group(2)))
        self.calls: list[tuple[str, int, dict]] = []
        self.loops: dict[tuple[int, str], list] = {}
        self.arriving: tuple[int, str] | None = None
        self.steps = 0
        self.reread = 0

    def next(self, label: str, after: int, keywords: tuple[str, ...]) -> int | None:
        """Index of the first O-line of ``label`` after line ``after`` with one of
        ``keywords``."""
        entries = self.lines.get(label, [])
        k = bisect.bisect_right(entries, (after, "~"))
        for i, kw in entries[k:]:
            if kw in keywords:
                return i
        return None

    def definitions_after(self, end: int, program: list[str]) -> int:
        """Non-blank lines of the subroutine definitions after line index ``end`` (they are
        read when called, so they are no lines "after the program end")."""
        count = 0
        for entries in self.lines.values():
            head = None
            for i, kw in entries:
                if kw == "SUB":
                    head = i
                elif kw == "ENDSUB" and head is not None:
                    if head > end:
                        count += sum(1 for line in program[head:i + 1]
                                     if line.strip() and line.strip() != "%")
                    head = None
        return count


def _refuse(run: _Run, col: int, shown: str, what: str, effect: str,
            remedy: str = "fix the program") -> None:
    """A construct the reader cannot run: strict raises, lenient warns with the effect."""
    if run.strict:
        run.problem(col, "o_word", f"{shown}: {what}; {remedy}, or read with "
                    f"{fix('strict', False)} to go on: {effect}")
    run.problem(col, "o_word", f"{shown}: {what}; {effect}", skip="o_word")


def _condition(run: _Run, u: str, end: int) -> float:
    """The bracketed value after an O-word keyword (:func:`_check_rest` saw the bracket)."""
    return P.read_word(run, u, E.skip_blanks(u, end))[0]


def _arguments(run: _Run, u: str, end: int) -> list[float]:
    args: list[float] = []
    j = E.skip_blanks(u, end)
    while j < len(u) and u[j] in "[(":
        if u[j] == "(":
            k = u.find(")", j)
            j = len(u) if k < 0 else k + 1
        else:
            if len(args) == _MAX_ARGS:
                raise E.ExpressionError(j + 1, f"more than {_MAX_ARGS} call arguments")
            v, j = P.read_word(run, u, j)
            args.append(v)
        j = E.skip_blanks(u, j)
    return args


def _check_rest(u: str, end: int, shown: str, keyword: str) -> None:
    """Nothing but bracketed values and comments may follow an O-word's keyword (LinuxCNC
    refuses other words there too: ``o1 if [#1] G1 X5`` would lose the move)."""
    j, n = E.skip_blanks(u, end), len(u)
    if keyword in ("IF", "ELSEIF", "WHILE", "REPEAT") and u[j:j + 1] != "[":
        raise E.ExpressionError(j + 1, f"{shown} needs its value in brackets, e.g. "
                                f"{shown} [#1 GT 0]")
    while j < n:
        c = u[j]
        if c == "[" or c == "(":
            close = "]" if c == "[" else ")"
            depth, k = 0, j
            while k < n:
                if u[k] == c:
                    depth += 1
                elif u[k] == close:
                    depth -= 1
                    if not depth:
                        break
                k += 1
            j = E.skip_blanks(u, k + 1)
        elif c == ";":
            return
        else:
            raise E.ExpressionError(j + 1, f"{shown}: only its value in brackets and comments "
                                    "may follow it (LinuxCNC refuses other words on an O-word "
                                    "line); put the rest on a line of its own")


def flow(run: _Run, label: str, keyword: str, col: int, u: str, end: int) -> None:
    """Run the O-word line ``o<label> <keyword>`` (``u[end:]`` holds its condition or arguments);
    raises :class:`Jump` to go on elsewhere. Expression errors raise
    :class:`~robot_io.gcode._expr.ExpressionError`."""
    _check_rest(u, end, f"o{label} {keyword.lower()}", keyword)
    f = run.flow
    if f is None:
        f = run.flow = Flow(run.lines)
    i = run.line - 1
    depth = len(f.calls)
    key = (depth, label)
    shown = f"o{label} {keyword.lower()}"
    if keyword == "SUB":   # a definition where it is written: skip its body
        stop = f.next(label, i, ("ENDSUB",))
        if stop is None:
            _refuse(run, col, shown, f"no o{label} endsub closes the subroutine",
                    "the lines after it are read as part of the main program")
            return
        raise Jump(stop + 1)
    if keyword == "CALL":
        head = f.next(label, -1, ("SUB",))
        if head is None:
            where = (f" (LinuxCNC would look for the file {label[1:-1]}.ngc in its subroutine "
                     "path, which a single file does not give)" if label[0] == "<" else "")
            _refuse(run, col, shown, f"no o{label} sub in this file{where}",
                    "the call is skipped: its moves are missing and the moves after it start "
                    "from where the tool was before the call")
            return
        args = _arguments(run, u, end)
        if depth >= MAX_CALL_DEPTH:
            _refuse(run, col, shown, f"calls nest deeper than {MAX_CALL_DEPTH} (runaway "
                    "recursion?)", "the call is skipped")
            return
        body = f.next(label, head, ("ENDSUB",))
        if not _step(run, f, col, shown, 1 if body is None else body - head):
            return
        f.calls.append((label, i + 1, run.params.enter(args)))
        raise Jump(head + 1)
    if keyword == "ENDSUB" or keyword == "RETURN":
        j = E.skip_blanks(u, end)
        value = _condition(run, u, j) if u[j:j + 1] == "[" else None
        if not f.calls or f.calls[-1][0] != label:
            _refuse(run, col, shown, f"not inside a call of o{label}", "the line is ignored")
            return
        _label_, back, saved = f.calls.pop()
        for k in [k for k in f.loops if k[0] == depth]:   # loops of the call end with it
            del f.loops[k]
        run.params.leave(saved, value)
        raise Jump(back)
    if keyword in ("IF", "ELSEIF", "ELSE", "ENDIF"):
        _if(run, f, key, keyword, col, u, end, shown, i)
        return
    _loop(run, f, key, keyword, col, u, end, shown, i)


def _if(run: _Run, f: Flow, key: tuple, keyword: str, col: int, u: str, end: int, shown: str,
        i: int) -> None:
    label = key[1]
    arrived = f.arriving == key
    f.arriving = None
    if keyword == "ENDIF":
        return
    if (keyword == "ELSEIF" or keyword == "ELSE") and not arrived:   # a branch was taken
        stop = f.next(label, i, ("ENDIF",))
        if stop is None:
            _refuse(run, col, shown, f"no o{label} endif closes the if", "the lines after "
                    "it are read as if every branch ran")
            return
        raise Jump(stop + 1)
    if keyword == "ELSE" or _condition(run, u, end) != 0.0:
        return
    stop = f.next(label, i, ("ELSEIF", "ELSE", "ENDIF"))
    if stop is None:
        _refuse(run, col, shown, f"no o{label} else/endif closes the if", "the lines after "
                "it are read as if the condition were true")
        return
    f.arriving = key
    raise Jump(stop)


def _step(run: _Run, f: Flow, col: int, shown: str, body: int) -> bool:
    """Count one more loop round or call, whose body is ``body`` lines (see MAX_FLOW_LINES)."""
    f.steps += 1
    f.reread += max(body, 0) + 1
    if f.steps <= MAX_FLOW_STEPS and f.reread <= MAX_FLOW_LINES:
        return True
    what = (f"runs more than {MAX_FLOW_STEPS:,} loop iterations and calls in all"
            if f.steps > MAX_FLOW_STEPS else
            f"reads more than {MAX_FLOW_LINES:,} lines again through its loops and calls (an "
            "endless loop, or a program to post from CAM without O-word loops)")
    _refuse(run, col, shown, f"the program {what}", "the rest of the program is not read")
    raise Jump(len(run.lines))


def _loop(run: _Run, f: Flow, key: tuple, keyword: str, col: int, u: str, end: int, shown: str,
          i: int) -> None:
    label = key[1]
    loop = f.loops.get(key)
    if keyword == "DO":
        f.loops[key] = ["do", i, 1, 0]
        return
    if keyword == "REPEAT":
        count = _condition(run, u, end)
        stop = f.next(label, i, ("ENDREPEAT",))
        if stop is None:
            _refuse(run, col, shown, f"no o{label} endrepeat closes the loop", "its body is "
                    "read once")
            return
        n = int(count) if count >= 1.0 else 0
        if n > MAX_LOOP_ITERATIONS:
            _refuse(run, col, shown, f"repeats {n:,} times, more than {MAX_LOOP_ITERATIONS:,}",
                    f"its body is read {MAX_LOOP_ITERATIONS:,} times")
            n = MAX_LOOP_ITERATIONS
        if n == 0:
            raise Jump(stop + 1)
        f.loops[key] = ["repeat", i, 1, n - 1]
        return
    if keyword == "WHILE" and loop is not None and loop[0] == "do" and loop[1] < i:
        if _condition(run, u, end) == 0.0:   # the end of a do loop
            del f.loops[key]
            return
        if _again(run, f, key, loop, col, shown, i + 1, i - loop[1]):
            raise Jump(loop[1] + 1)
        return
    if keyword == "WHILE":
        stop = f.next(label, i, ("ENDWHILE",))
        if stop is None:
            _refuse(run, col, shown, f"no o{label} endwhile closes the loop", "its body is "
                    "read once")
            return
        if _condition(run, u, end) == 0.0:
            f.loops.pop(key, None)
            raise Jump(stop + 1)
        if loop is None or loop[1] != i:
            f.loops[key] = ["while", i, 1, 0]
        else:
            _again(run, f, key, loop, col, shown, stop + 1, stop - i)
        return
    if loop is None:
        _refuse(run, col, shown, f"not inside an o{label} loop", "the line is ignored")
        return
    kind, head = loop[0], loop[1]
    if keyword == "ENDWHILE":
        raise Jump(head)
    if keyword == "ENDREPEAT":
        if loop[3] <= 0:
            del f.loops[key]
            return
        loop[3] -= 1
        if _again(run, f, key, loop, col, shown, i + 1, i - head):
            raise Jump(head + 1)
        return
    # BREAK / CONTINUE: to the loop's end or its test
    closing = {"while": ("ENDWHILE",), "repeat": ("ENDREPEAT",), "do": ("WHILE",)}[kind]
    stop = f.next(label, i, closing)
    if stop is None:
        _refuse(run, col, shown, f"the o{label} loop has no end", "the line is ignored")
        return
    if keyword == "BREAK":
        del f.loops[key]
        raise Jump(stop + 1)
    raise Jump(head if kind == "while" else stop)


def _again(run: _Run, f: Flow, key: tuple, loop: list, col: int, shown: str, out: int,
           body: int) -> bool:
    """Count one more round of ``loop`` (``body`` lines long); over a limit the loop is left
    (jump to ``out``)."""
    loop[2] += 1
    if loop[2] > MAX_LOOP_ITERATIONS:
        del f.loops[key]
        _refuse(run, col, shown, f"the loop ran {MAX_LOOP_ITERATIONS:,} times without ending "
                "(a condition that never turns false?)", "it is left there and the lines "
                "after it are read")
        raise Jump(out)
    return _step(run, f, col, shown, body)


def program_number(run: _Run, value: float, col: int, first: bool) -> None:
    """An ``O`` number word: the program number in the program's ``first`` block, else
    refused."""
    number = round(value)
    if abs(value - number) > E.INTEGER_TOL or number < 0:
        run.problem(col, "bad_word", f"program number O{value:g} must be a whole number",
                    skip="bad_word")
        return
    if first:
        run.meta["program"] = f"O{number}"
        run.meta["program_number"] = number
        return
    _refuse(run, col, f"O{number}", "a bare O-number after the program start begins a "
            f"Fanuc-style subprogram (run by M98 P{number}, ended by M99) or a second program, "
            "which cctmill does not read as such", "the lines after it are read as part of "
            "the main program (a subprogram's moves appear once, where it is written, not "
            "where M98 calls it)", "keep one program, with its number first")


def fanuc_subprogram(run: _Run, key: int, col: int) -> None:
    """Fanuc ``M98`` (subprogram call) and ``M99`` (subprogram end): refused or skipped."""
    if key == 980:
        _refuse(run, col, "M98", "Fanuc subprogram calls are not supported", "the call is "
                "skipped: its moves are missing and the moves after it start from where the "
                "tool was before the call", "write the subprogram as an o-sub or let the CAM "
                "post write the moves out")
    else:
        _refuse(run, col, "M99", "the Fanuc subprogram end (or a main program's restart) is "
                "not supported", "the line is ignored", "remove it")
