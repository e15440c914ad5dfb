"""KukaVarProxy / OpenShowVar (TCP, port 7000): wire format, a blocking connection, and the
``$OV_PRO`` robot link.

Wire format (KUKA_IO.md §3.2; all integers big-endian unsigned 16-bit)::

    request  msg_id | body_len | function (u8) | name_len | name [| value_len | value]   (write only)
    reply    msg_id | body_len | function (u8) | value_len | value | 0x0001 | status (u8)

``body_len`` of a request counts the bytes after the field. Server builds disagree for replies: the
KUKAVARPROXY source counts the three trailer bytes (``1 + 2 + len(value) + 3``), the server in the
py_openshowvar README does not (``1 + 2 + len(value)``). :func:`read_reply` therefore parses
structurally — header, function, ``value_len``, value, trailer — reading exactly that many bytes, and
accepts either ``body_len``. A failed request answers status 0, with or without value bytes; status 0
means "no value". Reading the name ``PING`` returns ``PONG`` (keep-alive).

Layers:

- :func:`pack_request`, :func:`parse_request`, :func:`pack_reply`, :func:`parse_reply`: bytes ↔
  :class:`KvpRequest` / :class:`KvpReply`, raising :class:`~robot_io.links.base.ProtocolError`;
- :class:`KvpConnection`: one blocking TCP connection (``read``, ``write``, ``ping``) with socket
  timeouts, raising :class:`~robot_io.links.base.LinkError`;
- :class:`KvpClient`: the :class:`~robot_io.links.base.RobotLink` for ``$OV_PRO``. A worker thread owns
  the connection: it writes the latest requested override (latest wins), verifies it with a
  read-back, polls ``$OV_PRO`` as keep-alive, and reconnects with bounded exponential backoff. A
  write answered with status 0, or whose read-back shows another value, is counted in
  ``stats.refused`` (with the reason in ``last_error``) and not retried until another value is set.
"""

from __future__ import annotations

import logging
import select
import socket
import struct
import threading
import time
from dataclasses import dataclass

from robot_io.links.base import LinkError, LinkStats, LinkStatus, ProtocolError, StatsCounter, override_to_int

__all__ = [
    "FN_READ",
    "FN_WRITE",
    "KVP_DEFAULT_PORT",
    "MAX_BODY_BYTES",
    "OV_PRO",
    "KvpClient",
    "KvpConnection",
    "KvpReply",
    "KvpRequest",
    "pack_reply",
    "pack_request",
    "parse_reply",
    "parse_request",
    "read_reply",
]

_log = logging.getLogger(__name__)

KVP_DEFAULT_PORT = 7000
FN_READ = 0
FN_WRITE = 1
#: Array read/write as 16-bit words (known to the protocol; not used by cctmill).
FN_READ_ARRAY = 2
FN_WRITE_ARRAY = 3
OV_PRO = "$OV_PRO"

#: Largest ``body_len`` accepted [bytes]: variable names are ≤ 24 characters and a KRL value printout
#: (a FRAME, an E6POS) is a few hundred bytes; anything longer is a broken or hostile stream.
MAX_BODY_BYTES = 4096
_HEADER = struct.Struct("!HHB")  # msg_id, body_len, function
_U16 = struct.Struct("!H")
_TRAILER_TAG = b"\x00\x01"
_TRAILER_BYTES = 3
#: While idle the client looks at its socket this often, so a closed server is noticed within this
#: time rather than at the next poll [s].
_IDLE_CHECK_S = 0.02


@dataclass(frozen=True)
class KvpRequest:
    """One request: ``value`` is ``None`` for a read (function 0)."""

    msg_id: int
    function: int
    name: str
    value: str | None = None


@dataclass(frozen=True)
class KvpReply:
    """One reply.

    Attributes:
        msg_id: echo of the request's id.
        function: echo of the request's function.
        value: the variable's value as KRL prints it (for a write: the value written); ``None`` when
            ``ok`` is false.
        ok: status byte 1.
        trailer_counted: whether ``body_len`` counted the 3 trailer bytes (server build).
    """

    msg_id: int
    function: int
    value: str | None
    ok: bool
    trailer_counted: bool


def _ascii(data: bytes, what: str, size: int) -> str:
    try:
        return data.decode("ascii")
    except UnicodeDecodeError:
        raise ProtocolError("kvp", f"{what} is not ASCII", size) from None


def pack_request(req: KvpRequest) -> bytes:
    """Bytes of a read (``value`` None) or write request; raises :class:`LinkError` on bad input."""
    if not 0 <= req.msg_id <= 0xFFFF:
        raise LinkError("kvp", f"msg_id {req.msg_id} outside 0..65535")
    try:
        name = req.name.encode("ascii")
        value = None if req.value is None else req.value.encode("ascii")
    except UnicodeEncodeError:
        raise LinkError("kvp", f"variable {req.name!r} and its value must be ASCII") from None
    if not name:
        raise LinkError("kvp", "empty variable name")
    if req.function == FN_READ and value is None:
        body = bytes([FN_READ]) + _U16.pack(len(name)) + name
    elif req.function == FN_WRITE and value is not None:
        body = bytes([FN_WRITE]) + _U16.pack(len(name)) + name + _U16.pack(len(value)) + value
    else:
        raise LinkError("kvp", f"function {req.function} with value {req.value!r}: use 0 (read, no "
                               "value) or 1 (write, with value)")
    if len(body) > MAX_BODY_BYTES:
        raise LinkError("kvp", f"request body {len(body)} bytes exceeds {MAX_BODY_BYTES}")
    return _U16.pack(req.msg_id) + _U16.pack(len(body)) + body


def parse_request(frame: bytes) -> KvpRequest:
    """Parse one complete request frame (header included, exactly ``4 + body_len`` bytes).

    Raises :class:`ProtocolError` for anything but a well-formed read or write; array functions 2/3
    are parsed only as far as the name (value ``None``).
    """
    n = len(frame)
    if n < _HEADER.size + 2:
        raise ProtocolError("kvp", "shorter than header + name length", n)
    msg_id, body_len, fn = _HEADER.unpack_from(frame)
    if body_len != n - 4:
        raise ProtocolError("kvp", f"body_len {body_len} but {n - 4} bytes follow", n)
    (name_len,) = _U16.unpack_from(frame, 5)
    end = 7 + name_len
    if name_len == 0 or end > n:
        raise ProtocolError("kvp", f"name_len {name_len} does not fit", n)
    name = _ascii(frame[7:end], "variable name", n)
    if fn in (FN_READ, FN_READ_ARRAY):
        if end != n:
            raise ProtocolError("kvp", f"{n - end} stray bytes after the name of a read", n)
        return KvpRequest(msg_id, fn, name)
    if fn in (FN_WRITE, FN_WRITE_ARRAY):
        if end + 2 > n:
            raise ProtocolError("kvp", "write without value length", n)
        (value_len,) = _U16.unpack_from(frame, end)
        if end + 2 + value_len != n:
            raise ProtocolError("kvp", f"value_len {value_len} does not match the frame", n)
        value = _ascii(frame[end + 2:], "value", n)
        return KvpRequest(msg_id, fn, name, value if fn == FN_WRITE else None)
    raise ProtocolError("kvp", f"unknown function {fn}", n)


def pack_reply(msg_id: int, function: int, value: str | None, ok: bool, count_trailer: bool) -> bytes:
    """Bytes of a reply; ``value`` None writes ``value_len`` 0 (how a failed read is answered here)."""
    data = b"" if value is None else value.encode("ascii")
    body_len = 1 + 2 + len(data) + (_TRAILER_BYTES if count_trailer else 0)
    return (_U16.pack(msg_id & 0xFFFF) + _U16.pack(body_len) + bytes([function & 0xFF])
            + _U16.pack(len(data)) + data + _TRAILER_TAG + bytes([1 if ok else 0]))


def _check_reply(head: bytes, value: bytes, trailer: bytes) -> KvpReply:
    size = len(head) + len(value) + len(trailer)
    msg_id, body_len, fn = _HEADER.unpack_from(head)
    (value_len,) = _U16.unpack_from(head, 5)
    if body_len == 3 + value_len + _TRAILER_BYTES:
        counted = True
    elif body_len == 3 + value_len:
        counted = False
    else:
        raise ProtocolError("kvp", f"body_len {body_len} fits neither value_len {value_len} + 3 nor + 6",
                            size)
    if trailer[:2] != _TRAILER_TAG or trailer[2] not in (0, 1):
        raise ProtocolError("kvp", f"trailer {trailer!r} is not 00 01 00|01", size)
    ok = trailer[2] == 1
    text = _ascii(value, "value", size)
    return KvpReply(msg_id, fn, text if ok else None, ok, counted)


def parse_reply(data: bytes) -> KvpReply:
    """Parse one complete reply (exactly ``7 + value_len + 3`` bytes); raises :class:`ProtocolError`."""
    n = len(data)
    if n < 7 + _TRAILER_BYTES:
        raise ProtocolError("kvp", "shorter than the smallest reply (10 bytes)", n)
    (value_len,) = _U16.unpack_from(data, 5)
    if n != 7 + value_len + _TRAILER_BYTES:
        raise ProtocolError("kvp", f"value_len {value_len} does not match {n} bytes", n)
    return _check_reply(data[:7], data[7:7 + value_len], data[7 + value_len:])


def _recv_exact(sock: socket.socket, n: int) -> bytes:
    buf = bytearray()
    while len(buf) < n:
        chunk = sock.recv(n - len(buf))
        if not chunk:
            raise ConnectionError(f"connection closed after {len(buf)} of {n} bytes")
        buf += chunk
    return bytes(buf)


def read_reply(sock: socket.socket) -> KvpReply:
    """Read exactly one reply from a stream socket, structurally (header → value_len → value →
    trailer), whichever ``body_len`` convention the server uses.

    Raises ``OSError`` (timeouts included) for the socket and :class:`ProtocolError` for the bytes.
    """
    head = _recv_exact(sock, 7)
    (value_len,) = _U16.unpack_from(head, 5)
    if value_len > MAX_BODY_BYTES:
        raise ProtocolError("kvp", f"value_len {value_len} exceeds {MAX_BODY_BYTES}", 7)
    rest = _recv_exact(sock, value_len + _TRAILER_BYTES)
    return _check_reply(head, rest[:value_len], rest[value_len:])


class KvpConnection:
    """One blocking KukaVarProxy connection.

    Args:
        host, port: server address.
        timeout: connect and per-reply timeout [s].

    ``read``/``write`` raise :class:`LinkError` when the server refuses (status 0),
    :class:`ProtocolError` for bad bytes or a wrong ``msg_id``, and ``OSError`` for the socket; after
    any of the latter two the connection should be closed (the stream position is unknown).
    """

    def __init__(self, host: str, port: int, timeout: float = 0.5) -> None:
        self._msg_id = 0
        try:
            self._sock = socket.create_connection((host, port), timeout=timeout)
        except OSError as e:
            raise LinkError("kvp", f"cannot connect to {host}:{port}: {e}; is KukaVarProxy running "
                                   "and port 7000 open (KR C4: NAT)?") from e
        self._sock.settimeout(timeout)
        self._sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.last_reply: KvpReply | None = None

    def request(self, function: int, name: str, value: str | None = None) -> KvpReply:
        """Send one request and read its reply; raises on a wrong ``msg_id``, not on status 0."""
        self._msg_id = (self._msg_id + 1) & 0xFFFF
        self._sock.sendall(pack_request(KvpRequest(self._msg_id, function, name, value)))
        reply = read_reply(self._sock)
        if reply.msg_id != self._msg_id or reply.function != function:
            raise ProtocolError("kvp", f"reply id/function {reply.msg_id}/{reply.function} for request "
                                       f"{self._msg_id}/{function}", 10 + len(reply.value or ""))
        self.last_reply = reply
        return reply

    def read(self, name: str) -> str:
        """Value of variable ``name`` as KRL prints it."""
        reply = self.request(FN_READ, name)
        if not reply.ok or reply.value is None:
            raise LinkError("kvp", f"server could not read {name!r} (status 0); check the name "
                                   "(arrays need [], e.g. $ROBNAME[])")
        return reply.value

    def write(self, name: str, value: str) -> str:
        """Write ``value`` (KRL literal) to ``name``; returns the value the server echoed."""
        reply = self.request(FN_WRITE, name, value)
        if not reply.ok:
            raise LinkError("kvp", f"server refused {name} = {value!r} (status 0)")
        return reply.value or ""

    def check_idle(self) -> None:
        """Raise ``ConnectionError`` if the server closed the connection, :class:`ProtocolError` if it
        sent bytes nobody asked for (the stream is then out of step); return at once otherwise."""
        readable, _, _ = select.select([self._sock], [], [], 0.0)
        if not readable:
            return
        data = self._sock.recv(1, socket.MSG_PEEK)  # readable: does not block
        if not data:
            raise ConnectionError("server closed the connection")
        raise ProtocolError("kvp", "unsolicited bytes from the server", 1)

    def ping(self) -> bool:
        """Keep-alive: read ``PING``, expect ``PONG``."""
        reply = self.request(FN_READ, "PING")
        return reply.ok and reply.value == "PONG"

    def close(self) -> None:
        try:
            self._sock.close()
        except OSError:  # pragma: no cover - close of a broken socket
            pass

    def __enter__(self) -> KvpConnection:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class KvpClient:
    """``$OV_PRO`` robot link over KukaVarProxy (implements :class:`~robot_io.links.base.RobotLink`).

    Args:
        host, port: KukaVarProxy address (port 7000 on a controller).
        timeout: connect and reply timeout [s] per request.
        poll_s: period of the keep-alive read of ``$OV_PRO`` when nothing is to be written [s]
            (KukaVarProxy drops a client idle for 30 s).
        backoff_initial_s, backoff_max_s: reconnect delay [s], doubled after each failed attempt up to
            the maximum; reset after a successful connection.
        late_s: a reply slower than this counts as late [s].
        variable: the variable written (``$OV_PRO``).

    The worker thread starts at once and connects in the background; the constructor does not block
    or raise when the server is not there yet (see ``connected`` / ``stats``).
    """

    def __init__(self, host: str, port: int = KVP_DEFAULT_PORT, timeout: float = 0.2, poll_s: float = 0.5,
                 backoff_initial_s: float = 0.05, backoff_max_s: float = 2.0, late_s: float = 0.05,
                 variable: str = OV_PRO) -> None:
        if not (timeout > 0 and poll_s > 0 and 0 < backoff_initial_s <= backoff_max_s and late_s > 0):
            raise LinkError("kvp", "timeout, poll_s, late_s and 0 < backoff_initial_s <= backoff_max_s "
                                   "must be positive")
        self.host, self.port = host, int(port)
        self.timeout, self.poll_s, self.late_s = timeout, poll_s, late_s
        self.backoff_initial_s, self.backoff_max_s = backoff_initial_s, backoff_max_s
        self.variable = variable
        self._stats = StatsCounter()
        self._lock = threading.Lock()
        self._wake = threading.Condition(self._lock)
        self._wanted: int | None = None      # latest set_override value
        self._written: int | None = None     # last value written and read back on this connection
        self._refused: int | None = None     # last value the server refused (not retried)
        self._confirmed: float | None = None  # last $OV_PRO read from the controller
        self._connected = False
        self._closing = False
        self._ever_connected = False
        self._thread = threading.Thread(target=self._run, name=f"kvp-client-{host}:{port}", daemon=True)
        self._thread.start()

    # -- RobotLink -------------------------------------------------------------------------------
    def set_override(self, percent: float) -> LinkStatus:
        value = override_to_int(percent)
        if value is None:
            return LinkStatus(False, f"override {percent!r} is not a finite number; nothing sent")
        with self._wake:
            if self._closing:
                return LinkStatus(False, "link closed", None)
            self._wanted = value
            self._wake.notify_all()
            up = self._connected
        if up:
            return LinkStatus(True, "queued", value)
        return LinkStatus(False, "not connected (reconnecting); value kept and written on reconnect",
                          value)

    def read_override(self) -> float | None:
        with self._lock:
            return self._confirmed

    @property
    def stats(self) -> LinkStats:
        return self._stats.snapshot()

    @property
    def connected(self) -> bool:
        with self._lock:
            return self._connected

    def close(self) -> None:
        with self._wake:
            self._closing = True
            self._wake.notify()
        if self._thread.is_alive() and threading.current_thread() is not self._thread:
            self._thread.join(timeout=self.timeout + self.backoff_max_s + 1.0)

    def __enter__(self) -> KvpClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- helpers for scripts and tests -----------------------------------------------------------
    def flush(self, timeout: float = 1.0) -> bool:
        """Wait until the latest ``set_override`` value is written and read back; ``False`` on timeout
        or when the server refused it."""
        deadline = time.monotonic() + timeout
        with self._wake:
            while not self._closing:
                if self._wanted is None or (self._written == self._wanted
                                            and self._confirmed == float(self._wanted)):
                    return True
                left = deadline - time.monotonic()
                if left <= 0 or self._refused == self._wanted:
                    return False
                self._wake.wait(left)
        return False

    def wait_connected(self, timeout: float = 1.0) -> bool:
        """Wait until the link is up; ``False`` on timeout."""
        deadline = time.monotonic() + timeout
        with self._wake:
            while not self._connected and not self._closing:
                left = deadline - time.monotonic()
                if left <= 0:
                    return False
                self._wake.wait(left)
            return self._connected

    # -- worker ----------------------------------------------------------------------------------
    def _set_connected(self, up: bool) -> None:
        with self._wake:
            self._connected = up
            self._wake.notify_all()

    def _timed(self, conn: KvpConnection, function: int, value: str | None = None) -> KvpReply:
        t0 = time.perf_counter()
        self._stats.add(sent=1)
        reply = conn.request(function, self.variable, value)
        dt = time.perf_counter() - t0
        self._stats.add(replies=1, late=int(dt > self.late_s))
        return reply

    def _confirm(self, reply: KvpReply) -> None:
        if not reply.ok or reply.value is None:
            self._stats.add(error=f"{self.variable} read refused (status 0)")
            return
        try:
            value = float(reply.value.strip())
        except ValueError:
            self._stats.add(malformed=1, error=f"{self.variable} read back {reply.value!r}: not a number")
            return
        with self._wake:
            self._confirmed = value
            self._wake.notify_all()

    def _serve(self, conn: KvpConnection) -> None:
        """Write new values and poll until the connection fails or the link closes."""
        next_poll = 0.0
        while True:
            with self._wake:
                while True:
                    if self._closing:
                        return
                    todo = self._wanted
                    if todo is not None and todo not in (self._written, self._refused):
                        break
                    todo = None
                    left = next_poll - time.monotonic()
                    if left <= 0:
                        break
                    self._wake.wait(min(left, _IDLE_CHECK_S))
                    if self._wanted in (None, self._written, self._refused):
                        conn.check_idle()  # notice a lost server between polls
            if todo is not None:
                reply = self._timed(conn, FN_WRITE, str(todo))
                if not reply.ok:
                    with self._wake:
                        self._refused = todo
                    self._stats.add(refused=1, error=f"{self.variable} = {todo} refused (status 0)")
            reply = self._timed(conn, FN_READ)
            self._confirm(reply)
            with self._wake:
                if todo is not None and self._refused != todo:
                    if self._confirmed == float(todo):
                        self._written = todo
                    else:
                        self._refused = todo
                        self._stats.add(refused=1, error=f"{self.variable} read back {reply.value!r} "
                                                         f"after writing {todo}")
                self._wake.notify_all()
            next_poll = time.monotonic() + self.poll_s

    def _run(self) -> None:
        delay = self.backoff_initial_s
        while True:
            conn = None
            try:
                conn = KvpConnection(self.host, self.port, self.timeout)
                if self._ever_connected:
                    self._stats.add(reconnects=1)
                self._ever_connected = True
                with self._wake:
                    # A new connection writes the wanted value again (the controller may have lost it).
                    self._written = self._refused = None
                self._set_connected(True)
                delay = self.backoff_initial_s
                self._serve(conn)
            except TimeoutError as e:
                self._stats.add(timeouts=1, error=f"no reply within {self.timeout:g} s: {e}")
            except ProtocolError as e:
                self._stats.add(malformed=1, error=str(e))
            except (LinkError, OSError) as e:
                self._stats.add(error=str(e))
            except Exception as e:  # noqa: BLE001 - the link must not die on an unforeseen error
                _log.exception("kvp worker: unexpected error")
                self._stats.add(error=f"unexpected {type(e).__name__}: {e}")
            finally:
                if conn is not None:
                    conn.close()
                self._set_connected(False)
            deadline = time.monotonic() + delay
            with self._wake:
                while not self._closing and time.monotonic() < deadline:
                    self._wake.wait(deadline - time.monotonic())
                if self._closing:
                    return
            _log.debug("kvp: reconnecting to %s:%s after %.3f s", self.host, self.port, delay)
            delay = min(delay * 2.0, self.backoff_max_s)
