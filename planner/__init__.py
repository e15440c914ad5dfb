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
from typing import Any

#: Where each public name lives; imported on first use (PEP 562, type checkers see the module's
#: ``__getattr__``; import from the module itself for its types), so that importing one part
#: of the package (the plan file, the supervisor) does not load the rest.
_EXPORTS: dict[str, tuple[str, ...]] = {
    "planner._atomic": ("OutputError",),
    "planner.calibrate": ("FitRefused", "RecordError"),
    "planner.check": ("CheckReport", "check_plan", "check_result"),
    "planner.demo": ("DemoError", "run_demo"),
    "planner.export": ("ExportError", "export_plan", "plan_to_krl"),
    "planner.job": ("Job", "JobError", "load_job", "parse_job"),
    "planner.limits": ("Limits",),
    "planner.optimize": ("PlanSolverError",),
    "planner.outputs": ("KrlOptions", "PlanOutputs", "run_plan_job", "write_plan_outputs"),
    "planner.place.engine": ("EngineError",),
    "planner.plan": ("PlanInfeasibleError", "PlanResult", "plan_job", "plan_of_result", "plan_prepared"),
    "planner.plan_file": ("Plan", "PlanFileError", "PlanSamples", "PlanSection", "load_plan"),
    "planner.prepare": ("Prepared", "prepare"),
    "planner.report.browser": ("ReportRenderError",),
    "planner.supervisor.policy": ("Supervisor", "SupervisorConfig"),
    "planner.supervisor.session": ("SessionSummary", "run_session"),
    "planner.timing": ("TimingError",),
}
_SOURCES = {name: module for module, names in _EXPORTS.items() for name in names}

__all__ = sorted(_SOURCES)

def __getattr__(name: str) -> Any:
    if name not in _SOURCES:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(_SOURCES[name]), name)


def __dir__() -> list[str]:
    return __all__
