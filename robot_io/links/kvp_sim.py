"""Simulated KukaVarProxy server: the same bytes as the controller's, over loopback.

:class:`KvpSimServer` is a threaded TCP server that behaves like KUKAVARPROXY (KUKA_IO.md §3.1–3.2):
pipelined requests split by ``body_len + 4``, at most ``max_clients`` clients (10), an idle timeout
(30 s), ``PING`` → ``PONG``, unknown variables answered with status 0 and no value, and a reply
``body_len`` that counts the 3 trailer bytes (the VB source) or not (the py_openshowvar README
server), chosen by ``count_trailer``. Writing ``$OV_PRO`` (an integer 0..100) changes a simulated path
speed (:class:`~robot_io.links._sim_peer.SimulatedPathSpeed`); a new name is written into a table of at
most :data:`MAX_VARIABLES` variables, past it the write fails (status 0). Every request that does not
follow the protocol is counted in :attr:`KvpSimServer.stats` ``malformed`` and answered with status 0
when its header could be read; a frame longer than :data:`~robot_io.links.kvp.MAX_BODY_BYTES` or cut
off by the client's close cannot be resynchronised: it is counted and the connection closed.

What the controller does with a write of ``$OV_PRO`` is :attr:`KvpSimServer.override_mode` (settable
while the server runs, to test the supervisor's link-fault handling): ``"apply"`` (a healthy
controller), ``"refuse"`` (every write answered with status 0 and the override unchanged — a
controller whose variable is write-protected, or CrossComm failing) or ``"ignore"`` (answered with
status 1 and the value echoed, but the override unchanged, so a read-back shows the old value). The
monotonic time of the first write not applied is kept in :attr:`KvpSimServer.first_refusal_s`.

Binds 127.0.0.1 unless told otherwise; port 0 picks a free port (see :attr:`KvpSimServer.address`).
"""

from __future__ import annotations

import logging
import socket
import threading
import time
from dataclasses import dataclass

from robot_io.links._sim_peer import SimulatedPathSpeed, SimulatedPeer
from robot_io.links.base import LinkError, ProtocolError
from robot_io.links.kvp import (
    FN_READ,
    FN_WRITE,
    MAX_BODY_BYTES,
    OV_PRO,
    KvpRequest,
    pack_reply,
    parse_request,
)

__all__ = ["MAX_VARIABLES", "OVERRIDE_MODES", "KvpServerStats", "KvpSimServer"]

_log = logging.getLogger(__name__)

#: Poll period of the server's sockets for the stop flag [s]; bounds the time ``stop()`` takes.
_POLL_S = 0.05
#: Most variables the simulated table holds: a write of a new name past it is refused with the
#: protocol's failure reply (status 0), so a client writing ever new names cannot fill memory
#: (each entry may be a 4 KiB value) or slow every look-up. The controller's own names and a
#: test's fit many times over.
MAX_VARIABLES = 1024

#: What the simulated controller does with a write of ``$OV_PRO`` (see the module docstring).
OVERRIDE_MODES = ("apply", "refuse", "ignore")

_DEFAULT_VARIABLES = {
    OV_PRO: "100",
    "$ROBNAME[]": "KR210SIM",
    "$MODEL_NAME[]": "#KR210_R2700_2 C2 SIM",
    "$KR_SERIALNO": "0",
    "$MODE_OP": "#EX",
}


@dataclass(frozen=True)
class KvpServerStats:
    """Counters of the simulated server.

    Attributes:
        connections: clients accepted.
        refused: clients refused because ``max_clients`` were connected.
        requests: request frames received (well-formed or not).
        replies: replies sent.
        malformed: request frames that do not follow the protocol (including oversized ones and
            ones cut off by a close).
        unsupported: well-formed array requests (functions 2/3), answered with status 0.
        idle_closed: connections closed by the idle timeout.
        ov_pro_writes: accepted writes of ``$OV_PRO``.
        ov_pro_refused: writes of ``$OV_PRO`` not applied because of :attr:`KvpSimServer.override_mode`
            (answered status 0 when ``"refuse"``, status 1 when ``"ignore"``).
        table_full: writes of a new name refused because :data:`MAX_VARIABLES` were held.
    """

    connections: int = 0
    refused: int = 0
    requests: int = 0
    replies: int = 0
    malformed: int = 0
    unsupported: int = 0
    idle_closed: int = 0
    ov_pro_writes: int = 0
    ov_pro_refused: int = 0
    table_full: int = 0


class KvpSimServer(SimulatedPeer):
    """Threaded simulated KukaVarProxy server (a context manager: ``with KvpSimServer() as srv:``).

    Args:
        host: bind address (default loopback only).
        port: TCP port; 0 = any free port.
        count_trailer: reply ``body_len`` counts the 3 trailer bytes (KUKAVARPROXY source) or not.
        max_clients: simultaneous clients (KUKAVARPROXY: 10).
        idle_timeout_s: a client silent this long is disconnected [s] (KUKAVARPROXY: 30).
        programmed_speed: ``$VEL.CP`` of the simulated motion [m/s].
        tau: time constant of the path speed response to an override change [s].
        reply_delay_s: artificial delay before each reply [s] (to test timeouts and late replies).
        variables: initial variables (name → KRL value text); default ``$OV_PRO`` = "100" and a few
            identification variables.
        override_mode: what a write of ``$OV_PRO`` does, one of :data:`OVERRIDE_MODES` (the
            attribute of the same name can be changed while the server runs).
    """

    def __init__(self, host: str = "127.0.0.1", port: int = 0, count_trailer: bool = True,
                 max_clients: int = 10, idle_timeout_s: float = 30.0, programmed_speed: float = 1e-3,
                 tau: float = 0.03, reply_delay_s: float = 0.0,
                 variables: dict[str, str] | None = None, override_mode: str = "apply") -> None:
        if max_clients < 1 or idle_timeout_s <= 0 or reply_delay_s < 0:
            raise LinkError("kvp-sim", "max_clients >= 1, idle_timeout_s > 0 and reply_delay_s >= 0 "
                                       "are required")
        if override_mode not in OVERRIDE_MODES:
            raise LinkError("kvp-sim", f"override_mode {override_mode!r}: use one of "
                                       f"{', '.join(OVERRIDE_MODES)}")
        self.override_mode = override_mode
        #: monotonic time [s] of the first ``$OV_PRO`` write not applied (None: none yet)
        self.first_refusal_s: float | None = None
        self.host, self.port = host, int(port)
        self.count_trailer = count_trailer
        self.max_clients = max_clients
        self.idle_timeout_s = idle_timeout_s
        self.reply_delay_s = reply_delay_s
        self.variables: dict[str, str] = dict(_DEFAULT_VARIABLES if variables is None else variables)
        self.variables.setdefault(OV_PRO, "100")
        if len(self.variables) > MAX_VARIABLES:
            raise LinkError("kvp-sim", f"{len(self.variables)} variables given, at most "
                                       f"{MAX_VARIABLES} (MAX_VARIABLES) are held")
        self.path = SimulatedPathSpeed(programmed_speed, tau, float(self.variables[OV_PRO]))
        self._lock = threading.Lock()
        self._stats = KvpServerStats()
        self._stop = threading.Event()
        self._listener: socket.socket | None = None
        self._accept_thread: threading.Thread | None = None
        self._clients: dict[threading.Thread, socket.socket] = {}

    # -- lifecycle ---------------------------------------------------------------------------------
    def start(self) -> KvpSimServer:
        """Bind, listen and serve in background threads; returns self."""
        if self._listener is not None:
            return self
        sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            sock.bind((self.host, self.port))
        except OSError as e:
            sock.close()
            raise LinkError("kvp-sim", f"cannot bind {self.host}:{self.port}: {e}; pick another port "
                                       "or 0 for any free one") from e
        sock.listen(16)
        sock.settimeout(_POLL_S)
        self._listener = sock
        self.port = sock.getsockname()[1]
        self._stop.clear()
        self._accept_thread = threading.Thread(target=self._accept_loop, name=f"kvp-sim-{self.port}",
                                               daemon=True)
        self._accept_thread.start()
        return self

    def stop(self) -> None:
        """Close the listener and every client, join all threads; idempotent."""
        self._stop.set()
        if self._listener is not None:
            try:  # stop listening now: new connections are refused, accept() wakes up
                self._listener.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
        if self._accept_thread is not None:
            self._accept_thread.join()
            self._accept_thread = None
        if self._listener is not None:
            self._listener.close()
            self._listener = None
        with self._lock:
            clients = list(self._clients)
        for t in clients:
            t.join()

    def __enter__(self) -> KvpSimServer:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    @property
    def address(self) -> tuple[str, int]:
        """(host, port) actually bound."""
        return self.host, self.port

    @property
    def client_count(self) -> int:
        with self._lock:
            return len(self._clients)

    # -- serving -----------------------------------------------------------------------------------
    def _accept_loop(self) -> None:
        assert self._listener is not None  # noqa: S101 - set by start() before the thread runs
        while not self._stop.is_set():
            try:
                conn, _ = self._listener.accept()
            except TimeoutError:
                continue
            except OSError:
                break
            with self._lock:
                full = len(self._clients) >= self.max_clients
            if full:
                self._count(refused=1)
                conn.close()
                continue
            conn.settimeout(_POLL_S)
            conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            t = threading.Thread(target=self._client_loop, args=(conn,), daemon=True,
                                 name=f"kvp-sim-{self.port}-client")
            with self._lock:
                self._clients[t] = conn
            self._count(connections=1)
            t.start()

    def _client_loop(self, conn: socket.socket) -> None:
        buf = bytearray()
        last = time.monotonic()
        try:
            while not self._stop.is_set():
                try:
                    chunk = conn.recv(65536)
                except TimeoutError:
                    if time.monotonic() - last > self.idle_timeout_s:
                        self._count(idle_closed=1)
                        break
                    continue
                except OSError:
                    break
                if not chunk:
                    if buf:  # a frame cut off by the client's close
                        self._count(requests=1, malformed=1)
                    break
                last = time.monotonic()
                buf += chunk
                if not self._drain(conn, buf):
                    break
        finally:
            conn.close()
            with self._lock:
                self._clients.pop(threading.current_thread(), None)

    def _drain(self, conn: socket.socket, buf: bytearray) -> bool:
        """Answer every complete frame in ``buf`` (consumed); ``False`` to close the connection."""
        while len(buf) >= 4:
            body_len = int.from_bytes(buf[2:4], "big")
            if body_len > MAX_BODY_BYTES:
                self._count(requests=1, malformed=1)
                _log.debug("kvp-sim: body_len %d exceeds %d, closing", body_len, MAX_BODY_BYTES)
                return False
            if len(buf) < 4 + body_len:
                return True
            frame = bytes(buf[:4 + body_len])
            del buf[:4 + body_len]
            reply = self._answer(frame)
            if reply is None:
                continue
            if self.reply_delay_s:
                time.sleep(self.reply_delay_s)
            self._count(replies=1)  # before sending: a client holding the reply sees it counted
            try:
                conn.sendall(reply)
            except OSError:
                return False
        return True

    def _answer(self, frame: bytes) -> bytes | None:
        """Reply bytes for one frame, or ``None`` when not even its header can be answered."""
        self._count(requests=1)
        try:
            req = parse_request(frame)
        except ProtocolError as e:
            self._count(malformed=1)
            _log.debug("kvp-sim: %s", e)
            if len(frame) < 5:
                return None
            return pack_reply(int.from_bytes(frame[:2], "big"), frame[4], None, False,
                              self.count_trailer)
        if req.function not in (FN_READ, FN_WRITE):
            self._count(unsupported=1)
            return pack_reply(req.msg_id, req.function, None, False, self.count_trailer)
        value, ok = self._execute(req)
        return pack_reply(req.msg_id, req.function, value, ok, self.count_trailer)

    def _execute(self, req: KvpRequest) -> tuple[str | None, bool]:
        name = req.name.strip()
        key = name.upper()
        if req.function == FN_READ:
            if key == "PING":
                return "PONG", True
            with self._lock:
                found = next((v for k, v in self.variables.items() if k.upper() == key), None)
            return (found, found is not None)
        value = (req.value or "").strip()
        if key == OV_PRO:
            try:
                percent = int(value)
            except ValueError:
                return None, False
            if not 0 <= percent <= 100:
                return None, False
            value = str(percent)
            mode = self.override_mode
            if mode != "apply":   # a controller that does not take the override
                with self._lock:
                    if self.first_refusal_s is None:
                        self.first_refusal_s = time.monotonic()
                self._count(ov_pro_refused=1)
                return (None, False) if mode == "refuse" else (value, True)
        with self._lock:   # look up and insert at once: the bound holds with many clients
            existing = next((k for k in self.variables if k.upper() == key), None)
            full = existing is None and len(self.variables) >= MAX_VARIABLES
            if not full:
                self.variables[name if existing is None else existing] = value
        if full:
            self._count(table_full=1)
            return None, False
        if key == OV_PRO:
            self.path.set_override(percent)
            self._count(ov_pro_writes=1)
        return value, True
