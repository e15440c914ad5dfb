"""The height grid of :mod:`planner.zmap` and the exact geometry of a flat end mill's sweep.

Private helper of :mod:`planner.zmap` (docs/model.md §8, "3-axis: a height map"). Each cell keeps
the height of the remaining stock at its centre and three *owner* steps, the candidates from which
the engagement near the cell is read exactly (not from the raster):

* the step that passed lowest over the centre (on a ramp: the last one whose disc reached it, which
  merely grazes it);
* of the latest pass that cut the cell lower, the step whose axis passed closest to the centre (it
  covers the cell's whole neighbourhood: the wall the previous turn of a helix left, the level
  above in a pocket);
* the same of the pass before (a crescent that pass cut and the latest one missed, narrower than a
  cell);
* of the latest pass over the cell at any height, the closest step (a later pass at a higher level
  that cut a band too narrow to lower any cell centre: a finishing helix 0.1 mm outside a bore).

A *pass* over a cell is a run of consecutive steps covering its centre.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["OWNERS", "HeightGrid", "Steps"]

OWNERS = 4
"""Owner steps per cell [-] (lowest; closest of the lowest pass, and of the one before; closest of
the latest pass)."""

_NEIGHBOURS = np.array([(0, 0), (1, 0), (0, 1), (1, 1)])
"""Offsets of the 2 × 2 cells whose centres surround a point, whose owners are its candidate steps
[cells]. For a cell no larger than R/√2, a step whose swept area contains the point also contains
one of these centres (the one towards the tool axis)."""


class Steps:
    """The path's steps, one per sample (the step arriving at it), as columns for :meth:`height`.

    Index −1 (and ``n``) is a sentinel that covers nothing, and so is every step that removes no
    material (``clears`` False: rapids). A step without XY length (a plunge) covers the disc
    around it at its lower end.
    """

    def __init__(self, points: np.ndarray, clears: np.ndarray) -> None:
        start = np.vstack([points[:1], points[:-1]])
        d = points - start
        l2 = d[:, 0] ** 2 + d[:, 1] ** 2
        moving = l2 > 0.0
        far = 1e30  # the sentinel lies so far away that no disc reaches it (squares stay finite)
        low = np.where(moving, start[:, 2], np.minimum(start[:, 2], points[:, 2]))
        cols = np.column_stack([start[:, 0], start[:, 1], d[:, 0], d[:, 1],
                                np.where(moving, 1.0 / np.where(moving, l2, 1.0), 0.0),
                                np.where(clears, low, math.inf),
                                np.where(clears & moving, d[:, 2], 0.0)])
        #: per step (rows, the sentinel last): start x, y, step dx, dy, 1/|step_xy|² (0 for a
        #: plunge), z at the start (the lower end for a plunge; +inf if it clears nothing), dz.
        self.table = np.vstack([cols, [far, far, 0.0, 0.0, 0.0, math.inf, 0.0]])
        self.ax, self.ay, self.dx, self.dy, self.inv, self.za, self.dz = self.table.T
        # the same as Python floats, for the one-step-at-a-time grid update
        (self.ax_of, self.ay_of, self.dx_of, self.dy_of, self.inv_of, self.za_of,
         self.dz_of) = (c.tolist() for c in self.table.T)

    def height(self, qx: np.ndarray, qy: np.ndarray, k: np.ndarray, r2: np.ndarray | float
               ) -> np.ndarray:
        """Lowest tip height [m] at which steps ``k`` (any shape, −1 for none) pass over the points
        (qx, qy) [m] broadcast with it, for a flat end mill of squared radius ``r2`` [m²]
        (broadcast too); +inf where a step's disc never covers a point (distance² < r2 strictly).

        The disc covers q for the step parameters t ∈ [0, 1] within the chord half-width
        √(r2 − perp²) of q's projection on the step; z is linear in t, so its least value over that
        interval is at one end.
        """
        g = self.table[k]
        ax, ay, dx, dy, inv, za, dz = g.T if g.ndim == 2 else np.moveaxis(g, -1, 0)
        rx = qx - ax
        ry = qy - ay
        along = rx * dx + ry * dy
        t_c = along * inv
        perp2 = rx * rx + ry * ry
        along *= t_c
        perp2 -= along
        slack = r2 - perp2
        half = np.maximum(slack, 0.0)
        half *= inv
        np.sqrt(half, out=half)
        lo = np.maximum(t_c - half, 0.0)
        t_c += half
        hi = np.minimum(t_c, 1.0, out=t_c)
        miss = (slack <= 0.0) | (lo > hi)
        lo *= dz
        hi *= dz
        z = np.minimum(lo, hi, out=lo)
        z += za
        z[miss] = np.inf
        return z


class HeightGrid:
    """Stock top z(x, y) [m] on a regular grid of square cells, with :data:`OWNERS` owner steps per
    cell (module docstring).

    Args:
        bounds: (xmin, ymin, xmax, ymax) of the stock outline [m]; the grid covers it with two cells
            to spare on every side.
        cell: cell size [m].
        z_top: initial height of every cell [m].
        tie_tol: heights within this of a cell's are the same level [m].
        steps: the path's steps.
    """

    def __init__(self, bounds: tuple[float, float, float, float], cell: float, z_top: float,
                 tie_tol: float, steps: Steps) -> None:
        xmin, ymin, xmax, ymax = bounds
        self.cell = cell
        self.tie_tol = tie_tol
        self.steps = steps
        self.x0, self.y0 = xmin - 2.0 * cell, ymin - 2.0 * cell
        self.nx = math.ceil((xmax - xmin) / cell) + 5
        self.ny = math.ceil((ymax - ymin) / cell) + 5
        self.xc = self.x0 + cell * np.arange(self.nx)
        self.yc = self.y0 + cell * np.arange(self.ny)
        self.h = np.full((self.nx, self.ny), float(z_top))
        # 36 bytes a cell: int32 steps (paths of up to 2**31 samples), float32 squared distances
        # (compared with one another only)
        self.owner = np.full((self.nx, self.ny, OWNERS), -1, dtype=np.int32)
        self.dist = np.full((self.nx, self.ny, 2), np.inf, dtype=np.float32)  # closest owners' [m²]
        self.last = np.full((self.nx, self.ny), -1, dtype=np.int32)  # last step covering a cell
        self.previous = -2  # the step removed last (−2: none yet)
        self._offsets = (_NEIGHBOURS[:, 0] * self.ny + _NEIGHBOURS[:, 1])

    def remove(self, k: int, radius: float) -> None:
        """Lower the cells step ``k`` sweeps to the tool's lowest pass over their centres and update
        their owners. Steps must be removed in path order (a pass is a run of consecutive steps)."""
        st, inv_c, r = self.steps, 1.0 / self.cell, radius
        ax, ay, dx, dy = st.ax_of[k], st.ay_of[k], st.dx_of[k], st.dy_of[k]
        i0 = max(math.ceil((min(ax, ax + dx) - r - self.x0) * inv_c), 0)
        i1 = min(math.floor((max(ax, ax + dx) + r - self.x0) * inv_c) + 1, self.nx)
        j0 = max(math.ceil((min(ay, ay + dy) - r - self.y0) * inv_c), 0)
        j1 = min(math.floor((max(ay, ay + dy) + r - self.y0) * inv_c) + 1, self.ny)
        if i0 >= i1 or j0 >= j1:
            return
        inv, za, dz, r2 = st.inv_of[k], st.za_of[k], st.dz_of[k], r * r
        rx, ry = self.xc[i0:i1, None] - ax, self.yc[None, j0:j1] - ay
        t = (rx * dx + ry * dy) * inv
        tc = np.clip(t, 0.0, 1.0)
        d2 = (rx - tc * dx) ** 2 + (ry - tc * dy) ** 2  # squared distance to the step's axis
        covered = d2 < r2
        if dz == 0.0:
            z = np.where(covered, za, np.inf)
        else:  # the lowest end of the interval of t over which the disc covers the centre
            half = np.sqrt(np.maximum(r2 - (d2 - (t - tc) ** 2 / inv), 0.0) * inv)
            z = za + dz * np.clip(t + (half if dz < 0.0 else -half), 0.0, 1.0)
            z[~covered] = np.inf
        win = np.s_[i0:i1, j0:j1]
        h, owner, dist, last = self.h[win], self.owner[win], self.dist[win], self.last[win]
        new = covered & (last != self.previous)
        tol = self.tie_tol
        np.copyto(owner[..., 0], k, where=z < h)
        deeper = new & (z < h - tol)
        np.copyto(owner[..., 2], owner[..., 1], where=deeper)
        lower = deeper | ((z <= h + tol) & (d2 < dist[..., 0]))
        np.copyto(owner[..., 1], k, where=lower)
        np.copyto(dist[..., 0], d2, where=lower)
        latest = new | (covered & (d2 < dist[..., 1]))
        np.copyto(owner[..., 3], k, where=latest)
        np.copyto(dist[..., 1], d2, where=latest)
        np.copyto(last, k, where=covered)
        self.previous = k
        np.minimum(h, z, out=h)

    def cells(self, qx: np.ndarray, qy: np.ndarray) -> np.ndarray:
        """The flat index of the lower-left of the 2 × 2 cells whose centres surround each point
        (qx, qy) [m] (any shape, the same returned), for :meth:`neighbourhood`. Points off the grid
        read its edge (the caller tests the stock outline)."""
        i = np.minimum(np.maximum(((qx - self.x0) / self.cell).astype(np.int64), 0), self.nx - 2)
        j = np.minimum(np.maximum(((qy - self.y0) / self.cell).astype(np.int64), 0), self.ny - 2)
        return i * self.ny + j

    def neighbourhood(self, cells: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The owners and the heights of the 2 × 2 cells at ``cells`` (from :meth:`cells`), shape
        (m,): arrays of shape (m, 4 · OWNERS) (−1 where no step has cut) and (m, 4) [m]."""
        flat = cells[:, None] + self._offsets
        return self.owner.reshape(-1, OWNERS)[flat].reshape(cells.size, -1), self.h.reshape(-1)[flat]
