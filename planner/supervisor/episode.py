"""A chatter episode: its record, and how the moves made in it are judged.

The band lags the chatter amplitude by the band filter's delay D
(:attr:`~planner.supervisor.detector.Detector.delay_s`), so whether a feed change worked shows only
a *decision period* T_d = D + one chatter period after it. :func:`judge` looks at the band's
envelope (its largest value over half a chatter period) each step of an open episode:

- a **raise** (the characteristic says faster is stabilising) is to be reversed when the envelope
  grows by :data:`GROWTH_RATIO` over its value one band delay after the raise (the raise feeds the
  chatter), and at the latest at T_d if the envelope is still :data:`NOT_FALLING_RATIO` of its peak
  since the raise (it did not turn the chatter);
- at the **floor** (the applied override within :data:`AT_FLOOR_TOL_PCT` of it), the episode is to
  be escalated when the band is over the limit and has not fallen one decision period after the
  floor was reached, or is still over the limit :data:`ESCALATE_PERIODS` periods after.

What the policy then does (back off, hold, raise an :class:`OperatorAlarm`) is in
:mod:`planner.supervisor.policy`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

__all__ = [
    "AT_FLOOR_TOL_PCT",
    "ESCALATE_PERIODS",
    "GROWTH_RATIO",
    "NOT_FALLING_RATIO",
    "Episode",
    "OperatorAlarm",
    "judge",
]

#: After a raise, an envelope this many times its value one band delay after the raise is growth:
#: the raise feeds the chatter (the envelope of saturated chatter wanders by a few per cent).
GROWTH_RATIO = 1.25
#: An envelope still at this fraction of its peak one decision period after a move has not fallen:
#: the move did not turn the chatter (a move that does shows a fall to 0.3–0.8 of the peak by then
#: in the simulated cut, for decay rates from 5 to 30 /s).
NOT_FALLING_RATIO = 0.9
#: At the floor, an alarm still on after this many decision periods escalates, falling or not.
ESCALATE_PERIODS = 4
#: The applied override is at the floor (or at a target) when within this of it [percent]: the
#: override is an integer.
AT_FLOOR_TOL_PCT = 1.0


@dataclass
class Episode:
    """One chatter episode: from the first alarm until it is resolved or escalated.

    Attributes:
        start_s: supervisor time of the first alarm [s]; ``signal_start_s`` its band value's stamp.
        end_s: time the episode ended [s] (None while open).
        last_alarm_s: time of the last alarm step [s].
        override_start: override the controller applied at the first alarm [percent].
        override_min: lowest override the controller applied during the episode [percent].
        target_min: lowest target the policy set (it may not have been reached) [percent].
        section: section of the first alarm, its position in ``plan.sections`` (from 0; the
            summaries give its :attr:`section_number`, from 1).
        direction: stabilising direction used at the start (0: backed off towards the floor).
        reversed_s: time a raise was reversed [s] (None: not reversed).
        outcome: ``"resolved"`` (the band quiet again) or ``"escalated"`` (operator alarm); None
            while open.
        outcome_reason: why it ended so, in words.
        base: the override the policy's steps are taken from [percent] (the start, then where a
            step that did not work ended).
        reached_s: when the applied override reached the target in force [s] (None: not yet).
    """

    start_s: float
    signal_start_s: float | None
    section: int
    override_start: float
    direction: int
    override_min: float = math.inf
    target_min: float = math.inf
    last_alarm_s: float = 0.0
    end_s: float | None = None
    base: float = 100.0
    reached_s: float | None = None
    reached_peak: float = field(default=0.0, repr=False)
    reversed_s: float | None = None
    outcome: str | None = None
    outcome_reason: str = ""
    override_max: float = field(default=-math.inf, repr=False)
    # judging the raise: the envelope's peak since it, and its value one band delay after it
    peak: float = field(default=0.0, repr=False)
    lag_env: float | None = field(default=None, repr=False)
    # judging the floor: when the applied override reached it and the envelope's peak since
    floor_s: float | None = field(default=None, repr=False)
    floor_peak: float = field(default=0.0, repr=False)

    @property
    def section_number(self) -> int:
        """The section as the log, plan.json, the report and the KRL program number it, from 1."""
        return self.section + 1

    @property
    def raising(self) -> bool:
        """The episode is raising the feed (direction +1, not reversed)."""
        return self.direction > 0 and self.reversed_s is None


@dataclass(frozen=True)
class OperatorAlarm:
    """Something the operator must know: the supervisor could not keep the cut safe by itself.

    Attributes:
        t_s: supervisor time [s].
        kind: ``"link_refused"`` / ``"link_not_applied"`` (the controller does not apply the
            override), ``"chatter_escalated"`` (chatter at the floor), ``"run_ended_in_episode"``.
        section: the running section's number, from 1.
        reason: what happened, in words.
    """

    t_s: float
    kind: str
    section: int
    reason: str


def judge(ep: Episode, now: float, env: float, alarm: bool, applied: float, floor: float,
          band_delay_s: float, decision_period_s: float) -> tuple[str, str] | None:
    """Judge the episode's move at supervisor time ``now`` [s] (module docstring).

    Args:
        ep: the open episode (its judging state is updated).
        env: the band's envelope now (signal unit).
        alarm: the band is over the limit this step.
        applied: the override the controller applies [percent].
        floor: the floor in force [percent].
        band_delay_s, decision_period_s: D and T_d [s].

    Returns:
        ``("reverse", why)`` for a raise that feeds the chatter, ``("escalate", why)`` for chatter
        the floor does not stop, None otherwise.
    """
    t_d = decision_period_s
    if ep.raising:
        t = now - ep.start_s
        ep.peak = max(ep.peak, env)
        if t >= band_delay_s:
            if ep.lag_env is None:
                ep.lag_env = env
            if alarm and env > GROWTH_RATIO * ep.lag_env:
                return ("reverse", f"the band grew from {ep.lag_env:.4g} to {env:.4g} {t:.3f} s "
                                   f"after raising the feed (band delay {band_delay_s:.3f} s)")
        if t >= t_d and env >= NOT_FALLING_RATIO * ep.peak:
            return ("reverse", f"the band has not fallen one decision period ({t_d:.3f} s) after "
                               f"raising the feed: envelope {env:.4g}, peak {ep.peak:.4g}")
        return None
    if applied > floor + AT_FLOOR_TOL_PCT:
        ep.floor_s = None
        return None
    if ep.floor_s is None:
        ep.floor_s, ep.floor_peak = now, env
    ep.floor_peak = max(ep.floor_peak, env)
    t = now - ep.floor_s
    if alarm and t >= t_d and env >= NOT_FALLING_RATIO * ep.floor_peak:
        return ("escalate", f"chatter at the floor {floor:.1f} %: the band has not fallen {t:.3f} s "
                            f"after the applied override reached it (envelope {env:.4g}, peak "
                            f"{ep.floor_peak:.4g})")
    if alarm and t >= ESCALATE_PERIODS * t_d:
        return ("escalate", f"chatter at the floor {floor:.1f} %: still over the limit {t:.3f} s "
                            f"({ESCALATE_PERIODS} decision periods) after the applied override "
                            "reached it")
    return None
