"""Robot link latency over loopback: KukaVarProxy write round trip and RSI reply time.

1. KVP: ``$OV_PRO`` write round trips (request → reply) and write + read-back pairs (what
   :class:`robot_io.links.kvp.KvpClient` does per override change) of
   :class:`~robot_io.links.kvp.KvpConnection`
   against :class:`~robot_io.links.kvp_sim.KvpSimServer`; py-openshowvar's write on the same server when
   installed; baseline: a bare TCP echo of the same request bytes (thread + loopback cost only).
2. RSI: :class:`~robot_io.links.rsi_sim.RsiSimController` at 4 ms and 12 ms against
   :class:`~robot_io.links.rsi.RsiServer`: round trip (``<Rob>`` sent → its ``<Sen>`` received, replies
   after the deadline included), the server's own receive-to-reply time, and late cycles (no reply by
   the end of the cycle; "never answered" = no reply at all); baseline: a bare UDP echo ping-pong of
   the same telegram.

Worst case and p99 are what count for an online link (the controller cycle is 4 ms or 12 ms); the
ratios are against the bare echo measured in the same run. The peer (simulated controller, echo)
runs in a child process, as a controller is another machine; both share the benchmark machine's
cores with whatever else runs there, so worst cases include that scheduling noise.

Run from the repository root: ``python benchmarks/link_latency.py [--kvp-n N] [--rsi-s S] [--json]``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import multiprocessing as mp
import socket
import sys
import threading
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from robot_io.links.kvp import FN_WRITE, KvpConnection, KvpRequest, pack_request  # noqa: E402
from robot_io.links.kvp_sim import KvpSimServer  # noqa: E402
from robot_io.links.rsi import RsiServer, build_rob  # noqa: E402
from robot_io.links.rsi_process import RsiProcessServer  # noqa: E402
from robot_io.links.rsi_sim import RsiSimController  # noqa: E402

CYCLES_S = (0.004, 0.012)


def _summary(samples_s: list[float] | np.ndarray) -> dict:
    a = np.asarray(samples_s, float)
    return {"n": int(a.size), "p50_ms": float(np.percentile(a, 50) * 1e3),
            "p99_ms": float(np.percentile(a, 99) * 1e3), "max_ms": float(a.max() * 1e3)}


def _echo_proc(udp: bool, pipe) -> None:
    """Child process: bare echo server (TCP or UDP) on loopback — the baseline peer."""
    kind = socket.SOCK_DGRAM if udp else socket.SOCK_STREAM
    sock = socket.socket(socket.AF_INET, kind)
    sock.bind(("127.0.0.1", 0))
    if not udp:
        sock.listen(1)
    pipe.send(sock.getsockname())
    if udp:
        sock.settimeout(0.1)
        while not pipe.poll():
            try:
                data, addr = sock.recvfrom(65536)
            except TimeoutError:
                continue
            sock.sendto(data, addr)
        return
    conn, _ = sock.accept()
    conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    with conn:
        while data := conn.recv(65536):
            conn.sendall(data)


def _kvp_server_proc(count_trailer: bool, pipe) -> None:
    """Child process: the simulated KukaVarProxy server until told to stop."""
    with KvpSimServer(count_trailer=count_trailer) as srv:
        pipe.send(srv.address)
        pipe.recv()


def _rsi_controller_proc(addr: tuple[str, int], cycle: float, cycles: int, pipe) -> None:
    """Child process: the simulated RSI controller for ``cycles`` cycles; sends back its counters."""
    sim = RsiSimController(addr, cycle_s=cycle, max_cycles=cycles, timeout_packets=cycles + 1)
    with sim:
        sim.wait(cycles * cycle * 3 + 5)
    pipe.send({"stats": dataclasses.asdict(sim.stats), "round_trips": sim.round_trips(),
               "late_round_trips": sim.late_round_trips(), "status": sim.status})


class _Child:
    """A child process running ``target(*args, pipe)``; ``first`` is the first message it sent."""

    def __init__(self, target, *args) -> None:
        ctx = mp.get_context("spawn")
        self.pipe, child_end = ctx.Pipe()
        self.proc = ctx.Process(target=target, args=(*args, child_end), daemon=True)
        self.proc.start()

    def recv(self, timeout: float = 30.0):
        if not self.pipe.poll(timeout):
            raise RuntimeError("benchmark peer process did not answer")
        return self.pipe.recv()

    def close(self) -> None:
        try:
            self.pipe.send("stop")
        except OSError:
            pass
        self.proc.join(10)
        if self.proc.is_alive():
            self.proc.terminate()
            self.proc.join()


def kvp_latency(n: int = 2000) -> dict:
    """KVP round trips [ms]: write, write + read-back, py-openshowvar write, bare TCP echo."""
    out: dict = {}
    req = pack_request(KvpRequest(1, FN_WRITE, "$OV_PRO", "80"))
    echo = _Child(_echo_proc, False)
    try:
        with socket.create_connection(tuple(echo.recv()), timeout=1.0) as s:
            s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            times = []
            for _ in range(n):
                t0 = time.perf_counter()
                s.sendall(req)
                got = 0
                while got < len(req):
                    got += len(s.recv(65536))
                times.append(time.perf_counter() - t0)
        out["baseline_tcp_echo"] = _summary(times)
    finally:
        echo.close()
    for count_trailer in (True, False):
        srv = _Child(_kvp_server_proc, count_trailer)
        try:
            host, port = srv.recv()
            with KvpConnection(host, port, timeout=1.0) as c:
                w, wr = [], []
                for i in range(n):
                    value = str(i % 101)
                    t0 = time.perf_counter()
                    if c.write("$OV_PRO", value) != value:
                        raise RuntimeError("write not echoed")
                    t1 = time.perf_counter()
                    if c.read("$OV_PRO") != value:
                        raise RuntimeError("read-back differs")
                    t2 = time.perf_counter()
                    w.append(t1 - t0)
                    wr.append(t2 - t0)
        finally:
            srv.close()
        key = "trailer counted" if count_trailer else "trailer not counted"
        out[f"write ({key})"] = _summary(w)
        out[f"write + read-back ({key})"] = _summary(wr)
    try:
        import py_openshowvar
    except ImportError as e:
        out["py_openshowvar"] = f"skipped: {e}"
    else:
        srv = _Child(_kvp_server_proc, True)
        try:
            client = py_openshowvar.openshowvar(*srv.recv())
            try:
                times = []
                for i in range(n):
                    t0 = time.perf_counter()
                    if client.write("$OV_PRO", str(i % 101), debug=False) is None:
                        raise RuntimeError("py-openshowvar write failed")
                    times.append(time.perf_counter() - t0)
            finally:
                client.close()
        finally:
            srv.close()
        out["py-openshowvar write (same server)"] = _summary(times)
    return out


def rsi_latency(seconds: float = 4.0) -> dict:
    """RSI round trip and server reply time [ms] per cycle, and a bare UDP echo ping-pong."""
    out: dict = {}
    telegram = build_rob(1_000_000, (1368.8, 5.2, 876.6, 0.0, 90.0, 0.0), (0, -90, 90, 0, 45, 0), 0, 100)
    echo = _Child(_echo_proc, True)
    try:
        addr = tuple(echo.recv())
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            s.settimeout(1.0)
            times = []
            for _ in range(int(seconds / 0.004)):
                t0 = time.perf_counter()
                s.sendto(telegram, addr)
                s.recv(65536)
                times.append(time.perf_counter() - t0)
                time.sleep(0.004)
        out["baseline_udp_echo"] = _summary(times)
    finally:
        echo.close()
    runs: list[tuple[str, float, float | None, bool]] = [(f"{c * 1e3:.0f} ms", c, None, False)
                                                         for c in CYCLES_S]
    # The supervisor shares the server's process: a CPU-bound Python thread beside the server holds
    # the GIL for up to sys.getswitchinterval() (5 ms by default) at a time.
    # RsiProcessServer moves the server out of the caller's process.
    runs += [("4 ms, CPU-bound thread beside the server (switch interval 5 ms)", 0.004, 0.005, False),
             ("4 ms, CPU-bound thread beside the server (switch interval 0.5 ms)", 0.004, 0.0005, False),
             ("4 ms, CPU-bound thread in the caller, RsiProcessServer (switch interval 5 ms)", 0.004,
              0.005, True)]
    for name, cycle, switch, process in runs:
        out[name] = _rsi_run(cycle, seconds, switch, process)
    return out


def _rsi_run(cycle: float, seconds: float, switch_interval: float | None, process: bool) -> dict:
    stop = threading.Event()
    busy = None
    old_switch = sys.getswitchinterval()
    if switch_interval is not None:
        sys.setswitchinterval(switch_interval)

        def spin() -> None:
            x = 0
            while not stop.is_set():
                x = (x * 31 + 7) % 1_000_003

        busy = threading.Thread(target=spin, daemon=True)
        busy.start()
    try:
        server = RsiProcessServer if process else RsiServer
        with server(reply_budget_s=cycle / 2) as srv:
            cycles = int(seconds / cycle)
            ctl = _Child(_rsi_controller_proc, srv.address, cycle, cycles)
            try:
                res = ctl.recv(timeout=cycles * cycle * 3 + 30)
            finally:
                ctl.close()
            ss = srv.stats
            times = srv.reply_times()
    finally:
        stop.set()
        if busy is not None:
            busy.join()
        sys.setswitchinterval(old_switch)
    st = res["stats"]
    if res["status"] != "done" or not res["round_trips"]:
        raise RuntimeError(f"RSI run did not complete: {res['status']}")
    return {"round_trip": _summary(res["round_trips"] + res["late_round_trips"]),
            "server_reply": _summary(times), "cycles": st["cycles"], "late": st["late"],
            "stale": st["stale"], "wrong_ipoc": st["wrong_ipoc"],
            "malformed": st["malformed"] + ss.malformed, "sender_overruns": st["overruns"],
            "cycle_ms": cycle * 1e3}


def markdown(res: dict) -> str:
    """The results as Markdown tables."""
    k, r = res["kvp"], res["rsi"]
    base = k["baseline_tcp_echo"]
    lines = ["| KVP (TCP, loopback) | n | p50 | p99 | worst | p50 / echo p50 |",
             "|---|---:|---:|---:|---:|---:|"]
    for name, s in k.items():
        if isinstance(s, str):
            lines.append(f"| {name} | {s} | | | | |")
            continue
        label = "bare TCP echo (baseline)" if name == "baseline_tcp_echo" else name
        lines.append(f"| {label} | {s['n']} | {s['p50_ms']:.3f} ms | {s['p99_ms']:.3f} ms | "
                     f"{s['max_ms']:.3f} ms | {s['p50_ms'] / base['p50_ms']:.1f}× |")
    ub = r["baseline_udp_echo"]
    lines += ["", "| RSI (UDP, loopback) | cycles | round trip p50 / p99 / worst | server reply p99 / worst "
              "| late cycles (never answered) | worst / cycle | p50 / echo p50 |",
              "|---|---:|---|---|---:|---:|---:|",
              f"| bare UDP echo (baseline) | {ub['n']} | {ub['p50_ms']:.3f} / {ub['p99_ms']:.3f} / "
              f"{ub['max_ms']:.3f} ms | — | — | — | 1.0× |"]
    for name, s in r.items():
        if name == "baseline_udp_echo":
            continue
        rt, sr = s["round_trip"], s["server_reply"]
        lines.append(f"| {name} | {s['cycles']} | {rt['p50_ms']:.3f} / {rt['p99_ms']:.3f} / "
                     f"{rt['max_ms']:.3f} ms | {sr['p99_ms']:.3f} / {sr['max_ms']:.3f} ms | {s['late']} "
                     f"({s['late'] - s['stale']}) | {rt['max_ms'] / s['cycle_ms']:.2f} | "
                     f"{rt['p50_ms'] / ub['p50_ms']:.1f}× |")
    return "\n".join(lines)


def summary_rows(res: dict) -> list[tuple[str, str, str, str]]:
    """(benchmark, this run, target, verdict) rows for ``run_all.py``'s summary table."""
    k = res["kvp"]["write + read-back (trailer counted)"]
    rows = [("link: KVP $OV_PRO write + read-back (loopback)",
             f"p99 {k['p99_ms']:.2f} ms, worst {k['max_ms']:.2f} ms",
             "(no target; KukaVarProxy is not real-time, JOpenShowVar writes every 10 ms)", "—")]
    for name, s in res["rsi"].items():
        if name == "baseline_udp_echo":
            continue
        rt = s["round_trip"]
        ok = s["late"] == 0 and rt["max_ms"] < s["cycle_ms"]
        rows.append((f"link: RSI reply, {name} (loopback)",
                     f"round trip p99 {rt['p99_ms']:.2f} ms, worst {rt['max_ms']:.2f} ms; "
                     f"{s['late']} late of {s['cycles']}",
                     f"every reply inside the {s['cycle_ms']:.0f} ms cycle", "met" if ok else "NOT met"))
    return rows


def run(kvp_n: int = 2000, rsi_s: float = 4.0) -> dict:
    return {"kvp": kvp_latency(kvp_n), "rsi": rsi_latency(rsi_s)}


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--kvp-n", type=int, default=2000, help="KVP round trips per variant")
    ap.add_argument("--rsi-s", type=float, default=4.0, help="seconds of RSI traffic per cycle time")
    ap.add_argument("--json", action="store_true", help="print JSON instead of Markdown")
    args = ap.parse_args(argv)
    res = run(args.kvp_n, args.rsi_s)
    print(json.dumps(res, indent=2) if args.json else markdown(res))
    return res


if __name__ == "__main__":
    main()
