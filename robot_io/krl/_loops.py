"""Control blocks: FOR loops unrolled, IF branches chosen, the rest skipped or refused (private
helper of ``robot_io.krl.reader``, whose docstring states the conventions).

Robot-milling converters write the path as a ``.dat`` array of positions and a ``.src`` that
loops over it (``FOR I = 1 TO 4682`` / ``LIN PTS[I] C_DIS`` / ``ENDFOR``). A FOR loop whose counter
is a declared INT and whose bounds the reader can evaluate is run iteration by iteration, like the
controller's advance run; the moves it makes carry ``Move.extra["loop"]`` (the counters of the
loops in force, e.g. ``{"I": 17}``). An IF whose condition the program decides (literals,
constants, known variables, loop counters: :mod:`robot_io.krl._conditions`) runs its THEN or ELSE
branch. Blocks decided on the robot at run time — WHILE, REPEAT, LOOP, SWITCH, an IF on an input —
are skipped when they cannot move the robot and refused when they can, saying why.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial
from typing import TYPE_CHECKING

from robot_io.krl._conditions import condition
from robot_io.krl._program import BLOCKS, MOTIONS, Routine, Stmt
from robot_io.krl._syntax import Cursor, LineError, parse_value
from robot_io.krl._values import Ctx, Unknown, expect_end

if TYPE_CHECKING:
    from robot_io.krl._interp import Runner

__all__ = ["MAX_UNROLLED_MOVES", "loop_context", "run_block"]

#: Moves the reader makes inside loops, all loops of a reading together, before it refuses the
#: program: a converter's FOR loop over a .dat array has one move per point, and a 5 000-point
#: program is far below this, while a bound typed with extra digits (TO 46820000) is stopped
#: before it fills the memory (a move is about 1 kB).
MAX_UNROLLED_MOVES = 1_000_000

#: Why a block of each kind cannot be followed when it holds motion, and what to do instead.
_INSTEAD = ("write the path as straight-line code, or as a FOR loop whose counter is a declared "
            "INT and whose bounds the program states (the reader unrolls those)")
_WHY = {
    "WHILE": "how often a WHILE loop runs depends on its condition, tested on the robot at run "
             "time, so the reader cannot unroll it",
    "REPEAT": "how often a REPEAT … UNTIL loop runs depends on its condition, tested on the "
              "robot at run time, so the reader cannot unroll it",
    "LOOP": "a LOOP runs until an EXIT decided on the robot at run time, so the reader cannot "
            "unroll it",
    "SWITCH": "which CASE runs is decided on the robot at run time; the reader does not choose "
              "SWITCH branches",
}


@dataclass
class _Body:
    """What a block holds, worked out once per block (a loop body is run many times)."""

    mover: Stmt | None              # the first statement that may move the robot
    direct_moves: int               # motions outside nested blocks: made on every iteration
    sets: dict[str, Stmt]           # plain names assigned (or used as FOR counters) inside


def loop_context(runner: Runner) -> str:
    """`` (at I = 17 of the FOR loop at line 5)`` while loops run, for messages; else empty."""
    if not runner.loops:
        return ""
    counters = ", ".join(f"{name} = {k}" for name, k, _, _ in runner.loops)
    lines = ", ".join(str(line) for _, _, line, _ in runner.loops)
    many = "s" if len(runner.loops) > 1 else ""
    return f" (at {counters} of the FOR loop{many} at line{many} {lines})"


def run_block(runner: Runner, ctx: Ctx, st: Stmt, i: int) -> int:
    """Run, skip or refuse the block opened by ``st`` (index ``i``); the next index, or -1 after
    a RETURN inside it."""
    routine = ctx.routine
    if routine is None:                      # blocks exist only inside routines
        return i + 1
    end = routine.block_end.get(i, i)
    kw = st.keyword
    if kw == "FOR":
        return _run_for(runner, ctx, routine, st, i, end)
    if kw == "IF":
        return _run_if(runner, ctx, routine, st, i, end)
    why = _WHY.get(kw, f"the reader does not run {kw} blocks around motion")
    return _skip_or_refuse(runner, routine, st, i, end, f"{why}; {_INSTEAD}")


def _skip_or_refuse(runner: Runner, routine: Routine, st: Stmt, i: int, end: int,
                    why: str) -> int:
    mover = _body(runner, routine, i, end).mover
    if mover is None:
        runner.tp.skipped["control_flow"] += 1
        return end + 1
    raise LineError(st.tokens[0].col, f"{mover.tokens[0].text} at line {mover.line} is inside "
                    f"{st.keyword} … {BLOCKS[st.keyword]} (lines {st.line}–"
                    f"{routine.body[end].line}): {why}", "control_flow")


def _body(runner: Runner, routine: Routine, i: int, end: int) -> _Body:
    found = routine.cache.get(i)
    if isinstance(found, _Body):
        return found
    body = routine.body
    mover: Stmt | None = None
    sets: dict[str, Stmt] = {}
    for inner in body[i + 1:end]:
        if mover is None and runner.may_move(inner):
            mover = inner
        if inner.data is not None:
            if inner.data[0] is None and inner.data[3] is None:
                sets.setdefault(inner.data[2], inner)
        elif inner.fast is None:
            t = inner.tokens
            if inner.keyword == "FOR" and len(t) > 1:
                sets.setdefault(t[1].upper, inner)
            elif len(t) > 1 and t[0].kind == "name" and t[1].text == "=":
                sets.setdefault(t[0].upper, inner)
    direct = 0                  # motions inside nested blocks may not run on every iteration
    j = i + 1
    while j < end:
        if body[j].keyword in MOTIONS:
            direct += 1
        elif body[j].keyword in BLOCKS:
            j = routine.block_end.get(j, j)
        j += 1
    info = _Body(mover, direct, sets)
    routine.cache[i] = info
    return info


def _whole(v: object, col: int, what: str) -> int:
    if isinstance(v, bool) or not isinstance(v, float) or v != int(v):
        raise LineError(col, f"the {what} of a FOR loop must be a whole number (KRL counts "
                        f"with INT), not {v!r}", "control_flow")
    return int(v)


def _run_for(runner: Runner, ctx: Ctx, routine: Routine, st: Stmt, i: int, end: int) -> int:
    """``FOR name = start TO stop [STEP k]`` … ``ENDFOR``: unrolled when it can be."""
    cur = Cursor(st.tokens, st.end_col, 1)
    counter = cur.next("the counter after FOR (FOR I = 1 TO 10)")
    if counter.kind != "name":
        raise LineError(counter.col, f"FOR needs a counter name, found {counter.text!r} "
                        "(FOR I = 1 TO 10)")
    name = counter.upper
    cur.expect("=", "'=' after the FOR counter (FOR I = 1 TO 10)")
    resolve = partial(runner.vars.resolve, ctx)
    step_col = 0
    try:
        start_col = cur.col
        start_v = parse_value(cur, resolve)
        cur.expect("TO", "TO and the end value (FOR I = 1 TO 10)")
        stop_col = cur.col
        stop_v = parse_value(cur, resolve)
        step_v: object = 1.0
        if cur.accept("STEP") is not None:
            step_col = cur.col
            step_v = parse_value(cur, resolve)
        expect_end(cur)
    except LineError as e:
        if e.category == "syntax":
            raise
        return _skip_or_refuse(runner, routine, st, i, end, f"its bounds are not known here "
                               f"({e.reason}); give them as numbers or as INT variables the "
                               "program sets")
    var = runner.vars.lookup(ctx, name)
    if var is None or var.type is None:
        return _skip_or_refuse(runner, routine, st, i, end, f"its counter {counter.text} is not "
                               f"declared; declare it (DECL INT {counter.text}) in the routine "
                               "or its .dat so the reader can unroll the loop")
    if var.type != "INT" or var.dims:
        raise LineError(counter.col, f"the FOR counter {counter.text} is declared "
                        f"{var.type}{'[…]' if var.dims else ''}; KRL counts with a plain INT",
                        "control_flow")
    start = _whole(start_v, start_col, "start")
    stop = _whole(stop_v, stop_col, "end")
    step = _whole(step_v, step_col, "STEP")
    if step == 0:
        raise LineError(step_col, "STEP 0 never ends the loop; give a STEP other than 0",
                        "control_flow")
    info = _body(runner, routine, i, end)
    setter = info.sets.get(name)
    if setter is not None:
        raise LineError(counter.col, f"line {setter.line} inside this FOR … ENDFOR (lines "
                        f"{st.line}–{routine.body[end].line}) sets its counter {counter.text}: "
                        "the reader unrolls loops whose counter runs from start to end by STEP; "
                        "use another variable there", "control_flow")
    if any(v is var for _, _, _, v in runner.loops):
        raise LineError(counter.col, f"this FOR uses the counter {counter.text} of a loop it "
                        "is inside; give the inner loop its own counter", "control_flow")
    ks = range(start, stop + (1 if step > 0 else -1), step)
    robot = runner.robot
    predicted = len(ks) * info.direct_moves
    if robot.unrolled + predicted > MAX_UNROLLED_MOVES:
        raise LineError(st.tokens[0].col, f"this FOR loop makes {predicted} moves ({len(ks)} "
                        f"iterations × {info.direct_moves}), more than the reader unrolls "
                        f"(MAX_UNROLLED_MOVES = {MAX_UNROLLED_MOVES} in all loops): check the "
                        "bounds, or split the path into programs of fewer points", "limit",
                        fatal=True)
    outer = robot.loop
    runner.loops.append((name, start, st.line, var))
    try:
        for k in ks:
            var.value = float(k)
            runner.loops[-1] = (name, k, st.line, var)
            robot.loop = {**outer, name: k}
            if not runner.run_range(ctx, i + 1, end):
                return -1
            if robot.unrolled > MAX_UNROLLED_MOVES:
                raise LineError(st.tokens[0].col, f"the loops have made more than "
                                f"{MAX_UNROLLED_MOVES} moves by {counter.text} = {k} "
                                "(MAX_UNROLLED_MOVES, the most the reader unrolls): check the "
                                "bounds, or split the path into programs of fewer points",
                                "limit", fatal=True)
    finally:
        runner.loops.pop()
        robot.loop = outer
        var.value = Unknown(f"the reader leaves {counter.text} undefined after its FOR loop at "
                            f"{st.file}:{st.line}")
    return end + 1


def _run_if(runner: Runner, ctx: Ctx, routine: Routine, st: Stmt, i: int, end: int) -> int:
    """``IF cond THEN … [ELSE …] ENDIF``: the branch the condition picks, when the program
    decides it; otherwise skipped (no motion inside) or refused."""
    toks = st.tokens
    why = ""
    value = False
    if len(toks) < 3 or toks[-1].upper != "THEN":
        why = "the IF line does not end with THEN"
    else:
        cur = Cursor(toks[:-1], toks[-1].col, 1)
        try:
            value = condition(cur, partial(runner.vars.resolve, ctx))
            expect_end(cur)
        except LineError as e:
            why = e.reason
    if why:
        return _skip_or_refuse(runner, routine, st, i, end, "its condition depends on "
                               f"run-time state ({why}), so the reader cannot know which "
                               "branch moves the robot; decide it in the program (a constant "
                               "or a variable it sets), or write the path without the IF")
    el = routine.else_at.get(i)
    if value:
        a, b = i + 1, (el if el is not None else end)
    else:
        a, b = (el + 1 if el is not None else end), end
    if not runner.run_range(ctx, a, b):
        return -1
    return end + 1
