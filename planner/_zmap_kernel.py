"""The height grid's step loop compiled (numba): :meth:`planner._zmap_grid.HeightGrid.advance` for
long paths.

Private helper of :mod:`planner._zmap_grid`. :func:`advance` cuts planned steps one after another,
each with the arithmetic of :meth:`~planner._zmap_grid.HeightGrid._geometry` (the sweep over the
cell centres of the step's window) and :meth:`~planner._zmap_grid.HeightGrid._update` (heights and
owners), element by element in the same order of floating-point operations, so that the grid it
leaves is bit for bit the one the numpy path leaves (``tests/test_zmap.py`` checks it). The numpy
path pays about 20 numpy calls a step (≈ 20 µs for the ~440 cells of a window at the default cell
of R/10), whatever the window holds; here a step costs its cells (≈ 1 µs).

numba compiles on the first call of a machine (about a second) and caches the machine code next to
this file (``cache=True``); loading it in a new process costs about 0.3 s, paid once, which is why
the grid uses it only on paths long enough to gain it back (:data:`planner._zmap_grid.COMPILED_STEPS`).
"""

from __future__ import annotations

import math

import numba
import numpy as np

__all__ = ["advance"]


@numba.njit(cache=True, nogil=True)
def advance(order: np.ndarray, start: int, stop: int,
            ax: np.ndarray, ay: np.ndarray, dx: np.ndarray, dy: np.ndarray, inv: np.ndarray,
            za: np.ndarray, dz: np.ndarray,
            x0: float, y0: float, inv_cell: float, xc: np.ndarray, yc: np.ndarray,
            radius: float, tie_tol: float,
            h: np.ndarray, owner: np.ndarray, dist: np.ndarray, last: np.ndarray,
            previous: int) -> int:  # pragma: no cover - compiled; checked bit for bit in tests
    """Cut the steps ``order[start:stop]`` into the grid (``h``, ``owner``, ``dist``, ``last``,
    updated in place) and return the step cut last (``previous`` if none was on the grid).

    The step columns are those of :class:`planner._zmap_grid.Steps` ([m], [1/m²]); ``x0, y0`` the
    grid's origin [m], ``inv_cell`` 1/cell [1/m], ``xc, yc`` the cell centres [m], ``radius`` R [m],
    ``tie_tol`` the grid's level tolerance [m]."""
    nx, ny = h.shape
    r = radius
    r2 = radius * radius
    for p in range(start, stop):
        k = order[p]
        sx, sy, sdx, sdy, sinv = ax[k], ay[k], dx[k], dy[k], inv[k]
        ex, ey = sx + sdx, sy + sdy
        i0 = max(np.ceil((min(sx, ex) - r - x0) * inv_cell), 0.0)
        i1 = min(np.floor((max(sx, ex) + r - x0) * inv_cell) + 1.0, float(nx))
        j0 = max(np.ceil((min(sy, ey) - r - y0) * inv_cell), 0.0)
        j1 = min(np.floor((max(sy, ey) + r - y0) * inv_cell) + 1.0, float(ny))
        if i1 - i0 <= 0.0 or j1 - j0 <= 0.0:  # the window is off the grid: nothing at all
            continue
        step_za, step_dz = za[k], dz[k]
        for i in range(int(i0), int(i1)):
            rx = xc[i] - sx
            rxdx = rx * sdx
            for j in range(int(j0), int(j1)):
                ry = yc[j] - sy
                t = rxdx + ry * sdy
                t *= sinv
                tc = min(max(t, 0.0), 1.0)
                ex_ = rx - tc * sdx
                ey_ = ry - tc * sdy
                d2 = ex_ * ex_ + ey_ * ey_
                if not d2 < r2:
                    continue
                if step_dz != 0.0:  # the lowest end of the interval of t over which the disc covers
                    e = t - tc
                    e *= e
                    e /= sinv
                    e = r2 - (d2 - e)
                    e = max(e, 0.0) * sinv
                    e = math.sqrt(e)
                    if step_dz > 0.0:
                        e = -e
                    ts = min(max(t + e, 0.0), 1.0)
                    z = ts * step_dz + step_za
                else:
                    z = step_za
                hh = h[i, j]
                new = last[i, j] != previous
                lt = z < hh
                if lt:
                    owner[i, j, 0] = k
                deeper = new and z < hh - tie_tol
                if deeper:
                    owner[i, j, 2] = owner[i, j, 1]
                if deeper or (z <= hh + tie_tol and d2 < dist[i, j, 0]):
                    owner[i, j, 1] = k
                    dist[i, j, 0] = d2
                if new or d2 < dist[i, j, 1]:
                    owner[i, j, 3] = k
                    dist[i, j, 1] = d2
                last[i, j] = k
                if lt:
                    h[i, j] = z
        previous = k
    return previous
