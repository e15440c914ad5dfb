"""KUKA RSI over UDP: the XML telegrams and the PC-side server, the override link of a KR C4.

The controller is the client: every cycle (4 ms ``#IPO_FAST`` or 12 ms ``#IPO``) it sends a ``<Rob>``
telegram and expects a ``<Sen>`` reply, echoing its ``IPOC`` unchanged, inside the cycle
(KUKA_IO.md §2.1–2.3). :class:`RsiServer` answers every telegram at once with zero ``RKorr``, the
echoed ``IPOC`` and the override channel (``<OvProW>`` → ``MAP2OV_PRO`` → ``$OV_PRO``, §2.4).

Parsing treats every datagram as untrusted:

- size-bounded (``max_packet_bytes``, 4 KiB by default) before any parsing;
- XML through ``defusedxml`` with DTDs forbidden: no entity expansion (billion laughs), no external
  entities, no DTD at all;
- attribute and element names matched case-insensitively (``Type`` and ``TYPE`` both occur);
- the ``<Dat TaskType="b">`` wrapper of older configurations accepted (its children are read as the
  root's);
- ``IPOC`` must be an unsigned 64-bit decimal integer; its text is echoed exactly as received;
- an XML declaration naming an encoding that neither expat nor Python knows
  (``encoding="UTF-1"``) is a malformed packet like any other.

Any packet that fails is dropped (no reply) and counted as malformed. The first packet after the
link (re)starts is dropped when shorter than 100 bytes (older RSI sends one short telegram first;
counted apart, not as malformed).
"""

from __future__ import annotations

import collections
import logging
import math
import re
import socket
import threading
import time
from dataclasses import dataclass, field
from xml.etree.ElementTree import Element, ParseError

import defusedxml.ElementTree as safe_et
from defusedxml import DefusedXmlException

from robot_io.links.base import LinkError, LinkStats, LinkStatus, ProtocolError, StatsCounter, override_to_int

__all__ = [
    "IPOC_MAX",
    "MAX_PACKET_BYTES",
    "SHORT_FIRST_PACKET_BYTES",
    "RobTelegram",
    "RsiServer",
    "SenTelegram",
    "build_rob",
    "build_sen",
    "parse_rob",
    "parse_sen",
]

_log = logging.getLogger(__name__)

#: Largest datagram parsed [bytes]; a full ``<Rob>`` with poses, currents and Tech is about 1.2 kB.
MAX_PACKET_BYTES = 4096
#: A first packet shorter than this is the short start telegram of older RSI [bytes]
#: (ros-industrial kuka_rsi_hw_interface drops it).
SHORT_FIRST_PACKET_BYTES = 100
IPOC_MAX = 2**64 - 1
#: Poll period of the server socket for the stop flag and the link timeout [s].
_POLL_S = 0.02
_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_.-]{0,63}$")
_DIGITS = re.compile(r"^[0-9]{1,20}$")
_POSE_KEYS = ("X", "Y", "Z", "A", "B", "C")
_AXIS_KEYS = ("A1", "A2", "A3", "A4", "A5", "A6")


def _root(data: bytes, tag: str, max_bytes: int) -> tuple[dict[str, str], list[Element], bool]:
    """(root attributes with lower-case names, body elements, ``<Dat>`` wrapper seen) of an RSI
    telegram; raises ProtocolError."""
    n = len(data)
    if n > max_bytes:
        raise ProtocolError("rsi", f"larger than {max_bytes} bytes", n)
    if n == 0:
        raise ProtocolError("rsi", "empty datagram", n)
    try:
        root = safe_et.fromstring(data, forbid_dtd=True, forbid_entities=True, forbid_external=True)
    except DefusedXmlException as e:
        raise ProtocolError("rsi", f"refused XML feature: {type(e).__name__}", n) from None
    except (ParseError, ValueError) as e:   # UnicodeError is a ValueError
        raise ProtocolError("rsi", f"not well-formed XML: {e}", n) from None
    except LookupError as e:   # expat hands a declared encoding it lacks to Python's codecs
        raise ProtocolError("rsi", f"unknown XML encoding: {str(e)[:60]}", n) from None
    if root.tag.lower() != tag.lower():
        raise ProtocolError("rsi", f"root element <{root.tag[:40]}>, expected <{tag}>", n)
    body: list[Element] = []
    dat = False
    for child in root:
        if child.tag.lower() == "dat":
            body.extend(child)
            dat = True
        else:
            body.append(child)
    return {k.lower(): v for k, v in root.attrib.items()}, body, dat


def _ipoc(body: list[Element], size: int) -> tuple[int, str]:
    texts = [e.text for e in body if e.tag.lower() == "ipoc"]
    if len(texts) != 1:
        raise ProtocolError("rsi", f"{len(texts)} <IPOC> elements, expected one", size)
    text = (texts[0] or "").strip()
    if not _DIGITS.match(text) or int(text) > IPOC_MAX:
        raise ProtocolError("rsi", f"IPOC {text[:30]!r} is not an unsigned 64-bit integer", size)
    return int(text), text


#: Elements whose attributes must all be finite numbers (poses, axes, the late counter,
#: corrections); other elements keep only their numeric attributes.
_NUMERIC = frozenset({"RIST", "RSOL", "AIPOS", "ASPOS", "EIPOS", "ESPOS", "MACUR", "DELAY", "RKORR", "AKORR"})


def _floats(elem: Element, size: int) -> dict[str, float]:
    strict = elem.tag.upper() in _NUMERIC
    out: dict[str, float] = {}
    for k, v in elem.attrib.items():
        try:
            x = float(v)
        except ValueError:
            x = math.nan
        if not math.isfinite(x):
            if strict:
                raise ProtocolError("rsi", f"<{elem.tag[:40]}> {k[:40]}={v[:30]!r} is not a finite number",
                                    size)
            continue
        out[k.upper()] = x
    return out


@dataclass(frozen=True)
class RobTelegram:
    """A parsed ``<Rob>`` telegram (robot → PC).

    Attributes:
        ipoc: interpolation counter [ms] (opaque, unsigned 64-bit).
        ipoc_text: ``IPOC`` as received (what the reply echoes).
        type: the root ``Type``/``TYPE`` attribute, ``None`` when absent.
        poses: elements with numeric attributes, by upper-case tag (``"RIST"`` → {"X": mm, ..., "C":
            deg}, ``"AIPOS"`` → {"A1": deg, ...}, ``"DELAY"`` → {"D": count}).
        values: text elements by upper-case tag (``"OVPRO"`` → "100").
        dat: the body was wrapped in ``<Dat>``.
    """

    ipoc: int
    ipoc_text: str
    type: str | None
    poses: dict[str, dict[str, float]] = field(default_factory=dict)
    values: dict[str, str] = field(default_factory=dict)
    dat: bool = False

    @property
    def rist(self) -> dict[str, float] | None:
        """Actual Cartesian pose (X, Y, Z [mm]; A, B, C [deg]) or ``None``."""
        return self.poses.get("RIST")

    @property
    def aipos(self) -> dict[str, float] | None:
        """Actual axis angles A1..A6 [deg] or ``None``."""
        return self.poses.get("AIPOS")

    @property
    def delay(self) -> int | None:
        """The controller's late-packet counter (``<Delay D=..>``) or ``None``."""
        d = self.poses.get("DELAY", {}).get("D")
        return None if d is None else int(d)

    @property
    def ov_pro(self) -> float | None:
        """``$OV_PRO`` the controller reports (``<OvPro>``) [percent], ``None`` when absent or bad."""
        text = self.values.get("OVPRO")
        try:
            v = float(text) if text is not None else None
        except ValueError:
            return None
        return v if v is not None and math.isfinite(v) else None


def parse_rob(data: bytes, max_bytes: int = MAX_PACKET_BYTES) -> RobTelegram:
    """Parse a ``<Rob>`` datagram; raises :class:`~robot_io.links.base.ProtocolError`."""
    attrs, body, dat = _root(data, "Rob", max_bytes)
    ipoc, text = _ipoc(body, len(data))
    poses: dict[str, dict[str, float]] = {}
    values: dict[str, str] = {}
    for e in body:
        tag = e.tag.upper()
        if tag == "IPOC":
            continue
        if e.attrib:
            poses[tag] = _floats(e, len(data))
        else:
            values[tag] = (e.text or "").strip()
    return RobTelegram(ipoc, text, attrs.get("type"), poses, values, dat)


@dataclass(frozen=True)
class SenTelegram:
    """A parsed ``<Sen>`` telegram (PC → robot).

    Attributes:
        ipoc, ipoc_text: the echoed counter.
        type: the root ``Type`` attribute (must equal the config's SENTYPE), ``None`` when absent.
        override: the override channel's value [percent], ``None`` when the element is absent (the
            controller then holds the last value: HOLDON=1).
        corrections: correction elements by upper-case tag (``"RKORR"``, ``"AKORR"``).
    """

    ipoc: int
    ipoc_text: str
    type: str | None
    override: int | None
    corrections: dict[str, dict[str, float]] = field(default_factory=dict)


def parse_sen(data: bytes, override_tag: str = "OvProW", max_bytes: int = MAX_PACKET_BYTES) -> SenTelegram:
    """Parse a ``<Sen>`` datagram; raises :class:`~robot_io.links.base.ProtocolError`."""
    attrs, body, _ = _root(data, "Sen", max_bytes)
    ipoc, text = _ipoc(body, len(data))
    override = None
    corrections: dict[str, dict[str, float]] = {}
    for e in body:
        tag = e.tag.upper()
        if tag == override_tag.upper():
            raw = (e.text or "").strip()
            if not re.match(r"^-?[0-9]{1,6}$", raw):
                raise ProtocolError("rsi", f"<{e.tag}> {raw[:30]!r} is not an integer", len(data))
            override = int(raw)
        elif e.attrib:
            corrections[tag] = _floats(e, len(data))
    return SenTelegram(ipoc, text, attrs.get("type"), override, corrections)


def _check_name(name: str, what: str) -> str:
    if not _NAME.match(name):
        raise LinkError("rsi", f"{what} {name!r} must be an XML name (letters, digits, _)")
    return name


def build_sen(ipoc_text: str, override_percent: int | None, sentype: str = "ImFree",
              override_tag: str = "OvProW", correction: str | None = "RKorr", dat: bool = False,
              estr: str | None = None) -> bytes:
    """A ``<Sen>`` reply: zero correction, the override channel (omitted when ``None``), the IPOC echo.

    ``ipoc_text`` is echoed verbatim (pass :attr:`RobTelegram.ipoc_text`); ``correction`` is
    ``"RKorr"`` (X..C), ``"AKorr"`` (A1..A6) or ``None`` (no correction element); ``estr`` is free
    ASCII text shown on the HMI (XML-escaped).
    """
    parts = [f'<Sen Type="{sentype}">']
    if dat:
        parts.append('<Dat TaskType="b">')
    if estr is not None:
        safe = (estr.encode("ascii", "replace").decode().replace("&", "&amp;").replace("<", "&lt;")
                .replace(">", "&gt;"))
        parts.append(f"<EStr>{safe}</EStr>")
    if correction == "RKorr":
        parts.append('<RKorr X="0.0" Y="0.0" Z="0.0" A="0.0" B="0.0" C="0.0"/>')
    elif correction == "AKorr":
        parts.append('<AKorr A1="0.0" A2="0.0" A3="0.0" A4="0.0" A5="0.0" A6="0.0"/>')
    if override_percent is not None:
        parts.append(f"<{override_tag}>{int(override_percent)}</{override_tag}>")
    parts.append(f"<IPOC>{ipoc_text}</IPOC>")
    if dat:
        parts.append("</Dat>")
    parts.append("</Sen>")
    return "".join(parts).encode("ascii")


def build_rob(ipoc: int, rist_mm_deg: tuple[float, ...] | None = None,
              aipos_deg: tuple[float, ...] | None = None, delay: int | None = 0,
              ov_pro_percent: float | None = None, type_attr: str = "Type", dat: bool = False,
              precision: int = 4) -> bytes:
    """A ``<Rob>`` telegram as a controller sends it (for the simulated controller and tests).

    ``rist_mm_deg`` = (X, Y, Z [mm], A, B, C [deg]); ``aipos_deg`` = A1..A6 [deg]; ``type_attr`` is
    the spelling of the root attribute (``"Type"`` on real controllers, ``"TYPE"`` in ROS sims).
    """
    p = int(precision)
    parts = [f'<Rob {type_attr}="KUKA">']
    if dat:
        parts.append('<Dat TaskType="b">')
    if rist_mm_deg is not None:
        parts.append("<RIst " + " ".join(f'{k}="{v:.{p}f}"' for k, v in zip(_POSE_KEYS, rist_mm_deg,
                                                                          strict=True)) + "/>")
    if aipos_deg is not None:
        parts.append("<AIPos " + " ".join(f'{k}="{v:.{p}f}"' for k, v in zip(_AXIS_KEYS, aipos_deg,
                                                                           strict=True)) + "/>")
    if delay is not None:
        parts.append(f'<Delay D="{int(delay)}"/>')
    if ov_pro_percent is not None:
        parts.append(f"<OvPro>{int(round(ov_pro_percent))}</OvPro>")
    parts.append(f"<IPOC>{int(ipoc)}</IPOC>")
    if dat:
        parts.append("</Dat>")
    parts.append("</Rob>")
    return "".join(parts).encode("ascii")


class RsiServer:
    """PC-side RSI server: the override link of a KR C4 (implements
    :class:`~robot_io.links.base.RobotLink`).

    Args:
        bind_host, port: UDP address to bind (the controller's Ethernet config names it); port 0 picks
            a free port (see :attr:`address`).
        sentype: ``Type`` of the reply root (must equal ``<SENTYPE>`` in the config).
        override_tag: element of the override channel (``OvProW`` → MAP2OV_PRO).
        correction: ``"RKorr"``, ``"AKorr"`` or ``None``: the zero correction element sent.
        dat: wrap replies in ``<Dat TaskType="b">``; ``None`` mirrors the robot's telegrams.
        initial_override_percent: sent until :meth:`set_override` is called, when the robot reports no
            ``<OvPro>``; when it does, its own value is echoed (no jump at start).
        reply_budget_s: a reply sent later than this after its telegram arrived counts as late [s].
        link_timeout_s: no ``<Rob>`` for this long → link down, counted as a timeout [s].
        cycle_ms: the controller's IPOC step per cycle [ms] (4 or 12), for :attr:`missed_cycles`;
            ``None`` learns it as the smallest step seen.
        max_packet_bytes: datagrams longer than this are malformed [bytes].
        keep_reply_times: how many reply times to keep for :meth:`reply_times`.

    Counters (:attr:`stats`): ``replies`` = valid telegrams, ``sent`` = replies, ``malformed``,
    ``late``, ``timeouts``, ``reconnects``; :attr:`short_first_dropped` and :attr:`missed_cycles`
    (cycles skipped by the IPOC sequence, i.e. telegrams lost on the way in) apart.
    """

    def __init__(self, bind_host: str = "127.0.0.1", port: int = 0, sentype: str = "ImFree",
                 override_tag: str = "OvProW", correction: str | None = "RKorr", dat: bool | None = None,
                 initial_override_percent: float = 100.0, reply_budget_s: float = 0.002,
                 link_timeout_s: float = 0.25, cycle_ms: int | None = None,
                 max_packet_bytes: int = MAX_PACKET_BYTES,
                 keep_reply_times: int = 100_000) -> None:
        _check_name(sentype, "sentype")
        _check_name(override_tag, "override_tag")
        if correction not in ("RKorr", "AKorr", None):
            raise LinkError("rsi", f"correction {correction!r}: use 'RKorr', 'AKorr' or None")
        first = override_to_int(initial_override_percent)
        if first is None:
            raise LinkError("rsi", "initial_override_percent must be a finite number")
        if not (reply_budget_s > 0 and link_timeout_s > 0 and (cycle_ms is None or cycle_ms > 0)
                and max_packet_bytes > 0):
            raise LinkError("rsi", "reply_budget_s, link_timeout_s, cycle_ms and max_packet_bytes must be "
                                   "positive")
        self.sentype, self.override_tag, self.correction, self.dat = sentype, override_tag, correction, dat
        self.reply_budget_s, self.link_timeout_s = reply_budget_s, link_timeout_s
        self.cycle_ms, self.max_packet_bytes = cycle_ms, max_packet_bytes
        self._initial = first
        self._auto_cycle = cycle_ms is None
        self._stats = StatsCounter()
        self._lock = threading.Lock()
        self._override: int | None = None
        self._last_rob: RobTelegram | None = None
        self._last_rx = -math.inf
        self._up = False
        self._ever_up = False
        self._peer: tuple[str, int] | None = None
        self._times: collections.deque[float] = collections.deque(maxlen=keep_reply_times)
        self.short_first_dropped = 0
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
        with self._lock:
            self._override = value
        if self.connected:
            return LinkStatus(True, "sent in next reply", value)
        return LinkStatus(False, f"no <Rob> from the controller for {self.link_timeout_s} s; value kept "
                                 "for the next reply", value)

    def read_override(self) -> float | None:
        with self._lock:
            return None if self._last_rob is None else self._last_rob.ov_pro

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
        """The last valid ``<Rob>`` (pose, axes, Delay, OvPro), ``None`` before the first."""
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
            try:
                self._handle(data, addr, t_rx)
            except Exception as e:  # noqa: BLE001 - the server must keep answering
                _log.exception("rsi server: unexpected error")
                self._stats.add(malformed=1, error=f"unexpected {type(e).__name__}: {e}")

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
            self._stats.add(timeouts=1, error=f"no <Rob> for {self.link_timeout_s} s")

    def _handle(self, data: bytes, addr: tuple[str, int], t_rx: float) -> None:
        self._check_timeout()
        with self._lock:
            starting = not self._up
        if starting and len(data) < SHORT_FIRST_PACKET_BYTES:
            self.short_first_dropped += 1
            return
        try:
            rob = parse_rob(data, self.max_packet_bytes)
        except ProtocolError as e:
            self._stats.add(malformed=1, error=str(e))
            return
        with self._lock:
            prev = self._last_rob
            value = self._wanted_override()
            if value is None:
                value = override_to_int(rob.ov_pro) if rob.ov_pro is not None else self._initial
        dat = rob.dat if self.dat is None else self.dat
        reply = build_sen(rob.ipoc_text, value, self.sentype, self.override_tag, self.correction, dat)
        if prev is not None and not starting and rob.ipoc > prev.ipoc:
            step = rob.ipoc - prev.ipoc
            if self._auto_cycle:
                self.cycle_ms = step if self.cycle_ms is None else min(self.cycle_ms, step)
            self.missed_cycles += max(0, step // (self.cycle_ms or step) - 1)
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
