"""One placement, planned for real: the task of a placement study.

:func:`evaluate_placement` moves the job's ``$BASE`` and runs :func:`planner.plan.plan_job` — reach,
IK, engagement, ceilings, optimisation, timing; no proxy. It is pure (equal arguments, equal
result, nothing written) and never raises for the placement's sake: an error cctmill raises on
purpose (unreachable, infeasible limits, an unconverged solve) is a result with its reason, and so is
an unexpected one (marked ``internal``), so one bad placement cannot stop a study of thousands.
"""

from __future__ import annotations

import math
import os
import socket
import time
from dataclasses import dataclass, field
from typing import Any

from models.errors import CctmillError
from planner.place.grid import Placement
from planner.place.spec import JobSpec, job_at, local_path

__all__ = ["PlacementResult", "evaluate_placement"]


@dataclass(frozen=True)
class PlacementResult:
    """What planning the job at one placement gave.

    Attributes:
        placement: the placement.
        feasible: a plan exists (every sample reached, every limit met, the solve converged).
        cycle_time: the toppra-timed cycle [s] (None when infeasible).
        process_time: Σ L/f over feed moves [s].
        cut_time: Σ ds/f over the cut samples [s].
        binding_counts: sections by what binds them (``chatter``, ``robot``, …).
        margin_min: the lowest chatter margin along the path at the planned feeds [N/m] (the
            worst margin).
        force_max: the largest resultant cutting force [N].
        deflection_max: the largest static TCP deflection [m].
        solver_status: IPOPT's status (``n/a`` for the thesis and constant methods).
        reason: why there is no plan (the planner's message, which names the sample, joint or
            limit), or None.
        error: the error's class (``UnreachablePoseError``, ``PlanInfeasibleError``, …), or None;
            ``internal`` results are errors no placement should cause (a bug: please report).
        internal: the error is not one cctmill raises on purpose.
        wall_time: wall time of the evaluation [s] (not compared: runs differ).
        worker: ``host:pid`` that ran it (not compared).
    """

    placement: Placement
    feasible: bool
    cycle_time: float | None = None
    process_time: float | None = None
    cut_time: float | None = None
    binding_counts: dict[str, int] = field(default_factory=dict)
    margin_min: float | None = None
    force_max: float | None = None
    deflection_max: float | None = None
    solver_status: str | None = None
    reason: str | None = None
    error: str | None = None
    internal: bool = False
    wall_time: float = field(default=0.0, compare=False)
    worker: str = field(default="", compare=False)

    @property
    def score(self) -> float:
        """What a study minimises: the cycle time [s], ``inf`` without a plan."""
        return self.cycle_time if self.feasible and self.cycle_time is not None else math.inf

    def as_json(self) -> dict[str, Any]:
        """The result in ``place.json``'s units (names carry them)."""
        return {**self.placement.as_json(), "feasible": self.feasible,
                "cycle_time_s": self.cycle_time, "process_time_s": self.process_time,
                "cut_time_s": self.cut_time, "binding_counts": dict(self.binding_counts),
                "worst_margin_N_per_m": self.margin_min, "force_max_N": self.force_max,
                "deflection_max_mm": (None if self.deflection_max is None
                                      else self.deflection_max * 1e3),
                "solver_status": self.solver_status, "reason": self.reason, "error": self.error,
                "internal": self.internal, "wall_time_s": self.wall_time, "worker": self.worker}

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> PlacementResult:
        """The inverse of :meth:`as_json`."""
        dm = d.get("deflection_max_mm")
        return cls(
            placement=Placement.from_mm_deg(d["x_mm"], d["y_mm"], d["z_mm"], d["yaw_deg"]),
            feasible=bool(d["feasible"]), cycle_time=d.get("cycle_time_s"),
            process_time=d.get("process_time_s"), cut_time=d.get("cut_time_s"),
            binding_counts=dict(d.get("binding_counts") or {}),
            margin_min=d.get("worst_margin_N_per_m"), force_max=d.get("force_max_N"),
            deflection_max=None if dm is None else dm * 1e-3,
            solver_status=d.get("solver_status"), reason=d.get("reason"), error=d.get("error"),
            internal=bool(d.get("internal", False)), wall_time=float(d.get("wall_time_s", 0.0)),
            worker=str(d.get("worker", "")))


def _worker() -> str:
    return f"{socket.gethostname()}:{os.getpid()}"


def evaluate_placement(spec: JobSpec, placement: Placement) -> PlacementResult:
    """Plan ``spec``'s job with ``$BASE`` at ``placement`` (see the module docstring).

    Never raises for the placement's sake; a job that cannot be planned anywhere (an unreadable
    toolpath) is a result with its reason at every placement.
    """
    from planner.plan import plan_job

    t0 = time.perf_counter()
    try:
        res = plan_job(job_at(spec, placement), threads=1)  # one core a worker: no oversubscription
    except CctmillError as e:
        return PlacementResult(placement, False, reason=local_path(spec, str(e)),
                               error=type(e).__name__, wall_time=time.perf_counter() - t0,
                               worker=_worker())
    except Exception as e:  # noqa: BLE001 - one placement must not stop the study; it is reported
        return PlacementResult(placement, False, reason=local_path(spec, f"{type(e).__name__}: {e}"),
                               error=type(e).__name__, internal=True,
                               wall_time=time.perf_counter() - t0, worker=_worker())
    counts: dict[str, int] = {}
    for s in res.plan_sections:
        counts[s.binding] = counts.get(s.binding, 0) + 1
    ev = res.evaluation
    some = bool(ev.force.size)
    return PlacementResult(
        placement, True, cycle_time=float(res.cycle_time), process_time=float(res.process_time),
        cut_time=float(res.cut_time), binding_counts=dict(sorted(counts.items())),
        margin_min=float(ev.margin.min()) if some else None,
        force_max=float(ev.force.max()) if some else None,
        deflection_max=float(ev.deflection_norm.max()) if some else None,
        solver_status=res.solver.status, wall_time=time.perf_counter() - t0, worker=_worker())
