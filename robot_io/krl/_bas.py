"""``BAS(#CMD[, value])`` and the inline forms' motion data (private helper of
``robot_io.krl.reader``, whose docstring states the conventions).

KUKA's teach-pendant inline forms write a LIN as a fold around ``LDAT_ACT=LCPDAT1``,
``FDAT_ACT=FP1``, ``BAS(#CP_PARAMS, v)`` and ``LIN XP1``, with the motion data in the ``.dat``:
``DECL LDAT LCPDAT1={VEL 0.2,ACC 100.0,APO_DIST 100.0,…}`` (VEL in m/s for CP motions),
``DECL PDAT PPDAT1={VEL 100.0,…}`` (VEL in % of the axes' maximum speed) and
``DECL FDAT FP1={TOOL_NO 1,BASE_NO 1,…}``. What is read here:

* ``BAS(#VEL_CP, v)`` and ``BAS(#CP_PARAMS, v)`` set the path speed to ``v`` [m/s]; ``v`` may be any
  expression the reader evaluates, e.g. ``LDAT_ACT.VEL`` after ``LDAT_ACT=LCPDAT1`` (older
  inline forms). The number in the call is the speed: KSS inline forms write the form's "Vel"
  there and the LDAT's VEL is then not used (INFERRED from robot-forum.com thread 11570 and
  the inline-form folds of several converters).
* ``BAS(#CP_DAT)`` takes the path speed from ``LDAT_ACT.VEL`` [m/s] (INFERRED: #CP_DAT/#PTP_DAT
  "apply" LDAT_ACT/PDAT_ACT, as converters that set ``LDAT_ACT.VEL`` and then call it rely on).
* ``BAS(#PTP_PARAMS, p)``, ``BAS(#VEL_PTP, p)`` and ``BAS(#PTP_DAT)`` (``PDAT_ACT.VEL``) set the PTP
  speed, a percentage of the axes' maximum speed. A PTP has no Cartesian feed (``Move.feed`` stays
  ``None``); the percentage goes to ``Move.extra["ptp_velocity_pct"]``.
* ``BAS(#TOOL, n)``/``BAS(#BASE, n)`` select ``TOOL_DATA[n]``/``BASE_DATA[n]``; ``#FRAMES``,
  ``#PTP_PARAMS`` and ``#CP_PARAMS`` select them from ``FDAT_ACT``'s TOOL_NO/BASE_NO when that is
  known (INFERRED from KUKA's inline-form code).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from robot_io.krl._motion import Frame, frame_from
from robot_io.krl._program import Stmt
from robot_io.krl._syntax import Aggregate, Cursor, LineError, Ref
from robot_io.krl._values import Ctx, Unknown, expect_end
from robot_io.toolpath import SourceRef

if TYPE_CHECKING:
    from robot_io.krl._interp import Runner

__all__ = ["frame_by_index", "run_bas"]

#: Commands that set the CP speed, the PTP speed, or select frames (others are only counted).
_CP_SPEED = frozenset({"#VEL_CP", "#CP_PARAMS", "#CP_DAT"})
_PTP_SPEED = frozenset({"#VEL_PTP", "#PTP_PARAMS", "#PTP_DAT"})


def _src(st: Stmt, col: int) -> str:
    return str(SourceRef(st.file, st.line, col))


def _motion_data(runner: Runner, ctx: Ctx, name: str) -> tuple[Any, str]:
    """``NAME.VEL`` of LDAT_ACT/PDAT_ACT, or an :class:`Unknown` saying why it is not known."""
    var = runner.vars.lookup(ctx, name)
    value = var.value if var is not None else Unknown(f"{name} is not set in the program")
    if isinstance(value, Unknown):
        return value, value.reason
    if not isinstance(value, Aggregate) or "VEL" not in value.fields:
        return Unknown(f"{name} has no VEL"), f"{name} has no VEL component"
    return value.fields["VEL"], ""


def run_bas(runner: Runner, ctx: Ctx, st: Stmt, cur: Cursor) -> None:
    """``BAS(#CMD[, value])`` at the cursor (just past ``BAS(``)."""
    cmd = cur.next("a BAS command such as #INITMOV")
    if cmd.kind != "enum":
        raise LineError(cmd.col, f"expected a BAS command such as #INITMOV, found "
                        f"{cmd.text!r}")
    arg: Any = None
    col = cur.col
    if cur.accept(","):
        col = cur.col
        arg = runner.vars.value_or_unknown(ctx, cur, st)
    cur.expect(")", "')'")
    expect_end(cur)
    c = cmd.upper
    robot = runner.robot
    if c == "#CP_DAT":
        arg, why = _motion_data(runner, ctx, "LDAT_ACT")
        if isinstance(arg, Unknown):
            raise LineError(cmd.col, f"BAS(#CP_DAT) sets the path speed from LDAT_ACT.VEL, "
                            f"which is not known here ({why}); set LDAT_ACT to an LDAT of the "
                            ".dat first (LDAT_ACT=LCPDAT1)", "unknown_value")
        col = cmd.col
    if c in _CP_SPEED:
        if isinstance(arg, Unknown):
            raise LineError(col, f"BAS({c}, …): the speed is not known here ({arg.reason})",
                            "unknown_value")
        robot.set_feed(st, col, arg, f"BAS({c})")
    elif c in _PTP_SPEED:
        if c == "#PTP_DAT":
            arg, _ = _motion_data(runner, ctx, "PDAT_ACT")
        ok = isinstance(arg, float) and not isinstance(arg, bool)
        robot.ptp_velocity_pct = arg if ok else None
    if c in ("#TOOL", "#BASE"):
        if isinstance(arg, bool) or not isinstance(arg, float) or arg != int(arg) or arg < 0:
            raise LineError(col, f"BAS({c}, n) needs a whole number n >= 0")
        which = c[1:]
        robot.apply_frame(st, cmd.col, which,
                          frame_by_index(runner, ctx, st, col, which, int(arg)))
    elif c in ("#FRAMES", "#PTP_PARAMS", "#CP_PARAMS"):
        _fdat_frames(runner, ctx, st, cmd.col)
    if c not in _CP_SPEED and c not in ("#TOOL", "#BASE"):
        runner.tp.skipped["bas"] += 1


def _fdat_frames(runner: Runner, ctx: Ctx, st: Stmt, col: int) -> None:
    """Inline forms select $TOOL/$BASE from FDAT_ACT's TOOL_NO/BASE_NO when it is known."""
    var = runner.vars.lookup(ctx, "FDAT_ACT")
    fdat = var.value if var is not None else None
    if not isinstance(fdat, Aggregate):
        return
    for which in ("TOOL", "BASE"):
        n = fdat.fields.get(f"{which}_NO")
        if isinstance(n, float) and n == int(n) and n >= 0:
            runner.robot.apply_frame(st, col, which,
                                     frame_by_index(runner, ctx, st, col, which, int(n)))


def frame_by_index(runner: Runner, ctx: Ctx, st: Stmt, col: int, which: str, n: int) -> Frame:
    """``TOOL_DATA[n]`` / ``BASE_DATA[n]`` as selected by ``BAS(#TOOL, n)`` etc.; 0 = null."""
    if n == 0:
        return Frame("$NULLFRAME", np.eye(4), _src(st, col), 0)
    table = f"{which}_DATA"
    try:
        value: Any = runner.vars.resolve(ctx, Ref(table, (n,), (), col, f"{table}[{n}]"))
    except LineError:
        value = None
    return frame_from(value, f"{table}[{n}]", _src(st, col), col, n)
