"""A job as plain data a worker can plan from, and the per-process cache of what it builds.

Workers are other processes, maybe other machines: what travels is a :class:`JobSpec` — the TOML
document as parsed, the job file's name and folder, and the toolpath files' bytes — never a built
object (a CasADi Function or symbol, a pinocchio model). A worker validates the document once per
job and keeps the result in a module-level cache keyed by the spec's content digest; the robot's
symbolic kinematics and the point model's CasADi Functions are built on the first plan and cached
per process by :func:`models.robot.load_robot` and :func:`models.analysis.point_function`. A worker
that shares the client's file system reads the toolpaths where the job names them (they are checked
against the digest); one that does not writes the shipped bytes to a temporary folder of its own.

The cache is the only state here: it changes no result (equal specs, equal jobs), and
:func:`cache_info` shows it.
"""

from __future__ import annotations

import atexit
import copy
import hashlib
import json
import os
import shutil
import tempfile
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from planner.job import Job, JobError, parse_job
from planner.place.grid import Placement

__all__ = ["JobSpec", "cache_info", "job_at", "job_of", "local_path"]


@dataclass(frozen=True)
class JobSpec:
    """A job as plain, picklable data (see the module docstring).

    Attributes:
        doc: the TOML document as parsed.
        file: the job file's name (for messages).
        folder: where relative paths resolved on the client.
        toolpaths: ``(path on the client, bytes)`` of every toolpath file, in the job's order.
        digest: SHA-256 of all of the above (the cache key and the engine's task-key stem).
    """

    doc: dict[str, Any]
    file: str
    folder: str
    toolpaths: tuple[tuple[str, bytes], ...]
    digest: str

    @classmethod
    def from_doc(cls, doc: dict[str, Any], file: str = "<job>", folder: str | os.PathLike = ".",
                 ) -> JobSpec:
        """The spec of a parsed document (validated here: a bad job fails before any task).

        Raises:
            JobError: the document is not a valid job, or a toolpath file cannot be read.
        """
        job = parse_job(doc, file, folder)
        files = []
        for p in job.toolpath_files():
            try:
                files.append((str(p), p.read_bytes()))
            except OSError as e:
                raise JobError(file, [f"[job] toolpath: cannot read {p}: {e.strerror or e}; fix "
                                      "the path (relative to the job file)"]) from e
        h = hashlib.sha256()
        h.update(json.dumps(doc, sort_keys=True, default=str).encode())
        h.update(f"\0{file}\0{Path(folder).resolve()}\0".encode())
        for name, data in files:
            h.update(f"{name}\0{len(data)}\0".encode())
            h.update(data)
        return cls(doc=copy.deepcopy(doc), file=str(file), folder=str(Path(folder).resolve()),
                   toolpaths=tuple(files), digest=h.hexdigest())

    @classmethod
    def from_file(cls, path: str | os.PathLike) -> JobSpec:
        """The spec of a job file (UTF-8 TOML).

        Raises:
            JobError: as :func:`planner.job.load_job`, or a toolpath cannot be read.
        """
        from planner.job import load_job

        p = Path(path)
        load_job(p)  # every message of the job loader, before the document is taken as is
        doc = tomllib.loads(p.read_text(encoding="utf-8"))
        return cls.from_doc(doc, str(p), p.parent.resolve())

    @property
    def name(self) -> str:
        """The job's ``[job] name``."""
        return str(self.doc.get("job", {}).get("name", "job"))


#: digest → (the validated job, the folder it was written to or None, the client paths of its
#: toolpath files, their paths here). Per process; see the module docstring.
_JOBS: dict[str, tuple[Job, str | None, tuple[str, ...], tuple[str, ...]]] = {}
_TEMP_DIRS: list[str] = []


def _remove_temp_dirs() -> None:
    for d in _TEMP_DIRS:
        shutil.rmtree(d, ignore_errors=True)


def _same_file(path: str, data: bytes) -> bool:
    try:
        p = Path(path)
        return p.is_file() and p.stat().st_size == len(data) and p.read_bytes() == data
    except OSError:
        return False


def job_of(spec: JobSpec) -> Job:
    """The validated job of ``spec``, built once per process (see the module docstring)."""
    hit = _JOBS.get(spec.digest)
    if hit is not None:
        return hit[0]
    names = tuple(name for name, _ in spec.toolpaths)
    if all(_same_file(name, data) for name, data in spec.toolpaths):
        job = parse_job(spec.doc, spec.file, spec.folder)
        _JOBS[spec.digest] = (job, None, names, names)
        return job
    if not _TEMP_DIRS:
        atexit.register(_remove_temp_dirs)
    tmp = tempfile.mkdtemp(prefix=f"cctmill-job-{spec.digest[:12]}-")
    _TEMP_DIRS.append(tmp)
    rel = []
    for i, (name, data) in enumerate(spec.toolpaths):
        sub = Path(tmp) / f"f{i}"
        sub.mkdir()
        (sub / Path(name).name).write_bytes(data)
        rel.append(f"f{i}/{Path(name).name}")
    doc = copy.deepcopy(spec.doc)
    doc.setdefault("job", {})["toolpath"] = rel
    job = parse_job(doc, spec.file, tmp)
    _JOBS[spec.digest] = (job, tmp, names, tuple(str(Path(tmp) / r) for r in rel))
    return job


def local_path(spec: JobSpec, text: str) -> str:
    """``text`` (a message) with this process's copies of the toolpath files named as on the
    client, so that a worker without the client's files reports the user's paths."""
    hit = _JOBS.get(spec.digest)
    if hit is None or hit[1] is None:
        return text
    for client, here in zip(hit[2], hit[3], strict=True):
        text = text.replace(here, client)
    return text


def job_at(spec: JobSpec, placement: Placement) -> Job:
    """The job of ``spec`` with ``$BASE`` moved to ``placement`` (its B and C kept)."""
    job = job_of(spec)
    abc = list(job.cell.base_abc_deg)
    abc[0] = placement.yaw_deg
    cell = job.cell.model_copy(update={"base_mm": placement.base_mm, "base_abc_deg": abc})
    return job.model_copy(update={"cell": cell})


def cache_info() -> dict[str, Any]:
    """What this process has cached: its pid, the jobs (digest prefixes) and how many of them were
    written to a temporary folder."""
    return {"pid": os.getpid(), "jobs": sorted(d[:12] for d in _JOBS),
            "copied": sum(1 for v in _JOBS.values() if v[1] is not None)}
