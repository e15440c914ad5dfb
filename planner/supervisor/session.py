"""A whole supervised run: a plan, a signal source and a robot link, the loop, and its summary.

:func:`run_session` runs the supervisor over an open source and link; :func:`supervise` first opens
them from their names, as ``cctmill supervise`` and the demo do, and closes them afterwards::

    plan = load_plan("out/")
    summary = supervise(plan, signal="sim", robot="sim", config=SessionConfig(duration=6.0))
    summary.episodes                 # every chatter episode: the applied overrides, its outcome, timing
    summary.alarms                   # operator alarms (`cctmill supervise` exits 3 when any)

Names of a signal: a CSV/NPY file (replayed in real time), ``udp://HOST:PORT`` (a sample stream to
bind, :mod:`robot_io.signals.udp`) or ``sim`` (the simulated cut, :mod:`planner.supervisor.sim_cut`,
whose feed follows the override the controller applies). Names of a robot: ``sim`` (a simulated
controller in-process over loopback, KukaVarProxy or RSI), ``kvp://HOST:PORT`` (a KukaVarProxy to
connect to) or ``rsi://BIND_HOST:PORT`` (the RSI server the controller sends to, in its own process).
σ of the stable band: :attr:`SessionConfig.sigma`, else from a simulated stable cut (``sim``), else
learned from the first :attr:`SessionConfig.learn` seconds of the signal (the user vouches they are
stable).

Online deflection compensation (:attr:`SessionConfig.compensation`, ``cctmill supervise
--compensate-rkorr``; docs/compensation.md): every cycle a
:class:`~planner.supervisor.compensation.PlanCompensation` turns the mean force into an RSI
``RKorr`` correction. It needs an RSI link and a 3-axis mean force: the simulated signal provides
the model's (a simulated sensor); a recorded or streamed signal is one channel, so it is refused.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any
from urllib.parse import urlsplit

import numpy as np

from models.errors import InputError
from planner.calibrate.supervisor_records import SectionRecorder, chain_on_cycle
from planner.plan_file import Plan
from planner.supervisor.compensation import CompensationConfig, PlanCompensation
from planner.supervisor.episode import OperatorAlarm
from planner.supervisor.event_log import EventLog
from planner.supervisor.loop import LoopReport, VirtualClock, run_loop
from planner.supervisor.metrics import episode_metrics
from planner.supervisor.plot import RunTrace, plot_run
from planner.supervisor.policy import Supervisor, SupervisorConfig
from planner.supervisor.sim_cut import CutScenario, SimulatedCut

__all__ = [
    "DEFAULT_SIM_DURATION_S",
    "DEFAULT_SIM_FS_HZ",
    "SessionConfig",
    "SessionSummary",
    "run_session",
    "simulated_sigma",
    "supervise",
]

#: Sample rate of the simulated signal when none is given [Hz].
DEFAULT_SIM_FS_HZ = 10_000.0
#: Length of a simulated run when none is given [s].
DEFAULT_SIM_DURATION_S = 6.0
#: How long a UDP stream may take to send its first datagram when the rate is not given [s].
UDP_FIRST_DATAGRAM_S = 5.0


@dataclass(frozen=True)
class SessionConfig:
    """How to run a supervised session (SI).

    Attributes:
        supervisor: the policy's tuning.
        cycle: supervisor cycle [s] (KR C4 0.004, KR C2 0.012).
        duration: stop after this long [s] (None: a simulated run 6 s, a file its length, a stream
            until interrupted).
        fs_hz: signal sample rate [Hz] (None: the simulated cut's 10 kHz, the file's time column,
            the stream's header).
        sigma: band σ of stable cutting (None: from a simulated stable cut, else learned).
        learn: learn σ from this much signal at the start [s].
        start: arc length where the cut starts [m].
        log: append every decision to this JSON-lines file (None: in memory only).
        plot: write the band/override plot to this PNG (None: no plot).
        signal_column: the CSV column to replay (None: the first non-time column).
        sim_protocol: protocol of the simulated controller, ``kvp`` or ``rsi``.
        fast: a simulated signal with a real link runs on a virtual clock (no sleeping).
        rsi_config: the controller's RSI ETHERNET configuration file (SENTYPE, correction element,
            override tags; :mod:`robot_io.links.rsi_config`) for an RSI link; None: the defaults.
        compensation: online deflection compensation through RKorr (None: off, the default; its
            ``cycle_s`` is taken from :attr:`cycle`).
        compensation_offline: the program was exported with ``--compensate-deflection``: the
            online part corrects only what the plan's δ did not.
        records: append one cut record per section run to this JSON Lines file (the detector's
            verdict; the chatter frequency of a chatter section; the steady mean force when the
            signal is the simulated cut — a recorded or streamed signal is one channel, no force
            vector; docs/calibration.md), None: none.
        records_tool: the tool data name the records give (``cctmill tools``).
    """

    supervisor: SupervisorConfig = field(default_factory=SupervisorConfig)
    cycle: float = 0.004
    duration: float | None = None
    fs_hz: float | None = None
    sigma: float | None = None
    learn: float = 1.0
    start: float = 0.0
    log: str | None = None
    plot: str | None = None
    signal_column: str | None = None
    sim_protocol: str = "kvp"
    fast: bool = False
    rsi_config: str | None = None
    compensation: CompensationConfig | None = None
    compensation_offline: bool = False
    records: str | None = None
    records_tool: str = ""

    def check(self) -> None:
        """Raises InputError naming the field that is out of range."""
        if not (math.isfinite(self.cycle) and self.cycle > 0):
            raise InputError("cycle", "must be positive")
        if self.duration is not None and not self.duration > 0:
            raise InputError("duration", "must be positive")
        if self.fs_hz is not None and not (math.isfinite(self.fs_hz) and self.fs_hz > 0):
            raise InputError("fs_hz", "must be positive")
        if self.sigma is not None and not self.sigma > 0:
            raise InputError("sigma", "must be positive")
        if self.sim_protocol not in ("kvp", "rsi"):
            raise InputError("sim_protocol", f"{self.sim_protocol!r}: use kvp or rsi")


@dataclass
class SessionSummary:
    """What a supervised run did (SI inside; :meth:`as_json` is the CLI's JSON, units in names).

    Attributes:
        plan, signal, robot: what ran (the plan's file or label, the two names).
        fs_hz: signal sample rate [Hz].
        detector: level, band_hz, chatter_hz, tooth_hz, level_reason, L_c, sigma, ucl.
        counts: the supervisor's counters; log, log_dropped: the event log and its drops.
        loop: the loop's report (None when interrupted before it returned).
        cycle: supervisor cycle [s].
        link_stats, source_stats: the link's and the source's counters.
        episodes: every chatter episode as the JSON gives it (start, section — its number, from
            1, as in plan.json and the KRL program —, direction, the overrides the controller
            applied at the start and at the lowest, the lowest target, when a raise was reversed,
            end, outcome ``resolved``/``escalated`` and why; with the simulated truth also
            detection delay, onset to alarm, settling and quiet times, in ms as the names say).
        alarms: every operator alarm (time on the loop's clock and after the start [s], kind,
            section, reason): the run needs the operator (``cctmill supervise`` then exits with
            status 3).
        plot: the plot written, if any.
        compensation: what the online compensation did (status counts, refused corrections,
            total; with the simulated RSI controller also what it applied), None when off.
    """

    plan: str
    signal: str
    robot: str
    fs_hz: float
    detector: dict[str, Any]
    counts: dict[str, int]
    log: str | None
    log_dropped: int
    loop: LoopReport | None
    cycle: float
    link_stats: dict[str, Any]
    source_stats: dict[str, Any]
    episodes: list[dict[str, Any]]
    alarms: list[dict[str, Any]] = field(default_factory=list)
    plot: str | None = None
    compensation: dict[str, Any] | None = None
    records: dict[str, Any] | None = None

    def as_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {"plan": self.plan, "signal": self.signal, "robot": self.robot,
                               "fs_hz": self.fs_hz, **self.detector, "counts": dict(self.counts),
                               "log": self.log, "log_dropped": self.log_dropped}
        rep = self.loop
        if rep is not None:
            lat = rep.step_latency_s
            out.update({
                "steps": rep.steps, "duration_s": rep.duration_s, "status_counts": rep.status_counts,
                "final_override": rep.last.override if rep.last else None,
                "final_applied_override": rep.last_applied,
                "step_latency_ms": {"p50": _ms(float(np.percentile(lat, 50))) if lat.size else None,
                                    "p99": _ms(float(np.percentile(lat, 99))) if lat.size else None,
                                    "max": _ms(float(lat.max())) if lat.size else None,
                                    "cycle": _ms(self.cycle)},
                "overruns": rep.overruns, "link_writes": rep.link_writes,
                "link_failures": rep.link_failures, "link_downs": rep.link_downs,
                "link_refusals": rep.link_refusals, "link_not_followed": rep.link_not_followed,
                "follow_ms": _ms(rep.follow_s) if math.isfinite(rep.follow_s) else None,
            })
        out["link_stats"] = dict(self.link_stats)
        out["source_stats"] = dict(self.source_stats)
        out["episodes"] = [dict(e) for e in self.episodes]
        out["alarms"] = [dict(a) for a in self.alarms]
        if self.plot:
            out["plot"] = self.plot
        if self.compensation is not None:
            out["compensation"] = dict(self.compensation)
        if self.records is not None:
            out["records"] = dict(self.records)
        return out


def _ms(x: float | None) -> float | None:
    return None if x is None else round(1e3 * x, 2)


def simulated_sigma(plan: Plan, fs_hz: float, scenario: CutScenario, config: SupervisorConfig,
                    duration_s: float = 2.0) -> float:
    """σ of the band in a simulated stable cut (no onset, no loss) at 100 % override, from the
    start of the plan's first cut section (air and rapids carry no cutting force)."""
    clk = VirtualClock()
    stable = replace(scenario, onset_s=None, loss_s=None, seed=scenario.seed + 1)
    cuts = [s for s in plan.sections if s.kind == "cut"]
    start = cuts[0].s_start if cuts else 0.0
    cut = SimulatedCut(plan, lambda: 100.0, fs_hz, stable, clock=clk, start_s=start)
    ys = []
    for _ in range(int(duration_s / 0.01)):
        clk.sleep(0.01)
        ys.append(cut.generate()[1])
    probe = Supervisor(plan, fs_hz, sigma=1.0, config=config)
    return probe.detector.learn(np.concatenate(ys))


def run_session(plan: Plan, source: Any, link: Any, config: SessionConfig, fs_hz: float,
                signal: str = "?", robot: str = "?", cut: SimulatedCut | None = None,
                scenario: CutScenario | None = None,
                clock: Callable[[], float] = time.monotonic,
                sleep: Callable[[float], None] = time.sleep,
                before_step: Callable[[], None] | None = None,
                on_alarm: Callable[[OperatorAlarm], None] | None = None,
                compensation: PlanCompensation | None = None,
                controller: Any = None) -> SessionSummary:
    """Supervise ``plan`` with an open signal ``source`` and robot ``link`` (neither is closed).

    Args:
        plan: the plan being cut.
        source: a :class:`robot_io.signals.SignalSource`.
        link: a :class:`robot_io.links.RobotLink`.
        config: the session's settings (``sigma`` None: learned from the first ``learn`` s).
        fs_hz: the source's sample rate [Hz].
        signal, robot: the names the summary gives them.
        cut, scenario: the simulated cut and its scenario, for the episodes' true timing (and
            the records: the signal is then the cut's resultant force).
        clock, sleep, before_step: the loop's clock (a :class:`VirtualClock` runs without waiting).
        on_alarm: called with every operator alarm as it is raised, inside the loop (return fast):
            e.g. a stop request the KRL program polls.
        compensation: the online deflection compensation to run every cycle (None: none);
            controller: the simulated RSI controller, whose applied correction the summary gives.
    """
    log = EventLog(config.log)
    try:
        sup = Supervisor(plan, fs_hz, sigma=config.sigma, config=config.supervisor, log=log,
                         learn_s=config.learn, start_s=config.start)
        duration = config.duration
        if duration is None:
            duration = getattr(source, "duration_s", None) or math.inf
        trace = RunTrace()
        # the records see the signal the supervisor reads; only the simulated cut's samples are a
        # force the records can hold (its resultant, along the model's direction)
        recorder = (SectionRecorder(plan, config.records, config.records_tool,
                                    detector=config.supervisor.detector, log=config.log,
                                    fs_hz=fs_hz, signal="resultant" if cut is not None else "scalar",
                                    band_hz=getattr(sup.detector, "band_hz", sup.level.band_hz))
                    if config.records else None)
        read = recorder.tap(source) if recorder is not None else source
        try:
            rep: LoopReport | None = run_loop(sup, read, link, duration, config.cycle, clock=clock,
                                              sleep=sleep, before_step=before_step, on_step=trace,
                                              on_alarm=on_alarm,
                                              on_cycle=chain_on_cycle(compensation, recorder))
        except KeyboardInterrupt:
            rep = None
            sup.finish(clock())
        if recorder is not None:
            recorder.close(clock())
        log.flush()
    finally:
        log.close()
    summary = _summary(sup, rep, source, link, cut, scenario, config, signal, robot)
    if compensation is not None:
        summary.compensation = _compensation_summary(compensation, rep, link, controller)
    if recorder is not None:
        summary.records = {"file": str(recorder.path), "written": recorder.written,
                           "with_force": recorder.with_force,
                           "with_chatter_hz": recorder.with_chatter_hz,
                           "errors": recorder.errors, "last_error": recorder.last_error}
    if config.plot:
        ch = sup.level
        plot_run(trace, config.plot, cut.truth if cut is not None else None,
                 title=f"cctmill supervise: {signal} -> {robot}, level {ch.level} "
                       f"({ch.band_hz[0]:.3g}-{ch.band_hz[1]:.3g} Hz)")
        summary.plot = config.plot
    return summary


def _summary(sup: Supervisor, rep: LoopReport | None, source: Any, link: Any,
             cut: SimulatedCut | None, scenario: CutScenario | None, config: SessionConfig,
             signal: str, robot: str) -> SessionSummary:
    ch = sup.level
    detector = {"level": ch.level, "band_hz": list(ch.band_hz), "chatter_hz": ch.chatter_hz,
                "tooth_hz": ch.tooth_hz, "level_reason": ch.reason, "detector": sup.cfg.detector,
                "detector_reason": sup.detector.reason, "L_c": sup.detector.l_c,
                "sigma": sup.detector.sigma,
                "ucl": sup.detector.ucl if sup.detector.sigma else None}
    metrics = []
    if cut is not None and cut.start_clock_s is not None:
        metrics = episode_metrics(sup, cut.truth, ch.chatter_hz,
                                  scenario.onset_s if scenario is not None else None,
                                  cut.start_clock_s)
    t0 = rep.t_start if rep is not None and math.isfinite(rep.t_start) else 0.0
    episodes = []
    for k, ep in enumerate(sup.episodes):
        e: dict[str, Any] = {"start_s": ep.start_s, "section": ep.section_number,
                             "direction": ep.direction, "override_start": ep.override_start,
                             "override_min": ep.override_min, "target_min": ep.target_min,
                             "reversed_after_ms": (_ms(ep.reversed_s - ep.start_s)
                                                   if ep.reversed_s is not None else None),
                             "end_s": ep.end_s, "outcome": ep.outcome,
                             "outcome_reason": ep.outcome_reason}
        if k < len(metrics):
            m = metrics[k]
            e.update({"detection_delay_ms": _ms(m.detection_delay_s),
                      "onset_to_alarm_ms": _ms(m.onset_to_alarm_s),
                      "settling_ms": _ms(m.settling_s), "quiet_ms": _ms(m.quiet_s)})
        episodes.append(e)
    return SessionSummary(
        plan=plan_name(sup.plan), signal=signal, robot=robot, fs_hz=sup.fs_hz, detector=detector,
        counts=dict(sup.counts), log=config.log, log_dropped=sup.log.dropped, loop=rep,
        cycle=config.cycle, link_stats=dict(link.stats.__dict__),
        source_stats=source.stats.as_dict(), episodes=episodes,
        alarms=[{"t_s": a.t_s, "after_s": a.t_s - t0, "kind": a.kind, "section": a.section,
                 "reason": a.reason} for a in sup.alarms])


def _compensation_summary(comp: PlanCompensation, rep: LoopReport | None, link: Any,
                          controller: Any) -> dict[str, Any]:
    out = comp.summary()
    lat = rep.on_cycle_latency_s if rep is not None else np.zeros(0)
    out["step_ms"] = ({"p50": _ms(float(np.percentile(lat, 50))), "p99": _ms(float(np.percentile(lat, 99))),
                       "max": _ms(float(lat.max()))} if lat.size else None)
    if rep is not None and "on_cycle_errors" in rep.extra:
        out["errors"] = rep.extra["on_cycle_errors"]
    sent = getattr(link, "correction_sent", None)
    out["sent"] = list(sent) if sent is not None else None
    ctl = getattr(controller, "correction", None)
    if ctl is not None:
        out["controller_applied"] = list(ctl.total)
        out["controller_late"] = int(controller.stats.late)
    return out


def plan_name(plan: Plan) -> str:
    """The plan as a summary names it: its file, else its label."""
    return str(plan.path) if plan.path is not None else plan.label


def _endpoint(text: str, scheme: str, what: str) -> tuple[str, int]:
    u = urlsplit(text)
    if u.scheme != scheme or not u.hostname or u.port is None:
        raise InputError(what, f"{text!r}: expected {scheme}://HOST:PORT")
    return u.hostname, int(u.port)


class _Closer:
    """Calls ``stop`` on close (for the simulated peers, which stop rather than close)."""

    def __init__(self, stop: Callable[[], Any]) -> None:
        self._stop = stop

    def close(self) -> None:
        self._stop()


def _open_link(robot: str, config: SessionConfig, closers: list) -> Any:
    # the RSI server learns the controller's IPOC step from the telegrams: the loop period is not it
    if robot == "sim":
        if config.sim_protocol == "rsi":
            from robot_io.links.rsi import RsiServer
            from robot_io.links.rsi_sim import RsiSimController

            server = RsiServer(config=config.rsi_config)
            closers.append(server)
            ctl = RsiSimController(server.address, cycle_s=config.cycle).start()
            closers.append(_Closer(ctl.stop))
            return server
        from robot_io.links.kvp import KvpClient
        from robot_io.links.kvp_sim import KvpSimServer

        srv = KvpSimServer().start()
        closers.append(_Closer(srv.stop))
        client = KvpClient(*srv.address, timeout=0.1)
        closers.append(client)
        return client
    if robot.startswith("kvp://"):
        from robot_io.links.kvp import KvpClient

        client = KvpClient(*_endpoint(robot, "kvp", "robot"))
        closers.append(client)
        return client
    if robot.startswith("rsi://"):
        # the RSI server of a real cell runs in its own process: its replies are due inside the
        # controller's cycle whatever this process's GIL is doing
        from robot_io.links.rsi_process import RsiProcessServer

        host, port = _endpoint(robot, "rsi", "robot")
        server = RsiProcessServer(host, port, config=config.rsi_config)
        closers.append(server)
        return server
    raise InputError("robot", f"{robot!r}: use sim, kvp://HOST:PORT or rsi://BIND_HOST:PORT")


def _open_source(signal: str, config: SessionConfig, closers: list) -> tuple[Any, float]:
    fs = config.fs_hz
    if signal.startswith("udp://"):
        from robot_io.signals.udp import UdpSignalSource

        host, port = _endpoint(signal, "udp", "signal")
        src = UdpSignalSource(host, port)
        closers.append(src)
        if fs is None:
            deadline = time.monotonic() + UDP_FIRST_DATAGRAM_S
            while src.fs_hz <= 0 and time.monotonic() < deadline:
                time.sleep(0.005)
                src.read(0)  # drains datagrams into the backlog; keeps the samples
            if src.fs_hz <= 0:
                raise InputError("fs_hz", f"no sample datagram on {host}:{port} within "
                                 f"{UDP_FIRST_DATAGRAM_S:g} s; start the stream first or give the rate")
            fs = src.fs_hz
        return src, fs
    from robot_io.signals.replay import ReplaySource

    src = ReplaySource.from_file(signal, fs, column=config.signal_column, realtime=True)
    return src, src.fs_hz


def supervise(plan: Plan, signal: str, robot: str, config: SessionConfig,
              scenario: CutScenario | None = None) -> SessionSummary:
    """Open the named signal source and robot link, run :func:`run_session`, close them.

    Args:
        plan: the plan being cut.
        signal: a recorded file, ``udp://HOST:PORT`` or ``sim`` (see the module docstring).
        robot: ``sim``, ``kvp://HOST:PORT`` or ``rsi://BIND_HOST:PORT``.
        config: the session's settings.
        scenario: the simulated cut's scenario (``signal="sim"``; default: :class:`CutScenario`).

    Raises:
        InputError: a name or setting is wrong (the field is named); LinkError: the link fails.
    """
    config.check()
    scenario = scenario or CutScenario()
    closers: list[Any] = []
    cut: SimulatedCut | None = None
    before_step = None
    clock: Callable[[], float] = time.monotonic
    sleep: Callable[[float], None] = time.sleep
    try:
        sim_signal = signal == "sim"
        fs = (config.fs_hz or DEFAULT_SIM_FS_HZ) if sim_signal else config.fs_hz
        if config.compensation is not None:
            if not sim_signal:
                raise InputError("compensation", "online compensation needs the 3-axis mean force; a "
                                                 "recorded or streamed signal is one channel: use "
                                                 "--signal sim")
            if not (robot.startswith("rsi://") or (robot == "sim" and config.sim_protocol == "rsi")):
                raise InputError("compensation", "RKorr is an RSI correction: use --robot rsi://HOST:PORT "
                                                 "or --robot sim --sim-protocol rsi")
        controller = None
        if sim_signal and robot == "sim":
            from planner.supervisor.sim_cell import SimCell

            cell = SimCell(plan, config.sim_protocol, fs, scenario, cycle_s=config.cycle,
                           start_s=config.start)
            closers.append(cell)
            source, link, cut, before_step = cell.source, cell.link, cell.cut, cell.daq
            controller = cell.rsi_controller
        else:
            link = _open_link(robot, config, closers)
            if sim_signal:
                if config.fast:
                    vc = VirtualClock()
                    clock, sleep = vc, vc.sleep

                def applied() -> float:
                    v = link.read_override()
                    return 100.0 if v is None else float(v)

                cut = SimulatedCut(plan, applied, fs, scenario, clock=clock, start_s=config.start)
                source = cut
            else:
                source, fs = _open_source(signal, config, closers)
        if config.sigma is None and sim_signal:
            config = replace(config, sigma=simulated_sigma(plan, fs, scenario, config.supervisor))
        if config.duration is None and sim_signal:
            config = replace(config, duration=DEFAULT_SIM_DURATION_S)
        comp = None
        if config.compensation is not None:
            # one step a loop cycle: the rate limit is counted in the session's cycle
            comp = PlanCompensation(plan, None, replace(config.compensation, cycle_s=config.cycle),
                                    offline=config.compensation_offline)
            comp.set_force(comp.model_force)  # the simulated sensor: the model's mean force
        return run_session(plan, source, link, config, fs, signal=signal, robot=robot, cut=cut,
                           scenario=scenario, clock=clock, sleep=sleep, before_step=before_step,
                           compensation=comp, controller=controller)
    finally:
        for c in reversed(closers):
            try:
                c.close()
            except Exception:  # noqa: BLE001 - closing must not hide the result
                pass
