"""The check that the controller applies the commanded override (planner.supervisor.link_watch):
refused writes, an override that does not follow, and what is not a fault (a lagging but
following controller, one late loop iteration, a link that is down)."""

from __future__ import annotations

import pytest

from planner.supervisor.link_watch import (
    FOLLOW_MIN_CHECKS,
    KVP_FOLLOW_S,
    NO_REPORT_S,
    RSI_FOLLOW_CYCLES,
    LinkWatch,
    follow_time,
)
from robot_io.links.kvp import KvpClient
from robot_io.links.rsi import RsiServer
from robot_io.links.rsi_process import RsiProcessServer

DT = 0.004
FOLLOW = RSI_FOLLOW_CYCLES * DT


def _run(watch, commands, applied, steps, t0=0.0, connected=True, refused=lambda k: 0):
    """Step the watch: command ``commands(k)`` and report ``applied(k)`` at step k; return the
    faults with their step."""
    faults = []
    for k in range(steps):
        now = t0 + k * DT
        f = watch.check(now, applied(k), connected, refused(k))
        if f is not None:
            faults.append((k, f))
        c = commands(k)
        if c is not None:
            watch.commanded(now, c)
    return faults


def test_a_controller_that_follows_with_a_lag_is_no_fault():
    # a ramp 100 -> 20 % at 400 %/s, applied two cycles late
    ramp = [max(20, 100 - int(1.6 * k)) for k in range(400)]
    w = LinkWatch(FOLLOW)
    assert _run(w, lambda k: ramp[k], lambda k: ramp[max(0, k - 2)], 400) == []
    assert w.refusals == w.not_followed == 0


def test_a_command_that_is_never_applied_is_a_fault_one_follow_time_later():
    w = LinkWatch(FOLLOW)
    cmds = lambda k: 100 if k < 50 else 60  # noqa: E731
    faults = _run(w, cmds, lambda k: 100.0, 200)
    assert len(faults) == 1  # reported once, not every cycle
    k, f = faults[0]
    late = (k - 50) * DT
    assert FOLLOW <= late <= FOLLOW + (FOLLOW_MIN_CHECKS + 1) * DT
    assert f.kind == "not_applied" and f.commanded == 60 and f.applied == 100.0
    assert "applies 100 %" in f.reason and "60 %" in f.reason
    assert w.not_followed == 1


def test_one_late_iteration_is_not_a_fault():
    # the applied value is stale for one (long) loop iteration only
    w = LinkWatch(FOLLOW)
    faults = []
    for k in range(100):
        now = k * DT + (0.05 if k >= 40 else 0.0)   # a 50 ms stall before step 40
        applied = 100.0 if k < 41 else 60.0         # the controller had long applied 60 ...
        faults += [w.check(now, applied, True, 0)]  # ... the loop sees it one step late
        w.commanded(now, 100 if k < 39 else 60)
    assert not any(faults)


def test_every_refused_write_is_a_fault_at_once():
    w = LinkWatch(FOLLOW, refused0=3)   # refusals before the run are not this run's
    faults = _run(w, lambda k: 60, lambda k: 100.0, 20, refused=lambda k: 3 + (k >= 5) + (k >= 12))
    assert [k for k, _ in faults] == [5, 12]
    assert all(f.kind == "refused" for _, f in faults)
    assert w.refusals == 2


def test_a_link_that_is_down_is_not_judged_and_gets_a_follow_time_when_back():
    w = LinkWatch(FOLLOW)
    assert _run(w, lambda k: 60, lambda k: 100.0, 50, connected=False) == []
    # back: the controller needs a follow time before it is judged
    faults = _run(w, lambda k: 60, lambda k: 100.0, 40, t0=50 * DT)
    assert faults and faults[0][0] * DT >= FOLLOW


def test_a_controller_that_reports_no_override_does_not_follow():
    w = LinkWatch(FOLLOW)
    faults = _run(w, lambda k: 100, lambda k: None, 400)
    assert len(faults) == 1 and "reports no override" in faults[0][1].reason
    # not within the follow time: a slow first read-back is not a refusal
    assert faults[0][0] * DT == pytest.approx(NO_REPORT_S, abs=2 * DT)


def test_follow_time_is_the_protocols():
    rsi = RsiServer.__new__(RsiServer)
    proc = RsiProcessServer.__new__(RsiProcessServer)
    kvp = KvpClient.__new__(KvpClient)
    assert follow_time(rsi, 0.004) == pytest.approx(RSI_FOLLOW_CYCLES * 0.004)
    rsi.cycle_ms = 12   # learned from the IPOC sequence: the controller's cycle, not the loop's
    assert follow_time(rsi, 0.004) == pytest.approx(RSI_FOLLOW_CYCLES * 0.012)
    assert follow_time(proc, 0.012) == pytest.approx(RSI_FOLLOW_CYCLES * 0.012)
    assert follow_time(kvp, 0.004) == KVP_FOLLOW_S
    assert follow_time(object(), 0.004) == KVP_FOLLOW_S
    # inside the 100 ms an operator alarm is due, at either controller cycle
    assert RSI_FOLLOW_CYCLES * 0.012 + FOLLOW_MIN_CHECKS * 0.012 < 0.1
    with pytest.raises(ValueError):
        LinkWatch(0.0)
    learned = {"s": 0.02}
    w = LinkWatch(lambda: learned["s"])   # the follow time may change while the link runs
    learned["s"] = 0.06
    assert w.follow_s == 0.06
