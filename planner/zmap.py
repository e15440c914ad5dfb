"""Engagement from a Z-map (docs/model.md §8, "3-axis: a height map"): the stock's top surface
z(x, y) on a regular grid, cut down sample by sample as a flat end mill sweeps the path, so that
a_e, a_p, the engaged arc and the mode follow the material actually left — on helices, ramps and
pockets, where the 2.5-D per-level model (:mod:`planner.stock`) is wrong.

**The grid.** Square cells of size ``cell`` (default R/10) cover the stock outline; every cell
starts at the stock top. A 3-axis tool (axis +Z) moving straight from one sample to the next sweeps
a stadium, and the lowest tip height it passes over a point is known in closed form (z is linear
along the step, so it is least at one end of the interval in which the disc covers the point);
each step lowers the cells whose centres it sweeps to that height. Each cell also keeps the
*owners* it needs to be read exactly (:mod:`planner._zmap_grid`): the lowest step over it, the
closest step of the latest pass that cut it lower and of the pass before, the closest step of the
latest pass at any height.

**Reading it.** At each cutting sample, before its own step is cut, the front half of the tool
circle (φ ∈ [0, π] from X_o = a × f towards the feed f, the path tangent: the angles, milling side
and ``engaged_angle`` of :mod:`planner.cutting_frame` and :mod:`planner.stock`) is probed every
:data:`ANGULAR_RESOLUTION` (:mod:`planner._zmap_scan`). The height h(q) of the material left at a
probe q is the lowest exact sweep over q of its candidate steps: the owners of the 2 × 2 cells
around q — at the two side probes, which touch the band of any earlier pass along the same line,
with their neighbours along the path — and the steps too recent to be in the grid that can reach
the front half. Where the four cells stand level and no recent step reaches the front half, h is
that level. q engages if it lies inside the stock outline (tested exactly) and h stands more than
:data:`DEPTH_TOL` above max(tip, stock bottom). The engaged probes give the arc [φ_st, φ_ex], whose
open ends are bisected against the same exact sweeps; then, as in :mod:`planner.stock`,

    a_e = R (cos φ_st − cos φ_ex); slot (a_e = 2R) if the arc reaches both sides, up milling if it
    is anchored at φ = 0 (material on +X_o), down if at φ = π, else by its middle;
    a_p = max over the engaged probes of h(q) − max(tip, stock bottom), ≤ z_top − tip:

the height of the material the flank meets above the tip — the pitch on a helix after its first
turn, the level step in a pocket, the growing depth on a ramp into solid stock. A tip below the
stock bottom is a warning (:func:`planner.stock.below_bottom_warnings`); a_p is never negative and
a_e never above 2R.

**Error bound.** Where each boundary of the engaged arc is the stock outline, a_e and the angles
are exact to the bisection (≈ 1e-5 R); where it is the edge of an earlier pass, within
:data:`SLIVER_TOL` (20 µm) of it; a_p is the exact height of the material left on constant-height
levels and within the surface's slope times one cell on ramps and helices (on the 0.5 mm-pitch,
0.2 mm-radius helices of the bundled Fusion 360 program: 0.49 ± 0.03 mm). Material narrower than
about a cell between two earlier cuts, where the cells around it belong to neither, is read from
the cells: a_e and a_p errors of order one cell there. Material thinner than :data:`DEPTH_TOL` along
the axis or :data:`MIN_A_E` across the feed is no engagement.

Not modelled (as in :mod:`planner.stock`): ball and bull-nose tools (flat end mill only), the
back half of the tool, cutting with the tool's bottom only (plunges are AIR with ``plunge`` set);
tilted tools are refused (use the fixed source).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
import shapely

from models.cutting import MILLING_MODES
from models.errors import InputError
from planner._zmap_grid import HeightGrid, Steps
from planner._zmap_scan import refine, scan, window
from planner.cutting_frame import (
    AIR,
    Engagement,
    feed_directions,
    radial_directions,
)
from planner.stock import LEVEL_TOL, Stock, below_bottom_warnings, stock_inputs

__all__ = [
    "ANGULAR_RESOLUTION",
    "CELL_FRACTION",
    "DEPTH_TOL",
    "MAX_CELLS",
    "MIN_A_E",
    "SLIVER_TOL",
    "default_cell",
    "zmap_engagement",
]

_UP, _DOWN, _SLOT = MILLING_MODES["up"], MILLING_MODES["down"], MILLING_MODES["slot"]

CELL_FRACTION = 0.1
"""Default cell size as a fraction of the tool radius R [-] (``[engagement.stock] zmap_cell_mm``
overrides it): 0.14 mm for a 2.8 mm end mill, 1.27 mm for the demo's 25.4 mm one. The probes read
exact sweeps, so the cell bounds only the material it cannot resolve (narrower than a cell between
two cuts) and the slope error on ramps; each step lowers about (2R/cell)² = 400 cells. Coarser
cells lose the wall an earlier pass left tangent to the tool more often (at R/8 the demo still
agrees with the 2.5-D model; at R/6 a helix's a_p is 7 % high)."""

MAX_CELLS = 10_000_000
"""Largest grid [cells]: 10 M cells hold 360 MB (36 bytes a cell: the height, four owner steps, two
distances and the last step over it); a larger stock needs a larger cell."""

ANGULAR_RESOLUTION = math.radians(2.0)
"""Spacing of the probes on the front half of the tool circle [rad], as in :mod:`planner.stock`:
an arc that touches neither side is found if longer than this; its ends are then bisected."""

SLIVER_TOL = 2e-5
"""Earlier passes clear a point within this of their swept disc [m] (20 µm, twice the default
chord tolerance of 10 µm). The path's arcs are chords: two passes along the same circle (a helix's
turns, a pocket's levels) leave scallops up to the chord sagitta between their swept bands, and
read exactly they would be walls of the full stock height, 10 µm thick, at the side of the tool.
Radial engagements thinner than this against an earlier cut are not seen (a pass retracing one
within 20 µm cuts nothing), well below :data:`MIN_A_E`. The caller passes twice its chord
tolerance when that is larger."""

DEPTH_TOL = LEVEL_TOL
"""Material standing less than this above max(tool tip, stock bottom) is no engagement [m] (10 µm,
:data:`planner.stock.LEVEL_TOL`): CAM programs write z to 1 µm, and a pass that retraces an earlier
one at the same height finds nothing. A ramp's step down per sample is far larger."""

MIN_A_E = 1e-5
"""Engagements narrower than this across the feed are AIR [m]: below an end mill's edge radius the
tool rubs rather than cuts (the 2.5-D model's threshold too)."""

_SIDE_PROBE = 0.01
"""The side probes sit this far inside the front half, at φ = 0.01 and π − 0.01 [rad], as in
:mod:`planner.stock`: exactly at φ = 0, π the circle touches the band its own pass sweeps."""

_INSIDE_TOL = 1e-9
"""The pass's own last steps clear a probe only if it lies deeper than this inside their disc [m]:
the probes of the current circle touch the band its own pass sweeps; rounding must not clear them."""

_OWN_STEPS = 2.0
"""The steps of the last ``_OWN_STEPS · √(2 R SLIVER_TOL)`` of path [-] are the pass's own and are
tested without the sliver tolerance; older ones with it. On a straight pass a step that ended L
behind the tool reaches the side probes within R + L²/2R, so the older ones stay ≥ 4 SLIVER_TOL
away from them and cannot clear a slot's sides (0.47 mm of path at R = 1.4 mm, 1.4 mm at 12.7)."""

_DIAMETER_ROUNDING = 1e-9
"""a_e = R (cos φ_st − cos φ_ex) exceeds 2R only by rounding: by more than this fraction of 2R [-]
it is a bug and raises; within it a_e is clipped to 2R."""

_LAG_CELLS = 1.5
"""A step enters the grid only once the tool has moved √(2 R ι) + ι further along the path, with
ι = 1.5 cells [-] (0.7 R at a cell of R/10); until then it is a *recent* step, tested explicitly
where it can reach the front half. In the grid the steps of the current pass become the owners of
the cells they sweep, and at the sides of the tool those are the cells (up to ι inside the band's
edge) whose owners show the wall an earlier pass along the same line left there: the level above,
the previous turn of a helix."""

_MAX_RECENT = 64
"""At most this many recent steps are kept out of the grid [-]; on a path sampled finer than
``lag / 64`` the older ones enter it early (the side probes may then lose the wall an earlier pass
left tangent to them: an a_p error within a cell of the side)."""


def default_cell(tool_radius: float) -> float:
    """The default Z-map cell size [m] for a tool of radius R [m]: ``CELL_FRACTION · R``."""
    return CELL_FRACTION * float(tool_radius)


def zmap_engagement(points: Any, tool_axis: Any, cutting: Any, tool_radius: float, stock: Stock,
                    cell: float | None = None, where: Callable[[int], str] | None = None,
                    sliver: float = SLIVER_TOL) -> Engagement:
    """Engagement of a 3-axis program from a Z-map of the stock (module docstring).

    Args:
        points: tool-tip positions in the workpiece frame [m], shape (n, 3), in path order (the
            caller samples densely enough to see the engagement change; each step's sweep is exact).
        tool_axis: tool axis from the tip towards the spindle, shape (3,) or (n, 3); within
            :data:`planner.stock.VERTICAL_AXIS_TOL` of +Z on cutting samples.
        cutting: True where the sample ends a feed move, shape (n,): the step arriving at it cuts.
            Rapids neither cut nor remove material.
        tool_radius: R [m] (flat end mill).
        stock: the stock (outline, z_bottom, z_top).
        cell: grid cell size [m], in (0, R/2]; default :func:`default_cell` (R/10).
        where: ``file:line`` of sample i (``PathSamples.where``), for messages and warnings.
        sliver: earlier passes clear points within this of their swept disc [m]
            (:data:`SLIVER_TOL`; pass twice the path's chord tolerance if that is larger).

    Returns:
        the :class:`~planner.cutting_frame.Engagement` per sample (feed_dir the arriving step, as
        ``PathSamples.feed_dir``); ``warnings`` names every run of samples below the stock bottom.

    Raises:
        InputError: on shapes, a non-positive radius, a cell outside (0, R/2] or a grid over
            :data:`MAX_CELLS`, or a cutting sample whose tool axis is tilted (use the fixed source).
    """
    pts, cut, axes = stock_inputs(points, tool_axis, cutting, tool_radius, stock, where,
                                  "the Z-map")
    radius = float(tool_radius)
    cell = default_cell(radius) if cell is None else float(cell)
    if not (math.isfinite(cell) and 0 < cell <= 0.5 * radius):
        raise InputError("zmap_cell_mm", f"the Z-map cell must lie in (0, R/2] = (0, "
                         f"{0.5e3 * radius:g}] mm for this tool, got {cell * 1e3:g} mm")
    if not (math.isfinite(sliver) and 0 <= sliver < 0.1 * radius):
        raise InputError("sliver", f"must lie in [0, R/10) = [0, {0.1 * radius:g}) m, got {sliver:g} m")
    bounds = tuple(float(v) for v in stock.polygon.bounds)
    cells = (math.ceil((bounds[2] - bounds[0]) / cell) + 5) * (math.ceil((bounds[3] - bounds[1])
                                                                         / cell) + 5)
    if cells > MAX_CELLS:
        raise InputError("zmap_cell_mm", f"a {cell * 1e3:g} mm cell makes a grid of {cells:,} cells "
                         f"over the stock (at most {MAX_CELLS:,}); give a larger "
                         f"[engagement.stock] zmap_cell_mm")

    z_top, z_bottom = float(stock.z_top), float(stock.z_bottom)
    feed, tangent, plunge = feed_directions(pts, cut, DEPTH_TOL)
    start = np.vstack([pts[:1], pts[:-1]])
    clears = cut & (np.minimum(pts[:, 2], start[:, 2]) < z_top)
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])
    steps = Steps(pts, clears)
    grid = HeightGrid(bounds, cell, z_top, DEPTH_TOL, steps)  # type: ignore[arg-type]
    inside = _outline_test(stock)
    theta = np.linspace(0.0, math.pi, math.ceil(math.pi / ANGULAR_RESOLUTION) + 1)
    theta[0], theta[-1] = _SIDE_PROBE, math.pi - _SIDE_PROBE
    last_bin = theta.size - 1
    r2_own, r2_old = (radius - _INSIDE_TOL) ** 2, (radius + sliver) ** 2
    reach = (bounds[0] - radius, bounds[1] - radius, bounds[2] + radius, bounds[3] + radius)
    floor = np.maximum(pts[:, 2], z_bottom)
    probe = (cut & ~plunge & (pts[:, 2] < z_top - DEPTH_TOL)
             & (pts[:, 0] > reach[0]) & (pts[:, 0] < reach[2])
             & (pts[:, 1] > reach[1]) & (pts[:, 1] < reach[3]))
    sweep = np.flatnonzero(clears)
    own_length = _OWN_STEPS * math.sqrt(2.0 * radius * max(sliver, _INSIDE_TOL))
    win = window(pts, tangent, s, sweep, np.flatnonzero(probe), steps, radius,
                 math.sqrt(2.0 * radius * _LAG_CELLS * cell) + _LAG_CELLS * cell, _MAX_RECENT,
                 own_length, r2_own, r2_old)
    found = scan(pts, tangent, probe, clears, floor, s, grid, steps, win, sweep, theta, radius,
                 r2_own, r2_old, own_length, z_top, DEPTH_TOL, inside)
    engaged, first, last, a_p = found.engaged, found.first, found.last, found.a_p
    phi_st = np.where(engaged, theta[first], 0.0)
    phi_ex = np.where(engaged, theta[last], 0.0)
    lo_open = engaged & (first > 0)
    hi_open = engaged & (last < last_bin)
    phi_st[engaged & ~lo_open] = 0.0
    phi_ex[engaged & ~hi_open] = math.pi
    if found.ends.size:
        rows, is_lo = found.ends[:, 0], found.ends[:, 1] < found.ends[:, 2]
        ends = refine(found, win, probe, theta, pts, tangent, radius, steps, floor, inside, r2_old,
                      DEPTH_TOL)
        phi_st[rows[is_lo]] = ends[is_lo]
        phi_ex[rows[~is_lo]] = ends[~is_lo]

    slot = engaged & ~lo_open & ~hi_open
    up = np.where(lo_open == hi_open, phi_st + phi_ex <= math.pi, ~lo_open)
    mode = np.where(engaged, np.where(slot, _SLOT, np.where(up, _UP, _DOWN)), AIR)
    a_e = np.where(slot, 2.0 * radius, radius * (np.cos(phi_st) - np.cos(phi_ex)))
    a_e[~engaged] = 0.0
    over = a_e > 2.0 * radius * (1.0 + _DIAMETER_ROUNDING)
    if over.any():
        i = int(np.flatnonzero(over)[0])
        raise RuntimeError(f"Z-map engagement: a_e {a_e[i] * 1e3:.6f} mm exceeds the tool diameter "
                           f"{2e3 * radius:.6f} mm at sample {i}: a bug in the engaged arc")
    np.minimum(a_e, 2.0 * radius, out=a_e)
    angle = np.where(engaged, phi_ex - phi_st, 0.0)
    thin = engaged & (a_e < MIN_A_E)
    mode[thin], a_e[thin], a_p[thin], angle[thin] = AIR, 0.0, 0.0, 0.0
    active = mode != AIR
    a_p[~active] = 0.0
    radial, _ = radial_directions(axes, feed)
    return Engagement(
        a_e=a_e,
        a_p=a_p,
        mode=mode.astype(int),
        radial_dir=np.where(active[:, None], radial, 0.0),
        engaged_angle=angle,
        feed_dir=np.where(active[:, None], feed, 0.0),
        plunge=plunge,
        warnings=below_bottom_warnings(pts, cut, stock, radius, where, DEPTH_TOL),
    )


def _outline_test(stock: Stock) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    """Exact point-in-outline test: comparisons for an axis-aligned box, shapely otherwise."""
    poly = stock.polygon
    x0, y0, x1, y1 = (float(v) for v in poly.bounds)
    if not poly.interiors and math.isclose(poly.area, (x1 - x0) * (y1 - y0), rel_tol=1e-12):
        return lambda qx, qy: (qx > x0) & (qx < x1) & (qy > y0) & (qy < y1)
    return lambda qx, qy: shapely.contains_xy(poly, qx, qy)
