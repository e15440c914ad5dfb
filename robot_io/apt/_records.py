"""APT/CL records (private to :mod:`robot_io.apt`): constants, the line splitter, number rules.

``records(text)`` turns the text into logical records (``$$`` comments and ``$`` continuations
resolved) with the physical line each starts on; the interpreter in ``robot_io.apt._interp`` parses
their heads and fields. Conventions are documented in :mod:`robot_io.apt`.
"""

from __future__ import annotations

import re
from collections.abc import Iterator

from models.errors import CctmillError

__all__ = [
    "ARC_MIN_RADIUS",
    "CYCLE_POSITION_TOL",
    "FEED_RETRACT_CYCLES",
    "FEED_WORDS",
    "FIX",
    "FRAME_ORTHONORMAL_TOL",
    "HEAD",
    "INCH",
    "MAX_ARC_TURNS",
    "MAX_NUMBER_CHARS",
    "MAX_RECORD_FIELDS",
    "MAX_WARNINGS_PER_CATEGORY",
    "MM",
    "NONFINITE",
    "NUMBER",
    "NUMBERS",
    "PECK_WORDS",
    "Record",
    "SILENT_RECORDS",
    "Skip",
    "TEXT_HEAD",
    "TEXT_WORDS",
    "TOOL_AXIS_NORM_TOL",
    "UNIT_WORDS",
    "Vec",
    "WORD",
    "cut_comment",
    "records",
    "short",
]

MM = 1e-3       #: one millimetre [m]
INCH = 0.0254   #: one inch [m]

#: No APT record this reader knows has more fields (CYCLE/DEEP2 has 13); capping the count keeps a
#: 10 MB record of commas linear and its error precise.
MAX_RECORD_FIELDS = 64
#: A number longer than this (characters) is rejected before conversion (CAM writes ~12).
MAX_NUMBER_CHARS = 40
#: i,j,k whose norm differs from 1 by more than this [-] is warned about (CAM writes 6–7 digits,
#: so rounding alone stays below 1e-5); it is normalised either way.
TOOL_AXIS_NORM_TOL = 1e-3
#: A CSYS/MSYS rotation whose RᵀR differs from I by more than this [-] is rejected (the shared
#: files, with 6 digits, are within 2e-6).
FRAME_ORTHONORMAL_TOL = 1e-4
#: Cycle positioning moves shorter than this [m] are not emitted: CAM rounds the approach point
#: (e.g. 3 µm off p + RTRCTO·a along a tilted axis in the shared data).
CYCLE_POSITION_TOL = 1e-5
#: An arc whose start lies closer than this to its centre [m] is rejected.
ARC_MIN_RADIUS = 1e-9
#: Largest ``TIMES,n`` accepted on a CIRCLE.
MAX_ARC_TURNS = 1000
#: Warnings kept per category; more are only counted in ``meta["warning_counts"]``.
MAX_WARNINGS_PER_CATEGORY = 50

UNIT_WORDS = {"MM": ("mm", MM), "INCHES": ("inch", INCH), "INCH": ("inch", INCH),
          "IN": ("inch", INCH)}
FEED_WORDS = {"MMPM": (MM, False), "IPM": (INCH, False), "MMPR": (MM, True),
               "IPR": (INCH, True)}
SILENT_RECORDS = frozenset({"COOLNT", "PPRINT", "INSERT", "REMARK", "END", "PAINT", "TOOL PATH",
                     "END-OF-PATH", "MACHIN", "CLRSRF", "OPSTOP", "STOP", "DELAY"})
FEED_RETRACT_CYCLES = frozenset({"TAP", "BORE", "REAM"})
TEXT_WORDS = frozenset({"PPRINT", "INSERT", "PARTNO", "REMARK"})
PECK_WORDS = ("1STPECK", "SUBPECK", "STEP")
FIX = "fix the record or read with strict=False to skip it"

_NUM = r"[+-]?+(?:\d++\.?+\d*+|\.\d++)(?:[eE][+-]?+\d++)?+"
NUMBER = re.compile(_NUM)
NUMBERS = re.compile(rf"[ \t]*+{_NUM}(?:[ \t]*+,[ \t]*+{_NUM})*+[ \t]*+")
WORD = re.compile(r"[A-Za-z0-9_]++")
HEAD = re.compile(
    r"[ \t]*+([A-Za-z][A-Za-z0-9_\-]*+(?:[ \t]++[A-Za-z][A-Za-z0-9_\-]*+)*+)[ \t]*+(/)?+")
TEXT_HEAD = re.compile(r"[ \t]*+(PPRINT|INSERT|PARTNO|REMARK)(?![A-Za-z0-9_])", re.I)
NONFINITE = frozenset({"NAN", "+NAN", "-NAN", "INF", "+INF", "-INF", "INFINITY", "+INFINITY",
                        "-INFINITY"})
Vec = tuple[float, float, float]


class Skip(CctmillError):
    """Lenient mode: abandon the current record (already warned about and counted)."""


class Record:
    """One logical record: head parsed, arguments as written."""

    __slots__ = ("word", "args", "args_at", "text", "line", "col", "pieces")

    def __init__(self, word: str, args: str | None, args_at: int, text: str, line: int,
                 col: int, pieces: list[tuple[int, int]] | None) -> None:
        self.word = word          # major word, upper case, single blanks ("TOOL PATH")
        self.args = args          # text after '/', None without one
        self.args_at = args_at    # offset of args in text
        self.text = text          # the record, comments and continuation marks removed
        self.line = line          # physical line where it starts (1-based)
        self.col = col            # column of the major word (1-based)
        self.pieces = pieces      # [(offset in text, physical line)] when continued


def cut_comment(raw: str, text_record: bool) -> tuple[str, bool]:
    """``raw`` without its ``$$`` comment or ``$`` continuation mark; True when continued."""
    k = raw.find("$")
    if k < 0:
        return raw, False
    end = len(raw.rstrip())
    while k >= 0:
        if raw.startswith("$", k + 1):
            return raw[:k], False
        if not text_record or k == end - 1:
            return raw[:k], True
        k = raw.find("$", k + 1)
    return raw, False


def records(text: str) -> Iterator[tuple[str, int, list[tuple[int, int]] | None]]:
    """(record text, start line, pieces or None) for every non-blank logical record."""
    lines = text.split("\n")
    n = len(lines)
    i = 0
    text_head = TEXT_HEAD.match
    while i < n:
        raw = lines[i]
        i += 1
        if raw.endswith("\r"):
            raw = raw[:-1]
        is_text = text_head(raw) is not None
        body, cont = cut_comment(raw, is_text)
        if not cont:
            if body and not body.isspace():
                yield body, i, None
            continue
        start = i
        parts = [body]
        pieces = [(0, i)]
        length = len(body)
        while cont and i < n:
            raw = lines[i]
            i += 1
            if raw.endswith("\r"):
                raw = raw[:-1]
            body, cont = cut_comment(raw, is_text)
            pieces.append((length, i))
            parts.append(body)
            length += len(body)
        joined = "".join(parts)
        if joined and not joined.isspace():
            yield joined, start, pieces


def short(s: str, n: int = 24) -> str:
    """``s`` cut to ``n`` characters for a message."""
    return s if len(s) <= n else s[:n] + "…"

