"""Section boundaries and feeds by CasADi + IPOPT: the fastest cut inside every limit (docs/model.md §8).

Each ``cut`` run is first divided into *cells*, each at least ``section_length_min`` long, by
the exact fastest split of :func:`planner.partition.fastest_split` (dynamic programming over the
samples: where to cut is combinatorial, which IPOPT cannot decide); a cell is the finest section
the plan may have. With x_c = f_c / f_ref the cell feeds scaled to order one (f_ref =
``feed_max``), IPOPT solves

    minimise   Σ_c (L_c / L) / x_c  +  w Σ_e t_e                 (machining time / (L / f_ref))
    subject to feed_min / f_ref ≤ x_c ≤ min_{k ∈ c} f̂_k / f_ref   (every sample's limits)
               −t_e ≤ x_{c+1} − x_c ≤ t_e,  t_e ≥ 0               (e: neighbouring cells of a run)
               |x_{c+1} − x_c| ≤ Δf_max / f_ref                   (bounded feed change, optional)

where f̂_k is sample k's feed ceiling (:meth:`planner.ceilings.PathModel.ceilings`: chatter
margin, force, deflection and power, each evaluated with the full CCT model) and L_c the cell's
length. The ℓ1 term (w = section_change_cost / (L / f_ref)) prices every feed change, so the
optimum is piecewise constant: neighbouring cells whose feeds come out equal merge into one
section, so IPOPT removes the boundaries that do not pay. The problem is convex (1/x is convex for
x > 0, the rest is linear), so IPOPT's feeds are the global optimum for those cells; without a
feed-change bound or price the cells at their ceilings are the optimum over every split.

The solve is warm-started from the thesis baseline's feeds. An unconverged solve raises
:class:`PlanSolverError`; the plan never reaches the exporter.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import casadi as ca
import numpy as np

from models.errors import CctmillError
from planner.partition import fastest_splits
from planner.sections import CUT, Section

__all__ = [
    "MAX_ITERATIONS",
    "MERGE_TOL",
    "NOT_SOLVED",
    "PlanSolverError",
    "SolveResult",
    "optimize_sections",
]

#: Neighbouring cells whose feeds differ by less than this fraction of feed_max are one section
#: [-] (IPOPT's interior point leaves ℓ1-zero differences at ~1e-9; real steps are ≥ 1e-3).
MERGE_TOL = 1e-4
#: IPOPT's convergence tolerance on the scaled problem [-].
IPOPT_TOL = 1e-9
#: A cell feed within this fraction of its ceiling is *at* the ceiling [-].
AT_CEILING = 1e-3
#: IPOPT iteration limit (the convex sectioning problem needs 20–40).
MAX_ITERATIONS = 500
#: The status of a plan whose feeds no NLP chose (thesis and constant methods, a path without cut
#: samples); :attr:`SolveResult.note` says why.
NOT_SOLVED = "n/a"
#: Statuses that count as converged.
_CONVERGED = ("Solve_Succeeded", "Solved_To_Acceptable_Level")


class PlanSolverError(CctmillError):
    """IPOPT did not converge: no plan is handed on.

    Attributes:
        status: IPOPT's return status.
        section: index of the worst cell (largest constraint violation), or ``None``.
        constraint: the constraint violated most there (``deflection``, ``force``, …, ``feed_min``,
            ``feed_change``), or the one closest to binding if none is violated.
    """

    def __init__(self, status: str, message: str, section: int | None = None,
                 constraint: str | None = None) -> None:
        self.status = status
        self.section = section
        self.constraint = constraint
        super().__init__(message)


@dataclass(frozen=True)
class SolveResult:
    """What the solver did (qpsolvers-style: success, status, iterations, times recorded apart).

    Attributes:
        status: IPOPT return status (:data:`NOT_SOLVED` when no NLP was solved).
        success: converged.
        iterations: IPOPT iterations.
        build_time: time to build the NLP and the solver [s].
        solve_time: time inside IPOPT [s].
        objective: the scaled objective at the optimum [-].
        note: when no NLP was solved, why not, for people ("the thesis section algorithm sets
            the feeds").
    """

    status: str
    success: bool
    iterations: int
    build_time: float
    solve_time: float
    objective: float
    note: str = ""

    def describe(self) -> str:
        """What the solver did, in words: IPOPT's status, iterations and times, or why no
        optimisation ran (never "n/a (0 iterations)")."""
        if self.status == NOT_SOLVED:
            return self.note or "no optimisation"
        return (f"IPOPT {self.status} after {self.iterations} iteration"
                f"{'s' if self.iterations != 1 else ''} (build {self.build_time:.3f} s, solve "
                f"{self.solve_time:.3f} s)")

    def as_json(self) -> dict:
        return {"status": self.status, "success": self.success, "iterations": self.iterations,
                "build_time_s": self.build_time, "solve_time_s": self.solve_time,
                "objective": self.objective}


def optimize_sections(runs: list[tuple[int, int, int]], ds: np.ndarray, ceiling: np.ndarray,
                      ceiling_binding: np.ndarray, feed_min: float, feed_max: float,
                      section_length_min: float, feed_change_max: float | None,
                      change_cost: float, warm: np.ndarray | None = None,
                      f_ref: float | None = None, max_iter: int = MAX_ITERATIONS,
                      cells: list[list[tuple[int, int]]] | None = None,
                      ) -> tuple[list[Section], SolveResult]:
    """The optimised sections of the ``cut`` runs.

    Args:
        runs: kind runs of the whole path (:func:`planner.sections.kind_runs`); only ``cut`` runs
            are optimised.
        ds: step length per sample [m], (n,).
        ceiling: feed ceiling per sample [m/s], (n,) (NaN outside ``cut`` samples).
        ceiling_binding: what sets each ceiling, (n,) str.
        feed_min, feed_max: feed bounds [m/s].
        section_length_min: shortest section [m].
        feed_change_max: largest feed change between neighbouring cells [m/s], or None.
        change_cost: time-equivalent cost of a feed change of ``f_ref`` [s].
        warm: per-sample feeds to start from [m/s], (n,) (e.g. the thesis baseline).
        f_ref: feed scale [m/s] (default ``feed_max``); the answer does not depend on it.
        max_iter: IPOPT iteration limit.
        cells: the cells of every cut run, if already made
            (:func:`planner.partition.fastest_splits` of these arguments).

    Returns:
        The cut sections (in path order) and the solver record.
    """
    t0 = time.perf_counter()
    f_ref = feed_max if f_ref is None else f_ref
    groups = fastest_splits(runs, ds, ceiling, section_length_min) if cells is None else cells
    cells = [c for g in groups for c in g]
    nc = len(cells)
    if nc == 0:
        return [], SolveResult(NOT_SOLVED, True, 0, 0.0, 0.0, 0.0,
                               "no optimisation needed: the path has no cut samples")
    length = np.array([ds[a:b].sum() for a, b in cells])
    total = max(float(length.sum()), 1e-12)
    cap = np.array([np.nanmin(ceiling[a:b]) for a, b in cells])
    edges = []
    k = 0
    for g in groups:
        edges += [(k + j, k + j + 1) for j in range(len(g) - 1)]
        k += len(g)
    ne = len(edges)
    x = ca.SX.sym("x", nc)
    t = ca.SX.sym("t", ne)
    time_ref = total / f_ref
    # the price is per change of feed_max, whatever the scale f_ref of the variables
    w = change_cost / time_ref * f_ref / feed_max
    # Zero-length cells (duplicate samples) weigh nothing; keep them strictly convex.
    weight = np.maximum(length / total, 1e-12)
    obj = ca.sum1(ca.DM(weight) / x) + (w * ca.sum1(t) if ne else 0)
    g_list, lbg, ubg = [], [], []
    if ne:
        i0 = [e[0] for e in edges]
        i1 = [e[1] for e in edges]
        diff = x[i1] - x[i0]
        g_list += [t - diff, t + diff]
        lbg += [0.0] * (2 * ne)
        ubg += [np.inf] * (2 * ne)
        if feed_change_max is not None:
            g_list.append(diff)
            lbg += [-feed_change_max / f_ref] * ne
            ubg += [feed_change_max / f_ref] * ne
    z = ca.vertcat(x, t)
    nlp = {"x": z, "f": obj, "g": ca.vertcat(*g_list) if g_list else ca.SX(0, 1)}
    opts = {"ipopt.print_level": 0, "print_time": False, "ipopt.sb": "yes",
            "ipopt.tol": IPOPT_TOL, "ipopt.max_iter": int(max_iter)}
    solver = ca.nlpsol("feeds", "ipopt", nlp, opts)
    lbx = np.concatenate([np.full(nc, feed_min / f_ref), np.zeros(ne)])
    ubx = np.concatenate([cap / f_ref, np.full(ne, np.inf)])
    low = np.flatnonzero(cap < feed_min)
    if low.size:  # no feed fits this cell: say so before IPOPT refuses LBX > UBX
        k = int(low[0])
        a, b = cells[k]
        raise PlanSolverError("Infeasible_Bounds",
                              f"cell {k} (samples {a}..{b - 1}): its ceiling {cap[k] * 1e3:.4g} mm/s "
                              f"is below feed_min_mm_s {feed_min * 1e3:g}; lower feed_min_mm_s",
                              section=k, constraint="feed_min")
    if warm is not None:
        x0 = np.array([np.nanmin(warm[a:b]) for a, b in cells]) / f_ref
    else:
        x0 = cap / f_ref
    x0 = np.clip(x0, lbx[:nc], ubx[:nc])
    t_start = (np.abs(x0[[e[1] for e in edges]] - x0[[e[0] for e in edges]]) if ne
               else np.zeros(0))
    build = time.perf_counter() - t0
    t1 = time.perf_counter()
    sol = solver(x0=np.concatenate([x0, t_start]), lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg)
    solve = time.perf_counter() - t1
    stats = solver.stats()
    status = str(stats.get("return_status", "unknown"))
    result = SolveResult(status=status, success=bool(stats.get("success")) and status in _CONVERGED,
                         iterations=int(stats.get("iter_count", 0)), build_time=build,
                         solve_time=solve, objective=float(sol["f"]))
    xs = np.asarray(sol["x"], float).reshape(-1)[:nc]
    if not result.success:
        worst, what, amount = _worst_cell(xs, lbx[:nc], ubx[:nc], edges, feed_change_max, f_ref)
        a, b = cells[worst]
        tight = a + int(np.nanargmin(ceiling[a:b]))
        name = str(ceiling_binding[tight]) if what == "ceiling" else what
        raise PlanSolverError(status, f"the feed optimisation did not converge (IPOPT: {status}, "
                              f"{result.iterations} iterations); worst at cell {worst} "
                              f"(samples {a}..{b - 1}): {name} "
                              f"{'violated by' if amount > 0 else 'closest to binding, slack'} "
                              f"{abs(amount) * f_ref * 1e3:.3g} mm/s; try --method thesis, or "
                              "report this job", section=worst, constraint=name)
    xs = np.clip(xs, lbx[:nc], ubx[:nc])
    sections = _merge(groups, xs * (f_ref / feed_max), feed_max, ceiling, ceiling_binding,
                      feed_change_max)
    return sections, result


def _worst_cell(xs: np.ndarray, lo: np.ndarray, hi: np.ndarray, edges: list[tuple[int, int]],
                feed_change_max: float | None, f_ref: float) -> tuple[int, str, float]:
    """The cell and constraint with the largest violation (or least slack) at ``xs`` (scaled).

    Returns ``(cell, "ceiling" | "feed_min" | "feed_change", violation)``, violation < 0 a slack.
    """
    cand = [(xs - hi, "ceiling"), (lo - xs, "feed_min")]
    if feed_change_max is not None and edges:
        i0 = np.array([e[0] for e in edges])
        over = np.full(xs.size, -np.inf)
        np.maximum.at(over, i0 + 1, np.abs(xs[i0 + 1] - xs[i0]) - feed_change_max / f_ref)
        cand.append((over, "feed_change"))
    best = max(((float(v.max()), int(v.argmax()), name) for v, name in cand), key=lambda c: c[0])
    return best[1], best[2], best[0]


def _keep_change_bound(runs: list[list[int]], xs: np.ndarray, bound: float) -> list[list[int]]:
    """Split merged runs where running them at their lowest cell's feed would break the feed
    change bound to the next run (``xs`` and ``bound`` scaled): the cell at the offending boundary
    that the merge lowered most goes back to its own feed. The solver's feeds meet the bound cell
    by cell, so at worst every cell is its own section again."""
    runs = [list(r) for r in runs]
    while True:
        feed = [float(np.min(xs[r])) for r in runs]
        for i in range(len(runs) - 1):
            if abs(feed[i + 1] - feed[i]) <= bound * (1.0 + 1e-9):
                continue
            left, right = runs[i], runs[i + 1]
            lowered_left = xs[left[-1]] - feed[i] if len(left) > 1 else -1.0
            lowered_right = xs[right[0]] - feed[i + 1] if len(right) > 1 else -1.0
            if max(lowered_left, lowered_right) <= 0.0:
                continue     # the solver's own feeds (within its tolerance): nothing to undo
            if lowered_left >= lowered_right:
                runs[i:i + 1] = [left[:-1], left[-1:]]
            else:
                runs[i + 1:i + 2] = [right[:1], right[1:]]
            break
        else:
            return runs


def _merge(groups: list[list[tuple[int, int]]], xs: np.ndarray, f_ref: float,
           ceiling: np.ndarray, binding: np.ndarray,
           feed_change_max: float | None) -> list[Section]:
    """Merge neighbouring cells of equal feed (``xs`` scaled by ``f_ref`` = feed_max)."""
    out: list[Section] = []
    k = 0
    for g in groups:
        runs: list[list[int]] = []
        for j in range(len(g)):
            if runs and abs(xs[k + j] - xs[runs[-1][-1]]) <= MERGE_TOL:
                runs[-1].append(k + j)
            else:
                runs.append([k + j])
        if feed_change_max is not None:
            runs = _keep_change_bound(runs, xs, feed_change_max / f_ref)
        for r in runs:
            a, b = g[r[0] - k][0], g[r[-1] - k][1]
            feed = float(np.min(xs[r])) * f_ref
            out.append(Section(start=a, stop=b, kind=CUT, feed=feed))
        k += len(g)
    for i, sec in enumerate(out):
        c = ceiling[sec.start:sec.stop]
        tight = sec.start + int(np.nanargmin(c))
        if sec.feed >= ceiling[tight] * (1 - AT_CEILING):
            sec.binding = str(binding[tight])
            continue
        sec.binding = "feed_change"
        neighbours = [out[j] for j in (i - 1, i + 1) if 0 <= j < len(out)
                      and (out[j].stop == sec.start or out[j].start == sec.stop)]
        if feed_change_max is not None and any(
                abs(abs(nb.feed - sec.feed) - feed_change_max) <= AT_CEILING * f_ref
                for nb in neighbours):
            sec.note = "feed change bound to a neighbouring section"
        else:
            sec.note = "held below its ceiling: a separate section would cost more than it saves"
    return out
