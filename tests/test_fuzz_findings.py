"""Regression tests of the fuzzing findings of issue 22, each in the form of its input.

1. A KRL ``LIN`` literal of many signed components made the reader's line regex backtrack 2**n ways
   (24 components: 29 s). 2. ``G81 … L10000`` blocks multiplied a 2.7 kB program into 3 million
   moves. 3. An RSI reply declaring an unknown XML encoding leaked ``LookupError`` and killed the
   simulated controller's thread while its status said ``running``. 4. APT took coordinates up to
   1e308 mm (``length_m = inf``). 5. One UDP sample datagram far ahead added ~2**31 to ``lost``, a
   restarted sender's timestamps went back, and the simulated KVP server's table grew without end.
6. Recorded signal files (``make fuzz``, target ``signal``): an empty ``.npy`` leaked ``EOFError``, an
   ``.npz`` under a ``.npy`` name ``AttributeError`` (and a damaged one ``BadZipFile`` and an open
   file), a header declaring 10**11 samples ``MemoryError``, a header numpy tokenises
   ``TokenError``; a CSV field over 128 KiB leaked ``csv.Error``; a sample rate of 5e-324 Hz gave
   infinite times (an overflow warning). 7. An endless G-code o-word loop took 1.5-9 s to be refused
   and the flow limit allowed far more (``make fuzz``, target ``gcode``): now a budget of lines
   read again through loops and calls bounds a reading to well under a second.

The timing guards are generous hang detectors (the fixed code takes milliseconds); the assertions
are on the results. Sockets are loopback only.
"""

from __future__ import annotations

import io
import logging
import math
import re
import socket
import struct
import subprocess
import sys
import threading
import time

import numpy as np
import pytest
from _threads import no_leaked_threads, wait_for  # noqa: F401  (autouse fixture)

from robot_io.apt.reader import MAX_NUMBER_VALUE, read_apt_text
from robot_io.gcode import _words as gcode_words
from robot_io.gcode.reader import MAX_CYCLE_REPEATS, read_gcode_text
from robot_io.krl._syntax import fast_data, fast_motion
from robot_io.krl.reader import read_krl, read_krl_text
from robot_io.links import rsi_sim
from robot_io.links.base import LinkError, ProtocolError
from robot_io.links.kvp import FN_READ, FN_WRITE, KvpRequest, pack_request, read_reply
from robot_io.links.kvp_sim import MAX_VARIABLES, KvpSimServer
from robot_io.links.rsi import RsiServer, build_rob, build_sen, parse_rob, parse_sen
from robot_io.links.rsi_sim import RsiSimController
from robot_io.signals.replay import SignalFileError, load_signal
from robot_io.signals.udp import MAX_LOSS_GAP, UdpSignalSender, UdpSignalSource, pack_samples
from robot_io.toolpath import ToolpathError, summarize

#: A run that should take milliseconds but is allowed this much [s] on a loaded CI box before it
#: counts as the old exponential/unbounded behaviour (which took 6–30 s and more).
HANG_S = 2.0
WAIT_S = 3.0
PRE = "DEF fuzz( )\n$VEL.CP = 0.001\nPTP {X 0,Y 0,Z 10,A 0,B 90,C 0}\n"


def _timed(fn, *args, **kwargs):
    t = time.perf_counter()
    try:
        out = fn(*args, **kwargs)
    except ToolpathError as e:
        out = e
    elapsed = time.perf_counter() - t
    assert elapsed < HANG_S, f"took {elapsed:.1f} s: regex backtracking or an unbounded loop"
    return out


# -- 1. KRL: linear-time literal regexes ------------------------------------------------------------

#: tail after the signed components → (the error, what its column points at). "junk" fails only at
#: the very end: the old hang.
_KRL_TAILS = {
    "closed": ("}", "component A is given twice", lambda line: line.index("A", line.index("A") + 1)),
    "junk": (" ?}", "unexpected character '\\?'", lambda line: line.index("?")),
    "open": ("", "unbalanced '\\{'", lambda line: line.index("{")),
}


@pytest.mark.parametrize("n", [40, 4000])
@pytest.mark.parametrize("tail", sorted(_KRL_TAILS))
def test_krl_lin_literal_of_many_signed_components_reads_in_linear_time(tmp_path, n, tail):
    end, match, at = _KRL_TAILS[tail]
    line = "LIN {X 1" + ", A -1" * n + end
    src = tmp_path / "fuzz.src"
    src.write_text(PRE + line + "\nLIN {X 1,Y -1,Z -2,A 0,B 90,C 0}\nEND\n", encoding="ascii")
    err = _timed(read_krl, src)
    assert isinstance(err, ToolpathError) and re.search(match, err.reason)
    assert (err.file, err.line, err.column) == (str(src), 4, at(line) + 1)
    assert _timed(fast_motion, line) is None
    tp = _timed(read_krl, src, strict=False)   # lenient: the line skipped, the next one read
    assert tp.skipped["syntax"] == 1 and len(tp.moves) == 2
    np.testing.assert_allclose(tp.moves[-1].end, [1e-3, -1e-3, -2e-3])


@pytest.mark.parametrize("n", [40, 4000])
@pytest.mark.parametrize("tail", sorted(_KRL_TAILS))
def test_krl_dat_literal_of_many_signed_components_reads_in_linear_time(n, tail):
    end, match, at = _KRL_TAILS[tail]
    line = "DECL E6POS P1={X 1" + ", A -1" * n + end
    err = _timed(read_krl_text, PRE + "LIN P1\nEND\n", "DEFDAT fuzz\n" + line + "\nENDDAT\n",
                 file="fuzz.src")
    assert isinstance(err, ToolpathError) and re.search(match, err.reason)
    assert (err.file, err.line, err.column) == ("fuzz.dat", 2, at(line) + 1)
    assert _timed(fast_data, line) is None


def test_krl_fast_paths_cannot_hang_the_suite():
    """The same lines in a child process that is killed after a while: an exponential regex fails
    this test (2**40 steps) instead of hanging the run, as the in-process checks above would."""
    code = ("from robot_io.krl._syntax import fast_data, fast_motion\n"
            "tail = ', A -1' * 40 + ' ?}'\n"
            "assert fast_motion('LIN {X 1' + tail) is None\n"
            "assert fast_data('DECL E6POS P1={X 1' + tail) is None\n")
    subprocess.run([sys.executable, "-c", code], check=True, timeout=5 * HANG_S)


@pytest.mark.parametrize("sep", ["", " ", "  ", "\t", " \t "])
def test_krl_fast_paths_still_read_every_separator(sep):
    """Blanks, or nothing before a sign, between a component and its value (``X-1``, ``X -1``)."""
    body = f"X{sep}-1.5,Y{sep}+2,Z {sep}3,A{sep}-.5,B{sep}-1E1,C{sep}+0"
    want = {"X": -1.5, "Y": 2.0, "Z": 3.0, "A": -0.5, "B": -10.0, "C": 0.0}
    assert fast_motion(f"  LIN {{{body}}} C_DIS  ") == ("LIN", want, 7, "C_DIS")
    assert fast_data(f"P1[ 2 ] = {{E6POS: {body}}}") == (None, False, "P1", 2, want, 11, "E6POS")
    assert fast_motion(f"LIN {{X{sep}1Y 2}}") is None   # a missing comma is no literal
    tp = read_krl_text(PRE + f"LIN {{{body}}}\nEND\n")
    np.testing.assert_allclose(tp.moves[-1].end, [-1.5e-3, 2e-3, 3e-3])


# -- 2. G-code: repeats and moves bounded ------------------------------------------------------------

def _cycles(blocks: int) -> str:
    """The finding's form: a few bytes of G81 … L10000 blocks, each 30,000 moves."""
    return "G21 G90 G0 X0 Y0 Z5 F100\n" + "G91 G81 X0.01 Z-1 R1 L10000\n" * blocks + "M30\n"


def test_gcode_cycle_repeats_are_capped_in_all():
    text = _cycles(100)
    assert len(text) < 3000
    err = _timed(read_gcode_text, text, file="fuzz.nc")
    first_over = MAX_CYCLE_REPEATS // 9999 + 1   # the blocks whose repeats fit, then this one
    assert isinstance(err, ToolpathError)
    assert (err.file, err.line, err.column) == ("fuzz.nc", first_over + 1, 9)
    assert f"more than {MAX_CYCLE_REPEATS:,} (MAX_CYCLE_REPEATS)" in err.reason
    assert "program the holes as moves or split the program" in err.reason


def test_gcode_cycle_repeats_in_an_oword_loop_count_too(monkeypatch):
    monkeypatch.setattr(gcode_words, "MAX_CYCLE_REPEATS", 3 * 99)
    text = ("G21 G90 G0 X0 Y0 Z5 F100\no100 repeat [1000]\nG91 G81 X0.01 Z-1 R1 L100\n"
            "o100 endrepeat\nM30\n")
    with pytest.raises(ToolpathError, match=r":3:9: G81 L100 makes the L repeats .* more than 297"):
        read_gcode_text(text)
    tp = read_gcode_text(text, strict=False)   # lenient: the blocks over the limit are skipped
    assert tp.skipped["canned_cycle"] == 1000 - 3
    three = read_gcode_text(text.replace("[1000]", "[3]"))
    np.testing.assert_array_equal(tp.moves.ends, three.moves.ends)


@pytest.mark.parametrize("strict", [True, False])
@pytest.mark.parametrize("form", ["oword", "plain"])
def test_gcode_moves_are_capped_overall(monkeypatch, strict, form):
    """Past MAX_MOVES the reading stops with the line that went over, in lenient mode too."""
    monkeypatch.setattr(gcode_words, "MAX_MOVES", 1000)
    if form == "oword":   # a loop multiplies two lines into 4000 moves
        text = ("G21 G90 G0 X0 Y0 Z5 F100\n#1=0\no100 while [#1 LT 2000]\nG1 X[#1] Y1\n"
                "G1 X[#1] Y0\n#1=[#1+1]\no100 endwhile\nM30\n")
        where = (5, 4)      # move 1001: the G0, then 500 rounds of lines 4 and 5
    else:                 # 1500 plain lines, read in bulk
        text = "G21 G90 G0 X0 Y0 Z5 F100\n" + "".join(f"G1 X{i} Y1\n" for i in range(1500))
        where = (1001, 4)
    with pytest.raises(ToolpathError, match="more than 1,000 moves") as e:
        read_gcode_text(text, file="fuzz.nc", strict=strict)
    assert (e.value.line, e.value.column) == where
    assert "split it into smaller programs" in e.value.reason


# -- 3. RSI: unknown XML encoding ---------------------------------------------------------------------

_DECL = b'<?xml version="1.0" encoding="%s"?>'


@pytest.mark.parametrize("encoding", [b"UTF-1", b"rot13", b"hex", b"x" * 200])
def test_rsi_unknown_xml_encoding_is_a_protocol_error(encoding):
    with pytest.raises(ProtocolError, match="unknown XML encoding"):
        parse_rob(_DECL % encoding + build_rob(1000, (0,) * 6, (0,) * 6, 0, 100.0))
    with pytest.raises(ProtocolError, match="unknown XML encoding"):
        parse_sen(_DECL % encoding + build_sen("1000", 50))


def test_rsi_server_drops_and_counts_a_telegram_in_an_unknown_encoding():
    rob = build_rob(1000, (1.0,) * 6, (0.0,) * 6, 0, 100.0)
    with RsiServer() as srv, socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.settimeout(WAIT_S)
        s.sendto(rob, srv.address)
        assert parse_sen(s.recv(4096)).ipoc == 1000
        s.sendto(_DECL % b"UTF-1" + rob, srv.address)
        assert wait_for(lambda: srv.stats.malformed == 1)
        assert "unknown XML encoding" in srv.stats.last_error   # not an "unexpected" error
        s.sendto(rob.replace(b"1000", b"1004"), srv.address)   # still serving
        assert parse_sen(s.recv(4096)).ipoc == 1004


class _OddServer:
    """A raw UDP peer answering each ``<Rob>`` with ``answer(k, rob)`` (k counts from 1)."""

    def __init__(self, answer):
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(0.02)
        self.address = self.sock.getsockname()
        self.answer = answer
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._run)

    def _run(self):
        k = 0
        while not self.stop.is_set():
            try:
                data, addr = self.sock.recvfrom(65536)
            except TimeoutError:
                continue
            k += 1
            self.sock.sendto(self.answer(k, parse_rob(data)), addr)

    def __enter__(self):
        self.thread.start()
        return self

    def __exit__(self, *exc):
        self.stop.set()
        self.thread.join()
        self.sock.close()


def test_rsi_sim_survives_replies_in_an_unknown_encoding():
    def answer(k, rob):
        sen = build_sen(rob.ipoc_text, 50)
        return _DECL % b"UTF-1" + sen if k in (3, 7) else sen

    with _OddServer(answer) as odd, \
            RsiSimController(odd.address, max_cycles=20, timeout_packets=100) as sim:
        assert sim.wait(WAIT_S)
        assert sim.status == "done"
    st = sim.stats
    # the two replies it cannot read count as late; on a loaded machine another may be late too
    assert (st.cycles, st.malformed) == (20, 2) and st.replies + st.late == 20 and st.late >= 2


def test_rsi_sim_status_says_when_its_thread_died(monkeypatch, caplog):
    def broken(*args, **kwargs):
        raise RuntimeError("a bug in the reply parser")

    monkeypatch.setattr(rsi_sim, "parse_sen", broken)
    with caplog.at_level(logging.CRITICAL, logger="robot_io.links.rsi_sim"), \
            _OddServer(lambda k, rob: build_sen(rob.ipoc_text, 50)) as odd, \
            RsiSimController(odd.address, max_cycles=20, timeout_packets=100) as sim:
        assert sim.wait(WAIT_S)
        assert sim.status == "error"
    assert sim.status == "error"   # stop() does not turn it into "stopped"


# -- 4. APT: one magnitude limit ------------------------------------------------------------------------

_APT = "UNITS/MM\nFEDRAT/100,MMPM\nGOTO/0,0,0\n{}\nGOTO/1,0,0\nFINI\n"


@pytest.mark.parametrize("record, col", [
    ("GOTO/1e308,0,0", 6),
    ("GOTO/0,-1e308,0", 8),
    ("GOTO/0,0,1234567890123456789012345678901234567890", 10),   # 40 digits, no exponent
    ("GOTO/0,0,0,1E10,0,1", 12),
    ("FEDRAT/1e300,MMPM", 8),
    ("CIRCLE/0,0,0,0,0,1,2e9", 20),
])
def test_apt_numbers_beyond_the_limit_are_refused_or_skipped(record, col):
    text = _APT.format(record)
    with pytest.raises(ToolpathError, match=rf"<string>:4:{col}: .*out of range \(\|value\| <= 1e\+09\)"):
        read_apt_text(text)
    tp = read_apt_text(text, strict=False)
    assert tp.skipped["malformed_record"] == 1
    s = summarize(tp)
    assert math.isfinite(s["length_m"]) and s["length_m"] == pytest.approx(1e-3)


def test_apt_numbers_at_the_limit_are_read():
    tp = read_apt_text(_APT.format(f"GOTO/{MAX_NUMBER_VALUE:.0f},0,-{MAX_NUMBER_VALUE:.0f}"))
    np.testing.assert_allclose(tp.moves[1].end, [1e6, 0, -1e6])


# -- 5. UDP signal stream and the simulated KVP table ----------------------------------------------------

def _read_all(src: UdpSignalSource, datagrams: int) -> list:
    """Chunks read until ``datagrams`` have arrived (each read one chunk)."""
    chunks = []
    assert wait_for(lambda: (chunks.append(src.read(1000)) or
                             src.stats.packets + src.stats.out_of_order >= datagrams))
    chunks.append(src.read(1000))
    return [c for c in chunks if len(c)]


def test_udp_sequence_jump_far_ahead_is_a_restart_not_loss():
    with UdpSignalSource() as src:
        tx = UdpSignalSender(*src.address)
        for seq in range(5):
            tx.send_raw(pack_samples(seq, 10 + seq * 1e-3, 1000.0, np.ones(1)))
        tx.send_raw(pack_samples(5 + 2**31 - 1, 10.005, 1000.0, np.ones(1)))   # the finding
        seq = 2**31 + 4 + 1 + MAX_LOSS_GAP        # at the window: that many lost
        tx.send_raw(pack_samples(seq, 10.006, 1000.0, np.ones(1)))
        tx.send_raw(pack_samples(seq + 2 + MAX_LOSS_GAP, 10.007, 1000.0, np.ones(1)))  # past it
        tx.close()
        _read_all(src, 8)
    s = src.stats
    assert (s.packets, s.resyncs, s.lost, s.rebases) == (8, 2, MAX_LOSS_GAP, 0)


def test_udp_timestamps_keep_increasing_over_a_sender_restart():
    """Seq far behind (a restart, clock back to 0), far ahead (clock back again), a repeated and an
    overlapping datagram: every chunk increases and carries on from the one before."""
    with UdpSignalSource() as src:
        tx = UdpSignalSender(*src.address)
        for seq in range(100):
            tx.send_raw(pack_samples(seq, 5.0 + seq * 2e-3, 1000.0, np.ones(2)))
        tx.send_raw(pack_samples(0, 0.0, 1000.0, np.full(3, 2.0)))            # restart: re-based
        tx.send_raw(pack_samples(1, 0.003, 1000.0, np.full(2, 3.0)))          # goes on from there
        tx.send_raw(pack_samples(1 + 10**6, 0.0, 1000.0, np.full(2, 4.0)))    # restart again
        tx.send_raw(pack_samples(2 + 10**6, 0.0, 1000.0, np.full(2, 5.0)))    # repeated: dropped
        tx.send_raw(pack_samples(3 + 10**6, 0.001, 1000.0, np.full(3, 6.0)))  # overlaps by one
        tx.close()
        chunks = _read_all(src, 105)
    t = np.concatenate([c.t_s for c in chunks])
    v = np.concatenate([c.values for c in chunks])
    assert all(np.all(np.diff(c.t_s) > 0) for c in chunks)
    np.testing.assert_allclose(np.diff(t), 1e-3, atol=1e-9)   # one period everywhere
    assert t[0] == 5.0 and t.size == 200 + 3 + 2 + 2 + 2
    np.testing.assert_array_equal(v[200:], [2, 2, 2, 3, 3, 4, 4, 6, 6])
    s = src.stats
    assert (s.resyncs, s.rebases, s.backward_samples, s.lost) == (2, 2, 3, 0)


def _write_all(sock: socket.socket, names: list[str]) -> list[bool]:
    oks = []
    for k in range(0, len(names), 256):   # pipelined in batches the socket buffers hold
        part = names[k:k + 256]
        sock.sendall(b"".join(pack_request(KvpRequest(i, FN_WRITE, n, "1")) for i, n in
                              enumerate(part)))
        oks += [read_reply(sock).ok for _ in part]
    return oks


def test_kvp_sim_variable_table_is_bounded():
    with KvpSimServer() as srv, socket.create_connection(srv.address, timeout=WAIT_S) as s:
        room = MAX_VARIABLES - len(srv.variables)
        oks = _write_all(s, [f"$FUZZ_{i}" for i in range(room + 100)])
        assert oks == [True] * room + [False] * 100
        assert len(srv.variables) == MAX_VARIABLES and srv.stats.table_full == 100
        assert _write_all(s, ["$OV_PRO", "$fuzz_0"]) == [True, True]   # known names still written
        s.sendall(pack_request(KvpRequest(1, FN_READ, f"$FUZZ_{room}")))
        assert not read_reply(s).ok                                      # the refused name: unknown
        assert srv.override_percent == 1.0
    with pytest.raises(LinkError, match="MAX_VARIABLES"):
        KvpSimServer(variables={f"V{i}": "0" for i in range(MAX_VARIABLES + 1)})


# -- 6. Recorded signal files: every unusable file is a SignalFileError -----------------------------------

def _npy(header: bytes, data: bytes = b"", version: bytes = b"\x01\x00") -> bytes:
    """A ``.npy`` file of this header text (padded and ended as numpy writes it) and data."""
    pad = 64 - (10 + len(header) + 1) % 64
    text = header + b" " * pad + b"\n"
    return b"\x93NUMPY" + version + struct.pack("<H", len(text)) + text + data


def _npz() -> bytes:
    buf = io.BytesIO()
    np.savez(buf, t=np.arange(3.0))
    return buf.getvalue()


_HEADER = b"{'descr': '<f8', 'fortran_order': False, 'shape': %s, }"


@pytest.mark.parametrize("name, content, match", [
    ("empty.npy", b"", r"not a readable \.npy array \(No data left in file\)"),
    ("archive.npy", _npz(), r"an \.npz archive of arrays, not one array"),
    ("damaged_archive.npy", b"PK\x03\x04" + b"\x00" * 40, r"an \.npz archive of arrays"),
    ("huge_header.npy", _npy(_HEADER % b"(100000000000,)", np.ones(3).tobytes()),
     r"not a readable \.npy array \(mmap length is greater than file size\)"),
    ("unterminated_header.npy", _npy(_HEADER.replace(b" }", b" '''}") % b"(3,)", np.ones(3).tobytes()),
     r"not a readable \.npy array \(\('EOF in multi-line"),
    ("complex.npy", _npy(_HEADER.replace(b"<f8", b"<c16") % b"(3,)", np.ones(6).tobytes()),
     r"dtype complex128 is not real numbers"),
    ("long_field.csv", b"t_s,force_N\n0," + b"1" * 140_000 + b"\n1,2\n",
     r":2: not readable as CSV \(field larger than field limit"),
])
def test_an_unusable_signal_file_is_a_signal_file_error(tmp_path, recwarn, name, content, match):
    path = tmp_path / name
    path.write_bytes(content)
    with pytest.raises(SignalFileError, match=match) as e:
        load_signal(path, fs_hz=1000.0)
    assert e.value.file == str(path)
    assert not recwarn.list     # no file left open (a ResourceWarning), no numpy warning


def test_a_huge_header_is_refused_without_allocating_it(tmp_path):
    path = tmp_path / "huge.npy"
    path.write_bytes(_npy(_HEADER % b"(100000000000,)", np.ones(3).tobytes()))
    code = (f"import resource; from robot_io.signals.replay import load_signal, SignalFileError\n"
            f"resource.setrlimit(resource.RLIMIT_DATA, (2**31, resource.RLIM_INFINITY))\n"
            f"try: load_signal({str(path)!r}, fs_hz=1000.0)\nexcept SignalFileError: pass\n")
    subprocess.run([sys.executable, "-c", code], check=True, timeout=60)   # MemoryError: exit 1


def test_a_sample_rate_too_small_for_finite_times_is_refused(tmp_path):
    path = tmp_path / "one_column.csv"
    path.write_text("value\n1\n2\n3\n")
    with pytest.raises(SignalFileError, match=r"sample rate 4.94066e-324 Hz is too small: the times of 3 "):
        load_signal(path, fs_hz=5e-324)
    with pytest.raises(SignalFileError, match=r"go beyond 1e\+09 s"):
        load_signal(path, fs_hz=1e-300)          # finite, but not the times of a recording
    t, v = load_signal(path, fs_hz=2e-9)        # the last sample at 1e9 s: still a time
    assert np.all(np.isfinite(t)) and np.all(np.diff(t) > 0) and v.tolist() == [1, 2, 3]


@pytest.mark.parametrize(("content", "match"), [
    ("t,v\n0,1\ninf,2\ninf,3\n", r":3: time inf s is not a finite time"),
    ("t,v\n-1e308,1\n1e308,2\n", r":2: time -1e\+308 s is not a finite time"),
    ("t,v\n0,1\nnan,2\n", r":3: time nan s is not a finite time"),
])
def test_signal_times_out_of_range_are_refused_without_warnings(tmp_path, recwarn, content, match):
    """Fuzz finding (signal): "inf, inf" times warned "invalid value encountered in subtract" before
    the file was refused; every time is now checked against one magnitude limit first."""
    path = tmp_path / "times.csv"
    path.write_text(content)
    with pytest.raises(SignalFileError, match=match):
        load_signal(path)
    assert not [w for w in recwarn if issubclass(w.category, RuntimeWarning)]


def test_a_valid_npy_signal_still_loads(tmp_path):
    path = tmp_path / "signal.npy"
    np.save(path, np.column_stack([np.arange(4) * 1e-3, np.arange(4.0)]))
    t, v = load_signal(path)
    np.testing.assert_allclose(t, [0, 1e-3, 2e-3, 3e-3])
    assert v.tolist() == [0, 1, 2, 3]
    np.save(path, np.arange(5, dtype="<i2"))
    t, v = load_signal(path, fs_hz=100.0)
    assert t[-1] == pytest.approx(0.04) and v.dtype == float


# -- 7. G-code O-word loops: a budget of lines read again ---------------------------------------------

#: The fuzz target's finding, in the same form: a while loop whose body resets its counter (a
#: mutation put ``#1 = 0`` inside it) and moves every round. Read 100,000 rounds (the loop limit)
#: it took 8 s and 140 MB.
ENDLESS = ("G21 G90 G0 X0 Y0 Z5 F100\n#1 = 0\no100 while [#1 LT 3]\nG1 X[#1] Y[SIN[#1]]\n"
           "#1 = 0\n#1 = [#1 + 1]\no100 endwhile\nM30\n")


def test_gcode_an_endless_loop_is_refused_within_the_time_bound():
    from robot_io.gcode.reader import MAX_FLOW_LINES

    err = _timed(read_gcode_text, ENDLESS, file="fuzz.ngc")
    assert isinstance(err, ToolpathError) and (err.file, err.line) == ("fuzz.ngc", 3)
    assert f"reads more than {MAX_FLOW_LINES:,} lines again through its loops and calls" in err.reason
    t = time.perf_counter()
    tp = read_gcode_text(ENDLESS, strict=False)   # lenient: the rest of the program is not read
    assert time.perf_counter() - t < HANG_S
    assert tp.skipped["o_word"] == 1
    # the first round, then one for each 4-line body (and its test line) the budget holds, the G0
    assert len(tp.moves) == 1 + MAX_FLOW_LINES // 5 + 1


def test_gcode_the_flow_limits_keep_a_reading_within_the_time_bound():
    """Lines of a loop timed, then multiplied out to the budget of lines read again: the longest
    reading it allows stays under the fuzz rule's 2 s (a call counts its body as a loop does)."""
    from robot_io.gcode.reader import MAX_FLOW_LINES

    rounds = 2000
    text = (f"G21 G90 G0 X0 Y0 Z5 F100\n#1=0\no100 while [#1 LT {rounds}]\nG1 X[#1] Y[SIN[#1]]\n"
            "#1=[#1+1]\no100 endwhile\nM30\n")
    t = time.perf_counter()
    assert len(read_gcode_text(text).moves) == rounds + 1
    per_line = (time.perf_counter() - t) / (4 * rounds)
    assert per_line * MAX_FLOW_LINES < HANG_S, f"the budget: {per_line * MAX_FLOW_LINES:.1f} s"
    calls = ("G21 G90 G0 X0 Y0 Z5 F100\no1 sub\nG1 X1\nG1 X2\no1 endsub\no2 repeat [100000]\n"
             "o1 call\no2 endrepeat\nM30\n")
    with pytest.raises(ToolpathError, match="lines again through its loops and calls"):
        read_gcode_text(calls)


def test_udp_a_signalling_nan_sample_is_a_nan_not_a_warning(recwarn):
    """Fuzz finding (udp): a float32 signalling NaN warned "invalid value encountered in cast"
    (an error under the suite's warnings filter); it is now a NaN sample, which the supervisor
    refuses as implausible."""
    from robot_io.signals.udp import HEADER, MAGIC, parse_samples

    snan = struct.pack("<I", 0x7FA00000)
    data = HEADER.pack(MAGIC, 7, 0.0, 1000.0, 3) + struct.pack("<f", 1.0) + snan + struct.pack("<f", 2.0)
    seq, t0, fs, values = parse_samples(data)
    assert (seq, t0, fs) == (7, 0.0, 1000.0)
    assert values[0] == 1.0 and math.isnan(values[1]) and values[2] == 2.0
    assert not [w for w in recwarn if issubclass(w.category, RuntimeWarning)]


_KRL_LONG_LOOP = """DEF fuzz( )
$VEL.CP=0.001
PTP {X 0,Y 0,Z 10,A 0,B 90,C 0}
LIN {B 0,Z 0}
DECL INT I
FOR I = 1 TO 100000
CIRC {A 555,X -14001},{X 0.5}
$BASE = {FRAME: X 0,Y 0,Z 0,A 0,B 0.0,C 0}
END
"""


def test_krl_a_short_program_cannot_run_a_long_loop(tmp_path):
    """Fuzz finding (krl, 39 inputs): a 13-line program whose unclosed FOR ran 100,000 times a
    motion the lenient reader skips took 7 s (each run re-parses the statement). The work a
    reading may do now grows with what it read (EXECUTED_PER_LINE per line, at least
    EXECUTED_FLOOR): refused with the reason, in well under the 2 s bound."""
    from robot_io.krl._interp import EXECUTED_FLOOR
    from robot_io.readers import read_toolpath

    path = tmp_path / "fuzz.src"
    path.write_text(_KRL_LONG_LOOP)
    t0 = time.perf_counter()
    with pytest.raises(ToolpathError, match=rf"more than {EXECUTED_FLOOR} statements executed "
                                            r"for \d+ lines read"):
        read_toolpath(path, strict=False)
    assert time.perf_counter() - t0 < 2.0


def test_krl_a_loop_over_a_long_dat_array_still_reads(tmp_path):
    """The budget grows with the program: a FOR loop over a 30,000-point .dat array (one move a
    point, as some converters write) is read whole."""
    from robot_io.readers import read_toolpath

    n = 30_000
    (tmp_path / "arr.dat").write_text(
        "DEFDAT arr\nDECL E6POS P[30000]\n"
        + "".join(f"P[{i}]={{X {i * 0.1:.1f},Y 0,Z 0,A 0,B 90,C 0}}\n" for i in range(1, n + 1))
        + "ENDDAT\n")
    (tmp_path / "arr.src").write_text(
        "DEF arr( )\nDECL INT I\n$VEL.CP=0.01\nPTP {X 0,Y 0,Z 10,A 0,B 90,C 0}\n"
        f"FOR I = 1 TO {n}\nLIN P[I]\nENDFOR\nEND\n")
    tp = read_toolpath(tmp_path / "arr.src", strict=False)
    assert len(tp.moves) >= n
