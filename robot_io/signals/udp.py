"""A force/strain sample stream over UDP: the wire format, a receiving source and a sender.

Datagram layout (little-endian, no padding; one datagram = one block of consecutive samples)::

    offset  size  field
    0       4     magic   b"CCTS"
    4       4     seq     u32, +1 per datagram (wraps at 2**32)
    8       8     t0_s    f64, timestamp of the first sample [s] on the sender's clock
    16      4     fs_hz   f32, sample rate [Hz] (> 0, finite)
    20      2     count   u16, samples in this datagram (1 .. MAX_SAMPLES)
    22      4*n   values  f32 × count

Sample ``i`` has timestamp ``t0_s + i / fs_hz``. A datagram whose size differs from
``22 + 4 * count``, with a wrong magic, a count of 0 or over :data:`MAX_SAMPLES`, or a non-finite or
non-positive ``fs_hz`` or ``t0_s`` is *malformed*: dropped and counted. Sequence numbers are compared
modulo 2**32: a datagram older than the newest seen is *out of order* (dropped, counted); a jump
forward of at most :data:`MAX_LOSS_GAP` counts the skipped numbers as *lost*; one more than
:data:`REORDER_WINDOW` behind, or more than :data:`MAX_LOSS_GAP` ahead, means the sender restarted:
the stream resynchronises on it (counted in ``resyncs``, nothing counted as lost). Sample values are
passed on as received (a NaN is the consumer's to judge).

Timestamps are the sender's and increase strictly over the whole stream, as :class:`SignalChunk`
promises. A restarted sender whose clock starts again at or before the last sample handed on is
*re-based*: its timestamps are shifted so that its first sample comes one sample period after the
last one (counted in ``rebases``; the shift stays until the next restart). Without a restart,
samples whose timestamp is not after the previous sample's (a repeated or overlapping block) are
dropped and counted in ``backward_samples``.

The receiver binds 127.0.0.1 unless told otherwise, never blocks (a read drains at most
:data:`MAX_DATAGRAMS_PER_READ` datagrams) and never raises.
"""

from __future__ import annotations

import math
import socket
import struct
import time
from collections.abc import Callable

import numpy as np

from robot_io.signals.base import Backlog, SignalChunk, SourceStats, empty_chunk

__all__ = [
    "HEADER",
    "MAGIC",
    "MAX_LOSS_GAP",
    "MAX_SAMPLES",
    "REORDER_WINDOW",
    "UdpSignalSender",
    "UdpSignalSource",
    "pack_samples",
    "parse_samples",
]

MAGIC = b"CCTS"
HEADER = struct.Struct("<4sIdfH")
#: Largest sample count of one datagram (16 KiB of samples; well under the 65,507-byte UDP limit).
MAX_SAMPLES = 4096
#: Datagrams one ``read`` drains at most, so a flood cannot stall the supervisor's step.
MAX_DATAGRAMS_PER_READ = 256
#: A datagram at most this many sequence numbers behind the newest is late (dropped); further
#: behind, the sender is taken to have restarted and the stream resynchronises on it.
REORDER_WINDOW = 64
#: A datagram more than this many sequence numbers ahead of the expected one means the sender
#: restarted (or the numbers are garbage), not that the datagrams between were lost: at a brisk
#: 1,000 datagrams/s it is over a minute of silence, which the source reports as ``no_data`` long
#: before; counted as loss, one such datagram added up to 2**31 to ``lost``.
MAX_LOSS_GAP = 65_536
#: Samples held for a consumer that reads less than arrives; older ones are dropped and counted.
BACKLOG_SAMPLES = 65536
_SEQ_MOD = 1 << 32


def pack_samples(seq: int, t0_s: float, fs_hz: float, values: np.ndarray) -> bytes:
    """One datagram of ``values`` (shape (n,), 1 ≤ n ≤ MAX_SAMPLES) starting at ``t0_s`` [s]."""
    v = np.asarray(values, dtype="<f4").ravel()
    if not 1 <= v.size <= MAX_SAMPLES:
        raise ValueError(f"count {v.size} outside 1..{MAX_SAMPLES}")
    return HEADER.pack(MAGIC, seq % _SEQ_MOD, float(t0_s), float(fs_hz), v.size) + v.tobytes()


def parse_samples(data: bytes) -> tuple[int, float, float, np.ndarray] | None:
    """(seq, t0_s, fs_hz, values float64) of a datagram, or ``None`` when it is malformed."""
    if len(data) < HEADER.size:
        return None
    magic, seq, t0, fs, count = HEADER.unpack_from(data)
    if (magic != MAGIC or not 1 <= count <= MAX_SAMPLES or len(data) != HEADER.size + 4 * count
            or not (math.isfinite(fs) and fs > 0) or not math.isfinite(t0)):
        return None
    with np.errstate(invalid="ignore"):  # a signalling NaN stays a NaN: the supervisor refuses it
        values = np.frombuffer(data, dtype="<f4", count=count, offset=HEADER.size).astype(float)
    return seq, t0, fs, values


class UdpSignalSource:
    """Receives sample datagrams on ``(bind_host, port)`` (port 0: an ephemeral port, see ``address``).

    Args:
        bind_host: address to bind (default loopback only).
        port: UDP port.
        silence_s: after this long without a valid datagram the chunk status is ``no_data``.
        clock: monotonic clock [s] (default ``time.monotonic``).
    """

    def __init__(self, bind_host: str = "127.0.0.1", port: int = 0, silence_s: float = 0.1,
                 clock: Callable[[], float] | None = None) -> None:
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 20)
        self._sock.bind((bind_host, port))
        self._sock.setblocking(False)
        self.address: tuple[str, int] = self._sock.getsockname()
        self.fs_hz = 0.0
        self.stats = SourceStats()
        self._silence_s = silence_s
        self._clock = clock or time.monotonic
        self._last_rx = self._clock()
        self._next_seq: int | None = None
        self._last_t = -math.inf   # timestamp of the last sample kept [s]
        self._offset = 0.0         # shift of the sender's clock since its last restart [s]
        self._backlog = Backlog(BACKLOG_SAMPLES)
        self._closed = False

    def _accept(self, data: bytes) -> None:
        parsed = parse_samples(data)
        if parsed is None:
            self.stats.malformed += 1
            self.stats.last_error = f"malformed datagram ({len(data)} bytes)"
            return
        seq, t0, fs, values = parsed
        restarted = False
        if self._next_seq is not None:
            ahead = (seq - self._next_seq) % _SEQ_MOD
            behind = (self._next_seq - seq) % _SEQ_MOD
            if ahead >= _SEQ_MOD // 2 and behind <= REORDER_WINDOW:
                self.stats.out_of_order += 1
                return
            if ahead > MAX_LOSS_GAP:  # far behind or far ahead: the sender restarted its sequence
                restarted = True
                self.stats.resyncs += 1
                self.stats.last_error = (f"sender restarted (seq {seq} after "
                                         f"{(self._next_seq - 1) % _SEQ_MOD})")
            else:
                self.stats.lost += ahead
        self._next_seq = (seq + 1) % _SEQ_MOD
        self.stats.packets += 1
        self.fs_hz = float(fs)
        self._last_rx = self._clock()
        t = self._times(t0, fs, values.shape[0], restarted)
        keep = t > np.maximum.accumulate(np.concatenate(([self._last_t], t[:-1])))
        if not keep.all():
            self.stats.backward_samples += int(keep.size - np.count_nonzero(keep))
            t, values = t[keep], values[keep]
        if t.size:
            self._last_t = float(t[-1])
            self.stats.overflow += self._backlog.push(t, values)

    def _times(self, t0: float, fs: float, n: int, restarted: bool) -> np.ndarray:
        """Timestamps [s] of a datagram's ``n`` samples; after a restart whose clock went back to
        or before the last sample, re-based to go on one period after it."""
        if restarted:
            self._offset = 0.0
            if t0 <= self._last_t:
                self._offset = self._last_t + 1.0 / fs - t0
                self.stats.rebases += 1
        t = (t0 + self._offset) + np.arange(n) / fs
        t[~np.isfinite(t)] = -math.inf   # an overflowing end is dropped as not increasing
        return t

    def read(self, max_samples: int) -> SignalChunk:
        if self._closed:
            return empty_chunk("error")
        try:
            for _ in range(MAX_DATAGRAMS_PER_READ):
                try:
                    data = self._sock.recv(65536)
                except (BlockingIOError, InterruptedError):
                    break
                self._accept(data)
        except OSError as e:
            self.stats.last_error = f"socket error: {e}"
            return empty_chunk("error")
        t, v = self._backlog.pop(int(max_samples))
        self.stats.samples += v.shape[0]
        if v.shape[0] == 0 and self._clock() - self._last_rx > self._silence_s:
            return empty_chunk("no_data")
        return SignalChunk(t, v, "ok")

    def close(self) -> None:
        if not self._closed:
            self._closed = True
            self._sock.close()

    def __enter__(self) -> UdpSignalSource:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class UdpSignalSender:
    """Sends sample blocks to ``(host, port)`` in the format above (a DAQ stand-in, used by the sim)."""

    def __init__(self, host: str, port: int) -> None:
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._addr = (host, port)
        self.seq = 0

    def send(self, t0_s: float, fs_hz: float, values: np.ndarray) -> None:
        """Send ``values`` (split into datagrams of at most MAX_SAMPLES); ignores send errors."""
        v = np.asarray(values, dtype=float).ravel()
        for start in range(0, v.size, MAX_SAMPLES):
            part = v[start:start + MAX_SAMPLES]
            try:
                self._sock.sendto(pack_samples(self.seq, t0_s + start / fs_hz, fs_hz, part), self._addr)
            except OSError:
                pass
            self.seq = (self.seq + 1) % _SEQ_MOD

    def send_raw(self, data: bytes) -> None:
        """Send arbitrary bytes (tests: malformed datagrams)."""
        try:
            self._sock.sendto(data, self._addr)
        except OSError:
            pass

    def close(self) -> None:
        self._sock.close()
