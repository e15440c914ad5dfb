"""cctmill planning: jobs, path kinematics and engagement, the feed planner (feed ceilings, the
thesis baseline, the IPOPT optimiser, toppra/ruckig timing, the independent checker), the typed
plan and its files, reports, KRL export, the online supervisor and the command line. Uses
``models`` and ``robot_io``.

The library entry points, in the order a job goes through them::

    job = load_job("job.toml")
    result = plan_job(job)                      # prepare + plan; raises on infeasible limits
    check_result(result).ok                     # every sample re-evaluated independently
    plan = Plan.from_result(result)             # the typed plan, SI
    plan = plan.save("out/")                    # plan.json + samples.npz
    export_plan(plan, "out/krl")                # KUKA KRL
    run_plan_job(job, "out/", krl=KrlOptions()) # all of it, with the report (what `cctmill plan` runs)
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

#: Where each public name lives; imported on first use (PEP 562), so that importing one part
#: of the package (the plan file, the supervisor) does not load the rest.
_SOURCES = {
    "CheckReport": "planner.check",
    "DemoError": "planner.demo",
    "ExportError": "planner.export",
    "Job": "planner.job",
    "JobError": "planner.job",
    "KrlOptions": "planner.outputs",
    "Limits": "planner.limits",
    "Plan": "planner.plan_file",
    "PlanFileError": "planner.plan_file",
    "PlanInfeasibleError": "planner.plan",
    "PlanOutputs": "planner.outputs",
    "PlanResult": "planner.plan",
    "PlanSamples": "planner.plan_file",
    "PlanSection": "planner.plan_file",
    "PlanSolverError": "planner.optimize",
    "Prepared": "planner.prepare",
    "ReportRenderError": "planner.report.html",
    "SessionSummary": "planner.supervisor.session",
    "Supervisor": "planner.supervisor.policy",
    "SupervisorConfig": "planner.supervisor.policy",
    "TimingError": "planner.timing",
    "check_plan": "planner.check",
    "check_result": "planner.check",
    "export_plan": "planner.export",
    "load_job": "planner.job",
    "load_plan": "planner.plan_file",
    "parse_job": "planner.job",
    "plan_job": "planner.plan",
    "plan_of_result": "planner.plan",
    "plan_prepared": "planner.plan",
    "plan_to_krl": "planner.export",
    "prepare": "planner.prepare",
    "run_demo": "planner.demo",
    "run_plan_job": "planner.outputs",
    "run_session": "planner.supervisor.session",
    "write_plan_outputs": "planner.outputs",
}

__all__ = [
    "CheckReport",
    "DemoError",
    "ExportError",
    "Job",
    "JobError",
    "KrlOptions",
    "Limits",
    "Plan",
    "PlanFileError",
    "PlanInfeasibleError",
    "PlanOutputs",
    "PlanResult",
    "PlanSamples",
    "PlanSection",
    "PlanSolverError",
    "Prepared",
    "ReportRenderError",
    "SessionSummary",
    "Supervisor",
    "SupervisorConfig",
    "TimingError",
    "check_plan",
    "check_result",
    "export_plan",
    "load_job",
    "load_plan",
    "parse_job",
    "plan_job",
    "plan_of_result",
    "plan_prepared",
    "plan_to_krl",
    "prepare",
    "run_demo",
    "run_plan_job",
    "run_session",
    "write_plan_outputs",
]

if TYPE_CHECKING:  # for type checkers and IDEs: the same names, imported eagerly
    from planner.check import CheckReport, check_plan, check_result
    from planner.demo import DemoError, run_demo
    from planner.export import ExportError, export_plan, plan_to_krl
    from planner.job import Job, JobError, load_job, parse_job
    from planner.limits import Limits
    from planner.optimize import PlanSolverError
    from planner.outputs import KrlOptions, PlanOutputs, run_plan_job, write_plan_outputs
    from planner.plan import PlanInfeasibleError, PlanResult, plan_job, plan_of_result, plan_prepared
    from planner.plan_file import Plan, PlanFileError, PlanSamples, PlanSection, load_plan
    from planner.prepare import Prepared, prepare
    from planner.report.html import ReportRenderError
    from planner.supervisor.policy import Supervisor, SupervisorConfig
    from planner.supervisor.session import SessionSummary, run_session
    from planner.timing import TimingError


def __getattr__(name: str) -> Any:
    if name not in _SOURCES:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(_SOURCES[name]), name)


def __dir__() -> list[str]:
    return __all__
