"""Cell placement studies and the engine they run on: where to put the part (``$BASE``).

A study plans the job for real at every placement of a grid (:mod:`~planner.place.grid`), one task
per placement (:mod:`~planner.place.study`), optionally pruned by a cheap screen
(:mod:`~planner.place.screen`) and refined by Nelder–Mead (:mod:`~planner.place.refine`), on Dask
distributed or serially (:mod:`~planner.place.engine`); :mod:`~planner.place.search` runs it and
:mod:`~planner.place.outputs` writes ``place.json``, the heat map and the best plan::

    spec = JobSpec.from_file("job.toml")
    with open_engine(resolve_scheduler()) as engine:
        study = run_study(spec, default_grid(job_of(spec)), engine, refine_best=True)
    write_place_outputs(study, spec, "out/")

Names are imported on first use (PEP 562): importing the package loads neither Dask nor the physics.
"""

from __future__ import annotations

import importlib
from typing import Any

_EXPORTS: dict[str, tuple[str, ...]] = {
    "planner.place.engine": ("DaskEngine", "Engine", "EngineError", "MapOutcome", "SerialEngine",
                             "open_engine", "resolve_scheduler"),
    "planner.place.grid": ("Axis", "Placement", "PlacementGrid", "default_grid", "own_placement"),
    "planner.place.outputs": ("write_place_outputs",),
    "planner.place.refine": ("RefineResult", "refine"),
    "planner.place.screen": ("ScreenResult", "screen_placement"),
    "planner.place.search": ("PlacementStudy", "run_study"),
    "planner.place.spec": ("JobSpec", "job_at", "job_of"),
    "planner.place.study": ("PlacementResult", "evaluate_placement"),
}
_SOURCES = {name: module for module, names in _EXPORTS.items() for name in names}

__all__ = sorted(_SOURCES)


def __getattr__(name: str) -> Any:
    if name not in _SOURCES:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(_SOURCES[name]), name)


def __dir__() -> list[str]:
    return __all__
