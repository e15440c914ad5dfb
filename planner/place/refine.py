"""Derivative-free refinement of the best grid placement: Nelder–Mead over the axes the grid varies.

The objective is the real plan's cycle time at a placement (through the study's engine); a
placement without a plan scores :data:`PENALTY` times the start's cycle, so the simplex walks back
into the feasible region. A cycle time is piecewise smooth in the placement at best (the optimiser's
active set and the robot-limited stretches switch), which is why no gradient is used: scipy's
Nelder–Mead with the grid's box as bounds, in coordinates scaled by the grid spacing, the initial
simplex half a grid step along each axis (its vertices planned at once, in parallel). Only the axes
with more than one grid value move; the others stay at their single value.

Placements are snapped to :data:`SNAP_MM` / :data:`SNAP_DEG` before they are planned: a setter
positions a fixture to about that, and snapped placements repeat exactly (equal placements, one
plan: the engine's key).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from planner.place.grid import Placement, PlacementGrid
from planner.place.study import PlacementResult

__all__ = ["MAX_EVALUATIONS", "PENALTY", "SNAP_DEG", "SNAP_MM", "RefineResult", "refine"]

#: Plans the refinement may spend (the initial simplex included).
MAX_EVALUATIONS = 30
#: Score of a placement without a plan, as a multiple of the start's cycle [-].
PENALTY = 2.0
#: Placement resolution of the refinement [mm] and [deg].
SNAP_MM = 0.1
SNAP_DEG = 0.01
#: Convergence: simplex size in grid steps [-] and cycle-time spread [s].
XATOL_STEPS = 0.02
FATOL_S = 0.01


@dataclass
class RefineResult:
    """What the refinement did.

    Attributes:
        start: the grid placement it started from (its result).
        best: the best result it found (``start`` when nothing better).
        evaluated: every placement it planned, in order.
        axes: the axes it moved (``x``, ``y``, ``z``, ``yaw``).
        converged: scipy's verdict; message its reason.
    """

    start: PlacementResult
    best: PlacementResult
    evaluated: list[PlacementResult] = field(default_factory=list)
    axes: tuple[str, ...] = ()
    converged: bool = False
    message: str = ""

    def as_json(self) -> dict:
        return {"start": self.start.placement.as_json(), "best": self.best.as_json(),
                "axes": list(self.axes), "plans": len(self.evaluated),
                "converged": self.converged, "message": self.message,
                "gain_vs_start_s": (None if not (self.start.feasible and self.best.feasible)
                                    else self.start.score - self.best.score)}


def _snap(v: np.ndarray) -> Placement:
    x, y, z = (round(float(c) * 1e3 / SNAP_MM) * SNAP_MM for c in v[:3])
    yaw = round(math.degrees(float(v[3])) / SNAP_DEG) * SNAP_DEG
    return Placement.from_mm_deg(x, y, z, yaw)


def refine(evaluate: Callable[[list[Placement]], list[PlacementResult]], start: PlacementResult,
           grid: PlacementGrid, max_evaluations: int = MAX_EVALUATIONS) -> RefineResult:
    """Refine ``start`` (a feasible grid result) inside ``grid``'s box.

    Args:
        evaluate: plans placements and returns their results in order (the study's engine).
        start: the best grid placement's result.
        grid: the grid (its box bounds the search, its spacing scales it).
        max_evaluations: plans to spend at most.
    """
    from scipy.optimize import minimize

    names = ("x", "y", "z", "yaw")
    free = [i for i, a in enumerate(grid.axes) if a.n > 1]
    out = RefineResult(start=start, best=start, axes=tuple(names[i] for i in free))
    if not free or not start.feasible or max_evaluations < 2:
        out.message = "nothing to refine" if not free else "no feasible start"
        return out
    x0 = start.placement.vector()
    step = np.array([grid.axes[i].step for i in free])
    lo = np.array([(grid.axes[i].lo - x0[i]) / step[k] for k, i in enumerate(free)])
    hi = np.array([(grid.axes[i].hi - x0[i]) / step[k] for k, i in enumerate(free)])
    penalty = PENALTY * start.score
    seen: dict[str, PlacementResult] = {start.placement.key: start}

    def placement_of(u: np.ndarray) -> Placement:
        v = x0.copy()
        v[free] = x0[free] + np.clip(u, lo, hi) * step
        return _snap(v)

    def run(us: list[np.ndarray]) -> list[float]:
        ps = [placement_of(u) for u in us]
        todo = list({p.key: p for p in ps if p.key not in seen}.values())
        todo = todo[:max(0, max_evaluations - len(out.evaluated))]
        for r in evaluate(todo) if todo else []:
            seen[r.placement.key] = r
            out.evaluated.append(r)
            if r.score < out.best.score:
                out.best = r
        return [seen[p.key].score if p.key in seen else penalty for p in ps]

    def f(u: np.ndarray) -> float:
        s = run([u])[0]
        return s if math.isfinite(s) else penalty

    simplex = [np.zeros(len(free))]
    for k in range(len(free)):
        e = np.zeros(len(free))
        e[k] = 0.5 if hi[k] >= 0.5 else -0.5
        simplex.append(e)
    try:
        run(simplex[1:])  # the initial simplex's vertices at once: planned in parallel
        res = minimize(f, simplex[0], method="Nelder-Mead", bounds=list(zip(lo, hi, strict=True)),
                       options={"initial_simplex": np.array(simplex), "xatol": XATOL_STEPS,
                                "fatol": FATOL_S, "maxfev": max_evaluations})
    except KeyboardInterrupt:  # the engine was interrupted: keep what was planned
        out.message = "interrupted"
        return out
    out.converged = bool(res.success)
    out.message = str(res.message)
    return out
