"""Many jobs planned on one engine, one output folder per job: ``cctmill plan JOB1 JOB2 … -o OUT``.

Each job is a task on the placement studies' engine (:mod:`planner.place.engine`): a worker plans it
and writes everything ``cctmill plan`` writes (:func:`planner.outputs.run_plan_job`) into a
temporary folder of its own, and sends the files back as bytes; this process writes them into
``OUT/<job file stem>/`` (each file atomically) — so workers need no access to ``OUT``, only to
the job (which travels as a :class:`~planner.place.spec.JobSpec`). A job that cannot be planned is
a result with its reason, never the end of the batch; ``OUT/batch.json`` lists every job.
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from models.errors import CctmillError
from planner._atomic import atomic_path, write_text_atomic
from planner.outputs import KrlOptions
from planner.place.engine import Engine
from planner.place.spec import JobSpec, job_of, local_path

__all__ = ["BATCH_SCHEMA", "BatchJob", "BatchOptions", "BatchResult", "folder_names", "plan_batch"]

#: ``batch.json``'s schema name and version.
BATCH_SCHEMA = "cctmill.batch/1"


@dataclass(frozen=True)
class BatchOptions:
    """What every job of a batch is planned with (as ``cctmill plan``'s flags)."""

    method: str | None = None
    safety_factor: float | None = None
    krl: KrlOptions | None = None

    def key(self) -> str:
        return hashlib.sha256(repr(self).encode()).hexdigest()[:16]


@dataclass
class BatchJob:
    """One job of a batch.

    Attributes:
        job_file: the job file; name: its ``[job] name``; folder: where its files went.
        ok: it was planned and written.
        cycle_time: [s]; method and solver status of the plan.
        reason, error: why not (the planner's message and its error class).
        files: the files written, relative to ``folder``.
        wall_time: on the worker [s]; worker: ``host:pid``.
    """

    job_file: str
    name: str
    folder: str
    ok: bool
    cycle_time: float | None = None
    method: str | None = None
    solver_status: str | None = None
    reason: str | None = None
    error: str | None = None
    files: list[str] = field(default_factory=list)
    wall_time: float = 0.0
    worker: str = ""

    def as_json(self) -> dict[str, Any]:
        return {"job_file": self.job_file, "name": self.name, "folder": self.folder, "ok": self.ok,
                "cycle_time_s": self.cycle_time, "method": self.method,
                "solver_status": self.solver_status, "reason": self.reason, "error": self.error,
                "files": self.files, "wall_time_s": self.wall_time, "worker": self.worker}


@dataclass
class BatchResult:
    """A batch: every job in the order given, and how it ran."""

    jobs: list[BatchJob]
    interrupted: bool = False
    engine: str = "none"
    workers: int = 1
    wall_time: float = 0.0

    @property
    def ok(self) -> bool:
        return not self.interrupted and all(j.ok for j in self.jobs)

    def as_json(self) -> dict[str, Any]:
        return {"schema": BATCH_SCHEMA, "ok": self.ok, "interrupted": self.interrupted,
                "engine": {"scheduler": self.engine, "workers": self.workers},
                "wall_time_s": self.wall_time, "jobs": [j.as_json() for j in self.jobs]}


def folder_names(files: list[str | os.PathLike]) -> list[str]:
    """One output folder name per job file: its stem, numbered where stems repeat
    (``a/job.toml``, ``b/job.toml`` → ``job``, ``job-2``)."""
    out, used = [], set()
    for f in files:
        stem = Path(f).stem or "job"
        name, k = stem, 1
        while name in used:
            k += 1
            name = f"{stem}-{k}"
        used.add(name)
        out.append(name)
    return out


def _plan_files(options: BatchOptions, spec: JobSpec) -> dict[str, Any]:
    """The task: plan ``spec`` and return its summary and its files' bytes (never raises for the
    job's sake)."""
    import socket

    from planner.outputs import run_plan_job

    t0 = time.perf_counter()
    worker = f"{socket.gethostname()}:{os.getpid()}"
    try:
        with tempfile.TemporaryDirectory(prefix="cctmill-batch-") as tmp:
            outputs = run_plan_job(job_of(spec), tmp, options.method, options.safety_factor,
                                   krl=options.krl)
            files = {p.relative_to(tmp).as_posix(): p.read_bytes()
                     for p in sorted(Path(tmp).rglob("*")) if p.is_file()}
        res = outputs.result
        return {"ok": True, "cycle_time": float(res.cycle_time), "method": res.method,
                "solver_status": res.solver.status, "files": files,
                "wall_time": time.perf_counter() - t0, "worker": worker}
    except CctmillError as e:
        return {"ok": False, "reason": local_path(spec, str(e)), "error": type(e).__name__,
                "files": {}, "wall_time": time.perf_counter() - t0, "worker": worker}


def plan_batch(files: list[str | os.PathLike], out: str | os.PathLike, engine: Engine,
               options: BatchOptions | None = None, progress: bool = False) -> BatchResult:
    """Plan every job file on ``engine`` into ``out/<name>/`` and write ``out/batch.json``.

    Raises:
        JobError: a job file is not valid (before any job is planned: the batch is checked first).
        OutputError: a file cannot be written.
    """
    t0 = time.perf_counter()
    opts = options or BatchOptions()
    specs = [JobSpec.from_file(f) for f in files]
    names = folder_names(files)
    root = Path(out)
    items = [(f"{i:04d}-{s.digest[:16]}", s) for i, s in enumerate(specs)]
    outcome = engine.map(_plan_files, opts, opts.key(), items, desc="jobs", progress=progress)
    jobs = []
    for (key, spec), name, f in zip(items, names, files, strict=True):
        folder = root / name
        r = outcome.results.get(key)
        if r is None:
            why = outcome.failed.get(key, "interrupted before it finished")
            jobs.append(BatchJob(str(f), spec.name, str(folder), False, reason=why,
                                 error="EngineFailure" if key in outcome.failed else "Interrupted"))
            continue
        for rel, data in r["files"].items():
            with atomic_path(folder / rel) as tmp:
                tmp.write_bytes(data)
        jobs.append(BatchJob(str(f), spec.name, str(folder), r["ok"], r.get("cycle_time"),
                             r.get("method"), r.get("solver_status"), r.get("reason"),
                             r.get("error"), sorted(r["files"]), r["wall_time"], r["worker"]))
    result = BatchResult(jobs, outcome.interrupted, engine.address, engine.workers,
                         time.perf_counter() - t0)
    write_text_atomic(root / "batch.json", json.dumps(result.as_json(), indent=2) + "\n")
    return result
