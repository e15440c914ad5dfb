"""The plan's per-sample table: :class:`PlanSamples` (SI) and its file ``samples.npz`` (the units in
the array names), with the unit conversions of the plan's file edge. The file's ``section`` is the
section's number, from 1 (plan.json's ``index``); in memory it is the position in the plan's
sections, from 0."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["NUMBER", "SAMPLE_ARRAYS", "SAMPLE_EXTRA", "PlanSamples", "from_file_unit", "to_file_unit"]

#: Arrays every ``samples.npz`` holds: file name → trailing shape.
SAMPLE_ARRAYS: dict[str, tuple[int, ...]] = {
    "s_m": (), "q_rad": (6,), "position_wp_m": (3,), "abc_wp_deg": (3,), "tool_axis_wp": (3,),
    "section": (), "kind": (), "arc": (), "move": (), "line": (), "source_file": (), "feed_mm_s": (),
    "speed_mm_s": (), "time_s": (), "force_N": (), "deflection_mm": (), "deflection_wp_m": (3,),
    "deflection_normal_mm": (), "gamma_deg": (), "margin_N_per_m": (), "power_kW": (),
    "a_e_m": (), "a_p_m": (), "mode": (),
}
#: Arrays a plan made by ``cctmill plan`` also holds (synthetic plans may not).
SAMPLE_EXTRA: dict[str, tuple[int, ...]] = {
    "ceiling_mm_s": (), "robot_limited": (), "bound_mm_s": (), "joint_speed_rad_s": (6,),
}
#: A conversion of :func:`to_file_unit`: a position from 0 in memory is a number from 1 in the file.
NUMBER = "number"
#: file name → (attribute, SI → file conversion); ``None`` copies, ``"deg"`` is rad → deg,
#: :data:`NUMBER` a position from 0 → a number from 1.
_SAMPLE_UNITS: dict[str, tuple[str, float | str | None]] = {
    "s_m": ("s", None), "q_rad": ("q", None), "position_wp_m": ("position_wp", None),
    "abc_wp_deg": ("abc_wp", "deg"), "tool_axis_wp": ("tool_axis_wp", None),
    "section": ("section", NUMBER), "kind": ("kind", None), "arc": ("arc", None),
    "move": ("move", None), "line": ("line", None), "source_file": ("source_file", None),
    "feed_mm_s": ("feed", 1e3), "speed_mm_s": ("speed", 1e3), "time_s": ("time", None),
    "force_N": ("force", None), "deflection_mm": ("deflection", 1e3),
    "deflection_wp_m": ("deflection_wp", None), "deflection_normal_mm": ("deflection_normal", 1e3),
    "gamma_deg": ("gamma", "deg"), "margin_N_per_m": ("margin", None), "power_kW": ("power", 1e-3),
    "a_e_m": ("a_e", None), "a_p_m": ("a_p", None), "mode": ("mode", None),
    "ceiling_mm_s": ("ceiling", 1e3), "robot_limited": ("robot_limited", None),
    "bound_mm_s": ("bound", 1e3), "joint_speed_rad_s": ("joint_speed", None),
}


def to_file_unit(v: Any, unit: float | str | None) -> Any:
    """An SI value (or array) in a file's unit: ``unit`` the factor (e.g. 1e3 for m → mm), ``"deg"``
    for rad → deg, :data:`NUMBER` for a position from 0 → a number from 1, None to copy; None stays
    None."""
    if v is None or unit is None:
        return v
    if unit == NUMBER:
        return v + 1
    if unit == "deg":
        return np.degrees(v)
    return v * unit


def from_file_unit(v: Any, unit: float | str | None) -> Any:
    """The inverse of :func:`to_file_unit`."""
    if v is None or unit is None:
        return v
    if unit == NUMBER:
        return v - 1
    if unit == "deg":
        return np.radians(v)
    return v / unit


@dataclass(frozen=True)
class PlanSamples:
    """Every path sample of the plan, SI; arrays of shape (n,) unless noted.

    Attributes:
        s: arc length [m]; q: joint angles [rad], (n, 6); position_wp: TCP in ``$BASE`` [m],
            (n, 3); abc_wp: TCP orientation in ``$BASE`` as KUKA A, B, C [rad], (n, 3);
            tool_axis_wp: unit tool axis in ``$BASE``, (n, 3).
        section (position in :attr:`Plan.sections`, from 0; the file's ``section`` numbers from 1),
            kind (0 cut, 1 air, 2 rapid), arc (bool), move, line, source_file (index into
            :attr:`Plan.files`): where each sample comes from.
        feed: planned feed [m/s]; speed: timed path speed [m/s]; time: timed clock [s].
        force [N]; deflection: ‖δ‖ [m]; deflection_wp: δ in ``$BASE`` axes [m], (n, 3);
        deflection_normal [m]; gamma [rad]; margin [N/m]; power [W] (NaN where not cutting).
        a_e, a_p: engagement [m]; mode: milling mode code.
        ceiling [m/s], robot_limited (bool), bound [m/s], joint_speed [rad/s] (n, 6): optional.
    """

    s: np.ndarray
    q: np.ndarray
    position_wp: np.ndarray
    abc_wp: np.ndarray
    tool_axis_wp: np.ndarray
    section: np.ndarray
    kind: np.ndarray
    arc: np.ndarray
    move: np.ndarray
    line: np.ndarray
    source_file: np.ndarray
    feed: np.ndarray
    speed: np.ndarray
    time: np.ndarray
    force: np.ndarray
    deflection: np.ndarray
    deflection_wp: np.ndarray
    deflection_normal: np.ndarray
    gamma: np.ndarray
    margin: np.ndarray
    power: np.ndarray
    a_e: np.ndarray
    a_p: np.ndarray
    mode: np.ndarray
    ceiling: np.ndarray | None = None
    robot_limited: np.ndarray | None = None
    bound: np.ndarray | None = None
    joint_speed: np.ndarray | None = None

    def __len__(self) -> int:
        return int(self.s.shape[0])

    def as_arrays(self) -> dict[str, np.ndarray]:
        """The ``samples.npz`` arrays (units in the names)."""
        out = {}
        for name, (attr, unit) in _SAMPLE_UNITS.items():
            v = getattr(self, attr)
            if v is not None:
                out[name] = to_file_unit(v, unit)
        return out

    @classmethod
    def from_arrays(cls, arrays: dict[str, np.ndarray]) -> PlanSamples:
        kw = {attr: from_file_unit(arrays[name], unit) for name, (attr, unit) in _SAMPLE_UNITS.items()
              if name in arrays}
        return cls(**kw)
