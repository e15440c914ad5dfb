"""Coordinate frames of the APT/CL interpreter (private): points and directions through the
frame in force, the ``CSYS``/``MSYS`` and ``TRNTYP`` records; conventions in
:mod:`robot_io.apt.reader`."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from robot_io.apt import _records as rc
from robot_io.options import fix

if TYPE_CHECKING:
    from robot_io.apt._interp import Run

__all__ = ["direction", "frame_", "point", "trntyp", "vector"]


def _norm(v: tuple[float, ...]) -> float:
    return math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])


def _rot(r: tuple[rc.Vec, rc.Vec, rc.Vec], v: tuple[float, ...]) -> rc.Vec:
    """R·v for R given by rows."""
    return (r[0][0] * v[0] + r[0][1] * v[1] + r[0][2] * v[2],
            r[1][0] * v[0] + r[1][1] * v[1] + r[1][2] * v[2],
            r[2][0] * v[0] + r[2][1] * v[1] + r[2][2] * v[2])


def point(run: Run, vals: list[float]) -> rc.Vec:
    """``vals[0:3]`` in the units in force as a point [m] (moved by the frame with ``apply_frames``)."""
    s = run.length_scale()
    p = (vals[0] * s, vals[1] * s, vals[2] * s)
    if run.opts.apply_frames and run.frame is not None:
        r, t = run.frame
        q = _rot(r, p)
        p = (q[0] + t[0], q[1] + t[1], q[2] + t[2])
    return p


def vector(run: Run, vals: list[float]) -> rc.Vec:
    """``vals[0:3]`` in the units in force as a displacement [m] (turned, not moved, by the frame
    with ``apply_frames``)."""
    s = run.length_scale()
    v = (vals[0] * s, vals[1] * s, vals[2] * s)
    if run.opts.apply_frames and run.frame is not None:
        v = _rot(run.frame[0], v)
    return v


def direction(run: Run, vals: list[float], first: int, what: str) -> rc.Vec:
    """``vals[first:first + 3]`` as a unit vector (turned by the frame with ``apply_frames``)."""
    v = (vals[first], vals[first + 1], vals[first + 2])
    n = _norm(v)
    if not n > 1e-9:
        run.bad(run.field_offset(run.rec, first),   # type: ignore[arg-type]
                f"{run.rec.word}: {what} {v} is a zero vector; give a unit vector")  # type: ignore[union-attr]
    if abs(n - 1.0) > rc.TOOL_AXIS_NORM_TOL:
        run.warn(run.locate(run.rec, run.field_offset(run.rec, first))[0],  # type: ignore[arg-type]
                 "axis_not_unit", f"{what} has norm {n:.6g}, not 1; normalised")
    v = (v[0] / n, v[1] / n, v[2] / n)
    if run.opts.apply_frames and run.frame is not None:
        v = _rot(run.frame[0], v)
    return v


def frame_(run: Run, rec: rc.Record) -> None:
    if rec.word == "CSYS":
        vals = run.numbers(rec, (12,), "12 numbers (the APT matrix [R | t], row by row)")
    else:
        vals = run.numbers(rec, (9, 12), "9 numbers (origin, x axis, y axis) or 12 (the "
                           "APT matrix [R | t], row by row)")
    s = run.length_scale()
    if len(vals) == 12:
        rows = ((vals[0], vals[1], vals[2]), (vals[4], vals[5], vals[6]),
                (vals[8], vals[9], vals[10]))
        t = (vals[3] * s, vals[7] * s, vals[11] * s)
    else:
        x = np.array(vals[3:6])
        y = np.array(vals[6:9])
        z = np.cross(x, y)
        rows = tuple(tuple(float(c) for c in row)
                     for row in np.column_stack([x, y, z]))  # type: ignore[assignment]
        t = (vals[0] * s, vals[1] * s, vals[2] * s)
    rm = np.array(rows, dtype=float)
    err = float(np.abs(rm.T @ rm - np.eye(3)).max())
    if err > rc.FRAME_ORTHONORMAL_TOL or np.linalg.det(rm) < 0:
        run.bad(run.field_offset(rec, 0), f"{rec.word}: the rotation part is not a proper "
                f"rotation (|RᵀR − I| = {err:.2g}, det = {np.linalg.det(rm):.3g}); the "
                f"columns of R must be orthonormal axes; {rc.fix_or_skip()}")
    if run.opts.apply_frames:
        if run.meta["trntyp"] == "WORLD":
            run.warn(rec.col, "frames_on_world_data", f"frames are applied "
                     f"({fix('apply_frames', True)}) to a file that declares TRNTYP/WORLD: its "
                     "points are already in the world frame and are moved a second time; read "
                     "without applying the frames")
        run.frame = (rows, t)  # type: ignore[assignment]
    zn = _norm((rows[0][2], rows[1][2], rows[2][2]))
    z_axis = (rows[0][2] / zn, rows[1][2] / zn, rows[2][2] / zn)
    if rec.word == "CSYS" or run.opts.apply_frames:
        run.axis = z_axis
    run.meta["frames"].append({
        "record": rec.word, "line": rec.line,
        "rotation": [list(r) for r in rows], "origin_m": list(t)})


def trntyp(run: Run, rec: rc.Record) -> None:
    toks = run.tokens(rec)
    run.meta["trntyp"] = toks[0][0] if toks else None
