"""KukaVarProxy: byte layouts against KUKA_IO.md §3.2, the simulated server, py-openshowvar interop,
the $OV_PRO link (read-back, reconnect with backoff, timeouts). Loopback only, ephemeral ports."""

from __future__ import annotations

import math
import socket
import struct
import threading
import time
from types import SimpleNamespace

import numpy as np
import pytest
from _threads import no_leaked_threads, wait_for  # noqa: F401  (autouse fixture)

from robot_io.links.base import LinkError, ProtocolError, RobotLink
from robot_io.links.kvp import (
    FN_READ,
    FN_WRITE,
    KvpClient,
    KvpConnection,
    KvpReply,
    KvpRequest,
    pack_reply,
    pack_request,
    parse_reply,
    parse_request,
    read_reply,
)
from robot_io.links.kvp_sim import KvpSimServer

py_openshowvar = pytest.importorskip("py_openshowvar")



def _reply_tuple(data: bytes) -> tuple:
    """A reply unpacked the way the py_openshowvar README prints it."""
    n = len(data) - 7 - 3
    return struct.unpack(f"!HHBH{n}s3s", data)


# -- byte layouts (KUKA_IO.md §3.2, literally) -----------------------------------------------------

def test_read_request_layout_matches_py_openshowvar_packer():
    ours = pack_request(KvpRequest(48, FN_READ, "$OV_PRO"))
    theirs = py_openshowvar.openshowvar._pack_read_req(SimpleNamespace(varname=b"$OV_PRO", msg_id=48))
    assert ours == theirs == struct.pack("!HHBH7s", 48, 10, 0, 7, b"$OV_PRO")


def test_write_request_layout_matches_py_openshowvar_packer():
    ours = pack_request(KvpRequest(67, FN_WRITE, "$OV_PRO", "80"))
    theirs = py_openshowvar.openshowvar._pack_write_req(
        SimpleNamespace(varname=b"$OV_PRO", value=b"80", msg_id=67))
    # body_len = 1 + 2 + 7 + 2 + 2
    assert ours == theirs == struct.pack("!HHBH7sH2s", 67, 14, 1, 7, b"$OV_PRO", 2, b"80")


def test_reply_layouts_of_the_published_examples():
    # py_openshowvar README (server that does not count the trailer): read and write of $OV_PRO
    assert _reply_tuple(pack_reply(48, 0, "100", True, count_trailer=False)) == \
        (48, 6, 0, 3, b"100", b"\x00\x01\x01")
    assert _reply_tuple(pack_reply(67, 1, "100", True, count_trailer=False)) == \
        (67, 6, 1, 3, b"100", b"\x00\x01\x01")
    # KUKAVARPROXY 6.1.101 (VB source: counts the trailer): failed write of a FRAME
    failed = struct.pack("!HHBH21s3s", 10, 27, 1, 21, b"{X 50.2, Y -0.5, Z 0}", b"\x00\x01\x00")
    assert pack_reply(10, 1, "{X 50.2, Y -0.5, Z 0}", False, count_trailer=True) == failed
    r = parse_reply(failed)
    assert r == KvpReply(10, 1, None, False, True)


@pytest.mark.parametrize("count_trailer", [True, False])
def test_reply_parser_accepts_both_body_len_variants(count_trailer):
    data = pack_reply(48, 0, "100", True, count_trailer)
    assert struct.unpack_from("!H", data, 2)[0] == (9 if count_trailer else 6)
    assert parse_reply(data) == KvpReply(48, 0, "100", True, count_trailer)


@pytest.mark.parametrize("count_trailer", [True, False])
def test_stream_reader_reads_exactly_one_reply_byte_by_byte(count_trailer):
    a, b = socket.socketpair()
    try:
        b.settimeout(1.0)
        first = pack_reply(1, 0, "{X 1.0,Y 2.0}", True, count_trailer)
        second = pack_reply(2, 0, None, False, count_trailer)  # status 0 without value
        sender = threading.Thread(target=lambda: [a.send(bytes([x])) for x in first + second])
        sender.start()
        assert read_reply(b) == KvpReply(1, 0, "{X 1.0,Y 2.0}", True, count_trailer)
        assert read_reply(b) == KvpReply(2, 0, None, False, count_trailer)
        sender.join()
    finally:
        a.close()
        b.close()


@pytest.mark.parametrize("data, match", [
    (struct.pack("!HHBH3s3s", 1, 7, 0, 3, b"100", b"\x00\x01\x01"), "fits neither"),
    (struct.pack("!HHBH3s3s", 1, 6, 0, 3, b"100", b"\x01\x01\x01"), "trailer"),
    (struct.pack("!HHBH3s3s", 1, 6, 0, 3, b"100", b"\x00\x01\x02"), "trailer"),
    (struct.pack("!HHBH3s3s", 1, 6, 0, 3, b"1\xff0", b"\x00\x01\x01"), "ASCII"),
    (struct.pack("!HHBH", 1, 6, 0, 3), "shorter"),
    (struct.pack("!HHBH3s3s", 1, 6, 0, 4, b"100", b"\x00\x01\x01"), "does not match"),
])
def test_malformed_replies_are_refused(data, match):
    with pytest.raises(ProtocolError, match=match):
        parse_reply(data)


def test_request_round_trip_and_refusals():
    for req in (KvpRequest(0, FN_READ, "$OV_PRO"), KvpRequest(65535, FN_WRITE, "$OV_PRO", "55"),
                KvpRequest(7, FN_WRITE, "$BASE", "{X 1.0,Y 2.0,Z 3.0,A 0,B 0,C 0}"),
                KvpRequest(9, FN_WRITE, "$X", "")):
        assert parse_request(pack_request(req)) == req
    with pytest.raises(LinkError, match="msg_id"):
        pack_request(KvpRequest(70000, FN_READ, "$OV_PRO"))
    with pytest.raises(LinkError, match="ASCII"):
        pack_request(KvpRequest(1, FN_READ, "$ÖV"))
    with pytest.raises(LinkError, match="function"):
        pack_request(KvpRequest(1, FN_READ, "$OV_PRO", "5"))


@pytest.mark.parametrize("frame, match", [
    (struct.pack("!HHBH7s", 1, 11, 0, 7, b"$OV_PRO"), "body_len"),
    (struct.pack("!HHBH7sB", 1, 11, 0, 7, b"$OV_PRO", 0), "stray"),
    (struct.pack("!HHBH7s", 1, 10, 9, 7, b"$OV_PRO"), "unknown function"),
    (struct.pack("!HHBH7s", 1, 10, 0, 8, b"$OV_PRO"), "name_len"),
    (struct.pack("!HHBH", 1, 3, 0, 0), "name_len"),
    (struct.pack("!HHBH7sH1s", 1, 13, 1, 7, b"$OV_PRO", 2, b"8"), "value_len"),
    (struct.pack("!HHBH7s", 1, 10, 1, 7, b"$OV_PRO"), "without value"),
    (b"\x00\x01\x00", "shorter"),
])
def test_malformed_requests_are_refused(frame, match):
    with pytest.raises(ProtocolError, match=match):
        parse_request(frame)


# -- the simulated server ---------------------------------------------------------------------------

@pytest.mark.parametrize("count_trailer", [True, False])
def test_sim_server_answers_pipelined_requests_in_order(count_trailer):
    with KvpSimServer(count_trailer=count_trailer) as srv, \
            socket.create_connection(srv.address, timeout=2.0) as s:
        s.sendall(pack_request(KvpRequest(1, FN_READ, "$OV_PRO"))
                  + pack_request(KvpRequest(2, FN_WRITE, "$OV_PRO", "80"))
                  + pack_request(KvpRequest(3, FN_READ, "PING"))
                  + pack_request(KvpRequest(4, FN_READ, "$NO_SUCH_VAR"))
                  + pack_request(KvpRequest(5, FN_WRITE, "$OV_PRO", "150"))
                  + pack_request(KvpRequest(6, FN_WRITE, "$OV_PRO", "abc"))
                  + struct.pack("!HHBH9s", 7, 12, 2, 9, b"$AXIS_ACT"))  # array read: unsupported
        replies = [read_reply(s) for _ in range(7)]
        assert [(r.msg_id, r.function, r.value, r.ok) for r in replies] == [
            (1, 0, "100", True), (2, 1, "80", True), (3, 0, "PONG", True), (4, 0, None, False),
            (5, 1, None, False), (6, 1, None, False), (7, 2, None, False)]
        assert all(r.trailer_counted is count_trailer for r in replies)
        assert srv.override_percent == 80.0
        st = srv.stats
        assert (st.requests, st.replies, st.malformed, st.unsupported, st.ov_pro_writes) == (7, 7, 0, 1, 1)


def test_sim_server_reassembles_requests_split_across_segments():
    req = pack_request(KvpRequest(9, FN_WRITE, "$OV_PRO", "33")) + pack_request(KvpRequest(10, FN_READ,
                                                                                         "$OV_PRO"))
    with KvpSimServer() as srv, socket.create_connection(srv.address, timeout=2.0) as s:
        s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        for i in range(len(req)):
            s.send(req[i:i + 1])
            time.sleep(0.0005)
        assert [(r.msg_id, r.value) for r in (read_reply(s), read_reply(s))] == [(9, "33"), (10, "33")]
        assert srv.stats.malformed == 0


def test_sim_server_override_drives_the_path_speed():
    with KvpSimServer(programmed_speed=2e-3, tau=0.02) as srv, KvpConnection(*srv.address) as conn:
        assert srv.path_speed() == pytest.approx(2e-3)
        assert conn.write("$OV_PRO", "50") == "50"
        just_after = srv.path_speed()
        assert 1e-3 < just_after <= 2e-3  # first-order lag, not a jump
        assert wait_for(lambda: abs(srv.path_speed() - 1e-3) < 1e-6)
        assert conn.read("$OV_PRO") == "50"
        assert conn.ping()


def test_simulated_path_speed_is_a_first_order_lag_in_closed_form():
    from robot_io.links._sim_peer import SimulatedPathSpeed

    now = [0.0]
    path = SimulatedPathSpeed(programmed_speed=2e-3, tau=0.05, clock=lambda: now[0])
    now[0] = 1.0
    assert path.speed() == pytest.approx(2e-3) and path.position() == pytest.approx(2e-3)
    path.set_override(50)
    now[0] = 1.05  # one time constant later: 1 - 1/e of the step done
    assert path.speed() == pytest.approx(1e-3 + 1e-3 * math.exp(-1.0))
    # position = integral of the speed: numeric check of the closed form
    ts = np.linspace(1.0, 1.05, 20001)
    v = 1e-3 + 1e-3 * np.exp(-(ts - 1.0) / 0.05)
    assert path.position() == pytest.approx(2e-3 + float(np.sum((v[1:] + v[:-1]) / 2 * np.diff(ts))),
                                            rel=1e-9)
    now[0] = 3.0
    assert path.speed() == pytest.approx(1e-3, rel=1e-12)


def test_client_counts_slow_replies_as_late():
    with KvpSimServer(reply_delay_s=0.03) as srv, KvpClient(*srv.address, timeout=0.5, late_s=0.01) as link:
        assert link.wait_connected()
        assert link.set_override(20).ok and link.flush(3.0)
        st = link.stats
        assert st.late == st.replies >= 2 and st.timeouts == 0


def test_sim_server_refuses_clients_beyond_the_limit():
    with KvpSimServer(max_clients=2) as srv:
        a, b = KvpConnection(*srv.address), KvpConnection(*srv.address)
        try:
            assert a.ping() and b.ping()
            with socket.create_connection(srv.address, timeout=2.0) as c:
                assert c.recv(16) == b""  # closed by the server at once
            assert wait_for(lambda: srv.stats.refused == 1)
            assert srv.stats.connections == 2
        finally:
            a.close()
            b.close()


def test_sim_server_closes_idle_clients():
    with KvpSimServer(idle_timeout_s=0.15) as srv, \
            socket.create_connection(srv.address, timeout=2.0) as s:
        t0 = time.monotonic()
        assert s.recv(16) == b""
        assert time.monotonic() - t0 >= 0.15
        assert wait_for(lambda: srv.stats.idle_closed == 1)


def test_sim_server_cannot_bind_a_used_port():
    with KvpSimServer() as srv:
        with pytest.raises(LinkError, match="cannot bind"):
            KvpSimServer(port=srv.address[1]).start()


# -- interoperability with py-openshowvar -----------------------------------------------------------

@pytest.mark.parametrize("count_trailer", [True, False])
def test_py_openshowvar_reads_and_writes_ov_pro_on_the_sim(count_trailer):
    with KvpSimServer(count_trailer=count_trailer) as srv:
        client = py_openshowvar.openshowvar(*srv.address)
        try:
            assert client.read("$OV_PRO", debug=False) == b"100"
            assert client.write("$OV_PRO", "80", debug=False) == b"80"
            assert srv.override_percent == 80.0
            assert client.read("$OV_PRO", debug=False) == b"80"
            assert client.read("PING", debug=False) == b"PONG"
            assert client.read("$NO_SUCH_VAR", debug=False) is None  # status 0
            assert client.read("$OV_PRO", debug=False) == b"80"  # still in step after a failure?
        finally:
            client.close()


@pytest.mark.parametrize("count_trailer", [True, False])
def test_our_client_against_py_openshowvar_writes(count_trailer):
    """Both clients on one server: a value one writes the other reads."""
    with KvpSimServer(count_trailer=count_trailer) as srv, KvpClient(*srv.address, poll_s=0.02) as link:
        theirs = py_openshowvar.openshowvar(*srv.address)
        try:
            assert link.wait_connected()
            assert link.set_override(42).ok
            assert link.flush()
            assert theirs.read("$OV_PRO", debug=False) == b"42"
            assert theirs.write("$OV_PRO", "17", debug=False) == b"17"
            assert wait_for(lambda: link.read_override() == 17.0)
        finally:
            theirs.close()


# -- the $OV_PRO link ---------------------------------------------------------------------------------

@pytest.mark.parametrize("count_trailer", [True, False])
def test_client_writes_and_reads_back_ov_pro(count_trailer):
    with KvpSimServer(count_trailer=count_trailer) as srv, KvpClient(*srv.address) as link:
        assert isinstance(link, RobotLink)
        assert link.wait_connected()
        status = link.set_override(63.4)
        assert status.ok and status.percent == 63
        assert link.flush()
        assert link.read_override() == 63.0
        assert srv.override_percent == 63.0
        assert link.set_override(250).percent == 100
        assert link.flush() and srv.override_percent == 100.0
        assert link.set_override(-5).percent == 0
        assert link.flush() and srv.override_percent == 0.0
        bad = link.set_override(math.nan)
        assert not bad.ok and bad.percent is None
        st = link.stats
        assert st.malformed == st.timeouts == st.reconnects == 0
        assert st.replies == st.sent >= 6


@pytest.mark.parametrize("mode,status_ok", [("refuse", False), ("ignore", True)])
def test_client_counts_writes_the_controller_does_not_apply(mode, status_ok):
    # a controller that answers status 0 ("refuse"), or status 1 without taking the value
    # ("ignore": the read-back shows the old one): both are refusals, counted with the reason
    with KvpSimServer(override_mode=mode) as srv, KvpClient(*srv.address) as link:
        assert link.wait_connected()
        t0 = time.monotonic()
        assert link.set_override(40).ok           # queued: the answer comes from the controller
        assert not link.flush()
        assert wait_for(lambda: link.stats.refused == 1)
        assert srv.first_refusal_s is not None and srv.first_refusal_s >= t0
        assert srv.stats.ov_pro_refused == 1 and srv.stats.ov_pro_writes == 0
        assert srv.override_percent == 100.0 and link.read_override() == 100.0
        st = link.stats
        assert ("status 0" in st.last_error) != status_ok and "40" in st.last_error
        assert link.set_override(40).ok and not link.flush(0.1)  # not retried: still one
        assert link.stats.refused == 1
        srv.override_mode = "apply"               # the controller takes writes again
        assert link.set_override(55).ok and link.flush()
        assert srv.override_percent == 55.0 and link.stats.refused == 1


def test_sim_server_refuses_an_unknown_override_mode():
    with pytest.raises(LinkError, match="override_mode 'maybe'"):
        KvpSimServer(override_mode="maybe")


def test_set_override_does_not_block_on_a_silent_server():
    """A server that accepts and never answers: the worker hangs in recv, set_override does not."""
    lsock = socket.socket()
    lsock.bind(("127.0.0.1", 0))
    lsock.listen(1)
    link = KvpClient(*lsock.getsockname(), timeout=0.3)
    try:
        conn, _ = lsock.accept()
        assert link.wait_connected()
        t0 = time.perf_counter()
        for i in range(1000):
            link.set_override(i % 100)
        # Structural bound: one blocking request would take the 0.3 s timeout.
        assert time.perf_counter() - t0 < 0.3
        assert wait_for(lambda: link.stats.timeouts >= 1)
        assert "no reply" in link.stats.last_error
        conn.close()
    finally:
        link.close()
        lsock.close()


def test_client_reconnects_after_server_restart_on_the_same_port():
    srv = KvpSimServer().start()
    port = srv.address[1]
    link = KvpClient("127.0.0.1", port, backoff_initial_s=0.01, backoff_max_s=0.1)
    try:
        assert link.wait_connected()
        assert link.set_override(70).ok and link.flush()
        srv.stop()
        assert wait_for(lambda: not link.connected)
        status = link.set_override(40)  # while down: kept, not raised
        assert not status.ok and status.percent == 40 and "reconnecting" in status.reason
        time.sleep(0.3)  # a few failed attempts with backoff
        assert link.stats.reconnects == 0
        srv = KvpSimServer(port=port).start()  # a fresh controller: $OV_PRO back at 100
        assert link.wait_connected()
        assert link.flush()
        assert srv.override_percent == 40.0  # the wanted value is written on reconnect
        assert link.read_override() == 40.0
        assert link.stats.reconnects == 1
    finally:
        link.close()
        srv.stop()


def test_idle_client_notices_a_lost_server_before_its_next_poll():
    srv = KvpSimServer().start()
    link = KvpClient(*srv.address, poll_s=30.0, backoff_initial_s=0.01, backoff_max_s=0.05)
    try:
        assert link.wait_connected() and link.set_override(60).ok and link.flush()
        srv.stop()
        t0 = time.monotonic()
        assert wait_for(lambda: not link.connected, 1.0)  # far sooner than the 30 s poll
        assert time.monotonic() - t0 < 1.0
        assert "closed" in link.stats.last_error or "connect" in link.stats.last_error
    finally:
        link.close()
        srv.stop()


def test_client_backs_off_exponentially_and_bounded(monkeypatch):
    import robot_io.links.kvp as kvp

    attempts: list[float] = []

    def refuse(host, port, timeout):
        attempts.append(time.monotonic())
        raise LinkError("kvp", f"cannot connect to {host}:{port}: refused (test)")

    monkeypatch.setattr(kvp, "KvpConnection", refuse)
    link = KvpClient("127.0.0.1", 9, backoff_initial_s=0.01, backoff_max_s=0.08)
    try:
        assert wait_for(lambda: len(attempts) >= 7)
        assert not link.connected
        assert "cannot connect" in link.stats.last_error
        assert not link.set_override(50).ok
        for _ in range(50):  # set_override must not cut the backoff short
            link.set_override(50)
    finally:
        link.close()
    gaps = [b - a for a, b in zip(attempts, attempts[1:], strict=False)]
    expected = [min(0.01 * 2**k, 0.08) for k in range(len(gaps))]
    assert all(g >= e * 0.95 for g, e in zip(gaps, expected, strict=True)), (gaps, expected)
    assert link.stats.reconnects == 0


def _garbage_server(reply: bytes, stop: threading.Event) -> tuple[socket.socket, threading.Thread]:
    lsock = socket.socket()
    lsock.bind(("127.0.0.1", 0))
    lsock.listen(4)
    lsock.settimeout(0.05)

    def serve():
        while not stop.is_set():
            try:
                conn, _ = lsock.accept()
            except TimeoutError:
                continue
            with conn:
                conn.settimeout(0.5)
                try:
                    if conn.recv(1024):
                        conn.sendall(reply)
                    conn.recv(1024)
                except OSError:
                    pass

    t = threading.Thread(target=serve)
    t.start()
    return lsock, t


@pytest.mark.parametrize("reply", [
    pack_reply(999, 0, "100", True, True),               # wrong msg_id
    struct.pack("!HHBH3s3s", 1, 7, 0, 3, b"100", b"\x00\x01\x01"),  # body_len fits no variant
    b"\xff" * 12,                                        # noise
])
def test_client_counts_bad_replies_and_keeps_running(reply):
    stop = threading.Event()
    lsock, t = _garbage_server(reply, stop)
    link = KvpClient(*lsock.getsockname(), timeout=0.2, backoff_initial_s=0.01, backoff_max_s=0.05)
    try:
        assert wait_for(lambda: link.stats.malformed >= 2)
        assert link.set_override(30).percent == 30
        assert link.read_override() is None
    finally:
        link.close()
        stop.set()
        t.join()
        lsock.close()


# -- cctmill robot-sim kvp ------------------------------------------------------------------------------

def test_cli_robot_sim_kvp_serves_until_the_duration(capsys):
    from planner.cli import build_parser, main

    build_parser()  # import every command module before the clock starts
    result = {}
    t = threading.Thread(target=lambda: result.setdefault(
        "rc", main(["robot-sim", "kvp", "--port", "0", "--duration-s", "1.5", "--stats-every-s", "0.2",
                    "--no-count-trailer"])))
    t.start()
    seen: list[str] = []
    try:
        assert wait_for(lambda: "listening on" in "".join(seen.append(capsys.readouterr().out) or seen),
                        10.0)
        out = "".join(seen)
        port = int(out.split("listening on 127.0.0.1:")[1].split()[0])
        client = py_openshowvar.openshowvar("127.0.0.1", port)
        try:
            assert client.write("$OV_PRO", "55", debug=False) == b"55"
        finally:
            client.close()
    finally:
        t.join()
    out += capsys.readouterr().out
    assert result["rc"] == 0
    assert "excludes the trailer" in out
    assert out.strip().splitlines()[-1].split("$OV_PRO ")[1].startswith("55 ")


def test_cli_robot_sim_refuses_bad_flags(capsys):
    from planner.cli import main

    assert main(["robot-sim", "rsi", "--port", "0"]) == 2
    assert "--port" in capsys.readouterr().err
    assert main(["robot-sim", "kvp", "--port", "0", "--duration-s", "-1"]) == 2
    assert "--duration-s" in capsys.readouterr().err
