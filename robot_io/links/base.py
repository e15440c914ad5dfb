"""The robot link: how the online supervisor talks to a KUKA controller's program override.

Two members implement :class:`RobotLink`, one file each:

- :class:`robot_io.links.kvp.KvpClient` — KukaVarProxy (TCP 7000) client that writes and reads ``$OV_PRO``;
  a background worker owns the socket, reconnects with bounded exponential backoff and verifies every
  write with a read-back;
- :class:`robot_io.links.rsi.RsiServer` — RSI (UDP XML) server: the controller sends ``<Rob>`` every 4 ms or
  12 ms and the server replies inside the cycle with zero ``RKorr``, the echoed ``IPOC`` and the
  override channel.
- :class:`robot_io.links.rsi_process.RsiProcessServer` — the same server in a child process: use it when
  the calling process also computes (a CPU-bound thread holds the GIL for up to 5 ms at a time, longer
  than the 4 ms cycle; ``benchmarks/link_latency.py`` measures it).

Their simulated peers (:mod:`robot_io.links.kvp_sim`, :mod:`robot_io.links.rsi_sim`) speak the same bytes over
loopback.

Contract for the caller (the supervisor loop), all methods thread-safe:

``set_override(percent) -> LinkStatus``
    Never raises and returns in bounded time (microseconds: it only stores the value for the link's
    own thread, which sends it — KVP: the worker writes it, latest value wins; RSI: the next reply
    carries it). ``percent`` is clamped to [0, 100] and rounded to an integer (``$OV_PRO`` is an
    integer percentage); NaN/inf are refused with ``ok=False`` and nothing is sent. ``ok`` tells
    whether the link is up *now*; a value set while the link is down is kept and sent once it is
    back.
``read_override() -> float | None``
    The last override the controller confirmed [percent] (KVP: read back from ``$OV_PRO``; RSI: the
    ``<OvPro>`` element of the last ``<Rob>``), or ``None`` when nothing was confirmed yet. This,
    not the value set, is what the controller applies: the supervisor decides on it.
``stats -> LinkStats``
    A snapshot (a copy: safe to keep) of the link's counters.
``connected -> bool``
    The link is up: KVP socket connected; RSI ``<Rob>`` packets arriving.
``close()``
    Stop the link's thread and close its socket; idempotent. Links are context managers.

Everything a link does wrong is counted in :class:`LinkStats` and described in ``last_error``;
nothing is raised into the caller's loop. An ``ok`` answer of ``set_override`` says the value was
queued, not that the controller took it: a write the controller refuses is counted in
``LinkStats.refused`` when the protocol tells (KVP), and the supervisor checks that
``read_override()`` follows what it commands either way.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass, replace
from typing import Protocol, runtime_checkable

from models.errors import CctmillError

__all__ = [
    "OVERRIDE_MAX_PERCENT",
    "OVERRIDE_MIN_PERCENT",
    "LinkError",
    "LinkStats",
    "LinkStatus",
    "ProtocolError",
    "RobotLink",
    "StatsCounter",
    "override_to_int",
]

#: ``$OV_PRO`` range [percent] (KUKA_IO.md §1.3: integer 0..100).
OVERRIDE_MIN_PERCENT = 0
OVERRIDE_MAX_PERCENT = 100


class LinkError(CctmillError):
    """A robot link cannot be set up as asked (bad address, port in use, bad option).

    Raised only by constructors and blocking helpers, never by ``set_override``/``read_override``.

    Attributes:
        link: ``"kvp"`` or ``"rsi"``.
    """

    def __init__(self, link: str, message: str) -> None:
        super().__init__(f"{link}: {message}")
        self.link = link


class ProtocolError(LinkError):
    """A packet on the wire does not follow the protocol (KUKA_IO.md §2.3, §3.2).

    The links catch it, count the packet as malformed and drop it; the parsers raise it.

    Attributes:
        reason: what is wrong with the packet.
        size: its length [bytes].
    """

    def __init__(self, link: str, reason: str, size: int) -> None:
        super().__init__(link, f"malformed packet ({size} bytes): {reason}")
        self.reason = reason
        self.size = size


@dataclass(frozen=True)
class LinkStatus:
    """Answer of :meth:`RobotLink.set_override`.

    Attributes:
        ok: the value was accepted and the link is up.
        reason: ``"queued"`` / ``"sent in next reply"`` when ok, else what is wrong (link down, value
            refused) in words fit for the supervisor's log.
        percent: the integer override that will be sent [percent], ``None`` when refused.
    """

    ok: bool
    reason: str
    percent: int | None = None


@dataclass(frozen=True)
class LinkStats:
    """Counters of a link since it was made.

    Attributes:
        sent: packets sent (KVP requests; RSI replies).
        replies: valid packets received (KVP replies; RSI ``<Rob>`` telegrams).
        malformed: received packets dropped as not following the protocol.
        late: KVP replies slower than the link's ``late_s``; RSI replies sent later than the reply
            budget after their ``<Rob>`` arrived.
        timeouts: KVP requests without a reply in time; RSI: periods without any ``<Rob>`` longer
            than the link timeout.
        reconnects: KVP: successful reconnections after the link was lost; RSI: link back after a
            timeout.
        refused: override writes the controller refused — KVP: a write answered with status 0, or
            one whose read-back shows another value (a controller that does not apply it). RSI has
            no per-write answer: whether ``<OvPro>`` follows the command is judged by the
            supervisor (:mod:`planner.supervisor.link_watch`), so an RSI link leaves this at 0.
        last_error: the latest problem in words ("" when none).
    """

    sent: int = 0
    replies: int = 0
    malformed: int = 0
    late: int = 0
    timeouts: int = 0
    reconnects: int = 0
    refused: int = 0
    last_error: str = ""


class StatsCounter:
    """Thread-safe mutable counters behind a :class:`LinkStats` snapshot (for link implementations)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._stats = LinkStats()

    def add(self, error: str | None = None, **increments: int) -> None:
        """Add ``increments`` to the named counters; record ``error`` as ``last_error`` if given."""
        with self._lock:
            s = self._stats
            changes: dict[str, int | str] = {k: getattr(s, k) + v for k, v in increments.items()}
            if error is not None:
                changes["last_error"] = error
            self._stats = replace(s, **changes)  # type: ignore[arg-type]

    def snapshot(self) -> LinkStats:
        with self._lock:
            return self._stats


def override_to_int(percent: float) -> int | None:
    """``percent`` clamped to [0, 100] and rounded half up to an integer; ``None`` if not finite."""
    try:
        value = float(percent)
    except (TypeError, ValueError):
        return None
    if not math.isfinite(value):
        return None
    value = min(max(value, OVERRIDE_MIN_PERCENT), OVERRIDE_MAX_PERCENT)
    return int(math.floor(value + 0.5))


@runtime_checkable
class RobotLink(Protocol):
    """What the supervisor needs from a controller link (see the module docstring for the contract)."""

    def set_override(self, percent: float) -> LinkStatus:
        """Store ``percent`` [0..100] for sending; never raises, bounded time."""
        ...

    def read_override(self) -> float | None:
        """Last override the controller confirmed [percent], ``None`` if none yet."""
        ...

    @property
    def stats(self) -> LinkStats:
        """Snapshot of the counters."""
        ...

    @property
    def connected(self) -> bool:
        """The link is up now."""
        ...

    def close(self) -> None:
        """Stop the link's thread and close its socket; idempotent."""
        ...
