"""KUKA frames: the one place the A, B, C convention is coded (job, planner, KRL writer and reader
all use it), plus the circle geometry of CIRC moves.

KUKA A, B, C (degrees) are Z-Y'-X'' Euler angles: R = Rz(A)·Ry(B)·Rx(C); the columns of R are the
axes of the rotated frame (e.g. the TCP) expressed in the reference frame (e.g. ``$BASE``). The
first column is the frame's +x axis: for ``$TOOL`` the tool axis (docs/model.md §1).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = [
    "CIRC_COLLINEAR_SIN",
    "CIRC_POINT_TOL",
    "GIMBAL_TOL",
    "abc_to_matrix",
    "circle_through",
    "frame_from_mm_deg",
    "frame_matrix",
    "matrices_to_abc",
    "matrix_to_abc",
    "rotate_about",
    "x_axes",
]

#: Below this |cos B| [-] the A and C angles are not separable (B = ±90°); ``matrix_to_abc``
#: then returns C = 0 and puts the whole rotation about z into A.
GIMBAL_TOL = 1e-9
#: Two CIRC points closer than this [m] count as the same point (1 nm, far below KRL's 1 µm print).
CIRC_POINT_TOL = 1e-9
#: Three CIRC points are collinear when the sine of the angle at the start point is below this
#: [-]; a chord of 1 m then already has a radius beyond 500 km, which no program means.
CIRC_COLLINEAR_SIN = 1e-6


def abc_to_matrix(a_deg: float, b_deg: float, c_deg: float) -> np.ndarray:
    """Rotation matrix [-], shape (3, 3), of KUKA angles A, B, C [deg]: Rz(A)·Ry(B)·Rx(C)."""
    a, b, c = np.radians([a_deg, b_deg, c_deg])
    ca, sa, cb, sb, cc, sc = np.cos(a), np.sin(a), np.cos(b), np.sin(b), np.cos(c), np.sin(c)
    rz = np.array([[ca, -sa, 0.0], [sa, ca, 0.0], [0.0, 0.0, 1.0]])
    ry = np.array([[cb, 0.0, sb], [0.0, 1.0, 0.0], [-sb, 0.0, cb]])
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cc, -sc], [0.0, sc, cc]])
    return rz @ ry @ rx


def x_axes(abc_deg: np.ndarray) -> np.ndarray:
    """The rotated frames' +x axes (the first column of :func:`abc_to_matrix`, to the last bit) of
    rows of KUKA A, B, C [deg], shape (n, 3) → (n, 3): for TCP orientations, the tool axes."""
    a, b = np.radians(abc_deg[:, 0]), np.radians(abc_deg[:, 1])
    return np.column_stack([np.cos(a) * np.cos(b), np.sin(a) * np.cos(b), -np.sin(b)])


def matrix_to_abc(rot: np.ndarray) -> tuple[float, float, float]:
    """KUKA angles A, B, C [deg] of a rotation matrix, shape (3, 3); B in [-90, 90]."""
    cb = math.hypot(float(rot[0, 0]), float(rot[1, 0]))
    b = math.atan2(-float(rot[2, 0]), cb)
    if cb > GIMBAL_TOL:
        a = math.atan2(float(rot[1, 0]), float(rot[0, 0]))
        c = math.atan2(float(rot[2, 1]), float(rot[2, 2]))
    else:
        a = math.atan2(-float(rot[0, 1]), float(rot[1, 1]))
        c = 0.0
    return math.degrees(a), math.degrees(b), math.degrees(c)


def matrices_to_abc(rot: np.ndarray) -> np.ndarray:
    """:func:`matrix_to_abc` of many rotation matrices, shape (m, 3, 3) → (m, 3) [deg]."""
    rot = np.asarray(rot, float)
    cb = np.hypot(rot[:, 0, 0], rot[:, 1, 0])
    b = np.arctan2(-rot[:, 2, 0], cb)
    regular = cb > GIMBAL_TOL
    a = np.where(regular, np.arctan2(rot[:, 1, 0], rot[:, 0, 0]),
                 np.arctan2(-rot[:, 0, 1], rot[:, 1, 1]))
    c = np.where(regular, np.arctan2(rot[:, 2, 1], rot[:, 2, 2]), 0.0)
    return np.degrees(np.column_stack([a, b, c]))


def frame_matrix(x_m: float, y_m: float, z_m: float, a_deg: float, b_deg: float,
                 c_deg: float) -> np.ndarray:
    """Homogeneous transform, shape (4, 4), SI [m], of a KRL FRAME given in metres and degrees."""
    t = np.eye(4)
    t[:3, :3] = abc_to_matrix(a_deg, b_deg, c_deg)
    t[:3, 3] = (x_m, y_m, z_m)
    return t


def frame_from_mm_deg(xyz_mm, abc_deg) -> np.ndarray:
    """Homogeneous transform, shape (4, 4), SI [m], of a frame given as the job and the KRL
    program write it: X, Y, Z [mm] (3,) and A, B, C [deg] (3,)."""
    t = np.eye(4)
    t[:3, :3] = abc_to_matrix(*abc_deg)
    t[:3, 3] = np.asarray(xyz_mm, float) * 1e-3
    return t


def circle_through(p0: np.ndarray, p1: np.ndarray, p2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Centre [m] and unit normal of the circle through ``p0``, ``p1``, ``p2`` (each shape (3,)).

    The normal is ``(p1 - p0) × (p2 - p0)`` normalised, so travelling from ``p0`` through ``p1`` to
    ``p2`` is counter-clockwise about it. Raises ``ValueError`` (with the reason) for coincident or
    collinear points.
    """
    u = p1 - p0
    v = p2 - p0
    nu, nv, nuv = float(np.linalg.norm(u)), float(np.linalg.norm(v)), float(np.linalg.norm(p2 - p1))
    if nu < CIRC_POINT_TOL:
        raise ValueError("the auxiliary point equals the start point")
    if nuv < CIRC_POINT_TOL:
        raise ValueError("the auxiliary point equals the end point")
    if nv < CIRC_POINT_TOL:
        raise ValueError("the end point equals the start point (a full circle needs CA 360)")
    w = np.cross(u, v)
    nw = float(np.linalg.norm(w))
    if nw < CIRC_COLLINEAR_SIN * nu * nv:
        raise ValueError("start, auxiliary and end point lie on one line")
    centre = p0 + (float(u @ u) * np.cross(v, w) + float(v @ v) * np.cross(w, u)) / (2.0 * nw * nw)
    return centre, w / nw


def rotate_about(point: np.ndarray, centre: np.ndarray, normal: np.ndarray,
                 angle_rad: float) -> np.ndarray:
    """``point`` [m] turned by ``angle_rad`` about the axis through ``centre`` along unit ``normal``
    (right-hand rule)."""
    r = point - centre
    along = float(r @ normal) * normal
    r_perp = r - along
    return (centre + along + math.cos(angle_rad) * r_perp
            + math.sin(angle_rad) * np.cross(normal, r_perp))
