"""KUKA RSI over UDP: the PC-side server, the override link of a KR C4.

The controller is the client: every cycle (4 ms ``#IPO_FAST`` or 12 ms ``#IPO``) it sends a ``<Rob>``
telegram and expects a ``<Sen>`` reply, echoing its ``IPOC`` unchanged, inside the cycle
(KUKA_IO.md §2.1–2.3). :class:`RsiServer` answers every telegram at once with the correction
(zero unless :meth:`RsiServer.set_correction` gave one: the supervisor's online deflection
compensation), the echoed ``IPOC`` and the override channel (``<OvProW>`` → ``MAP2OV_PRO`` →
``$OV_PRO``, §2.4);
the shape of the reply (SENTYPE, correction element and its attributes, override tags) is the
controller's ETHERNET configuration, :class:`~robot_io.links.rsi_config.RsiConfig`. The telegrams
and their checks are :mod:`robot_io.links.rsi_telegram` (re-exported here).

Who may talk: the server locks to the configured controller address (``controller``) or to the
sender of the first valid ``<Rob>``, and drops datagrams from anyone else before parsing them
(counted in :attr:`RsiServer.foreign_dropped`). Without a configured port, the lock follows the
controller to a new source port only while the link is down (an RSI restart).

Any packet that fails to parse (:mod:`~robot_io.links.rsi_telegram`: size, encoding, XML, IPOC,
value ranges) is dropped (no reply) and counted as malformed. The first packet after the link
(re)starts is dropped when shorter than 100 bytes (older RSI sends one short telegram first;
counted apart, not as malformed).

The controller's IPOC step per cycle (4 or 12 ms on a KR C4, whatever a simulator uses) is learned
from the IPOC sequence itself, never taken from the supervisor's loop period:
:attr:`RsiServer.missed_cycles` counts the cycles the sequence skipped.
"""

from __future__ import annotations

import collections
import logging
import math
import os
import re
import socket
import threading
import time
from collections.abc import Sequence

from robot_io.links.base import LinkError, LinkStats, LinkStatus, ProtocolError, StatsCounter, override_to_int
from robot_io.links.rsi_config import RsiConfig, load_rsi_config
from robot_io.links.rsi_telegram import (
    AXIS_LIMIT,
    CORRECTION_DIGITS,
    DELAY_MAX,
    IPOC_MAX,
    MAX_PACKET_BYTES,
    ORIENTATION_LIMIT_DEG,
    POSITION_LIMIT_MM,
    RobTelegram,
    SenTelegram,
    build_rob,
    build_sen,
    parse_rob,
    parse_sen,
)

__all__ = [
    "AXIS_LIMIT",
    "CORRECTION_MODES",
    "DELAY_MAX",
    "IPOC_MAX",
    "MAX_PACKET_BYTES",
    "ORIENTATION_LIMIT_DEG",
    "POSITION_LIMIT_MM",
    "SHORT_FIRST_PACKET_BYTES",
    "RobTelegram",
    "RsiServer",
    "SenTelegram",
    "build_rob",
    "build_sen",
    "correction_values",
    "parse_rob",
    "parse_sen",
]

_log = logging.getLogger(__name__)

#: A first packet shorter than this is the short start telegram of older RSI [bytes]
#: (ros-industrial kuka_rsi_hw_interface drops it).
SHORT_FIRST_PACKET_BYTES = 100
#: Poll period of the server socket for the stop flag and the link timeout [s].
_POLL_S = 0.02
#: Replies whose relative correction is remembered, to send again when ``<Delay>`` says they were late.
_RESEND_WINDOW = 16
_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_.-]{0,63}$")
#: How the controller applies a correction (``RSI_ON(#RELATIVE)`` or ``RSI_ON(#ABSOLUTE)``).
CORRECTION_MODES = ("relative", "absolute")


def correction_values(values: Sequence[float], mode: str, element: str | None,
                      tags: Sequence[str]) -> list[float] | LinkStatus:
    """The correction ``values`` as floats, or the refusing status (no correction element, a
    mode not in :data:`CORRECTION_MODES`, not numbers, not one finite value per attribute
    ``tags`` of ``element``): the check of every ``set_correction``."""
    if not tags:
        return LinkStatus(False, "the RSI configuration has no correction element; nothing is sent")
    if mode not in CORRECTION_MODES:
        return LinkStatus(False, f"correction mode {mode!r} is not one of {', '.join(CORRECTION_MODES)}")
    try:
        vals = [float(v) for v in values]
    except (TypeError, ValueError):
        return LinkStatus(False, "correction values are not numbers; nothing sent")
    if len(vals) != len(tags) or not all(math.isfinite(v) for v in vals):
        return LinkStatus(False, f"<{element}> takes {len(tags)} finite values "
                                 f"({', '.join(tags)}); nothing sent")
    return vals


def _check_name(name: str, what: str) -> str:
    if not _NAME.match(name):
        raise LinkError("rsi", f"{what} {name!r} must be an XML name (letters, digits, _)")
    return name


class _IpocSteps:
    """The controller's IPOC step per cycle, learned from the sequence, and the cycles it skipped.

    The step is the smallest positive step of the current link session (a lost telegram makes a
    step a multiple of it, never smaller). Steps are kept as a histogram so that a loss seen before
    the true step showed is recounted once it does.
    """

    #: Distinct steps kept; past that, further new steps are counted with the step known then.
    MAX_DISTINCT = 256

    def __init__(self) -> None:
        self.step: int | None = None
        self._hist: dict[int, int] = {}
        self._before = 0  # missed cycles of earlier sessions and of folded steps

    def restart(self) -> None:
        """A new link session: keep the count, learn the step again."""
        self._before = self.missed
        self._hist.clear()
        self.step = None

    def add(self, step: int) -> None:
        if step <= 0:
            return
        if step in self._hist:
            self._hist[step] += 1
        elif len(self._hist) < self.MAX_DISTINCT:
            self._hist[step] = 1
        else:
            self._before += max(0, step // (self.step or step) - 1)
            return
        if self.step is None or step < self.step:
            self.step = step

    @property
    def missed(self) -> int:
        c = self.step
        if c is None:
            return self._before
        return self._before + sum(n * (s // c - 1) for s, n in self._hist.items())


def _resolve_controller(controller: str | tuple[str, int] | None) -> tuple[str | None, int | None]:
    """(IP, port or None) of a configured controller address; raises LinkError."""
    if controller is None:
        return None, None
    if isinstance(controller, str):
        host, port = controller, None
    else:
        host, port = controller[0], (None if controller[1] in (None, 0) else int(controller[1]))
    if port is not None and not 1 <= port <= 65535:
        raise LinkError("rsi", f"controller port {port} is not a UDP port (1..65535)")
    try:
        return socket.gethostbyname(host), port
    except OSError as e:
        raise LinkError("rsi", f"cannot resolve the controller address {host!r}: {e}") from e


class RsiServer:
    """PC-side RSI server: the override link of a KR C4 (implements
    :class:`~robot_io.links.base.RobotLink`).

    Args:
        bind_host, port: UDP address to bind (the controller's Ethernet config names it); port 0 picks
            a free port (see :attr:`address`).
        sentype: ``Type`` of the reply root (must equal ``<SENTYPE>`` in the config).
        override_tag: element of the override channel (``OvProW`` → MAP2OV_PRO).
        correction: ``"RKorr"``, ``"AKorr"`` or ``None``: the correction element sent (zeros until
            :meth:`set_correction`).
        dat: wrap replies in ``<Dat TaskType="b">``; ``None`` mirrors the robot's telegrams.
        initial_override_percent: sent until :meth:`set_override` is called, when the robot reports no
            override; when it does, its own value is echoed (no jump at start).
        reply_budget_s: a reply sent later than this after its telegram arrived counts as late [s].
        link_timeout_s: no ``<Rob>`` for this long → link down, counted as a timeout [s].
        cycle_ms: the IPOC step the controller is expected to use [ms], a cross-check only: the step
            is always learned from the IPOC sequence (see :attr:`cycle_ms`), so the supervisor's
            loop period never enters :attr:`missed_cycles`; a mismatch is logged once.
        max_packet_bytes: datagrams longer than this are malformed [bytes].
        keep_reply_times: how many reply times to keep for :meth:`reply_times`.
        config: the controller's ETHERNET configuration (an
            :class:`~robot_io.links.rsi_config.RsiConfig` or the path of its XML file): SENTYPE,
            correction element and attributes, override channel and read-back. Given, it replaces
            ``sentype``, ``override_tag`` and ``correction`` (which must then be left at their
            defaults), and its PORT must equal ``port`` unless ``port`` is 0.
        controller: the controller's address, ``"HOST"`` or ``(HOST, PORT)``: only datagrams from it
            are parsed. ``None``: lock to the sender of the first valid ``<Rob>``.

    Counters (:attr:`stats`): ``replies`` = valid telegrams, ``sent`` = replies, ``malformed``,
    ``late``, ``timeouts``, ``reconnects``; apart: :attr:`short_first_dropped`,
    :attr:`foreign_dropped` (datagrams from another sender than the controller, dropped unparsed)
    and :attr:`missed_cycles` (cycles skipped by the IPOC sequence, i.e. telegrams lost on the way
    in).
    """

    def __init__(self, bind_host: str = "127.0.0.1", port: int = 0, sentype: str = "ImFree",
                 override_tag: str | None = "OvProW", correction: str | None = "RKorr",
                 dat: bool | None = None, initial_override_percent: float = 100.0,
                 reply_budget_s: float = 0.002, link_timeout_s: float = 0.25, cycle_ms: int | None = None,
                 max_packet_bytes: int = MAX_PACKET_BYTES,
                 keep_reply_times: int = 100_000, config: RsiConfig | str | os.PathLike[str] | None = None,
                 controller: str | tuple[str, int] | None = None) -> None:
        if config is None:
            _check_name(sentype, "sentype")
            if override_tag is not None:
                _check_name(override_tag, "override_tag")
            cfg = RsiConfig.from_options(sentype, override_tag, correction)
        else:
            if (sentype, override_tag, correction) != ("ImFree", "OvProW", "RKorr"):
                raise LinkError("rsi", "give the reply's shape either as config or as sentype/override_tag/"
                                       "correction, not both")
            cfg = config if isinstance(config, RsiConfig) else load_rsi_config(config)
        src = f" (RSI config {cfg.source})" if cfg.source else ""
        if cfg.only_send:
            raise LinkError("rsi", f"ONLYSEND is TRUE{src}: the controller takes no replies, so no override "
                                   "can be sent; set <ONLYSEND>FALSE</ONLYSEND>")
        if cfg.protocol != "UDP":
            raise LinkError("rsi", f"PROTOCOL {cfg.protocol}{src}: only RSI over UDP is implemented")
        if cfg.port is not None and port != 0 and port != cfg.port:
            raise LinkError("rsi", f"the controller sends to port {cfg.port}{src}, but the server would bind "
                                   f"{port}; use the same port")
        first = override_to_int(initial_override_percent)
        if first is None:
            raise LinkError("rsi", "initial_override_percent must be a finite number")
        if not (reply_budget_s > 0 and link_timeout_s > 0 and (cycle_ms is None or cycle_ms > 0)
                and max_packet_bytes > 0):
            raise LinkError("rsi", "reply_budget_s, link_timeout_s, cycle_ms and max_packet_bytes must be "
                                   "positive")
        self.config = cfg
        self.sentype, self.override_tag, self.correction = cfg.sentype, cfg.override_tag, cfg.correction
        self.dat = dat
        self.reply_budget_s, self.link_timeout_s = reply_budget_s, link_timeout_s
        self.max_packet_bytes = max_packet_bytes
        #: The controller's IPOC step per cycle [ms] learned from the sequence (``None`` before two
        #: telegrams of a link session).
        self.cycle_ms: int | None = None
        self._expected_step = cycle_ms
        self._step_warned = False
        self._steps = _IpocSteps()
        self._initial = first
        self._stats = StatsCounter()
        self._lock = threading.Lock()
        self._override: int | None = None
        ntags = len(cfg.correction_tags) if cfg.correction is not None else 0
        self._corr: list[float] | None = None  # None: zeros
        self._corr_mode = "relative"
        self._corr_sent = [0.0] * ntags
        self._corr_recent: collections.deque = collections.deque(maxlen=_RESEND_WINDOW)
        self._last_delay: float | None = None
        #: relative corrections sent again because the controller counted their reply late
        self.corrections_resent = 0
        self._last_rob: RobTelegram | None = None
        self._last_rx = -math.inf
        self._up = False
        self._ever_up = False
        self._peer: tuple[str, int] | None = None
        self._lock_ip, self._lock_port = _resolve_controller(controller)
        self._port_fixed = self._lock_port is not None
        self._last_foreign: tuple[str, int] | None = None
        self._times: collections.deque[float] = collections.deque(maxlen=keep_reply_times)
        self.short_first_dropped = 0
        #: Datagrams from another sender than the controller, dropped before parsing.
        self.foreign_dropped = 0
        self.missed_cycles = 0
        self._stop = threading.Event()
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            self._sock.bind((bind_host, port))
        except OSError as e:
            self._sock.close()
            raise LinkError("rsi", f"cannot bind UDP {bind_host}:{port}: {e}; the port must match the "
                                   "controller's Ethernet config and be free") from e
        self._sock.settimeout(_POLL_S)
        self.address: tuple[str, int] = self._sock.getsockname()[:2]
        self._thread = threading.Thread(target=self._run, name=f"rsi-server-{self.address[1]}", daemon=True)
        self._thread.start()

    # -- RobotLink -------------------------------------------------------------------------------
    def set_override(self, percent: float) -> LinkStatus:
        value = override_to_int(percent)
        if value is None:
            return LinkStatus(False, f"override {percent!r} is not a finite number; nothing sent")
        if self.override_tag is None:
            return LinkStatus(False, "the RSI configuration has no override channel (a RECEIVE element "
                                     "OvProW wired to MAP2OV_PRO); nothing is sent")
        with self._lock:
            self._override = value
        if self.connected:
            return LinkStatus(True, "sent in next reply", value)
        return LinkStatus(False, f"no <Rob> from the controller for {self.link_timeout_s:g} s; value kept "
                                 "for the next reply", value)

    def set_correction(self, values: Sequence[float], mode: str = "relative") -> LinkStatus:
        """The correction element's values from the next reply on (RKorr: X, Y, Z [mm], A, B, C
        [deg]; one value per attribute of the configured correction element, in its order).

        ``mode`` must match the controller's ``RSI_ON``: ``"relative"`` (``#RELATIVE``, what the KRL
        export writes) adds every received correction to the path, so the values are an
        *increment*: they are added to what is still to send and the next reply carries the sum
        once, later replies zeros until the next call (no increment is sent twice, none is lost
        when the loop and the controller run at different rates; the controller drops a reply
        that misses its cycle and counts it in ``<Delay D>``, so when that count goes up the
        dropped replies' corrections are sent again, :attr:`corrections_resent` — the controller's
        behaviour the simulated one follows, UNVERIFIED on hardware). ``"absolute"`` (``#ABSOLUTE``)
        holds the total offset: every reply carries the values until the next call. Limits are the
        caller's and the controller's (POSCORR), not checked here. Never raises: ``percent`` of the
        status is 0 when the values were taken (``ok`` then says whether the controller is
        connected; taken while it is not, they go out with the first reply after), ``None`` when
        not, and the reason says why (no correction element configured, a bad mode, non-finite
        values). Values go out rounded to :data:`CORRECTION_DIGITS` decimals; in relative mode
        the remainder stays pending, so the controller's sum follows the sum given.
        """
        tags = self.config.correction_tags if self.config.correction is not None else ()
        vals = correction_values(values, mode, self.config.correction, tags)
        if isinstance(vals, LinkStatus):
            return vals
        with self._lock:
            if mode == "relative":
                if self._corr_mode != "relative" or self._corr is None:
                    self._corr = [0.0] * len(tags)
                self._corr = [a + b for a, b in zip(self._corr, vals, strict=True)]
            else:
                self._corr = vals
            self._corr_mode = mode
        return LinkStatus(self.connected, "sent in next reply" if self.connected
                          else "no <Rob> from the controller; kept for the next reply", 0)

    @property
    def correction_sent(self) -> tuple[float, ...]:
        """Sum of the correction values sent so far in relative mode, the values of the last reply
        in absolute mode (RKorr: mm, deg); zeros before any."""
        with self._lock:
            return tuple(self._corr_sent)

    def read_override(self) -> float | None:
        with self._lock:
            return None if self._last_rob is None else self._last_rob.override

    @property
    def stats(self) -> LinkStats:
        return self._stats.snapshot()

    @property
    def connected(self) -> bool:
        with self._lock:
            return self._up and time.monotonic() - self._last_rx < self.link_timeout_s

    def close(self) -> None:
        self._stop.set()
        if self._thread.is_alive() and threading.current_thread() is not self._thread:
            self._thread.join()
        self._sock.close()

    def __enter__(self) -> RsiServer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- extras ------------------------------------------------------------------------------------
    @property
    def last_telegram(self) -> RobTelegram | None:
        """The last valid ``<Rob>`` (pose, axes, Delay, override), ``None`` before the first."""
        with self._lock:
            return self._last_rob

    @property
    def peer(self) -> tuple[str, int] | None:
        """Address the last valid ``<Rob>`` came from (the controller), ``None`` before the first."""
        with self._lock:
            return self._peer

    @property
    def last_receive_time(self) -> float:
        """``time.monotonic()`` of the last valid ``<Rob>`` (−inf before the first) [s]."""
        with self._lock:
            return self._last_rx

    def reply_times(self) -> list[float]:
        """Time from a telegram's arrival to its reply being handed to the socket (parse, checks,
        build) for the kept replies [s], oldest first; the full round trip is measured by the peer."""
        with self._lock:
            return list(self._times)

    # -- server thread -----------------------------------------------------------------------------
    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                data, addr = self._sock.recvfrom(self.max_packet_bytes + 1)
            except TimeoutError:
                self._check_timeout()
                continue
            except OSError as e:  # e.g. ICMP errors reported on the socket; keep serving
                if self._stop.is_set():
                    break
                self._stats.add(error=f"socket: {e}")
                continue
            t_rx = time.perf_counter()
            self._check_timeout()
            if self._foreign(addr):
                self._drop_foreign(addr)
                continue
            try:
                self._handle(data, addr, t_rx)
            except Exception as e:  # noqa: BLE001 - the server must keep answering
                _log.exception("rsi server: unexpected error")
                self._stats.add(malformed=1, error=f"unexpected {type(e).__name__}: {e}")

    def _foreign(self, addr: tuple[str, int]) -> bool:
        """The datagram is not from the controller (decided on the address alone, before parsing).
        Only the server thread writes the lock and ``_up``."""
        if self._lock_ip is not None and addr[0] != self._lock_ip:
            return True
        if self._lock_port is not None and addr[1] != self._lock_port:
            # a controller that restarts RSI may send from a new port: only while the link is down
            return self._port_fixed or self._up
        return False

    def _drop_foreign(self, addr: tuple[str, int]) -> None:
        self.foreign_dropped += 1
        n = self.foreign_dropped
        if addr != self._last_foreign:
            self._last_foreign = addr
            self._stats.add(error=f"dropped a datagram from {addr[0]}:{addr[1]}, not the controller "
                                  f"{self._lock_ip}:{self._lock_port}")
        if n & (n - 1) == 0:  # 1, 2, 4, 8 …: a flood cannot flood the log
            _log.warning("rsi server: %d datagram(s) from other senders than the controller %s:%s dropped "
                         "(last from %s:%d)", n, self._lock_ip, self._lock_port, addr[0], addr[1])

    def _wanted_override(self) -> int | None:
        """The override to send, ``None`` before any ``set_override`` (hook for
        :class:`robot_io.links.rsi_process.RsiProcessServer`, which keeps it in shared memory)."""
        return self._override

    def _check_timeout(self) -> None:
        with self._lock:
            lost = self._up and time.monotonic() - self._last_rx >= self.link_timeout_s
            if lost:
                self._up = False
        if lost:
            self._stats.add(timeouts=1, error=f"no <Rob> for {self.link_timeout_s:g} s")

    def _learn_step(self, rob: RobTelegram, prev: RobTelegram | None, starting: bool) -> None:
        if starting:
            self._steps.restart()
        elif prev is not None and rob.ipoc > prev.ipoc:
            self._steps.add(rob.ipoc - prev.ipoc)
        self.cycle_ms = self._steps.step
        self.missed_cycles = self._steps.missed
        step, want = self.cycle_ms, self._expected_step
        if step is not None and want is not None and step != want and not self._step_warned:
            self._step_warned = True
            _log.info("rsi server: the controller steps IPOC by %d ms a telegram, not the expected %d ms; "
                      "missed cycles are counted with the controller's step", step, want)

    def _requeue_late(self, rob: RobTelegram, starting: bool) -> None:
        """Under the lock: when the controller's ``<Delay D>`` (late replies so far) went up since
        the last telegram, the last replies missed their cycle and the controller dropped them, so
        their relative corrections go back to the pending sum (``#RELATIVE`` would lose them)."""
        d = rob.poses.get("DELAY", {}).get("D")
        last, self._last_delay = self._last_delay, d
        if starting:
            self._corr_recent.clear()
            return
        if d is None or last is None or not d > last:
            return
        for _ in range(min(int(round(d - last)), len(self._corr_recent))):
            lost = self._corr_recent.pop()
            if lost is None or not any(lost):
                continue
            self.corrections_resent += 1
            pending = self._corr
            self._corr = lost if pending is None else [a + b for a, b in zip(pending, lost, strict=True)]
            self._corr_sent = [a - b for a, b in zip(self._corr_sent, lost, strict=True)]

    def _handle(self, data: bytes, addr: tuple[str, int], t_rx: float) -> None:
        with self._lock:
            starting = not self._up
        if starting and len(data) < SHORT_FIRST_PACKET_BYTES:
            self.short_first_dropped += 1
            return
        try:
            rob = parse_rob(data, self.max_packet_bytes, self.config.override_read_tag)
        except ProtocolError as e:
            self._stats.add(malformed=1, error=str(e))
            return
        cfg = self.config
        with self._lock:
            prev = self._last_rob
            value = self._wanted_override() if cfg.override_tag is not None else None
            if value is None and cfg.override_tag is not None:
                value = override_to_int(rob.override) if rob.override is not None else self._initial
            self._requeue_late(rob, starting)
            corr = self._corr
            if corr is not None:
                # the telegram carries CORRECTION_DIGITS decimals: what it cannot carry of an
                # increment stays pending (sent once it adds up), so no rounding accumulates
                corr = [round(v, CORRECTION_DIGITS) for v in corr]
                if self._corr_mode == "relative":
                    rest = [a - b for a, b in zip(self._corr, corr, strict=True)]
                    self._corr = rest if any(rest) else None  # an increment is sent once
                    self._corr_sent = [a + b for a, b in zip(self._corr_sent, corr, strict=True)]
                else:
                    self._corr_sent = list(corr)
            self._corr_recent.append(corr if self._corr_mode == "relative" else None)
        dat = rob.dat if self.dat is None else self.dat
        reply = build_sen(rob.ipoc_text, value, cfg.sentype, cfg.override_tag or "", cfg.correction, dat,
                          correction_tags=cfg.correction_tags, correction_values=corr)
        self._learn_step(rob, prev, starting)
        if self._lock_ip is None:
            self._lock_ip = addr[0]
        if not self._port_fixed:
            self._lock_port = addr[1]
        again = starting and self._ever_up
        self._ever_up = True
        # Everything is counted before the reply leaves, so a peer that has the reply sees the counts.
        dt = time.perf_counter() - t_rx
        with self._lock:
            self._times.append(dt)
            self._last_rob = rob
            self._last_rx = time.monotonic()
            self._up = True
            self._peer = addr
        self._stats.add(replies=1, sent=1, late=int(dt > self.reply_budget_s), reconnects=int(again))
        self._sock.sendto(reply, addr)
