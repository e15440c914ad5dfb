"""The sample-by-sample scan of :mod:`planner.zmap`: probe the tool circle, then cut the grid.

Private helper of :mod:`planner.zmap` (docs/model.md §8). :func:`scan` walks the path once; at each
probed sample it reads the material left at the probes of the front half of the tool circle, then
the steps that have fallen far enough behind the tool are cut into the grid. :func:`refine`
bisects the open ends of the arcs found, afterwards and all at once.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from planner._zmap_grid import OWNERS, HeightGrid, Steps

__all__ = ["Scan", "Window", "refine", "scan", "window"]

_CHUNK = 1024
"""Probed samples whose probe points, cells and outline test are computed at once [-]."""

_SIDE_NEIGHBOURS = np.arange(-2, 3)
"""Path offsets of the steps tested at the side probes around each owner of their cells [steps]."""

_BISECTION_STEPS = 12
"""Bisection steps refining each open end of an arc [-]: one probe spacing over 4096, 8.5e-6 rad
at 2°, so a_e is resolved to ≈ 1e-5 R where the boundary is a candidate step's edge."""

_BISECT_CHUNK = 4_000
"""Arc ends bisected per vectorised chunk [-] (bounds the (chunk, candidates) temporaries)."""

Inside = Callable[[np.ndarray, np.ndarray], np.ndarray]


@dataclass(frozen=True)
class Window:
    """The recent steps of every probed sample that can reach its front half (CSR layout).

    The recent steps of sample i are the material-removing steps before it that are not yet in the
    grid (the tool is less than ``lag`` further along); of those, a step is kept only if it can
    cover a point of the front half of the tool circle — on a straight or gently curved pass the
    steps behind the tool cannot, on a path curving tighter than R (a small helix) they can.

    Attributes:
        applied: for each sample, the number of removing steps already in the grid, shape (n,).
        ptr: ``step[ptr[j]:ptr[j + 1]]`` are the kept steps of the j-th probed sample, shape (m+1,).
        step: the kept steps (sample indices), shape (ptr[-1],).
        r2: their squared radius for the exact test [m²], shape (ptr[-1],): R − tol for the pass's
            own last steps, R + sliver for the others.
    """

    applied: np.ndarray
    ptr: np.ndarray
    step: np.ndarray
    r2: np.ndarray


def window(pts: np.ndarray, tangent: np.ndarray, s: np.ndarray, sweep: np.ndarray,
           probed: np.ndarray, steps: Steps, radius: float, lag: float, max_recent: int,
           own_length: float, r2_own: float, r2_old: float) -> Window:
    """The :class:`Window` of every probed sample (vectorised over all of them).

    A step with both ends behind the tool (b ≤ 0 along the feed f) at lateral offsets a (along
    X_o) lies at least √((R − |a|)² + b²) from every front-half probe, and a segment at most L/2
    below its ends' value (L its length): it is dropped when both ends clear its radius by that.
    """
    n = pts.shape[0]
    upto = np.searchsorted(sweep, np.arange(n))  # removing steps before each sample
    first = np.searchsorted(s[sweep], s - lag, side="left")
    applied = np.maximum.accumulate(np.minimum(np.maximum(first, upto - max_recent), upto))
    lo, hi = applied[probed], upto[probed]
    count = hi - lo
    owner = np.repeat(np.arange(probed.size), count)
    k = sweep[np.repeat(lo - np.cumsum(count) + count, count) + np.arange(count.sum())]
    i = probed[owner]
    fx, fy = tangent[i, 0], tangent[i, 1]
    r2 = np.where(s[k] >= s[i] - own_length, r2_own, r2_old)
    keep = np.zeros(k.size, dtype=bool)
    length2 = (steps.dx[k] ** 2 + steps.dy[k] ** 2) / 4.0
    for ex, ey in ((steps.ax[k], steps.ay[k]), (steps.ax[k] + steps.dx[k], steps.ay[k] + steps.dy[k])):
        rx, ry = ex - pts[i, 0], ey - pts[i, 1]
        a, b = fx * ry - fy * rx, fx * rx + fy * ry  # along X_o = (−f_y, f_x) and along f
        keep |= (b > 0.0) | ((radius - np.abs(a)) ** 2 + b * b < r2 + length2)
    kept = np.bincount(owner[keep], minlength=probed.size)
    ptr = np.concatenate([[0], np.cumsum(kept)])
    return Window(applied=applied, ptr=ptr, step=k[keep], r2=r2[keep])


@dataclass
class Scan:
    """What :func:`scan` found. Arrays over the n samples; ``ends`` one row per open arc end.

    Attributes:
        engaged: a probe met material, shape (n,).
        first, last: the first and last engaged probe bins, shape (n,).
        a_p: the tallest material met above max(tip, stock bottom) [m], shape (n,).
        ends: (sample, air bin, material bin), shape (m, 3).
        owners: candidate steps of each end (the owners of the cells around both probes), (m, 32).
    """

    engaged: np.ndarray
    first: np.ndarray
    last: np.ndarray
    a_p: np.ndarray
    ends: np.ndarray
    owners: np.ndarray


def scan(pts: np.ndarray, tangent: np.ndarray, probe: np.ndarray, clears: np.ndarray,
         floor: np.ndarray, s: np.ndarray, grid: HeightGrid, steps: Steps, win: Window,
         sweep: np.ndarray, theta: np.ndarray, radius: float, r2_own: float, r2_old: float,
         own_length: float, z_top: float, depth_tol: float, inside: Inside) -> Scan:
    """Walk the path: at each probed sample read the front half of the tool circle (probe angles
    ``theta`` [rad]), then cut the steps that have fallen ``lag`` behind into the grid.

    The height h at a probe q is the lowest of the exact sweeps over q of its candidate steps —
    the owners of the 2 × 2 cells around q and the sample's kept recent steps — or, if none covers
    q, the tallest of those four cells. Where the four cells stand level (within ``depth_tol``) and
    no recent step can reach the front half, there is no boundary near q and h is that level,
    read without the exact test; the side probes (tangent to the bands of earlier passes along the
    same line) are always tested exactly, against their owners' path neighbours too. q engages if
    ``inside`` the outline and h stands more than ``depth_tol`` above ``floor`` (max(tip, stock
    bottom)). ``s`` is the path length at each sample [m]; steps less than ``own_length`` behind
    are tested with ``r2_own``, older ones with ``r2_old`` [m²].
    """
    n, bins = pts.shape[0], theta.size
    cos_t, sin_t = np.cos(theta), np.sin(theta)
    last_bin = bins - 1
    side = np.zeros(bins, dtype=bool)
    side[[0, last_bin]] = True
    probed = np.flatnonzero(probe)
    rank = np.cumsum(probe) - 1
    out = Scan(engaged=np.zeros(n, dtype=bool), first=np.zeros(n, dtype=np.int64),
               last=np.zeros(n, dtype=np.int64), a_p=np.zeros(n), ends=np.zeros((0, 3), np.int64),
               owners=np.zeros((0, 8 * OWNERS), np.int64))
    ends: list[tuple[int, int, int]] = []
    end_owners: list[np.ndarray] = []
    applied_of, sweep_list, ptr = win.applied.tolist(), sweep.tolist(), win.ptr.tolist()
    applied, chunk = 0, -1
    for i in np.flatnonzero(probe | clears).tolist():
        target = applied_of[i]
        while applied < target:
            grid.remove(sweep_list[applied], radius)
            applied += 1
        if not probe[i]:
            continue
        row = int(rank[i])
        if row // _CHUNK != chunk:  # the probes of the next _CHUNK probed samples, at once
            chunk = row // _CHUNK
            rows = probed[chunk * _CHUNK:(chunk + 1) * _CHUNK]
            fx, fy = tangent[rows, 0, None], tangent[rows, 1, None]
            all_qx = pts[rows, 0, None] + radius * (fx * sin_t - fy * cos_t)  # q = c + R n(φ),
            all_qy = pts[rows, 1, None] + radius * (fy * sin_t + fx * cos_t)  # n = cos φ X_o + sin φ f
            all_in = inside(all_qx, all_qy)
            all_cells = grid.cells(all_qx, all_qy)
        j0, j1 = ptr[row], ptr[row + 1]
        r = row - chunk * _CHUNK
        owners, cell_h = grid.neighbourhood(all_cells[r])
        h = cell_h.max(axis=1)
        qx, qy = all_qx[r], all_qy[r]
        # Candidate (probe, step) pairs: the owners of the probes' cells where the four cells do
        # not stand level (a boundary is near) or at the sides; the side probes touch the bands of
        # earlier passes along the same line (a pocket's level above, a helix's previous turn)
        # within 1e-4 R, where only the step passing right beside a probe covers it and the cells'
        # owners are the closest steps to their own centres, up to a cell along: their path
        # neighbours are tested too; and every probe against the recent steps that can reach the
        # front half (on a path curving tighter than R).
        if j1 > j0:
            exact = np.arange(bins)
        else:
            exact = np.flatnonzero(side | (h - cell_h.min(axis=1) > depth_tol))
        pi, ci = np.nonzero(owners[exact] >= 0)
        rows_, ks = [exact[pi]], [owners[exact][pi, ci]]
        near = (owners[[0, last_bin]][:, :, None] + _SIDE_NEIGHBOURS).reshape(2, -1)
        si, sj = np.nonzero((near >= 0) & (near < i))  # earlier steps only
        rows_.append(np.where(si == 0, 0, last_bin))
        ks.append(near[si, sj])
        if j1 > j0:
            m = j1 - j0
            rows_.append(np.repeat(np.arange(bins), m))
            ks.append(np.tile(win.step[j0:j1], bins))
        rows_all, k_all = np.concatenate(rows_), np.concatenate(ks)
        r2 = np.where(s[k_all] >= s[i] - own_length, r2_own, r2_old)
        best = np.full(bins, np.inf)
        np.minimum.at(best, rows_all, steps.height(qx[rows_all], qy[rows_all], k_all, r2))
        h = np.where(best < np.inf, best, h)
        np.minimum(h, z_top, out=h)
        mat = (h > floor[i] + depth_tol) & all_in[r]
        if not mat.any():
            continue
        lo = int(mat.argmax())
        hi = last_bin - int(mat[::-1].argmax())
        out.engaged[i], out.first[i], out.last[i] = True, lo, hi
        out.a_p[i] = float(h[mat].max()) - floor[i]
        for air, other in ((lo - 1, lo), (hi + 1, hi)):
            if 0 <= air <= last_bin:
                ends.append((i, air, other))
                end_owners.append(owners[[air, other]].ravel())
    if ends:
        out.ends, out.owners = np.asarray(ends, dtype=np.int64), np.vstack(end_owners)
    return out


def refine(found: Scan, win: Window, probe: np.ndarray, theta: np.ndarray, pts: np.ndarray,
           tangent: np.ndarray, radius: float, steps: Steps, floor: np.ndarray, inside: Inside,
           r2_old: float, depth_tol: float) -> np.ndarray:
    """The open arc ends of ``found`` [rad], shape (m,), bisected between their air and material
    probes against the outline and the exact sweeps of their candidate steps: the owners of the
    cells around both probes and the sample's kept recent steps."""
    ends = found.ends
    out = np.empty(ends.shape[0])
    rank = np.cumsum(probe) - 1
    for c0 in range(0, ends.shape[0], _BISECT_CHUNK):
        sl = slice(c0, c0 + _BISECT_CHUNK)
        r = ends[sl, 0]
        lo, hi = win.ptr[rank[r]], win.ptr[rank[r] + 1]
        width = int((hi - lo).max(initial=0))
        pos = lo[:, None] + np.arange(width)[None, :]
        mine = pos < hi[:, None]
        at = np.minimum(pos, max(win.step.size - 1, 0))
        recent = np.where(mine, win.step[at] if win.step.size else -1, -1)
        rad2 = np.where(mine, win.r2[at] if win.r2.size else r2_old, r2_old)
        k = np.hstack([found.owners[sl], recent.reshape(r.size, width)])
        rad2 = np.hstack([np.full(found.owners[sl].shape, r2_old), rad2.reshape(r.size, width)])
        air, mat = theta[ends[sl, 1]], theta[ends[sl, 2]]
        cx, cy, fx, fy, lim = pts[r, 0], pts[r, 1], tangent[r, 0], tangent[r, 1], floor[r]
        for _ in range(_BISECTION_STEPS):
            mid = 0.5 * (air + mat)
            c, sn = radius * np.cos(mid), radius * np.sin(mid)
            qx, qy = cx - fy * c + fx * sn, cy + fx * c + fy * sn
            h = steps.height(qx[:, None], qy[:, None], k, rad2).min(axis=1)
            material = inside(qx, qy) & ~(h <= lim + depth_tol)
            mat = np.where(material, mid, mat)
            air = np.where(material, air, mid)
        out[sl] = 0.5 * (air + mat)
    return out
