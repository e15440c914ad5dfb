"""The online supervisor: wavelet chatter detection and closed-loop feed override, inside a safety
envelope.

One module per part: the detector (:mod:`~planner.supervisor.detector`), the section's stability
characteristic (:mod:`~planner.supervisor.characteristic`), the override policy
(:mod:`~planner.supervisor.policy`), the loop and its clock (:mod:`~planner.supervisor.loop`), a
whole supervised run (:mod:`~planner.supervisor.session`), the event log, metrics and plot, and the
simulated cut and cell used to test it without a robot (:mod:`~planner.supervisor.sim_cut`,
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
from planner.supervisor.event_log import (
    EventLog,
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
)
from planner.supervisor.plot import (
    RunTrace,
    plot_run,
)
from planner.supervisor.policy import (
    STATUSES,
    Episode,
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
    "BandMonitor",
    "Characteristic",
    "CutScenario",
    "CutTruth",
    "DEFAULT_SIM_DURATION_S",
    "DEFAULT_SIM_FS_HZ",
    "DEFAULT_WAVELET",
    "Detector",
    "DetectorOutput",
    "EDGE_OCTAVES",
    "Episode",
    "EpisodeMetrics",
    "EventLog",
    "FLAT_MARGIN_REL",
    "LevelChoice",
    "LoopReport",
    "OVERSAMPLE",
    "ROBOTS",
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
    "feed_limit_for_force",
    "force_at",
    "margin_at",
    "plot_run",
    "run_loop",
    "run_session",
    "select_level",
    "simulated_sigma",
    "stabilising_direction",
    "supervise",
]
