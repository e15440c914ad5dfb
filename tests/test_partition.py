"""The fastest split of a cut run into sections of a minimum length, against brute force.

Named problems: random ceiling profiles on short runs with uneven steps (brute force enumerates
every split), and a single notch that a fixed grid of cells straddles.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from planner.partition import fastest_split, split_time
from planner.sections import split_by_length


def _brute(ds: np.ndarray, ceiling: np.ndarray, a: int, b: int, lmin: float) -> float:
    """Fastest time over every split of [a, b) whose sections are all ≥ lmin."""
    best = np.inf
    inner = range(a + 1, b)
    for r in range(len(inner) + 1):
        for cuts in itertools.combinations(inner, r):
            edges = [a, *cuts, b]
            pieces = list(itertools.pairwise(edges))
            if any(ds[x:y].sum() < lmin for x, y in pieces):
                continue
            best = min(best, split_time(ds, ceiling, pieces))
    return best


@pytest.mark.parametrize("seed", range(12))
def test_split_is_the_brute_force_optimum(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(6, 13))
    ds = rng.uniform(0.5e-3, 3e-3, n)
    ds[0] = 0.0 if seed % 2 else ds[0]
    if seed % 3 == 0:
        ds[rng.integers(1, n)] = 0.0  # a repeated CAM point
    ceiling = rng.uniform(0.005, 0.04, n)
    lmin = float(rng.uniform(2e-3, 6e-3))
    pieces = fastest_split(ds, ceiling, 0, n, lmin)
    assert pieces[0][0] == 0 and pieces[-1][1] == n
    assert all(p[1] == q[0] for p, q in itertools.pairwise(pieces))
    assert all(ds[a:b].sum() >= lmin for a, b in pieces)
    assert split_time(ds, ceiling, pieces) == pytest.approx(_brute(ds, ceiling, 0, n, lmin), rel=1e-12)


def test_split_centres_a_notch_that_a_fixed_grid_straddles():
    ds = np.full(41, 1e-3)
    ceiling = np.full(41, 0.04)
    ceiling[19:22] = 0.01  # a 3 mm notch across the grid edge at sample 20
    grid = split_by_length(ds, 0, 41, 10e-3)
    pieces = fastest_split(ds, ceiling, 0, 41, 10e-3)
    t_grid, t_best = split_time(ds, ceiling, grid), split_time(ds, ceiling, pieces)
    # the grid slows two 10 mm cells to the notch's feed, the split one
    assert t_grid == pytest.approx(20e-3 / 0.01 + 21e-3 / 0.04)
    assert t_best == pytest.approx(10e-3 / 0.01 + 31e-3 / 0.04)
    slow = [p for p in pieces if np.min(ceiling[p[0]:p[1]]) < 0.02]
    assert len(slow) == 1 and slow[0][0] <= 19 and slow[0][1] >= 22


def test_short_runs_and_missing_ceilings():
    ds = np.array([0.0, 1e-3, 1e-3])
    assert fastest_split(ds, np.array([np.nan, 0.01, 0.02]), 0, 3, 10e-3) == [(0, 3)]
    ceiling = np.array([np.nan] + [0.02] * 20)
    ds = np.concatenate([[0.0], np.full(20, 1e-3)])
    pieces = fastest_split(ds, ceiling, 0, 21, 5e-3)
    assert split_time(ds, ceiling, pieces) == pytest.approx(20e-3 / 0.02)

