"""From moves to path samples: arcs to chords, arc length, poses in the robot base, source lines.

Every sample remembers the move, file and line it came from, so any later finding (an unreachable
pose, a binding constraint) can be traced to the CAM program. Arcs are cut into chords whose sagitta
stays below ``chord_tol``; every segment is further split so no step exceeds ``step_max``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from models.errors import InputError
from robot_io.toolpath import Move, MoveKind, Toolpath, arc_geometry

__all__ = ["PathSamples", "sample_toolpath", "step_directions"]

#: Tool axis of a 3-axis program (no tool-axis words): +Z of the workpiece frame, tip → spindle.
DEFAULT_TOOL_AXIS = np.array([0.0, 0.0, 1.0])


@dataclass(frozen=True)
class PathSamples:
    """The path as ordered samples. SI. ``n`` samples.

    Attributes:
        s: arc length of the tool tip along the path [m], shape (n,), rapids included.
        position: tool-tip (TCP) position in the robot base [m], shape (n, 3).
        position_wp: the same in the workpiece frame (``$BASE``) [m], shape (n, 3).
        tool_axis: tool axis in the robot base, unit, tip → spindle, shape (n, 3). The TCP's +x
            axis (docs/model.md §1) is its negative.
        tool_axis_wp: the same in the workpiece frame, shape (n, 3).
        feed: programmed path speed of the move that ends at the sample [m/s], shape (n,);
            NaN for rapids and the first sample.
        cutting: True where the sample ends a feed move (not a rapid), shape (n,).
        move: index of the move in ``moves``, shape (n,).
        line: source line of that move, shape (n,).
        file: source file index into ``files``, shape (n,).
        files: the source files.
        moves: the moves (all toolpaths concatenated).
        base: ``$BASE``, 4×4 (workpiece → robot base).
    """

    s: np.ndarray
    position: np.ndarray
    position_wp: np.ndarray
    tool_axis: np.ndarray
    tool_axis_wp: np.ndarray
    feed: np.ndarray
    cutting: np.ndarray
    move: np.ndarray
    line: np.ndarray
    file: np.ndarray
    files: tuple[str, ...]
    moves: tuple[Move, ...]
    base: np.ndarray

    def __len__(self) -> int:
        return int(self.s.size)

    def where(self, i: int) -> str:
        """``file:line`` of sample ``i``."""
        return f"{self.files[int(self.file[i])]}:{int(self.line[i])}"

    @property
    def feed_dir(self) -> np.ndarray:
        """Unit direction of travel in the robot base, shape (n, 3) (see :func:`step_directions`)."""
        return step_directions(self.position)

    @property
    def feed_dir_wp(self) -> np.ndarray:
        """Unit direction of travel in the workpiece frame, shape (n, 3)."""
        return step_directions(self.position_wp)


def step_directions(points: np.ndarray) -> np.ndarray:
    """Unit direction of the step arriving at each point, shape (n, 3).

    The first point copies the second's; a zero-length step copies the previous direction.

    Args:
        points: ordered positions [m], shape (n, 3).
    """
    d = np.diff(points, axis=0)
    norm = np.linalg.norm(d, axis=1)
    out = np.zeros_like(points)
    last = np.array([1.0, 0.0, 0.0])
    for i in range(1, points.shape[0]):
        if norm[i - 1] > 0:
            last = d[i - 1] / norm[i - 1]
        out[i] = last
    if points.shape[0] > 1:
        out[0] = out[1]
    return out


def _chord_count(radius: float, sweep: float, chord_tol: float) -> int:
    if radius <= chord_tol:
        return 1
    step = 2.0 * math.acos(1.0 - chord_tol / radius)
    return max(1, math.ceil(abs(sweep) / step))


def _move_points(m: Move, chord_tol: float, step_max: float) -> np.ndarray:
    """Points along a move after its start, ending exactly at ``m.end``, shape (k, 3)."""
    if m.start is None:
        return m.end.reshape(1, 3)
    if m.is_arc:
        g = arc_geometry(m)
        k = _chord_count(g["radius"], g["sweep"], chord_tol)
        length = math.hypot(g["radius"] * abs(g["sweep"]), g["axial"])
        k = max(k, math.ceil(length / step_max))
        t = np.arange(1, k + 1) / k
        th = g["sweep"] * t
        c0 = m.center + ((m.start - m.center) @ g["normal"]) * g["normal"]
        pts = (c0 + g["radius"] * (np.cos(th)[:, None] * g["u"] + np.sin(th)[:, None] * g["v"])
               + (g["axial"] * t)[:, None] * g["normal"])
        pts[-1] = m.end
        return pts
    length = float(np.linalg.norm(m.end - m.start))
    k = max(1, math.ceil(length / step_max))
    t = np.arange(1, k + 1) / k
    return m.start + t[:, None] * (m.end - m.start)


def sample_toolpath(toolpaths: list[Toolpath], base: np.ndarray, chord_tol: float = 1e-5,
                    step_max: float = 2e-3) -> PathSamples:
    """Sample one or more toolpaths (in order) into :class:`PathSamples`.

    Args:
        toolpaths: read toolpaths; their moves are in the workpiece frame.
        base: ``$BASE`` 4×4 transform, workpiece → robot base (SI).
        chord_tol: largest sagitta of an arc chord [m].
        step_max: largest distance between consecutive samples [m].
    """
    if not chord_tol > 0 or not step_max > 0:
        raise InputError("path", "chord_tol and step_max must be positive")
    pos, axis, feed, cut, mv, line, fidx = [], [], [], [], [], [], []
    moves: list[Move] = []
    files = tuple(tp.file for tp in toolpaths)
    prev_axis = DEFAULT_TOOL_AXIS
    for fi, tp in enumerate(toolpaths):
        for m in tp.moves:
            pts = _move_points(m, chord_tol, step_max)
            end_axis = prev_axis if m.tool_axis is None else m.tool_axis / np.linalg.norm(m.tool_axis)
            k = pts.shape[0]
            if k > 1 and not np.allclose(end_axis, prev_axis):
                t = (np.arange(1, k + 1) / k)[:, None]
                ax = (1 - t) * prev_axis + t * end_axis
                ax /= np.linalg.norm(ax, axis=1, keepdims=True)
            else:
                ax = np.repeat(end_axis.reshape(1, 3), k, axis=0)
            pos.append(pts)
            axis.append(ax)
            rapid = m.kind == MoveKind.RAPID
            f = math.nan if (rapid or m.feed is None) else m.feed
            if f != f and not rapid and m.duration is not None and m.duration > 0:
                f = m.length / m.duration
            feed.append(np.full(k, f))
            cut.append(np.full(k, not rapid))
            mv.append(np.full(k, len(moves)))
            line.append(np.full(k, m.source.line))
            fidx.append(np.full(k, fi))
            moves.append(m)
            prev_axis = end_axis
    if not pos:
        raise InputError("toolpath", "no moves to sample; is the file empty?")
    p_wp = np.vstack(pos)
    a_wp = np.vstack(axis)
    rot, trans = base[:3, :3], base[:3, 3]
    steps = np.linalg.norm(np.diff(p_wp, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(steps)])
    feed_arr = np.concatenate(feed)
    feed_arr[0] = math.nan
    return PathSamples(
        s=s, position=p_wp @ rot.T + trans, position_wp=p_wp, tool_axis=a_wp @ rot.T,
        tool_axis_wp=a_wp, feed=feed_arr, cutting=np.concatenate(cut),
        move=np.concatenate(mv), line=np.concatenate(line), file=np.concatenate(fidx),
        files=files, moves=tuple(moves), base=np.asarray(base, float))
