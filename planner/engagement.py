"""Engagement of the tool along a path: radial depth a_e, axial depth a_p, up/down/slot, cutting frame.

Three sources (docs/model.md §8):

* :func:`fixed_engagement` — per operation from the job file: the same a_e, a_p and mode on every
  cutting sample; only the radial direction follows the path.
* :func:`zmap_engagement` — from a prismatic :class:`Stock` cut down by the path on a height map
  (3-axis, :mod:`planner.zmap`): right on helices, ramps and pockets; the job's default with a stock.
* :func:`stock_engagement` — from the same stock, 2.5-D (vertical tool, cleared-area polygons per Z
  level, :mod:`planner.stock`): exact on constant-height levels, wrong where the material left
  varies within a level (a helix smaller than the tool, a ramp across earlier cuts).

All return an :class:`Engagement` per path sample. The record and its cutting frame (X_o = a × f,
the milling side) are defined in :mod:`planner.cutting_frame`; the public names of the three
modules are re-exported here.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from models.cutting import MILLING_MODES
from models.errors import InputError
from planner.cutting_frame import (
    AIR,
    AXIS_NORM_MIN,
    PLUNGE_TOL,
    Engagement,
    as_vectors,
    cutting_mask,
    radial_directions,
    unit_axes,
)
from planner.stock import (
    ANGULAR_RESOLUTION,
    LEVEL_TOL,
    RAMP_LEVEL_TOL,
    VERTICAL_AXIS_TOL,
    Stock,
    below_bottom_warnings,
    stock_engagement,
)
from planner.zmap import CELL_FRACTION, SLIVER_TOL, default_cell, zmap_engagement

__all__ = [
    "AIR",
    "ANGULAR_RESOLUTION",
    "CELL_FRACTION",
    "Engagement",
    "LEVEL_TOL",
    "PLUNGE_TOL",
    "RAMP_LEVEL_TOL",
    "SLIVER_TOL",
    "Stock",
    "VERTICAL_AXIS_TOL",
    "below_bottom_warnings",
    "default_cell",
    "fixed_engagement",
    "stock_engagement",
    "zmap_engagement",
]

_SLOT = MILLING_MODES["slot"]

_DIAMETER_RTOL = 1e-6
"""Relative tolerance on a_e against the tool diameter 2R [-]: the same as
:class:`models.analysis.Cut` uses for a slot, so a job's a_e that passes here passes there."""


def _per_sample(value: Any, n: int, name: str) -> np.ndarray:
    arr = np.asarray(value, dtype=float)
    if arr.ndim > 1 or (arr.ndim == 1 and arr.shape != (n,)):
        raise InputError(name, f"must be a number or shape ({n},), got shape {arr.shape}")
    return np.broadcast_to(arr, (n,)).copy()


def _mode_codes(mode: Any, n: int) -> np.ndarray:
    try:
        items = [mode] * n if isinstance(mode, (str, int, np.integer)) else list(mode)
    except TypeError as e:
        raise InputError("mode", f"give 'up', 'down', 'slot' or a code, got {mode!r}") from e
    if len(items) != n:
        raise InputError("mode", f"give one mode or {n}, got {len(items)}")
    codes = np.empty(n, dtype=int)
    for i, m in enumerate(items):
        if isinstance(m, str) and m in MILLING_MODES:
            codes[i] = MILLING_MODES[m]
        elif isinstance(m, (int, np.integer)) and int(m) in MILLING_MODES.values():
            codes[i] = int(m)
        else:
            raise InputError("mode", f"sample {i}: {m!r} is not one of {sorted(MILLING_MODES)} "
                             f"(codes {MILLING_MODES})")
    return codes


# --------------------------------------------------------------------------------------------------
# Fixed engagement (job file)
# --------------------------------------------------------------------------------------------------


def fixed_engagement(n: int, a_e: Any, a_p: Any, mode: Any, feed_dirs: Any, tool_axis: Any,
                     cutting: Any, tool_radius: float | None = None) -> Engagement:
    """Engagement given per operation: the same a_e, a_p and mode on every cutting sample.

    Args:
        n: number of samples.
        a_e: radial depth [m], a number or shape (n,); > 0 (2R for a slot).
        a_p: axial depth [m], a number or shape (n,); > 0.
        mode: ``"up"``, ``"down"``, ``"slot"`` or a code of ``MILLING_MODES``; one, or one per sample.
        feed_dirs: feed direction per sample (workpiece frame), shape (n, 3); normalised here.
        tool_axis: tool axis from the tip towards the spindle, shape (3,) or (n, 3); normalised here.
        cutting: True on feed moves, shape (n,); other samples are AIR.
        tool_radius: R [m]; when given, a_e is checked against 2R (a slot must have a_e = 2R) and the
            engaged angle is computed, else it is NaN on cutting samples other than slots (π).

    The radial direction is X_o = a × f / |a × f| for every mode (:mod:`planner.cutting_frame`); a
    cutting sample whose feed runs along the tool axis is a plunge and reported as AIR with
    ``plunge`` set.

    Raises:
        InputError: on shapes, non-positive depths, unknown modes, a zero feed direction on a cutting
            sample, or (with ``tool_radius``) a_e outside (0, 2R].
    """
    if int(n) != n or n < 0:
        raise InputError("n", f"must be a non-negative integer, got {n!r}")
    n = int(n)
    cut = cutting_mask(cutting, n)
    ae = _per_sample(a_e, n, "a_e")
    ap = _per_sample(a_p, n, "a_p")
    codes = _mode_codes(mode, n)
    axes = unit_axes(tool_axis, n)
    feed = as_vectors(feed_dirs, n, "feed_dirs")
    fnorm = np.linalg.norm(feed, axis=1)
    bad = np.flatnonzero(cut & (fnorm < AXIS_NORM_MIN))
    if bad.size:
        raise InputError("feed_dirs", f"sample {bad[0]} cuts but has no feed direction (zero vector)")
    bad = np.flatnonzero(cut & ~((ae > 0) & np.isfinite(ae) & (ap > 0) & np.isfinite(ap)))
    if bad.size:
        raise InputError("engagement", f"sample {bad[0]}: a_e ({ae[bad[0]]:g} m) and a_p "
                         f"({ap[bad[0]]:g} m) must be positive")
    angle = np.where(codes == _SLOT, math.pi, np.nan)
    if tool_radius is not None:
        if not (math.isfinite(tool_radius) and tool_radius > 0):
            raise InputError("tool_radius", f"must be positive [m], got {tool_radius:g}")
        two_r = 2.0 * tool_radius
        bad = np.flatnonzero(cut & (ae > two_r * (1 + _DIAMETER_RTOL)))
        if bad.size:
            raise InputError("a_e", f"sample {bad[0]}: {ae[bad[0]] * 1e3:.3f} mm exceeds the tool "
                             f"diameter {two_r * 1e3:.3f} mm")
        off = ~np.isclose(ae, two_r, rtol=_DIAMETER_RTOL, atol=0.0)
        bad = np.flatnonzero(cut & (codes == _SLOT) & off)
        if bad.size:
            raise InputError("a_e", f"a slot engages the full diameter ({two_r * 1e3:.3f} mm), got "
                             f"{ae[bad[0]] * 1e3:.3f} mm at sample {bad[0]}")
        angle = np.where(codes == _SLOT, math.pi,
                         np.arccos(np.clip(1.0 - ae / tool_radius, -1.0, 1.0)))
    unit_feed = np.zeros_like(feed)
    ok = fnorm >= AXIS_NORM_MIN
    unit_feed[ok] = feed[ok] / fnorm[ok, None]
    radial, plunge = radial_directions(axes, unit_feed)
    plunge &= cut
    active = cut & ~plunge
    return Engagement(
        a_e=np.where(active, ae, 0.0),
        a_p=np.where(active, ap, 0.0),
        mode=np.where(active, codes, AIR),
        radial_dir=np.where(active[:, None], radial, 0.0),
        engaged_angle=np.where(active, angle, 0.0),
        feed_dir=np.where(active[:, None], unit_feed, 0.0),
        plunge=plunge,
    )

