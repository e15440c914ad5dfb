"""The cutting frame along a path and the per-sample :class:`Engagement` record given in it, shared
by the engagement sources of :mod:`planner.engagement`, with the checks of their path inputs and
the feed directions the stock models measure the engaged arc about (:func:`feed_directions`).

**Cutting frame and milling side** (docs/model.md §4). Z_o is the feed direction f, X_o the radial direction
(the cutting edge at immersion φ = 0), Y_o = Z_o × X_o. The edge at φ points along
n(φ) = cos φ X_o + sin φ Z_o and moves along t(φ) = −sin φ X_o + cos φ Z_o = (−Y_o) × n(φ), so the
tool turns about −Y_o. A right-hand cutter turning M03 turns clockwise seen from the spindle looking
towards the tip, i.e. looking along −a where a is the tool axis from the tip towards the spindle; a
rotation that looks clockwise to a viewer looking along v is a positive rotation about v, so the tool
turns about −a. Hence, for every mode:

    Y_o = a (tip → spindle),    X_o = Y_o × Z_o = a × f / |a × f|,

X_o is the left normal of the feed seen from the spindle (for a vertical tool seen from above: the
feed turned 90° counter-clockwise). Up (conventional) milling has the material on +X_o, i.e. on the
left of the feed seen from the spindle; down (climb) milling on −X_o, the right; a slot on both.
Check by the edge velocity: feed +x, a = +z, so X_o = +y and ω = −Ω z. The edge passing the +y side
moves along ω × (R y) = +ΩR x, parallel to the feed and tangent to the surface the previous tooth left:
with the material on +y the tooth enters there with zero chip, which then grows (h = c sin φ) — up
milling. This is the shop rule "with M03, G41 (tool left of the material) is climb milling".
For a ramp (f not perpendicular to a) Y_o = a − (a·f) f, normalised: the tool axis' part normal to
the feed. A feed along the tool axis (a plunge) has no X_o; such samples are flagged ``plunge`` and
left out of the side-milling model (mode −1).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from models.errors import InputError

__all__ = [
    "AIR",
    "AXIS_NORM_MIN",
    "Engagement",
    "PLUNGE_TOL",
    "as_vectors",
    "cutting_mask",
    "feed_directions",
    "radial_directions",
    "unit_axes",
]

AIR = -1
"""Mode code of a sample that does not cut (rapid, air, plunge); the others are MILLING_MODES."""

PLUNGE_TOL = 1e-6
"""|a × f| (the sine of the angle between feed and tool axis) below which a feed runs along the tool
axis [-]: X_o = a × f has no direction left, the sample is a plunge. Purely numerical."""

AXIS_NORM_MIN = 1e-12
"""Smallest norm of a given tool axis or feed direction that can be normalised [-]."""

_SMOOTH_TURN = math.radians(15.0)
"""Consecutive path steps turning by less than this are a sampled curve [rad], and the feed
direction at the sample between them is their bisector; larger turns are corners of the program,
where the arriving step's direction is kept. A circle of radius r sampled to a chord tolerance ε
turns by 2 √(2ε/r) per step: 7° for ε = 10 µm, r = 5 mm."""

_MIN_XY_STEP = 1e-8
"""A path step shorter than this in XY has no horizontal feed direction [m] (a repeated point, or a
plunge when z changes by more than the level tolerance); far below any sampling step."""


@dataclass(frozen=True)
class Engagement:
    """Engagement per path sample. SI, workpiece frame (unless the caller rotated it).

    Attributes:
        a_e: radial depth of cut [m], shape (n,); 0 where not cutting. 2R for a slot.
        a_p: axial depth of cut [m], shape (n,); 0 where not cutting.
        mode: milling mode code, shape (n,), int: :data:`models.cutting.MILLING_MODES` (0 up, 1 down,
            2 slot) or :data:`AIR` (−1) where the tool does not cut (rapid, above or outside the
            stock, in cleared space, plunge).
        radial_dir: X_o = a × f / |a × f|, unit, shape (n, 3); zeros where ``mode == AIR``. The
            material lies on +X_o for up milling, on −X_o for down milling (module docstring), and
            Y_o = Z_o × X_o is the tool axis from the tip towards the spindle (its part normal to
            the feed on a ramp).
        engaged_angle: φ_ex − φ_st, the angular extent of the engaged arc [rad], shape (n,); 0 where
            not cutting, π for a slot. NaN on up/down samples of a
            :func:`~planner.engagement.fixed_engagement` given no tool radius.
        feed_dir: Z_o, the unit feed direction the radial direction was built from, shape (n, 3),
            zeros where ``mode == AIR``; ``None`` if the producer did not record it. Pass it with
            ``radial_dir`` to :class:`models.analysis.Cut` — the two are orthogonal by construction.
            :func:`~planner.stock.stock_engagement` and :func:`~planner.zmap.zmap_engagement`
            give the direction of the step arriving at the sample, as ``PathSamples.feed_dir``
            does (and measure the engaged arc about the path tangent).
        plunge: True on cutting samples whose feed runs along the tool axis (no X_o; reported as
            AIR), shape (n,); ``None`` if not recorded.
        warnings: what the producer found questionable but not wrong enough to stop, one line
            each, naming the sample and its toolpath ``file:line`` (a tool below the stock bottom);
            the planner shows them with the plan.
    """

    a_e: np.ndarray
    a_p: np.ndarray
    mode: np.ndarray
    radial_dir: np.ndarray
    engaged_angle: np.ndarray
    feed_dir: np.ndarray | None = None
    plunge: np.ndarray | None = None
    warnings: tuple[str, ...] = ()

    def __len__(self) -> int:
        return int(np.shape(self.a_e)[0])

    @property
    def cutting(self) -> np.ndarray:
        """True where the tool cuts (``mode != AIR``), shape (n,)."""
        return np.asarray(self.mode) != AIR


# --------------------------------------------------------------------------------------------------
# Input checks shared by both sources
# --------------------------------------------------------------------------------------------------


def as_vectors(value: Any, n: int, name: str) -> np.ndarray:
    """A (3,) or (n, 3) array of finite vectors as (n, 3) float."""
    arr = np.asarray(value, dtype=float)
    if arr.shape == (3,):
        arr = np.broadcast_to(arr, (n, 3))
    if arr.shape != (n, 3):
        raise InputError(name, f"must have shape (3,) or ({n}, 3), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise InputError(name, "contains NaN or infinite values")
    return arr


def unit_axes(tool_axis: Any, n: int) -> np.ndarray:
    """Tool axes (tip → spindle), normalised, shape (n, 3)."""
    axes = as_vectors(tool_axis, n, "tool_axis")
    norm = np.linalg.norm(axes, axis=1)
    bad = np.flatnonzero(norm < AXIS_NORM_MIN)
    if bad.size:
        raise InputError("tool_axis", f"sample {bad[0]}: zero vector; give the unit axis from the "
                         f"tool tip towards the spindle")
    return axes / norm[:, None]


def cutting_mask(cutting: Any, n: int) -> np.ndarray:
    """The per-sample cutting flags (booleans, or 0/1) as a bool array, shape (n,)."""
    mask = np.asarray(cutting)
    if mask.shape != (n,):
        raise InputError("cutting", f"must have shape ({n},), got {mask.shape}")
    if mask.dtype != bool:
        if not np.all(np.isin(mask, (0, 1))):
            raise InputError("cutting", "must be booleans (True on feed moves)")
        mask = mask.astype(bool)
    return mask


def radial_directions(axes: np.ndarray, feed: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """X_o = a × f / |a × f| for unit a, f, shape (n, 3), and the plunge mask |a × f| < PLUNGE_TOL."""
    cross = np.cross(axes, feed)
    norm = np.linalg.norm(cross, axis=1)
    plunge = norm < PLUNGE_TOL
    radial = np.zeros_like(cross)
    radial[~plunge] = cross[~plunge] / norm[~plunge, None]
    return radial, plunge



def feed_directions(points: np.ndarray, cut: np.ndarray, z_tol: float
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-sample feed directions of a vertical-tool path, for the stock models.

    Args:
        points: tool-tip positions [m], shape (n, 3), in path order.
        cut: True where the step arriving at the sample cuts, shape (n,).
        z_tol: a vertical arriving step that changes z by more than this is a plunge [m].

    Returns:
        feed: unit 3-D direction of the step arriving at each sample, shape (n, 3) (zeros where
            none) — the same convention as ``PathSamples.feed_dir``, so that X_o built from it is
            orthogonal to the feed the caller uses.
        tangent_xy: unit horizontal direction at each sample, for measuring the engaged arc, shape
            (n, 2) (zeros where none).
        plunge: cutting samples reached by a vertical step (no horizontal direction), shape (n,).

    ``tangent_xy`` is the arriving step's direction, or where the next step also cuts and turns by
    less than :data:`_SMOOTH_TURN` (a sampled curve) the bisector of both steps: the tangent at the
    sample of a circular arc sampled in equal steps. The arriving chord lags it by half a step's
    turn, and would turn the measured arc by as much. A cutting sample whose arriving step has no XY
    length takes the directions of the nearest earlier sample of its cutting run that has one, else
    of the nearest later one (repeated points, the first sample of the path); a vertical arriving
    step that changes z by more than ``z_tol`` is a plunge, and so is every sample of a run without
    horizontal motion (drilling).
    """
    n = points.shape[0]
    step = np.zeros_like(points)
    step[1:] = points[1:] - points[:-1]
    xy_len = np.hypot(step[:, 0], step[:, 1])
    has_dir = cut & (xy_len >= _MIN_XY_STEP)
    plunge = cut & ~has_dir & (np.abs(step[:, 2]) > z_tol)
    source = np.where(has_dir, np.arange(n), -1)
    run = np.cumsum(np.concatenate([[1], ~cut[1:] | ~cut[:-1]]))  # consecutive cutting samples
    fill = np.flatnonzero(cut & ~has_dir & ~plunge)
    if fill.size:
        prev = np.maximum.accumulate(source)
        nxt = np.minimum.accumulate(np.where(has_dir, np.arange(n), n)[::-1])[::-1]
        for i in fill:
            if prev[i] >= 0 and run[prev[i]] == run[i]:
                source[i] = prev[i]
            elif nxt[i] < n and run[nxt[i]] == run[i]:
                source[i] = nxt[i]
            else:
                plunge[i] = True
    unit = np.zeros_like(points)
    unit[has_dir] = step[has_dir] / np.linalg.norm(step[has_dir], axis=1)[:, None]
    xy = np.zeros((n, 2))
    xy[has_dir] = step[has_dir, :2] / xy_len[has_dir, None]
    tangent = xy.copy()
    xy_next = np.zeros_like(xy)
    xy_next[:-1] = xy[1:]
    smooth = has_dir & (np.einsum("ij,ij->i", xy, xy_next) > math.cos(_SMOOTH_TURN))
    bisector = xy[smooth] + xy_next[smooth]
    tangent[smooth] = bisector / np.linalg.norm(bisector, axis=1)[:, None]
    ok = source >= 0
    feed = np.zeros_like(points)
    feed_xy = np.zeros((n, 2))
    feed[ok] = unit[source[ok]]
    feed_xy[ok] = tangent[source[ok]]
    return feed, feed_xy, plunge
