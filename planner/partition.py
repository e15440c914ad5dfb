"""Section boundaries: the fastest split of a cut run into sections no shorter than a minimum.

A section runs at one feed, so its feed can be at most the lowest feed ceiling of its samples.
Given the ceilings f̂_k along a run and the shortest allowed section L_min, the fastest plan solves

    minimise   Σ_i L_i / min_{k ∈ i} f̂_k     over the splits of the run into sections i,
    subject to L_i ≥ L_min (a run shorter than L_min is one section).

:func:`fastest_split` solves it exactly by dynamic programming over the samples. A section of
length ≥ 2 L_min + 2 max(ds) can always be cut in two that are both ≥ L_min, and cutting never
slows a plan (the minimum over a part is at least the minimum over the whole), so only sections
shorter than that need to be tried: the work is O(n · w), w the samples in such a window.

The optimiser (:mod:`planner.optimize`) uses these sections as its cells: IPOPT then picks the
feeds under the couplings a split cannot see (bounded feed change, the price of a feed change),
merging neighbours whose feeds come out equal. Without those couplings the split is the optimum
itself, so :func:`split_time` is a lower bound on the machining time of any plan that keeps the
minimum section length, and the benchmark reports how close each method comes to it.
"""

from __future__ import annotations

import numpy as np

from planner.sections import CUT, split_by_length

__all__ = ["cut_time_bound", "fastest_split", "fastest_splits", "split_time"]


def _section_times(length: np.ndarray, ceiling_min: np.ndarray) -> np.ndarray:
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(length > 0, length / ceiling_min, 0.0)


def fastest_split(ds: np.ndarray, ceiling: np.ndarray, start: int, stop: int,
                  length_min: float) -> list[tuple[int, int]]:
    """The fastest split of samples ``[start, stop)`` into sections at least ``length_min`` long.

    Args:
        ds: step length per sample [m], (n,) (:func:`planner.sections.step_lengths`).
        ceiling: feed ceiling per sample [m/s], (n,); NaN (a sample without a model, e.g. the
            path's first) limits nothing.
        start, stop: the run.
        length_min: shortest section [m].

    Returns:
        ``(a, b)`` sample ranges in order, covering the run.
    """
    steps = np.asarray(ds[start:stop], float)
    cum = np.concatenate([[0.0], np.cumsum(steps)])  # cum[k]: length of samples start..start+k-1
    n = stop - start
    if n <= 1 or cum[-1] < length_min:
        return [(start, stop)]
    c = np.asarray(ceiling[start:stop], float)
    c = np.where(np.isfinite(c), c, np.inf)
    window = 2.0 * length_min + 2.0 * float(steps.max())
    best = np.full(n + 1, np.inf)
    best[0] = 0.0
    came = np.zeros(n + 1, dtype=int)
    for j in range(1, n + 1):
        lo = int(np.searchsorted(cum, cum[j] - window, side="left"))
        hi = int(np.searchsorted(cum, cum[j] - length_min, side="right"))  # last i with L ≥ L_min
        if hi <= lo:
            continue
        # lowest ceiling of samples i..j-1 for every i in [lo, j), then keep i < hi
        low = np.minimum.accumulate(c[lo:j][::-1])[::-1][: hi - lo]
        i = np.arange(lo, hi)
        cost = best[lo:hi] + _section_times(cum[j] - cum[i], low)
        k = int(np.argmin(cost))
        if np.isfinite(cost[k]):
            best[j], came[j] = cost[k], lo + k
    if not np.isfinite(best[n]):  # cannot happen for a run ≥ L_min; keep a valid split anyway
        return split_by_length(ds, start, stop, length_min)
    out: list[tuple[int, int]] = []
    j = n
    while j > 0:
        out.append((start + int(came[j]), start + j))
        j = int(came[j])
    return out[::-1]


def split_time(ds: np.ndarray, ceiling: np.ndarray, pieces: list[tuple[int, int]]) -> float:
    """Σ L_i / (lowest ceiling of section i) over ``pieces`` [s]."""
    if not pieces:
        return 0.0
    length = np.array([ds[a:b].sum() for a, b in pieces])
    low = np.array([np.min(np.where(np.isfinite(ceiling[a:b]), ceiling[a:b], np.inf))
                    for a, b in pieces])
    return float(_section_times(length, low).sum())


def fastest_splits(runs: list[tuple[int, int, int]], ds: np.ndarray, ceiling: np.ndarray,
                   length_min: float) -> list[list[tuple[int, int]]]:
    """:func:`fastest_split` of every ``cut`` run of ``runs`` (:func:`planner.sections.kind_runs`)."""
    return [fastest_split(ds, ceiling, a, b, length_min) for a, b, kind in runs if kind == CUT]


def cut_time_bound(splits: list[list[tuple[int, int]]], ds: np.ndarray, ceiling: np.ndarray) -> float:
    """The least cut time Σ L/f any plan with sections ≥ the minimum length can have [s].

    Args:
        splits: :func:`fastest_splits` of the path's cut runs.
        ds: step length per sample [m], (n,).
        ceiling: feed ceiling per sample [m/s], (n,).
    """
    return sum(split_time(ds, ceiling, pieces) for pieces in splits)
