"""cctmill planning: jobs, path kinematics and engagement, the feed planner (feed ceilings, the
thesis baseline, the IPOPT optimiser, toppra/ruckig timing, the independent checker), reports, KRL
export, the online supervisor's detector and policy, and the command line. Uses ``models`` and
``robot_io``.

The library entry points, in the order a job goes through them::

    job = load_job("job.toml")
    result = plan_job(job)                      # prepare + plan; raises on infeasible limits
    check_result(result).ok                     # every sample re-evaluated independently
    write_plan_outputs(result, "out/")          # plan.json, samples.npz, report.html
    export_plan("out/plan.json", "out/krl")     # KUKA KRL
"""

from planner.check import CheckReport, check_plan, check_result
from planner.export import export_plan
from planner.job import Job, JobError, load_job, parse_job
from planner.plan import PlanInfeasibleError, PlanResult, plan_job, plan_prepared, write_plan_outputs
from planner.plan_file import Plan, PlanFileError, load_plan
from planner.prepare import Prepared, prepare
from planner.supervisor import Supervisor, SupervisorConfig

__all__ = [
    "CheckReport",
    "Job",
    "JobError",
    "Plan",
    "PlanFileError",
    "PlanInfeasibleError",
    "PlanResult",
    "Prepared",
    "Supervisor",
    "SupervisorConfig",
    "check_plan",
    "check_result",
    "export_plan",
    "load_job",
    "load_plan",
    "parse_job",
    "plan_job",
    "plan_prepared",
    "prepare",
    "write_plan_outputs",
]
