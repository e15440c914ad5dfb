"""From a job to its files: plan → plan.json/samples.npz → report → KRL, in that order.

The pipeline computes (:func:`planner.plan.plan_job` returns a result and writes nothing); this
module is the one orchestrating function the ``cctmill plan`` command (and the demo) call::

    outputs = run_plan_job(load_job("job.toml"), "out/", krl=KrlOptions(controller="krc4"))
    outputs.plan.cycle_time          # [s]; outputs.files: every file written, by name
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from planner._atomic import check_output, output_errors
from planner.plan_file import Plan

if TYPE_CHECKING:  # the pipeline loads the physics: imported where it runs
    from planner.job import Job
    from planner.plan import PlanResult

__all__ = ["KrlOptions", "PlanOutputs", "run_plan_job", "write_plan_outputs"]


@dataclass(frozen=True)
class KrlOptions:
    """How to write the KRL program (see :func:`planner.export.plan_to_krl`)."""

    name: str | None = None
    controller: str = "krc4"
    compensate: bool = False
    override_hook: str = "none"
    base_index: int | None = None
    tool_index: int | None = None
    apo_cdis_mm: float = 0.1
    advance: int = 3

    def kwargs(self) -> dict[str, Any]:
        return dict(self.__dict__)


@dataclass
class PlanOutputs:
    """What :func:`write_plan_outputs` / :func:`run_plan_job` made.

    Attributes:
        result: the planning result (everything the plan was made from).
        plan: the typed plan, with ``path`` the written ``plan.json``.
        files: written files by name (``plan``, ``samples``, the report's, ``krl`` a list).
    """

    result: PlanResult
    plan: Plan
    files: dict[str, Path | list[Path]] = field(default_factory=dict)


def write_plan_outputs(res: PlanResult, folder: str | os.PathLike, report: bool = True,
                       krl: KrlOptions | None = None,
                       report_sections: tuple[str, ...] = (),
                       progress: bool = False) -> PlanOutputs:
    """Write plan.json and samples.npz, then (``report``) report.html and its PNGs, then (``krl``)
    the KRL program, into ``folder``. ``progress``: a bar on stderr over the report's files (a
    long path's PNGs take seconds), on a terminal only.

    Raises:
        OutputError: a file cannot be written (names it).
        ExportError, KrlError: the plan cannot be written as KRL (nothing of it is written).
    """
    from planner.plan import plan_of_result

    plan = plan_of_result(res).save(folder)
    json_path = plan.path or Path(folder) / "plan.json"
    out = PlanOutputs(res, plan, {"plan": json_path, "samples": json_path.parent / "samples.npz"})
    if report:
        from planner.report import write_report

        out.files.update(write_report(res, folder, sections=report_sections, progress=progress))
    if krl is not None:
        from planner.export import export_plan

        with output_errors(folder):     # the KRL writer's OSError, said as ours
            out.files["krl"] = export_plan(plan, folder, **krl.kwargs())
    return out


def run_plan_job(job: Job, folder: str | os.PathLike, method: str | None = None,
                 safety_factor: float | None = None, krl: KrlOptions | None = None,
                 progress: bool = False) -> PlanOutputs:
    """Plan ``job`` and write everything :func:`write_plan_outputs` writes. ``folder`` is checked
    first (:func:`planner._atomic.check_output`): a file in its place fails before the planning.

    Raises:
        OutputError: ``folder`` cannot be written (checked before planning) or a file in it.
        PlanInfeasibleError, PlanSolverError, UnreachablePoseError: as :func:`plan_job`.
        ExportError, KrlError: the plan cannot be written as KRL (nothing of it is written).
    """
    from planner.plan import plan_job

    check_output(folder, "folder")
    res = plan_job(job, method=method, safety_factor=safety_factor, progress=progress)
    return write_plan_outputs(res, folder, krl=krl, progress=progress)
