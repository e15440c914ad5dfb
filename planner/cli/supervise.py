"""``cctmill supervise``: run the online chatter supervisor against a signal and a controller.

::

    cctmill supervise --plan PLAN_DIR_OR_JSON --signal FILE|udp://HOST:PORT|sim
                      --robot sim|kvp://HOST:PORT|rsi://BIND_HOST:PORT
                      [--log events.jsonl] [--fs-hz N] [--alpha-f 6e-5] [--duration-s S] ...

- ``--signal FILE`` replays a recorded CSV/NPY in real time; ``udp://HOST:PORT`` binds a UDP
  sample-stream receiver (format in :mod:`robot_io.signals.udp`); ``sim`` simulates the cut
  (:mod:`planner.supervisor.sim_cut`) whose feed follows the override the controller applies.
- ``--robot sim`` starts a simulated controller in-process and talks to it over loopback
  (``--sim-protocol kvp``: KukaVarProxy server + client, the default; ``rsi``: RSI controller +
  server); ``kvp://HOST:PORT`` connects to a KukaVarProxy; ``rsi://BIND_HOST:PORT`` binds the RSI
  server the controller sends to.
- σ of the stable band: ``--sigma``, else from a simulated stable cut (``--signal sim``), else
  learned from the first ``--stable-s`` seconds of the signal (the user vouches they are stable).

Prints a summary (episodes with detection delay and settling time when simulated, step latency
against the controller cycle, link and source counters) as text or ``--json``.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from typing import Any
from urllib.parse import urlsplit

import numpy as np

from models.errors import InputError
from planner.supervisor.event_log import EventLog
from planner.plan_file import load_plan
from planner.supervisor.sim_cut import CutScenario, SimulatedCut
from planner.supervisor.loop import VirtualClock, run_loop
from planner.supervisor.metrics import episode_metrics
from planner.supervisor.plot import RunTrace, plot_run
from planner.supervisor import Supervisor, SupervisorConfig

__all__ = ["register", "run", "simulated_sigma", "supervise"]


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``supervise`` subcommand."""
    p = sub.add_parser("supervise", help="online wavelet chatter supervisor: signal in, feed override out")
    p.add_argument("--plan", required=True, metavar="PLAN_DIR_OR_JSON", help="plan from `cctmill plan`")
    p.add_argument("--signal", required=True, metavar="FILE|udp://HOST:PORT|sim",
                   help="recorded CSV/NPY (replayed in real time), UDP sample stream to bind, or sim")
    p.add_argument("--robot", required=True, metavar="sim|kvp://HOST:PORT|rsi://BIND_HOST:PORT",
                   help="simulated controller over loopback, KukaVarProxy to connect to, or the RSI "
                        "server address to bind")
    p.add_argument("--signal-column", metavar="NAME",
                   help="CSV value column (default: the first non-time column; e.g. resultant_N "
                        "for a `cctmill simulate --out` record)")
    p.add_argument("--log", metavar="events.jsonl", help="append every decision as JSON lines")
    p.add_argument("--fs-hz", type=float, help="sample rate [Hz] (files without a time column, sim; "
                                               "default 10000 for sim, from the stream for udp)")
    p.add_argument("--alpha-f", type=float, default=6e-5,
                   help="false-alarm rate per band value (default 6e-5: L_c = 4.0)")
    p.add_argument("--duration-s", type=float, help="stop after this long [s] (default: sim 6 s, file: "
                                                     "its length, udp: until Ctrl-C)")
    p.add_argument("--cycle-ms", type=float, default=4.0, help="supervisor cycle [ms] (KR C4 4, KR C2 12)")
    p.add_argument("--sigma", type=float, help="band sigma of stable cutting (signal unit)")
    p.add_argument("--stable-s", type=float, default=1.0,
                   help="learn sigma from this much signal at the start [s] (default 1)")
    p.add_argument("--floor-pct", type=float, default=20.0, help="lowest override [%%] (default 20)")
    p.add_argument("--safe-pct", type=float, help="override when the signal is lost [%%] (default: floor)")
    p.add_argument("--start-mm", type=float, default=0.0, help="arc length where the cut starts [mm]")
    g = p.add_argument_group("simulation (--signal sim / --robot sim)")
    g.add_argument("--sim-protocol", choices=["kvp", "rsi"], default="kvp",
                   help="protocol of the simulated controller (default kvp)")
    g.add_argument("--chatter-onset-s", type=float, default=2.0,
                   help="when the cut becomes less stable than planned [s] (default 2; negative: never)")
    g.add_argument("--boundary-shift", type=float, default=1.6,
                   help="after the onset the true margin at feed f is the plan's at f x this (default 1.6)")
    g.add_argument("--margin-offset-n-per-m", type=float, default=0.0,
                   help="after the onset the true margin is also this much lower [N/m] (default 0)")
    g.add_argument("--signal-loss-s", metavar="A:B", help="no samples between A and B [s]")
    g.add_argument("--seed", type=int, default=0, help="noise seed")
    g.add_argument("--fast", action="store_true",
                   help="--signal sim with kvp://: run on a virtual clock (no sleeping)")
    p.add_argument("--plot", metavar="FILE.png",
                   help="plot the band against its limit, the override and (sim) the true chatter")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.set_defaults(run=run)


def _endpoint(text: str, scheme: str, flag: str) -> tuple[str, int]:
    u = urlsplit(text)
    if u.scheme != scheme or not u.hostname or u.port is None:
        raise InputError(flag, f"{text!r}: expected {scheme}://HOST:PORT")
    return u.hostname, int(u.port)


def _scenario(args: argparse.Namespace) -> CutScenario:
    loss = None
    if args.signal_loss_s:
        try:
            a, b = (float(x) for x in args.signal_loss_s.split(":"))
        except ValueError:
            raise InputError("--signal-loss-s", f"{args.signal_loss_s!r}: expected A:B seconds") from None
        if not 0 <= a < b:
            raise InputError("--signal-loss-s", "need 0 <= A < B")
        loss = (a, b)
    if not args.boundary_shift > 0:
        raise InputError("--boundary-shift", "must be positive")
    onset = args.chatter_onset_s if args.chatter_onset_s is not None and args.chatter_onset_s >= 0 else None
    return CutScenario(onset_s=onset, boundary_shift=args.boundary_shift, loss_s=loss, seed=args.seed,
                       margin_offset_N_per_m=args.margin_offset_n_per_m)


def simulated_sigma(plan, fs_hz: float, scenario: CutScenario, config: SupervisorConfig,
                    duration_s: float = 2.0) -> float:
    """σ of the band in a simulated stable cut (no onset, no loss) at 100 % override, from the
    start of the plan's first cut section (air and rapids carry no cutting force)."""
    clk = VirtualClock()
    stable = CutScenario(**{**scenario.__dict__, "onset_s": None, "loss_s": None,
                            "seed": scenario.seed + 1})
    cuts = [s for s in plan.sections if s.get("kind", "cut") == "cut"]
    start = float(cuts[0]["s_start_m"]) if cuts else 0.0
    cut = SimulatedCut(plan, lambda: 100.0, fs_hz, stable, clock=clk, start_s=start)
    ts, ys = [], []
    for _ in range(int(duration_s / 0.01)):
        clk.sleep(0.01)
        t, y = cut.generate()
        ts.append(t)
        ys.append(y)
    probe = Supervisor(plan, fs_hz, sigma=1.0, config=config)
    return probe.detector.learn(np.concatenate(ys))


def run(args: argparse.Namespace) -> int:
    """``cctmill supervise``: :func:`supervise`, then print its summary (text or JSON)."""
    summary = supervise(args)
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        print(_text(summary))
    return 0


def supervise(args: argparse.Namespace) -> dict[str, Any]:
    """Run the supervisor as the parsed ``cctmill supervise`` flags say; return the summary."""
    if not args.cycle_ms > 0:
        raise InputError("--cycle-ms", "must be positive")
    if args.duration_s is not None and not args.duration_s > 0:
        raise InputError("--duration-s", "must be positive")
    if args.fs_hz is not None and not (math.isfinite(args.fs_hz) and args.fs_hz > 0):
        raise InputError("--fs-hz", "must be positive")
    plan = load_plan(args.plan)
    cfg = SupervisorConfig(alpha_f=args.alpha_f, floor_pct=args.floor_pct, safe_pct=args.safe_pct)
    cycle_s = args.cycle_ms * 1e-3
    closers: list[Any] = []
    cell = None
    cut: SimulatedCut | None = None
    before_step = None
    clock, sleep = time.monotonic, time.sleep
    scenario = _scenario(args)
    fs = args.fs_hz
    try:
        sim_signal = args.signal == "sim"
        if sim_signal and args.robot == "sim":
            from planner.supervisor.sim_cell import SimCell

            fs = fs or 10_000.0
            cell = SimCell(plan, args.sim_protocol, fs, scenario, cycle_s=cycle_s,
                           start_s=args.start_mm * 1e-3)
            closers.append(cell)
            source, link, cut, before_step = cell.source, cell.link, cell.cut, cell.daq
        else:
            link = _make_link(args, cycle_s, closers)
            if sim_signal:
                fs = fs or 10_000.0
                if args.fast:
                    vc = VirtualClock()
                    clock, sleep = vc, vc.sleep

                def applied() -> float:
                    v = link.read_override()
                    return 100.0 if v is None else float(v)

                cut = SimulatedCut(plan, applied, fs, scenario, clock=clock, start_s=args.start_mm * 1e-3)
                source = cut
            else:
                source, fs = _make_source(args, fs, closers)
        if args.sigma is not None:
            if not args.sigma > 0:
                raise InputError("--sigma", "must be positive")
            sigma: float | None = args.sigma
        elif sim_signal:
            sigma = simulated_sigma(plan, fs, scenario, cfg)
        else:
            sigma = None
        log = EventLog(args.log)
        closers.append(log)
        sup = Supervisor(plan, fs, sigma=sigma, config=cfg, log=log, learn_s=args.stable_s,
                         start_s=args.start_mm * 1e-3)
        duration = args.duration_s
        if duration is None:
            duration = (6.0 if sim_signal else getattr(source, "duration_s", None) or math.inf)
        trace = RunTrace()
        try:
            rep = run_loop(sup, source, link, duration, cycle_s, clock=clock, sleep=sleep,
                           before_step=before_step, on_step=trace)
        except KeyboardInterrupt:
            rep = None
        log.flush()
        summary = _summary(sup, rep, source, link, cut, scenario, cycle_s, args)
        if args.plot:
            plot_run(trace, args.plot, cut.truth if cut is not None else None,
                     title=f"cctmill supervise: {args.signal} -> {args.robot}, level "
                           f"{sup.level.level} ({sup.level.band_hz[0]:.3g}-{sup.level.band_hz[1]:.3g} Hz)")
            summary["plot"] = args.plot
    finally:
        for c in reversed(closers):
            try:
                c.close()
            except Exception:  # noqa: BLE001 - closing must not hide the result
                pass
    return summary


def _make_link(args: argparse.Namespace, cycle_s: float, closers: list):
    if args.robot == "sim":
        if args.sim_protocol == "rsi":
            from robot_io.links.rsi import RsiServer
            from robot_io.links.rsi_sim import RsiSimController

            server = RsiServer(cycle_ms=int(round(cycle_s * 1000)))
            closers.append(server)
            ctl = RsiSimController(server.address, cycle_s=cycle_s).start()
            closers.append(type("_Stop", (), {"close": lambda self: ctl.stop()})())
            return server
        from robot_io.links.kvp import KvpClient
        from robot_io.links.kvp_sim import KvpSimServer

        srv = KvpSimServer().start()
        closers.append(type("_Stop", (), {"close": lambda self: srv.stop()})())
        client = KvpClient(*srv.address, timeout=0.1)
        closers.append(client)
        return client
    if args.robot.startswith("kvp://"):
        from robot_io.links.kvp import KvpClient

        client = KvpClient(*_endpoint(args.robot, "kvp", "--robot"))
        closers.append(client)
        return client
    if args.robot.startswith("rsi://"):
        # the RSI server of a real cell runs in its own process: its replies are due inside the
        # controller's cycle whatever this process's GIL is doing
        from robot_io.links.rsi_process import RsiProcessServer

        host, port = _endpoint(args.robot, "rsi", "--robot")
        server = RsiProcessServer(host, port, cycle_ms=int(round(cycle_s * 1000)))
        closers.append(server)
        return server
    raise InputError("--robot", f"{args.robot!r}: use sim, kvp://HOST:PORT or rsi://BIND_HOST:PORT")


def _make_source(args: argparse.Namespace, fs: float | None, closers: list):
    if args.signal.startswith("udp://"):
        from robot_io.signals.udp import UdpSignalSource

        host, port = _endpoint(args.signal, "udp", "--signal")
        src = UdpSignalSource(host, port)
        closers.append(src)
        if fs is None:
            deadline = time.monotonic() + 5.0
            while src.fs_hz <= 0 and time.monotonic() < deadline:
                time.sleep(0.005)
                src.read(0)  # drains datagrams into the backlog; keeps the samples
            if src.fs_hz <= 0:
                raise InputError("--fs-hz", f"no sample datagram on {host}:{port} within 5 s; start the "
                                 "stream first or give the rate")
            fs = src.fs_hz
        return src, fs
    from robot_io.signals.replay import ReplaySource

    src = ReplaySource.from_file(args.signal, fs, column=args.signal_column, realtime=True)
    return src, src.fs_hz


def _ms(x: float | None) -> float | None:
    return None if x is None else round(1e3 * x, 2)


def _summary(sup: Supervisor, rep, source, link, cut, scenario, cycle_s, args) -> dict:
    ch = sup.level
    out: dict[str, Any] = {
        "plan": str(sup.plan.path), "signal": args.signal, "robot": args.robot,
        "fs_hz": sup.fs_hz, "level": ch.level, "band_hz": list(ch.band_hz), "chatter_hz": ch.chatter_hz,
        "tooth_hz": ch.tooth_hz, "level_reason": ch.reason, "L_c": sup.detector.l_c,
        "sigma": sup.detector.sigma, "ucl": sup.detector.ucl if sup.detector.sigma else None,
        "counts": dict(sup.counts), "log": args.log, "log_dropped": sup.log.dropped,
    }
    if rep is not None:
        lat = rep.step_latency_s
        out.update({
            "steps": rep.steps, "duration_s": rep.duration_s, "status_counts": rep.status_counts,
            "final_override": rep.last.override if rep.last else None,
            "step_latency_ms": {"p50": _ms(float(np.percentile(lat, 50))) if lat.size else None,
                                "p99": _ms(float(np.percentile(lat, 99))) if lat.size else None,
                                "max": _ms(float(lat.max())) if lat.size else None,
                                "cycle": _ms(cycle_s)},
            "overruns": rep.overruns, "link_writes": rep.link_writes,
            "link_failures": rep.link_failures, "link_downs": rep.link_downs,
        })
    out["link_stats"] = dict(link.stats.__dict__)
    out["source_stats"] = source.stats.as_dict()
    eps = []
    metrics = []
    if cut is not None and cut.start_clock_s is not None:
        f_c = ch.chatter_hz
        metrics = episode_metrics(sup, cut.truth, f_c, scenario.onset_s, cut.start_clock_s)
    for k, ep in enumerate(sup.episodes):
        e: dict[str, Any] = {"start_s": ep.start_s, "section": ep.section, "direction": ep.direction,
                             "override_start": ep.override_start, "override_min": ep.override_min,
                             "end_s": ep.end_s}
        if k < len(metrics):
            m = metrics[k]
            e.update({"detection_delay_ms": _ms(m.detection_delay_s),
                      "onset_to_alarm_ms": _ms(m.onset_to_alarm_s),
                      "settling_ms": _ms(m.settling_s), "quiet_ms": _ms(m.quiet_s)})
        eps.append(e)
    out["episodes"] = eps
    return out


def _g(x: float | None) -> str:
    return "(learning)" if x is None else f"{x:.4g}"


def _text(s: dict) -> str:
    rows = [f"plan          {s['plan']}",
            f"signal        {s['signal']} at {s['fs_hz']:g} Hz; robot {s['robot']}",
            f"detector      {s['level_reason']}",
            f"chart         L_c {s['L_c']:.3f}, sigma {_g(s['sigma'])}, UCL {_g(s['ucl'])}"]
    if "steps" in s:
        lat = s["step_latency_ms"]
        rows.append(f"steps         {s['steps']} over {s['duration_s']:.2f} s: "
                    + ", ".join(f"{k} {v}" for k, v in sorted(s["status_counts"].items())))
        rows.append(f"step latency  p50 {lat['p50']} ms, p99 {lat['p99']} ms, max {lat['max']} ms "
                    f"(cycle {lat['cycle']} ms; overruns {s['overruns']})")
        rows.append(f"override      final {s['final_override']:.1f} %; link writes {s['link_writes']}, "
                    f"failures {s['link_failures']}, downs {s['link_downs']}")
    ls = s["link_stats"]
    rows.append("link          " + ", ".join(f"{k} {v}" for k, v in ls.items() if k != "last_error")
                + (f"; last error: {ls['last_error']}" if ls.get("last_error") else ""))
    ss = s["source_stats"]
    rows.append("source        " + ", ".join(f"{k} {v}" for k, v in ss.items() if k != "last_error"))
    rows.append(f"episodes      {len(s['episodes'])}")
    for e in s["episodes"]:
        extra = ""
        if "detection_delay_ms" in e:
            extra = (f"; detection delay {e['detection_delay_ms']} ms, onset to alarm "
                     f"{e['onset_to_alarm_ms']} ms, settling {e['settling_ms']} ms")
        rows.append(f"  section {e['section']}: override {e['override_start']:.1f} -> "
                    f"{e['override_min']:.1f} % (direction {e['direction']:+d}){extra}")
    if s.get("log"):
        rows.append(f"log           {s['log']}")
    if s.get("plot"):
        rows.append(f"plot          {s['plot']}")
    return "\n".join(rows)

