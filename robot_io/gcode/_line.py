"""The careful line reader of the G-code interpreter (private): lines with comments, problems,
parameters, expressions or O-words, with exact columns.

:meth:`robot_io.gcode._interp._Run.read_line` reads a line of plain words itself and hands any
other line to :func:`slow_tokens`, which steps through it with the same token regex
(:data:`robot_io.gcode._words.TOKEN`) and, where that regex sees no word, tries in turn: an
O-word at the line start (:mod:`robot_io.gcode._oword`), a parameter setting ``#… = value`` or
a word whose value is an expression (:mod:`robot_io.gcode._params`); only then is the text
malformed. Messages quote the offending word — never the text of a comment.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from robot_io.gcode import _expr as E
from robot_io.gcode import _oword
from robot_io.gcode import _params as P
from robot_io.gcode import _words as W
from robot_io.options import fix

if TYPE_CHECKING:
    from robot_io.gcode._interp import _Run

__all__ = ["comment", "percent_or_slash", "slow_tokens"]


def percent_or_slash(run: _Run, u: str, first: str) -> str | None:
    """A ``%`` line (``None``: nothing to read) or a ``/`` block-delete line (read it)."""
    if first == "%":
        if u.strip() != "%":
            run.skipped["percent_line"] += 1
            run.warn(1, "percent_line", "text after '%' ignored (a '%' line only delimits "
                     "the program)")
        return None
    i = u.index("/")
    run.meta["block_delete_lines"] += 1
    run.warn(i + 1, "block_delete", "block delete '/' ignored: the block is read as "
             "executed (block delete switch off)")
    return u[:i] + " " + u[i + 1:]


def comment(run: _Run, text: str) -> None:
    """Remember a TCP announcement, and a program name on the first program line."""
    if "TCP:" in text and run.tcp_hint is None:
        run.tcp_hint = run.line
    if run.line == run.first_line and text[0] == "(" and run.meta["program"] is None:
        run.meta["program"] = text[1:-1].strip()


def _nested_end(u: str, start: int, end: int) -> int:
    """For the comment ``u[start:end]`` (``(`` … first ``)``): the end of the comment when it
    holds a ``(`` that a later ``)`` balances (``(T1 (6MM) FLAT)``), ``end`` when it holds none,
    and -1 when the look for the balancing ``)`` ran to the end of the line in vain (an unbalanced
    ``(T1 ( FLAT) Y2 (NOTE)`` is the comment ``(T1 ( FLAT)``, as before; the caller then looks no
    more on that line, so a line is read in linear time)."""
    depth = u.count("(", start + 1, end - 1)
    if not depth or u.find(")", end) < 0:
        return end
    i, n = end, len(u)
    while i < n and depth:
        c = u[i]
        if c == "(":
            depth += 1
        elif c == ")":
            depth -= 1
        i += 1
    return -1 if depth else i


def slow_tokens(run: _Run, u: str) -> tuple[dict, list, int] | None:
    """Tokenise a line with comments, problems, parameters or expressions; ``None`` if the
    line is to be skipped (lenient) after a problem, or held nothing to execute (an O-word).
    The line's parameter settings take effect at its end (not when it is skipped)."""
    keys = run.keys
    words: dict[str, tuple[float, int]] = {}
    codes: list[tuple[str, int | None, int, str]] = []
    col0 = 0
    match = W.TOKEN.match
    n = len(u)
    pos = 0
    params = run.params
    program_word = False   # the line starts with an O number
    comment_end = 0        # column of the ')' of the last comment so far
    nesting = True         # look for nested comments (until a look ran to the end in vain)
    while pos < n:
        m = match(u, pos)
        if m is None:   # only blanks are left
            break
        pos = m.end()
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
            if letter == "O" and not words and not codes:
                program_word = True
                kw = _oword.keyword_at(u, pos)
                if kw is not None:
                    params.pending.clear()
                    try:
                        _oword.flow(run, str(int(float(num))), kw, col, u,
                                    E.skip_blanks(u, pos) + len(kw))
                    except E.ExpressionError as e:
                        return _skip_line(run, e.col, e.category, e.message, e.category)
                    return None
            value = float(num)
            if len(num) > 10 and abs(value) > W.MAX_WORD_VALUE:
                return _skip_line(run, col, "malformed_word", f"{letter}{num[:20]} is out of "
                                  f"range (|value| > {W.MAX_WORD_VALUE:g}); fix the number",
                                  "malformed_block")
        elif com is not None:
            start = m.start(3)
            end = _nested_end(u, start, m.end(3)) if nesting else m.end(3)
            if end == -1:   # no balance up to the end of the line: an ordinary comment
                end, nesting = m.end(3), False
            if end != m.end(3):
                done = (f"remove the inner parentheses, or read with {fix('strict', False)} to "
                        f"take the text up to column {end} as one comment" if run.strict else
                        f"the text up to column {end} was read as one comment")
                run.problem(start + 1, "nested_comment", f"comment at column {start + 1} "
                            f"holds a '(' before its ')' at column {m.end(3)}: comments do not "
                            "nest in G-code (LinuxCNC and Fanuc end one at its first ')' and "
                            f"read the rest as code); {done}", skip="nested_comment")
                pos = end
            comment(run, run.raw[start:end])
            comment_end = pos
            continue
        elif eol is not None:
            comment(run, run.raw[m.start(4):m.end(4)])
            continue
        elif opn is not None:
            run.problem(m.start(5) + 1, "unclosed_comment", "comment '(' is not closed on this "
                        "line; add ')'", skip="unclosed_comment")
            continue
        else:
            start = m.start(6)
            col = start + 1
            try:
                item = _expression_item(run, u, start, not words and not codes)
            except E.ExpressionError as e:
                return _skip_line(run, e.col, e.category, f"{e.message}; fix the expression"
                                  if e.category == "bad_expression" else e.message, e.category)
            if item is None:
                reason = _garbage_reason(u, col, program_word and list(words) == ["O"],
                                         comment_end)
                return _skip_line(run, col, "malformed_word", reason, "malformed_block")
            if item == -1:   # an O-word line, handled
                params.pending.clear()
                return None
            letter, value, pos = item
            if letter is None:   # a parameter setting
                continue
            if abs(value) > W.MAX_WORD_VALUE:
                return _skip_line(run, col, "malformed_word", f"{letter} = {value:.6g} (an "
                                  f"expression) is out of range (|value| > "
                                  f"{W.MAX_WORD_VALUE:g}); fix the expression",
                                  "malformed_block")
            if letter == "G" or letter == "M":
                codes.append(_code(letter, value, col))
                continue
            if letter == "N":
                continue
        if letter in words:
            run.problem(col, "duplicate_word", f"second {letter} word in one block (first at "
                        f"column {words[letter][1]}); keep one of them", skip="duplicate_word")
        elif not col0 and letter in "XYZABCIJKR":
            col0 = col
        words[letter] = (value, col)
    if params.pending:
        params.commit()
    return words, codes, col0


def _skip_line(run: _Run, col: int, category: str, reason: str, skip: str) -> None:
    """A problem that skips the rest of the line: its settings are dropped too."""
    run.params.pending.clear()
    run.problem(col, category, reason, skip=skip)
    return None


def _code(letter: str, value: float, col: int) -> tuple[str, int | None, int, str]:
    """A G or M code whose number came from an expression (``G[#1]``)."""
    return letter, W.code_key_of(value), col, f"{value:g}"


def _expression_item(run: _Run, u: str, i: int, first: bool):
    """What starts at ``u[i]`` where the token regex saw no word: ``(letter, value, end)`` for a
    word with an expression value, ``(None, 0.0, end)`` for a parameter setting, ``-1`` for an
    O-word line (handled), ``None`` when it is no expression at all (malformed text)."""
    c = u[i]
    if c == "#":
        return None, 0.0, P.read_setting(run, u, i)
    if c == ":" and first:   # ISO program number ":1001", as O1001
        j = k = E.skip_blanks(u, i + 1)
        while k < len(u) and "0" <= u[k] <= "9":
            k += 1
        return ("O", float(u[j:k]), k) if k > j else None
    if not ("A" <= c <= "Z"):
        return None
    j = E.skip_blanks(u, i + 1)
    if c == "O" and first and u[j:j + 1] == "<":
        found = _oword.label_at(u, j)
        kw = None if found is None else _oword.keyword_at(u, found[1])
        if found is None or kw is None:
            raise E.ExpressionError(i + 1, "O<name> needs a keyword after it (sub, call, if, "
                                    "while, …)")
        run.params.pending.clear()
        _oword.flow(run, found[0], kw, i + 1, u, E.skip_blanks(u, found[1]) + len(kw))
        return -1
    if not E.starts_value(u, j):
        return None
    value, end = P.read_word(run, u, j)
    return c, value, end


def _word_at(u: str, col: int) -> str:
    """The word at ``col`` (1-based) for a message: its letter, blanks and the text up to the
    next blank, bracket or comment — never a comment's text."""
    i = col - 1
    j = i + 1
    if "A" <= u[i] <= "Z":
        j = E.skip_blanks(u, j)
    n = min(len(u), j + 16)
    while j < n and u[j] not in " \t();":
        j += 1
    return u[i:max(j, i + 1)]


def _garbage_reason(u: str, col: int, after_number: bool, comment_end: int) -> str:
    """Why the text at ``col`` (1-based) is not a word, and what to do; ``after_number``: it
    follows the program number (``O1001 PART``); ``comment_end``: the column of the ``)`` of a
    comment before it on the line, 0 if none."""
    ch = u[col - 1]
    if comment_end:
        close, opening = u.find(")", col - 1), u.find("(", col - 1)
        if close >= 0 and (opening < 0 or close < opening):   # (T1 D=6.) FLAT END MILL)
            return (f"a ')' at column {close + 1} closes no comment: the comment before it "
                    f"ended at its first ')' (column {comment_end}) and the text after that was "
                    "read as code; comments do not nest in G-code: keep one pair of "
                    "parentheses around the comment")
    word = _word_at(u, col)
    if after_number:
        return (f"unexpected {word!r} after the program number: a program number takes "
                "nothing but a comment; put text in parentheses")
    if "A" <= ch <= "Z":
        rest = u[col:col + 40].lstrip(" \t")
        if rest.lstrip("+-.").lstrip(" \t")[:1] in ("", ";", "("):
            return (f"word {word!r} without a number (truncated word?); give it a number or "
                    "remove it")
        return (f"malformed number in {word!r}: one plain decimal number per word, e.g. "
                f"{ch}1.25 (no exponents, NaN/inf or repeated points)")
    if ch == "[":
        return ("an expression '[…]' must be the value of a word, e.g. X[#1 + 2]; give it a "
                "word letter")
    return f"unexpected character {ch!r} in {word!r}; remove it"
