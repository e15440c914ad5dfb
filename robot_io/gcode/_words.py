"""G-code words: the line tokeniser, code tables and limits of :mod:`robot_io.gcode` (private).

G and M codes are keyed by ``round(10 · value)``, so ``G1`` is 10, ``G90.1`` is 901 and ``M30`` is
300: one integer per code, no float comparisons in the interpreter.
"""

from __future__ import annotations

import re

from robot_io.options import fix

__all__ = [
    "ARC_MIN_RADIUS",
    "ARC_WORDS",
    "ASCII_UPPER",
    "AXIS_WORDS",
    "CANNED_CYCLES",
    "CODE_TOL",
    "CUTTER_COMP_G",
    "EXPANDED_CYCLES",
    "HARMLESS_G",
    "HARMLESS_M",
    "IGNORED_WORDS",
    "INCH",
    "LINUXCNC_SWITCHKINS_M",
    "MAX_ARC_TURNS",
    "MAX_CYCLE_REPEAT",
    "MAX_CYCLE_REPEATS",
    "MAX_MOVES",
    "MAX_WARNINGS_PER_CATEGORY",
    "MAX_WORD_VALUE",
    "MM",
    "MOTION_G",
    "ROTARY_WORDS",
    "TOKEN",
    "UNKNOWN_LETTERS",
    "UNSUPPORTED_AXIS_G",
    "USER_M_RANGE",
    "WORK_OFFSETS_G",
    "code_key",
    "code_key_of",
    "code_name",
    "fix_hint",
    "upper",
]

MM = 1e-3       #: one millimetre [m]
#: A G/M number within this [-] of a tenth is that code (float noise such as G[0.1*30] is G3;
#: G1.23 is no code).
CODE_TOL = 1e-6
INCH = 0.0254   #: one inch [m]

#: An arc radius below this [m] has no plane basis worth the name (and is surely a typo).
ARC_MIN_RADIUS = 1e-9
#: Largest ``P`` (turns) of an arc accepted; more is a typo, and the box of a move loops per turn.
MAX_ARC_TURNS = 1000
#: Largest magnitude of any word's number [program units]; beyond it the number is garbage
#: (a km-sized move in mm, or a 1e300 that would overflow squares).
MAX_WORD_VALUE = 1e9
#: Largest ``L`` (repeat count) of one canned-cycle block.
MAX_CYCLE_REPEAT = 10_000
#: Repeats beyond each cycle block's first that ``L`` words may add in one reading, in all: every
#: repeat makes up to four moves, so a 15-byte ``G81 … L10000`` line is 40,000 of them and 100
#: such lines were 3 million moves from 2.7 kB (issue 22). A quarter million repeats (≤ 1 million
#: moves, like the KRL reader's ``MAX_UNROLLED_MOVES``) is more holes than any drilling job.
MAX_CYCLE_REPEATS = 250_000
#: Most moves one reading makes, whatever made them (plain lines, O-word loops and calls, cycle
#: repeats): about 240 bytes a move in the reader alone (2.4 GB here) and more in the planner;
#: a longer program is to be split.
MAX_MOVES = 10_000_000
#: Warnings kept per category; further ones are only counted (``meta["warning_counts"]``).
MAX_WARNINGS_PER_CATEGORY = 50

#: One token per match, leading whitespace included. Groups: 1 letter, 2 number, 3 ``( … )``
#: comment, 4 ``;`` comment, 5 unclosed ``(``, 6 garbage: from the first character that starts no
#: word or comment to the end of the line (one token, so a 10 MB tail is not a million tokens).
#: The number is an atomic group followed by a negative look-ahead, so ``X1.2.3`` and a 10 MB run of
#: digits fail in linear time (no backtracking into the digits); the comment body is possessive for
#: the same reason. Spaces between the letter and the number are allowed (``Y -25.409``), not
#: inside the number.
TOKEN = re.compile(
    r"\s*+(?:"
    r"([A-Z])[ \t]*+([-+]?(?>\d+(?:\.\d*+)?|\.\d++))(?![\d.])"
    r"|(\([^)]*+\))"
    r"|(;.*)"
    r"|(\(.*)"
    r"|(\S.*)"
    r")"
)

#: ``str.translate`` table upper-casing ASCII letters only (length-preserving, for non-ASCII lines).
ASCII_UPPER = str.maketrans("abcdefghijklmnopqrstuvwxyz", "ABCDEFGHIJKLMNOPQRSTUVWXYZ")


def upper(line: str) -> str:
    """Upper-case ASCII letters only, keeping the length (so columns stay right)."""
    return line.upper() if line.isascii() else line.translate(ASCII_UPPER)


def code_key(number: str) -> int | None:
    """``"01"`` → 10, ``"90.1"`` → 901; ``None`` when the number is not a code (``G1.23``)."""
    return code_key_of(float(number))


def code_key_of(value: float) -> int | None:
    """:func:`code_key` of a number's value (``G[#1]``: the value of an expression)."""
    v = value * 10.0
    k = round(v)
    if abs(v - k) > CODE_TOL or k < 0:
        return None
    return int(k)


def fix_hint() -> str:
    """How to get past a problem, appended to strict-mode messages, in the words of the
    interface in use (built when the message is, see :func:`robot_io.options.fix`)."""
    return f"read with {fix('strict', False)} to skip it, or remove it"


def code_name(letter: str, key: int) -> str:
    """``("G", 901)`` → ``"G90.1"``."""
    return f"{letter}{key // 10}" if key % 10 == 0 else f"{letter}{key // 10}.{key % 10}"


AXIS_WORDS = frozenset("XYZ")
ROTARY_WORDS = frozenset("ABC")
ARC_WORDS = frozenset("IJKR")
#: Words read only as parameters of a code on the same line (N line number, H/D offset numbers,
#: P/Q/L parameters); never an error on their own.
IGNORED_WORDS = frozenset("NHDPQL")
#: Letters cctmill does not read: extra linear axes and vendor words.
UNKNOWN_LETTERS = frozenset("EUVW")

#: Motion group (modal group 1).
MOTION_G = {0: "G0", 10: "G1", 20: "G2", 30: "G3"}
#: Canned cycles (also modal group 1). G81 and G82 are expanded into moves; the others are read
#: as "canned cycle not expanded" (a counted warning; the position afterwards is still right).
CANNED_CYCLES = frozenset({730, 810, 820, 830, 840, 850, 860, 870, 880, 890})
EXPANDED_CYCLES = frozenset({810, 820})

#: Modal codes that do not change where the tool tip goes as the program is written (they pick
#: compensation tables, path blending, cycle retract mode, spindle mode): G15 polar coordinates
#: off, G40 cutter compensation off, G43/G43.1 tool length offset on (the programmed Z is then the
#: tool tip, which is what we read), G49 length offset off, G50 scaling off, G61/G61.1/G64 path
#: control, G69 rotation off, G80 cancel cycle, G97 spindle in rpm, G98/G99 cycle retract mode.
#: (G4 dwell is read separately and summed in ``meta["dwell_s"]``.)
HARMLESS_G = frozenset({150, 400, 430, 431, 490, 500, 610, 611, 640, 690, 800, 970, 980, 990})
#: Cutter radius compensation on: accepted with a warning, the path is read uncompensated.
CUTTER_COMP_G = frozenset({410, 420})
#: Work offsets G54–G59, G59.1–G59.3: accepted, listed in ``meta["work_offsets"]``.
WORK_OFFSETS_G = frozenset({540, 550, 560, 570, 580, 590, 591, 592, 593})
#: Codes that change what axis words mean (G10/G52/G92.x offsets, G51 scaling, G68 rotation, G16
#: polar): never guessed at. Strict → error; lenient → the whole block is skipped.
UNSUPPORTED_AXIS_G = frozenset({100, 160, 510, 520, 680, 920, 921, 922, 923})

#: M codes that do not move the tool: M0/M1 stops, M3/M4/M5 spindle, M6 tool change,
#: M7/M8/M9 coolant, M2/M30/M60 program end/pallet.
HARMLESS_M = frozenset({0, 10, 20, 30, 40, 50, 60, 70, 80, 90, 300, 600})
#: LinuxCNC switchable-kinematics remaps of the trt sim configs (``remap_subs/42[89]remap.ngc``):
#: M428 selects the XYZAC tool-centre-point kinematics, M429 identity (trivial) kinematics,
#: M430 a user kinematics.
LINUXCNC_SWITCHKINS_M = {4280: "tcp", 4290: "identity", 4300: "user"}
#: LinuxCNC user-defined M codes (M100–M199 run a user program, no motion): a counted warning
#: even in strict mode.
USER_M_RANGE = range(1000, 2000)
