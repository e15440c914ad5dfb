"""Online supervisor: step latency against the controller cycle, detection delay and closed-loop
settling against the thesis (5 ms, 0.27–0.3 s).

1. **Step latency** — :meth:`planner.supervisor.Supervisor.step` timed with ``perf_counter`` over
   ``--steps`` (default 100,000) steps of 4 ms (40 samples at 10 kHz) of a supervised simulated cut
   in closed loop (a plan of alternating 8 / 6 mm/s sections: feed steps, chatter episodes, back-offs,
   recoveries; the supervisor's own DWT band, chart, policy, ruckig and log in every step). Reported:
   p50, p99, p99.9 and the worst case of the step's CPU time (``thread_time``: its own cost) and
   of its wall time (``perf_counter``: plus whatever preemption the machine inflicts), and the worst
   case as a fraction of the 4 ms (KR C4) and 12 ms (KR C2) cycles. Baseline measured in the same
   run: the naive detector step — a full ``pywt.wavedec`` of a sliding window as long as the band
   filter — against the streaming band alone. The closed loop is deterministic (seeded, virtual
   clock), so the timed run is repeated ``--repeats`` times and the *per-step minimum* over the
   repeats is the step's intrinsic cost: preemption and VM steal time on a shared machine land on
   different steps each time and drop out; the raw figures are reported too.
   Also the whole loop iteration in real time with the simulated cell in the *same* process (KVP
   and RSI sims, UDP DAQ: their threads compete for the GIL, so this is a pessimistic figure).
2. **Detection delay and settling** — closed-loop runs on a virtual clock (``--seeds`` seeds;
   definitions in :mod:`planner.supervisor.metrics`) for wavelets db2, db4 (default) and db8.

Run from the repository root: ``python benchmarks/supervisor_latency.py [--steps N] [--seeds K]``.
"""

from __future__ import annotations

import argparse
import gc
import json
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
for _p in (str(ROOT), str(ROOT / "tests")):
    if _p not in sys.path:
        sys.path.insert(0, _p)

import pywt  # noqa: E402
from _plans import make_plan  # noqa: E402

from planner.plan_file import load_plan  # noqa: E402
from planner.supervisor import Supervisor, SupervisorConfig  # noqa: E402
from planner.supervisor.detector import BandMonitor  # noqa: E402
from planner.supervisor.loop import VirtualClock, run_loop  # noqa: E402
from planner.supervisor.metrics import episode_metrics  # noqa: E402
from planner.supervisor.session import simulated_sigma  # noqa: E402
from planner.supervisor.sim_cell import SimCell  # noqa: E402
from planner.supervisor.sim_cut import CutScenario, SimulatedCut  # noqa: E402
from robot_io.links.base import LinkStats, LinkStatus  # noqa: E402

FS = 10_000.0
CYCLE_S = 0.004
CYCLES_S = (0.004, 0.012)
THESIS_DETECTION_S = 0.005
THESIS_CLOSED_LOOP_S = (0.27, 0.30)
WAVELETS = ("db2", "db4", "db8")
BASELINE_STEPS = 5000
WALL_NOT_MET = "NOT met on this shared 2-core VM (a real-time host needs a dedicated core)"
OVERRUNS_SEEN = "overruns seen (GIL shared with the sims)"


class _Link:
    """In-process controller stand-in: applies the override at once (no sockets: pure step cost)."""

    def __init__(self) -> None:
        self.v = 100.0
        self.stats = LinkStats()
        self.connected = True

    def set_override(self, p: float) -> LinkStatus:
        self.v = float(p)
        return LinkStatus(True, "applied", int(round(p)))

    def read_override(self) -> float:
        return self.v

    def close(self) -> None:
        pass


def _pct(a: np.ndarray, q: float) -> float:
    return float(np.percentile(a, q)) * 1e3


def _closed_loop_run(plan, sigma, cfg, sc, steps: int, alarms: list | None = None):
    clk = VirtualClock()
    link = _Link()
    cut = SimulatedCut(plan, link.read_override, FS, sc, clock=clk)
    sup = Supervisor(plan, FS, sigma=sigma, config=cfg)
    gc.collect()
    on_step = None if alarms is None else (lambda now, res: alarms.append(res.alarm))
    rep = run_loop(sup, cut, link, steps * CYCLE_S, CYCLE_S, clock=clk, sleep=clk.sleep,
                   on_step=on_step)
    sup.log.close()
    return sup, rep


def step_latency(steps: int, folder: Path, repeats: int = 5) -> dict:
    n_sec = 40
    secs = [{"length_m": 0.1, "feed_mm_s": 8.0 if i % 2 == 0 else 6.0} for i in range(n_sec)]
    plan = load_plan(make_plan(folder / "long", secs, step_m=0.005))
    cfg = SupervisorConfig()
    sc = CutScenario(onset_s=1.5)
    sigma = simulated_sigma(plan, FS, sc, cfg)
    walls, cpus = [], []
    alarms: list[bool] = []
    for k in range(repeats):
        sup, rep = _closed_loop_run(plan, sigma, cfg, sc, steps, alarms if k == 0 else None)
        walls.append(rep.step_latency_s[200:])  # after the first band values (imports, caches)
        cpus.append(rep.step_cpu_s[200:])
        if rep.status_counts != _closed_loop_run.__dict__.setdefault("counts", rep.status_counts):
            raise RuntimeError("closed-loop runs differ between repeats: not deterministic")
    _closed_loop_run.__dict__.pop("counts", None)
    # the same deterministic step sequence ran `repeats` times: the per-step minimum removes the
    # preemption and steal time the shared machine adds at random moments
    lat = np.concatenate(walls)
    cpu = np.concatenate(cpus)
    intrinsic = np.min(np.vstack(walls), axis=0)
    alarm_steps = intrinsic[np.asarray(alarms[200:], dtype=bool)]
    # the streaming band alone (one BandMonitor.push of 40 samples), CPU time
    mon = BandMonitor(sup.level.level, sup.cfg.wavelet)
    win = mon.length
    x = np.random.default_rng(0).normal(size=win + 40 * BASELINE_STEPS)
    mon.push(np.arange(win) / FS, x[:win])
    band = np.empty(BASELINE_STEPS)
    for i in range(BASELINE_STEPS):
        seg = x[win + 40 * i: win + 40 * (i + 1)]
        t0 = time.thread_time()
        mon.push(np.arange(40) / FS, seg)
        band[i] = time.thread_time() - t0
    # baseline: the naive detector step, a full wavedec of a window as long as the band filter
    base = np.empty(BASELINE_STEPS)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # "all coefficients see boundary effects"
        for i in range(BASELINE_STEPS):
            w = x[40 * i: 40 * i + win]
            t0 = time.thread_time()
            d = pywt.wavedec(w, sup.cfg.wavelet, mode="zero", level=sup.level.level)[1]
            _ = float(np.max(np.abs(d[-2:])))
            base[i] = time.thread_time() - t0
    return {
        "steps": int(intrinsic.size), "repeats": repeats,
        "alarm_steps": rep.status_counts.get("alarm", 0),
        "episodes": len(sup.episodes), "status_counts": rep.status_counts,
        "wall": _lat(lat), "cpu": _lat(cpu), "intrinsic": _lat(intrinsic),
        "alarm_step": _lat(alarm_steps) if alarm_steps.size else None,
        "of_cycle_intrinsic": {f"{c * 1e3:.0f}ms": float(intrinsic.max()) / c for c in CYCLES_S},
        "of_cycle_wall": {f"{c * 1e3:.0f}ms": float(lat.max()) / c for c in CYCLES_S},
        "band_cpu": _lat(band), "baseline_wavedec_cpu": _lat(base),
        "filter_taps": int(win), "level": sup.level.level,
    }


def _lat(a: np.ndarray) -> dict:
    return {"p50_ms": _pct(a, 50), "p99_ms": _pct(a, 99), "p999_ms": _pct(a, 99.9),
            "max_ms": float(a.max()) * 1e3}


def loop_latency_real_time(folder: Path, duration_s: float = 5.0) -> dict:
    plan = load_plan(make_plan(folder / "rt", [{"length_m": 0.5, "feed_mm_s": 8.0}]))
    out = {}
    for robot in ("kvp", "rsi"):
        sc = CutScenario(onset_s=1.0)
        sigma = simulated_sigma(plan, FS, sc, SupervisorConfig())
        with SimCell(plan, robot, FS, sc) as cell:
            sup = Supervisor(plan, FS, sigma=sigma)
            rep = run_loop(sup, cell.source, cell.link, duration_s, CYCLE_S, before_step=cell.daq)
        s, c = rep.step_latency_s[50:], rep.cycle_latency_s[50:]
        out[robot] = {"steps": int(s.size), "step_p99_ms": _pct(s, 99), "step_max_ms": float(s.max()) * 1e3,
                      "iteration_p99_ms": _pct(c, 99), "iteration_max_ms": float(c.max()) * 1e3,
                      "overruns": rep.overruns, "episodes": len(sup.episodes)}
    return out


def closed_loop(seeds: int, folder: Path) -> dict:
    plan = load_plan(make_plan(folder / "cl", [{"length_m": 0.5, "feed_mm_s": 8.0}]))
    out = {}
    for wavelet in WAVELETS:
        cfg = SupervisorConfig(wavelet=wavelet)
        rows = []
        for seed in range(seeds):
            sc = CutScenario(onset_s=1.0, seed=seed)
            sigma = simulated_sigma(plan, FS, sc, cfg)
            clk = VirtualClock()
            link = _Link()
            cut = SimulatedCut(plan, link.read_override, FS, sc, clock=clk)
            sup = Supervisor(plan, FS, sigma=sigma, config=cfg)
            run_loop(sup, cut, link, 2.6, CYCLE_S, clock=clk, sleep=clk.sleep)
            m = episode_metrics(sup, cut.truth, sup.level.chatter_hz, sc.onset_s, cut.start_clock_s)
            if m:
                rows.append(m[0])
        det = np.array([r.detection_delay_s for r in rows if r.detection_delay_s is not None])
        ons = np.array([r.onset_to_alarm_s for r in rows if r.onset_to_alarm_s is not None])
        st = np.array([r.settling_s for r in rows if r.settling_s is not None])
        qt = np.array([r.quiet_s for r in rows if r.quiet_s is not None])
        fmin = np.array([r.override_min for r in rows])
        out[wavelet] = {
            "runs": seeds, "detected": len(rows),
            "detection_delay_ms": _stats(det), "onset_to_alarm_ms": _stats(ons),
            "settling_ms": _stats(st), "quiet_ms": _stats(qt),
            "override_min_pct": _stats(fmin, scale=1.0),
        }
    return out


def _stats(a: np.ndarray, scale: float = 1e3) -> dict:
    if a.size == 0:
        return {"median": None, "max": None}
    return {"median": float(np.median(a)) * scale, "max": float(a.max()) * scale}


def markdown(r: dict) -> str:
    s = r["step"]
    w, c, i, b, n = (s["wall"], s["cpu"], s["intrinsic"], s["baseline_wavedec_cpu"], s["band_cpu"])
    ok_i = s["of_cycle_intrinsic"]["4ms"] < 0.5
    ok_wall = s["of_cycle_wall"]["4ms"] < 0.5
    lines = [
        "| figure | this run | target / thesis | verdict |", "|---|---|---|---|",
        f"| supervisor step, {s['steps']:,} closed-loop steps × {s['repeats']} identical repeats, "
        f"per-step minimum (p50 / p99 / p99.9 / worst) | {i['p50_ms']:.3f} / {i['p99_ms']:.3f} / "
        f"{i['p999_ms']:.3f} / {i['max_ms']:.3f} ms | well inside 4 ms (KR C4) and 12 ms (KR C2), "
        f"worst case | worst = {s['of_cycle_intrinsic']['4ms']:.0%} of 4 ms, "
        f"{s['of_cycle_intrinsic']['12ms']:.0%} of 12 ms: {'met' if ok_i else 'NOT met'} |",
        f"| same steps, every run, wall time as measured (preemption and VM steal included) | "
        f"{w['p50_ms']:.3f} / {w['p99_ms']:.3f} / {w['p999_ms']:.3f} / {w['max_ms']:.3f} ms | same | "
        f"worst = {s['of_cycle_wall']['4ms']:.0%} of 4 ms: "
        f"{'met' if ok_wall else WALL_NOT_MET} |",
        (f"| detection computation: the steps that raise an alarm ({s['alarm_steps']:,}), per-step "
         f"minimum, p50 / worst | {s['alarm_step']['p50_ms']:.3f} / {s['alarm_step']['max_ms']:.3f} ms"
         f" | thesis ≈ 5 ms (read as computation) | "
         f"{'met' if s['alarm_step']['max_ms'] <= 5 else 'NOT met'} |") if s.get("alarm_step") else
        "| detection computation | no alarm in the run | — | — |",
        f"| same steps, thread CPU time | {c['p50_ms']:.3f} / {c['p99_ms']:.3f} / {c['p999_ms']:.3f} / "
        f"{c['max_ms']:.3f} ms | — | — |",
        f"| streaming band alone (40 samples, level {s['level']}, {s['filter_taps']} taps), CPU p50 / worst"
        f" | {n['p50_ms']:.3f} / {n['max_ms']:.3f} ms | — | "
        f"{b['p50_ms'] / n['p50_ms']:.1f}× faster than the baseline (median) |",
        f"| baseline: full pywt.wavedec of a {s['filter_taps']}-sample window per step, CPU p50 / worst"
        f" | {b['p50_ms']:.3f} / {b['max_ms']:.3f} ms | — | — |",
    ]
    for robot, v in r.get("real_time", {}).items():
        lines.append(f"| whole loop iteration in real time, {robot.upper()} sim + UDP DAQ in the same "
                     f"process (p99 / worst; overruns) | {v['iteration_p99_ms']:.3f} / "
                     f"{v['iteration_max_ms']:.3f} ms; {v['overruns']} of {v['steps']} | inside the "
                     f"cycle | {'met' if v['overruns'] == 0 else OVERRUNS_SEEN} |")
    for w, v in r["closed_loop"].items():
        d, o, st, q = v["detection_delay_ms"], v["onset_to_alarm_ms"], v["settling_ms"], v["quiet_ms"]
        tag = " (default)" if w == "db4" else ""
        lines.append(
            f"| {w}{tag}: detection delay, median / worst of {v['detected']}/{v['runs']} runs | "
            f"{_f(d['median'])} / {_f(d['max'])} ms (onset to alarm {_f(o['median'])} ms) | thesis ≈ 5 ms"
            f" | {'met' if d['max'] is not None and d['max'] <= 5 else 'NOT met: the band filter delay'} |")
        lines.append(
            f"| {w}{tag}: closed-loop settling (alarm → chatter under the visible level), median / worst"
            f" | {_f(st['median'])} / {_f(st['max'])} ms (band quiet after {_f(q['median'])} ms) | "
            f"thesis 270–300 ms | {_verdict(st['max'])} |")
    return "\n".join(lines)


def _f(x: float | None) -> str:
    return "—" if x is None else f"{x:.0f}"


def _verdict(worst_ms: float | None) -> str:
    if worst_ms is None:
        return "—"
    return "met (≤ 300 ms)" if worst_ms <= THESIS_CLOSED_LOOP_S[1] * 1e3 else "NOT met (> 300 ms)"


def run(steps: int = 100_000, seeds: int = 8, real_time_s: float = 5.0, log=print,
        repeats: int = 5) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        log("supervisor: step latency ...")
        r = {"step": step_latency(steps, folder, repeats)}
        if real_time_s > 0:
            log("supervisor: loop in real time with the sims ...")
            r["real_time"] = loop_latency_real_time(folder, real_time_s)
        log("supervisor: detection delay and settling ...")
        r["closed_loop"] = closed_loop(seeds, folder)
    return r


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--steps", type=int, default=100_000, help="steps timed (default 100000)")
    ap.add_argument("--seeds", type=int, default=8, help="closed-loop runs per wavelet (default 8)")
    ap.add_argument("--real-time-s", type=float, default=5.0, help="real-time loop run per robot [s]")
    ap.add_argument("--repeats", type=int, default=5, help="identical repeats of the timed run")
    ap.add_argument("--json", action="store_true", help="print JSON instead of a table")
    args = ap.parse_args(argv)
    r = run(args.steps, args.seeds, args.real_time_s, log=lambda s: print(s, file=sys.stderr),
            repeats=args.repeats)
    print(json.dumps(r, indent=2) if args.json else markdown(r))
    return r


if __name__ == "__main__":
    main()
