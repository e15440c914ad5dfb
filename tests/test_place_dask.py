"""Placement studies on Dask distributed: a LocalCluster equals the serial run; a study through
``--scheduler`` on a ``dask scheduler`` and two ``dask worker`` processes on loopback; a worker
killed mid-study leaves the study complete and correct.

Every process a test starts is in its own session and is killed (its whole group) by the fixture,
pass or fail. About 30 s on 2 cores (the demo plan is ~0.5 s; the workers import the planner on
their first task).
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from planner.demo import demo_job_file
from planner.place.engine import open_engine
from planner.place.grid import Axis, PlacementGrid
from planner.place.search import run_study
from planner.place.spec import JobSpec, cache_info

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[1]
DASK = Path(sys.executable).with_name("dask")
#: How long the loopback cluster may take to come up [s] (2 shared cores).
START_S = 90.0


def _grid(n_z: int) -> PlacementGrid:
    """x 1500/1800 mm × z over 0..800 mm at the demo's y and yaw: every placement reachable."""
    return PlacementGrid(Axis(1.5, 1.8, 2), Axis.single(-0.06),
                         Axis(0.0, 0.8, n_z) if n_z > 1 else Axis.single(0.4), Axis.single(0.0))


@pytest.fixture(scope="module")
def spec() -> JobSpec:
    return JobSpec.from_file(demo_job_file())


@pytest.fixture(scope="module")
def serial(spec):
    """The serial study of the 6-placement grid: the reference every engine must reproduce."""
    with open_engine("none") as eng:
        return run_study(spec, _grid(3), eng)


def _rows(study) -> list[dict]:
    """The study's rows without what legitimately differs between runs (who, how long)."""
    out = []
    for r in study.as_json()["placements"]:
        out.append({k: v for k, v in r.items() if k not in ("wall_time_s", "worker")})
    return out


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class LoopbackCluster:
    """``dask scheduler`` and ``dask worker`` processes on 127.0.0.1, each in its own session."""

    def __init__(self, tmp: Path, workers: int = 2) -> None:
        self.port = _free_port()
        self.address = f"tcp://127.0.0.1:{self.port}"
        self.procs: list[subprocess.Popen] = []
        self.logs = tmp
        self._start([str(DASK), "scheduler", "--host", "127.0.0.1", "--port", str(self.port),
                     "--no-dashboard"], "scheduler")
        self.workers = [self._start([str(DASK), "worker", self.address, "--host", "127.0.0.1",
                                     "--nthreads", "1", "--nworkers", "1", "--no-dashboard",
                                     "--death-timeout", "60", "--local-directory", str(tmp)],
                                    f"worker{i}") for i in range(workers)]
        from distributed import Client

        with Client(self.address, timeout=START_S, set_as_default=False) as c:
            c.wait_for_workers(workers, timeout=START_S)

    def _start(self, cmd: list[str], name: str) -> subprocess.Popen:
        log = open(self.logs / f"{name}.log", "wb")  # noqa: SIM115 - closed with the process
        p = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, cwd=ROOT,
                             start_new_session=True)
        log.close()
        self.procs.append(p)
        return p

    def kill(self, p: subprocess.Popen) -> None:
        """SIGKILL ``p``'s whole process group (a ``dask worker`` is a nanny and its worker)."""
        with contextlib.suppress(ProcessLookupError):
            os.killpg(p.pid, signal.SIGKILL)
        p.wait(timeout=30)

    def close(self) -> None:
        for p in reversed(self.procs):
            if p.poll() is None:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(p.pid, signal.SIGTERM)
        deadline = time.monotonic() + 10
        for p in self.procs:
            try:
                p.wait(timeout=max(0.1, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                self.kill(p)


@pytest.fixture
def loopback(tmp_path):
    cluster = LoopbackCluster(tmp_path)
    try:
        yield cluster
    finally:
        cluster.close()


def test_local_cluster_equals_serial(spec, serial):
    with open_engine("local", workers=2) as eng:
        study = run_study(spec, _grid(3), eng)
        caches = eng.run_on_workers(cache_info)
    assert study.engine == "local" and study.workers == 2
    assert _rows(study) == _rows(serial)
    assert study.best == serial.best and study.own == serial.own
    assert len(study.results) == len(_grid(3)) and not study.failed and not study.interrupted
    # each worker validated the job once (its cache) and planned from the client's files
    assert len(caches) == 2
    assert all(c["jobs"] == [spec.digest[:12]] and c["copied"] == 0 for c in caches.values())
    assert len({r.worker for r in study.results}) == 2  # both worked


def test_study_through_scheduler_on_loopback_workers(loopback, spec, serial, tmp_path, capsys):
    from planner.cli import main

    out = tmp_path / "out"
    rc = main(["place", str(demo_job_file()), "-o", str(out), "--x-mm", "1500:1800:2",
               "--y-mm", "-60", "--z-mm", "0:800:3", "--scheduler", loopback.address,
               "--no-best-plan", "--json"])
    assert rc == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["engine"] == {"scheduler": loopback.address, "workers": 2}
    doc = json.loads((out / "place.json").read_text(encoding="utf-8"))
    assert doc["complete"] and not doc["interrupted"]
    rows = [{k: v for k, v in r.items() if k not in ("wall_time_s", "worker")}
            for r in doc["placements"]]
    assert rows == _rows(serial)
    # the tasks ran in the worker processes, not here
    assert {r["worker"].rsplit(":", 1)[1] for r in doc["placements"]} <= {
        str(p) for p in _worker_pids(loopback)}
    assert (out / "place_heatmap.png").stat().st_size > 0


def _worker_pids(cluster: LoopbackCluster) -> set[int]:
    from distributed import Client

    with Client(cluster.address, timeout=30, set_as_default=False) as c:
        return set(c.run(os.getpid).values())


def test_worker_killed_mid_study_completes_correctly(loopback, spec, serial):
    from distributed import Client

    victim = loopback.workers[0]
    box: dict = {}

    def study() -> None:
        with open_engine(loopback.address) as eng:
            box["study"] = run_study(spec, _grid(3), eng)

    watcher = Client(loopback.address, timeout=30, set_as_default=False)
    try:
        victim_address, victim_pid = next((a, pid) for a, pid in watcher.run(os.getpid).items()
                                          if _is_child_of(pid, victim.pid))
        t = threading.Thread(target=study)
        t.start()
        deadline = time.monotonic() + START_S
        while time.monotonic() < deadline:  # until the victim is running a placement's plan
            running = [str(k) for k in watcher.processing().get(victim_address, ())
                       if str(k).startswith("evaluate_placement-")]
            if running:
                break
            time.sleep(0.02)
        else:
            pytest.fail("the victim worker never ran a placement")
        assert t.is_alive()  # mid-study
        loopback.kill(victim)
        t.join(timeout=START_S)
        assert not t.is_alive()
    finally:
        watcher.close()
    got = box["study"]
    assert not got.failed and not got.interrupted
    keys = [r.placement.key for r in got.results]
    assert sorted(keys) == sorted(p.key for p in _grid(3).placements())  # none missing, none twice
    assert _rows(got) == _rows(serial)
    # what the victim was running when it died was run again by the other worker
    lost = running[0].split("-", 2)[2]
    redone = next(r for r in got.candidates() if r.placement.key == lost)
    assert not redone.worker.endswith(f":{victim_pid}")


def _is_child_of(pid: int, parent: int) -> bool:
    """Whether ``pid`` is ``parent`` or its descendant (``dask worker`` runs a nanny → worker)."""
    while pid > 1:
        if pid == parent:
            return True
        try:
            stat = Path(f"/proc/{pid}/stat").read_text()
        except OSError:
            return False
        pid = int(stat.rsplit(")", 1)[1].split()[1])
    return False


def _session_members(sid: int) -> list[int]:
    """Pids of the processes still in session ``sid``."""
    out = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                fields = (d / "stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[3]) == sid:
                out.append(int(d.name))
    return out


def test_ctrl_c_cancels_closes_the_cluster_and_writes_what_finished(tmp_path):
    out = tmp_path / "out"
    cmd = [str(Path(sys.executable).with_name("cctmill")), "place", "--demo", "-o", str(out),
           "--workers", "2"]
    p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, cwd=ROOT,
                         start_new_session=True,
                         preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        lines = [p.stderr.readline(), p.stderr.readline()]  # the study, then the engine ready
        assert lines[1].startswith(b"engine ready: local, 2 workers"), lines
        time.sleep(3.0)  # the first plans done (75 placements take far longer)
        os.killpg(p.pid, signal.SIGINT)  # as Ctrl-C in a terminal: the whole process group
        _, err = p.communicate(timeout=60)
    finally:
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGKILL)
            p.wait()
    assert p.returncode == 130, err
    assert b"Traceback" not in err  # the workers ignore it; the command stops them
    doc = json.loads((out / "place.json").read_text(encoding="utf-8"))
    assert doc["interrupted"] and not doc["complete"]
    assert len(doc["placements"]) < doc["grid"]["placements"] + 1  # stopped before the end
    assert not (out / "best").exists()
    deadline = time.monotonic() + 10
    while _session_members(p.pid) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert _session_members(p.pid) == []  # no worker left behind
