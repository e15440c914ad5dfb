"""Detection delay and closed-loop settling of a supervised simulated cut (the thesis's 5 ms and
0.27–0.3 s).

Definitions (times on the simulation's clock, i.e. the signal's time stamps):

- *visible*: the first moment after the chatter onset at which the true chatter amplitude a(t)
  times the band filter's gain at f_c reaches the control limit — when an ideal detector without
  delay would alarm;
- *detection delay* = time stamp of the first alarming band value − visible (the band filter's
  group delay plus the step quantisation; the computation itself is the step latency);
- *onset to alarm* = first alarm − the onset of the model error (includes the growth of chatter
  from its seed, which no detector can shorten);
- *settling time* = from the first alarm until the true chatter amplitude falls back under the
  visibility level a_vis = UCL / gain for good within the episode (the closed loop's answer);
- *quiet time* = from the first alarm until the supervisor declares the band quiet (its episode
  end minus the ``quiet_s`` wait); only for an episode that ended resolved (an escalated one was
  never declared quiet).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from planner.display import quantity
from planner.supervisor.policy import Supervisor
from planner.supervisor.sim_cut import CutTruth

__all__ = ["EpisodeMetrics", "band_gain", "episode_metrics", "episode_outcome_text",
           "episode_timing_text"]


@dataclass(frozen=True)
class EpisodeMetrics:
    """Timing of one chatter episode [s] (None when it did not happen in the record)."""

    alarm_s: float
    visible_s: float | None
    detection_delay_s: float | None
    onset_to_alarm_s: float | None
    settling_s: float | None
    quiet_s: float | None
    override_start: float
    override_min: float
    direction: int


def band_gain(sup: Supervisor, f_hz: float) -> float:
    """|G(f)| of the supervisor's band filter: band value per unit sinusoid amplitude at f [Hz]."""
    return sup.detector.gain(f_hz)


def episode_metrics(sup: Supervisor, truth: CutTruth, chatter_hz: float, onset_s: float | None,
                    clock_offset_s: float) -> list[EpisodeMetrics]:
    """Metrics of every episode of ``sup`` against the simulated truth.

    Args:
        sup: the supervisor after the run.
        truth: the simulated cut's record.
        chatter_hz: the simulated chatter frequency [Hz].
        onset_s: simulation time of the model error's onset [s], or None.
        clock_offset_s: supervisor clock − simulation time [s] (the cut's start on that clock).
    """
    tr = truth.arrays()
    if tr["t_s"].size == 0 or sup.detector.sigma is None:
        return []
    a_vis = sup.detector.ucl / band_gain(sup, chatter_hz)
    t, a = tr["t_s"], tr["chatter_N"]
    out: list[EpisodeMetrics] = []
    for k, ep in enumerate(sup.episodes):
        alarm = ep.signal_start_s if ep.signal_start_s is not None else ep.start_s - clock_offset_s
        prev_end = -math.inf
        if k:
            prev = sup.episodes[k - 1]
            prev_end = prev.end_s - clock_offset_s if prev.end_s is not None else alarm
        seen = np.flatnonzero((t > prev_end) & (t <= alarm) & (a >= a_vis))
        visible = float(t[seen[0]]) if seen.size else None
        end = ep.end_s - clock_offset_s if ep.end_s is not None else None
        window = (t >= alarm) & (t <= (end if end is not None else t[-1]))
        settling = None
        idx = np.flatnonzero(window)
        if idx.size:
            above = np.flatnonzero(a[idx] >= a_vis)
            if above.size == 0:
                settling = 0.0
            elif above[-1] + 1 < idx.size:
                settling = float(t[idx[above[-1] + 1]] - alarm)
        out.append(EpisodeMetrics(
            alarm_s=float(alarm), visible_s=visible,
            detection_delay_s=None if visible is None else float(alarm - visible),
            onset_to_alarm_s=(None if onset_s is None or k else float(alarm - onset_s)),
            settling_s=settling,
            quiet_s=(None if end is None or ep.outcome != "resolved"
                     else float(end - sup.cfg.quiet_s - alarm)),
            override_start=ep.override_start, override_min=ep.override_min,
            direction=ep.direction))
    return out


def episode_timing_text(episode: dict[str, Any]) -> str:
    """An episode's timing in words, from the summary's episode (``*_ms`` keys, null where the
    record does not have it): what a missing time means, never ``None ms``; empty when the run had
    no simulated truth to time it against."""
    if "detection_delay_ms" not in episode:
        return ""
    delay = episode.get("detection_delay_ms")
    parts = ["alarm before the chatter reached the visible amplitude (a transient, not chatter)"
             if delay is None else f"detected {quantity(delay, '.0f', 'ms')} after the chatter "
             "became visible"]
    onset = episode.get("onset_to_alarm_ms")
    if onset is not None:        # only the first episode follows the scenario's onset
        parts.append(f"{quantity(onset, '.0f', 'ms')} from the onset to the alarm")
    settle = episode.get("settling_ms")
    parts.append("the chatter not gone by the end of the record" if settle is None
                 else f"gone {quantity(settle, '.0f', 'ms')} after the alarm")
    quiet = episode.get("quiet_ms")
    if quiet is not None:
        parts.append(f"declared quiet {quantity(quiet, '.0f', 'ms')} after the alarm")
    elif episode.get("outcome") is None:
        parts.append("the episode still open at the end")
    return ", ".join(parts)


def episode_outcome_text(episode: dict[str, Any]) -> str:
    """How an episode of the summary went, in words: that its overrides are the ones the
    controller applied (and its lowest target), a reversal, and how it ended."""
    parts = ["overrides applied by the controller"
             + (f" (lowest target {quantity(episode['target_min'], '.0f', '%')})"
                if episode.get("target_min") is not None else "")]
    rev = episode.get("reversed_after_ms")
    if rev is not None:
        parts.append(f"the raise reversed {quantity(rev, '.0f', 'ms')} after the alarm")
    outcome = episode.get("outcome")
    why = episode.get("outcome_reason") or ""
    if outcome == "resolved":
        parts.append("resolved")
    elif outcome is not None:
        parts.append(f"{outcome}: {why}" if why else outcome)
    return "; ".join(parts)
