"""End to end over loopback with real sockets (issue 6, "must show" 1).

Each scenario runs the supervisor loop in real time against the simulated cell of
:mod:`planner.supervisor.sim_cell`: the simulated cut's samples travel as UDP datagrams to the supervisor's
source, the override travels to a simulated controller over KukaVarProxy (TCP) or RSI (UDP XML),
and the cut's feed follows the override *that controller applies*:

1. chatter appears mid-cut → detected → override lowered → chatter gone;
2. a feed step without chatter (the thesis's false-alarm test) → no alarm;
3. signal lost → hold, then the safe override (and the controller gets it);
4. controller link lost → the loop keeps running, the link reconnects, the override is resent;
5. a controller that refuses the override (KVP status 0, a KVP write it does not apply, an RSI
   ``<OvPro>`` that does not follow) → hold and an operator alarm within 100 ms of the first
   refusal, and ``cctmill supervise`` exits with status 3;
6. chatter that a raise (the characteristic's stabilising direction) feeds → reversed within one
   decision period, backed off to the floor, escalated.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from _plans import make_plan

from planner.cli import main
from planner.plan_file import load_plan
from planner.supervisor import Supervisor, SupervisorConfig
from planner.supervisor.event_log import EventLog
from planner.supervisor.loop import run_loop
from planner.supervisor.metrics import episode_metrics
from planner.supervisor.session import simulated_sigma
from planner.supervisor.sim_cell import SimCell
from planner.supervisor.sim_cut import CutScenario
from robot_io.links.kvp_sim import KvpSimServer
from robot_io.signals.udp import UdpSignalSender

FS = 10_000.0
CUT = [{"length_m": 0.5, "feed_mm_s": 8.0}]
STEP = [{"length_m": 0.0064, "feed_mm_s": 8.0}, {"length_m": 0.5, "feed_mm_s": 4.0}]  # step at 0.8 s


def _run(tmp_path, sections, robot, scenario, duration_s, events=None, config=None, **plan_kw):
    plan = load_plan(make_plan(tmp_path / "plan", sections, **plan_kw))
    cfg = config or SupervisorConfig()
    sigma = simulated_sigma(plan, FS, scenario, cfg)
    log = EventLog(tmp_path / "events.jsonl")
    with SimCell(plan, robot, FS, scenario) as cell:
        sup = Supervisor(plan, FS, sigma=sigma, config=cfg, log=log)
        t0 = []
        pending = sorted(events or [], key=lambda e: e[0])
        history = []

        def on_step(now, res):
            if not t0:
                t0.append(now)
            while pending and now - t0[0] >= pending[0][0]:
                pending.pop(0)[1](cell)
            history.append((now - t0[0], res, cell.applied_override(), cell.link.connected, now))

        rep = run_loop(sup, cell.source, cell.link, duration_s, before_step=cell.daq, on_step=on_step)
        log.close()
        link_stats = cell.link.stats
        metrics = episode_metrics(sup, cell.cut.truth, sup.level.chatter_hz, scenario.onset_s,
                                  cell.cut.start_clock_s)
        return sup, rep, cell, history, link_stats, metrics


@pytest.mark.parametrize("robot", ["kvp", "rsi"])
def test_chatter_detected_override_lowered_chatter_gone(tmp_path, robot):
    sc = CutScenario(onset_s=0.8)
    sup, rep, cell, hist, link, metrics = _run(tmp_path, CUT, robot, sc, 2.4)
    assert rep.status_counts.get("error", 0) == 0
    assert sup.episodes, rep.status_counts
    ep = sup.episodes[0]
    assert ep.direction == -1 and ep.override_min < 85.0
    # the controller itself ran slower: its applied override went down
    applied = np.array([h[2] for h in hist])
    assert applied.min() < 85.0
    tr = cell.cut.truth.arrays()
    assert tr["chatter_N"].max() > 3.0            # chatter really grew ...
    m = metrics[0]
    assert m.settling_s is not None and m.settling_s < 0.6   # ... and was gone again, quickly
    assert m.detection_delay_s is not None and 0 <= m.detection_delay_s < 0.3
    after = tr["chatter_N"][(tr["t_s"] > ep.signal_start_s + m.settling_s)
                            & (tr["t_s"] < ep.signal_start_s + m.settling_s + 0.3)]
    assert after.size and after.max() < 3.0
    assert link.malformed == 0 and cell.source.stats.malformed == 0
    recs = [json.loads(x) for x in (tmp_path / "events.jsonl").read_text().splitlines()]
    assert any(r["status"] == "alarm" and "lowering" in r["reason"] for r in recs)


def test_feed_step_without_chatter_gives_no_alarm(tmp_path):
    sup, rep, cell, hist, link, _ = _run(tmp_path, STEP, "rsi", CutScenario(), 1.8)
    tr = cell.cut.truth.arrays()
    assert tr["section"][-1] == 1 and tr["feed"][-1] == pytest.approx(4e-3, rel=0.02)
    assert tr["chatter_N"].max() == 0.0
    assert not sup.episodes and rep.status_counts.get("alarm", 0) == 0, rep.status_counts
    assert rep.last.override == pytest.approx(100.0)
    assert cell.applied_override() == pytest.approx(100.0)


def test_feed_step_would_alarm_without_the_transient_model(tmp_path):
    # the same step through the plain chart (no expected-transient allowance) does alarm: the
    # scenario is a real test of the allowance, not a step too small to matter
    cfg = SupervisorConfig(use_transient_model=False)
    sup, rep, *_ = _run(tmp_path, STEP, "kvp", CutScenario(), 1.5, config=cfg)
    assert rep.status_counts.get("alarm", 0) > 0


def test_signal_lost_holds_then_safe_override(tmp_path):
    sc = CutScenario(loss_s=(0.9, 99.0))
    sup, rep, cell, hist, link, _ = _run(tmp_path, CUT, "kvp", sc, 1.8)
    statuses = [h[1].status for h in hist]
    assert "hold" in statuses and "safe" in statuses
    assert statuses.index("hold") < statuses.index("safe")
    held = [h[1].override for h in hist if h[1].status == "hold"]
    assert max(held) - min(held) < 1e-6
    assert hist[-1][1].override == pytest.approx(sup.safe_pct)
    assert cell.applied_override() == pytest.approx(sup.safe_pct, abs=1.0)  # the controller got it
    assert rep.status_counts.get("error", 0) == 0


@pytest.mark.parametrize("robot", ["kvp", "rsi"])
def test_controller_link_lost_reconnects_without_a_crash(tmp_path, robot):
    events = [(0.6, lambda c: c.stop_controller()), (1.0, lambda c: c.start_controller())]
    # a 100 N force limit caps the override at 66.7 %, so the override is not the default 100 %
    sup, rep, cell, hist, link, _ = _run(tmp_path, CUT, robot, CutScenario(), 2.0, events,
                                         force_max_N=100.0)
    assert rep.steps > 0.3 * 2.0 / 0.004  # the loop kept going through the outage (a loaded
    # machine may slow it down; a crash or a hang would stop it)
    assert rep.status_counts.get("error", 0) == 0
    assert rep.link_downs >= 1
    assert link.reconnects >= 1
    assert hist[-1][3]  # connected again
    assert not all(h[3] for h in hist)  # and it was down
    assert hist[-1][1].override == pytest.approx(100.0 * 80.0 / 15.0 / 8.0)
    assert cell.applied_override() == pytest.approx(hist[-1][1].override, abs=1.0)
    down = [h for h in hist if 0.7 < h[0] < 0.95]
    assert down and all(h[1].status != "error" for h in down)
    if robot == "kvp":  # the restarted proxy got the override written again
        assert cell.kvp_server.stats.ov_pro_writes >= 1
    assert not sup.episodes  # the outage did not look like chatter


def test_cli_supervise_sim_json(tmp_path, capsys):
    make_plan(tmp_path / "plan", CUT)
    rc = main(["supervise", "--plan", str(tmp_path / "plan"), "--signal", "sim", "--robot", "sim",
               "--duration-s", "2.2", "--chatter-onset-s", "0.8", "--json",
               "--log", str(tmp_path / "ev.jsonl"), "--plot", str(tmp_path / "run.png")])
    assert rc == 0
    out = json.loads(capsys.readouterr().out)
    assert out["level"] == 9 and out["L_c"] == pytest.approx(4.0, abs=0.02)
    assert out["episodes"] and out["episodes"][0]["direction"] == -1
    assert out["episodes"][0]["detection_delay_ms"] is not None
    assert out["step_latency_ms"]["p99"] < 4.0
    assert (tmp_path / "ev.jsonl").read_text().count("\n") > 10
    assert (tmp_path / "run.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_cli_supervise_udp_stream_to_kvp(tmp_path, capsys):
    # a DAQ of our own sends a stable record over UDP; a KVP server of our own is the controller
    make_plan(tmp_path / "plan", CUT)
    rng = np.random.default_rng(3)
    import socket
    import threading

    probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    probe.bind(("127.0.0.1", 0))
    port = probe.getsockname()[1]
    probe.close()
    stop = threading.Event()

    def daq():
        tx = UdpSignalSender("127.0.0.1", port)
        k = 0
        while not stop.is_set():
            t = (k + np.arange(40)) / FS
            y = 140 + 40 * np.sin(2 * np.pi * 33.3 * t) + rng.normal(0, 0.5, 40)
            tx.send(float(t[0]), FS, y)
            k += 40
            stop.wait(0.004)
        tx.close()

    th = threading.Thread(target=daq, daemon=True)
    with KvpSimServer() as srv:
        th.start()
        try:
            rc = main(["supervise", "--plan", str(tmp_path / "plan"), "--signal", f"udp://127.0.0.1:{port}",
                       "--robot", f"kvp://127.0.0.1:{srv.address[1]}", "--duration-s", "1.6",
                       "--stable-s", "0.8", "--json"])
        finally:
            stop.set()
            th.join()
        assert rc == 0
        out = json.loads(capsys.readouterr().out)
        assert out["fs_hz"] == pytest.approx(FS)
        assert out["sigma"] is not None and not out["episodes"]
        assert out["source_stats"]["samples"] > 0.8 * FS
        assert srv.override_percent == pytest.approx(100.0)


@pytest.mark.parametrize("chatter_end_s,rc_expected", [(2.0, 0), (None, 3)])
def test_cli_supervise_replays_a_recorded_file(tmp_path, capsys, chatter_end_s, rc_expected):
    # 1.6 s of a stable cut in a CSV without a time column, then chatter at f_c: the first 0.8 s
    # teach sigma, the chatter must be caught; the override goes to the simulated KVP. A record
    # whose chatter stops is resolved (exit 0); one that ends chattering is escalated (exit 3)
    make_plan(tmp_path / "plan", CUT)
    rng = np.random.default_rng(5)
    t = np.arange(int(2.8 * FS)) / FS
    y = (140 + 40 * np.sin(2 * np.pi * 33.3 * t) + 0.7 * np.sin(2 * np.pi * 11 * t)
         + rng.normal(0, 0.3, t.size))
    on = (t > 1.6) & (t < (chatter_end_s or np.inf))
    y += np.where(on, 20.0, 0.0) * np.sin(2 * np.pi * 10.98 * t)
    rec = tmp_path / "record.csv"
    rec.write_text("force_N\n" + "\n".join(f"{v:.4f}" for v in y) + "\n", encoding="utf-8")
    rc = main(["supervise", "--plan", str(tmp_path / "plan"), "--signal", str(rec), "--fs-hz", "10000",
               "--robot", "sim", "--stable-s", "0.8", "--json"])
    assert rc == rc_expected
    out = json.loads(capsys.readouterr().out)
    assert out["sigma"] is not None and out["level"] == 9
    assert out["duration_s"] == pytest.approx(2.8, abs=0.3)  # the file's length
    assert len(out["episodes"]) >= 1 and out["episodes"][0]["direction"] == -1
    assert out["final_override"] < 100.0
    ep = out["episodes"][-1]
    if rc_expected == 0:
        assert ep["outcome"] == "resolved" and not out["alarms"]
    else:   # a record does not answer the override: the chatter goes on at the floor, and the
        # episode is escalated (never open at the end of a run); the operator is told
        assert ep["outcome"] == "escalated" and "floor" in ep["outcome_reason"]
        assert out["final_override"] == pytest.approx(20.0)
        assert [a["kind"] for a in out["alarms"]] == ["chatter_escalated"]


@pytest.mark.parametrize("argv,match", [
    (["--signal", "udp://nohost", "--robot", "sim"], "udp://HOST:PORT"),
    (["--signal", "sim", "--robot", "ftp://x:1"], "use sim, kvp://"),
    (["--signal", "sim", "--robot", "sim", "--alpha-f", "2"], "alpha-f"),
    (["--signal", "sim", "--robot", "sim", "--signal-loss-s", "3:1"], "signal-loss-s"),
    (["--signal", "missing.csv", "--robot", "sim"], "no such file"),
])
def test_cli_supervise_errors(tmp_path, capsys, argv, match):
    make_plan(tmp_path / "plan", CUT)
    rc = main(["supervise", "--plan", str(tmp_path / "plan"), "--duration-s", "0.1", *argv])
    assert rc == 2
    assert match in capsys.readouterr().err


def _events(tmp_path):
    return [json.loads(x) for x in (tmp_path / "events.jsonl").read_text().splitlines()]


@pytest.mark.parametrize("robot,mode", [("kvp", "refuse"), ("kvp", "ignore"), ("rsi", "ignore")])
def test_a_refusing_controller_is_an_operator_alarm_within_100_ms(tmp_path, robot, mode):
    # the controller takes the override until 0.3 s, then refuses it (KVP status 0) or ignores it
    # (KVP status 1 without applying; RSI <OvPro> stays where it is); chatter from 0.8 s makes the
    # supervisor lower the feed: the first write it cannot apply must hold the supervisor and
    # alarm the operator within 100 ms, and it must not drive its override to the floor
    def refuse(cell):
        if robot == "kvp":
            cell.kvp_server.override_mode = mode
        else:
            cell.rsi_controller.path.ignore_override = True

    sc = CutScenario(onset_s=0.8)
    sup, rep, cell, hist, link, _ = _run(tmp_path, CUT, robot, sc, 2.0, [(0.3, refuse)])
    assert rep.status_counts.get("error", 0) == 0
    alarms = [r for r in _events(tmp_path) if r.get("event") == "operator_alarm"]
    assert len(alarms) == 1 and len(sup.alarms) == 1
    kind = "link_refused" if robot == "kvp" else "link_not_applied"
    assert alarms[0]["alarm"] == kind and sup.alarms[0].kind == kind
    assert "cannot act" in alarms[0]["reason"]
    if robot == "kvp":   # the controller's own record of the first write it did not take
        first = cell.kvp_server.first_refusal_s
        assert link.refused >= 1 and rep.link_refusals >= 1
    else:                # the first command sent after the controller stopped following
        first = next(h[4] for h in hist if h[0] > 0.3 and round(h[1].override) != 100)
        assert rep.link_not_followed == 1
    assert first is not None
    delay = alarms[0]["t_s"] - first
    assert 0.0 <= delay < 0.1, delay
    print(f"{robot}/{mode}: first refusal -> operator alarm {1e3 * delay:.1f} ms")
    # from the alarm on: hold, at one override, well above the floor; the controller stayed at 100
    after = [h for h in hist if h[4] >= alarms[0]["t_s"]]
    assert after and all(h[1].status == "hold" for h in after)
    held = {round(h[1].override, 6) for h in after}
    assert len(held) == 1 and held.pop() > sup.cfg.floor_pct + 20.0
    assert cell.applied_override() == pytest.approx(100.0)
    assert sup.episodes and all(e.outcome == "escalated" for e in sup.episodes)


def test_cli_supervise_exits_3_when_the_controller_refuses(tmp_path, capsys):
    # a 100 N force limit caps the override at 67 %: the first write already is refused
    make_plan(tmp_path / "plan", CUT, force_max_N=100.0)
    with KvpSimServer(override_mode="refuse") as srv:
        rc = main(["supervise", "--plan", str(tmp_path / "plan"), "--signal", "sim",
                   "--robot", f"kvp://127.0.0.1:{srv.address[1]}", "--duration-s", "1.0",
                   "--chatter-onset-s", "-1", "--json"])
        assert srv.stats.ov_pro_refused >= 1 and srv.override_percent == 100.0
    assert rc == 3
    out = json.loads(capsys.readouterr().out)
    assert [a["kind"] for a in out["alarms"]] == ["link_refused"]
    assert out["link_refusals"] >= 1 and out["link_stats"]["refused"] >= 1
    assert "status 0" in out["link_stats"]["last_error"]
    assert out["final_applied_override"] == 100.0 and out["final_override"] <= 67.0
    assert out["status_counts"].get("hold", 0) > 0.5 * out["steps"]


def test_a_raise_that_feeds_the_chatter_is_reversed_within_one_decision_period(tmp_path):
    # the characteristic says faster is stabilising (margin rising with feed, boundary 4 mm/s);
    # a signal loss brings the override down to a safe 40 %; from 0.8 s the arm is unstable at
    # every feed (the plan's margin - 5e5 N/m): the raise the characteristic asks for feeds the
    # chatter, and must be reversed within one decision period, then backed off and escalated
    sections = [{"length_m": 0.5, "feed_mm_s": 8.0, "rising": True, "boundary_mm_s": 4.0}]
    sc = CutScenario(loss_s=(0.3, 0.8), onset_s=0.8, margin_offset_N_per_m=5e5)
    sup, rep, cell, hist, link, _ = _run(tmp_path, sections, "kvp", sc, 2.8,
                                         config=SupervisorConfig(safe_pct=40.0))
    assert rep.status_counts.get("error", 0) == 0
    ep = sup.episodes[0]
    assert ep.direction == 1 and ep.reversed_s is not None
    t_rev = ep.reversed_s - ep.start_s
    assert t_rev <= sup.decision_period_s + 2 * 0.004, (t_rev, sup.decision_period_s)
    print(f"raise -> reversal {1e3 * t_rev:.0f} ms (decision period "
          f"{1e3 * sup.decision_period_s:.0f} ms)")
    recs = _events(tmp_path)
    assert all(r["reason"] for r in recs), [r for r in recs if not r["reason"]][:3]
    raising = [r for r in recs if r["status"] == "alarm" and "raising the feed" in r["reason"]]
    rev = [r for r in recs if "reversing" in r["reason"]]
    assert raising and rev and rev[0]["t_s"] == pytest.approx(ep.reversed_s)
    assert all(r["t_s"] <= ep.reversed_s for r in raising)  # never raised again after it
    # the controller applied the back-off, all the way to the floor; the episode ended escalated
    assert min(h[2] for h in hist if h[4] > ep.reversed_s) <= sup.cfg.floor_pct + 1.0
    assert ep.outcome == "escalated" and [a.kind for a in sup.alarms] == ["chatter_escalated"]
    assert max(h[1].override for h in hist) <= 100.0

