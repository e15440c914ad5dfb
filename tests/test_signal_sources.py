"""Signal sources: recorded-signal replay (CSV, NPY) and the UDP sample stream (wire format,
malformed / out-of-order / lost datagrams, backlog bound), over real loopback sockets."""

from __future__ import annotations

import struct
import time

import numpy as np
import pytest

from robot_io.signals.base import SignalSource
from robot_io.signals.replay import ReplaySource, SignalFileError, load_signal
from robot_io.signals.udp import (
    HEADER,
    MAGIC,
    MAX_SAMPLES,
    UdpSignalSender,
    UdpSignalSource,
    pack_samples,
    parse_samples,
)


# -- replay ------------------------------------------------------------------------------------
def test_csv_with_header_and_time_column(tmp_path):
    p = tmp_path / "s.csv"
    p.write_text("# force record\nvalue_N,t_s\n1.5,0.0\n2.5,0.001\n\n3.5,0.002\n", encoding="utf-8")
    t, v = load_signal(p)
    np.testing.assert_allclose(t, [0.0, 0.001, 0.002])
    np.testing.assert_allclose(v, [1.5, 2.5, 3.5])


def test_csv_single_column_needs_rate(tmp_path):
    p = tmp_path / "s.csv"
    p.write_text("1\n2\n3\n", encoding="utf-8")
    with pytest.raises(SignalFileError, match="fs_hz"):
        load_signal(p)
    t, v = load_signal(p, fs_hz=1000.0)
    np.testing.assert_allclose(t, [0.0, 0.001, 0.002])


@pytest.mark.parametrize("text,line,match", [
    ("t_s,f\n0,1\n0.001,x\n", 3, "field 2 'x' is not a number"),
    ("t_s,f\n0,1\n0.001,2,3\n", 3, "3 fields, expected 2"),
    ("t_s,f\n0,1\n0,2\n", 3, "does not increase"),
    ("t_s,f,g\n0,1\n", 2, "header names 3"),
])
def test_csv_errors_name_the_line(tmp_path, text, line, match):
    p = tmp_path / "bad.csv"
    p.write_text(text, encoding="utf-8")
    with pytest.raises(SignalFileError, match=match) as e:
        load_signal(p)
    assert e.value.line == line and str(e.value).startswith(f"{p}:{line}:")


def test_npy_forms_and_errors(tmp_path):
    a = tmp_path / "one.npy"
    np.save(a, np.arange(5.0))
    t, v = load_signal(a, fs_hz=100.0)
    np.testing.assert_allclose(t, np.arange(5) / 100.0)
    b = tmp_path / "two.npy"
    np.save(b, np.column_stack([np.arange(4) * 0.5, np.arange(4.0)]))
    t, v = load_signal(b)
    np.testing.assert_allclose(t, [0, 0.5, 1.0, 1.5])
    c = tmp_path / "three.npy"
    np.save(c, np.zeros((3, 3)))
    with pytest.raises(SignalFileError, match="shape"):
        load_signal(c)
    with pytest.raises(SignalFileError, match="no such file"):
        load_signal(tmp_path / "missing.csv")


def test_replay_hands_out_in_order_and_ends():
    src = ReplaySource(np.arange(10) / 10.0, np.arange(10.0))
    assert isinstance(src, SignalSource)
    c1, c2, c3 = src.read(4), src.read(4), src.read(4)
    np.testing.assert_allclose(np.concatenate([c1.values, c2.values, c3.values]), np.arange(10.0))
    assert src.read(4).status == "end"
    assert src.fs_hz == pytest.approx(10.0)


def test_replay_realtime_paces_by_the_clock():
    now = [0.0]
    src = ReplaySource(np.arange(100) / 100.0, np.arange(100.0), realtime=True, clock=lambda: now[0])
    assert len(src.read(1000)) == 1  # the first read starts the replay: the sample at t = 0
    now[0] = 0.25
    assert len(src.read(1000)) == 25
    now[0] = 10.0
    assert len(src.read(1000)) == 74 and src.read(10).status == "end"


# -- UDP ---------------------------------------------------------------------------------------
def test_wire_format_layout():
    data = pack_samples(7, 1.25, 10_000.0, np.array([1.0, -2.0]))
    assert data[:4] == MAGIC and len(data) == HEADER.size + 8 == 30
    magic, seq, t0, fs, n = struct.unpack_from("<4sIdfH", data)
    assert (seq, t0, fs, n) == (7, 1.25, 10_000.0, 2)
    assert struct.unpack_from("<2f", data, 22) == (1.0, -2.0)
    seq, t0, fs, v = parse_samples(data)
    np.testing.assert_allclose(v, [1.0, -2.0])


@pytest.mark.parametrize("mutate", [
    lambda d: b"XXXX" + d[4:],                               # magic
    lambda d: d[:-1],                                        # truncated
    lambda d: d + b"\0",                                     # trailing byte
    lambda d: d[:20] + struct.pack("<H", 0) + d[22:],        # count 0
    lambda d: d[:16] + struct.pack("<f", float("nan")) + d[20:],  # fs NaN
    lambda d: d[:16] + struct.pack("<f", -1.0) + d[20:],     # fs negative
    lambda d: d[:8] + struct.pack("<d", float("inf")) + d[16:],  # t0 inf
    lambda d: b"",
])
def test_malformed_datagrams_are_rejected(mutate):
    assert parse_samples(mutate(pack_samples(0, 0.0, 1000.0, np.ones(3)))) is None


def _drain(src: UdpSignalSource, want: int, timeout_s: float = 2.0):
    got_t, got_v = [], []
    deadline = time.monotonic() + timeout_s
    n = 0
    while n < want and time.monotonic() < deadline:
        c = src.read(100_000)
        got_t.append(c.t_s)
        got_v.append(c.values)
        n += len(c)
        if not len(c):
            time.sleep(0.001)
    return np.concatenate(got_t), np.concatenate(got_v)


def test_udp_stream_carries_timestamps_and_counts_problems():
    with UdpSignalSource() as src:
        assert src.address[0] == "127.0.0.1"
        tx = UdpSignalSender(*src.address)
        try:
            tx.send(10.0, 1000.0, np.arange(5.0))            # seq 0
            tx.send_raw(b"garbage")                          # malformed
            tx.seq = 3                                       # seq 1, 2 lost
            tx.send(10.010, 1000.0, np.arange(5.0, 8.0))     # seq 3
            tx.send_raw(pack_samples(2, 10.0, 1000.0, np.ones(2)))  # late: out of order
            t, v = _drain(src, 8)
        finally:
            tx.close()
        np.testing.assert_allclose(v, [0, 1, 2, 3, 4, 5, 6, 7])
        np.testing.assert_allclose(t, [10.0, 10.001, 10.002, 10.003, 10.004, 10.010, 10.011, 10.012])
        time.sleep(0.01)
        src.read(10)
        s = src.stats
        assert (s.malformed, s.lost, s.out_of_order, s.packets, s.samples) == (1, 2, 1, 2, 8)
        assert src.fs_hz == 1000.0


def test_udp_sender_restart_resynchronises():
    with UdpSignalSource() as src:
        tx = UdpSignalSender(*src.address)
        for i in range(100):
            tx.send(i * 0.001, 1000.0, np.ones(1))
        _drain(src, 100)
        tx.send_raw(pack_samples(60, 9.0, 1000.0, np.ones(1)))   # 39 behind: late, dropped
        tx.seq = 0                                                 # the DAQ restarted
        for i in range(5):
            tx.send(i * 0.001, 1000.0, np.full(1, 2.0))
        tx.close()
        t, v = _drain(src, 5)
        np.testing.assert_allclose(v, 2.0)
        # its clock restarted too: re-based to go on one period after the last sample (0.099 s)
        np.testing.assert_allclose(t, 0.100 + np.arange(5) * 0.001)
        s = src.stats
        assert (s.out_of_order, s.resyncs, s.rebases, s.lost) == (1, 1, 1, 0)


def test_udp_large_block_is_split_and_reassembled():
    with UdpSignalSource() as src:
        tx = UdpSignalSender(*src.address)
        x = np.arange(MAX_SAMPLES * 2 + 10, dtype=float)
        tx.send(0.0, 10_000.0, x)
        tx.close()
        t, v = _drain(src, x.size)
        np.testing.assert_allclose(v, x)
        np.testing.assert_allclose(np.diff(t), 1e-4, rtol=1e-9)
        assert src.stats.lost == 0


def test_udp_silence_reports_no_data_and_close_reports_error():
    now = [0.0]
    src = UdpSignalSource(silence_s=0.1, clock=lambda: now[0])
    assert src.read(10).status == "ok"
    now[0] = 0.5
    assert src.read(10).status == "no_data"
    src.close()
    assert src.read(10).status == "error"
    src.close()  # idempotent
