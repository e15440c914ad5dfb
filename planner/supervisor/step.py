"""What one step of the online supervisor is: its status, its configuration and its result.

Private to nothing: :mod:`planner.supervisor.policy` takes a :class:`SupervisorConfig` and returns
a :class:`StepResult` per step; the loop, the session, the event log and the metrics read them.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

from planner.supervisor.detector import DEFAULT_WAVELET

__all__ = [
    "MAX_DT_S",
    "MIN_LEARN_VALUES",
    "RESTART_BACK_S",
    "STATUSES",
    "TARGET_EPS_PCT",
    "StepResult",
    "StepStatus",
    "SupervisorConfig",
]

#: Step statuses: ``ok`` monitoring, nothing to do; ``learning`` collecting the stable window;
#: ``warmup`` the band filter is filling (after start or a gap): override held; ``alarm`` chatter:
#: backing off; ``quiet`` band under the limit, waiting before recovery; ``recover`` climbing back
#: towards the plan; ``hold`` override held: signal missing or implausible, or the supervisor
#: cannot act (the controller does not apply the override; chatter escalated at the floor);
#: ``safe`` signal lost for too long: safe override; ``error`` internal failure: override held.
class StepStatus(enum.StrEnum):
    """What a supervisor step is doing (a ``str``: compares and serialises as its value)."""

    OK = "ok"              # monitoring, no alarm
    LEARNING = "learning"  # learning σ of stable cutting
    WARMUP = "warmup"      # band filters settling after a start, restart or gap
    ALARM = "alarm"        # the band is over its limit: the override is being moved
    QUIET = "quiet"        # after an alarm, waiting for the band to stay quiet
    RECOVER = "recover"    # returning towards the planned feed
    HOLD = "hold"          # no signal, or cannot act (link fault, escalated): override held
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
        detector: the chatter detector, a name in ``planner.supervisor.detectors.DETECTORS``
            (``dwt`` the thesis's wavelet band, ``iir`` the faster band-pass with tooth notches).
        chatter_hz: expected chatter frequency when the plan has no natural frequencies [Hz].
        floor_pct: lowest override the supervisor commands.
        safe_pct: override after the signal is lost (None: the floor).
        backoff_pct_s, recover_pct_s: largest override rates down and up [%/s].
        accel_pct_s2, jerk_pct_s3: ruckig limits of the override trajectory.
        gain_pct: override change per unit of relative excess over the limit [%].
        max_step_pct: largest change of the target per step [%].
        quiet_s: band under the limit this long before recovery starts.
        persist_s: an alarm that lasts this long at the reached target, the band not falling,
            takes one more step.
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
    detector: str = "dwt"
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
        section: current section, its position in ``plan.sections`` (from 0; the log and the
            summaries give its :attr:`section_number`, from 1).
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

    @property
    def section_number(self) -> int:
        """The section as the log, plan.json, the report and the KRL program number it: 1 for the
        first (0: none, as the KRL marker ``NAME_SEC``)."""
        return self.section + 1
