"""The thesis's section algorithm (docs/model.md §8): the baseline the optimiser has to beat.

1. Cut every ``cut`` run into sections of length L_s (equal pieces, none longer than L_s).
2. At each section's midpoint take the stability characteristic: f_max is the midpoint's feed
   limit (here the feed ceiling of :meth:`planner.ceilings.PathModel.ceilings`, which holds the
   thesis's stability and payload (force) limits *and* the deflection and power limits the
   optimiser obeys, so both run under identical limits), f_real = f_max / safety factor.
3. Δγ_max = the distance in γ, at the midpoint, from f_real to that limit: |γ(f_max) − γ(f_real)|.
4. Δγ = the change of γ across the section, γ linearly interpolated (in s, at f_real) between the
   midpoints of neighbouring sections of the run.
5. Halve the sections where |Δγ| ≥ Δγ_max (and γ turns at all); repeat until every section
   passes.

Two additions, because the thesis checks midpoints only and a plan must hold at every sample:
a section also fails (and is halved) while any of its samples has a ceiling below f_real; and no
section is halved below ``section_length_min`` — such a section gets f_real = (its lowest
ceiling) / safety factor instead. The result is reproducible: no randomness, no solver.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from planner.sections import CUT, Section

__all__ = ["ANGLE_TOL", "MAX_ROUNDS", "thesis_sections", "wrap_angle"]

#: A γ change below this is no change [rad] (floating-point noise of interpolated angles).
ANGLE_TOL = 1e-9
#: Halving rounds before giving up refining (each round at least halves the failing sections;
#: 2^30 × L_min exceeds any path).
MAX_ROUNDS = 30


def wrap_angle(a: np.ndarray) -> np.ndarray:
    """Wrap a difference of directions (γ is a direction angle) to (−π/2, π/2] [rad]."""
    return -((-np.asarray(a, float) + np.pi / 2) % np.pi - np.pi / 2)


def _equal_pieces(s: np.ndarray, a: int, b: int, length: float) -> list[tuple[int, int]]:
    """``[a, b)`` in ⌈L / length⌉ pieces of (nearly) equal arc length."""
    s0 = s[a - 1] if a > 0 else s[a]
    total = s[b - 1] - s0
    k = max(1, int(np.ceil(total / length - 1e-9)))
    if k == 1:
        return [(a, b)]
    bounds = s0 + total * np.arange(1, k) / k
    cuts = a + np.searchsorted(s[a:b], bounds, side="right")
    edges = [a, *sorted({int(c) for c in cuts if a < c < b}), b]
    return [(edges[i], edges[i + 1]) for i in range(len(edges) - 1)]


def _length(s: np.ndarray, sec: tuple[int, int]) -> float:
    a, b = sec
    return float(s[b - 1] - (s[a - 1] if a > 0 else s[a]))


def _mid(s: np.ndarray, sec: tuple[int, int]) -> int:
    a, b = sec
    s0 = s[a - 1] if a > 0 else s[a]
    target = 0.5 * (s0 + s[b - 1])
    return a + int(np.argmin(np.abs(s[a:b] - target)))


def thesis_sections(runs: list[tuple[int, int, int]], s: np.ndarray, ceiling: np.ndarray,
                    ceiling_binding: np.ndarray, gamma_at: Callable[[np.ndarray, np.ndarray], np.ndarray],
                    section_length: float, section_length_min: float, safety_factor: float,
                    feed_min: float, every_sample: bool = True) -> list[Section]:
    """The thesis baseline's sections of the ``cut`` runs.

    Args:
        runs: kind runs of the path; only ``cut`` runs are sectioned.
        s: arc length per sample [m], (n,).
        ceiling: feed ceiling per sample [m/s], (n,).
        ceiling_binding: what sets each ceiling, (n,) str.
        gamma_at: ``gamma_at(samples, feeds) -> γ [rad]`` for path sample indices and feeds [m/s].
        section_length: the initial L_s [m].
        section_length_min: no section is halved below this [m].
        safety_factor: f_real = f_max / safety_factor.
        feed_min: lowest feed [m/s].
        every_sample: also require every sample of a section to hold at f_real (module
            docstring); ``False`` is the algorithm exactly as published, midpoints only — its plans
            may break limits between midpoints (the benchmark counts how often).
    """
    out: list[Section] = []
    for a, b, kind in runs:
        if kind != CUT:
            continue
        secs = _equal_pieces(s, a, b, section_length)
        for _ in range(MAX_ROUNDS):
            mids = np.array([_mid(s, x) for x in secs])
            f_max = ceiling[mids]
            f_real = np.maximum(f_max / safety_factor, feed_min)
            g_real = gamma_at(mids, f_real)
            g_max = gamma_at(mids, f_max)
            dg_max = np.abs(wrap_angle(g_max - g_real))
            s_mid = s[mids]
            starts = np.array([s[x[0] - 1] if x[0] > 0 else s[x[0]] for x in secs])
            ends = np.array([s[x[1] - 1] for x in secs])
            if len(secs) > 1:
                g_unwrapped = g_real[0] + np.concatenate([[0.0], np.cumsum(wrap_angle(np.diff(g_real)))])
                dg = (np.interp(ends, s_mid, g_unwrapped) - np.interp(starts, s_mid, g_unwrapped))
            else:
                dg = np.zeros(1)
            low = np.array([every_sample and np.nanmin(ceiling[x[0]:x[1]]) < fr
                            for x, fr in zip(secs, f_real, strict=True)], dtype=bool)
            # a section whose γ does not turn cannot approach the limit (|Δγ| = Δγ_max = 0)
            fail = ((np.abs(dg) >= dg_max) & (np.abs(dg) > ANGLE_TOL)) | low
            splittable = np.array([_length(s, x) >= 2 * section_length_min for x in secs])
            todo = fail & splittable
            if not np.any(todo):
                break
            nxt: list[tuple[int, int]] = []
            for x, split in zip(secs, todo, strict=True):
                pieces = (_equal_pieces(s, x[0], x[1], 0.5 * _length(s, x) + 1e-12) if split
                          else [x])
                if len(pieces) > 1 and min(_length(s, p) for p in pieces) >= section_length_min:
                    nxt += pieces
                else:
                    nxt.append(x)
            if len(nxt) == len(secs):
                break
            secs = nxt
        mids = np.array([_mid(s, x) for x in secs])
        for x, mid in zip(secs, mids, strict=True):
            f_real = max(ceiling[mid] / safety_factor, feed_min)
            lowest = float(np.nanmin(ceiling[x[0]:x[1]]))
            note = ""
            tight = mid
            if every_sample and lowest < f_real:
                f_real = max(lowest / safety_factor, feed_min)
                tight = x[0] + int(np.nanargmin(ceiling[x[0]:x[1]]))
                note = "shortest section still failing at its midpoint feed: lowest ceiling / SF"
            out.append(Section(start=x[0], stop=x[1], kind=CUT,
                               feed=float(min(f_real, lowest) if every_sample else f_real),
                               binding=str(ceiling_binding[tight]), note=note))
    return out
