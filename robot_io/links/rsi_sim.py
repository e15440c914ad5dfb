"""Simulated RSI controller: the UDP client side of RSI, sending ``<Rob>`` every cycle.

:class:`RsiSimController` behaves like a KR C4 running ``RSI_ON`` with an ETHERNET object
(KUKA_IO.md §2.2): every ``cycle_s`` (4 ms or 12 ms) it sends ``<Rob>`` with ``RIst``, ``AIPos``,
``Delay``, ``OvPro`` and ``IPOC`` (IPOC advances by the cycle in ms), waits for the ``<Sen>`` reply
until the reply deadline (the end of the cycle), and counts:

- ``late``: cycles without a valid reply by the deadline (what ``<Delay D>`` reports);
- ``stale``: replies that arrived after their cycle had ended (IPOC of an earlier cycle);
- ``wrong_ipoc``: replies echoing an IPOC that was never sent;
- ``malformed``: replies that do not parse.

The override channel of a valid reply is applied to a simulated path speed
(:class:`~robot_io.links._sim_peer.SimulatedPathSpeed`); a reply without it keeps the last value
(HOLDON=1). A Cartesian correction element (``RKorr`` X..C) of a valid reply is applied to the
path (:class:`~robot_io.links._sim_peer.SimulatedCorrection`: added every cycle in the default
``#RELATIVE`` mode, held in ``#ABSOLUTE``, the total capped at POSCORR ±5 mm / ±5°), and the
``RIst`` the controller reports is the programmed path plus that correction, as on the real one.
Given the site's ETHERNET configuration (``config``, an
:class:`~robot_io.links.rsi_config.RsiConfig`), the controller sends the configured override
read-back element (or none), reads the configured override channel (or none) and counts a reply
whose ``Type`` is not the configured SENTYPE as malformed. After ``timeout_packets`` consecutive
late cycles the controller stops with status ``"RSIBad"``, like the real one (ETHERNET object
``Timeout``, KSS29002).
"""

from __future__ import annotations

import collections
import logging
import socket
import threading
import time
from dataclasses import dataclass, replace

from robot_io.links._sim_peer import (
    POSCORR_LIMIT_DEG,
    POSCORR_LIMIT_MM,
    SimulatedCorrection,
    SimulatedPathSpeed,
    SimulatedPeer,
)
from robot_io.links.base import LinkError, ProtocolError
from robot_io.links.rsi import MAX_PACKET_BYTES, build_rob, parse_sen
from robot_io.links.rsi_config import RsiConfig

__all__ = ["POSCORR_LIMIT_DEG", "POSCORR_LIMIT_MM", "RsiSimController", "RsiSimStats", "SimulatedCorrection"]

_log = logging.getLogger(__name__)

#: Start pose of the simulated TCP (X, Y, Z [mm], A, B, C [deg]); the path runs along base +X.
_START_POSE = (1368.8, 5.2, 876.6, 0.0, 90.0, 0.0)
_AXES_DEG = (0.0, -90.0, 90.0, 0.0, 45.0, 0.0)


@dataclass(frozen=True)
class RsiSimStats:
    """Counters of the simulated controller (see the module docstring for their meaning).

    Attributes:
        cycles: cycles run (telegrams sent, the short first packet not included).
        replies: valid, timely replies.
        late, stale, wrong_ipoc, malformed: see the module docstring.
        consecutive_late: current run of late cycles.
        max_consecutive_late: longest run so far.
        overruns: cycles the sender itself started later than one cycle after their due time.
    """

    cycles: int = 0
    replies: int = 0
    late: int = 0
    stale: int = 0
    wrong_ipoc: int = 0
    malformed: int = 0
    consecutive_late: int = 0
    max_consecutive_late: int = 0
    overruns: int = 0


class RsiSimController(SimulatedPeer):
    """A simulated KUKA controller speaking RSI to a PC server (a context manager).

    Args:
        server_addr: (host, port) of the PC's RSI server.
        cycle_s: RSI cycle [s]: 0.004 (``#IPO_FAST``) or 0.012 (``#IPO``).
        timeout_packets: consecutive late cycles tolerated before ``RSIBad`` (ETHERNET ``Timeout``).
        reply_deadline_s: how long after sending a reply still counts [s] (default: the cycle).
        programmed_speed: ``$VEL.CP`` of the simulated motion [m/s].
        tau: time constant of the path speed's response to an override change [s].
        override_percent: ``$OV_PRO`` at start [percent].
        override_tag: the override channel's element in ``<Sen>``.
        ipoc_start: first IPOC [ms].
        type_attr: spelling of the ``<Rob>`` root attribute (``"Type"`` or ``"TYPE"``).
        dat: wrap the body in ``<Dat TaskType="b">`` (older configurations).
        short_first_packet: send one short ``<Rob>`` first, like RSI ≤ 2.3.
        max_cycles: stop after this many cycles (``None``: run until :meth:`stop`).
        bind_host: local address of the client socket.
        keep_round_trips: how many round-trip times to keep.
        config: the ETHERNET configuration the simulated controller runs (SENTYPE checked in
            replies, override channel and read-back tags); given, ``override_tag`` must be left at
            its default.
        correction_mode: how RKorr is applied: ``"relative"`` (``RSI_ON(#RELATIVE)``, the KRL
            export's) or ``"absolute"``.
        correction_limit_mm, correction_limit_deg: POSCORR limits of the total correction [mm], [deg].
    """

    def __init__(self, server_addr: tuple[str, int], cycle_s: float = 0.004, timeout_packets: int = 100,
                 reply_deadline_s: float | None = None, programmed_speed: float = 1e-3, tau: float = 0.03,
                 override_percent: float = 100.0, override_tag: str = "OvProW",
                 ipoc_start: int = 1_000_000, type_attr: str = "Type", dat: bool = False,
                 short_first_packet: bool = False, max_cycles: int | None = None,
                 bind_host: str = "127.0.0.1", keep_round_trips: int = 100_000,
                 config: RsiConfig | None = None, correction_mode: str = "relative",
                 correction_limit_mm: float = POSCORR_LIMIT_MM,
                 correction_limit_deg: float = POSCORR_LIMIT_DEG) -> None:
        if not (cycle_s > 0 and timeout_packets >= 1):
            raise LinkError("rsi-sim", "cycle_s must be positive and timeout_packets >= 1")
        if config is not None and override_tag != "OvProW":
            raise LinkError("rsi-sim", "give the override tag either in config or as override_tag, not both")
        try:
            self.server_addr = (socket.gethostbyname(server_addr[0]), int(server_addr[1]))
        except OSError as e:
            raise LinkError("rsi-sim", f"cannot resolve {server_addr[0]!r}: {e}") from e
        self.cycle_s = cycle_s
        self.cycle_ms = max(1, int(round(cycle_s * 1000.0)))
        self.timeout_packets = timeout_packets
        self.reply_deadline_s = cycle_s if reply_deadline_s is None else reply_deadline_s
        self.config = config
        self.override_tag: str | None = override_tag if config is None else config.override_tag
        self.override_read_tag: str | None = "OvPro" if config is None else config.override_read_tag
        self.type_attr, self.dat, self.short_first_packet = type_attr, dat, short_first_packet
        self.max_cycles = max_cycles
        self.path = SimulatedPathSpeed(programmed_speed, tau, override_percent)
        try:
            #: the Cartesian path correction received through RKorr
            self.correction = SimulatedCorrection(correction_mode, correction_limit_mm, correction_limit_deg)
        except ValueError as e:
            raise LinkError("rsi-sim", str(e)) from e
        self._corr_tag = "RKORR" if config is None else (config.correction or "").upper()
        self._ipoc = int(ipoc_start)
        self._sent: collections.OrderedDict[int, float] = collections.OrderedDict()  # IPOC → send time
        self._lock = threading.Lock()
        self._stats = RsiSimStats()
        self._rtt: collections.deque[float] = collections.deque(maxlen=keep_round_trips)
        self._late_rtt: collections.deque[float] = collections.deque(maxlen=keep_round_trips)
        self._status = "idle"
        self._stop = threading.Event()
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            self._sock.bind((bind_host, 0))
        except OSError as e:
            self._sock.close()
            raise LinkError("rsi-sim", f"cannot bind {bind_host}: {e}") from e
        self._local: tuple[str, int] = self._sock.getsockname()[:2]
        self._thread: threading.Thread | None = None

    # -- lifecycle ---------------------------------------------------------------------------------
    def start(self) -> RsiSimController:
        if self._thread is None:
            self._status = "running"
            self._thread = threading.Thread(target=self._run, daemon=True,
                                            name=f"rsi-sim-{self.server_addr[1]}")
            self._thread.start()
        return self

    def stop(self) -> None:
        """Stop sending and join the thread; idempotent."""
        self._stop.set()
        if self._thread is not None and threading.current_thread() is not self._thread:
            self._thread.join()
        if self._status == "running":
            self._status = "stopped"
        self._sock.close()

    def wait(self, timeout: float | None = None) -> bool:
        """Wait for the run to end by itself (``max_cycles`` or ``RSIBad``); ``True`` if it did."""
        if self._thread is None:
            return True
        self._thread.join(timeout)
        return not self._thread.is_alive()

    def __enter__(self) -> RsiSimController:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    # -- observation -------------------------------------------------------------------------------
    @property
    def status(self) -> str:
        """``"idle"``, ``"running"``, ``"done"`` (max_cycles reached), ``"stopped"``, ``"RSIBad"``
        or ``"error"`` (the thread ended on an unexpected error, logged; also when it ended
        without saying why)."""
        thread = self._thread
        if self._status == "running" and thread is not None and not thread.is_alive():
            return "error"
        return self._status

    def round_trips(self) -> list[float]:
        """Send-to-valid-reply times of the kept cycles answered in time [s], oldest first."""
        with self._lock:
            return list(self._rtt)

    def late_round_trips(self) -> list[float]:
        """Send-to-reply times of the replies that came after their cycle's deadline (stale) [s]."""
        with self._lock:
            return list(self._late_rtt)

    @property
    def local_address(self) -> tuple[str, int]:
        """The (host, port) the controller sends from (kept after :meth:`stop`)."""
        return self._local

    # -- cycle -------------------------------------------------------------------------------------
    def path_pose(self) -> tuple[float, ...]:
        """The pose the controller commands now: programmed path plus correction (X, Y, Z [mm],
        A, B, C [deg]), what ``RIst`` reports."""
        s_mm = self.path.position() * 1000.0
        base = (_START_POSE[0] + s_mm,) + _START_POSE[1:]
        return tuple(p + d for p, d in zip(base, self.correction.total, strict=True))

    def _telegram(self, ipoc: int) -> bytes:
        s_mm = self.path.position() * 1000.0
        x, y, z, a, b, c = _START_POSE
        dx, dy, dz, da, db, dc = self.correction.total
        with self._lock:
            delay = self._stats.late
        ov = self.path.override_percent if self.override_read_tag is not None else None
        return build_rob(ipoc, (x + s_mm + dx, y + dy, z + dz, a + da, b + db, c + dc), _AXES_DEG, delay,
                         ov, self.type_attr, self.dat,
                         override_tag=self.override_read_tag or "OvPro")

    def _classify(self, data: bytes, ipoc: int, t_send: float, t_recv: float = 0.0) -> bool:
        """Handle one received datagram (received at ``t_recv``, perf_counter); ``True`` when it is the
        valid reply of this cycle."""
        try:
            sen = parse_sen(data, self.override_tag, MAX_PACKET_BYTES)
        except ProtocolError as e:
            self._count(malformed=1)
            _log.debug("rsi-sim: %s", e)
            return False
        if self.config is not None and sen.type != self.config.sentype:
            self._count(malformed=1)
            _log.debug("rsi-sim: reply Type %r, the configured SENTYPE is %r", sen.type, self.config.sentype)
            return False
        if sen.ipoc != ipoc:
            sent_at = self._sent.get(sen.ipoc)
            if sen.ipoc != -1 and sent_at is not None:
                with self._lock:
                    self._late_rtt.append(t_recv - sent_at)
                self._count(stale=1)
            else:
                self._count(wrong_ipoc=1)
            return False
        rtt = t_recv - t_send
        if sen.override is not None and sen.override != int(self.path.override_percent):
            self.path.set_override(min(max(sen.override, 0), 100))
        corr = sen.corrections.get(self._corr_tag)
        if corr is not None and all(k in corr for k in ("X", "Y", "Z", "A", "B", "C")):
            self.correction.apply(tuple(corr[k] for k in ("X", "Y", "Z", "A", "B", "C")))
        with self._lock:
            self._rtt.append(rtt)
            s = self._stats
            self._stats = replace(s, replies=s.replies + 1, consecutive_late=0)
        return True

    def _drain(self) -> None:
        """Classify datagrams that arrived between cycles (all stale or wrong by now)."""
        self._sock.setblocking(False)
        try:
            while True:
                try:
                    data, addr = self._sock.recvfrom(MAX_PACKET_BYTES + 1)
                except (BlockingIOError, InterruptedError):
                    return
                except OSError:
                    return
                if addr[:2] == self.server_addr:
                    self._classify(data, -1, 0.0, time.perf_counter())
        finally:
            self._sock.setblocking(True)

    def _run(self) -> None:
        try:
            self._loop()
            if self._status == "running":   # stopped by stop(): never seen as a dead "running"
                self._status = "stopped"
        except OSError as e:
            if not self._stop.is_set():
                _log.warning("rsi-sim stopped on socket error: %s", e)
                self._status = "stopped"
        except Exception:   # noqa: BLE001 - a dead thread must not leave the status "running"
            _log.exception("rsi-sim: unexpected error, the controller stopped")
            self._status = "error"

    def _loop(self) -> None:
        if self.short_first_packet:
            self._sock.sendto(f'<Rob {self.type_attr}="KUKA"></Rob>'.encode(), self.server_addr)
        due = time.perf_counter()
        n = 0
        while not self._stop.is_set():
            if self.max_cycles is not None and n >= self.max_cycles:
                self._status = "done"
                return
            self._drain()
            ipoc = self._ipoc
            t_send = time.perf_counter()
            self._sent[ipoc] = t_send
            if len(self._sent) > 4096:
                self._sent.popitem(last=False)
            if t_send - due > self.cycle_s:
                self._count(overruns=1)
                due = t_send
            self._sock.sendto(self._telegram(ipoc), self.server_addr)
            self._count(cycles=1)
            deadline = t_send + self.reply_deadline_s
            answered = False
            while not answered:
                left = deadline - time.perf_counter()
                if left <= 0:
                    break
                self._sock.settimeout(left)
                try:
                    data, addr = self._sock.recvfrom(MAX_PACKET_BYTES + 1)
                except TimeoutError:
                    break
                except OSError:
                    break
                t_recv = time.perf_counter()
                if addr[:2] != self.server_addr:
                    continue
                if t_recv > deadline:  # woke up past the deadline: too late for this cycle
                    self._classify(data, -1, t_send, t_recv)
                    break
                answered = self._classify(data, ipoc, t_send, t_recv)
            if not answered:
                with self._lock:
                    s = self._stats
                    run = s.consecutive_late + 1
                    self._stats = replace(s, late=s.late + 1, consecutive_late=run,
                                          max_consecutive_late=max(s.max_consecutive_late, run))
                if run >= self.timeout_packets:
                    self._status = "RSIBad"
                    _log.warning("rsi-sim: %d consecutive late packets: RSIBad (stopped)", run)
                    return
            n += 1
            self._ipoc += self.cycle_ms
            due += self.cycle_s
            pause = due - time.perf_counter()
            if pause > 0:
                self._stop.wait(pause)
