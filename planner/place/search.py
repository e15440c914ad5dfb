"""A placement study: the job's own placement, a grid (optionally screened), then refinement.

::

    spec = JobSpec.from_file("job.toml")
    with open_engine("local") as engine:             # or "none", or "tcp://host:8786"
        study = run_study(spec, default_grid(job_of(spec)), engine, refine=True)
    study.best.placement.base_mm, study.speedup      # [mm]; own cycle / best cycle

Every placement is a full plan (:func:`planner.place.study.evaluate_placement`) on the engine;
results are gathered by placement, so the study is the same whatever ran it and in whatever order
it finished. Ctrl-C stops the engine's map: the study returned holds what finished and says it was
interrupted.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

from planner.place.engine import Engine
from planner.place.grid import Placement, PlacementGrid, own_placement
from planner.place.refine import RefineResult, refine
from planner.place.screen import ScreenResult, screen_placement, select
from planner.place.spec import JobSpec, job_of
from planner.place.study import PlacementResult, evaluate_placement

__all__ = ["PLACE_SCHEMA", "PlacementStudy", "run_study"]

#: ``place.json``'s schema name and version.
PLACE_SCHEMA = "cctmill.place/1"


@dataclass
class PlacementStudy:
    """A finished (or interrupted) placement study.

    Attributes:
        job_name, job_file: the job.
        grid: the grid studied.
        own: the job's own placement's result (None when interrupted before it finished).
        results: the grid's planned results, in grid order (pruned ones absent).
        screen: the screen's results in grid order (None without a screen); screen_ratio its
            pruning factor.
        pruned: grid placements the screen kept from a full plan.
        refinement: the refinement (None without one).
        failed: placements the engine could not run (their workers kept dying), with the reason.
        interrupted: Ctrl-C stopped it; what is here is what finished.
        engine: the engine's address; workers: its worker processes.
        wall_time: [s].
    """

    job_name: str
    job_file: str
    grid: PlacementGrid
    own: PlacementResult | None
    results: list[PlacementResult] = field(default_factory=list)
    screen: list[ScreenResult] | None = None
    screen_ratio: float | None = None
    pruned: list[Placement] = field(default_factory=list)
    refinement: RefineResult | None = None
    failed: dict[str, str] = field(default_factory=dict)
    interrupted: bool = False
    engine: str = "none"
    workers: int = 1
    wall_time: float = 0.0

    def candidates(self) -> list[PlacementResult]:
        """Every planned result once: own, grid, refinement (the own is a grid point too, often)."""
        rs = ([self.own] if self.own is not None else []) + list(self.results)
        if self.refinement is not None:
            rs += self.refinement.evaluated
        return list({r.placement.key: r for r in reversed(rs)}.values())[::-1]

    @property
    def best(self) -> PlacementResult | None:
        """The fastest feasible plan of the study (grid order breaks ties), or None."""
        ok = [r for r in self.candidates() if r.feasible]
        return min(ok, key=lambda r: r.score) if ok else None

    @property
    def best_of_grid(self) -> PlacementResult | None:
        ok = [r for r in self.results if r.feasible]
        return min(ok, key=lambda r: r.score) if ok else None

    @property
    def speedup(self) -> float | None:
        """Own cycle / best cycle (> 1: the best is faster), or None without both."""
        b = self.best
        if b is None or self.own is None or not self.own.feasible:
            return None
        return self.own.score / b.score

    def as_json(self) -> dict[str, Any]:
        """``place.json`` (units in the names)."""
        best, own = self.best, self.own
        rows = []
        for stage, rs in (("own", [own] if own else []), ("grid", self.results),
                          ("refine", self.refinement.evaluated if self.refinement else [])):
            rows += [{"stage": stage, **r.as_json()} for r in rs]
        return {
            "schema": PLACE_SCHEMA, "job": self.job_name, "job_file": self.job_file,
            "complete": not self.interrupted and not self.failed,
            "interrupted": self.interrupted,
            "engine": {"scheduler": self.engine, "workers": self.workers},
            "grid": {**self.grid.as_json(), "placements": len(self.grid)},
            "own": None if own is None else own.as_json(),
            "best": None if best is None else best.as_json(),
            "speedup_vs_own": self.speedup,
            "cycle_saved_s": (None if self.speedup is None else own.score - best.score),  # type: ignore[union-attr]
            "counts": {"planned": len(self.candidates()),
                       "feasible": sum(r.feasible for r in self.candidates()),
                       "pruned_by_screen": len(self.pruned), "engine_failed": len(self.failed),
                       "internal_errors": sum(r.internal for r in self.candidates())},
            "screen": None if self.screen is None else {
                "ratio": self.screen_ratio, "results": [s.as_json() for s in self.screen],
                "pruned": [p.as_json() for p in self.pruned]},
            "refine": None if self.refinement is None else self.refinement.as_json(),
            "failed": [{"key": k, "reason": v} for k, v in sorted(self.failed.items())],
            "placements": rows,
            "wall_time_s": self.wall_time,
        }


def _keyed(spec: JobSpec, placements: list[Placement]) -> list[tuple[str, Placement]]:
    unique = {p.key: p for p in placements}
    return [(f"{spec.digest[:16]}-{k}", p) for k, p in unique.items()]


def _evaluate(engine: Engine, spec: JobSpec, placements: list[Placement], progress: bool,
              desc: str, study: PlacementStudy) -> dict[str, PlacementResult]:
    """Plan ``placements`` on the engine; results by placement key (failures noted in ``study``)."""
    items = _keyed(spec, placements)
    out = engine.map(evaluate_placement, spec, spec.digest, items, desc=desc, progress=progress)
    study.interrupted |= out.interrupted
    for k, reason in out.failed.items():
        study.failed[k.split("-", 1)[1]] = reason
    return {r.placement.key: r for r in out.results.values()}


def run_study(spec: JobSpec, grid: PlacementGrid, engine: Engine, screen: float | None = None,
              refine_best: bool = False, max_refine: int | None = None,
              progress: bool = False) -> PlacementStudy:
    """Plan the job at its own placement and every grid placement, then optionally refine.

    Args:
        spec: the job.
        grid: the placements.
        engine: where the plans run (:func:`planner.place.engine.open_engine`).
        screen: prune with the cheap screen, keeping estimates within this factor of the best
            (:data:`planner.place.screen.SCREEN_RATIO` is a sound value); None plans every one.
        refine_best: refine the best grid placement (:mod:`planner.place.refine`).
        max_refine: plans the refinement may spend (default its own).
        progress: progress bars on stderr.
    """
    t0 = time.perf_counter()
    job = job_of(spec)
    study = PlacementStudy(job_name=spec.name, job_file=spec.file, grid=grid, own=None,
                           engine=engine.address, workers=engine.workers)
    own = own_placement(job)
    placements = grid.placements()
    if screen is not None:
        if not (math.isfinite(screen) and screen >= 1.0):
            from models.errors import InputError

            raise InputError("--screen", f"must be a factor >= 1, got {screen!r}")
        items = _keyed(spec, placements)
        out = engine.map(screen_placement, spec, spec.digest, items, desc="screen",
                         progress=progress)
        study.interrupted |= out.interrupted
        by_key = {r.placement.key: r for r in out.results.values()}
        study.screen = [by_key[p.key] for p in placements if p.key in by_key]
        study.screen_ratio = screen
        kept = {p.key for p in select(study.screen, screen)}
        study.pruned = [s.placement for s in study.screen if s.placement.key not in kept]
        placements = [p for p in placements if p.key in kept]
    if not study.interrupted:
        done = _evaluate(engine, spec, [own, *placements], progress, "placements", study)
        study.own = done.get(own.key)
        study.results = [done[p.key] for p in placements if p.key in done]
    start = study.best_of_grid
    if refine_best and not study.interrupted and start is not None:
        def evaluate(ps: list[Placement]) -> list[PlacementResult]:
            got = _evaluate(engine, spec, ps, False, "refine", study)
            if study.interrupted:
                raise KeyboardInterrupt
            return [got[p.key] for p in ps if p.key in got]

        kw = {} if max_refine is None else {"max_evaluations": max_refine}
        study.refinement = refine(evaluate, start, grid, **kw)
    study.workers = engine.workers
    study.wall_time = time.perf_counter() - t0
    return study

