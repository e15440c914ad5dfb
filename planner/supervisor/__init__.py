"""The online supervisor: wavelet chatter detection and closed-loop feed override, inside a safety
envelope.

One module per part: the detector (:mod:`~planner.supervisor.detector`), the section's stability
characteristic (:mod:`~planner.supervisor.characteristic`), the override policy
(:mod:`~planner.supervisor.policy`) and how it judges a chatter episode's moves
(:mod:`~planner.supervisor.episode`), the online deflection compensation through RSI ``RKorr``
(:mod:`~planner.supervisor.compensation`), the check that the controller applies the override
(:mod:`~planner.supervisor.link_watch`), the loop and its clock (:mod:`~planner.supervisor.loop`),
a whole supervised run (:mod:`~planner.supervisor.session`), the event log, metrics and plot, and
the simulated cut and cell used to test it without a robot (:mod:`~planner.supervisor.sim_cut`,
:mod:`~planner.supervisor.sim_cell`)."""

from planner.supervisor.characteristic import (
    FLAT_MARGIN_REL,
    Characteristic,
    characteristic_of,
    chatter_frequency,
    feed_limit_for_force,
    force_at,
    margin_at,
    stabilising_direction,
)
from planner.supervisor.compensation import (
    COMPENSATION_FORCES,
    COMPENSATION_FRAMES,
    CompensationConfig,
    CompensationResult,
    CompensationStatus,
    DeflectionCompensator,
    PlanCompensation,
)
from planner.supervisor.detector import (
    DEFAULT_WAVELET,
    EDGE_OCTAVES,
    OVERSAMPLE,
    TRANSIENT_GAIN,
    TRANSIENT_SLACK_S,
    BandMonitor,
    Detector,
    DetectorOutput,
    LevelChoice,
    control_limit,
    detail_filter,
    select_level,
)
from planner.supervisor.detector_iir import (
    IirBandMonitor,
    IirDetector,
)
from planner.supervisor.detectors import (
    DEFAULT_DETECTOR,
    DETECTORS,
    make_detector,
)
from planner.supervisor.episode import (
    AT_FLOOR_TOL_PCT,
    ESCALATE_PERIODS,
    GROWTH_RATIO,
    NOT_FALLING_RATIO,
    Episode,
    OperatorAlarm,
    judge,
)
from planner.supervisor.event_log import (
    EventLog,
)
from planner.supervisor.link_watch import (
    FOLLOW_MIN_CHECKS,
    FOLLOW_TOL_PCT,
    KVP_FOLLOW_S,
    NO_REPORT_S,
    RSI_FOLLOW_CYCLES,
    LinkFault,
    LinkWatch,
    follow_time,
)
from planner.supervisor.loop import (
    LoopReport,
    VirtualClock,
    run_loop,
)
from planner.supervisor.metrics import (
    EpisodeMetrics,
    band_gain,
    episode_metrics,
    episode_outcome_text,
    episode_timing_text,
)
from planner.supervisor.plot import (
    RunTrace,
    plot_run,
)
from planner.supervisor.policy import (
    STATUSES,
    StepResult,
    StepStatus,
    Supervisor,
    SupervisorConfig,
)
from planner.supervisor.session import (
    DEFAULT_SIM_DURATION_S,
    DEFAULT_SIM_FS_HZ,
    SessionConfig,
    SessionSummary,
    run_session,
    simulated_sigma,
    supervise,
)
from planner.supervisor.sim_cell import (
    ROBOTS,
    SimCell,
)
from planner.supervisor.sim_cut import (
    CutScenario,
    CutTruth,
    SimulatedCut,
)

__all__ = [
    "AT_FLOOR_TOL_PCT",
    "BandMonitor",
    "COMPENSATION_FORCES",
    "COMPENSATION_FRAMES",
    "Characteristic",
    "CompensationConfig",
    "CompensationResult",
    "CompensationStatus",
    "CutScenario",
    "CutTruth",
    "DEFAULT_DETECTOR",
    "DEFAULT_SIM_DURATION_S",
    "DEFAULT_SIM_FS_HZ",
    "DEFAULT_WAVELET",
    "DETECTORS",
    "DeflectionCompensator",
    "Detector",
    "DetectorOutput",
    "EDGE_OCTAVES",
    "ESCALATE_PERIODS",
    "Episode",
    "EpisodeMetrics",
    "EventLog",
    "FLAT_MARGIN_REL",
    "FOLLOW_MIN_CHECKS",
    "FOLLOW_TOL_PCT",
    "GROWTH_RATIO",
    "IirBandMonitor",
    "IirDetector",
    "KVP_FOLLOW_S",
    "LevelChoice",
    "LinkFault",
    "LinkWatch",
    "LoopReport",
    "NOT_FALLING_RATIO",
    "NO_REPORT_S",
    "OVERSAMPLE",
    "OperatorAlarm",
    "PlanCompensation",
    "ROBOTS",
    "RSI_FOLLOW_CYCLES",
    "RunTrace",
    "STATUSES",
    "SessionConfig",
    "SessionSummary",
    "SimCell",
    "SimulatedCut",
    "StepResult",
    "StepStatus",
    "Supervisor",
    "SupervisorConfig",
    "TRANSIENT_GAIN",
    "TRANSIENT_SLACK_S",
    "VirtualClock",
    "band_gain",
    "characteristic_of",
    "chatter_frequency",
    "control_limit",
    "detail_filter",
    "episode_metrics",
    "episode_outcome_text",
    "episode_timing_text",
    "feed_limit_for_force",
    "follow_time",
    "force_at",
    "judge",
    "make_detector",
    "margin_at",
    "plot_run",
    "run_loop",
    "run_session",
    "select_level",
    "simulated_sigma",
    "stabilising_direction",
    "supervise",
]
