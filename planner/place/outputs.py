"""A placement study's files: ``place.json``, the heat map, and the best placement's plan.

:func:`write_place_outputs` is what ``cctmill place`` calls after :func:`planner.place.search.run_study`:

* ``place.json`` — every placement (feasible, cycle time, binding counts, worst margin, or the
  reason it has no plan), the own and the best, the screen and the refinement; written atomically,
  first, so an interrupted or failing study still leaves what finished;
* ``place_heatmap.png`` — :func:`planner.report.placement.plot_placement_heatmap`;
* ``best/`` — the plan of the best placement with everything ``cctmill plan`` writes, its report
  carrying the study's section (not for an interrupted study).
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any

from planner._atomic import write_text_atomic
from planner.place.search import PlacementStudy
from planner.place.spec import JobSpec, job_at

__all__ = ["write_place_outputs"]


def _finite(v: Any) -> Any:
    """``v`` with every non-finite float as None (JSON has no NaN)."""
    if isinstance(v, float):
        return v if math.isfinite(v) else None
    if isinstance(v, dict):
        return {k: _finite(x) for k, x in v.items()}
    if isinstance(v, list | tuple):
        return [_finite(x) for x in v]
    return v


def write_place_outputs(study: PlacementStudy, spec: JobSpec, folder: str | os.PathLike,
                        best_plan: bool = True, progress: bool = False) -> dict[str, Path]:
    """Write the study's files into ``folder`` (module docstring); return them by name.
    ``progress``: bars on stderr while the best placement is planned again and its report
    written (seconds on a long job), on a terminal only.

    Raises:
        OutputError: a file cannot be written.
    """
    from planner.report.placement import placement_section, plot_placement_heatmap

    out = Path(folder)
    doc = _finite(study.as_json())
    files: dict[str, Path] = {"place": write_text_atomic(out / "place.json",
                                                         json.dumps(doc, indent=2) + "\n")}
    files["heatmap"] = plot_placement_heatmap(doc, out / "place_heatmap.png")
    best = study.best
    if best_plan and best is not None and not study.interrupted:
        from planner.outputs import write_plan_outputs
        from planner.plan import plan_job

        res = plan_job(job_at(spec, best.placement), progress=progress)
        written = write_plan_outputs(res, out / "best",
                                     report_sections=(placement_section(doc, files["heatmap"]),),
                                     progress=progress)
        files.update({f"best_{k}": v for k, v in written.files.items() if isinstance(v, Path)})
    return files
