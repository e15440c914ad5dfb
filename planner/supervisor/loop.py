"""The supervisor loop: read the signal, step the policy, command the controller, every cycle.

:func:`run_loop` runs at a fixed rate (``cycle_s``, the controller cycle: 4 ms KR C4, 12 ms KR C2)
on ``clock``/``sleep`` (wall time by default; :class:`VirtualClock` runs a simulation faster than
wall time, the sockets staying real). Each iteration:

1. ``before_step(now)`` (the simulated cut's DAQ: generate and send samples), if given;
2. ``source.read`` → chunk; ``link.read_override()`` → the override the controller confirmed;
3. the :class:`~planner.supervisor.link_watch.LinkWatch` judges the link — refused writes
   (``link.stats.refused`` went up) or a reported override that does not follow the command
   within the link's follow time — and hands a fault to :meth:`Supervisor.link_fault` (count,
   log, operator alarm, hold), so the step of the same cycle already holds;
4. :meth:`Supervisor.step` (its duration is the *step latency*, measured with ``perf_counter``,
   and its CPU time with ``thread_time``);
5. ``link.set_override`` when the integer override changes, every ``keepalive_s``, and at once
   when ``link.connected`` comes back after an outage;
6. ``on_cycle(now, result, applied, link)``, if given: the online deflection compensation
   (:class:`~planner.supervisor.compensation.PlanCompensation`: force → δ → ``set_correction``),
   timed (``on_cycle_latency_s``); what it raises is counted in ``extra["on_cycle_errors"]``;
7. every new operator alarm of the supervisor goes to ``on_alarm`` (e.g. a stop request to the
   controller), if given;
8. the decision log is drained to its file (after the step, so no step waits for the disk).

When the run ends, :meth:`Supervisor.finish` closes an episode still open (escalated). Nothing
here raises from inside the loop: a source or link that throws (they should not) is counted and
treated as "no samples" / "link down". Link transitions (down, back) are logged in the
supervisor's event log.
"""

from __future__ import annotations

import gc
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from planner.supervisor.episode import OperatorAlarm
from planner.supervisor.link_watch import LinkWatch, follow_time
from planner.supervisor.policy import StepResult, Supervisor
from robot_io.links.base import RobotLink
from robot_io.signals.base import SignalSource, empty_chunk

__all__ = ["GC_EVERY_STEPS", "LoopReport", "VirtualClock", "run_loop"]

#: Cycles between the loop's own collections of the young generations (the automatic collector
#: is off inside the loop): at 4 ms, once a second; a pass over the young objects takes tens of µs.
GC_EVERY_STEPS = 250


class VirtualClock:
    """A clock that moves only when slept on (simulations faster than wall time)."""

    def __init__(self, t0: float = 0.0) -> None:
        self.t = t0

    def __call__(self) -> float:
        return self.t

    def sleep(self, dt: float) -> None:
        self.t += max(0.0, dt)


@dataclass
class LoopReport:
    """What a run did.

    Attributes:
        steps: loop iterations.
        duration_s: loop time covered [s] (on the loop's clock).
        step_latency_s: duration of each Supervisor.step [s] (perf_counter: wall time, including
            any preemption by other processes), shape (steps,).
        step_cpu_s: CPU time of this thread in each step [s] (``time.thread_time``: the step's own
            cost, without preemption), shape (steps,).
        cycle_latency_s: duration of each whole iteration's work (read, step, command) [s].
        on_cycle_latency_s: duration of each ``on_cycle`` call [s] (perf_counter; empty without).
        overruns: iterations whose work took longer than the cycle.
        link_writes: set_override calls; link_failures: calls answered not ok.
        link_downs: times the link went from up (connected and writes ok) to down.
        link_refusals: override writes the controller refused during the run (the link's count).
        link_not_followed: times the override the controller reports stopped following the
            command (RSI's only sign of a refusal).
        follow_s: the follow time the link was judged with [s].
        t_start: the loop's clock at its first cycle [s].
        status_counts: steps per supervisor status.
        last: the last step's result.
        last_applied: the override the controller reported last [percent] (None: none).
        alarms: the operator alarms raised during the run.
        extra: free-form additions (the CLI adds source and link statistics).
    """

    steps: int = 0
    duration_s: float = 0.0
    step_latency_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    step_cpu_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    cycle_latency_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    on_cycle_latency_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    overruns: int = 0
    link_writes: int = 0
    link_failures: int = 0
    link_downs: int = 0
    link_refusals: int = 0
    link_not_followed: int = 0
    follow_s: float = math.nan
    t_start: float = math.nan
    status_counts: dict[str, int] = field(default_factory=dict)
    last: StepResult | None = None
    last_applied: float | None = None
    alarms: list[OperatorAlarm] = field(default_factory=list)
    extra: dict[str, Any] = field(default_factory=dict)


def run_loop(sup: Supervisor, source: SignalSource, link: RobotLink, duration_s: float,
             cycle_s: float = 0.004, clock: Callable[[], float] = time.monotonic,
             sleep: Callable[[float], None] = time.sleep,
             before_step: Callable[[float], None] | None = None,
             on_step: Callable[[float, StepResult], None] | None = None,
             should_stop: Callable[[], bool] | None = None,
             keepalive_s: float = 0.5, freeze_gc: bool = True,
             follow_s: float | None = None,
             on_alarm: Callable[[OperatorAlarm], None] | None = None,
             on_cycle: Callable[[float, StepResult, float | None, RobotLink], Any] | None = None
             ) -> LoopReport:
    """Run the supervisor for ``duration_s`` [s] (see the module docstring); return the report.

    ``follow_s`` is the time the controller has to show a commanded override [s] (None: the
    link's own, :func:`~planner.supervisor.link_watch.follow_time`, for RSI from the controller's
    cycle the link learns); ``on_alarm`` is called with
    every operator alarm as it is raised (it must return quickly; what it raises is counted in
    ``extra["on_alarm_error"]``); ``on_cycle`` is called every cycle after the override is
    commanded (see the module docstring).

    With ``freeze_gc`` (default) the garbage collector is run once, every object alive at the
    start is frozen (``gc.freeze``) for the loop's duration, and the automatic collector is off
    inside the loop: the loop collects the young generations itself, every
    :data:`GC_EVERY_STEPS` cycles, in the slack after a step and before the sleep. A full pass never
    lands inside a step: an unfrozen one over a process that has imported CasADi and pinocchio
    took ~0.1 s on the benchmark machine, and even a frozen one over the loop's own records
    ~2 ms (a 4 ms cycle cannot spare either).
    """
    n_max = int(math.ceil(duration_s / cycle_s)) + 1
    step_lat = np.zeros(n_max)
    step_cpu = np.zeros(n_max)
    cyc_lat = np.zeros(n_max)
    rep = LoopReport()
    was_enabled = gc.isenabled()
    if freeze_gc:
        gc.collect()
        gc.freeze()
        gc.disable()
    try:
        watch = LinkWatch(follow_s if follow_s is not None else (lambda: follow_time(link, cycle_s)),
                          _refused(link)[0],
                          clock=None if clock is time.monotonic else time.monotonic)
        return _loop(sup, source, link, duration_s, cycle_s, clock, sleep, before_step, on_step,
                     should_stop, keepalive_s, rep, step_lat, step_cpu, cyc_lat, n_max,
                     young_gc=freeze_gc, watch=watch, on_alarm=on_alarm, on_cycle=on_cycle)
    finally:
        if freeze_gc:
            gc.unfreeze()
            if was_enabled:
                gc.enable()


def _refused(link: Any) -> tuple[int, str]:
    """(refused writes so far, last error) of a link; (0, "") when it cannot say."""
    try:
        st = link.stats
        return int(getattr(st, "refused", 0)), str(getattr(st, "last_error", ""))
    except Exception:  # noqa: BLE001 - a link should not raise; then it reports nothing
        return 0, ""


def _loop(sup, source, link, duration_s, cycle_s, clock, sleep, before_step, on_step, should_stop,
          keepalive_s, rep, step_lat, step_cpu, cyc_lat, n_max, young_gc=False, watch=None,
          on_alarm=None, on_cycle=None) -> LoopReport:
    hook_lat = np.zeros(n_max if on_cycle is not None else 0)
    max_samples = max(1, int(8 * cycle_s * max(sup.fs_hz, 1.0)) + 64)
    t_start = clock()
    rep.t_start = t_start
    next_t = t_start
    last_sent: int | None = None
    last_send_t = -math.inf
    link_ok = True
    n_alarms = len(sup.alarms)
    now = t_start
    k = 0
    while k < n_max:
        now = clock()
        if now - t_start >= duration_s or (should_stop is not None and should_stop()):
            break
        w0 = time.perf_counter()
        if before_step is not None:
            try:
                before_step(now)
            except Exception as e:  # noqa: BLE001
                rep.extra["before_step_error"] = repr(e)
        try:
            chunk = source.read(max_samples)
        except Exception:  # noqa: BLE001 - sources should not raise; count it as no data
            chunk = empty_chunk("error")
        try:
            applied = link.read_override()
        except Exception:  # noqa: BLE001
            applied = None
        rep.last_applied = applied
        try:
            up = bool(link.connected)
        except Exception:  # noqa: BLE001
            up = False
        if watch is not None:
            refused, last_error = _refused(link)
            fault = watch.check(now, applied, up, refused, last_error)
            if fault is not None:
                sup.link_fault(now, fault)
        c0 = time.thread_time()
        s0 = time.perf_counter()
        res = sup.step(now, chunk, applied)
        s1 = time.perf_counter()
        step_cpu[k] = time.thread_time() - c0
        cmd = int(math.floor(res.override + 0.5))
        why = "link reports not connected"
        if up and not link_ok:
            last_sent = None  # link back: send the override again at once
        if cmd != last_sent or now - last_send_t >= keepalive_s:
            try:
                st = link.set_override(res.override)
                sent_ok, why = bool(st.ok), str(st.reason)
            except Exception as e:  # noqa: BLE001
                sent_ok, why = False, f"link raised {type(e).__name__}: {e}"
            rep.link_writes += 1
            last_send_t = now
            last_sent = cmd  # refused or not, the link keeps the value and sends it when it is up
            if watch is not None:
                watch.commanded(now, cmd)
            if not sent_ok:
                rep.link_failures += 1
            up = up and sent_ok
        if up != link_ok:
            if not up:
                rep.link_downs += 1
            sup.log.write({"t_s": now, "section": res.section_number, "band": res.band, "ucl": res.ucl,
                           "override": res.override, "status": res.status,
                           "reason": ("controller link down: " + why) if not up
                           else "controller link back: override resent"})
            link_ok = up
        if on_cycle is not None:
            h0 = time.perf_counter()
            try:
                on_cycle(now, res, applied, link)
            except Exception as e:  # noqa: BLE001 - a hook must not stop the loop
                rep.extra["on_cycle_errors"] = rep.extra.get("on_cycle_errors", 0) + 1
                rep.extra["on_cycle_error"] = repr(e)
            hook_lat[k] = time.perf_counter() - h0
        n_alarms = _hand_on(sup, n_alarms, on_alarm, rep)
        sup.log.drain()  # the decisions of this step go to disk now, outside the step
        w1 = time.perf_counter()
        step_lat[k] = s1 - s0
        cyc_lat[k] = w1 - w0
        if w1 - w0 > cycle_s:
            rep.overruns += 1
        rep.status_counts[res.status] = rep.status_counts.get(res.status, 0) + 1
        rep.last = res
        if on_step is not None:
            on_step(now, res)
        k += 1
        if young_gc and k % GC_EVERY_STEPS == 0:
            gc.collect(1)  # the young generations only, in the cycle's slack
        next_t += cycle_s
        delay = next_t - clock()
        if delay > 0:
            sleep(delay)
        else:
            next_t = clock()  # behind: do not try to catch up with a burst
    sup.finish(now)   # an episode still open ends now: escalated
    _hand_on(sup, n_alarms, on_alarm, rep)
    sup.log.drain()
    rep.alarms = list(sup.alarms)
    if watch is not None:
        rep.link_refusals, rep.link_not_followed = watch.refusals, watch.not_followed
        rep.follow_s = watch.follow_s
    rep.steps = k
    rep.duration_s = clock() - t_start
    rep.step_latency_s = step_lat[:k]
    rep.step_cpu_s = step_cpu[:k]
    rep.cycle_latency_s = cyc_lat[:k]
    rep.on_cycle_latency_s = hook_lat[:k]
    return rep


def _hand_on(sup: Supervisor, n_done: int, on_alarm: Callable[[OperatorAlarm], None] | None,
             rep: LoopReport) -> int:
    """Give the supervisor's operator alarms after the first ``n_done`` to ``on_alarm``; return
    how many there are now."""
    n = len(sup.alarms)
    if on_alarm is not None:
        for alarm in sup.alarms[n_done:n]:
            try:
                on_alarm(alarm)
            except Exception as e:  # noqa: BLE001 - a hook must not stop the loop
                rep.extra["on_alarm_error"] = repr(e)
    return n
