"""APT/CL records (private to :mod:`robot_io.apt`): constants, the line splitter, number rules.

``records(text)`` turns the text into logical records (``$$`` comments and ``$`` continuations
resolved) with the physical line each starts on; ``listing_header(text)`` finds the text header NX
puts before a CLSF it lists; the interpreter in ``robot_io.apt._interp`` parses the records' heads
and fields. Conventions are documented in :mod:`robot_io.apt.reader`.
"""

from __future__ import annotations

import re
from collections.abc import Iterator

from models.errors import CctmillError
from robot_io.options import fix

__all__ = [
    "ARC_MIN_RADIUS",
    "CHORD_TOL",
    "CYCLE_POSITION_TOL",
    "DRILL_CYCLES",
    "FEED_RETRACT_CYCLES",
    "FEED_WORDS",
    "FRAME_ORTHONORMAL_TOL",
    "HEAD",
    "INCH",
    "MAX_ARC_TURNS",
    "MAX_LISTING_HEADER_LINES",
    "MAX_NUMBER_CHARS",
    "MAX_NUMBER_VALUE",
    "MAX_RECORD_FIELDS",
    "MAX_SPLINE_MOVES",
    "MAX_WARNINGS_PER_CATEGORY",
    "MM",
    "NONFINITE",
    "NUMBER",
    "NUMBERS",
    "PECK_WORDS",
    "Record",
    "SPLINE_START_TOL",
    "Skip",
    "TEXT_HEAD",
    "TEXT_WORDS",
    "TOOL_AXIS_NORM_TOL",
    "UNIT_WORDS",
    "Vec",
    "WORD",
    "cut_comment",
    "fix_or_skip",
    "listing_header",
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
#: Largest magnitude of any number of a record [program units: mm or inch, mm/min, rev/min …];
#: beyond it the number is garbage (a km-sized move in mm) and would overflow the geometry
#: (a 1e308 coordinate made ``length_m`` infinite). The same limit as the G-code reader's
#: ``robot_io.gcode.reader.MAX_WORD_VALUE`` and the KRL reader's ``MAX_KRL_VALUE``.
MAX_NUMBER_VALUE = 1e9
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
#: Default chord tolerance of spline flattening [m]: 10 µm, the planner's default
#: ``[path] chord_tol_mm = 0.01`` (the planner passes the job's value).
CHORD_TOL = 1e-5
#: A spline whose first CNTRL repeats its start point may miss the tool position by this much [m]:
#: NX writes 4 decimals (±0.05 µm in mm, ±1.3 µm in inches); 10 µm (as CYCLE_POSITION_TOL) also
#: passes a rounded re-export but not a spline that starts elsewhere.
SPLINE_START_TOL = 1e-5
#: Most linear moves one spline may become; a wild control polygon or a tiny chord tolerance is
#: refused rather than filling memory (the real NX splines need well under 1000).
MAX_SPLINE_MOVES = 100_000
#: An NX information-listing header is looked for in this many lines at the top of the file (its
#: five lines, rules and blank lines fit with room to spare).
MAX_LISTING_HEADER_LINES = 40

UNIT_WORDS = {"MM": ("mm", MM), "INCHES": ("inch", INCH), "INCH": ("inch", INCH),
          "IN": ("inch", INCH)}
FEED_WORDS = {"MMPM": (MM, False), "IPM": (INCH, False), "MMPR": (MM, True),
               "IPR": (INCH, True)}
FEED_RETRACT_CYCLES = frozenset({"TAP", "BORE", "REAM"})
#: The CYCLE types expanded as "feed in along the axis, back out" (others are refused).
DRILL_CYCLES = frozenset({"DRILL", "DEEP", "DEEP2", "BRKCHP", "TAP", "BORE", "REAM", "CSINK",
                          "CBORE"})
TEXT_WORDS = frozenset({"PPRINT", "INSERT", "PARTNO", "REMARK"})
PECK_WORDS = ("1STPECK", "SUBPECK", "STEP")

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
_LISTING_START = re.compile(r"[ \t]*information[ \t]+listing[ \t]+created[ \t]+by[ \t]*:", re.I)
_LISTING_RULE = re.compile(r"[ \t]*={3,}[ \t]*")
_LISTING_ITEM = re.compile(r"[ \t]*[A-Za-z][A-Za-z0-9 \t_.()-]*:.*")


def fix_or_skip() -> str:
    """The end of a message about a bad record, in the words of the interface in use (made when
    the message is, never at import)."""
    return f"fix the record or read leniently ({fix('strict', False)}) to skip it"


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


def listing_header(text: str) -> tuple[int, list[str]]:
    """The header NX writes before a CLSF it lists (``Information listing created by : …``,
    ``Date : …``, … up to a rule of ``=``), at the top of ``text`` only: (lines it takes, the
    header lines), or ``(0, [])``. Blank lines and rules before it and blank lines after it are
    part of it; any other line before the closing rule means there is no header."""
    lines = [ln.rstrip("\r") for ln in
             text.split("\n", MAX_LISTING_HEADER_LINES)[:MAX_LISTING_HEADER_LINES]]
    n = len(lines)
    i = 0
    while i < n and (not lines[i].strip() or _LISTING_RULE.fullmatch(lines[i])):
        i += 1
    if i == n or not _LISTING_START.match(lines[i]):
        return 0, []
    first = i
    while first > 0 and lines[first - 1].strip():   # a rule right above belongs to it
        first -= 1
    i += 1
    while i < n and not _LISTING_RULE.fullmatch(lines[i]):
        if lines[i].strip() and not _LISTING_ITEM.fullmatch(lines[i]):
            return 0, []
        i += 1
    if i == n:
        return 0, []
    end = i + 1
    while end < n and not lines[end].strip():
        end += 1
    return end, lines[first:i + 1]


def records(text: str, first: int = 0) -> Iterator[tuple[str, int, list[tuple[int, int]] | None]]:
    """(record text, start line, pieces or None) for every non-blank logical record, from the
    line with index ``first`` (line numbers stay those of ``text``)."""
    lines = text.split("\n")
    n = len(lines)
    i = first
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

