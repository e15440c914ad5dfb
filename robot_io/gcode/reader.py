"""Read G-code (RS274/NGC as CAM posts write it) into the plain move model of ``robot_io.toolpath``.

The reader runs the program the way the machine would: modal motion (bare ``X.. Y..`` lines
continue the last G0/G1/G2/G3), packed (``G1X1.5Y2F300``) and spaced (``G0  X  16.339``) words,
``( … )`` and ``;`` comments, ``%`` lines, ``/`` block delete (executed, with a warning), N words
and the program number (``O1001`` or ``:1001``), G90/G91, G90.1/G91.1, G17/G18/G19 arcs in I/J/K
or R form (helical, full circles, ``P`` turns), G20/G21, G93/G94, F/S/T/M6/M3/M4/M5, G28 homing,
G54–G59, G81/G82 canned cycles, and LinuxCNC parameters and expressions (``#1 = 10``,
``#<depth> = -2``, ``G1 X[#1*2] Z#<depth>``).

Conventions (read this before trusting a number)
------------------------------------------------
* Everything is SI inside: positions [m], feed [m/s], angles [rad], durations [s].
* ``F`` is stored as written and converted with the units in force *when the move runs*, so
  ``G20 F6`` means 6 in/min. Under G93 (inverse time) ``F`` is 1/min for that line only:
  ``Move.duration = 60 / F`` and ``Move.feed = None``; an F is required on every G93 feed line.
  Switching from G93 back to G94 forgets the feed (an inverse-time number is no feed; LinuxCNC does
  the same), so the next feed move needs an F.
* Arcs: G2 is clockwise and G3 counter-clockwise *about the plane normal* +Z (G17), +Y (G18), +X
  (G19) — RS274NGC's "as seen from the positive end of the axis normal to the plane". In G18 the
  plane axes are ordered (Z, X), so a G2 from X-0.28/Z0 relative to the centre goes *down* to
  X0/Z-0.28 (as the Fusion 360 ramp arcs in the shared data do). I/J/K are incremental from the
  start unless G90.1; the word along the normal (K in G17, J in G18, I in G19) must be 0 — a helix's
  travel is the axis word (Z in G17). R < 0 is the long way round (> 180°).
* The position before the first move, and of every axis named in ``G28``/``G30`` or moved in G53
  machine coordinates, is unknown (unless the options ``initial_position``/``home_position`` give
  it). A move whose *end* is not fully known cannot be drawn: it is skipped, counted in
  ``Toolpath.skipped["unknown_position"]`` and warned about; the next drawable move then has
  ``start=None`` (counted in ``meta["unknown_start_moves"]``). An arc needs its start, so an arc
  from an unknown position is skipped the same way.
* ``Move.source.column`` is the column of the block's first axis or arc word (X Y Z A B C I J K R),
  or of its motion code when it has none.
* ``Toolpath.meta``: ``program`` (O word, or the comment on the first line), ``program_number``
  (the O number, when there is one), ``work_offsets``,
  ``rotary_kinematics``, ``tcp_switches`` [(line, "tcp"/"identity"/"user")], ``homing_blocks``,
  ``unknown_start_moves``, ``block_delete_lines``, ``dwell_s``, ``warning_counts`` (all warnings
  by category, also those beyond ``MAX_WARNINGS_PER_CATEGORY``), ``lines`` and ``encoding``.
* Canned cycles: G81 and G82 are expanded into rapid/feed moves (G98 = back to the initial level,
  the default; G99 = back to R; preliminary rapid to R when below it; ``L`` repeats in G91, at
  most ``MAX_CYCLE_REPEAT`` per block and ``MAX_CYCLE_REPEATS`` beyond each block's first in all).
  G73 and G83–G89 are *not* expanded: a counted warning ``canned_cycle_not_expanded`` (in strict
  mode too), and the position afterwards is where the cycle would have left the tool.
* Cutter compensation G41/G42 is accepted with a warning: the path is read uncompensated.
* Parameters and expressions follow LinuxCNC (:mod:`robot_io.gcode._params`,
  :mod:`robot_io.gcode._expr`): ``#1``–``#5000`` are 0 until set (a counted warning
  ``unset_numbered_parameter``), a named one read before it is set is an error; the settings
  on a line take effect after all its values are read; trig in degrees; ``#5001`` and up are
  machine state, refused except the current position ``#5420``–``#5425`` (and the predefined
  names such as ``#<_x>``, ``#<_metric>``). A word's value may be an expression everywhere
  (``G[#1]``, ``F[#<feed>]``). Lines with ``#``, ``[`` or ``O`` never take the bulk path.
* ``O1001`` before the first block is the program number (``meta["program"] = "O1001"``,
  ``meta["program_number"] = 1001``). LinuxCNC O-word flow control is run as LinuxCNC runs it
  (:mod:`robot_io.gcode._oword`): ``sub``/``endsub``/``call``/``return`` of subroutines in the
  same file (arguments in ``#1``…, local parameters, ``#<_value>``), ``if``/``elseif``/``else``/
  ``endif``, ``while``/``do``/``repeat`` loops with ``break``/``continue``, at most
  ``MAX_LOOP_ITERATIONS`` rounds per loop. A call of a subroutine not in the file, a loop over
  its limit, a later bare O-number (a Fanuc subprogram) and ``M98``/``M99`` are refused
  (strict) or skipped with a counted warning ``o_word`` that says what the skipping may change.
* A reading makes at most ``MAX_MOVES`` moves, whatever makes them (plain lines, loops, calls,
  repeats); past it :class:`ToolpathError` names the line, in lenient reading too.
* Comments do not nest: a ``(`` inside a comment with a later ``)`` (``(T1 (6MM) FLAT)``) is
  refused (strict) or read as one comment with a warning ``nested_comment`` (lenient). Messages
  quote the offending word, never the text of a comment.
* Unknown G/M codes and words: strict → :class:`ToolpathError` with ``file:line:col`` and a fix;
  lenient → counted warning and the code (or, when the block has axis words a skipped code might
  have consumed, the whole block) is skipped. LinuxCNC user M codes M100–M199 are counted
  warnings in both modes; M428/M429/M430 are the switchable-kinematics remaps of LinuxCNC's trt
  configurations (M428 = XYZAC tool-centre-point kinematics on, M429 = identity).

5-axis (rotary words A, B, C)
-----------------------------
``rotary=None``/``"none"``: the program must not move rotary axes; if it does, strict reading
fails and tells the user to choose a kinematics, lenient reading keeps the angles in
``Move.extra`` (radians) and warns. ``rotary="xyzac-trunnion"`` (or ``"xyzbc-trunnion"``) is a
table-table machine with LinuxCNC's ``xyzac-trt-kins`` rotation order and signs, see
:mod:`robot_io.rotary`. Tool-centre-point (TCP) mode matters:

* TCP on (after M428, or ``tcp=True``): the XYZ words already *are* the tool tip in the
  workpiece frame (LinuxCNC's switchable kinematics interpolate in that "world" frame); A and C
  only set the tool axis ``axis_w = R_table(A, C)^T · (0, 0, 1)``. This is what the LinuxCNC
  demo programs mean: they start with ``M428 ;TCP:xyzac`` and end with ``M429 ;Restore
  Trivkins``, and their XYZ ranges are the part's own (the impeller's footer reports
  ``Rmax 45.44``, the radius of the XYZ words).
* TCP off (identity kinematics, no M428, or ``tcp=False``): XYZ are machine positions and the tip
  in the workpiece frame is ``R_table^T · (p - pivot - c_offset) + …`` (see ``rotary.py``). A move
  that turns the table is then a curve in the workpiece frame; the move model records its end
  points only.

``tcp=None`` (default) follows M428/M429 in the program, starting with TCP off.
The raw angles in force are stored in ``Move.extra`` as ``{"A": rad, "C": rad}``.

Speed: a 3-axis CAM program is mostly *plain* lines (only N/G0/G1/X/Y/Z/F words). The reader
scans the whole text once with numpy, reads the numbers of the plain lines in one
``np.fromstring`` call and executes long runs of them as array operations
(:mod:`robot_io.gcode._plain`); every other line goes through the line-by-line interpreter (one
compiled regex per line, :data:`robot_io.gcode._words.TOKEN`), which stays the definition of what
a line means — both ways give the same toolpath to the bit, the same warnings and the same errors
(``test_gcode`` checks it on the shared programs and on random and mutated ones). Moves are kept
as columns and ``Toolpath.moves`` is a :class:`~robot_io.toolpath.MoveList` that builds each
:class:`Move` on first access (about 2 µs each). Reading is linear in the input size, also for a
10 MB single line, and never recursive. ``benchmarks/toolpath_speed.py`` measures it against
pygcode in the same run; see docs/performance.md for the figures.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from typing import Any

from models.errors import InputError
from robot_io.gcode._interp import run_program
from robot_io.gcode._oword import (
    MAX_CALL_DEPTH,
    MAX_FLOW_LINES,
    MAX_FLOW_STEPS,
    MAX_LOOP_ITERATIONS,
)
from robot_io.gcode._words import (
    ARC_MIN_RADIUS,
    INCH,
    MAX_ARC_TURNS,
    MAX_CYCLE_REPEAT,
    MAX_CYCLE_REPEATS,
    MAX_MOVES,
    MAX_WARNINGS_PER_CATEGORY,
    MAX_WORD_VALUE,
    MM,
)
from robot_io.options import option_name
from robot_io.rotary import ROTARY_KINEMATICS
from robot_io.toolpath import (
    ARC_RADIUS_RTOL,
    ARC_RADIUS_TOL,
    Toolpath,
    check_option_names,
    read_source_text,
)

__all__ = [
    "ARC_MIN_RADIUS",
    "GcodeOptions",
    "GcodeReader",
    "INCH",
    "MAX_ARC_TURNS",
    "MAX_CALL_DEPTH",
    "MAX_CYCLE_REPEAT",
    "MAX_CYCLE_REPEATS",
    "MAX_FLOW_LINES",
    "MAX_FLOW_STEPS",
    "MAX_LOOP_ITERATIONS",
    "MAX_MOVES",
    "MAX_WARNINGS_PER_CATEGORY",
    "MAX_WORD_VALUE",
    "MM",
    "read_gcode",
    "read_gcode_text",
]


@dataclass(frozen=True)
class GcodeOptions:
    """Options of the G-code reader (all SI).

    Attributes:
        rotary: ``"none"``, ``"xyzac-trunnion"`` or ``"xyzbc-trunnion"``.
        pivot: tilt-axis rot point of the trunnion [m], shape (3,).
        c_offset: C axis relative to the tilt axis [m], shape (3,).
        tcp: tool-centre-point mode: ``None`` follows M428/M429, ``True``/``False`` forces it.
        initial_position: program position before the first move [m], shape (3,), or None.
        home_position: program position after G28/G30 [m], shape (3,), or None (unknown).
        default_units: units before the first G20/G21, ``"mm"`` or ``"inch"``.
        arc_radius_tol: allowed start/end radius mismatch of an arc [m].
        arc_radius_rtol: the same, relative to the radius [-]; the larger of the two applies.
    """

    rotary: str = "none"
    pivot: tuple[float, float, float] = (0.0, 0.0, 0.0)
    c_offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
    tcp: bool | None = None
    initial_position: tuple[float, float, float] | None = None
    home_position: tuple[float, float, float] | None = None
    default_units: str = "mm"
    arc_radius_tol: float = ARC_RADIUS_TOL
    arc_radius_rtol: float = ARC_RADIUS_RTOL

    @classmethod
    def from_kwargs(cls, rotary: str | None = None, **options: Any) -> GcodeOptions:
        """Validate reader keyword options; unknown names raise :class:`InputError`."""
        check_option_names(cls, options, "G-code")
        rot = "none" if rotary is None else str(rotary)
        if rot != "none" and rot not in ROTARY_KINEMATICS:
            raise InputError(option_name("rotary"), f"unknown rotary kinematics {rot!r}; "
                             f"choose 'none' or one of {sorted(ROTARY_KINEMATICS)}")
        if options.get("default_units", "mm") not in ("mm", "inch"):
            raise InputError(option_name("default_units"), "must be 'mm' or 'inch'")
        if options.get("tcp") not in (None, True, False):
            raise InputError(option_name("tcp"), "must be None (follow M428/M429), True or "
                             "False")
        for k in ("arc_radius_tol", "arc_radius_rtol"):
            v = options.get(k, 0.0)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                raise InputError(option_name(k), "must be a finite number >= 0")
        for k in ("pivot", "c_offset", "initial_position", "home_position"):
            if options.get(k) is not None:
                try:
                    vals = tuple(float(v) for v in options[k])
                except (TypeError, ValueError) as e:
                    raise InputError(option_name(k), "expected three numbers in metres") from e
                if len(vals) != 3 or not all(math.isfinite(v) for v in vals):
                    raise InputError(option_name(k), "expected three finite numbers in metres")
                options[k] = vals
        return cls(rotary=rot, **options)


# --------------------------------------------------------------------- public entry points
def read_gcode_text(text: str, file: str = "<string>", strict: bool = True,
                    rotary: str | None = None, **options: Any) -> Toolpath:
    """Read G-code from a string. See the module docstring for conventions.

    Args:
        text: the program.
        file: name used in messages and ``SourceRef``.
        strict: raise :class:`ToolpathError` on the first problem (default); ``False`` collects
            warnings, skips what it cannot read and counts it in ``Toolpath.skipped``.
        rotary: ``None``/``"none"``, ``"xyzac-trunnion"`` or ``"xyzbc-trunnion"``.
        **options: fields of :class:`GcodeOptions` (``pivot``, ``c_offset``, ``tcp``,
            ``initial_position``, ``home_position``, ``default_units``, ``arc_radius_tol``,
            ``arc_radius_rtol``; lengths in metres).
    """
    opts = GcodeOptions.from_kwargs(rotary, **options)
    return run_program(text, file, strict, opts)


def read_gcode(path: str | os.PathLike[str], strict: bool = True, rotary: str | None = None,
               **options: Any) -> Toolpath:
    """Read a G-code file (UTF-8, falling back to Latin-1). Same arguments as
    :func:`read_gcode_text`; ``meta["encoding"]`` records the decoding used."""
    file = os.fspath(path)
    opts = GcodeOptions.from_kwargs(rotary, **options)
    text, encoding = read_source_text(file)
    tp = run_program(text, file, strict, opts)
    tp.meta["encoding"] = encoding
    return tp


class GcodeReader:
    """The G-code member of the ``ToolpathReader`` family."""

    format = "gcode"
    suffixes = (".nc", ".ngc", ".gcode", ".gc", ".tap", ".cnc", ".mpf", ".eia")

    @staticmethod
    def sniff(head: str) -> bool:
        """Whether the first KiB of a file (upper-cased) look like G-code."""
        return any(w in head for w in ("G0", "G1", "G2", "G3", "G90", "G21", "G20"))

    def read(self, path: str, strict: bool = True, **options: Any) -> Toolpath:
        """Read ``path``; options as :func:`read_gcode`."""
        return read_gcode(path, strict=strict, **options)
