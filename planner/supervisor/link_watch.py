"""Does the controller apply the override the supervisor commands? A refusal is a link fault.

A link's ``set_override`` answers "queued", not "applied" (see :mod:`robot_io.links.base`). Two
things tell whether the controller took the value, and :class:`LinkWatch` checks both once per
loop cycle, before the supervisor's step:

- **refused writes**: the link's ``stats.refused`` counter went up (KVP: a write answered with
  status 0, or read back as another value). The fault is raised in the cycle that sees it, so a
  refusal reaches the operator within one cycle plus the link's own reply time;
- **an override that does not follow**: the override the controller reports (``read_override()``)
  is not within :data:`FOLLOW_TOL_PCT` of any value commanded over the last *follow time*, nor of
  the last value commanded before it (which it has had the follow time to reach), in
  :data:`FOLLOW_MIN_CHECKS` consecutive checks; a controller that reports no override at all for
  :data:`NO_REPORT_S` while connected does not follow either. A command the controller ignores
  is thus a fault one follow time and a few cycles after it was sent. RSI has no per-write
  answer, so this is how a refusing RSI controller is found: its ``<OvPro>`` stays where it was.
  The follow time is a property of the protocol (:func:`follow_time`): :data:`RSI_FOLLOW_CYCLES`
  controller cycles for RSI (the IPOC step the link learns, not the loop's period),
  :data:`KVP_FOLLOW_S` for KukaVarProxy.

While the link is down (``connected`` false) nothing is judged: the loop reports the outage
itself, and the follow check restarts one follow time after the link is back.

A :class:`LinkFault` is what the supervisor escalates
(:meth:`planner.supervisor.policy.Supervisor.link_fault`): hold the override, raise an operator
alarm.
"""

from __future__ import annotations

import collections
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

__all__ = [
    "FOLLOW_MIN_CHECKS",
    "FOLLOW_TOL_PCT",
    "KVP_FOLLOW_S",
    "NO_REPORT_S",
    "RSI_FOLLOW_CYCLES",
    "LinkFault",
    "LinkWatch",
    "follow_time",
]

#: Cycles within which an RSI controller's ``<OvPro>`` must show a commanded override: the reply
#: of cycle k carries the value, the controller applies it from cycle k+1 and reports it in that
#: cycle's ``<Rob>`` (2 cycles); the loop sends at any phase of the controller's cycle and the
#: child-process server syncs every 5 ms (1 more at 4 ms); 5 leaves two late packets of slack.
#: 20 ms at 4 ms (KR C4), 60 ms at 12 ms (KR C2) — inside the 100 ms an operator alarm is due.
RSI_FOLLOW_CYCLES = 5
#: Time within which KukaVarProxy must read back a written override [s]: the client reads
#: ``$OV_PRO`` right after every write; two round trips through the controller's CrossComm (not
#: real time, KUKA_IO.md §3.1; no public measurement, tens of ms reported) and the client's reply
#: timeout (0.1–0.2 s) fit. A write KukaVarProxy refuses outright is a refusal (status 0), caught
#: in the next cycle without waiting for this.
KVP_FOLLOW_S = 0.3
#: The override is an integer percentage rounded half up; a controller that rounds otherwise may
#: report 1 % off [percent].
FOLLOW_TOL_PCT = 1.0
#: Consecutive loop checks an override must fail to follow, besides the follow time, before it is a
#: fault: one late loop iteration (a stall of the machine) must not read as a refusal.
FOLLOW_MIN_CHECKS = 3
#: A connected link that reports no override at all for this long is a fault [s]: KukaVarProxy
#: reads ``$OV_PRO`` within milliseconds of connecting, so only a starved or broken client is
#: slower; an RSI controller whose ETHERNET configuration sends no override channel never
#: reports one (a configuration error, not a refusal of one write: no need to find it in 100 ms).
NO_REPORT_S = 1.0


@dataclass(frozen=True)
class LinkFault:
    """The controller does not apply the override.

    Attributes:
        t_s: loop time the fault was found [s].
        kind: ``"refused"`` (the link counted refused writes) or ``"not_applied"`` (the reported
            override does not follow the command).
        reason: what happened, in words fit for the log and the operator.
        commanded: the override last commanded [percent].
        applied: the override the controller reports [percent] (None: it reports none).
    """

    t_s: float
    kind: str
    reason: str
    commanded: int | None
    applied: float | None


def follow_time(link: Any, cycle_s: float) -> float:
    """The follow time [s] of a link now: for the RSI servers :data:`RSI_FOLLOW_CYCLES` controller
    cycles — the IPOC step the link learned (``cycle_ms``), ``cycle_s`` (the loop's) until it
    has —, :data:`KVP_FOLLOW_S` for any other link."""
    from robot_io.links.rsi import RsiServer
    from robot_io.links.rsi_process import RsiProcessServer

    if isinstance(link, RsiServer | RsiProcessServer):
        try:
            step_ms = float(getattr(link, "cycle_ms", None) or math.nan)
        except (TypeError, ValueError):
            step_ms = math.nan
        step = step_ms * 1e-3 if math.isfinite(step_ms) and step_ms > 0 else cycle_s
        return RSI_FOLLOW_CYCLES * step
    return KVP_FOLLOW_S


class LinkWatch:
    """Checks, cycle by cycle, that the controller applies what is commanded (module docstring).

    Args:
        follow_s: the follow time [s] (:func:`follow_time`), or a function giving it now (an RSI
            link learns its controller's cycle while it runs).
        refused0: the link's ``stats.refused`` at the start (refusals before the run are not ours).
        clock: the clock the follow time is measured on (None: the loop times given to
            :meth:`check` and :meth:`commanded`). A loop on a virtual clock talks to a real
            controller in wall time: its watch measures on ``time.monotonic``.

    Attributes:
        refusals: refused writes the link reported during the run.
        not_followed: times the reported override stopped following the command.
    """

    def __init__(self, follow_s: float | Callable[[], float], refused0: int = 0,
                 clock: Callable[[], float] | None = None) -> None:
        self._follow = follow_s if callable(follow_s) else float(follow_s)
        if not (math.isfinite(self.follow_s) and self.follow_s > 0):
            raise ValueError("follow_s must be positive")
        self.refusals = 0
        self.not_followed = 0
        self._refused = int(refused0)
        self._sent: collections.deque[tuple[float, int]] = collections.deque()
        self._up_since: float | None = None
        self._bad_since: float | None = None
        self._bad_checks = 0
        self._faulted = False
        self._clock = clock

    @property
    def follow_s(self) -> float:
        """The follow time in force [s]."""
        f = self._follow
        return float(f()) if callable(f) else f

    def commanded(self, now: float, percent: int) -> None:
        """Record an override sent to the link at loop time ``now`` [s]."""
        self._sent.append((self._clock() if self._clock else now, int(percent)))

    def _window(self, now: float, follow: float) -> tuple[int, int] | None:
        """(lowest, highest) override the controller may show now: every value sent within the
        follow time, and the last one sent before it."""
        horizon = now - follow
        while len(self._sent) >= 2 and self._sent[1][0] <= horizon:
            self._sent.popleft()   # the oldest is superseded by one the controller has had time for
        if not self._sent:
            return None
        values = [v for _, v in self._sent]
        return min(values), max(values)

    def check(self, now: float, applied: float | None, connected: bool, refused: int,
              last_error: str = "") -> LinkFault | None:
        """Judge the link at loop time ``now`` [s]; a :class:`LinkFault` the cycle a fault begins
        (a fault that goes on is reported once; every new refusal is reported again)."""
        last = self._sent[-1][1] if self._sent else None
        t = self._clock() if self._clock else now   # follow times are measured on this
        if refused > self._refused:
            n = refused - self._refused
            self._refused = refused
            self.refusals += n
            self._faulted = True
            why = f" ({last_error})" if last_error else ""
            return LinkFault(now, "refused", f"the controller refused {n} override write(s)"
                                             f"{why}", last, applied)
        if not connected:
            self._up_since = None
            self._bad_since = None
            self._bad_checks = 0
            return None
        if self._up_since is None:
            self._up_since = t
        follow = self.follow_s
        window = self._window(t, follow)
        if window is None or t - self._up_since < follow:
            return None
        lo, hi = window
        ok = (applied is not None and math.isfinite(applied)
              and lo - FOLLOW_TOL_PCT <= applied <= hi + FOLLOW_TOL_PCT)
        if ok:
            self._bad_since = None
            self._bad_checks = 0
            return None
        if self._bad_since is None:
            self._bad_since = t
        self._bad_checks += 1
        if self._bad_checks < FOLLOW_MIN_CHECKS or self._faulted:
            return None
        if applied is None and t - self._up_since < NO_REPORT_S:
            return None
        self._faulted = True
        self.not_followed += 1
        shown = "reports no override" if applied is None else f"applies {applied:.0f} %"
        asked = f"{lo} %" if lo == hi else f"{lo}-{hi} %"
        return LinkFault(now, "not_applied",
                         f"the controller {shown} where {asked} was commanded more than the "
                         f"follow time {follow:g} s ago", last, applied)
