"""The sample-by-sample scan of :mod:`planner.zmap`: probe the tool circle, then cut the grid.

Private helper of :mod:`planner.zmap` (docs/model.md §8). :func:`scan` walks the path once; at each
probed sample it reads the material left at the probes of the front half of the tool circle, then
the steps that have fallen far enough behind the tool are cut into the grid. :func:`refine`
bisects the open ends of the arcs found, afterwards and all at once.

Only the owners and heights of the cells around a sample's probes depend on where the walk is:
they are copied out of the grid when the sample is reached, and the rest of the reading (the
candidate steps, their exact sweeps, the arc) is done for a batch of samples at once (:func:`_read`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

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

    Only the cells' owners and heights depend on the order of the walk: they are copied out of the
    grid at each probed sample, and everything else — the candidates, their exact sweeps, the arc —
    is computed for :data:`_BATCH` probed samples at once (:func:`_read`).
    """
    n, bins = pts.shape[0], theta.size
    cos_t, sin_t = np.cos(theta), np.sin(theta)
    probed = np.flatnonzero(probe)
    rank = (np.cumsum(probe) - 1).tolist()
    out = Scan(engaged=np.zeros(n, dtype=bool), first=np.zeros(n, dtype=np.int64),
               last=np.zeros(n, dtype=np.int64), a_p=np.zeros(n), ends=np.zeros((0, 3), np.int64),
               owners=np.zeros((0, 8 * OWNERS), np.int64))
    ctx = _Context(pts=pts, probed=probed, floor=floor, s=s, steps=steps, win=win, bins=bins,
                   r2_own=r2_own, r2_old=r2_old, own_length=own_length, z_top=z_top,
                   depth_tol=depth_tol, out=out, reach=_reach(steps, grid.cell))
    own_buf = np.empty((_BATCH, bins * 4, OWNERS), dtype=grid.owner.dtype)
    h_buf = np.empty((_BATCH, bins * 4))
    applied_of, probe_of = win.applied.tolist(), probe.tolist()
    grid.plan(sweep, radius)
    applied, chunk, slot, batch0 = 0, -1, 0, 0
    geometry: tuple[np.ndarray, ...] = (h_buf,) * 5
    for i in np.flatnonzero(probe | clears).tolist():
        target = applied_of[i]
        if applied < target:
            grid.advance(target)
            applied = target
        if not probe_of[i]:
            continue
        row = rank[i]
        if row // _CHUNK != chunk:  # the probes of the next _CHUNK probed samples, at once
            chunk = row // _CHUNK
            rows = probed[chunk * _CHUNK:(chunk + 1) * _CHUNK]
            fx, fy = tangent[rows, 0, None], tangent[rows, 1, None]
            all_qx = pts[rows, 0, None] + radius * (fx * sin_t - fy * cos_t)  # q = c + R n(φ),
            all_qy = pts[rows, 1, None] + radius * (fy * sin_t + fx * cos_t)  # n = cos φ X_o + sin φ f
            around = grid.neighbours(grid.cells(all_qx, all_qy))  # (row, bin, corner)
            geometry = (all_qx, all_qy, inside(all_qx, all_qy), around.reshape(rows.size, -1),
                        around.transpose(0, 2, 1).reshape(rows.size, -1))
        r = row - chunk * _CHUNK
        grid.read(geometry[3][r], geometry[4][r], own_buf[slot], h_buf[slot])
        if slot == 0:
            batch0 = row
        slot += 1
        if slot == _BATCH or row + 1 == probed.size or (row + 1) % _CHUNK == 0:
            at = np.s_[batch0 - chunk * _CHUNK:row + 1 - chunk * _CHUNK]
            _read(ctx, batch0, own_buf[:slot], h_buf[:slot], geometry[0][at], geometry[1][at],
                  geometry[2][at])
            slot = 0
    if ctx.ends:
        out.ends, out.owners = np.concatenate(ctx.ends), np.concatenate(ctx.end_owners)
    return out


_BATCH = 64
"""Probed samples whose candidates and exact sweeps :func:`_read` computes at once [-] (fewer at
the end of a :data:`_CHUNK`; about 30 000 candidate pairs at the default cell, which stay in the
cache)."""


@dataclass
class _Context:
    """What :func:`_read` needs besides the batch, and where it writes."""

    pts: np.ndarray
    probed: np.ndarray
    floor: np.ndarray
    s: np.ndarray
    steps: Steps
    win: Window
    bins: int
    r2_own: float
    r2_old: float
    own_length: float
    z_top: float
    depth_tol: float
    out: Scan
    reach: np.ndarray = field(default_factory=lambda: _SIDE_NEIGHBOURS)
    ends: list[np.ndarray] = field(default_factory=list)
    end_owners: list[np.ndarray] = field(default_factory=list)


def _read(ctx: _Context, row0: int, cell_owners: np.ndarray, cell_h: np.ndarray, qx: np.ndarray,
          qy: np.ndarray, within: np.ndarray) -> None:
    """Read the probed samples ``row0, row0 + 1, …`` (ranks among the probed ones) from the owners
    (shape (m, bins · 4, OWNERS), bin-major) and heights (shape (m, 4 · bins), corner-major) of the
    2 × 2 cells around their probes, copied out of the grid when each was reached; ``qx, qy`` their
    probes [m], ``within`` the outline test, shape (m, bins). Each (probe, candidate step) pair is
    tested once."""
    m, bins = cell_h.shape[0], ctx.bins
    last_bin = bins - 1
    rows = np.arange(row0, row0 + m)
    i = ctx.probed[rows]
    owners = cell_owners.reshape(m, bins, 4 * OWNERS)
    ch = cell_h.reshape(m, 4, bins)
    h = np.maximum(np.maximum(ch[:, 0], ch[:, 1]), np.maximum(ch[:, 2], ch[:, 3]))
    low = np.minimum(np.minimum(ch[:, 0], ch[:, 1]), np.minimum(ch[:, 2], ch[:, 3]))
    lo_ptr, hi_ptr = ctx.win.ptr[rows], ctx.win.ptr[rows + 1]
    recent = hi_ptr - lo_ptr
    # The candidate (probe, step) pairs, as flat probe index g = row · bins + bin and step k: the
    # owners of the probes' cells where the four cells do not stand level (a boundary is near) or
    # at the sides; the side probes touch the bands of earlier passes along the same line (a
    # pocket's level above, a helix's previous turn) within 1e-4 R, where only the step passing
    # right beside a probe covers it and the cells' owners are the closest steps to their own
    # centres, up to a cell along: their path neighbours are tested too; and every probe against
    # the recent steps that can reach the front half (on a path curving tighter than R). The
    # exact sweep is a minimum: a step repeated among a probe's candidates is tested once. First
    # the owners where the cells do not stand level (at every probe where recent steps can reach
    # the front half) ...
    exact = h - low > ctx.depth_tol
    exact |= (recent > 0)[:, None]
    exact[:, 0] = exact[:, last_bin] = False  # the side probes: below, with their neighbours
    g_own = np.flatnonzero(exact)
    width = 4 * OWNERS
    cand = owners.reshape(m * bins, width).take(g_own, axis=0)
    cand.sort(axis=1)
    at, k_own = _distinct(cand, cand >= 0)
    row_of = at >> _CAND_SHIFT if 1 << _CAND_SHIFT == width else at // width
    gs, ks, rs = [g_own[row_of]], [k_own], [(g_own // bins)[row_of]]
    # ... at the side probes, the owners and their path neighbours (earlier steps only) ...
    near = (owners[:, [0, last_bin], :, None] + _SIDE_NEIGHBOURS).reshape(2 * m, -1)
    near.sort(axis=1)
    width = near.shape[1]
    at, k_side = _distinct(near, (near >= 0) & (near < np.repeat(i, 2)[:, None]))
    side_row = at // width
    gs.append(side_row // 2 * bins + (side_row % 2) * last_bin)
    ks.append(k_side)
    rs.append(side_row // 2)
    g_grid = np.concatenate(gs)
    r_grid = np.concatenate(rs)
    k_grid = np.concatenate(ks)
    r2_grid = np.where(ctx.s[k_grid] >= (ctx.s[i] - ctx.own_length)[r_grid], ctx.r2_own,
                       ctx.r2_old)
    # ... and every probe against the recent steps that can reach the front half (on a path
    # curving tighter than R), with the window's radius (the same rule)
    p0, p1 = int(ctx.win.ptr[row0]), int(ctx.win.ptr[row0 + m])
    if p1 > p0:
        row_r = np.repeat(np.arange(m), recent)
        g = np.concatenate([g_grid, np.repeat(row_r * bins, bins)
                            + np.tile(np.arange(bins), p1 - p0)])
        k = np.concatenate([k_grid, np.repeat(ctx.win.step[p0:p1], bins)])
        r2 = np.concatenate([r2_grid, np.repeat(ctx.win.r2[p0:p1], bins)])
    else:
        g, k, r2 = g_grid, k_grid, r2_grid
    best = np.full(m * bins, np.inf)
    for c0 in range(0, g.size, _PAIR_CHUNK):
        sl = np.s_[c0:c0 + _PAIR_CHUNK]
        gg = g[sl]
        np.minimum.at(best, gg, ctx.steps.height(qx.reshape(-1).take(gg), qy.reshape(-1).take(gg),
                                                 k[sl], r2[sl]))
    # Probes where the cells disagree and no candidate's sweep covers them: with several steps
    # to a cell (fine sampling), the step that passed over the probe may lie further along the
    # path than the cells' owners (the steps closest to the cell centres); their path
    # neighbours within two cells are tested too, so the probe is not read as the tallest cell
    # (the material an earlier pass removed)
    miss = np.flatnonzero((best == np.inf) & ((h - low) > ctx.depth_tol).reshape(-1))
    if miss.size:
        own = owners.reshape(m * bins, 4 * OWNERS).take(miss, axis=0)
        near = (own[:, :, None] + ctx.reach).reshape(miss.size, -1)
        near.sort(axis=1)
        width = near.shape[1]
        at, k_near = _distinct(near, (near >= 0) & (near < i[miss // bins][:, None]))
        g_m = miss[at // width]
        r2_m = np.where(ctx.s[k_near] >= (ctx.s[i] - ctx.own_length)[g_m // bins], ctx.r2_own,
                        ctx.r2_old)
        for c0 in range(0, g_m.size, _PAIR_CHUNK):
            sl = np.s_[c0:c0 + _PAIR_CHUNK]
            gg = g_m[sl]
            np.minimum.at(best, gg, ctx.steps.height(qx.reshape(-1).take(gg),
                                                     qy.reshape(-1).take(gg), k_near[sl],
                                                     r2_m[sl]))
    hf = h.reshape(-1)
    np.copyto(hf, best, where=best < np.inf)
    np.minimum(h, ctx.z_top, out=h)
    floor = ctx.floor[i]
    mat = h > (floor + ctx.depth_tol)[:, None]
    mat &= within
    engaged = mat.any(axis=1)
    if not engaged.any():
        return
    lo = mat.argmax(axis=1)
    hi = last_bin - mat[:, ::-1].argmax(axis=1)
    a_p = np.where(mat, h, -np.inf).max(axis=1) - floor
    e = np.flatnonzero(engaged)
    out, ie = ctx.out, i[e]
    out.engaged[ie], out.first[ie], out.last[ie], out.a_p[ie] = True, lo[e], hi[e], a_p[e]
    # the open ends, (sample, air bin, material bin), per sample the low end first
    air = np.column_stack([lo[e] - 1, hi[e] + 1])
    other = np.column_stack([lo[e], hi[e]])
    is_end = (air >= 0) & (air <= last_bin)
    er, ec = np.nonzero(is_end)
    if er.size:
        a, o = air[er, ec], other[er, ec]
        ctx.ends.append(np.column_stack([ie[er], a, o]).astype(np.int64))
        sel = owners[e[er]]
        ctx.end_owners.append(np.concatenate([sel[np.arange(er.size), a],
                                              sel[np.arange(er.size), o]], axis=1).astype(np.int64))


def _reach(steps: Steps, cell: float) -> np.ndarray:
    """Path offsets [steps] within which a step can pass over a probe whose 2 × 2 cells another
    step owns: two cells along the path at the typical (median) step length, at least
    :data:`_SIDE_NEIGHBOURS`' ±2, at most ±:data:`_MAX_REACH`."""
    length = np.hypot(steps.dx, steps.dy)
    length = length[length > 0]
    typical = float(np.median(length)) if length.size else cell
    k = int(min(max(math.ceil(2.0 * cell / max(typical, 1e-12)) + 1, 2), _MAX_REACH))
    return np.arange(-k, k + 1)


_MAX_REACH = 64
"""Largest path offset :func:`_reach` tests around an owner [steps] (bounds the candidates of a
probe at very fine sampling: 16 owners × 129)."""


def _distinct(cand: np.ndarray, valid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The flat positions and values of the valid entries of ``cand`` (rows sorted, shape (r, w))
    that differ from their predecessor in the row: each row's distinct valid candidates."""
    flat = cand.reshape(-1)
    first = valid[:, 0].copy()
    keep = valid.reshape(-1)
    keep[1:] &= flat[1:] != flat[:-1]
    keep[::cand.shape[1]] = first  # a row's first entry has no predecessor
    at = np.flatnonzero(keep)
    return at, flat.take(at)


_CAND_SHIFT = (4 * OWNERS).bit_length() - 1
"""log2 of the candidates per probe (4 cells × OWNERS, a power of two) [-]: a shift divides."""

_PAIR_CHUNK = 32_768
"""Candidate pairs whose exact sweeps are computed at once [-] (the temporaries stay in the cache)."""


def refine(found: Scan, win: Window, probe: np.ndarray, theta: np.ndarray, pts: np.ndarray,
           tangent: np.ndarray, radius: float, steps: Steps, floor: np.ndarray, inside: Inside,
           r2_old: float, depth_tol: float) -> np.ndarray:
    """The open arc ends of ``found`` [rad], shape (m,), bisected between their air and material
    probes against the outline and the exact sweeps of their candidate steps: the owners of the
    cells around both probes and the sample's kept recent steps (each tested once)."""
    ends = found.ends
    out = np.empty(ends.shape[0])
    rank = np.cumsum(probe) - 1
    for c0 in range(0, ends.shape[0], _BISECT_CHUNK):
        sl = slice(c0, c0 + _BISECT_CHUNK)
        r = ends[sl, 0]
        size = r.size
        cand = np.sort(found.owners[sl], axis=1)
        at, k_own = _distinct(cand, cand >= 0)
        lo, hi = win.ptr[rank[r]], win.ptr[rank[r] + 1]
        count = hi - lo
        start = np.cumsum(count) - count
        pos = np.arange(int(count.sum())) - np.repeat(start - lo, count)
        end = np.concatenate([at // cand.shape[1], np.repeat(np.arange(size), count)])
        k = np.concatenate([k_own, win.step[pos]])
        rad2 = np.concatenate([np.full(at.size, r2_old), win.r2[pos]])
        air, mat = theta[ends[sl, 1]], theta[ends[sl, 2]]
        cx, cy, fx, fy, lim = pts[r, 0], pts[r, 1], tangent[r, 0], tangent[r, 1], floor[r]
        lim = lim + depth_tol
        best = np.empty(size)
        for _ in range(_BISECTION_STEPS):
            mid = 0.5 * (air + mat)
            c, sn = radius * np.cos(mid), radius * np.sin(mid)
            qx, qy = cx - fy * c + fx * sn, cy + fx * c + fy * sn
            best.fill(np.inf)
            np.minimum.at(best, end, steps.height(qx.take(end), qy.take(end), k, rad2))
            material = inside(qx, qy) & ~(best <= lim)
            mat = np.where(material, mid, mat)
            air = np.where(material, air, mid)
        out[sl] = 0.5 * (air + mat)
    return out
