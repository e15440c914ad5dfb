"""The plain move model every toolpath reader produces, and its summary.

A :class:`Toolpath` is what a CAM program *means* on the machine that would run it: absolute end
points in the program's workpiece frame (SI metres), arcs with their centre and plane normal, the tool
axis where the program gives one, the feed the machine would use, and for every move the file, line
and column it came from. Readers (``robot_io.gcode``, ``robot_io.apt``, ``robot_io.krl.reader``)
resolve everything modal (units, absolute/incremental, planes, feed modes) so that nothing downstream
has to know which dialect the file spoke.

This module is ``robot_io``'s own: it does not import ``planner``.
"""

from __future__ import annotations

import enum
import gc
import math
from collections import Counter
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol, overload

import numpy as np

from models.errors import CctmillError

__all__ = [
    "Move",
    "MoveKind",
    "MoveList",
    "SourceRef",
    "Toolpath",
    "ToolpathError",
    "ToolpathReader",
    "ToolpathWarning",
    "arc_geometry",
    "check_option_names",
    "read_source_text",
    "summarize",
]


class ToolpathError(CctmillError):
    """A toolpath file cannot be read as written.

    Attributes:
        file: path of the file.
        line: 1-based line number (0 when the whole file is meant: not found, unreadable; the
            message then names only the file).
        column: 1-based column of the offending word (0 when the whole line is meant).
        reason: the problem and how to fix it, without the location.
    """

    def __init__(self, file: str, line: int, column: int, reason: str) -> None:
        self.file = file
        self.line = line
        self.column = column
        self.reason = reason
        where = f"{file}:{line}:{column}" if line > 0 else file
        super().__init__(f"{where}: {reason}")


@dataclass(frozen=True)
class SourceRef:
    """Where a move or warning came from: file, 1-based line and column."""

    file: str
    line: int
    column: int = 0

    def __str__(self) -> str:
        return f"{self.file}:{self.line}:{self.column}"


@dataclass(frozen=True)
class ToolpathWarning:
    """A problem that lenient reading (or a harmless oddity in strict reading) went past.

    Attributes:
        source: where.
        message: what, and what was done about it.
        category: short key for counting (e.g. ``"unknown_record"``, ``"ignored_word"``).
    """

    source: SourceRef
    message: str
    category: str

    def __str__(self) -> str:
        return f"{self.source}: {self.message}"


class MoveKind(enum.Enum):
    """Kind of motion of one move."""

    RAPID = "rapid"        #: positioning at the machine's rapid speed (G0, RAPID, PTP)
    LINEAR = "linear"      #: straight feed move (G1, GOTO, LIN)
    ARC_CW = "arc_cw"      #: clockwise about ``Move.normal`` (G2 in its plane; CIRC)
    ARC_CCW = "arc_ccw"    #: counter-clockwise about ``Move.normal`` (G3)


@dataclass(frozen=True)
class Move:
    """One move, fully resolved. SI; workpiece frame of the program.

    Attributes:
        kind: the motion kind.
        start: start point of the TCP [m], shape (3,); ``None`` when the machine position before the
            first move (or after a homing) is not known.
        end: end point of the TCP (tool tip) [m], shape (3,).
        feed: path speed [m/s] the machine would use for this move; ``None`` for rapids, or when the
            program gives only a duration (inverse time) — then see ``duration``.
        duration: move time [s] for inverse-time feed (G93), else ``None``.
        center: arc centre [m], shape (3,), in the arc's start plane (arcs only).
        normal: unit normal of the arc plane, shape (3,); the arc turns counter-clockwise about
            ``normal`` for ``ARC_CCW`` and clockwise for ``ARC_CW`` (arcs only). For a helix the
            axial travel is ``end - start`` projected on ``normal``.
        turns: extra full turns of an arc (G-code ``P``), normally 0.
        tool_axis: unit vector from the tool tip towards the spindle [-], shape (3,), when the
            program gives one (5-axis, APT ``GOTO/x,y,z,i,j,k``), else ``None``.
        spindle_rpm: spindle speed in force [rev/min], ``None`` if never set.
        tool: tool number in force, ``None`` if never set.
        source: file, line, column of the word or record that made this move.
        extra: reader-specific extras (e.g. the raw rotary axis values ``{"A": rad, "C": rad}``).
    """

    kind: MoveKind
    start: np.ndarray | None
    end: np.ndarray
    source: SourceRef
    feed: float | None = None
    duration: float | None = None
    center: np.ndarray | None = None
    normal: np.ndarray | None = None
    turns: int = 0
    tool_axis: np.ndarray | None = None
    spindle_rpm: float | None = None
    tool: int | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def is_arc(self) -> bool:
        """True for ``ARC_CW`` and ``ARC_CCW``."""
        return self.kind in (MoveKind.ARC_CW, MoveKind.ARC_CCW)

    @property
    def length(self) -> float:
        """Path length of the tool tip [m] (helical arcs included); 0 when ``start`` is unknown."""
        if self.start is None:
            return 0.0
        if not self.is_arc:
            return float(np.linalg.norm(self.end - self.start))
        geo = arc_geometry(self)
        return float(math.hypot(geo["radius"] * abs(geo["sweep"]), geo["axial"]))


@dataclass
class Toolpath:
    """A whole program as moves, with what reading it noticed.

    Attributes:
        file: the file read.
        format: ``"gcode"``, ``"apt"`` or ``"krl"``.
        units: units the file was written in (``"mm"`` or ``"inch"``); moves are in metres.
        moves: the moves, in program order: a ``list`` of :class:`Move`, or (from the G-code
            reader) a :class:`MoveList`, which reads the same and builds each ``Move`` on access.
        warnings: everything noticed but not fatal.
        skipped: count of records/words skipped, by category (nothing is dropped silently).
        meta: reader-specific facts (e.g. ``{"program": "1117_wall", "rotary_kinematics": ...}``).
    """

    file: str
    format: str
    units: str
    moves: Sequence[Move] = field(default_factory=list)
    warnings: list[ToolpathWarning] = field(default_factory=list)
    skipped: Counter = field(default_factory=Counter)
    meta: dict[str, Any] = field(default_factory=dict)


_KIND_ORDER = (MoveKind.RAPID, MoveKind.LINEAR, MoveKind.ARC_CW, MoveKind.ARC_CCW)
_OBJ_NEW = object.__new__
_OBJ_SET = object.__setattr__


class MoveList(Sequence[Move]):
    """The moves of a program stored as columns; each :class:`Move` is built on first access.

    Reads like the ``list`` of moves it stands for (``len``, indexing, negative indices, slices
    → ``list``, iteration, ``==`` against a list); a move is built once and then kept, so
    ``moves[i] is moves[i]`` and ``moves[i + 1].start is moves[i].end`` as in a list of moves.
    A reader fills it with one numpy array per field instead of one object per move, which is
    what makes reading large programs fast; code that only needs the end points can use
    :attr:`ends` without building any :class:`Move`.

    Args:
        file: the file every ``SourceRef`` names.
        ends: end points [m], shape (n, 3); kept read-only.
        kinds: index into (RAPID, LINEAR, ARC_CW, ARC_CCW), shape (n,).
        lines, columns: ``SourceRef`` line and column, shape (n,).
        feeds: feed [m/s], NaN for ``None``, shape (n,).
        durations: inverse-time duration [s], NaN for ``None``, shape (n,).
        spindles: spindle speed [rev/min], NaN for ``None``, shape (n,).
        tools: tool number, -1 for ``None``, shape (n,).
        starts: 0 = start unknown (``None``), 1 = the previous move's end, 2 = given in
            ``sparse[i]["start"]``, shape (n,).
        sparse: the rare fields by move index: ``{"start", "center", "normal", "turns",
            "tool_axis", "extra"}`` (arrays read-only), any subset.
    """

    def __init__(self, file: str, ends: np.ndarray, kinds: np.ndarray, lines: np.ndarray,
                 columns: np.ndarray, feeds: np.ndarray, durations: np.ndarray,
                 spindles: np.ndarray, tools: np.ndarray, starts: np.ndarray,
                 sparse: dict[int, dict[str, Any]]) -> None:
        n = len(ends)
        ends = np.asarray(ends, dtype=float).reshape(n, 3)
        ends.flags.writeable = False
        cols = (kinds, lines, columns, feeds, durations, spindles, tools, starts)
        if any(len(c) != n for c in cols):
            raise ValueError("MoveList columns must all have one entry per move")
        self._file = file
        self._ends = ends
        self._cols = cols
        self._sparse = sparse
        self._lists: tuple[list, ...] | None = None
        self._moves: list[Move | None] = [None] * n

    @property
    def ends(self) -> np.ndarray:
        """End points of all moves [m], shape (n, 3), read-only (``moves[i].end`` is row i)."""
        return self._ends

    def __len__(self) -> int:
        return len(self._moves)

    @overload
    def __getitem__(self, index: int) -> Move: ...

    @overload
    def __getitem__(self, index: slice) -> list[Move]: ...

    def __getitem__(self, index: int | slice) -> Move | list[Move]:
        if isinstance(index, slice):
            if None in self._moves:
                self._build_all()
            return self._moves[index]  # type: ignore[return-value]
        i = index.__index__()
        if i < 0:
            i += len(self._moves)
        if not 0 <= i < len(self._moves):
            raise IndexError("move index out of range")
        return self._get(i)

    def __iter__(self) -> Iterator[Move]:
        if None in self._moves:
            self._build_all()
        return iter(self._moves)  # type: ignore[arg-type]

    def __eq__(self, other: object) -> bool:
        if isinstance(other, (MoveList, list)):
            return list(self) == list(other)
        return NotImplemented

    __hash__ = None  # type: ignore[assignment]

    def __repr__(self) -> str:
        return f"MoveList({len(self._moves)} moves, file={self._file!r})"

    def _get(self, i: int) -> Move:
        m = self._moves[i]
        return self._build(i) if m is None else m

    def _build_all(self) -> None:
        """Make every move not made yet, with the garbage collector paused: the objects made
        here only reference arrays and each other, and collecting while making tens of thousands
        of them doubles the time (it is switched back on in any case)."""
        was_enabled = gc.isenabled()
        gc.disable()
        try:
            if self._lists is None:
                self._lists = (*(c.tolist() for c in self._cols), list(self._ends))
            moves, sparse, file, order = self._moves, self._sparse, self._file, _KIND_ORDER
            new, setattr_ = _OBJ_NEW, _OBJ_SET
            prev = None
            for i, (kind, line, column, feed, duration, spindle, tool, start, end) in enumerate(
                    zip(*self._lists, strict=True)):
                if moves[i] is None:
                    if i in sparse:
                        self._build(i)
                    else:
                        src = new(SourceRef)
                        setattr_(src, "__dict__", {"file": file, "line": line, "column": column})
                        mv = new(Move)
                        setattr_(mv, "__dict__", {
                            "kind": order[kind], "start": prev if start == 1 else None,
                            "end": end, "source": src, "feed": None if feed != feed else feed,
                            "duration": None if duration != duration else duration,
                            "center": None, "normal": None, "turns": 0, "tool_axis": None,
                            "spindle_rpm": None if spindle != spindle else spindle,
                            "tool": None if tool < 0 else tool, "extra": {}})
                        moves[i] = mv
                prev = end
        finally:
            if was_enabled:
                gc.enable()

    def _build(self, i: int) -> Move:
        """Make move ``i`` without the frozen-dataclass ``__init__`` (13 ``object.__setattr__``
        calls); ``test_gcode`` checks that the result equals ``Move(**fields)``."""
        if self._lists is None:   # Python scalars and row views, made once
            self._lists = (*(c.tolist() for c in self._cols), list(self._ends))
        kinds, lines, columns, feeds, durations, spindles, tools, starts, rows = self._lists
        sp = self._sparse.get(i)
        flag = starts[i]
        if flag == 1:
            start = rows[i - 1] if i else None
        elif flag == 2 and sp is not None:
            start = sp["start"]
        else:
            start = None
        feed, duration, spindle, tool = feeds[i], durations[i], spindles[i], tools[i]
        src = _OBJ_NEW(SourceRef)
        _OBJ_SET(src, "__dict__", {"file": self._file, "line": lines[i], "column": columns[i]})
        mv = _OBJ_NEW(Move)
        _OBJ_SET(mv, "__dict__", {
            "kind": _KIND_ORDER[kinds[i]], "start": start, "end": rows[i], "source": src,
            "feed": None if feed != feed else feed,
            "duration": None if duration != duration else duration,
            "center": None if sp is None else sp.get("center"),
            "normal": None if sp is None else sp.get("normal"),
            "turns": 0 if sp is None else sp.get("turns", 0),
            "tool_axis": None if sp is None else sp.get("tool_axis"),
            "spindle_rpm": None if spindle != spindle else spindle,
            "tool": None if tool < 0 else tool,
            "extra": {} if sp is None or "extra" not in sp else sp["extra"]})
        self._moves[i] = mv
        return mv


def read_source_text(file: str) -> tuple[str, str]:
    """Read a toolpath file as text: UTF-8 (a BOM is dropped), falling back to Latin-1.

    Returns:
        (text, encoding used). Raises :class:`ToolpathError` (line 0) when the file cannot be read.
    """
    try:
        with open(file, "rb") as fh:
            data = fh.read()
    except FileNotFoundError as e:
        raise ToolpathError(file, 0, 0, "not found; check the path") from e
    except OSError as e:
        raise ToolpathError(file, 0, 0, f"cannot read the file ({e.strerror}); check the "
                            "path and its permissions") from e
    try:
        return data.decode("utf-8-sig"), "utf-8"
    except UnicodeDecodeError:
        return data.decode("latin-1"), "latin-1"


def check_option_names(options_class: type, options: dict[str, Any], reader: str) -> None:
    """Raise :class:`~models.errors.InputError` for a keyword that ``options_class`` (a dataclass)
    does not have; ``reader`` names the reader in the message (e.g. ``"APT"``). An option of
    another reader says which formats it applies to, in the words of the interface in use."""
    from models.errors import InputError
    from robot_io.options import OPTION_FORMATS, option_name

    names = set(options_class.__dataclass_fields__)
    for k in options:
        if k in names:
            continue
        formats = [f for f in OPTION_FORMATS.get(k, ()) if f != "*"]
        if formats:
            shown = " and ".join(_FORMAT_NAMES.get(f, f) for f in formats)
            raise InputError(option_name(k), f"applies to {shown} programs only, not to "
                             f"{reader} (leave it out for this file)")
        raise InputError(option_name(k), f"unknown {reader} reader option; known: "
                         + ", ".join(option_name(n) for n in sorted(names)))


#: How messages name the formats.
_FORMAT_NAMES = {"gcode": "G-code", "apt": "APT/CL", "krl": "KUKA KRL"}


class ToolpathReader(Protocol):
    """What every reader offers (:data:`robot_io.readers.READERS` is built from them).

    Attributes:
        format: the format's name (``"gcode"``, ``"apt"``, ``"krl"``).
        suffixes: the file extensions that announce it (lower case, with the dot).
    """

    format: str
    suffixes: tuple[str, ...]

    @staticmethod
    def sniff(head: str) -> bool:
        """Whether the first KiB of a file (upper-cased) look like this format."""
        ...

    def read(self, path: str, strict: bool = True, **options: Any) -> Toolpath:
        """Read ``path`` into a :class:`Toolpath`; strict mode raises :class:`ToolpathError`."""
        ...


#: Radii of the start and end point about an arc's centre may differ by this much [m] before
#: the arc is called inconsistent (LinuxCNC uses 0.002 mm absolute / 0.1 % relative; we allow
#: the larger of 2 µm and 0.1 % of the radius, and readers may widen it with an option).
ARC_RADIUS_TOL = 2e-6
ARC_RADIUS_RTOL = 1e-3


def arc_geometry(move: Move) -> dict[str, Any]:
    """Radius [m], signed sweep [rad] about ``normal``, axial travel [m] and in-plane basis of an arc.

    A full circle (end = start in the plane) sweeps 2π. ``turns`` adds full turns.
    """
    if move.start is None or move.center is None or move.normal is None:
        raise ValueError("arc_geometry needs an arc with start, center and normal")
    n = move.normal / np.linalg.norm(move.normal)
    rs = move.start - move.center
    rs = rs - (rs @ n) * n
    re = move.end - move.center
    axial = float((re @ n) - ((move.start - move.center) @ n))
    re = re - (re @ n) * n
    radius = float(np.linalg.norm(rs))
    u = rs / radius if radius > 0 else np.zeros(3)
    v = np.cross(n, u)
    ang = math.atan2(float(re @ v), float(re @ u))  # CCW angle from start to end, (-π, π]
    ccw = move.kind == MoveKind.ARC_CCW
    if ccw:
        sweep = ang if ang > 1e-12 else ang + 2 * math.pi
    else:
        sweep = ang if ang < -1e-12 else ang - 2 * math.pi
    sweep += (2 * math.pi if ccw else -2 * math.pi) * move.turns
    return {"radius": radius, "sweep": sweep, "axial": axial, "u": u, "v": v, "normal": n,
            "end_radius": float(np.linalg.norm(re))}


def _arc_extremes(move: Move) -> np.ndarray:
    """Points of an arc that bound its box exactly: the ends and every axis-extreme point inside
    the sweep, in closed form.

    Coordinate k of x(θ) = c + r (cos θ u + sin θ v) + axial·θ/sweep n is f(θ) = A cos θ +
    B sin θ + Cθ + const, with A = r u_k, B = r v_k, C = axial n_k / sweep; f'(θ) =
    −R sin(θ − φ) + C = 0 (R = √(A² + B²), φ = atan2(B, A)), i.e. θ = φ + asin(C/R) or
    θ = φ + π − asin(C/R), when |C| ≤ R. Of the repeats θ₀ + 2πm of such an angle inside the
    sweep (a helix of many turns has many), the box needs only the first and the last, since
    f(θ + 2π) = f(θ) + 2πC is monotone in m. At most 14 points, whatever the number of turns.
    """
    geo = arc_geometry(move)
    pts = [move.start, move.end]
    r, sweep, u, v, n = geo["radius"], geo["sweep"], geo["u"], geo["v"], geo["normal"]
    two_pi = 2.0 * math.pi
    span = abs(sweep)
    sign = 1.0 if sweep >= 0 else -1.0
    offset = ((move.start - move.center) @ n) * n
    axial = geo["axial"]
    for k in range(3):
        a_k, b_k = r * u[k], r * v[k]
        big_r = math.hypot(a_k, b_k)
        c_k = axial * n[k] / sweep if sweep else 0.0
        if big_r <= 0.0 or abs(c_k) > big_r:
            continue
        phi = math.atan2(b_k, a_k)
        lift = math.asin(max(-1.0, min(1.0, c_k / big_r)))
        for cand in (phi + lift, phi + math.pi - lift):
            # angles sign·t with t in (0, span): t = t0 + 2πm, m = 0 … m_last
            t0 = (sign * cand) % two_pi
            if t0 <= 0.0:
                t0 += two_pi
            if t0 >= span:
                continue
            m_last = max(math.floor((span - t0) / two_pi), 0)
            for m in {0, m_last}:
                t = t0 + two_pi * m
                if not 0.0 < t < span:
                    continue
                th = sign * t
                pts.append(move.center + r * (math.cos(th) * u + math.sin(th) * v) + offset
                           + axial * (th / sweep) * n)
    return np.array(pts)


#: Tool axes equal to this many decimals (1e-6: CAM writes 6–7 digits) count as one.
_AXIS_DIGITS = 6
_DEFAULT_AXIS = (0.0, 0.0, 1.0)


def summarize(tp: Toolpath) -> dict[str, Any]:
    """The ``cctmill inspect`` summary of a toolpath (SI, feeds in mm/min as named).

    ``bbox_m`` bounds every known tool-tip position: every move's end point, and for arcs the
    extreme points inside the sweep (not only the chord ends). ``length_m`` is the tool-tip path
    length of all moves with a known start (rapids included); ``cutting_length_m`` excludes rapids.
    ``has_tool_axis`` is true only when the program tilts the tool: some tool axis differs from
    +z (the 3-axis default); ``tool_axes`` counts the distinct tool axes it gives (to 1e-6) and
    ``tool_axis_turning_moves`` the feed moves that change the axis (0 for indexed 3+2 work,
    where only positioning moves turn it).
    """
    moves = tp.moves
    rapids = sum(1 for m in moves if m.kind == MoveKind.RAPID)
    arcs = sum(1 for m in moves if m.is_arc)
    length = sum(m.length for m in moves)
    cutting = sum(m.length for m in moves if m.kind != MoveKind.RAPID)
    pts = []
    for m in moves:
        if m.is_arc and m.start is not None:
            pts.append(_arc_extremes(m))
        else:
            pts.append(m.end.reshape(1, 3))
    if pts:
        allp = np.vstack(pts)
        bbox = [allp.min(axis=0).tolist(), allp.max(axis=0).tolist()]
    else:
        bbox = None
    feeds = [m.feed for m in moves if m.kind != MoveKind.RAPID and m.feed is not None]
    axes: set[tuple[float, ...]] = set()
    turning = 0     # feed moves whose tool axis differs from the move before (simultaneous)
    prev: tuple[float, ...] | None = None
    for m in moves:
        if m.tool_axis is None:
            continue
        ax = tuple(round(float(c), _AXIS_DIGITS) + 0.0 for c in m.tool_axis)
        axes.add(ax)
        if prev is not None and ax != prev and m.kind != MoveKind.RAPID:
            turning += 1
        prev = ax
    return {
        "file": tp.file,
        "format": tp.format,
        "units": tp.units,
        "moves": len(moves),
        "rapids": rapids,
        "arcs": arcs,
        "length_m": length,
        "cutting_length_m": cutting,
        "bbox_m": bbox,
        "feed_mm_min": ({"min": min(feeds) * 60e3, "max": max(feeds) * 60e3} if feeds else None),
        "inverse_time_moves": sum(1 for m in moves if m.duration is not None),
        "has_tool_axis": len(axes) > 1 or bool(axes - {_DEFAULT_AXIS}),
        "tool_axes": len(axes),
        "tool_axis_turning_moves": turning,
        "skipped": dict(tp.skipped),
        "warnings": [str(w) for w in tp.warnings],
    }
