"""The robot as a KRL program moves it: feed, frames, current pose, and the moves it makes
(private helper of ``robot_io.krl.reader``, whose docstring states the conventions).

The interpreter hands over plain data — target components in mm/deg, keyword, columns — and
:class:`RobotState` turns them into :class:`~robot_io.toolpath.Move` objects in SI, in the frame of
the first ``$BASE``. Problems are :class:`~robot_io.krl._syntax.LineError`; the ones lenient reading
goes past without skipping anything (no feed yet, an unknown ``$BASE`` change) go through ``soft``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from robot_io.krl._program import Stmt
from robot_io.krl._syntax import Aggregate, LineError
from robot_io.krl._values import CART
from robot_io.krl.frames import (
    abc_to_matrix,
    circle_through,
    frame_matrix,
    matrix_to_abc,
    rotate_about,
)
from robot_io.options import fix
from robot_io.toolpath import Move, MoveKind, SourceRef, Toolpath

__all__ = [
    "CA_FULL_TOL_DEG",
    "FRAME_TOL",
    "Frame",
    "MM",
    "PLAUSIBLE_VEL_CP",
    "RobotState",
    "frame_from",
]

#: One millimetre [m] (KRL positions are mm).
MM = 1e-3
#: Two frames are the same when their 4×4 transforms agree to this (metres and rotation entries).
FRAME_TOL = 1e-9
#: ``$VEL.CP`` above this [m/s] gets a warning (LiskinLabs kuka-krl-extension diagnostics use 3 m/s;
#: a milling feed is a few mm/s, so a larger value is almost surely mm/s written as m/s).
PLAUSIBLE_VEL_CP = 3.0
#: A CIRC ``CA`` within this of a whole number of turns [deg] is that many full circles.
CA_FULL_TOL_DEG = 1e-9

_XYZ = ("X", "Y", "Z")
_ABC = ("A", "B", "C")
_EXT = tuple(f"E{i}" for i in range(1, 7))
_STATUS = ("S", "T")

Soft = Callable[[Stmt, int, str, str], None]
Warn = Callable[[str, int, int, str, str], None]


@dataclass
class Frame:
    """A $BASE or $TOOL value: its name in the program and its transform [SI] if known."""

    name: str
    matrix: np.ndarray | None
    source: str | None
    index: int | None = None

    def same(self, other: Frame) -> bool:
        """Equal transforms, or (both unknown) the same name."""
        if self.matrix is not None and other.matrix is not None:
            return bool(np.allclose(self.matrix, other.matrix, rtol=0.0, atol=FRAME_TOL))
        return self.matrix is None and other.matrix is None and self.name == other.name

    def as_meta(self) -> dict[str, Any]:
        """The ``Toolpath.meta`` form."""
        return {"name": self.name, "matrix": None if self.matrix is None else self.matrix.copy(),
                "index": self.index, "source": self.source}


def frame_from(value: Any, name: str, source: str, col: int, index: int | None = None) -> Frame:
    """A :class:`Frame` from a FRAME aggregate (all of X…C needed); anything else is unknown."""
    if not isinstance(value, Aggregate):
        return Frame(name, None, source, index)
    f = value.fields
    missing = [k for k in CART if k not in f]
    bad = [k for k in CART if k in f and (isinstance(f[k], bool)
                                          or not isinstance(f[k], (int, float)))]
    if missing or bad:
        what = ("missing " + ", ".join(missing)) if missing else ("not a number: " + ", ".join(bad))
        raise LineError(col, f"a frame needs numbers for all of X, Y, Z, A, B, C ({what})")
    m = frame_matrix(f["X"] * MM, f["Y"] * MM, f["Z"] * MM, f["A"], f["B"], f["C"])
    return Frame(name, m, source, index)


class RobotState:
    """Feed, frames and pose in force, and the toolpath being built."""

    def __init__(self, tp: Toolpath, soft: Soft, warn: Warn) -> None:
        self.tp = tp
        self.meta = tp.meta
        self.soft = soft
        self.warn = warn
        self.feed: float | None = None
        self.ptp_velocity_pct: float | None = None   # PTP speed [% of the axes' maximum]
        self.apo_cdis: float | None = None
        self.cur: dict[str, float] = {}          # TCP pose in the current $BASE (mm, deg, S, T)
        self.unknown_why = "at the start of the program"
        self.last_end: np.ndarray | None = None  # last end point in the output frame [m]
        self.base = Frame("(controller $BASE: not set in the program)", None, None)
        self.tool = Frame("(controller $TOOL: not set in the program)", None, None)
        self.first_base: Frame | None = None     # $BASE at the first Cartesian motion
        self.out_from_base: np.ndarray | None = None   # 4×4 once $BASE changed mid-program
        self.pending_joint: dict[str, Any] | None = None
        self.loop: dict[str, int] = {}           # counters of the FOR loops being unrolled
        self.unrolled = 0                        # moves made inside loops so far

    # ------------------------------------------------------------------ settings
    def set_feed(self, st: Stmt, col: int, v: Any, what: str) -> None:
        """Path speed [m/s] from ``$VEL.CP`` (or ``BAS(#VEL_CP/#CP_PARAMS, v)``)."""
        if isinstance(v, bool) or not isinstance(v, float):
            raise LineError(col, f"{what} needs a number (path speed in m/s)")
        if v <= 0.0:
            raise LineError(col, f"{what} = {v:g} m/s: the path speed must be > 0", "bad_value")
        if v > PLAUSIBLE_VEL_CP:
            self.warn(st.file, st.line, col, f"{what} = {v:g} m/s is implausibly fast for "
                      f"milling (> {PLAUSIBLE_VEL_CP:g} m/s); was mm/s written? "
                      "($VEL.CP is in m/s)", "implausible_speed")
        self.feed = v

    def apply_frame(self, st: Stmt, col: int, which: str, new: Frame) -> None:
        """Make ``new`` the $TOOL or $BASE in force (see the reader's docs on $BASE changes)."""
        if which == "TOOL":
            if self.first_base is not None and not self.tool.same(new):
                self.meta["tool_changes"].append(new.as_meta())
            self.tool = new
            return
        if self.first_base is None:
            self.base = new
            return
        if self.base.same(new):
            return
        first, old = self.first_base, self.base
        if first.matrix is None or old.matrix is None or new.matrix is None:
            unknown = [f.name for f in (first, old, new) if f.matrix is None]
            self.soft(st, col, f"$BASE changes after the first motion (from {old.name} to "
                      f"{new.name}) and the value of {', '.join(dict.fromkeys(unknown))} is not "
                      "given in the program, so the later moves cannot be expressed in the first "
                      "base; give the frames as {FRAME: X …} literals (or BASE_DATA[n] = {FRAME: …} "
                      f"lines), keep one $BASE per program, or read with {fix('strict', False)} "
                      "(moves are then read in the new base as if it were the first)",
                      "base_change")
            self.base = new
            return
        # re-express the current pose in the new base (for partial and relative targets)
        if all(k in self.cur for k in _XYZ):
            to_new = np.linalg.solve(new.matrix, old.matrix)
            p = to_new @ np.array([self.cur["X"] * MM, self.cur["Y"] * MM, self.cur["Z"] * MM,
                                   1.0])
            self.cur.update(X=p[0] / MM, Y=p[1] / MM, Z=p[2] / MM)
            if all(k in self.cur for k in _ABC):
                r = to_new[:3, :3] @ abc_to_matrix(self.cur["A"], self.cur["B"], self.cur["C"])
                self.cur.update(zip(_ABC, matrix_to_abc(r), strict=True))
        self.base = new
        rel = np.linalg.solve(first.matrix, new.matrix)
        self.out_from_base = None if np.allclose(rel, np.eye(4), atol=FRAME_TOL) else rel
        self.meta["base_changes"].append(new.as_meta())

    def lose_position(self, why: str) -> None:
        """The robot went somewhere the reader cannot follow."""
        self.cur = {}
        self.last_end = None
        self.unknown_why = why

    # ------------------------------------------------------------------ motion
    def move(self, st: Stmt, kind: str, comps: dict[str, float], col: int, name: str,
             src: SourceRef, aux: tuple[str, dict[str, float], int, str] | None,
             ca: float | None, approx: str | None, rel_frame: str) -> None:
        """Carry out PTP/LIN/CIRC(_REL) to a target of ``kind`` ``cart``/``axes``/``current``."""
        kw = st.keyword
        rel = kw.endswith("_REL")
        if kind == "current":     # PTP $AXIS_ACT (BCO run): the robot stays where it is
            if kw == "PTP":
                self.meta["joint_moves"].append({"source": str(src), "axes_deg": None,
                                                 "target": name, "relative": False})
            self.tp.skipped["joint_move" if kw == "PTP" else "null_move"] += 1
            return
        if kind == "axes":
            if kw.startswith("PTP"):
                self._joint_move(src, comps, rel)
                return
            raise LineError(col, f"{kw} needs a Cartesian target (X, Y, Z, A, B, C); {name} is "
                            "an axis position (only PTP moves to axis positions)",
                            "unsupported_motion")
        if rel:
            comps = self._relative(comps, rel_frame, col, kw)
        if aux is not None:
            if aux[0] != "cart":
                raise LineError(aux[2], "the CIRC auxiliary point must be a Cartesian position",
                                "unsupported_motion")
            self._circ(st, src, self._fill(aux[1], aux[2], "CIRC (auxiliary point)"),
                       self._fill(comps, col, "CIRC"), ca, approx)
            return
        pose = self._fill(comps, col, kw)
        if kw.startswith("PTP"):
            self._emit(MoveKind.RAPID, pose, src, None, approx)
        else:
            self._emit(MoveKind.LINEAR, pose, src, self._feed(st, kw), approx)

    def _fill(self, comps: dict[str, float], col: int, what: str) -> dict[str, float]:
        """A full pose: components the target leaves out keep their current value."""
        missing = [k for k in _XYZ if k not in comps and k not in self.cur]
        if missing:
            raise LineError(col, f"the target of {what} leaves out {', '.join(missing)} and the "
                            f"current position is not known {self.unknown_why}; give X, Y and Z",
                            "unknown_position")
        pose = {**self.cur, **comps}
        if not all(k in pose for k in _ABC):
            for k in _ABC:
                pose.pop(k, None)
        return pose

    def _relative(self, comps: dict[str, float], frame: str, col: int,
                  kw: str) -> dict[str, float]:
        for k in _ABC + _EXT:
            if comps.get(k, 0.0) != 0.0:
                raise LineError(col, f"{kw} with a change of {k} is not supported: write the "
                                "absolute target", "unsupported_motion")
        if not all(k in self.cur for k in _XYZ):
            raise LineError(col, f"{kw} needs the current position, which is not known "
                            f"{self.unknown_why}; program an absolute target first",
                            "unknown_position")
        d = np.array([comps.get(k, 0.0) for k in _XYZ])
        if frame == "#TOOL":
            if not all(k in self.cur for k in _ABC):
                raise LineError(col, f"{kw} … #TOOL needs the current orientation, which is not "
                                "known; program an absolute target with A, B, C first",
                                "unknown_position")
            d = abc_to_matrix(self.cur["A"], self.cur["B"], self.cur["C"]) @ d
        return {k: self.cur[k] + float(d[i]) for i, k in enumerate(_XYZ)}

    def _feed(self, st: Stmt, kw: str) -> float | None:
        if self.feed is None:
            col = 1 + len(st.code) - len(st.code.lstrip())
            self.soft(st, col, f"{kw} before any $VEL.CP: the controller would use the path "
                      "speed left by earlier programs (BAS(#INITMOV) sets the $config.dat "
                      "default), which this program does not state; add $VEL.CP = <m/s>, e.g. "
                      f"$VEL.CP = 0.002, before line {st.line}", "no_feed")
        return self.feed

    def _joint_move(self, src: SourceRef, comps: dict[str, float], rel: bool) -> None:
        rec = {"source": str(src), "axes_deg": dict(comps), "target": None, "relative": rel}
        self.meta["joint_moves"].append(rec)
        self.tp.skipped["joint_move"] += 1
        self.lose_position(f"after the joint-space PTP at {src}")
        self.pending_joint = rec

    def _to_out(self, p_base: np.ndarray) -> np.ndarray:
        if self.out_from_base is None:
            return p_base
        return self.out_from_base[:3, :3] @ p_base + self.out_from_base[:3, 3]

    def _emit(self, kind: MoveKind, pose: dict[str, float], src: SourceRef, feed: float | None,
              approx: str | None, end: np.ndarray | None = None, **arc: Any) -> Move:
        if end is None:
            end = self._to_out(np.array([pose["X"] * MM, pose["Y"] * MM, pose["Z"] * MM]))
        extra: dict[str, Any] = {}
        tool_axis = None
        if "A" in pose:
            abc = (pose["A"], pose["B"], pose["C"])
            r = abc_to_matrix(*abc)
            if self.out_from_base is not None:
                r = self.out_from_base[:3, :3] @ r
                abc = matrix_to_abc(r)
            tool_axis = -r[:, 0]
            extra["abc_deg"] = abc
        for k in _STATUS:
            if k in pose:
                extra[k.lower()] = int(pose[k])
        ext = {k: pose[k] for k in _EXT if k in pose}
        if ext:
            extra["external"] = ext
        if approx is not None:
            extra["approx"] = approx
            if approx == "C_DIS" and self.apo_cdis is not None:
                extra["apo_cdis"] = self.apo_cdis
        if self.pending_joint is not None:
            extra["after_joint_move"] = self.pending_joint
            self.pending_joint = None
        if kind is MoveKind.RAPID and self.ptp_velocity_pct is not None:
            extra["ptp_velocity_pct"] = self.ptp_velocity_pct
        if self.loop:
            extra["loop"] = dict(self.loop)
            self.unrolled += 1
        start = self.last_end
        if start is None:
            self.meta["unknown_start_moves"] += 1
        if self.first_base is None:
            self.first_base = self.base
            self.meta["base"] = self.base.as_meta()
            self.meta["tool"] = self.tool.as_meta()
        move = Move(kind, start, end, src, feed=feed, tool_axis=tool_axis, tool=self.tool.index,
                    extra=extra, **arc)
        self.tp.moves.append(move)
        self.last_end = end
        self.cur = pose
        return move

    def _circ(self, st: Stmt, src: SourceRef, aux: dict[str, float], pose: dict[str, float],
              ca: float | None, approx: str | None) -> None:
        start = self.last_end
        if start is None:
            raise LineError(src.column, f"CIRC needs a known start point, which is not known "
                            f"{self.unknown_why}; program a LIN or PTP to a Cartesian position "
                            "before it", "unknown_position")
        p_aux = self._to_out(np.array([aux["X"], aux["Y"], aux["Z"]]) * MM)
        p_end = self._to_out(np.array([pose["X"], pose["Y"], pose["Z"]]) * MM)
        try:
            centre, normal = circle_through(start, p_aux, p_end)
        except ValueError as e:
            raise LineError(src.column, f"CIRC: {e}; check the auxiliary and end points",
                            "bad_arc") from None
        feed = self._feed(st, "CIRC")
        kind = MoveKind.ARC_CCW
        turns = 0
        end = p_end
        if ca is not None:
            turns_f = abs(ca) / 360.0
            whole = round(turns_f)
            if abs(turns_f - whole) * 360.0 < CA_FULL_TOL_DEG and whole >= 1:
                end, turns = start.copy(), whole - 1
            else:
                end = rotate_about(start, centre, normal, math.radians(ca))
                turns = math.floor(turns_f)
            if ca < 0:
                kind = MoveKind.ARC_CW
            p = end
            if self.out_from_base is not None:
                inv = np.linalg.inv(self.out_from_base)
                p = inv[:3, :3] @ end + inv[:3, 3]
            pose = {**pose, "X": float(p[0]) / MM, "Y": float(p[1]) / MM, "Z": float(p[2]) / MM}
        move = self._emit(kind, pose, src, feed, approx, end=end, center=centre, normal=normal,
                          turns=turns)
        move.extra["aux"] = p_aux
        if ca is not None:
            move.extra["ca_deg"] = ca
