"""What a 2.5-D path has cleared so far: per Z level, the union of the areas the tool swept.

Private helper of :mod:`planner.stock` (docs/model.md §8, "cleared-area polygons per Z level").
"""

from __future__ import annotations

import numpy as np
import shapely

__all__ = ["INSIDE_TOL", "QUAD_SEGS", "ClearedArea", "assign_levels", "clusters"]

QUAD_SEGS = 32
"""Segments per quarter circle of a buffered swept area [-]. The polygon is inscribed in the true
circle and lies at most R (1 − cos(π/128)) ≈ 3e-4 R inside it (4 µm at R = 12.7 mm): it may under-count
the cleared area by that much near the round ends of earlier passes, never over-count it — a probe
on the current tool circle ahead of the tool is never inside the true disc of an earlier sample of the
same straight pass, so rounding outwards would steal material from the current cut."""

INSIDE_TOL = 1e-9
"""A probe is cleared by a not-yet-merged swept area only if it lies deeper inside than this [m]:
probes lie exactly on the current tool circle, which touches the band swept by the same pass, and
rounding must not count them as cleared."""


class ClearedArea:
    """What the path has cleared so far, per Z level: merged polygons plus the current batch's steps.

    Level k holds the union of the areas swept by samples of level k only (levels ascend in height).
    A point q counts as cleared for a sample with clearing level k (its own level, or the highest
    level within the caller's slack above its tip) if a level j ≤ k covers it; it has been cleared
    down to h(q), the lowest level covering it (the stock top if none). The steps of the current
    batch are not merged yet and are tested exactly (point to segment distance), each only for
    samples after it.
    """

    def __init__(self, level_z: np.ndarray, radius: float) -> None:
        self.level_z = level_z
        self.radius = radius
        self.geoms = np.full(level_z.size, None, dtype=object)
        self.bounds = np.full((level_z.size, 4), np.nan)
        self.filled = np.zeros(level_z.size, dtype=bool)
        self.stage(np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0, dtype=int), np.zeros(0, dtype=int))

    def stage(self, a: np.ndarray, b: np.ndarray, level: np.ndarray, index: np.ndarray) -> None:
        """Set the current batch's steps: a → b [m], shape (m, 2) each, their level and sample."""
        self.seg_a, self.seg_b, self.seg_level, self.seg_index = a, b, level, index

    def commit(self) -> None:
        """Merge the current batch's swept areas into their levels and start an empty batch."""
        if self.seg_index.size:
            same = np.all(self.seg_a == self.seg_b, axis=1)
            geoms = np.where(same, shapely.points(self.seg_a),
                             shapely.linestrings(np.stack([self.seg_a, self.seg_b], axis=1)))
            swept = shapely.buffer(geoms, self.radius, quad_segs=QUAD_SEGS)
            for k in np.unique(self.seg_level):
                parts = list(swept[self.seg_level == k])
                if self.filled[k]:
                    parts.append(self.geoms[k])
                merged = shapely.union_all(parts)
                shapely.prepare(merged)
                self.geoms[k] = merged
                self.bounds[k] = shapely.bounds(merged)
                self.filled[k] = True
        self.stage(np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0, dtype=int), np.zeros(0, dtype=int))

    def cleared(self, xy: np.ndarray, owner: np.ndarray, owner_level: np.ndarray) -> np.ndarray:
        """Whether points xy [m], shape (k, 2), were cleared for their sample ``owner`` by earlier
        samples at levels ≤ ``owner_level`` (the owner's clearing level), shape (k,)."""
        out = np.zeros(xy.shape[0], dtype=bool)
        pi, _ = self._merged_hits(xy, owner_level, below=True)
        out[pi] = True
        rest = np.flatnonzero(~out)
        pi, _ = self._fresh_hits(xy[rest], owner[rest], owner_level[rest], below=True)
        out[rest[pi]] = True
        return out

    def height(self, xy: np.ndarray, owner: np.ndarray, owner_level: np.ndarray) -> np.ndarray:
        """Lowest level height [m] above ``owner_level`` that covers each point, +inf if none."""
        out = np.full(xy.shape[0], np.inf)
        pi, lv = self._merged_hits(xy, owner_level, below=False)
        np.minimum.at(out, pi, self.level_z[lv])
        pi, si = self._fresh_hits(xy, owner, owner_level, below=False)
        np.minimum.at(out, pi, self.level_z[self.seg_level[si]])
        return out

    def _merged_hits(self, xy: np.ndarray, owner_level: np.ndarray, below: bool
                     ) -> tuple[np.ndarray, np.ndarray]:
        """(point, level) pairs with the point inside the level's merged area, for the levels at or
        below (``below``) or above each point's owner level."""
        none = (np.zeros(0, dtype=int), np.zeros(0, dtype=int))
        if not xy.shape[0]:
            return none
        lo, hi = xy.min(axis=0), xy.max(axis=0)
        b = self.bounds
        with np.errstate(invalid="ignore"):  # NaN bounds of empty levels compare False
            cand = np.flatnonzero(self.filled & (b[:, 0] <= hi[0]) & (b[:, 2] >= lo[0])
                                  & (b[:, 1] <= hi[1]) & (b[:, 3] >= lo[1]))
        if not cand.size:
            return none
        b = b[cand]
        x, y = xy[:, 0, None], xy[:, 1, None]
        relation = (cand[None, :] <= owner_level[:, None]) if below else \
            (cand[None, :] > owner_level[:, None])
        pi, ci = np.nonzero((x >= b[:, 0]) & (x <= b[:, 2]) & (y >= b[:, 1]) & (y <= b[:, 3])
                            & relation)
        lv = cand[ci]
        inside = shapely.contains_xy(self.geoms[lv], xy[pi, 0], xy[pi, 1])
        return pi[inside], lv[inside]

    def _fresh_hits(self, xy: np.ndarray, owner: np.ndarray, owner_level: np.ndarray, below: bool
                    ) -> tuple[np.ndarray, np.ndarray]:
        """(point, step) pairs with the point strictly inside the stadium (step buffered by R) of a
        current-batch step of an earlier sample at or below (``below``) or above the owner level."""
        if not (xy.shape[0] and self.seg_index.size):
            return np.zeros(0, dtype=int), np.zeros(0, dtype=int)
        a, b = self.seg_a, self.seg_b
        centre, half = 0.5 * (a + b), 0.5 * np.abs(b - a) + self.radius
        level = self.seg_level[None, :]
        relation = (level <= owner_level[:, None]) if below else (level > owner_level[:, None])
        pi, si = np.nonzero((np.abs(xy[:, 0, None] - centre[:, 0]) <= half[:, 0])
                            & (np.abs(xy[:, 1, None] - centre[:, 1]) <= half[:, 1])
                            & (self.seg_index[None, :] < owner[:, None]) & relation)
        ab = b[si] - a[si]
        len2 = np.einsum("ij,ij->i", ab, ab)
        rel = xy[pi] - a[si]
        t = np.clip(np.einsum("ij,ij->i", rel, ab) / np.where(len2 > 0.0, len2, 1.0), 0.0, 1.0)
        d = rel - t[:, None] * ab
        inside = np.einsum("ij,ij->i", d, d) < (self.radius - INSIDE_TOL) ** 2
        return pi[inside], si[inside]


def clusters(z: np.ndarray, tol: float, breaks: np.ndarray) -> np.ndarray:
    """Lowest heights of clusters of ``z`` spanning at most ``tol`` and not straddling ``breaks``
    (sorted), ascending."""
    zs = np.unique(z)
    if not zs.size:
        return zs
    side = np.searchsorted(breaks, zs, side="right")
    starts = [zs[0]]
    start_side = side[0]
    for value, s in zip(zs[1:], side[1:], strict=True):
        if value > starts[-1] + tol or s != start_side:
            starts.append(value)
            start_side = s
    return np.asarray(starts)


def assign_levels(z: np.ndarray, flat: np.ndarray, tol: float, ramp_tol: float
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Z levels (ascending heights [m]) and the level index of every height.

    Flat samples (horizontal arriving step) form levels spanning ``tol``; a ramp sample joins the flat
    level within ``tol`` below it, else a ramp band spanning ``ramp_tol`` (never straddling
    a flat level). A level's height is its lowest member's.
    """
    flat_z = clusters(z[flat], tol, np.zeros(0))
    idx = np.searchsorted(flat_z, z, side="right") - 1
    snapped = flat | ((idx >= 0) & (z <= flat_z[np.maximum(idx, 0)] + tol) if flat_z.size
                      else np.zeros_like(flat))
    ramp_z = clusters(z[~snapped], ramp_tol, flat_z)
    level_z = np.union1d(flat_z, ramp_z)
    index = np.searchsorted(level_z, z, side="right") - 1
    return level_z, index
