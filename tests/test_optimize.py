"""The section optimiser (planner/optimize.py) on synthetic ceilings, against closed forms.

No robot and no job: the inputs are what :func:`planner.plan.plan_prepared` hands on (kind runs,
step lengths, a ceiling and its binding per sample). Oracles:

* no feed-change bound and no price: every cell at its lowest ceiling, cut time Σ L/f̂ =
  :func:`planner.partition.cut_time_bound` of the exact fastest split;
* a price c [s] per change of feed_max on two cells (a fast one of length L₁ next to a slow one at
  f₂): the fast cell runs at clip(√(L₁ f_max / c), f₂, f̂₁), the minimum of L₁/f + c (f − f₂)/f_max;
* a feed-change bound Δ next to a notch: each cell at min(f̂, neighbour + Δ), a ramp.

Named problems:
    NOTCH: 40 mm of 1 mm steps at 40 mm/s with a 3 mm notch at 10 mm/s (samples 19..21),
        sections ≥ 10 mm: one 10 mm slow section around the notch, 1.75 s.
    TWO_CELLS: a 10 mm cell at 40 mm/s (force-bound) then a 20 mm cell at 5 mm/s
        (deflection-bound), cells given.
    RAMP: five 10 mm cells at 40, 40, 5, 40, 40 mm/s, cells given.
"""

from __future__ import annotations

import numpy as np
import pytest

from models.errors import CctmillError
from planner.optimize import MERGE_TOL, PlanSolverError, optimize_sections
from planner.partition import cut_time_bound, fastest_splits
from planner.sections import AIR, CUT, RAPID, kind_runs

FEED_MIN = 0.5e-3  # [m/s]
FEED_MAX = 40e-3  # [m/s]
#: The solver's feeds sit within IPOPT's tolerance (1e-9 on the scaled problem) of their optimum;
#: clipped into the bounds, they are within this fraction of the closed form [-].
FEED_RTOL = 1e-6
#: A feed held between bounds by a price sits where the objective is flat: IPOPT's 1e-9 on the
#: objective leaves ~sqrt(1e-9) of it in the feed [-].
FLAT_RTOL = 1e-4


def _steps(n: int, step: float = 1e-3) -> np.ndarray:
    """Step lengths [m] of ``n`` samples, ``ds[0] = 0`` (planner.sections.step_lengths)."""
    ds = np.full(n, step)
    ds[0] = 0.0
    return ds


def _cut_time(ds: np.ndarray, sections) -> float:
    return float(sum(ds[s.start:s.stop].sum() / s.feed for s in sections))


def _solve(runs, ds, ceiling, binding=None, *, lmin=10e-3, change_max=None, cost=0.0, **kw):
    binding = np.full(ds.size, "deflection") if binding is None else binding
    return optimize_sections(runs, ds, ceiling, binding, kw.pop("feed_min", FEED_MIN),
                             kw.pop("feed_max", FEED_MAX), lmin, change_max, cost, **kw)


def _notch():
    ds = _steps(41)
    ceiling = np.full(41, 40e-3)
    ceiling[19:22] = 10e-3
    return [(0, 41, CUT)], ds, ceiling


def _two_cells():
    ds = _steps(31)
    ceiling = np.where(np.arange(31) < 11, 40e-3, 5e-3)
    binding = np.where(np.arange(31) < 11, "force", "deflection")
    return [(0, 31, CUT)], ds, ceiling, binding, [[(0, 11), (11, 31)]]


def _ramp():
    ds = _steps(51)
    caps = [40e-3, 40e-3, 5e-3, 40e-3, 40e-3]
    cells = [(0, 11), (11, 21), (21, 31), (31, 41), (41, 51)]
    ceiling = np.concatenate([np.full(b - a, c) for (a, b), c in zip(cells, caps, strict=True)])
    return [(0, 51, CUT)], ds, ceiling, [cells]


# ---------------------------------------------------------------------------------- closed forms


def test_notch_without_couplings_is_the_exact_fastest_split():
    runs, ds, ceiling = _notch()
    sections, solve = _solve(runs, ds, ceiling)
    assert solve.success and solve.status == "Solve_Succeeded" and solve.iterations > 0
    assert solve.build_time >= 0.0 and solve.solve_time >= 0.0
    np.testing.assert_allclose([s.feed for s in sections], [40e-3, 10e-3, 40e-3], rtol=FEED_RTOL)
    slow = sections[1]
    assert slow.start <= 19 and slow.stop >= 22
    assert ds[slow.start:slow.stop].sum() == pytest.approx(10e-3)  # as short as allowed
    # 10 mm at 10 mm/s + 30 mm at 40 mm/s, the bound no plan with 10 mm sections can beat
    assert _cut_time(ds, sections) == pytest.approx(10e-3 / 10e-3 + 30e-3 / 40e-3, rel=FEED_RTOL)
    bound = cut_time_bound(fastest_splits(runs, ds, ceiling, 10e-3), ds, ceiling)
    assert bound == pytest.approx(1.75, rel=1e-12)
    assert [s.binding for s in sections] == ["deflection"] * 3
    assert all(s.kind == CUT for s in sections)


@pytest.mark.parametrize("seed", range(8))
def test_without_couplings_every_cell_runs_at_its_lowest_ceiling(seed):
    """Random profiles over several cut runs (air and rapid runs between, NaN ceilings there)."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(60, 120))
    ds = rng.uniform(0.3e-3, 2e-3, n)
    ds[0] = 0.0
    ds[rng.integers(1, n)] = 0.0  # a repeated CAM point
    ceiling = np.exp(rng.uniform(np.log(1e-3), np.log(FEED_MAX), n))
    kinds = np.full(n, CUT)
    a = int(rng.integers(15, n // 2))
    kinds[a:a + 5] = AIR
    kinds[a + 5:a + 7] = RAPID
    ceiling[kinds != CUT] = np.nan
    runs = kind_runs(kinds)
    lmin = float(rng.uniform(2e-3, 8e-3))
    binding = rng.choice(["force", "deflection", "power", "chatter"], n)
    sections, solve = _solve(runs, ds, ceiling, binding, lmin=lmin)
    assert solve.success
    covered = np.zeros(n, int)
    for s in sections:
        covered[s.start:s.stop] += 1
    np.testing.assert_array_equal(covered, kinds == CUT)  # every cut sample once, nothing else
    splits = fastest_splits(runs, ds, ceiling, lmin)
    cells = [c for g in splits for c in g]
    for s in sections:
        inside = [c for c in cells if s.start <= c[0] and c[1] <= s.stop]
        assert inside[0][0] == s.start and inside[-1][1] == s.stop  # a union of whole cells
        for a_, b_ in inside:
            # merged cells differ by at most MERGE_TOL · feed_max; the section takes the lowest
            assert s.feed == pytest.approx(np.nanmin(ceiling[a_:b_]), rel=FEED_RTOL,
                                           abs=MERGE_TOL * FEED_MAX)
            assert s.feed <= np.nanmin(ceiling[a_:b_]) * (1 + 1e-12)
        tight = s.start + int(np.nanargmin(ceiling[s.start:s.stop]))
        assert s.binding == binding[tight]
    assert _cut_time(ds, sections) == pytest.approx(cut_time_bound(splits, ds, ceiling),
                                                    rel=FEED_RTOL)


@pytest.mark.parametrize(("cost", "fast_feed"), [
    (0.0, 40e-3),     # no price: both at their ceilings
    (0.25, 40e-3),    # sqrt(L1 f_max / c) = 40 mm/s: exactly the ceiling
    (1.0, 20e-3),     # held down to 20 mm/s
    (4.0, 10e-3),
    (100.0, 5e-3),    # sqrt(...) = 2 mm/s < f2: one section at the slow cell's feed
])
def test_price_of_a_feed_change_holds_a_short_fast_cell_down(cost, fast_feed):
    runs, ds, ceiling, binding, cells = _two_cells()
    sections, solve = _solve(runs, ds, ceiling, binding, cost=cost, cells=cells)
    assert solve.success
    l1, f2 = ds[0:11].sum(), 5e-3
    assert fast_feed == pytest.approx(np.clip(np.sqrt(l1 * FEED_MAX / cost) if cost else np.inf,
                                              f2, 40e-3))
    if fast_feed == f2:  # merged: one section, the slow cell's ceiling binds
        assert [(s.start, s.stop) for s in sections] == [(0, 31)]
        assert sections[0].feed == pytest.approx(f2, rel=FEED_RTOL)
        assert sections[0].binding == "deflection"
        return
    assert [(s.start, s.stop) for s in sections] == cells[0]
    np.testing.assert_allclose([s.feed for s in sections], [fast_feed, f2], rtol=FLAT_RTOL)
    assert sections[1].binding == "deflection"
    if fast_feed < 40e-3:
        assert sections[0].binding == "feed_change"
        assert "held below its ceiling" in sections[0].note
    else:
        assert sections[0].binding == "force"


def test_feed_change_bound_ramps_into_a_notch():
    runs, ds, ceiling, cells = _ramp()
    sections, solve = _solve(runs, ds, ceiling, change_max=10e-3, cells=cells)
    assert solve.success
    assert [(s.start, s.stop) for s in sections] == cells[0]
    np.testing.assert_allclose([s.feed for s in sections], [25e-3, 15e-3, 5e-3, 15e-3, 25e-3],
                               rtol=FEED_RTOL)
    assert [s.binding for s in sections] == ["feed_change"] * 2 + ["deflection"] + ["feed_change"] * 2
    assert all("feed change bound" in s.note for i, s in enumerate(sections) if i != 2)


def test_feed_change_bound_does_not_couple_separate_cut_runs():
    """Two cut runs around an air move: the bound holds between neighbouring cells of one run."""
    ds = _steps(61)
    kinds = np.array([CUT] * 25 + [AIR] * 11 + [CUT] * 25)
    ceiling = np.where(np.arange(61) < 25, 40e-3, 5e-3)
    ceiling[kinds != CUT] = np.nan
    runs = [(0, 25, CUT), (25, 36, AIR), (36, 61, CUT)]
    sections, solve = _solve(runs, ds, ceiling, change_max=1e-3)
    assert solve.success
    assert [(s.start, s.stop) for s in sections] == [(0, 25), (36, 61)]
    np.testing.assert_allclose([s.feed for s in sections], [40e-3, 5e-3], rtol=FEED_RTOL)


@pytest.mark.parametrize("seed", range(8))
def test_feeds_never_exceed_the_ceilings_and_every_bound_holds(seed):
    """Random profiles, prices and feed-change bounds: the plan is feasible and no faster than the
    split bound; a section is a union of cells, so never shorter than the minimum."""
    rng = np.random.default_rng(100 + seed)
    n = int(rng.integers(80, 160))
    ds = _steps(n, 1e-3)
    ceiling = np.clip(20e-3 + 25e-3 * np.sin(np.arange(n) / rng.uniform(3, 12))
                      + rng.normal(0, 3e-3, n), 1e-3, FEED_MAX)  # feed_max where nothing binds
    ceiling[rng.integers(5, n - 5, 3)] = 2e-3  # notches
    runs = [(0, n, CUT)]
    change_max = None if seed % 3 == 0 else float(rng.uniform(0.5e-3, 5e-3))
    cost = 0.0 if seed % 2 else float(rng.uniform(0.01, 1.0))
    lmin = float(rng.uniform(5e-3, 15e-3))
    sections, solve = _solve(runs, ds, ceiling, lmin=lmin, change_max=change_max, cost=cost)
    assert solve.success
    assert sections[0].start == 0 and sections[-1].stop == n
    assert all(p.stop == q.start for p, q in zip(sections, sections[1:], strict=False))
    for s in sections:
        assert s.feed <= np.min(ceiling[s.start:s.stop]) * (1 + 1e-12)
        assert FEED_MIN * (1 - 1e-12) <= s.feed <= FEED_MAX * (1 + 1e-12)
        assert ds[s.start:s.stop].sum() >= lmin * (1 - 1e-12)
    steps = np.abs(np.diff([s.feed for s in sections]))
    assert np.all(steps > MERGE_TOL * FEED_MAX)  # equal neighbours were merged
    if change_max is not None:
        assert np.all(steps <= change_max * (1 + 1e-6))
    bound = cut_time_bound(fastest_splits(runs, ds, ceiling, lmin), ds, ceiling)
    assert _cut_time(ds, sections) >= bound * (1 - 1e-9)
    if change_max is None and cost == 0.0:
        assert _cut_time(ds, sections) == pytest.approx(bound, rel=FEED_RTOL)


# ---------------------------------------------------------------------------------- invariances


def _random_problem(seed: int):
    rng = np.random.default_rng(seed)
    n = 120
    ds = _steps(n)
    ceiling = np.clip(20e-3 + 12e-3 * np.sin(np.arange(n) / 7.0) + rng.normal(0, 2e-3, n),
                      1e-3, FEED_MAX)
    return [(0, n, CUT)], ds, ceiling


@pytest.mark.parametrize("f_ref", [1e-3, 1.0])
def test_rescaling_the_feed_variable_does_not_change_the_answer(f_ref):
    runs, ds, ceiling = _random_problem(7)
    kw = {"change_max": 2e-3, "cost": 0.3}
    ref, _ = _solve(runs, ds, ceiling, **kw)
    got, solve = _solve(runs, ds, ceiling, f_ref=f_ref, **kw)
    assert solve.success
    assert [(s.start, s.stop, s.binding) for s in got] == [(s.start, s.stop, s.binding) for s in ref]
    np.testing.assert_allclose([s.feed for s in got], [s.feed for s in ref], rtol=FLAT_RTOL)


def test_rescaling_the_length_unit_does_not_change_the_answer():
    """Lengths and feeds in mm (times in s unchanged): the same sections, feeds × 1000."""
    runs, ds, ceiling = _random_problem(8)
    kw = {"cost": 0.3}
    ref, _ = _solve(runs, ds, ceiling, change_max=2e-3, **kw)
    got, solve = _solve(runs, ds * 1e3, ceiling * 1e3, lmin=10.0, change_max=2.0,
                        feed_min=FEED_MIN * 1e3, feed_max=FEED_MAX * 1e3, **kw)
    assert solve.success
    assert [(s.start, s.stop, s.binding) for s in got] == [(s.start, s.stop, s.binding) for s in ref]
    np.testing.assert_allclose([s.feed * 1e-3 for s in got], [s.feed for s in ref], rtol=1e-6)


def test_warm_start_does_not_change_the_answer():
    """The problem is convex: starting at feed_min everywhere finds the same optimum."""
    runs, ds, ceiling = _random_problem(9)
    kw = {"change_max": 2e-3, "cost": 0.3}
    ref, _ = _solve(runs, ds, ceiling, **kw)
    got, solve = _solve(runs, ds, ceiling, warm=np.full(ds.size, FEED_MIN), **kw)
    assert solve.success
    assert [(s.start, s.stop) for s in got] == [(s.start, s.stop) for s in ref]
    np.testing.assert_allclose([s.feed for s in got], [s.feed for s in ref], rtol=FLAT_RTOL)


def test_no_cut_run_is_no_problem():
    ds = _steps(10)
    sections, solve = _solve([(0, 10, AIR)], ds, np.full(10, np.nan))
    assert sections == []
    assert solve.success and solve.status == "n/a" and solve.iterations == 0


# ---------------------------------------------------------------------------------- errors


@pytest.mark.parametrize(("max_iter", "change_max"), [(1, None), (2, None), (1, 1e-3), (3, 1e-3)])
def test_unconverged_solve_raises_naming_the_cell_and_constraint(max_iter, change_max):
    runs, ds, ceiling = _notch()
    binding = np.where(np.arange(41) < 20, "force", "deflection")
    cells = fastest_splits(runs, ds, ceiling, 10e-3)[0]
    with pytest.raises(PlanSolverError, match=r"did not converge \(IPOPT: Maximum_Iterations_Exceeded"
                       r", \d+ iterations\); worst at cell \d+ \(samples \d+\.\.\d+\): \w+ ") as err:
        _solve(runs, ds, ceiling, binding, change_max=change_max, max_iter=max_iter)
    e = err.value
    assert isinstance(e, CctmillError)
    assert e.status == "Maximum_Iterations_Exceeded"
    assert 0 <= e.section < len(cells)
    a, b = cells[e.section]
    assert f"cell {e.section} (samples {a}..{b - 1}): {e.constraint} " in str(e)
    allowed = {"feed_min", str(binding[a + int(np.argmin(ceiling[a:b]))])}
    if change_max is not None:
        allowed.add("feed_change")
    assert e.constraint in allowed


def test_ceiling_below_feed_min_is_a_cctmill_error_naming_the_cell():
    runs, ds, ceiling = _notch()
    with pytest.raises(CctmillError, match="cell"):
        _solve(runs, ds, ceiling, feed_min=20e-3)


def test_merging_near_equal_cells_keeps_the_feed_change_bound():
    """Cells 10.000 and 10.003 mm/s merge at the lower feed only where the next change stays
    within feed_change_max: here the 10.003 cell keeps its own feed (was a 1.003 mm/s change)."""
    ds = _steps(31)
    cells = [[(0, 11), (11, 21), (21, 31)]]
    ceiling = np.concatenate([np.full(11, 10.000e-3), np.full(10, 10.003e-3), np.full(10, 40e-3)])
    sections, solve = _solve([(0, 31, CUT)], ds, ceiling, lmin=5e-3, change_max=1e-3, cells=cells)
    assert solve.success
    assert np.all(np.abs(np.diff([s.feed for s in sections])) <= 1e-3 * (1 + 1e-6))

