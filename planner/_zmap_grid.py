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

**Speed.** The steps are cut one at a time (the owners depend on the order), but what a step's
sweep is over its window of cells — the squared distance of each centre to the step's axis, whether
the disc covers it, the lowest tip height over it — does not depend on the grid: it is computed for
a batch of consecutive steps at once (:meth:`HeightGrid.advance`), and each step then costs only
the update of its window. :meth:`Steps.height` gathers its step columns one by one, so that every
operation after the gather runs on contiguous arrays. That update is still about 20 numpy calls a
step, whatever its window holds; on long paths (:data:`COMPILED_STEPS`) the steps are cut by a
compiled loop instead (:mod:`planner._zmap_kernel`, numba), with the same arithmetic cell by cell
and bit for bit the same grid.
"""

from __future__ import annotations

import math
import sys

import numpy as np

__all__ = ["COMPILED_STEPS", "OWNERS", "HeightGrid", "Steps"]

_GEOMETRY_BATCH = 64
"""Steps whose sweeps over the cell centres :meth:`HeightGrid.advance` computes at once [-]..."""

_GEOMETRY_CELLS = 65_536
"""... unless their windows hold more cells than this [-] (a batch keeps at least one step): the
temporaries then stay in the cache (about 600 cells a step at the default cell of R/10)."""

COMPILED_STEPS = 20_000
"""Paths of this many steps or more are cut by the compiled loop of :mod:`planner._zmap_kernel`
[steps], and so is every path once that loop is loaded in the process: it costs about 1 µs a step
against about 20 µs for the numpy update, but loading it (numba and its cached machine code) costs
about 0.4 s in a new process, gained back after some 20,000 steps."""

_KERNEL = "planner._zmap_kernel"

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
        table = np.vstack([cols, [far, far, 0.0, 0.0, 0.0, math.inf, 0.0]])
        # contiguous columns: gathered one by one, they keep every later operation contiguous
        self.ax, self.ay, self.dx, self.dy, self.inv, self.za, self.dz = (
            np.ascontiguousarray(c) for c in table.T)

    def height(self, qx: np.ndarray, qy: np.ndarray, k: np.ndarray, r2: np.ndarray | float
               ) -> np.ndarray:
        """Lowest tip height [m] at which steps ``k`` (any shape, −1 for none) pass over the points
        (qx, qy) [m] broadcast with it, for a flat end mill of squared radius ``r2`` [m²]
        (broadcast too); +inf where a step's disc never covers a point (distance² < r2 strictly).

        The disc covers q for the step parameters t ∈ [0, 1] within the chord half-width
        √(r2 − perp²) of q's projection on the step; z is linear in t, so its least value over that
        interval is at one end.
        """
        k = np.asarray(k)
        shape = np.broadcast_shapes(np.shape(qx), np.shape(qy), k.shape, np.shape(r2))
        if k.shape != shape:
            k = np.broadcast_to(k, shape)
        ax, ay, dx, dy = self.ax.take(k), self.ay.take(k), self.dx.take(k), self.dy.take(k)
        rx = np.subtract(qx, ax, out=ax)
        ry = np.subtract(qy, ay, out=ay)
        along = np.multiply(rx, dx, out=dx)
        along += np.multiply(ry, dy, out=dy)
        inv = self.inv.take(k)
        t_c = along * inv
        perp2 = np.multiply(rx, rx, out=rx)
        perp2 += np.multiply(ry, ry, out=ry)
        along *= t_c
        perp2 -= along
        slack = np.subtract(r2, perp2, out=perp2)
        half = np.maximum(slack, 0.0, out=along)
        half *= inv
        np.sqrt(half, out=half)
        lo = np.subtract(t_c, half, out=inv)
        np.maximum(lo, 0.0, out=lo)
        t_c += half
        hi = np.minimum(t_c, 1.0, out=t_c)
        miss = slack <= 0.0
        miss |= lo > hi
        dz = self.dz.take(k)
        lo *= dz
        hi *= dz
        z = np.minimum(lo, hi, out=lo)
        z += self.za.take(k)
        z[miss] = np.inf
        return z


_Sweep = tuple[int, int, int, int, int, "np.ndarray | None", "np.ndarray | None",
               "np.ndarray | float | None"]
"""A step's sweep over its window, :meth:`HeightGrid._update`'s arguments."""


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
        self._owner_rows, self._h_flat = self.owner.reshape(-1, OWNERS), self.h.reshape(-1)  # views
        self._offsets = (_NEIGHBOURS[:, 0] * self.ny + _NEIGHBOURS[:, 1])

    def plan(self, order: np.ndarray, radius: float, compiled: bool | None = None) -> None:
        """Declare the steps :meth:`advance` removes, in path order, and the tool radius R [m].

        ``compiled``: cut them with the compiled loop (:mod:`planner._zmap_kernel`), bit for bit
        the same grid; by default when it pays (:data:`COMPILED_STEPS`)."""
        self._order, self._radius, self.done = np.asarray(order, dtype=np.int64), radius, 0
        self._batch: list[_Sweep] = []
        self._batch_start = 0
        if compiled is None:
            compiled = self._order.size >= COMPILED_STEPS or _KERNEL in sys.modules
        self._compiled = bool(compiled)

    def advance(self, count: int) -> None:
        """Remove the first ``count`` planned steps (those not removed yet), each as
        :meth:`remove` would; their sweeps are computed a batch at a time (or by the compiled
        loop, one cell at a time)."""
        if self._compiled:
            if self.done < count:
                from planner._zmap_kernel import advance

                st = self.steps
                self.previous = int(advance(
                    self._order, self.done, count, st.ax, st.ay, st.dx, st.dy, st.inv, st.za,
                    st.dz, self.x0, self.y0, 1.0 / self.cell, self.xc, self.yc, self._radius,
                    self.tie_tol, self.h, self.owner, self.dist, self.last, self.previous))
                self.done = count
            return
        while self.done < count:
            b = self.done - self._batch_start
            if b >= len(self._batch):
                self._batch_start, b = self.done, 0
                self._batch = self._geometry(self._order[self.done:self.done + _GEOMETRY_BATCH],
                                             self._radius)
            self._update(*self._batch[b])
            self.done += 1

    def remove(self, k: int, radius: float) -> None:
        """Lower the cells step ``k`` sweeps to the tool's lowest pass over their centres and update
        their owners. Steps must be removed in path order (a pass is a run of consecutive steps)."""
        self._update(*self._geometry(np.array([k]), radius)[0])

    def _geometry(self, ks: np.ndarray, radius: float) -> list[_Sweep]:
        """The sweeps of the first of the steps ``ks`` (all of them, or as many as hold
        :data:`_GEOMETRY_CELLS` cells, at least one) over the cell centres of their windows, for
        :meth:`_update`. The arithmetic is that of one step at a time, element by element."""
        st, inv_c, r, r2 = self.steps, 1.0 / self.cell, radius, radius * radius
        ax, ay, dx, dy, inv = st.ax[ks], st.ay[ks], st.dx[ks], st.dy[ks], st.inv[ks]
        ex, ey = ax + dx, ay + dy
        i0 = np.maximum(np.ceil((np.minimum(ax, ex) - r - self.x0) * inv_c), 0).astype(np.int64)
        i1 = np.minimum(np.floor((np.maximum(ax, ex) + r - self.x0) * inv_c) + 1,
                        self.nx).astype(np.int64)
        j0 = np.maximum(np.ceil((np.minimum(ay, ey) - r - self.y0) * inv_c), 0).astype(np.int64)
        j1 = np.minimum(np.floor((np.maximum(ay, ey) + r - self.y0) * inv_c) + 1,
                        self.ny).astype(np.int64)
        ni, nj = np.maximum(i1 - i0, 0), np.maximum(j1 - j0, 0)
        nj = np.where(ni > 0, nj, 0)
        ni = np.where(nj > 0, ni, 0)
        size = ni * nj
        end = np.cumsum(size)
        fit = max(int(np.searchsorted(end, _GEOMETRY_CELLS, side="right")), 1)
        if fit < ks.size:
            ks, ax, ay, dx, dy, inv, i0, i1, j0, j1, ni, nj, size, end = (
                v[:fit] for v in (ks, ax, ay, dx, dy, inv, i0, i1, j0, j1, ni, nj, size, end))
        start = end - size
        # rows (step, i) and columns (step, j) of the windows, then their cells (row-major)
        row_step = np.repeat(np.arange(ks.size), ni)
        row_i = np.arange(row_step.size) - np.repeat(np.cumsum(ni) - ni - i0, ni)
        col_step = np.repeat(np.arange(ks.size), nj)
        col_j = np.arange(col_step.size) - np.repeat(np.cumsum(nj) - nj - j0, nj)
        rx_row = self.xc[row_i] - ax[row_step]
        ry_col = self.yc[col_j] - ay[col_step]
        per_row = nj[row_step]
        col = np.arange(int(end[-1]) if ks.size else 0) - np.repeat(
            np.cumsum(per_row) - per_row - (np.cumsum(nj) - nj)[row_step], per_row)
        rx = np.repeat(rx_row, per_row)
        ry = ry_col[col]
        dxb = np.repeat(dx[row_step], per_row)
        dyb = np.repeat(dy[row_step], per_row)
        t = np.repeat(rx_row * dx[row_step], per_row)
        t += (ry_col * dy[col_step])[col]
        inv_b = np.repeat(inv[row_step], per_row)
        t *= inv_b
        tc = np.maximum(t, 0.0)
        np.minimum(tc, 1.0, out=tc)
        d2 = tc * dxb
        np.subtract(rx, d2, out=d2)
        d2 *= d2
        e = np.multiply(tc, dyb, out=dxb)
        np.subtract(ry, e, out=e)
        e *= e
        d2 += e  # squared distance to the step's axis
        b = np.repeat(row_step, per_row)
        covered = d2 < r2
        dz, za = st.dz[ks], st.za[ks]
        z = None
        sloped = dz[b] != 0.0
        if sloped.any():  # the lowest end of the interval of t over which the disc covers the centre
            z = np.empty(t.size)
            ts, tcs, invs, bs = t[sloped], tc[sloped], inv_b[sloped], b[sloped]
            e = ts - tcs
            e *= e
            e /= invs
            np.subtract(d2[sloped], e, out=e)
            np.subtract(r2, e, out=e)
            np.maximum(e, 0.0, out=e)
            e *= invs
            np.sqrt(e, out=e)
            np.negative(e, out=e, where=dz[bs] > 0.0)
            ts += e
            np.maximum(ts, 0.0, out=ts)
            np.minimum(ts, 1.0, out=ts)
            ts *= dz[bs]
            ts += za[bs]
            z[sloped] = ts
        out: list[_Sweep] = []
        for k, a0, a1, c0, c1, o, n, zq, dzq in zip(
                ks.tolist(), i0.tolist(), i1.tolist(), j0.tolist(), j1.tolist(), start.tolist(),
                size.tolist(), za.tolist(), dz.tolist(), strict=True):
            if n == 0:  # the window is off the grid
                out.append((k, 0, 0, 0, 0, None, None, None))
                continue
            shape = (a1 - a0, c1 - c0)
            out.append((k, a0, a1, c0, c1, d2[o:o + n].reshape(shape),
                        covered[o:o + n].reshape(shape),
                        z[o:o + n].reshape(shape) if dzq != 0.0 and z is not None else zq))
        return out

    def _update(self, k: int, i0: int, i1: int, j0: int, j1: int, d2: np.ndarray | None,
                covered: np.ndarray | None, z: np.ndarray | float | None) -> None:
        """Apply step ``k``'s sweep (from :meth:`_geometry`) to the cells of its window
        [i0, i1) × [j0, j1): ``d2`` the squared distances of their centres to the step's axis [m²],
        ``covered`` where the disc covers them, ``z`` the lowest tip height over them [m] (a float
        for a level step; meaningless where not covered). Nothing (not even the step's being the
        previous one) where the window is off the grid (``d2`` None)."""
        if d2 is None or covered is None or z is None:
            return
        win = np.s_[i0:i1, j0:j1]
        hv, owner, dist, last = self.h[win], self.owner[win], self.dist[win], self.last[win]
        h = hv.copy()
        new = last != self.previous
        new &= covered
        tol = self.tie_tol
        lt = np.less(z, h)
        lt &= covered
        np.copyto(owner[..., 0], k, where=lt)
        deeper = np.less(z, h - tol)
        deeper &= new
        np.copyto(owner[..., 2], owner[..., 1], where=deeper)
        h += tol
        lower = np.less_equal(z, h)
        lower &= covered
        lower &= d2 < dist[..., 0]
        lower |= deeper
        np.copyto(owner[..., 1], k, where=lower)
        np.copyto(dist[..., 0], d2, where=lower)
        latest = d2 < dist[..., 1]
        latest &= covered
        latest |= new
        np.copyto(owner[..., 3], k, where=latest)
        np.copyto(dist[..., 1], d2, where=latest)
        np.copyto(last, k, where=covered)
        self.previous = k
        np.copyto(hv, z, where=lt)

    def cells(self, qx: np.ndarray, qy: np.ndarray) -> np.ndarray:
        """The flat index of the lower-left of the 2 × 2 cells whose centres surround each point
        (qx, qy) [m] (any shape, the same returned), for :meth:`neighbours`. Points off the grid
        read its edge (the caller tests the stock outline)."""
        i = np.minimum(np.maximum(((qx - self.x0) / self.cell).astype(np.int64), 0), self.nx - 2)
        j = np.minimum(np.maximum(((qy - self.y0) / self.cell).astype(np.int64), 0), self.ny - 2)
        return i * self.ny + j

    def neighbours(self, cells: np.ndarray) -> np.ndarray:
        """The flat indices of the 2 × 2 cells at ``cells`` (from :meth:`cells`), shape
        ``cells.shape + (4,)``, for :meth:`read`."""
        return cells[..., None] + self._offsets

    def read(self, flat_owners: np.ndarray, flat_h: np.ndarray, owners: np.ndarray,
             heights: np.ndarray) -> None:
        """Copy the owners of the cells ``flat_owners`` and the heights of the cells ``flat_h``
        (flat indices from :meth:`neighbours`, shape (m,)) into ``owners`` (shape (m, OWNERS),
        int32, −1 where no step has cut) and ``heights`` (shape (m,)) [m]."""
        self._owner_rows.take(flat_owners, axis=0, out=owners)
        self._h_flat.take(flat_h, out=heights)
