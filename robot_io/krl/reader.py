"""Read KUKA KRL programs (``.src`` + ``.dat``) into the plain move model of ``robot_io.toolpath``.

What is read (KUKA_IO.md §1): ``&`` header lines; ``DEF … END`` (local routines after the main one;
``DEFFCT`` functions are never run); ``DEFDAT … ENDDAT`` with ``DECL [GLOBAL] [CONST] TYPE NAME=…``
(E6POS/POS/FRAME/E6AXIS/AXIS aggregates, REAL/INT/BOOL, arrays and ``NAME[i]=…`` lines); ``;``
comments and ``;FOLD … ;ENDFOLD`` (comments — the statements inside folds, e.g. the INI fold, are
run); ``$VEL.CP`` (m/s; a literal, a REAL variable or simple arithmetic); ``$BASE``/``$TOOL``
(``{FRAME: …}`` literals, FRAME variables, ``BASE_DATA[n]``/``TOOL_DATA[n]``, ``$NULLFRAME``);
``BAS(#TOOL,n)``/``BAS(#BASE,n)``; ``PTP``/``LIN``/``CIRC`` to inline literals (with or without a
``E6POS:``-style type prefix) or named positions, with ``C_DIS``/``C_VEL``/``C_ORI``/``C_PTP``;
``CIRC aux, end[, CA angle]``; ``LIN_REL``/``PTP_REL`` (translation only); ``FOR`` loops and ``IF``
blocks the program decides (below); and calls ``NAME( )`` to local routines or to ``NAME.src``
beside the program (paged programs), in program order.

Conventions (read this before trusting a number)
------------------------------------------------
* Poses are the TCP in the program's ``$BASE`` frame (the workpiece frame), metres;
  ``Toolpath.units == "mm"`` because KRL positions are mm (angles deg). ``$VEL.CP`` is already SI
  (m/s) and becomes ``Move.feed`` of LIN and CIRC moves; PTP moves are ``MoveKind.RAPID`` with
  ``feed=None``.
* Orientation: KUKA A, B, C are Z-Y'-X'' Euler angles, R = Rz(A)·Ry(B)·Rx(C) (:func:`abc_to_matrix`);
  the columns of R are the TCP axes in ``$BASE``. The tool axis of docs/model.md §1 is the TCP +x (spindle →
  tip), so ``Move.tool_axis = -R[:, 0]`` (tip → spindle). ``Move.extra["abc_deg"]`` keeps (A, B, C),
  ``extra["s"]``/``extra["t"]`` the status/turn when given, ``extra["external"]`` E1–E6,
  ``extra["approx"]`` the approximation keyword and ``extra["apo_cdis"]`` [m] ``$APO.CDIS`` for
  ``C_DIS``. A target that leaves out components keeps the current ones (as the controller does); a
  target without A, B, C when the orientation was never given has ``tool_axis=None``.
* Targets are absolute; a target that leaves out X, Y or Z while the current position is unknown
  (program start, after a joint move) is an error.
* Joint-space PTP (``PTP {A1 …}``, an E6AXIS/AXIS variable, ``PTP_REL {A1 …}``): the TCP end is not
  known without the robot's kinematics, so no ``Move`` is made. It is counted in
  ``skipped["joint_move"]``, recorded in ``meta["joint_moves"]`` (source and ``axes_deg``), and
  attached to the next move as ``extra["after_joint_move"]``; that next move has ``start=None``
  (counted in ``meta["unknown_start_moves"]``). ``PTP $AXIS_ACT``/``PTP $POS_ACT`` (the BCO run) do
  not move the robot: counted as ``joint_move`` too, the position stays as it was.
* CIRC: the circle through start, auxiliary and end point. ``Move.normal`` is
  ``(aux − start) × (end − start)`` normalised, so the arc start → aux → end is always
  ``MoveKind.ARC_CCW`` about it; ``Move.center`` is the circumcentre; ``extra["aux"]`` keeps the
  auxiliary point [m]. With ``CA`` the arc runs CA degrees from the start (positive: in the
  direction of the auxiliary point, ``ARC_CCW``; negative: the other way, ``ARC_CW``), ``|CA| ≥
  360`` adds ``Move.turns``, and the end orientation is the programmed end point's
  (``extra["ca_deg"]``). The auxiliary point's orientation is ignored (as by the controller).
* ``LIN_REL``/``PTP_REL``: translation only (A, B, C, E1–E6 must be 0), in ``#BASE`` (default) or
  ``#TOOL`` axes; a relative orientation change or ``CIRC_REL`` is an error.
* ``$BASE``/``$TOOL``: the frames in force at the first Cartesian motion go to ``meta["base"]`` and
  ``meta["tool"]`` as ``{"name", "matrix" (4×4 SI or None when the program does not give the
  value, e.g. BASE_DATA[n] from $config.dat), "index", "source"}``. ``$TOOL`` may change between
  moves (the path is still the TCP's; ``meta["tool_changes"]``, ``Move.tool`` = the TOOL_DATA index).
  ``$BASE`` changing after the first motion is supported when the first and the new frame are both
  given in the program: later poses are transformed into the *first* base (``meta["base_changes"]``;
  ``extra["abc_deg"]`` then holds the transformed angles). When a value is missing, strict reading
  fails; lenient reading warns and reads the later moves in the new base unchanged. Inline forms'
  ``BAS(#FRAMES/#PTP_PARAMS/#CP_PARAMS)`` select frames from ``FDAT_ACT``'s TOOL_NO/BASE_NO when
  that is known (INFERRED from KUKA's inline-form code).
* Feed: a LIN/CIRC before any ``$VEL.CP`` is an error in strict mode (the controller would use a
  speed the program does not state), a warning with ``feed=None`` in lenient mode.
  ``BAS(#VEL_CP, v)``/``BAS(#CP_PARAMS, v)`` (inline forms) set it to v m/s (v may be
  ``LDAT_ACT.VEL``); ``BAS(#CP_DAT)`` and ``$VEL.CP = LCPDAT1.VEL`` take an LDAT's VEL (m/s).
  PTP speeds (``BAS(#PTP_PARAMS/#VEL_PTP, p)``, ``BAS(#PTP_DAT)``) go to
  ``extra["ptp_velocity_pct"]`` (% of the axes' maximum; INFERRED, :mod:`~robot_io.krl._bas`).
  ``$VEL.CP`` above 3 m/s gets a warning.
* Loops (:mod:`~robot_io.krl._loops`): a ``FOR`` with a declared INT counter and bounds the reader
  evaluates is unrolled (nested, ``STEP``, ``PTS[I+1]`` from .dat/.src arrays); its moves keep the
  motion's line as ``Move.source`` and the counters in ``extra["loop"]`` (``{"I": 17}``), at most
  :data:`MAX_UNROLLED_MOVES` in all. An element used but never set, or outside the declared size,
  is ``unknown_value``. An ``IF`` the program decides (constants, known variables, counters) runs
  its branch; WHILE/REPEAT/LOOP/SWITCH and run-time IFs are skipped without motion, else refused.
* Calls: a local ``DEF`` first, then ``NAME.src`` in the program's folder (case-insensitive; its
  ``.dat`` is read too), then KUKA system routines that do not move the robot (``BAS``, message and
  string routines, ``EKI_*``, ``RSI_*``/``ST_*`` except the sensor-guided motions), then
  ``ignore_calls``; anything else is a missing sub-module. Recursion (a page calling itself or an
  earlier page) is an error; a module may be called many times in sequence. Call arguments are not
  bound to parameters.
* Variables: routine locals, then the module's ``.dat``, then ``DECL GLOBAL`` items of any ``.dat``
  read so far and of the ``global_dat`` files (e.g. ``$config.dat``, all of whose items count as
  global). Values the reader does not evaluate (function calls, comparisons, run-time system
  variables) make a variable *unknown*; using it in a motion, frame or feed is an error then.
* Statements that run on the controller but never move the robot are accepted in both modes and
  counted in ``Toolpath.skipped`` by category, without a warning: ``header``, ``system_variable``
  (``$APO.CDIS``, ``$ADVANCE`` — also in ``meta["advance"]`` —, ``$ORI_TYPE`` …), ``io``, ``wait``,
  ``halt``, ``interrupt``, ``trigger``, ``bas``, ``builtin_call``, ``ignored_call``, ``declaration``
  (EXT, SIGNAL, ENUM, STRUC), ``label``, ``control_flow`` (a block it does not run — a run-time
  IF, WHILE, LOOP … — with no motion or calls inside), ``joint_move``.
* Problems: strict mode (default) raises :class:`~robot_io.toolpath.ToolpathError`
  ``file:line:col: reason`` on the first one; lenient mode warns (category), counts the skipped
  statement in ``Toolpath.skipped`` under the same category, and forgets the position after a
  skipped motion, call or block. Errors: syntax (unbalanced brackets, bad numbers, unterminated
  strings, misplaced END/ENDIF …), ``undeclared``/``unknown_value``, ``no_feed``,
  ``unsupported_motion`` (SPLINE/SPL/SLIN/SCIRC/SPTP, ASYPTP, CIRC_REL, ``$IPO_MODE = #TCP``, axis
  targets for LIN, orientation in LIN_REL), ``control_flow`` (motion or calls inside
  WHILE/REPEAT/LOOP/SWITCH or a run-time IF, a FOR that cannot be unrolled, GOTO, EXIT),
  ``missing_module``, ``recursive_call``, ``bad_arc``,
  ``unknown_position``, ``base_change``, ``unknown_statement``. A DEF/DEFDAT name that differs from
  the file name is only a warning (``module_name``): it does not change the path.
* ``Toolpath.meta``: ``program``, ``modules`` (files in the order first read), ``encoding``,
  ``lines``, ``base``, ``tool``, ``base_changes``, ``tool_changes``, ``joint_moves``,
  ``unknown_start_moves``, ``advance``, ``ipo_mode``, ``warning_counts``.

Implementation (``robot_io.krl``): ``_syntax`` (one line → tokens, literals, expressions; plain
``LIN|PTP {…}`` and ``NAME[i]={…}`` lines take a one-regex fast path), ``_program`` (files →
routines and matched blocks), ``_values`` (scopes and variables), ``_motion`` (feed, frames, pose →
``Move``), ``frames`` (ABC, frames, circles), ``_bas`` (BAS and motion data), ``_loops`` and
``_conditions`` (control blocks) and ``_interp`` (the statement loop, calls).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any

from models.errors import InputError
from robot_io.krl._interp import (
    MAX_CALL_DEPTH,
    MAX_EXECUTED_STATEMENTS,
    MAX_WARNINGS_PER_CATEGORY,
    Runner,
)
from robot_io.krl._loops import MAX_UNROLLED_MOVES
from robot_io.krl._motion import PLAUSIBLE_VEL_CP
from robot_io.krl._program import read_text
from robot_io.krl._syntax import MAX_KRL_VALUE
from robot_io.krl.frames import (
    CIRC_COLLINEAR_SIN,
    CIRC_POINT_TOL,
    abc_to_matrix,
    circle_through,
    frame_matrix,
    matrices_to_abc,
    matrix_to_abc,
)
from robot_io.toolpath import Toolpath, ToolpathError, check_option_names

__all__ = [
    "CIRC_COLLINEAR_SIN",
    "CIRC_POINT_TOL",
    "KrlOptions",
    "KrlReader",
    "MAX_CALL_DEPTH",
    "MAX_EXECUTED_STATEMENTS",
    "MAX_KRL_VALUE",
    "MAX_UNROLLED_MOVES",
    "MAX_WARNINGS_PER_CATEGORY",
    "PLAUSIBLE_VEL_CP",
    "abc_to_matrix",
    "circle_through",
    "frame_matrix",
    "matrices_to_abc",
    "matrix_to_abc",
    "read_krl",
    "read_krl_text",
]


@dataclass(frozen=True)
class KrlOptions:
    """Options of the KRL reader.

    Attributes:
        ignore_calls: names of called routines known not to move the robot (skipped and counted
            as ``ignored_call``), e.g. a cell's ``COLLSTOP`` whose module is not at hand.
        global_dat: further ``.dat`` files whose declarations are all visible as globals (e.g.
            the controller's ``$config.dat`` holding ``BASE_DATA``/``TOOL_DATA``/``XHOME``).
    """

    ignore_calls: tuple[str, ...] = ()
    global_dat: tuple[str, ...] = ()

    @classmethod
    def from_kwargs(cls, **options: Any) -> KrlOptions:
        """Validate reader keyword options; unknown names raise :class:`InputError`."""
        check_option_names(cls, options, "KRL")
        names = set(cls.__dataclass_fields__)
        out: dict[str, tuple[str, ...]] = {}
        for k in names:
            v = options.get(k, ())
            if isinstance(v, (str, os.PathLike)):
                v = (v,)
            try:
                out[k] = tuple(os.fspath(x) if isinstance(x, os.PathLike) else str(x) for x in v)
            except TypeError as e:
                raise InputError(k, "expected a list of names or paths") from e
        return cls(**out)


def _run(runner: Runner, opts: KrlOptions, path: str, src_text: str | None,
         dat_text: str | None) -> Toolpath:
    try:
        for gpath in opts.global_dat:
            try:
                text, _ = read_text(gpath)
            except OSError as e:
                raise ToolpathError(gpath, 0, 0, f"cannot read the global_dat file ({e.strerror}); "
                                    "check the path") from e
            runner.run_dat(None, text, gpath, None)
        mod = runner.load(path, src_text, dat_text)
    except ToolpathError as e:   # the private subclass leaves as the public type
        raise ToolpathError(e.file, e.line, e.column, e.reason) from None
    return runner.run_main(mod)


def read_krl_text(src_text: str, dat_text: str | None = None, file: str = "<string>",
                  strict: bool = True, **options: Any) -> Toolpath:
    """Read a KRL module given as text. See the module docstring for conventions.

    Args:
        src_text: the ``.src``.
        dat_text: its ``.dat``, or ``None`` for a module without one (no ``.dat`` is looked up).
        file: name used in messages and ``SourceRef``; when it is a path in an existing folder,
            called sub-modules are looked up there.
        strict: raise :class:`ToolpathError` on the first problem (default); ``False`` collects
            warnings, skips what it cannot read and counts it in ``Toolpath.skipped``.
        **options: fields of :class:`KrlOptions` (``ignore_calls``, ``global_dat``).
    """
    opts = KrlOptions.from_kwargs(**options)
    folder = os.path.dirname(file) or "."
    runner = Runner(file, strict, opts.ignore_calls,
                    folder if file != "<string>" and os.path.isdir(folder) else None)
    return _run(runner, opts, file, src_text, dat_text)


def read_krl(path: str | os.PathLike[str], strict: bool = True, **options: Any) -> Toolpath:
    """Read a KRL program from its ``.src`` (the ``.dat`` beside it, matched case-insensitively, is
    read too, and so are called sub-modules in the same folder). Same arguments as
    :func:`read_krl_text`; ``meta["encoding"]`` records the main file's decoding (UTF-8, else
    Windows-1252)."""
    file = os.fspath(path)
    opts = KrlOptions.from_kwargs(**options)
    if not os.path.isfile(file):
        raise ToolpathError(file, 0, 0, "not found; check the path of the .src")
    runner = Runner(file, strict, opts.ignore_calls, os.path.dirname(file) or ".")
    return _run(runner, opts, file, None, None)


class KrlReader:
    """The KUKA KRL member of the ``ToolpathReader`` family."""

    format = "krl"
    suffixes = (".src",)

    @staticmethod
    def sniff(head: str) -> bool:
        """Whether the first KiB of a file (upper-cased) look like a KRL routine."""
        return "DEF " in head and ("LIN " in head or "PTP " in head or "END" in head)

    def read(self, path: str, strict: bool = True, **options: Any) -> Toolpath:
        """Read ``path``; options as :func:`read_krl`."""
        return read_krl(path, strict=strict, **options)
