"""Table-table (trunnion) 5-axis kinematics: machine XYZ + tilt/rotary angles → workpiece frame.

A trunnion machine keeps the spindle vertical (tool axis = machine +Z, pointing from the tool tip
towards the spindle) and moves the workpiece: a *tilting* table turns about a machine axis (X for an
A axis, Y for a B axis), and a *rotary* table mounted on it turns about its own Z by C.

Rotation order and signs are those of LinuxCNC's ``xyzac-trt-kins`` / ``xyzbc-trt-kins``
(``src/emc/kinematics/trtfuncs.c``, functions ``xyzacKinematicsInverse`` and
``xyzacKinematicsForward``), so that the LinuxCNC demo programs (``boat-xyzac.ngc``,
``impeller-7bl-xyzac.ngc``) mean here what they mean on the machine they were written for. With all
offsets zero, LinuxCNC's inverse kinematics reads

    joints = Rx(A) · Rz(C) · world            (xyzac)
    joints = Ry(B) · Rz(C) · world            (xyzbc)

with the usual right-handed rotation matrices ``Rx(t) = [[1,0,0],[0,cos t,-sin t],[0,sin t,cos t]]``
etc. That is, the *table rotation* ``R_table = R_tilt · Rz(C)`` (tilt about the machine axis, then turn
about the table's own, tilted Z) carries a workpiece point to machine coordinates. Hence

    tip_w  = Rz(-C) · [R_tilt(-tilt) · (p_machine - pivot - c_offset) + c_offset] + pivot
    axis_w = R_table(tilt, C)^T · (0, 0, 1)
           = (sin C sin A, cos C sin A, cos A)          (xyzac)
           = (-cos C sin B, sin C sin B, cos B)         (xyzbc)

``pivot`` is LinuxCNC's ``x/y/z-rot-point`` (where the tilt axis crosses the machine frame) and
``c_offset`` the position of the C axis relative to the tilt axis (LinuxCNC's
``(0, y-offset, z-offset + tool-offset)`` for xyzac, ``(x-offset, 0, z-offset + tool-offset)`` for
xyzbc). Both default to zero, as in the LinuxCNC sim configuration of the demos.

A sanity check on the shared impeller program: at its first cut (X 6.302 Y -11.560, A -71.841°,
C -35.930°) this gives a tool axis (0.56, -0.77, 0.31), pointing radially *out* of the hub and
slightly up, as a roughing tool between impeller blades must; the opposite sign convention would
point the spindle through the hub.

This module is plain math (tuples of floats) so readers can call it per move without numpy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from models.errors import InputError

__all__ = [
    "ROTARY_KINEMATICS",
    "TrunnionKinematics",
    "make_rotary_kinematics",
]

Vec3 = tuple[float, float, float]

#: Names accepted by :func:`make_rotary_kinematics`, with their tilt axis letter.
ROTARY_KINEMATICS = {"xyzac-trunnion": "A", "xyzbc-trunnion": "B"}


@dataclass(frozen=True)
class TrunnionKinematics:
    """A tilting table (A about X, or B about Y) carrying a rotary table (C about its own Z).

    Attributes:
        name: ``"xyzac-trunnion"`` or ``"xyzbc-trunnion"``.
        tilt: the tilt axis letter, ``"A"`` or ``"B"``.
        pivot: where the tilt axis crosses the machine frame [m], shape (3,) (LinuxCNC rot-point).
        c_offset: position of the C axis relative to the tilt axis [m], shape (3,).
    """

    name: str
    tilt: str
    pivot: Vec3 = (0.0, 0.0, 0.0)
    c_offset: Vec3 = (0.0, 0.0, 0.0)

    def table_rotation(self, tilt: float, c: float) -> tuple[Vec3, Vec3, Vec3]:
        """``R_table = R_tilt(tilt) · Rz(c)`` (rows), angles [rad]: workpiece → machine axes."""
        st, ct, sc, cc = math.sin(tilt), math.cos(tilt), math.sin(c), math.cos(c)
        if self.tilt == "A":   # Rx(a) · Rz(c)
            return ((cc, -sc, 0.0), (ct * sc, ct * cc, -st), (st * sc, st * cc, ct))
        # Ry(b) · Rz(c)
        return ((ct * cc, -ct * sc, st), (sc, cc, 0.0), (-st * cc, st * sc, ct))

    def tool_axis(self, tilt: float, c: float) -> Vec3:
        """Unit tool axis (tip → spindle) in the workpiece frame [-]: ``R_table^T · (0, 0, 1)``."""
        r = self.table_rotation(tilt, c)
        return (r[2][0], r[2][1], r[2][2])

    def rotate_to_workpiece(self, v: Vec3, tilt: float, c: float) -> Vec3:
        """A machine-frame direction ``v`` seen from the rotated table: ``R_table^T · v``."""
        r = self.table_rotation(tilt, c)
        return (r[0][0] * v[0] + r[1][0] * v[1] + r[2][0] * v[2],
                r[0][1] * v[0] + r[1][1] * v[1] + r[2][1] * v[2],
                r[0][2] * v[0] + r[1][2] * v[1] + r[2][2] * v[2])

    def tip(self, p_machine: Vec3, tilt: float, c: float) -> Vec3:
        """Tool tip in the workpiece frame [m] from machine XYZ [m] and angles [rad]."""
        px, py, pz = self.pivot
        dx, dy, dz = self.c_offset
        # R_table = R_tilt · Rz(c), so R_table^T = Rz(-c) · R_tilt(-tilt); the C-axis offset is
        # added back between the two rotations (LinuxCNC forward kinematics).
        r = self.table_rotation(tilt, 0.0)   # R_tilt alone
        v = (p_machine[0] - px - dx, p_machine[1] - py - dy, p_machine[2] - pz - dz)
        w = (r[0][0] * v[0] + r[1][0] * v[1] + r[2][0] * v[2] + dx,
             r[0][1] * v[0] + r[1][1] * v[1] + r[2][1] * v[2] + dy,
             r[0][2] * v[0] + r[1][2] * v[1] + r[2][2] * v[2] + dz)
        sc, cc = math.sin(c), math.cos(c)
        return (cc * w[0] + sc * w[1] + px, -sc * w[0] + cc * w[1] + py, w[2] + pz)

    def machine(self, p_work: Vec3, tilt: float, c: float) -> Vec3:
        """Inverse of :meth:`tip`: machine XYZ [m] that puts the tip on ``p_work`` [m]."""
        px, py, pz = self.pivot
        dx, dy, dz = self.c_offset
        sc, cc = math.sin(c), math.cos(c)
        u = (p_work[0] - px, p_work[1] - py, p_work[2] - pz)
        w = (cc * u[0] - sc * u[1] - dx, sc * u[0] + cc * u[1] - dy, u[2] - dz)
        r = self.table_rotation(tilt, 0.0)
        return (r[0][0] * w[0] + r[0][1] * w[1] + r[0][2] * w[2] + dx + px,
                r[1][0] * w[0] + r[1][1] * w[1] + r[1][2] * w[2] + dy + py,
                r[2][0] * w[0] + r[2][1] * w[1] + r[2][2] * w[2] + dz + pz)


def _vec3(name: str, value: object) -> Vec3:
    try:
        vals = tuple(float(v) for v in value)  # type: ignore[union-attr]
    except (TypeError, ValueError) as e:
        raise InputError(name, f"expected three numbers in metres, got {value!r}") from e
    if len(vals) != 3 or not all(math.isfinite(v) for v in vals):
        raise InputError(name, f"expected three finite numbers in metres, got {value!r}")
    return (vals[0], vals[1], vals[2])


def make_rotary_kinematics(name: str, pivot: object = (0.0, 0.0, 0.0),
                           c_offset: object = (0.0, 0.0, 0.0)) -> TrunnionKinematics:
    """Build the kinematics called ``name`` (a key of :data:`ROTARY_KINEMATICS`).

    Args:
        name: ``"xyzac-trunnion"`` or ``"xyzbc-trunnion"``.
        pivot: tilt-axis rot-point in machine coordinates [m], shape (3,).
        c_offset: C axis relative to the tilt axis [m], shape (3,).
    """
    if name not in ROTARY_KINEMATICS:
        raise InputError("rotary", f"unknown rotary kinematics {name!r}; choose one of "
                         f"{sorted(ROTARY_KINEMATICS)} or 'none'")
    return TrunnionKinematics(name, ROTARY_KINEMATICS[name], _vec3("pivot", pivot),
                              _vec3("c_offset", c_offset))
