"""Modal state of the G-code machine while a program is read (private; see :mod:`robot_io.gcode`).

Program coordinates, SI. The planes table keys are the code keys of G17/G18/G19 (170/180/190).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from robot_io.gcode import _words as W

__all__ = ["DEG", "PLANES", "UNIT_AXES", "ModalState"]

DEG = math.pi / 180.0   #: one degree [rad]
#: plane → (p axis, q axis, normal axis, centre offset letters (p, q), word along the normal)
PLANES = {
    170: (0, 1, 2, ("I", "J"), "K"),
    180: (2, 0, 1, ("K", "I"), "J"),
    190: (1, 2, 0, ("J", "K"), "I"),
}
UNIT_AXES = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))


@dataclass
class ModalState:
    """What the machine remembers between blocks (program coordinates, SI).

    ``pos`` entries and ``rot`` angles [rad] are ``None`` while unknown; ``motion`` and ``plane``
    are code keys (G1 = 10, G17 = 170); ``scale`` is metres per program unit; ``feed_raw`` is the
    F word as written (converted with the units in force when a move runs).
    """

    pos: list[float | None] = field(default_factory=lambda: [None, None, None])
    rot: dict[str, float | None] = field(
        default_factory=lambda: {"A": None, "B": None, "C": None})
    motion: int | None = None
    plane: int = 170
    absolute: bool = True
    arc_absolute: bool = False
    scale: float = W.MM
    inverse_time: bool = False
    feed_raw: float | None = None
    spindle_s: float | None = None
    spindle_on: bool = False
    tool: int | None = None
    tcp: bool = False
    retract_r_plane: bool = False
    cycle_r: float | None = None   # sticky canned-cycle R and Z (absolute, program frame) [m]
    cycle_z: float | None = None
