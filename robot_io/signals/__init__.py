"""Signal sources: where the supervisor's force/strain samples come from.

:class:`~robot_io.signals.base.SignalSource` is the protocol; members: a recorded file replayed
(:mod:`~robot_io.signals.replay`) and a UDP sample stream (:mod:`~robot_io.signals.udp`)."""

from robot_io.signals.base import (
    CHUNK_STATUSES,
    Backlog,
    SignalChunk,
    SignalSource,
    SourceStats,
    empty_chunk,
)
from robot_io.signals.replay import (
    ReplaySource,
    SignalFileError,
    load_signal,
)
from robot_io.signals.udp import (
    HEADER,
    MAGIC,
    MAX_SAMPLES,
    REORDER_WINDOW,
    UdpSignalSender,
    UdpSignalSource,
    pack_samples,
    parse_samples,
)

__all__ = [
    "Backlog",
    "CHUNK_STATUSES",
    "HEADER",
    "MAGIC",
    "MAX_SAMPLES",
    "REORDER_WINDOW",
    "ReplaySource",
    "SignalChunk",
    "SignalFileError",
    "SignalSource",
    "SourceStats",
    "UdpSignalSender",
    "UdpSignalSource",
    "empty_chunk",
    "load_signal",
    "pack_samples",
    "parse_samples",
]
