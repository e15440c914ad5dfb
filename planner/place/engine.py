"""Where the plans of a study run: in this process, or on Dask distributed.

:func:`open_engine` gives an :class:`Engine` for a scheduler address:

* ``local`` (the default) — a Dask ``LocalCluster`` of worker processes, one thread each, as many
  as this process may use cores; started here and closed with the engine;
* ``tcp://HOST:PORT`` (any Dask address) — an existing cluster (``dask scheduler`` and
  ``dask worker``); the engine connects a client and closes only that;
* ``none`` — serially in this process (no Dask at all).

:func:`resolve_scheduler` picks the address: the command's ``--scheduler``, else the environment
variable :data:`SCHEDULER_ENV`, else the job's ``[plan] scheduler``, else ``local``.

Tasks are pure functions ``fn(shared, item)`` of plain data (a :class:`~planner.place.spec.JobSpec`
and a placement). The shared argument goes to the scheduler once, as a task of its own, so a
worker fetches it once and a lost copy is recomputed; every item's task has a key made from its
content, so a task is never run twice for one result and a lost worker's tasks are rerun
elsewhere by the scheduler with the same key. :meth:`Engine.map` collects results by key as they
complete (a progress bar counts them) and returns what finished when interrupted (Ctrl-C cancels
the rest).
"""

from __future__ import annotations

import contextlib
import logging
import os
import signal
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

from models.errors import CctmillError
from planner._progress import bar

__all__ = [
    "CONNECT_TIMEOUT",
    "SCHEDULER_ENV",
    "DaskEngine",
    "Engine",
    "EngineError",
    "MapOutcome",
    "SerialEngine",
    "local_workers",
    "open_engine",
    "resolve_scheduler",
]

#: Environment variable naming the scheduler when ``--scheduler`` is not given.
SCHEDULER_ENV = "CCTMILL_SCHEDULER"
#: How long connecting to an existing scheduler may take [s].
CONNECT_TIMEOUT = 10.0
#: How long a started LocalCluster may take to come up [s] (2 shared cores: generous).
LOCAL_START_TIMEOUT = 120.0


class EngineError(CctmillError):
    """The engine cannot be used: a bad scheduler address, or none answers there.

    Attributes:
        address: the address given.
    """

    def __init__(self, address: str, message: str) -> None:
        self.address = address
        super().__init__(message)


@dataclass
class MapOutcome:
    """What :meth:`Engine.map` finished.

    Attributes:
        results: result by item key, for every item that finished.
        failed: reason by item key, for items the engine could not run (their worker died
            repeatedly, :class:`distributed.KilledWorker`).
        interrupted: Ctrl-C stopped the map; the items in neither dict were cancelled.
        wall_time: [s].
    """

    results: dict[str, Any] = field(default_factory=dict)
    failed: dict[str, str] = field(default_factory=dict)
    interrupted: bool = False
    wall_time: float = 0.0


class Engine:
    """Runs pure tasks; see the module docstring. Use as a context manager."""

    #: ``none``, ``local`` or the scheduler's address.
    address: str = "none"

    @property
    def workers(self) -> int:
        """Worker processes now (1 for the serial engine)."""
        return 1

    def map(self, fn: Callable[[Any, Any], Any], shared: Any, shared_key: str,
            items: Sequence[tuple[str, Any]], desc: str = "placements",
            progress: bool = False) -> MapOutcome:
        """``fn(shared, item)`` for every ``(key, item)``; keys must be unique and say what the
        task computes (equal keys, equal results)."""
        raise NotImplementedError

    def close(self) -> None:
        """Release the engine (a started cluster is shut down)."""

    def __enter__(self) -> Engine:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _check_keys(items: Sequence[tuple[str, Any]]) -> None:
    keys = [k for k, _ in items]
    if len(set(keys)) != len(keys):
        raise ValueError("Engine.map: item keys must be unique")


class SerialEngine(Engine):
    """Everything in this process, in order (``--scheduler none``)."""

    address = "none"

    def map(self, fn, shared, shared_key, items, desc="placements", progress=False):
        _check_keys(items)
        out = MapOutcome()
        t0 = time.perf_counter()
        pbar = bar(len(items), desc, progress, unit="plan", min_total=1)
        try:
            for key, item in items:
                try:
                    out.results[key] = fn(shared, item)
                except Exception as e:  # noqa: BLE001 - as the Dask engine: reported, not fatal
                    out.failed[key] = f"the task raised {type(e).__name__}: {e}"
                pbar.update(1)
        except KeyboardInterrupt:
            out.interrupted = True
        finally:
            pbar.close()
        out.wall_time = time.perf_counter() - t0
        return out


def _identity(x: Any) -> Any:
    return x


class DaskEngine(Engine):
    """A Dask ``Client``, and the ``LocalCluster`` it owns if it started one."""

    def __init__(self, client: Any, address: str, cluster: Any = None) -> None:
        self.client = client
        self.cluster = cluster
        self.address = address

    @property
    def workers(self) -> int:
        return len(self.client.scheduler_info(n_workers=-1).get("workers", {}))

    def map(self, fn, shared, shared_key, items, desc="placements", progress=False):
        from distributed import KilledWorker, as_completed

        _check_keys(items)
        out = MapOutcome()
        t0 = time.perf_counter()
        client = self.client
        held = client.submit(_identity, shared, key=f"cctmill-shared-{shared_key}", pure=False)
        futures = [client.submit(fn, held, item, key=f"{fn.__name__}-{key}", pure=False)
                   for key, item in items]
        name_of = {f.key: key for f, (key, _) in zip(futures, items, strict=True)}
        pbar = bar(len(items), desc, progress, unit="plan", min_total=1)
        try:
            for fut in as_completed(futures, loop=client.loop):
                key = name_of[fut.key]
                try:
                    out.results[key] = fut.result()
                    fut.release()  # gathered: a worker lost later does not make it run again
                except KilledWorker as e:
                    out.failed[key] = (f"every worker that ran it died ({e}); the task is "
                                       "dropped: find what kills the workers (memory?)")
                except Exception as e:  # noqa: BLE001 - the task raised: reported, not fatal
                    out.failed[key] = f"the task raised {type(e).__name__}: {e}"
                pbar.update(1)
        except KeyboardInterrupt:
            out.interrupted = True
            client.cancel(futures, force=True)
        finally:
            pbar.close()
            del futures, held
        out.wall_time = time.perf_counter() - t0
        return out

    def run_on_workers(self, fn: Callable[..., Any], *args: Any) -> dict[str, Any]:
        """``fn(*args)`` on every worker now, by worker address (a warm-up, or diagnostics:
        :func:`planner.place.spec.cache_info`)."""
        return self.client.run(fn, *args)

    def close(self) -> None:
        with contextlib.suppress(Exception):  # a cluster that is gone is closed
            self.client.close()
        if self.cluster is not None:
            with contextlib.suppress(Exception):
                self.cluster.close()


def dask_setup(worker: Any) -> None:
    """Dask's preload hook, run in each worker of a local cluster as it starts: ignore Ctrl-C.

    Ctrl-C reaches every process of the terminal's group; the workers leave it to this process,
    which cancels the tasks and closes the cluster, instead of each dying with its own traceback.
    """
    del worker
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)


def local_workers() -> int:
    """Cores this process may use (the default number of local workers)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def resolve_scheduler(flag: str | None = None, job_value: str | None = None) -> str:
    """The scheduler to use: ``flag``, else ``$CCTMILL_SCHEDULER``, else the job's key, else
    ``local`` (see the module docstring).

    Raises:
        EngineError: the address is none of ``none``, ``local`` or ``SCHEME://HOST:PORT``.
    """
    for value, where in ((flag, "--scheduler"), (os.environ.get(SCHEDULER_ENV), SCHEDULER_ENV),
                         (job_value, "[plan] scheduler")):
        if value is None or not value.strip():
            continue
        v = value.strip()
        if v in ("none", "local") or "://" in v:
            return v
        raise EngineError(v, f"{where}: {v!r} is not a scheduler; give none (serial, in this "
                             "process), local (a cluster of this machine's cores) or a Dask "
                             "address such as tcp://10.0.0.5:8786")
    return "local"


def open_engine(address: str = "local", workers: int | None = None) -> Engine:
    """The engine for ``address`` (see the module docstring); close it (or use ``with``).

    Args:
        address: ``none``, ``local`` or a Dask scheduler address.
        workers: worker processes of a ``local`` cluster (default :func:`local_workers`).

    Raises:
        EngineError: no scheduler answers at ``address`` within :data:`CONNECT_TIMEOUT`.
    """
    if address == "none":
        return SerialEngine()
    from distributed import Client, LocalCluster

    if address == "local":
        n = workers or local_workers()
        cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                               dashboard_address=None, silence_logs=logging.ERROR,
                               timeout=LOCAL_START_TIMEOUT, preload=[__name__])
        return DaskEngine(Client(cluster, set_as_default=False), "local", cluster)
    try:
        client = Client(address, timeout=CONNECT_TIMEOUT, set_as_default=False)
    except (OSError, TimeoutError, ValueError) as e:
        raise EngineError(address, f"--scheduler {address}: no Dask scheduler answers there "
                                   f"({type(e).__name__}: {e}); start one (dask scheduler, then "
                                   "dask worker ADDRESS on each machine) or pass --scheduler "
                                   "local") from e
    try:
        client.wait_for_workers(1, timeout=CONNECT_TIMEOUT)
    except (OSError, TimeoutError) as e:
        client.close()
        raise EngineError(address, f"--scheduler {address}: the scheduler has no worker (none "
                                   f"joined within {CONNECT_TIMEOUT:g} s); start one on each "
                                   f"machine: dask worker {address} --nthreads 1") from e
    return DaskEngine(client, address)

