"""The online supervisor's policy: from signal chunks to a feed override, inside a safety envelope.

One :meth:`Supervisor.step` per controller cycle: it takes the chunk of samples that arrived and
the override the controller last confirmed, and returns a :class:`StepResult` with the override to
command. It never raises: an internal failure returns status ``error`` and holds the last override.

The policy — what the controller applies, where the tool is, the envelope, alarms, how a move is
judged over one decision period (:mod:`planner.supervisor.episode`), how an episode ends, quiet and
recovery, bad signals — is described in docs/supervisor.md ("Policy", "When the controller does
not apply the override") and docs/model.md §9. Every decision is written to the
:class:`~planner.supervisor.event_log.EventLog` with its reason (records with ``"event":
"operator_alarm"`` for the alarms), with a heartbeat every ``heartbeat_s`` while nothing changes;
operator alarms are kept in :attr:`Supervisor.alarms`. The step's types (status, configuration,
result) are in :mod:`planner.supervisor.step`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ruckig import InputParameter, Result, Ruckig, Trajectory

from planner.plan_file import Plan, PlanSection
from planner.supervisor.ceiling import planned_speed_at
from planner.supervisor.characteristic import (
    Characteristic,
    characteristic_of,
    feed_limit_for_force,
    force_at,
    stabilising_direction,
)
from planner.supervisor.detectors import detector_for_plan
from planner.supervisor.episode import (
    AT_FLOOR_TOL_PCT,
    ESCALATE_PERIODS,
    NOT_FALLING_RATIO,
    Episode,
    OperatorAlarm,
    judge,
)
from planner.supervisor.event_log import EventLog
from planner.supervisor.link_watch import LinkFault
from planner.supervisor.signal_check import chunk_problem
from planner.supervisor.step import (
    MAX_DT_S,
    MIN_LEARN_VALUES,
    STATUSES,
    TARGET_EPS_PCT,
    StepResult,
    StepStatus,
    SupervisorConfig,
)
from robot_io.signals.base import SignalChunk

__all__ = [
    "STATUSES",
    "StepResult",
    "StepStatus",
    "Supervisor",
    "SupervisorConfig",
]


def _planned_feed(sec: PlanSection | None) -> float:
    """The section's planned feed [m/s] (0 before the first section, or when it has none)."""
    if sec is None or not math.isfinite(sec.feed):
        return 0.0
    return sec.feed


@dataclass
class _Track:
    s_m: float = 0.0
    section: int = -1
    sec: PlanSection | None = None
    char: Characteristic | None = None
    cap: float = 100.0
    ceiling: float = 100.0
    raise_failed: bool = False   # a raise was reversed here: this section backs off


class Supervisor:
    """The policy (see the module docstring).

    Args:
        plan: the plan being cut.
        fs_hz: signal sample rate [Hz].
        sigma: band σ from stable cutting (None: learn it from the first ``learn_s`` of signal).
        config: tuning.
        log: decision log (None: an in-memory log).
        learn_s: length of the stable window to learn σ from [s] when ``sigma`` is None.
        start_s: arc length where the cut starts [m].
    """

    def __init__(self, plan: Plan, fs_hz: float, sigma: float | None = None,
                 config: SupervisorConfig | None = None, log: EventLog | None = None,
                 learn_s: float = 1.0, start_s: float = 0.0) -> None:
        self.plan = plan
        self.cfg = cfg = config or SupervisorConfig()
        self.log = log if log is not None else EventLog(None)
        self.fs_hz = float(fs_hz)
        self.detector = detector_for_plan(plan, cfg, self.fs_hz, sigma)
        self.level = self.detector.choice
        self.force_max_N = float(plan.limits.force_max)
        self.plausible_max = (cfg.plausible_max if cfg.plausible_max is not None
                              else 10.0 * self.force_max_N if math.isfinite(self.force_max_N)
                              else math.inf)
        self.safe_pct = cfg.safe_pct if cfg.safe_pct is not None else cfg.floor_pct
        self.episodes: list[Episode] = []
        self.alarms: list[OperatorAlarm] = []
        self.counts = {"steps": 0, "implausible_chunks": 0, "implausible_samples": 0, "gaps": 0,
                       "errors": 0, "alarms": 0, "no_direction": 0, "restarts": 0,
                       "reversals": 0, "escalations": 0, "link_faults": 0}
        #: how long the band lags the chatter amplitude [s] (the band filter's delay)
        self.band_delay_s = self.detector.delay_s
        #: the time a move needs to show in the band, and the time it is judged over [s]
        self.decision_period_s = self.band_delay_s + 1.0 / self.level.chatter_hz
        self._env_window_s = 0.5 / self.level.chatter_hz
        self._env: list[tuple[float, float]] = []
        self._fault: LinkFault | None = None
        self._applied: float | None = None
        self._escalated_s: float | None = None   # chatter escalated: the floor holds till quiet
        self._learn_s = learn_s
        self._learn_sum = 0.0
        self._learn_n = 0
        self._learn_t0: float | None = None
        self._track = _Track(s_m=start_s)
        self._otg = Ruckig(1)
        self._traj = Trajectory(1)
        self._traj_t0 = 0.0
        self._traj_ok = False
        self._fast_up = False
        self._pos, self._vel, self._acc = 100.0, 0.0, 0.0
        self._target = 100.0
        self._now: float | None = None
        self._last_signal_now: float | None = None
        self._last_t: float | None = None
        self._last_alarm: float | None = None
        self._status = StepStatus.LEARNING if sigma is None else StepStatus.WARMUP
        self._last_log = -math.inf
        self._logged_target = math.nan
        self._last_band: float | None = None
        self._enter_section(start_s)

    # -- helpers ----------------------------------------------------------------------------
    @property
    def override(self) -> float:
        """The override last commanded [percent]."""
        return self._pos

    def _enter_section(self, s: float) -> None:
        sec = self.plan.section_at(s)
        tr = self._track
        if sec.index == tr.section:
            return
        tr.section = sec.index
        tr.sec = sec
        tr.char = characteristic_of(sec)
        tr.cap = 100.0
        planned = _planned_feed(sec)
        if tr.char is not None and planned > 0 and math.isfinite(self.force_max_N):
            f_lim = feed_limit_for_force(tr.char, self.force_max_N)
            tr.cap = min(100.0, 100.0 * f_lim / planned)
        tr.ceiling = 100.0
        tr.raise_failed = False

    def _limits(self) -> tuple[float, float]:
        cap = self._track.cap
        floor = min(self.cfg.floor_pct, cap)
        return floor, cap

    def _plan_traj(self, now: float, target: float, fast_up: bool = False) -> None:
        cfg = self.cfg
        self._fast_up = fast_up
        inp = InputParameter(1)
        inp.current_position = [self._pos]
        inp.current_velocity = [self._vel]
        inp.current_acceleration = [self._acc]
        inp.target_position = [target]
        inp.target_velocity = [0.0]
        inp.target_acceleration = [0.0]
        inp.max_velocity = [cfg.backoff_pct_s if fast_up else cfg.recover_pct_s]
        inp.min_velocity = [-cfg.backoff_pct_s]
        inp.max_acceleration = [cfg.accel_pct_s2]
        inp.max_jerk = [cfg.jerk_pct_s3]
        try:
            res = self._otg.calculate(inp, self._traj)
            self._traj_ok = res in (Result.Working, Result.Finished)
        except Exception:  # noqa: BLE001 - ruckig refuses odd states; fall back to a clamp
            self._traj_ok = False
        self._traj_t0 = now
        self._target = target

    def _advance(self, now: float) -> None:
        if self._traj_ok:
            p, v, a = self._traj.at_time(max(0.0, now - self._traj_t0))
            self._pos, self._vel, self._acc = float(p[0]), float(v[0]), float(a[0])
        else:
            self._pos, self._vel, self._acc = self._target, 0.0, 0.0

    def _valid(self, chunk: SignalChunk) -> tuple[bool, str]:
        why = chunk_problem(chunk, self.plausible_max, self.cfg.stuck_samples, self._last_t)
        return not why, why

    # -- what the loop tells the supervisor ----------------------------------------------------
    def link_fault(self, now: float, fault: LinkFault) -> None:
        """The controller does not apply the override (from the loop's
        :class:`~planner.supervisor.link_watch.LinkWatch`): count it and log it with its reason;
        the first one raises an operator alarm, ends an open episode as escalated and makes every
        later step hold the override (never above what was commanded nor above what the controller
        applies). Never raises."""
        try:
            self.counts["link_faults"] += 1
            tr = self._track
            first = self._fault is None
            if first:
                self._fault = fault
                if self._open_episode() is not None:
                    self._end_episode(now, "escalated", "the controller does not apply the "
                                                         f"override ({fault.reason})")
            applied = "none" if fault.applied is None else f"{fault.applied:.0f} %"
            reason = (f"controller link fault ({fault.kind}): {fault.reason}; commanded "
                      f"{fault.commanded if fault.commanded is not None else 'nothing'} %, the "
                      f"controller applies {applied}")
            if first:
                reason += ": the supervisor cannot act; holding the override"
                self._raise_alarm(now, f"link_{fault.kind}", reason)
            else:
                self.log.write({"t_s": now, "section": tr.section + 1, "band": self._last_band,
                                "ucl": self.detector.ucl, "override": self._pos,
                                "status": StepStatus.HOLD, "event": "link_fault",
                                "reason": reason})
        except Exception:  # noqa: BLE001 - the loop must go on
            self.counts["errors"] += 1

    def finish(self, now: float) -> None:
        """The run ends: an episode still open is escalated (the cut ended chattering, or before
        the band was quiet long enough to say otherwise). Idempotent; never raises."""
        try:
            ep = self._open_episode()
            if ep is None:
                return
            since = now - ep.last_alarm_s
            why = ("the run ended during the episode, the band over the limit "
                   f"{since:.3f} s before (not yet quiet for {self.cfg.quiet_s:g} s)")
            self._end_episode(now, "escalated", why)
            self._raise_alarm(now, "run_ended_in_episode", f"chatter episode in section "
                              f"{ep.section_number} not resolved: {why}")
        except Exception:  # noqa: BLE001
            self.counts["errors"] += 1

    # -- the step ---------------------------------------------------------------------------
    def step(self, now: float, chunk: SignalChunk, applied_override: float | None = None) -> StepResult:
        """One decision at supervisor time ``now`` [s]; never raises.

        Args:
            now: supervisor clock [s] (monotonic).
            chunk: samples that arrived since the last step.
            applied_override: override the controller confirmed [percent] (None: assume the one
                commanded) — what every decision is taken on.
        """
        try:
            return self._step(now, chunk, applied_override)
        except Exception as e:  # noqa: BLE001 - the loop must go on
            self.counts["errors"] += 1
            tr = self._track
            res = StepResult(StepStatus.ERROR, self._pos, self._target, None, math.inf, False, tr.section,
                             tr.s_m, f"internal error, override held: {type(e).__name__}: {e}")
            self._status = StepStatus.ERROR
            self._emit(now, res, force=True)
            return res

    def _open_episode(self) -> Episode | None:
        return self.episodes[-1] if self.episodes and self.episodes[-1].end_s is None else None

    def _envelope(self, now: float, band: float | None) -> float | None:
        """The band's envelope: its largest value over the last half chatter period (the band of
        a sinusoid peaks twice a period), or None when no band value is that recent."""
        env = self._env
        if band is not None:
            env.append((now, band))
        horizon = now - self._env_window_s
        k = 0
        while k < len(env) and env[k][0] < horizon:
            k += 1
        if k:
            del env[:k]
        return max(b for _, b in env) if env else None

    def _step(self, now: float, chunk: SignalChunk, applied: float | None) -> StepResult:
        cfg = self.cfg
        self.counts["steps"] += 1
        tr = self._track
        dt = 0.0 if self._now is None else min(MAX_DT_S, max(0.0, now - self._now))
        self._now = now
        if self._last_signal_now is None:
            self._last_signal_now = now
        ov_applied = applied if applied is not None and math.isfinite(applied) else self._pos
        self._applied = ov_applied
        tr.s_m += planned_speed_at(self.plan, tr.s_m, tr.sec) * ov_applied / 100.0 * dt
        prev_section = tr.section
        self._enter_section(tr.s_m)
        floor, cap = self._limits()
        planned = planned_speed_at(self.plan, tr.s_m, tr.sec)
        reason = ""
        status = self._status
        target = self._target
        band: float | None = None
        ucl = self.detector.ucl
        alarm = False
        direction = 0
        quiet_hold = False   # a hold logged by heartbeat (it may last the rest of the run)

        # ---- signal ----
        valid = False
        n = len(chunk) if isinstance(chunk, SignalChunk) else 0
        if n:
            ok, why = self._valid(chunk)
            if ok:
                valid = True
                if self._last_t is not None and chunk.t_s[0] < self._last_t:
                    # far back in time: the source restarted its clock; a new stream
                    self.counts["restarts"] += 1
                    self.detector.reset()
                    reason = f"signal clock restarted ({self._last_t:.3f} s -> {chunk.t_s[0]:.3f} s)"
                elif self._last_t is not None and chunk.t_s[0] - self._last_t > 1.5 / self.fs_hz:
                    self.counts["gaps"] += 1
                    self.detector.reset()
                self._last_t = float(chunk.t_s[-1])
                self._last_signal_now = now
            else:
                self.counts["implausible_chunks"] += 1
                self.counts["implausible_samples"] += n
                self.detector.reset()
                reason = f"dropped {n} samples: {why}"
        missing = now - self._last_signal_now
        expected = None
        if cfg.use_transient_model and tr.char is not None:
            expected = force_at(tr.char, planned * ov_applied / 100.0)
        out = None
        if valid and self.detector.sigma is not None:
            out = self.detector.update(chunk.t_s, chunk.values, expected)
            band, ucl, alarm = out.band, out.ucl, out.alarm
            if alarm:
                self.counts["alarms"] += 1
        env = self._envelope(now, band) if out is not None else None
        ep = self._open_episode()

        if self._fault is not None:
            # cannot act: hold, never above what is commanded nor above what is applied (a
            # controller that starts to follow again must not jump upwards)
            status, target, quiet_hold = StepStatus.HOLD, min(self._pos, ov_applied), True
            reason = (reason + "; " if reason else "") + (
                f"the controller does not apply the override ({self._fault.kind} at "
                f"{self._fault.t_s:.3f} s): holding {min(max(target, floor), cap):.1f} % (the "
                f"controller applies {ov_applied:.1f} %), operator alarm raised"
                + (f"; band {band:.4g} over the limit {ucl:.4g}" if alarm else ""))
        elif missing > cfg.signal_timeout_s:
            status, target = StepStatus.SAFE, min(self.safe_pct, cap)
            reason = (reason + "; " if reason else "") + (
                f"no valid signal for {missing:.3f} s: safe override {target:.1f} %")
        elif missing > cfg.hold_after_s:
            status, target = StepStatus.HOLD, self._pos
            reason = (reason + "; " if reason else "") + (
                f"no valid signal for {missing:.3f} s: holding {self._pos:.1f} %")
        elif valid and self.detector.sigma is None:
            status, target = StepStatus.LEARNING, min(cap, tr.ceiling)
            if self._learn_t0 is None:
                self._learn_t0 = float(chunk.t_s[0])
            d = self.detector.observe(chunk.t_s, chunk.values, expected)
            self._learn_sum += float(d @ d)
            self._learn_n += d.size
            reason = "learning sigma from the stable window"
            if float(chunk.t_s[-1]) - self._learn_t0 >= self._learn_s:
                if self._learn_n >= MIN_LEARN_VALUES and self._learn_sum > 0:
                    self.detector.sigma = math.sqrt(self._learn_sum / self._learn_n)
                    status = StepStatus.OK
                    reason = (f"sigma {self.detector.sigma:.4g} learned from {self._learn_n} band "
                              f"values; UCL {self.detector.ucl:.4g}")
                else:
                    reason = (f"only {self._learn_n} band values after {self._learn_s:.2f} s: "
                              "still learning (the stable window is shorter than the band filter)")
        elif out is not None:
            judged = None
            if ep is not None and env is not None:
                judged = judge(ep, now, env, alarm, ov_applied, floor, self.band_delay_s,
                               self.decision_period_s)
            if band is None and not self.detector.monitor.ready:
                status, target = StepStatus.WARMUP, self._pos
                reason = reason or "band filter warming up: override held"
            elif self._escalated_s is not None and (
                    alarm or now - (self._last_alarm or now) < cfg.quiet_s):
                if alarm:
                    self._last_alarm = now
                status, target, quiet_hold = StepStatus.HOLD, floor, True
                reason = (f"chatter escalated at {self._escalated_s:.3f} s (operator alarm): "
                          f"holding the floor {floor:.1f} % until the band is quiet for "
                          f"{cfg.quiet_s:g} s"
                          + (f"; band {band:.4g} over the limit {ucl:.4g}" if alarm else ""))
            elif judged is not None and judged[0] == "escalate":
                status, target = StepStatus.HOLD, floor
                reason = f"{judged[1]}: escalated, operator alarm; holding the floor"
                self._escalate(now, ep, judged[1])
            elif judged is not None and judged[0] == "reverse":
                status = StepStatus.ALARM
                worst = max(env, ep.peak)
                step = min(cfg.max_step_pct, cfg.gain_pct * max(0.0, (worst - ucl) / ucl))
                target = min(self._target, ov_applied - step)
                self._reverse(now, ep, ov_applied)
                reason = (f"{judged[1]}: reversing, backing off {step:.1f} % towards the floor "
                          "(this section does not raise again)")
            elif alarm:
                status = StepStatus.ALARM
                target, direction, why = self._on_alarm(now, out.excess, out.t_s, planned, floor,
                                                        cap, ov_applied, env)
                reason = (f"chatter: band {band:.4g} > limit {ucl:.4g} (excess {out.excess:.2f}); "
                          + why)
            else:
                if self._escalated_s is not None:   # quiet after an escalation: act again
                    self._escalated_s = None
                    reason = "band quiet after the escalation: the supervisor acts again"
                since = math.inf if self._last_alarm is None else now - self._last_alarm
                if since < cfg.quiet_s:
                    status, target = StepStatus.QUIET, self._target
                    reason = f"band under the limit for {since:.3f} s: waiting {cfg.quiet_s:g} s"
                else:
                    if ep is not None:
                        self._end_episode(now, "resolved", f"band under the limit for "
                                                           f"{cfg.quiet_s:g} s")
                    goal = min(cap, tr.ceiling)
                    if self._pos < goal - 0.05:
                        status, target = StepStatus.RECOVER, goal
                        reason = (f"band quiet: recovering towards {goal:.1f} %"
                                  + (" (the section's chatter ceiling)" if tr.ceiling < cap else ""))
                    else:
                        status, target = StepStatus.OK, goal
                        reason = reason or "band quiet"
        else:   # no valid samples this cycle, not yet long enough to hold: nothing changes
            reason = reason or (f"no new samples for {missing:.3f} s (hold after "
                                f"{cfg.hold_after_s:g} s): {status.value} goes on")
        if prev_section != tr.section:
            number = tr.sec.number if tr.sec is not None else tr.section + 1
            reason = (f"section {number} (planned {planned * 1e3:.3g} mm/s, cap {cap:.1f} %); "
                      + reason)
        target = min(max(target, floor), cap)
        open_ep = self._open_episode()
        if open_ep is not None:
            open_ep.override_min = min(open_ep.override_min, ov_applied)
            open_ep.override_max = max(open_ep.override_max, ov_applied)
            open_ep.target_min = min(open_ep.target_min, target)
        fast_up = (open_ep is not None and open_ep.raising
                   and status in (StepStatus.ALARM, StepStatus.QUIET))
        self._advance(now)  # the state now, on the trajectory in force
        if status == StepStatus.HOLD and quiet_hold and abs(self._pos - target) > TARGET_EPS_PCT:
            # cannot act: the override is re-based on what the controller applies, no trajectory
            self._pos, self._vel, self._acc = target, 0.0, 0.0
            self._plan_traj(now, target, False)
        elif abs(target - self._target) > TARGET_EPS_PCT or fast_up != self._fast_up:
            self._plan_traj(now, target, fast_up)
        override = min(max(self._pos, floor), cap)
        if override != self._pos:
            reason += f"; clipped to the envelope [{floor:.1f}, {cap:.1f}] %"
            self._pos, self._vel, self._acc = override, 0.0, 0.0
            self._plan_traj(now, target, fast_up)
        res = StepResult(status, override, target, band, ucl, alarm, tr.section, tr.s_m, reason,
                         direction)
        changed = status != self._status or prev_section != tr.section
        self._status = status
        self._last_band = band if band is not None else self._last_band
        held = status == StepStatus.SAFE or (status == StepStatus.HOLD and not quiet_hold)
        self._emit(now, res, force=changed or held or (alarm and not quiet_hold))
        return res

    def _on_alarm(self, now: float, excess: float, t_band: float | None, planned: float,
                  floor: float, cap: float, applied: float, env: float | None) -> tuple[float, int, str]:
        cfg = self.cfg
        tr = self._track
        ep = self._open_episode()
        step = min(cfg.max_step_pct, cfg.gain_pct * max(excess, 0.0))
        direction, rel = (0, 0.0)
        if tr.char is not None and planned > 0:
            direction, rel = stabilising_direction(tr.char, planned * applied / 100.0)
        if ep is None:
            ep = Episode(now, t_band, tr.section, applied, direction, base=applied)
            ep.peak = env or 0.0
            self.episodes.append(ep)
            if direction > 0 and tr.raise_failed:
                ep.reversed_s = now   # this section's raise failed before: back off at once
            if not ep.raising:        # it chatters here and the way out is down: a ceiling
                tr.ceiling = min(tr.ceiling, applied * cfg.ceiling_factor)
        ep.last_alarm_s = now
        self._last_alarm = now
        # the amount is taken from the episode's base override, not from the moving one: the band
        # lags the feed by the filter's delay, so a per-step decrement would run to the floor.
        # If the alarm outlasts `persist_s` at the reached target and the band is not falling
        # (or it outlasts ESCALATE_PERIODS decision periods there), the base moves on.
        if abs(applied - self._target) > AT_FLOOR_TOL_PCT:
            ep.reached_s = None
        elif ep.reached_s is None:
            ep.reached_s, ep.reached_peak = now, env or 0.0
        else:
            ep.reached_peak = max(ep.reached_peak, env or 0.0)
            waited = now - ep.reached_s
            falling = env is not None and env < NOT_FALLING_RATIO * ep.reached_peak
            if (waited > cfg.persist_s and not falling) or (
                    waited > ESCALATE_PERIODS * self.decision_period_s):
                ep.base = applied
                ep.reached_s = None
        if ep.raising and direction > 0 and applied < cap - AT_FLOOR_TOL_PCT:
            target = max(self._target, ep.base + step)
            why = f"raising the feed by {step:.1f} % (d margin/d feed > 0, relative slope {rel:.3g})"
        elif ep.raising and ep.base < cap - AT_FLOOR_TOL_PCT:
            # raised as far as it goes (the cap), or to where the characteristic stops saying
            # faster: stop there; the decision period says whether it worked
            target = min(self._target, cap if direction > 0 else max(applied, ep.base))
            why = ((f"raised to the cap {cap:.1f} %" if direction > 0 else
                    f"raised to where the characteristic stops saying faster (relative slope "
                    f"{rel:.3g})") + f": holding {target:.1f} % while the raise is judged "
                   f"({self.decision_period_s:.3f} s after it)")
        elif ep.raising:   # the episode began at the cap: no room to raise
            self._reverse(now, ep, applied)
            target = min(self._target, ep.base - step)
            why = ((f"faster would stabilise but the override is at its cap {cap:.1f} %"
                    if direction > 0 else "the characteristic no longer says faster here "
                    f"(relative slope {rel:.3g})")
                   + f": reversing, backing off {step:.1f} % towards the floor")
        elif direction < 0:
            target = min(self._target, ep.base - step)
            why = f"lowering the feed by {step:.1f} % (d margin/d feed < 0, relative slope {rel:.3g})"
        else:
            target = min(self._target, ep.base - step)
            if direction > 0:
                why = (f"raising did not stabilise this section (reversed): backing off {step:.1f} "
                       "% towards the floor")
            elif ep.direction == 0:
                self.counts["no_direction"] += 1
                why = ("the characteristic offers no stabilising feed direction (relative slope "
                       f"{rel:.3g}): backing off {step:.1f} % towards the floor")
            else:
                why = (f"the episode backs off (no stabilising direction at the applied feed, "
                       f"relative slope {rel:.3g}): {step:.1f} % towards the floor")
        target = min(max(target, floor), cap)
        return target, direction, why

    def _reverse(self, now: float, ep: Episode, applied: float) -> None:
        """End a raise: back off from the applied override, never raise again in this section,
        and the feed the raise reached (it chatters there) makes the section's ceiling."""
        tr = self._track
        ep.reversed_s = now
        ep.base = applied
        ep.reached_s = None
        tr.raise_failed = True
        tr.ceiling = min(tr.ceiling, max(applied, ep.override_max) * self.cfg.ceiling_factor)
        self.counts["reversals"] += 1

    def _end_episode(self, now: float, outcome: str, why: str) -> None:
        ep = self._open_episode()
        if ep is None:
            return
        ep.end_s = now
        ep.outcome, ep.outcome_reason = outcome, why
        if (outcome == "resolved" and not ep.raising and ep.section == self._track.section
                and math.isfinite(ep.override_min)):
            # the boundary lies between where it chattered (the start, or the highest feed a
            # reversed raise reached) and where it went quiet: bisect
            top = ep.override_start if ep.reversed_s is None else max(ep.override_max,
                                                                      ep.override_start)
            mid = ep.override_min + 0.5 * (top - ep.override_min)
            self._track.ceiling = min(self._track.ceiling, mid)

    def _escalate(self, now: float, ep: Episode, why: str) -> None:
        self._end_episode(now, "escalated", why)
        self._escalated_s = now
        self.counts["escalations"] += 1
        self._raise_alarm(now, "chatter_escalated", f"section {ep.section_number}: {why}")

    def _raise_alarm(self, now: float, kind: str, reason: str) -> None:
        alarm = OperatorAlarm(now, kind, self._track.section + 1, reason)
        self.alarms.append(alarm)
        self.log.write({"t_s": now, "section": alarm.section, "band": self._last_band,
                        "ucl": self.detector.ucl, "override": self._pos,
                        "applied": self._applied, "status": StepStatus.HOLD,
                        "event": "operator_alarm", "alarm": kind, "reason": reason})

    def _emit(self, now: float, res: StepResult, force: bool) -> None:
        if not force and now - self._last_log < self.cfg.heartbeat_s and abs(
                res.target - self._logged_target) <= TARGET_EPS_PCT:
            return
        self._last_log = now
        self._logged_target = res.target
        self.log.write({"t_s": now, "section": res.section_number, "s_m": res.s_m, "band": res.band,
                        "ucl": res.ucl, "override": res.override, "applied": self._applied,
                        "target": res.target, "status": res.status, "alarm": res.alarm,
                        "direction": res.direction, "reason": res.reason})
