"""Fuzzing the robot links: random and mutated packets, oversized ones, entity bombs. The parsers
raise only ProtocolError; the servers and the simulated controller never crash or hang (socket
timeouts everywhere) and count every bad packet exactly. Seeded; bounded time."""

from __future__ import annotations

import socket
import struct
import threading
import time

import numpy as np
import pytest

try:  # tests/ as rootdir-on-path folder or as a package
    from conftest import mutate
except ImportError:  # pragma: no cover - depends on how pytest imports tests/
    from tests.conftest import mutate
from _threads import no_leaked_threads, wait_for  # noqa: F401  (autouse fixture)

from robot_io.links.base import ProtocolError
from robot_io.links.kvp import (
    FN_READ,
    FN_WRITE,
    MAX_BODY_BYTES,
    KvpClient,
    KvpConnection,
    KvpRequest,
    pack_reply,
    pack_request,
    parse_reply,
    parse_request,
    read_reply,
)
from robot_io.links.kvp_sim import KvpSimServer
from robot_io.links.rsi import MAX_PACKET_BYTES, RsiServer, build_rob, build_sen, parse_rob, parse_sen
from robot_io.links.rsi_sim import RsiSimController

WAIT_S = 5.0
XML_ALPHABET = b'<>/="&;![]- ?abcdefgKLMNOPRSTXYZ0123456789.\x00\xff'
N_PARSER_CASES = 3000
N_WIRE_CASES = 400

VALID_ROB = build_rob(1_000_000, (1368.8, 5.2, 876.6, 0.0, 90.0, 0.0), (0, -90, 90, 0, 45, 0), 0, 100)
VALID_SEN = build_sen("1000000", 80)

BILLION_LAUGHS = (b'<?xml version="1.0"?><!DOCTYPE Rob [<!ENTITY a "aaaaaaaaaa">'
                  + b"".join(f'<!ENTITY {c} "{("&" + p + ";") * 10}">'.encode()
                             for p, c in zip("abcdefgh", "bcdefghi", strict=True))
                  + b"]><Rob><OvPro>&i;</OvPro><IPOC>1</IPOC></Rob>")
EXTERNAL_ENTITY = (b'<?xml version="1.0"?><!DOCTYPE Rob [<!ENTITY x SYSTEM "file:///etc/passwd">]>'
                   b"<Rob><OvPro>&x;</OvPro><IPOC>1</IPOC></Rob>")
EXTERNAL_DTD = (b'<?xml version="1.0"?><!DOCTYPE Rob SYSTEM "http://127.0.0.1:9/x.dtd">'
                b"<Rob><IPOC>1</IPOC></Rob>")
PARAMETER_ENTITY = (b'<?xml version="1.0"?><!DOCTYPE Rob [<!ENTITY % p SYSTEM "file:///etc/passwd"> %p;]>'
                    b"<Rob><IPOC>1</IPOC></Rob>")
UNDECLARED_ENTITY = b"<Rob><OvPro>&lol;</OvPro><IPOC>1</IPOC></Rob>"
OVERSIZED = VALID_ROB[:-6] + b"<Pad>" + b"x" * MAX_PACKET_BYTES + b"</Pad></Rob>"
DEEP = b"<Rob>" + b"<a>" * 500 + b"</a>" * 500 + b"<IPOC>1</IPOC></Rob>"
HOSTILE = [BILLION_LAUGHS, EXTERNAL_ENTITY, EXTERNAL_DTD, PARAMETER_ENTITY, UNDECLARED_ENTITY, OVERSIZED,
           b"\xff\xfe<\x00R\x00o\x00b\x00>\x00", b"<Rob" * 900, b"\x00" * 200]



def _random_bytes(rng: np.random.Generator, max_len: int) -> bytes:
    return rng.integers(0, 256, int(rng.integers(0, max_len)), dtype=np.uint8).tobytes()


def _rob_valid(data: bytes) -> bool:
    try:
        parse_rob(data)
    except ProtocolError:
        return False
    return True


# -- parsers --------------------------------------------------------------------------------------------

@pytest.mark.parametrize("data", HOSTILE, ids=["billion-laughs", "external-entity", "external-dtd",
                                               "parameter-entity", "undeclared-entity", "oversized",
                                               "utf16", "unclosed", "nul"])
def test_hostile_xml_is_refused_without_expansion(data):
    t0 = time.perf_counter()
    with pytest.raises(ProtocolError):
        parse_rob(data)
    with pytest.raises(ProtocolError):
        parse_sen(data.replace(b"Rob", b"Sen"))
    assert time.perf_counter() - t0 < 1.0  # structural: an expanded bomb would take far longer


def test_deep_nesting_within_the_size_bound_parses():
    assert parse_rob(DEEP).ipoc == 1


def test_rsi_parsers_raise_only_protocol_error(rng):
    accepted = 0
    for i in range(N_PARSER_CASES):
        data = _random_bytes(rng, 600) if i % 3 == 0 else mutate(VALID_ROB if i % 2 else VALID_SEN,
                                                                 XML_ALPHABET, rng, 8)
        for parse in (parse_rob, parse_sen):
            try:
                parse(data)
                accepted += 1
            except ProtocolError:
                pass
    assert 0 < accepted < N_PARSER_CASES  # some mutations stay valid, most do not


def test_kvp_parsers_raise_only_protocol_error(rng):
    bases = [pack_request(KvpRequest(5, FN_WRITE, "$OV_PRO", "80")),
             pack_request(KvpRequest(6, FN_READ, "$OV_PRO")),
             pack_reply(5, 1, "80", True, True), pack_reply(6, 0, "100", True, False)]
    accepted = 0
    for i in range(N_PARSER_CASES):
        data = _random_bytes(rng, 64) if i % 3 == 0 else mutate(bases[i % 4], bytes(range(256)), rng, 4)
        for parse in (parse_request, parse_reply):
            try:
                parse(data)
                accepted += 1
            except ProtocolError:
                pass
    assert 0 < accepted < N_PARSER_CASES


def test_kvp_stream_reader_on_random_streams(rng):
    """read_reply on random bytes: a reply, ProtocolError, or a timeout/close — never a hang."""
    outcomes = {"reply": 0, "protocol": 0, "socket": 0}
    for _ in range(300):
        a, b = socket.socketpair()
        b.settimeout(0.01)
        try:
            a.sendall(_random_bytes(rng, 40))
            a.shutdown(socket.SHUT_WR)
            try:
                read_reply(b)
                outcomes["reply"] += 1
            except ProtocolError:
                outcomes["protocol"] += 1
            except OSError:  # ConnectionError on a short stream, TimeoutError
                outcomes["socket"] += 1
        finally:
            a.close()
            b.close()
    assert outcomes["protocol"] > 0 and outcomes["socket"] > 0


# -- RSI server on the wire --------------------------------------------------------------------------------

def _rob(ipoc: int) -> bytes:
    return build_rob(ipoc, (1368.8, 5.2, 876.6, 0.0, 90.0, 0.0), (0, -90, 90, 0, 45, 0), 0, 100)


def test_rsi_server_counts_every_bad_packet_exactly(rng):
    cases = [mutate(VALID_ROB, XML_ALPHABET, rng, 8) if i % 4 else _random_bytes(rng, 300)
             for i in range(N_WIRE_CASES)] + HOSTILE + [b"x" * 60000]
    expected_bad = sum(not _rob_valid(c) for c in cases)
    expected_good = len(cases) - expected_bad
    assert expected_bad > N_WIRE_CASES // 2
    with RsiServer(link_timeout_s=60.0) as srv, \
            socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as cli:
        cli.bind(("127.0.0.1", 0))
        cli.settimeout(2.0)
        cli.sendto(_rob(1), srv.address)  # link up first: a short first packet would be dropped
        assert parse_sen(cli.recv(4096)).ipoc == 1
        good_replies = 0
        sync = 10
        for start in range(0, len(cases), 20):  # batches, then a sync packet: no buffer overflow
            for c in cases[start:start + 20]:
                cli.sendto(c, srv.address)
            sync += 4
            cli.sendto(_rob(sync), srv.address)
            while True:
                sen = parse_sen(cli.recv(4096))
                if sen.ipoc == sync:
                    break
                good_replies += 1
        want_sent = 1 + expected_good + len(range(0, len(cases), 20))
        assert wait_for(lambda: srv.stats.sent == want_sent)  # counted just after the sendto
        st = srv.stats
        assert st.malformed == expected_bad
        assert good_replies == expected_good
        assert st.replies == st.sent == want_sent
        assert srv.short_first_dropped == 0
        # still serving
        cli.sendto(_rob(10**9), srv.address)
        assert parse_sen(cli.recv(4096)).ipoc_text == str(10**9)


def test_rsi_sim_controller_counts_garbage_replies_exactly(rng):
    n, garbage_cycles = 60, 50
    replies = [mutate(VALID_SEN, XML_ALPHABET, rng, 6) if i % 2 else _random_bytes(rng, 200)
               for i in range(garbage_cycles)]
    sent_bad = []
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    sock.settimeout(0.02)
    stop = threading.Event()

    def serve():
        k = 0
        while not stop.is_set():
            try:
                data, addr = sock.recvfrom(65536)
            except TimeoutError:
                continue
            rob = parse_rob(data)
            if k < garbage_cycles:
                bad = replies[k]
                try:
                    parse_sen(bad)
                    bad = b"<" + bad  # a mutation that stayed valid: make it invalid
                except ProtocolError:
                    pass
                sent_bad.append(bad)
                sock.sendto(bad, addr)
            else:
                sock.sendto(build_sen(rob.ipoc_text, 90), addr)
            k += 1

    t = threading.Thread(target=serve)
    t.start()
    try:
        with RsiSimController(sock.getsockname(), max_cycles=n, timeout_packets=n + 1) as sim:
            assert sim.wait(WAIT_S)
    finally:
        stop.set()
        t.join()
        sock.close()
    st = sim.stats
    assert st.malformed == len(sent_bad) == garbage_cycles
    assert st.late >= garbage_cycles and st.replies + st.late == n
    assert sim.status == "done"
    assert sim.override_percent == 90.0


# -- KVP server on the wire --------------------------------------------------------------------------------

def _expected_kvp(stream: bytes) -> tuple[int, int]:
    """(requests, malformed) the server must count for ``stream`` followed by the client's close:
    frames split by body_len + 4; an oversized body_len closes; a cut-off frame counts once."""
    requests = malformed = 0
    buf = stream
    while len(buf) >= 4:
        body_len = int.from_bytes(buf[2:4], "big")
        if body_len > MAX_BODY_BYTES:
            return requests + 1, malformed + 1
        if len(buf) < 4 + body_len:
            break
        frame, buf = buf[:4 + body_len], buf[4 + body_len:]
        requests += 1
        try:
            parse_request(frame)
        except ProtocolError:
            malformed += 1
    if buf:
        requests += 1
        malformed += 1
    return requests, malformed


def test_kvp_sim_server_counts_every_bad_request_exactly(rng):
    bases = [pack_request(KvpRequest(5, FN_WRITE, "$OV_PRO", "80")),
             pack_request(KvpRequest(6, FN_READ, "$OV_PRO")),
             pack_request(KvpRequest(7, FN_READ, "PING"))]
    want_requests = want_malformed = 0
    with KvpSimServer(count_trailer=False) as srv:
        for i in range(N_WIRE_CASES // 2):
            if i % 5 == 0:
                stream = _random_bytes(rng, 80)
            elif i % 5 == 1:
                stream = struct.pack("!HH", 1, 0xFFFF) + b"\x00" * 32  # oversized body_len
            else:
                stream = b"".join(mutate(bases[(i + k) % 3], bytes(range(256)), rng, 3)
                                  if k == 1 else bases[(i + k) % 3] for k in range(3))
            r, m = _expected_kvp(stream)
            want_requests += r
            want_malformed += m
            with socket.create_connection(srv.address, timeout=2.0) as s:
                s.sendall(stream)
                s.shutdown(socket.SHUT_WR)
                while s.recv(4096):  # drain replies until the server closes
                    pass
            assert wait_for(lambda w=want_requests: srv.stats.requests == w, 2.0)
        st = srv.stats
        assert st.requests == want_requests and st.malformed == want_malformed
        assert want_malformed > N_WIRE_CASES // 10
        with KvpConnection(*srv.address) as conn:  # still serving
            assert conn.ping()
        assert wait_for(lambda: srv.client_count == 0)


def test_kvp_client_survives_a_hostile_server(rng):
    """A server that answers each request with random bytes (or closes): the link never raises and
    counts malformed replies, timeouts and reconnects."""
    lsock = socket.socket()
    lsock.bind(("127.0.0.1", 0))
    lsock.listen(4)
    lsock.settimeout(0.02)
    stop = threading.Event()
    chunks = [_random_bytes(rng, 30) for _ in range(200)]

    def serve():
        k = 0
        while not stop.is_set():
            try:
                conn, _ = lsock.accept()
            except TimeoutError:
                continue
            with conn:
                conn.settimeout(0.2)
                try:
                    while not stop.is_set() and conn.recv(1024):
                        conn.sendall(chunks[k % len(chunks)])
                        k += 1
                except OSError:
                    pass

    t = threading.Thread(target=serve)
    t.start()
    link = KvpClient(*lsock.getsockname(), timeout=0.05, backoff_initial_s=0.005, backoff_max_s=0.02)
    try:
        for i in range(200):
            link.set_override(i % 101)
            time.sleep(0.001)
        assert wait_for(lambda: link.stats.malformed + link.stats.timeouts >= 10)
        st = link.stats
        assert st.reconnects >= 5 and st.last_error
    finally:
        link.close()
        stop.set()
        t.join()
        lsock.close()
