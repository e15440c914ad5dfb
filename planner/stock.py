"""Engagement from a stock model (docs/model.md §8): a prismatic :class:`Stock` and the engagement the path
makes in it, 2.5-D (vertical tool, cleared-area polygons per Z level, :mod:`planner._cleared_area`),
so a_e, a_p and the mode change where the path enters, leaves or re-cuts material. The cutting
frame and the :class:`~planner.cutting_frame.Engagement` record are those of
:mod:`planner.cutting_frame`; :mod:`planner.engagement` re-exports everything public here.

**Arcs, a_e and modes from geometry.** With the engaged arc [φ_st, φ_ex] of the tool circle
(φ ∈ [0, π], the front half), a_e is its width across the feed, a_e = R (cos φ_st − cos φ_ex):
R (1 − cos φ_ex) for up milling (φ_st = 0), R (1 + cos φ_st) for down milling (φ_ex = π), 2R for a slot.
An arc touching neither side (a corner, entering a wall head-on) is reported as up milling if its
middle lies before π/2 and down milling otherwise, with that same width; an arc with gaps (crossing an
earlier slot) is reported by its envelope. The SPEC force model knows only arcs anchored at 0 or π.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import shapely
from shapely.geometry import Polygon

from models.cutting import MILLING_MODES
from models.errors import InputError
from planner._cleared_area import ClearedArea, assign_levels
from planner.cutting_frame import (
    AIR,
    Engagement,
    cutting_mask,
    feed_directions,
    radial_directions,
    unit_axes,
)

__all__ = [
    "ANGULAR_RESOLUTION",
    "LEVEL_TOL",
    "RAMP_LEVEL_TOL",
    "Stock",
    "VERTICAL_AXIS_TOL",
    "below_bottom_warnings",
    "stock_engagement",
    "stock_inputs",
]

_UP, _DOWN, _SLOT = MILLING_MODES["up"], MILLING_MODES["down"], MILLING_MODES["slot"]

LEVEL_TOL = 1e-5
"""Tip heights within this of the lowest height of a Z level belong to that level [m]. CAM programs
write z to 1 µm and unit conversion adds ~1e-12 m; 10 µm absorbs both and a controller's rounding,
yet lies far below any real level step (≥ 0.1 mm)."""

RAMP_LEVEL_TOL = 1e-4
"""Ramp (and helix) tip heights are grouped in bands this tall [m]: a ramp would otherwise make one
level per sample. Within 0.1 mm of a ramp, a_p and the cleared area are resolved to this height."""

ANGULAR_RESOLUTION = math.radians(2.0)
"""Spacing of the probes on the tool circle between φ = 0 and π [rad] (both always probed, so a side
cut is found however thin). An arc that touches neither side is found if longer than this; the ends
of every arc are then refined by bisection."""

_SIDE_PROBE = 0.01
"""The side probes sit this far inside the front half, at φ = 0.01 and π − 0.01 [rad]. Exactly at
φ = 0, π the probe is tangent to the band swept by any earlier pass along the same line (a retraced
path, the pass above at the previous level) and its answer would be rounding. A side cut thinner
than R (1 − cos 0.01) = 5e-5 R is missed — below :data:`_MIN_A_E` for any R < 0.2 m."""

_BISECTION_STEPS = 10
"""Bisection steps refining each open end of the engaged arc [-]: the bracket shrinks from one probe
spacing to 1/1024 of it (3.4e-5 rad at 2°), so a_e is resolved to ≈ 2e-5 R (0.3 µm at R = 12.7 mm),
below the error of the swept-area polygons (≤ 3e-4 R, ``planner._cleared_area.QUAD_SEGS``)."""

_AP_INSET = 2e-3
"""The a_p points lie this fraction of R inside the tool circle [-]. A wall left by an earlier level
along the same path (every level of a pocket retraces it, a helix its previous turn) touches the
tool circle exactly; read on the circle its height would be rounding of the inscribed swept-area
polygons (≤ 3e-4 R inside the true circle). Material narrower than 2e-3 R above the level is not
counted in a_p."""

_AP_POINTS = 9
"""Engaged probes, spread along the arc, at which the height of the remaining material is read for
a_p [-]: a wall left by an earlier level shows at all of them; 9 catch a step across the arc to
within 1/8 of its length."""

VERTICAL_AXIS_TOL = math.radians(0.1)
"""Largest angle between the tool axis and +Z that 2.5-D engagement accepts [rad]. At 0.1° the
tool's flank leans 17 µm over a 10 mm axial depth — below the model's own accuracy; beyond that the
tool is tilted (5-axis) and the swept area is no longer a vertical extrusion."""

_BATCH = 48
"""Samples whose swept areas are merged into the level polygons at once [-]. Within a batch, earlier
samples of the batch are tested analytically (exact stadiums), so the batch size changes only the
speed, never the result beyond the polygon error."""

_MIN_A_E = 1e-5
"""Engagements narrower than this across the feed are reported as AIR [m]: below an end mill's edge
radius the tool rubs rather than cuts, and it covers the rounding of the swept-area polygons (a
pass that retraces an earlier one exactly would otherwise show a sliver of a few µm)."""

_MIN_A_P = LEVEL_TOL
"""Engagements shallower than this along the tool axis are reported as AIR [m], the level
tolerance: thinner material is rounding of the levels. It also catches the one case where the
2.5-D rule alone would give a_p ≤ 0: a tool below the stock bottom whose arc meets only what
earlier levels below the bottom "cleared" — empty space under the stock, not material."""

_DIAMETER_ROUNDING = 1e-9
"""a_e = R (cos φ_st − cos φ_ex) can exceed 2R only by rounding: by more than this fraction of 2R
[-] it is a bug in the arc, and raises; within it a_e is clipped to 2R."""

_MAX_BOTTOM_WARNINGS = 10
"""At most this many runs below the stock bottom are named one by one [-]; one line counts the rest."""


def below_bottom_warnings(points: np.ndarray, cutting: np.ndarray, stock: Stock, radius: float,
                          where: Callable[[int], str] | None = None, tol: float = LEVEL_TOL
                          ) -> tuple[str, ...]:
    """One warning per run of consecutive cutting samples whose tool tip lies below the stock bottom
    (by more than ``tol`` [m]) while the tool overlaps the outline: the program cuts deeper than the
    stock is thick (a through cut, or a wrong ``z_bottom_mm``). Names the run's deepest sample, its
    toolpath ``file:line`` (``where(i)``) and the depth, in mm.

    Args:
        points: tool-tip positions [m], shape (n, 3); cutting: shape (n,) bool; stock: the stock;
        radius: tool radius R [m]; where: ``file:line`` of a sample (``PathSamples.where``).
    """
    z_bottom = float(stock.z_bottom)
    low = cutting & (points[:, 2] < z_bottom - tol)
    idx = np.flatnonzero(low)
    if idx.size:
        near = shapely.distance(stock.polygon, shapely.points(points[idx, :2])) < radius
        low[idx[~near]] = False
        idx = idx[near]
    if not idx.size:
        return ()
    starts = idx[np.concatenate([[True], np.diff(idx) > 1])]
    stops = idx[np.concatenate([np.diff(idx) > 1, [True]])]
    out = []
    for a, b in zip(starts[:_MAX_BOTTOM_WARNINGS], stops[:_MAX_BOTTOM_WARNINGS], strict=True):
        i = a + int(np.argmin(points[a:b + 1, 2]))
        place = f" ({where(i)})" if where is not None else ""
        span = f"samples {a}–{b}" if b > a else f"sample {a}"
        out.append(f"sample {i}{place}: the tool tip is {(z_bottom - points[i, 2]) * 1e3:.3f} mm "
                   f"below the stock bottom (z_bottom_mm = {z_bottom * 1e3:g}) on {span}; a_p "
                   f"counts from the bottom — check [engagement.stock] z_bottom_mm or the program")
    if starts.size > _MAX_BOTTOM_WARNINGS:
        out.append(f"… and {starts.size - _MAX_BOTTOM_WARNINGS} more runs of samples below the stock "
                   f"bottom ({int(low.sum())} samples in all)")
    return tuple(out)


@dataclass(frozen=True)
class Stock:
    """A prismatic stock: a 2-D outline in the workpiece XY plane extruded from z_bottom to z_top.

    Attributes:
        outline: the outline [m]: a sequence of (x, y) vertices (closed implicitly), or a shapely
            ``Polygon`` (holes allowed: pre-cut pockets). Stored as given for a Polygon, as a tuple of
            float pairs otherwise.
        z_bottom: bottom of the stock [m].
        z_top: top of the stock [m], > z_bottom.
    """

    outline: Sequence[tuple[float, float]] | Polygon
    z_bottom: float
    z_top: float
    _polygon: Polygon = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        try:
            object.__setattr__(self, "z_bottom", float(self.z_bottom))
            object.__setattr__(self, "z_top", float(self.z_top))
        except (TypeError, ValueError) as e:
            raise InputError("stock", "z_bottom and z_top must be numbers [m]") from e
        if not (math.isfinite(self.z_bottom) and math.isfinite(self.z_top)):
            raise InputError("stock", f"z_bottom and z_top must be finite, got {self.z_bottom:g}, "
                             f"{self.z_top:g}")
        if not self.z_top > self.z_bottom:
            raise InputError("stock", f"z_top ({self.z_top:g} m) must lie above z_bottom "
                             f"({self.z_bottom:g} m)")
        if isinstance(self.outline, Polygon):
            poly = self.outline
        else:
            try:
                pts = tuple((float(x), float(y)) for x, y in self.outline)
            except (TypeError, ValueError) as e:
                raise InputError("stock outline", "must be a sequence of (x, y) pairs [m]") from e
            if len(pts) < 3 or not np.all(np.isfinite(pts)):
                raise InputError("stock outline", f"needs at least 3 finite (x, y) vertices, got "
                                 f"{len(pts)}")
            object.__setattr__(self, "outline", pts)
            poly = Polygon(pts)
        if poly.is_empty or not poly.convex_hull.area > 0.0:
            raise InputError("stock outline", "encloses no area (degenerate: repeated or collinear "
                             "vertices); give the stock's corners in order")
        if not poly.is_valid:
            raise InputError("stock outline", f"is not a simple polygon "
                             f"({shapely.is_valid_reason(poly)}); list the corners in order around "
                             f"the outline without crossing")
        shapely.prepare(poly)
        object.__setattr__(self, "_polygon", poly)

    @classmethod
    def box(cls, xmin: float, ymin: float, xmax: float, ymax: float, z_bottom: float,
            z_top: float) -> Stock:
        """A rectangular block [m], axis-aligned in the workpiece frame."""
        if not (xmax > xmin and ymax > ymin):
            raise InputError("stock", f"box needs xmax > xmin and ymax > ymin, got x {xmin:g}..{xmax:g}"
                             f", y {ymin:g}..{ymax:g} m")
        return cls([(xmin, ymin), (xmax, ymin), (xmax, ymax), (xmin, ymax)], z_bottom, z_top)

    @property
    def polygon(self) -> Polygon:
        """The outline as a (prepared) shapely Polygon [m]."""
        return self._polygon


# --------------------------------------------------------------------------------------------------
# Stock engagement (2.5-D)
# --------------------------------------------------------------------------------------------------


def stock_engagement(points: Any, tool_axis: Any, cutting: Any, tool_radius: float, stock: Stock,
                     z_tol: float = LEVEL_TOL, angular_resolution: float = ANGULAR_RESOLUTION,
                     where: Callable[[int], str] | None = None) -> Engagement:
    """Engagement from a prismatic stock and the path (2.5-D: vertical tool, cleared area per Z level).

    Args:
        points: tool-tip positions in the workpiece frame [m], shape (n, 3), in path order.
            Any spacing works (each step's swept area is exact); the caller samples densely enough
            to see the engagement change.
        tool_axis: tool axis from the tip towards the spindle, shape (3,) or (n, 3); must be within
            :data:`VERTICAL_AXIS_TOL` of +Z on cutting samples.
        cutting: True where the sample ends a feed move, shape (n,): the step arriving at it cuts.
            Rapids neither cut nor clear.
        tool_radius: R [m] (flat end mill).
        stock: the stock.
        z_tol: tip heights within this of a level's lowest height form one Z level [m].
        angular_resolution: probe spacing on the tool circle [rad].
        where: ``file:line`` of sample i (``PathSamples.where``), for the messages and warnings.

    Algorithm. The step arriving at a cutting sample sweeps a stadium (the step buffered by R) and
    clears its column from the tip up to the stock top. Tip heights are grouped into Z levels
    (:data:`LEVEL_TOL`; ramps in bands of :data:`RAMP_LEVEL_TOL`); level k keeps the union of the
    stadiums swept at level k, merged every :data:`_BATCH` samples (the current batch is tested
    exactly, so each sample sees precisely the steps before it). For a sample with tip height z the
    material is the stock outline minus the stadiums of earlier samples at levels up to z + z_tol
    (z + RAMP_LEVEL_TOL on a ramp): thinner remains are no engagement. The front half of the tool
    circle (φ ∈ [0, π], φ from X_o towards the feed, X_o from the path tangent; the back half was cut
    by this pass) is probed just inside φ = 0 and π (:data:`_SIDE_PROBE`) and every
    ``angular_resolution`` between, exactly on the circle; the engaged probes give the arc
    [φ_st, φ_ex], whose open ends are refined by bisection, and a_e and the mode as in the module
    docstring. A side cut is found down to 5e-5 R; an arc inside (0, π) shorter than the resolution
    may be missed; engagements narrower than :data:`_MIN_A_E` are AIR.

    a_p rule. A point q has been cleared down to h(q), the lowest level covering it (the stock top if
    none); at engaged points h > z. a_p = max of h over up to :data:`_AP_POINTS` engaged probes
    spread along the arc (read :data:`_AP_INSET` inside the circle), minus the tip height (raised to
    z_bottom when the tool cuts through the stock): the tallest wall the flutes meet. In a pocket
    cut level by level this is the level step; on a helical ramp, the pitch — when the pitch spans
    levels; a helix whose radius is below R has no level structure, and its a_p at the bottom is
    the bore depth (use :func:`planner.zmap.zmap_engagement`).

    Guards: a_p < :data:`_MIN_A_P` (including a_p ≤ 0, an arc under the stock bottom) is AIR; a_e is
    clipped to 2R (rounding only; more raises); a tool below ``stock.z_bottom`` is a warning in
    ``Engagement.warnings`` (:func:`below_bottom_warnings`).

    Not modelled: cutting with the tool's bottom only (plunges are AIR with ``plunge`` set), the back
    half of the tool, tilted tools (use :func:`planner.engagement.fixed_engagement`).

    Raises:
        InputError: on shapes, a non-positive radius or tolerance, or a cutting sample whose tool
            axis is more than VERTICAL_AXIS_TOL from +Z.
    """
    pts, cut, axes = stock_inputs(points, tool_axis, cutting, tool_radius, stock, where,
                                  "2.5-D engagement from a stock")
    n = pts.shape[0]
    if not (math.isfinite(z_tol) and z_tol > 0):
        raise InputError("z_tol", f"must be positive [m], got {z_tol:g}")
    if not (0 < angular_resolution <= math.pi / 4):
        raise InputError("angular_resolution", f"must lie in (0, π/4] rad, got {angular_resolution:g}")

    radius = float(tool_radius)
    z_top, z_bottom = float(stock.z_top), float(stock.z_bottom)
    feed, feed_xy, plunge = feed_directions(pts, cut, z_tol)
    in_stock = cut & (pts[:, 2] < z_top - z_tol)
    dz = np.abs(np.diff(pts[:, 2], prepend=pts[0, 2]))
    level_z, lvl = assign_levels(pts[in_stock, 2], dz[in_stock] <= z_tol, z_tol,
                                 RAMP_LEVEL_TOL)
    level = np.full(n, -1)
    level[in_stock] = lvl
    # Clearing level: material less than the slack above the tip is no engagement (z_tol on flat
    # levels, RAMP_LEVEL_TOL on ramps, where the level bands are that coarse).
    slack = np.where(dz <= z_tol, z_tol, RAMP_LEVEL_TOL)
    clear_level = np.searchsorted(level_z, pts[:, 2] + slack, side="right") - 1
    probe = in_stock & ~plunge
    area = ClearedArea(level_z, radius)
    outline = stock.polygon
    theta = np.linspace(0.0, math.pi, math.ceil(math.pi / angular_resolution) + 1)
    theta[0], theta[-1] = _SIDE_PROBE, math.pi - _SIDE_PROBE
    last_bin = theta.size - 1
    prev = np.maximum(np.arange(n) - 1, 0)

    a_e = np.zeros(n)
    a_p = np.zeros(n)
    mode = np.full(n, AIR)
    angle = np.zeros(n)

    def circle(rows: np.ndarray, phi: np.ndarray, scale: float = 1.0) -> np.ndarray:
        """Points on the tool circles (radius ``scale`` R) of samples ``rows`` at angles φ
        (broadcast together), shape (..., 2)."""
        f = feed_xy[rows]
        x_o = np.stack([-f[..., 1], f[..., 0]], axis=-1)  # a × f with a = +Z
        return pts[rows, :2] + scale * radius * (np.cos(phi)[..., None] * x_o
                                                 + np.sin(phi)[..., None] * f)

    def material(rows: np.ndarray, phi: np.ndarray) -> np.ndarray:
        """Whether the circle points of samples ``rows`` at φ are in remaining material (same shape)."""
        q = circle(rows, phi).reshape(-1, 2)
        owner = np.broadcast_to(rows, phi.shape).ravel()
        out = np.zeros(q.shape[0], dtype=bool)
        inside = np.flatnonzero(shapely.contains_xy(outline, q[:, 0], q[:, 1]))
        out[inside] = ~area.cleared(q[inside], owner[inside], clear_level[owner[inside]])
        return out.reshape(phi.shape)

    for start in range(0, n, _BATCH):
        idx = np.arange(start, min(start + _BATCH, n))
        clears = idx[in_stock[idx]]
        area.stage(pts[prev[clears], :2], pts[clears, :2], level[clears], clears)
        rows = idx[probe[idx]]
        if rows.size:
            phi = np.broadcast_to(theta, (rows.size, theta.size))
            mat = material(rows[:, None], phi)
            hit = mat.any(axis=1)
            rows, mat = rows[hit], mat[hit]
        if rows.size:
            first = mat.argmax(axis=1)
            last = last_bin - mat[:, ::-1].argmax(axis=1)
            lo_open, hi_open = first > 0, last < last_bin
            phi_st = np.where(lo_open, theta[first], 0.0)
            phi_ex = np.where(hi_open, theta[last], math.pi)
            which = np.concatenate([np.flatnonzero(lo_open), np.flatnonzero(hi_open)])
            if which.size:
                air_side = np.concatenate([theta[first[lo_open] - 1], theta[last[hi_open] + 1]])
                ends = _bisect(material, rows[which], air_side, theta[np.concatenate(
                    [first[lo_open], last[hi_open]])])
                n_lo = int(lo_open.sum())
                phi_st[lo_open], phi_ex[hi_open] = ends[:n_lo], ends[n_lo:]
            slot = ~lo_open & ~hi_open
            up = np.where(lo_open == hi_open, phi_st + phi_ex <= math.pi, ~lo_open)
            mode[rows] = np.where(slot, _SLOT, np.where(up, _UP, _DOWN))
            a_e[rows] = np.where(slot, 2.0 * radius, radius * (np.cos(phi_st) - np.cos(phi_ex)))
            angle[rows] = phi_ex - phi_st
            # a_p: clearing heights at up to _AP_POINTS engaged probes spread along the arc, read
            # _AP_INSET inside the circle, where a wall the flank merely touches is already passed.
            count = mat.sum(axis=1)
            rank = np.rint(np.linspace(0.0, 1.0, _AP_POINTS)[None, :] * (count[:, None] - 1))
            pick = (np.cumsum(mat, axis=1)[:, None, :] > rank[:, :, None]).argmax(axis=2)
            q = circle(rows[:, None], theta[pick], 1.0 - _AP_INSET).reshape(-1, 2)
            owner = np.repeat(rows, _AP_POINTS)
            h = area.height(q, owner, clear_level[owner]).reshape(rows.size, _AP_POINTS)
            a_p[rows] = np.minimum(h.max(axis=1), z_top) - np.maximum(pts[rows, 2], z_bottom)
        area.commit()

    over = a_e > 2.0 * radius * (1.0 + _DIAMETER_ROUNDING)
    if over.any():
        i = int(np.flatnonzero(over)[0])
        raise RuntimeError(f"stock engagement: a_e {a_e[i] * 1e3:.6f} mm exceeds the tool diameter "
                           f"{2e3 * radius:.6f} mm at sample {i}: a bug in the engaged arc")
    np.minimum(a_e, 2.0 * radius, out=a_e)
    thin = (mode != AIR) & ((a_e < _MIN_A_E) | (a_p < _MIN_A_P))
    mode[thin], a_e[thin], a_p[thin], angle[thin] = AIR, 0.0, 0.0, 0.0
    active = mode != AIR
    radial, _ = radial_directions(axes, feed)
    return Engagement(
        a_e=a_e,
        a_p=a_p,
        mode=mode,
        radial_dir=np.where(active[:, None], radial, 0.0),
        engaged_angle=angle,
        feed_dir=np.where(active[:, None], feed, 0.0),
        plunge=plunge,
        warnings=below_bottom_warnings(pts, cut, stock, radius, where, z_tol),
    )


def _bisect(material: Any, rows: np.ndarray, phi_air: np.ndarray, phi_mat: np.ndarray
            ) -> np.ndarray:
    """Refine the boundary between an air angle and a material angle on each row's tool circle."""
    air, mat = phi_air.astype(float), phi_mat.astype(float)
    for _ in range(_BISECTION_STEPS):
        mid = 0.5 * (air + mat)
        inside = material(rows, mid)
        mat = np.where(inside, mid, mat)
        air = np.where(inside, air, mid)
    return 0.5 * (air + mat)


def stock_inputs(points: Any, tool_axis: Any, cutting: Any, tool_radius: float, stock: Stock,
                 where: Callable[[int], str] | None, model: str
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The checked inputs of a stock model (this module's and :mod:`planner.zmap`'s): points
    [m], shape (n, 3); the cutting mask, shape (n,); unit tool axes, shape (n, 3).

    Raises:
        InputError: on shapes, a non-positive radius, a stock that is no :class:`Stock`, or a
            cutting sample whose tool axis is more than VERTICAL_AXIS_TOL from +Z (named with
            ``where(sample)`` when given; ``model`` names the model in the message).
    """
    pts = np.asarray(points, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise InputError("points", f"must have shape (n, 3), got {pts.shape}")
    if not np.all(np.isfinite(pts)):
        raise InputError("points", "contains NaN or infinite values")
    n = pts.shape[0]
    cut = cutting_mask(cutting, n)
    axes = unit_axes(tool_axis, n)
    if not (math.isfinite(tool_radius) and tool_radius > 0):
        raise InputError("tool_radius", f"must be positive [m], got {tool_radius:g}")
    if not isinstance(stock, Stock):
        raise InputError("stock", f"must be a Stock, got {type(stock).__name__}")
    tilt = np.arccos(np.clip(axes[:, 2], -1.0, 1.0))
    bad = np.flatnonzero(cut & (tilt > VERTICAL_AXIS_TOL))
    if bad.size:
        i = int(bad[0])
        place = f" ({where(i)})" if where is not None else ""
        raise InputError("tool_axis", f"sample {i}{place}: the tool axis is "
                         f"{math.degrees(tilt[i]):.3g} deg from +Z; {model} needs a vertical tool "
                         f"(within {math.degrees(VERTICAL_AXIS_TOL):g} deg: a 3-axis program) — "
                         "use fixed engagement ([engagement] source = \"fixed\") for a tilted "
                         "tool")
    return pts, cut, axes
