"""The signal-source family: where the supervisor's force/strain samples come from.

Every source (a recorded file replayed, a UDP sample stream, the simulated cut) implements
:class:`SignalSource`: ``read(max_samples)`` hands back a :class:`SignalChunk` of the samples that
arrived since the last call, each with its own timestamp, and a status. ``read`` never raises: a
source that lost its input, reached its end or received garbage says so in the status and counts it
in :class:`SourceStats`; the supervisor decides what to do (hold, then a safe override).

Timestamps are seconds on the source's own clock (the sender's clock for a UDP stream, the file's
time column for a replay); they are carried through unchanged so a log can be lined up with the
recording. The one exception keeps the :class:`SignalChunk` promise of increasing times: a UDP
sender that restarts with its clock gone back is re-based (see :mod:`robot_io.signals.udp`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np

__all__ = [
    "CHUNK_STATUSES",
    "Backlog",
    "SignalChunk",
    "SignalSource",
    "SourceStats",
    "empty_chunk",
]

#: What a chunk can say about its source:
#: ``ok`` samples delivered (possibly none this time, while the source is alive);
#: ``no_data`` nothing arrived for longer than the source's own silence limit;
#: ``end`` a replay reached its last sample (no more will come);
#: ``error`` the source is broken (socket closed, file unreadable); ``last_error`` says why.
CHUNK_STATUSES = ("ok", "no_data", "end", "error")


@dataclass(frozen=True)
class SignalChunk:
    """Samples read in one call.

    Attributes:
        t_s: sample timestamps [s], shape (n,), strictly increasing within a chunk and from one
            chunk of a source to the next, on the source's clock.
        values: sample values (force [N] or strain, in the source's unit), shape (n,), float64.
            Values are passed as received: non-finite or implausible ones are for the consumer to
            judge.
        status: one of :data:`CHUNK_STATUSES`.
    """

    t_s: np.ndarray
    values: np.ndarray
    status: str = "ok"

    def __len__(self) -> int:
        return int(self.values.shape[0])


def empty_chunk(status: str = "ok") -> SignalChunk:
    """A chunk with no samples and the given status."""
    return SignalChunk(np.zeros(0), np.zeros(0), status)


@dataclass
class SourceStats:
    """Counters a source keeps (monotonic; never reset by reading).

    Attributes:
        samples: samples handed out.
        packets: packets or blocks received (a replay counts its reads).
        malformed: packets dropped because they did not parse (wrong magic, size, values).
        out_of_order: packets dropped because they came after a later one.
        lost: packets never received (gaps in the sequence numbers).
        overflow: samples discarded because the consumer did not keep up.
        resyncs: times the sender was taken to have restarted (its sequence jumped far back or
            far ahead).
        rebases: restarts after which the timestamps were shifted to keep them increasing (the
            sender's clock had gone back).
        backward_samples: samples dropped because their timestamp was not after the previous
            sample's.
        last_error: text of the last problem, ``""`` if none.
    """

    samples: int = 0
    packets: int = 0
    malformed: int = 0
    out_of_order: int = 0
    lost: int = 0
    overflow: int = 0
    resyncs: int = 0
    rebases: int = 0
    backward_samples: int = 0
    last_error: str = ""

    def as_dict(self) -> dict[str, int | str]:
        return dict(self.__dict__)


@runtime_checkable
class SignalSource(Protocol):
    """What the supervisor needs from a signal source.

    Attributes:
        fs_hz: nominal sample rate [Hz] (``0.0`` until known, e.g. before a UDP stream's first
            packet).
        stats: the source's counters.
    """

    fs_hz: float
    stats: SourceStats

    def read(self, max_samples: int) -> SignalChunk:
        """Return at most ``max_samples`` samples that arrived since the last call; never raises."""
        ...

    def close(self) -> None:
        """Release sockets or files; idempotent."""
        ...


@dataclass
class Backlog:
    """Samples received but not yet handed out (shared by the sources); bounded."""

    limit: int
    t: list[np.ndarray] = field(default_factory=list)
    v: list[np.ndarray] = field(default_factory=list)
    size: int = 0

    def push(self, t: np.ndarray, v: np.ndarray) -> int:
        """Append; return how many of the oldest samples were discarded to stay under the limit."""
        self.t.append(t)
        self.v.append(v)
        self.size += v.shape[0]
        dropped = 0
        while self.size > self.limit and self.t:
            excess = self.size - self.limit
            head = self.v[0].shape[0]
            if head <= excess:
                self.t.pop(0)
                self.v.pop(0)
                self.size -= head
                dropped += head
            else:
                self.t[0] = self.t[0][excess:]
                self.v[0] = self.v[0][excess:]
                self.size -= excess
                dropped += excess
        return dropped

    def pop(self, n: int) -> tuple[np.ndarray, np.ndarray]:
        if not self.t or n <= 0:
            return np.zeros(0), np.zeros(0)
        t = np.concatenate(self.t)
        v = np.concatenate(self.v)
        take = min(n, t.shape[0])
        rest_t, rest_v = t[take:], v[take:]
        self.t = [rest_t] if rest_t.size else []
        self.v = [rest_v] if rest_v.size else []
        self.size = rest_v.shape[0]
        return t[:take], v[:take]
