"""The online supervisor's policy: from signal chunks to a feed override, inside a safety envelope.

One :meth:`Supervisor.step` per controller cycle: it takes the chunk of samples that arrived and
the override the controller last confirmed, and returns a :class:`StepResult` with the override to
command. It never raises: an internal failure returns status ``error`` and holds the last override.

Policy (docs/model.md §9):

- **Where am I.** The path position is dead-reckoned from the plan: s advances by the section's
  planned feed × the applied override per unit time (the robot links report no position). The
  section gives the planned feed, the stability characteristic and the force limit.
- **Envelope.** The override never exceeds 100 % (the planned feed) nor the override at which the
  characteristic's force reaches ``force_max_N``; it never goes under the floor (unless the force
  limit itself is lower). Changes follow a ruckig trajectory: jerk- and acceleration-limited, fast
  back-off (``backoff_pct_s``) and slow recovery (``recover_pct_s``); a stabilising move upwards
  during an alarm (the characteristic says "faster") is as fast as a back-off.
- **Alarm** (band over the control limit): move the override in the stabilising direction of the
  characteristic at the current feed, by ``gain_pct`` × the relative excess (at most
  ``max_step_pct``) from the override at the episode's start; an alarm that outlasts ``persist_s``
  at the reached target takes one more step from there. Where the characteristic offers no
  stabilising direction (flat margin), or says "faster" while the override is already at its cap,
  back off towards the floor and say so. The override at the alarm's start, × ``ceiling_factor``,
  becomes the section's ceiling at once; when the episode ends, the ceiling drops to halfway between
  the override where it chattered and the lowest one of the episode (a bisection of the real
  stability boundary, episode by episode): recovery does not climb back into the chatter.
- **Quiet** for ``quiet_s`` after the last alarm: recover towards min(100 %, ceiling).
- **Signal.** Non-finite, out-of-range (|value| > ``plausible_max``), stuck (a constant chunk of
  ``stuck_samples`` or more) or time-reversed samples are dropped and counted; a gap restarts the
  band filter (a warm-up, during which the override holds), and so does a source whose clock
  restarted (stamps more than ``RESTART_BACK_S`` before the previous ones: a new stream). No
  valid samples for ``hold_after_s``: hold the override; for ``signal_timeout_s``: go to the safe
  override.

Every decision is written to the :class:`~planner.supervisor.event_log.EventLog`: status changes, every alarm
step, every new target, and a heartbeat every ``heartbeat_s`` while nothing changes.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

import numpy as np
from ruckig import InputParameter, Result, Ruckig, Trajectory

from planner.plan_file import Plan, PlanSection
from planner.supervisor.characteristic import (
    Characteristic,
    characteristic_of,
    chatter_frequency,
    feed_limit_for_force,
    force_at,
    stabilising_direction,
)
from planner.supervisor.detector import DEFAULT_WAVELET, Detector, select_level
from planner.supervisor.event_log import EventLog
from robot_io.signals.base import SignalChunk

__all__ = [
    "STATUSES",
    "Episode",
    "StepResult",
    "StepStatus",
    "Supervisor",
    "SupervisorConfig",
]

#: Step statuses: ``ok`` monitoring, nothing to do; ``learning`` collecting the stable window;
#: ``warmup`` the band filter is filling (after start or a gap): override held; ``alarm`` chatter:
#: backing off; ``quiet`` band under the limit, waiting before recovery; ``recover`` climbing back
#: towards the plan; ``hold`` signal missing or implausible: override held; ``safe`` signal lost
#: for too long: safe override; ``error`` internal failure: override held.
class StepStatus(enum.StrEnum):
    """What a supervisor step is doing (a ``str``: compares and serialises as its value)."""

    OK = "ok"              # monitoring, no alarm
    LEARNING = "learning"  # learning σ of stable cutting
    WARMUP = "warmup"      # band filters settling after a start, restart or gap
    ALARM = "alarm"        # the band is over its limit: the override is being moved
    QUIET = "quiet"        # after an alarm, waiting for the band to stay quiet
    RECOVER = "recover"    # returning towards the planned feed
    HOLD = "hold"          # no signal: holding the last override
    SAFE = "safe"          # signal lost too long: the safe override
    ERROR = "error"        # an internal failure: holding the last override, said in the reason


#: Every status, in :class:`StepStatus` order.
STATUSES = tuple(StepStatus)
#: Override changes smaller than this are not a new target [percent].
TARGET_EPS_PCT = 1e-6
#: Band values needed before σ is taken as learned.
MIN_LEARN_VALUES = 100
#: Samples stamped more than this before the previous ones mean the source restarted its clock
#: (a new stream, accepted after a filter warm-up); less far back they are stale and dropped [s].
RESTART_BACK_S = 0.5
#: A time step longer than this is taken as a stall, not as motion [s].
MAX_DT_S = 0.5


@dataclass(frozen=True)
class SupervisorConfig:
    """Tuning of the supervisor (percent of the planned feed; seconds; the signal's unit).

    Attributes:
        alpha_f: false-alarm rate per band value (L_c from Φ(L_c) = 1 − α_f/2).
        wavelet: PyWavelets name of the DWT.
        chatter_hz: expected chatter frequency when the plan has no natural frequencies [Hz].
        floor_pct: lowest override the supervisor commands.
        safe_pct: override after the signal is lost (None: the floor).
        backoff_pct_s, recover_pct_s: largest override rates down and up [%/s].
        accel_pct_s2, jerk_pct_s3: ruckig limits of the override trajectory.
        gain_pct: override change per unit of relative excess over the limit [%].
        max_step_pct: largest change of the target per step [%].
        quiet_s: band under the limit this long before recovery starts.
        persist_s: an alarm that lasts this long at the reached target backs off one more step.
        ceiling_factor: the section's ceiling is the override at the alarm's start × this.
        hold_after_s: no valid signal this long → hold.
        signal_timeout_s: no valid signal this long → safe override.
        plausible_max: largest plausible |sample| (None: 10 × the plan's force limit).
        stuck_samples: a chunk of at least this many identical samples is a stuck sensor.
        heartbeat_s: log interval while nothing changes.
        use_transient_model: tell the detector the expected mean force (see planner.supervisor.detector).
    """

    alpha_f: float = 6e-5
    wavelet: str = DEFAULT_WAVELET
    chatter_hz: float = 11.0
    floor_pct: float = 20.0
    safe_pct: float | None = None
    backoff_pct_s: float = 400.0
    recover_pct_s: float = 20.0
    accel_pct_s2: float = 4000.0
    jerk_pct_s3: float = 100_000.0
    gain_pct: float = 30.0
    max_step_pct: float = 40.0
    quiet_s: float = 0.15
    persist_s: float = 0.25
    ceiling_factor: float = 0.95
    hold_after_s: float = 0.03
    signal_timeout_s: float = 0.3
    plausible_max: float | None = None
    stuck_samples: int = 64
    heartbeat_s: float = 0.1
    use_transient_model: bool = True


@dataclass(frozen=True)
class StepResult:
    """What one step decided.

    Attributes:
        status: what the step is doing.
        override: override to command now [percent].
        target: where the override trajectory is heading [percent].
        band: largest |detail| of this step, or None.
        ucl: control limit in force (UCL + transient allowance).
        alarm: the band was over the limit.
        section: current section index.
        s_m: dead-reckoned arc length [m].
        reason: the decision in words.
        direction: −1/0/+1 stabilising direction used on an alarm (0 otherwise or none).
    """

    status: StepStatus
    override: float
    target: float
    band: float | None
    ucl: float
    alarm: bool
    section: int
    s_m: float
    reason: str
    direction: int = 0


@dataclass
class Episode:
    """One chatter episode: from the first alarm to the band quiet again.

    Attributes:
        start_s: supervisor time of the first alarm [s]; ``signal_start_s`` its band value's stamp.
        end_s: time the band was quiet for ``quiet_s`` again [s] (None while open).
        last_alarm_s: time of the last alarm step [s].
        override_start, override_min: override at the start and lowest commanded [percent].
        section: section of the first alarm.
        direction: stabilising direction used at the start (0: backed off towards the floor).
    """

    start_s: float
    signal_start_s: float | None
    section: int
    override_start: float
    direction: int
    override_min: float = math.inf
    last_alarm_s: float = 0.0
    end_s: float | None = None
    base: float = 100.0
    reached_s: float | None = None


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
        cuts = [s for s in plan.sections if s.kind == "cut"] or list(plan.sections)
        f_c = float(np.median([chatter_frequency(s, cfg.chatter_hz) for s in cuts]))
        teeth = [s.tooth_frequency for s in cuts if s.tooth_frequency]
        f_t = float(np.median(teeth)) if teeth else None
        self.level = select_level(self.fs_hz, f_c, f_t)
        self.detector = Detector(self.fs_hz, self.level, cfg.alpha_f, sigma, cfg.wavelet)
        self.force_max_N = float(plan.limits.force_max)
        self.plausible_max = (cfg.plausible_max if cfg.plausible_max is not None
                              else 10.0 * self.force_max_N if math.isfinite(self.force_max_N)
                              else math.inf)
        self.safe_pct = cfg.safe_pct if cfg.safe_pct is not None else cfg.floor_pct
        self.episodes: list[Episode] = []
        self.counts = {"steps": 0, "implausible_chunks": 0, "implausible_samples": 0, "gaps": 0,
                       "errors": 0, "alarms": 0, "no_direction": 0, "restarts": 0}
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
        t, v = chunk.t_s, chunk.values
        if not (isinstance(t, np.ndarray) and isinstance(v, np.ndarray)):
            return False, "chunk without sample arrays"
        if t.shape != v.shape or t.ndim != 1:
            return False, "chunk arrays of different shapes"
        if not (np.issubdtype(t.dtype, np.number) and np.issubdtype(v.dtype, np.number)):
            return False, f"samples of type {v.dtype}, not numbers"
        if not (np.all(np.isfinite(v)) and np.all(np.isfinite(t))):
            return False, "non-finite samples"
        if np.max(np.abs(v)) > self.plausible_max:
            return False, f"|sample| {np.max(np.abs(v)):.4g} over the plausible {self.plausible_max:.4g}"
        if v.size >= self.cfg.stuck_samples and np.all(v == v[0]):
            return False, f"{v.size} identical samples (stuck sensor)"
        if v.size > 1 and not np.all(np.diff(t) > 0):
            return False, "time stamps not increasing"
        if self._last_t is not None and self._last_t - RESTART_BACK_S <= t[0] <= self._last_t:
            return False, "time stamps before the previous chunk's"
        return True, ""

    # -- the step ---------------------------------------------------------------------------
    def step(self, now: float, chunk: SignalChunk, applied_override: float | None = None) -> StepResult:
        """One decision at supervisor time ``now`` [s]; never raises.

        Args:
            now: supervisor clock [s] (monotonic).
            chunk: samples that arrived since the last step.
            applied_override: override the controller confirmed [percent] (None: assume the one
                commanded) — used for dead reckoning and the expected mean force.
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

    def _step(self, now: float, chunk: SignalChunk, applied: float | None) -> StepResult:
        cfg = self.cfg
        self.counts["steps"] += 1
        tr = self._track
        dt = 0.0 if self._now is None else min(MAX_DT_S, max(0.0, now - self._now))
        self._now = now
        if self._last_signal_now is None:
            self._last_signal_now = now
        ov_applied = applied if applied is not None and math.isfinite(applied) else self._pos
        tr.s_m += _planned_feed(tr.sec) * ov_applied / 100.0 * dt
        prev_section = tr.section
        self._enter_section(tr.s_m)
        floor, cap = self._limits()
        planned = _planned_feed(tr.sec)
        reason = ""
        status = self._status
        target = self._target
        band: float | None = None
        ucl = self.detector.ucl
        alarm = False
        direction = 0

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

        if missing > cfg.signal_timeout_s:
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
        elif valid:
            out = self.detector.update(chunk.t_s, chunk.values, expected)
            band, ucl, alarm = out.band, out.ucl, out.alarm
            if band is None and not self.detector.monitor.ready:
                status, target = StepStatus.WARMUP, self._pos
                reason = reason or "band filter warming up: override held"
            elif alarm:
                status = StepStatus.ALARM
                self.counts["alarms"] += 1
                target, direction, why = self._on_alarm(now, out.excess, out.t_s, planned, floor, cap)
                reason = (f"chatter: band {band:.4g} > limit {ucl:.4g} (excess {out.excess:.2f}); "
                          + why)
            else:
                since = math.inf if self._last_alarm is None else now - self._last_alarm
                if since < cfg.quiet_s:
                    status, target = StepStatus.QUIET, self._target
                    reason = f"band under the limit for {since:.3f} s: waiting {cfg.quiet_s} s"
                else:
                    self._close_episode(now)
                    goal = min(cap, tr.ceiling)
                    if self._pos < goal - 0.05:
                        status, target = StepStatus.RECOVER, goal
                        reason = (f"band quiet: recovering towards {goal:.1f} %"
                                  + (" (the section's chatter ceiling)" if tr.ceiling < cap else ""))
                    else:
                        status, target = StepStatus.OK, goal
                        reason = reason or "band quiet"
        if prev_section != tr.section:
            reason = (f"section {tr.section} (planned {planned * 1e3:.3g} mm/s, cap {cap:.1f} %); "
                      + reason)
        target = min(max(target, floor), cap)
        open_ep = self.episodes[-1] if self.episodes and self.episodes[-1].end_s is None else None
        fast_up = (open_ep is not None and open_ep.direction > 0
                   and status in (StepStatus.ALARM, StepStatus.QUIET))
        self._advance(now)  # the state now, on the trajectory in force
        if abs(target - self._target) > TARGET_EPS_PCT or fast_up != self._fast_up:
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
        self._emit(now, res, force=changed or alarm or status in (StepStatus.HOLD, StepStatus.SAFE))
        return res

    def _on_alarm(self, now: float, excess: float, t_band: float | None, planned: float,
                  floor: float, cap: float) -> tuple[float, int, str]:
        cfg = self.cfg
        tr = self._track
        ep = self.episodes[-1] if self.episodes and self.episodes[-1].end_s is None else None
        step = min(cfg.max_step_pct, cfg.gain_pct * max(excess, 0.0))
        direction, rel = (0, 0.0)
        if tr.char is not None and planned > 0:
            direction, rel = stabilising_direction(tr.char, planned * self._pos / 100.0)
        if ep is None:
            ep = Episode(now, t_band, tr.section, self._pos, direction, base=self._pos)
            self.episodes.append(ep)
            tr.ceiling = min(tr.ceiling, self._pos * cfg.ceiling_factor)
        ep.last_alarm_s = now
        self._last_alarm = now
        # the amount is taken from the episode's base override, not from the moving one: the band
        # lags the feed by the filter's delay, so a per-step decrement would run to the floor.
        # If the alarm outlasts `persist_s` at the reached target, the base moves on.
        if abs(self._pos - self._target) > 0.5:
            ep.reached_s = None
        elif ep.reached_s is None:
            ep.reached_s = now
        elif now - ep.reached_s > cfg.persist_s:
            ep.base = self._pos
            ep.reached_s = None
        if direction > 0 and self._pos < cap - 0.05:
            target = max(self._target, ep.base + step)
            why = f"raising the feed by {step:.1f} % (d margin/d feed > 0, relative slope {rel:.3g})"
        elif direction < 0:
            target = min(self._target, ep.base - step)
            why = f"lowering the feed by {step:.1f} % (d margin/d feed < 0, relative slope {rel:.3g})"
        else:
            self.counts["no_direction"] += 1
            target = min(self._target, ep.base - step)
            why = ("the characteristic offers no stabilising feed direction (relative slope "
                   f"{rel:.3g}): backing off {step:.1f} % towards the floor" if direction == 0 else
                   "faster would stabilise but the override is at its cap: backing off "
                   f"{step:.1f} % towards the floor")
        target = min(max(target, floor), cap)
        ep.override_min = min(ep.override_min, target)
        return target, direction, why

    def _close_episode(self, now: float) -> None:
        if self.episodes and self.episodes[-1].end_s is None:
            ep = self.episodes[-1]
            ep.end_s = now
            if ep.section == self._track.section and math.isfinite(ep.override_min):
                # the boundary lies between where it chattered and where it went quiet: bisect
                mid = ep.override_min + 0.5 * (ep.override_start - ep.override_min)
                self._track.ceiling = min(self._track.ceiling, mid)

    def _emit(self, now: float, res: StepResult, force: bool) -> None:
        if not force and now - self._last_log < self.cfg.heartbeat_s and abs(
                res.target - self._logged_target) <= TARGET_EPS_PCT:
            return
        self._last_log = now
        self._logged_target = res.target
        self.log.write({"t_s": now, "section": res.section, "s_m": res.s_m, "band": res.band,
                        "ucl": res.ucl, "override": res.override, "target": res.target,
                        "status": res.status, "alarm": res.alarm, "direction": res.direction,
                        "reason": res.reason})
