"""Where the G-code interpreter puts its moves (private): one column per field, not one object
per move; :meth:`MoveStore.finish` hands them on as a :class:`robot_io.toolpath.MoveList`.

The line-by-line interpreter adds moves one at a time (:meth:`MoveStore.add`, plain Python
lists); the bulk path of :mod:`robot_io.gcode._plain` adds a whole run of plain lines at once
(:meth:`MoveStore.add_block`, numpy arrays). Both end up in the same columns, in program order.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from robot_io.gcode import _words as W
from robot_io.toolpath import MoveList, ToolpathError

__all__ = ["KIND_INDEX", "START_GIVEN", "START_PREVIOUS", "START_UNKNOWN", "MoveStore"]

#: Motion code key (G0 = 0, G1 = 10, G2 = 20, G3 = 30) → ``MoveList`` kind index.
KIND_INDEX = {0: 0, 10: 1, 20: 2, 30: 3}
START_UNKNOWN = 0    #: ``Move.start`` is None
START_PREVIOUS = 1   #: ``Move.start`` is the previous move's end
START_GIVEN = 2      #: ``Move.start`` is stored with the move (the ``initial_position`` option)

_NAN = math.nan


class MoveStore:
    """The moves of one reading, as columns."""

    def __init__(self, file: str) -> None:
        self.file = file
        self.count = 0
        self.limit = W.MAX_MOVES   # read once per reading (and patched lower by tests)
        self.chunks: list[tuple[np.ndarray, ...]] = []
        self.sparse: dict[int, dict[str, Any]] = {}
        self._new_lists()

    def _new_lists(self) -> None:
        self.tips: list[tuple[float, float, float]] = []
        self.kinds: list[int] = []
        self.lines: list[int] = []
        self.cols: list[int] = []
        self.starts: list[int] = []
        self.feeds: list[float] = []
        self.durations: list[float] = []
        self.spindles: list[float] = []
        self.tools: list[int] = []

    def add(self, code: int, line: int, col: int, tip: tuple[float, float, float], start: int,
            feed: float | None, duration: float | None, spindle: float | None,
            tool: int | None, sparse: dict[str, Any] | None) -> None:
        """One move: motion ``code`` key, source line/column, end ``tip`` [m], a ``START_*``
        flag, feed [m/s], duration [s], spindle [rev/min], tool, and its rare fields."""
        if self.count >= self.limit:
            self.refuse(line, col)
        if sparse:
            self.sparse[self.count] = sparse
        self.count += 1
        self.tips.append(tip)
        self.kinds.append(KIND_INDEX[code])
        self.lines.append(line)
        self.cols.append(col)
        self.starts.append(start)
        self.feeds.append(_NAN if feed is None else feed)
        self.durations.append(_NAN if duration is None else duration)
        self.spindles.append(_NAN if spindle is None else spindle)
        self.tools.append(-1 if tool is None else tool)

    def add_block(self, tips: np.ndarray, kinds: np.ndarray, lines: np.ndarray,
                  cols: np.ndarray, feeds: np.ndarray, first_start: int,
                  spindle: float | None, tool: int | None) -> None:
        """``k`` linear/rapid moves at once: end points [m] (k, 3), kind indices, lines, columns,
        feeds [m/s] (NaN = None), the first move's ``START_*`` flag (the others start where the
        previous one ended), and the spindle speed and tool in force for all of them."""
        k = len(tips)
        if not k:
            return
        if self.count + k > self.limit:
            over = self.limit - self.count
            self.refuse(int(lines[over]), int(cols[over]))
        self._flush()
        starts = np.full(k, START_PREVIOUS, dtype=np.int8)
        starts[0] = first_start
        self.chunks.append((
            tips, kinds, lines, cols, starts, feeds, np.full(k, _NAN),
            np.full(k, _NAN if spindle is None else spindle),
            np.full(k, -1 if tool is None else tool, dtype=np.int64)))
        self.count += k

    def refuse(self, line: int, col: int) -> None:
        """Raise the :class:`ToolpathError` of the move past ``MAX_MOVES`` (in lenient reading
        too: a limit, not a problem to skip)."""
        raise ToolpathError(self.file, line, col, f"the program makes more than {self.limit:,} "
                            "moves (MAX_MOVES), too many to plan in memory: split it into "
                            "smaller programs, or check the loops and L repeats that multiply it")

    def _flush(self) -> None:
        if not self.kinds:
            return
        self.chunks.append((
            np.array(self.tips, dtype=float).reshape(-1, 3), np.array(self.kinds, np.int8),
            np.array(self.lines, np.int64), np.array(self.cols, np.int64),
            np.array(self.starts, np.int8), np.array(self.feeds, float),
            np.array(self.durations, float), np.array(self.spindles, float),
            np.array(self.tools, np.int64)))
        self._new_lists()

    def finish(self) -> MoveList:
        """All moves, in program order."""
        self._flush()
        if self.chunks:
            cols = [np.concatenate(c) for c in zip(*self.chunks, strict=True)]
        else:
            cols = [np.zeros((0, 3)), *(np.zeros(0, t) for t in (np.int8, np.int64, np.int64,
                                                                   np.int8, float, float, float,
                                                                   np.int64))]
        tips, kinds, lines, cols_, starts, feeds, durations, spindles, tools = cols
        return MoveList(self.file, tips, kinds, lines, cols_, feeds, durations, spindles, tools,
                        starts, self.sparse)
