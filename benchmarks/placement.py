"""Placement studies on Dask: serial against a LocalCluster of 2 workers, per-placement cost,
scheduler overhead per task, the screen's pruning, and the demo's best placement against its own.

All in this run, on the bundled demo job and its default grid (the robot's reachable box around
its own ``$BASE``: 5 × 5 × 3 placements, plus the own):

* **baseline — serial**: every placement planned in this process, one after the other
  (``--scheduler none``), after one warm-up plan (the CasADi Functions built);
* **two bare processes** (the machine's ceiling, not a product path): the same placements through
  ``concurrent.futures.ProcessPoolExecutor(2)``, each process warmed up first — what two cores of
  this machine give without any scheduler, so that Dask's own cost shows apart from the machine's;
* **LocalCluster(2)**: the same placements on two worker processes of one thread each, each
  worker warmed up by one plan first (its cache built); its results must equal the serial ones,
  placement for placement, or nothing is reported. The cluster's start and the warm-up are
  reported apart. The three runs are interleaved in rounds of a quarter of the placements each,
  so that the load of a shared machine falls on all three alike; the workers' CPU time says how
  much of a core each got;
* **scheduler overhead per task**: trivial tasks (``operator.add``) through the same engine map
  (keyed submit, ``as_completed``, gather) — the cost of a task that does nothing;
* **the screen** (reach and ceilings at ~64 samples) at its default ratio: how many placements it
  prunes, and whether it keeps the best placement of the full grid;
* **the demo's best placement** (grid, then Nelder–Mead refinement) against its own: cycle times.

The sizing estimate of docs/placement.md (workers for a 10,000-placement × 20-job study in one hour,
and where the scheduler becomes the bottleneck) is computed from these figures; ``--docs`` writes it
into that page's marked block. Run from the repository root:
``python benchmarks/placement.py [--json] [--docs]``.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import operator
import os
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

#: The target of the issue: LocalCluster(2) against serial on this 2-core machine.
TARGET_SPEEDUP = 1.7
#: Rounds the serial, bare and LocalCluster runs are interleaved in (a shared machine's load
#: changes by the minute: each sees the same).
CHUNKS = 4
#: Trivial tasks timed for the scheduler overhead.
NOOP_TASKS = 2000
#: The sizing question: placements × jobs, finished within this wall time [s].
SIZING_PLACEMENTS, SIZING_JOBS, SIZING_WALL_S = 10_000, 20, 3600.0
PAGE = ROOT / "docs" / "placement.md"
SIZING_START, SIZING_END = "<!-- placement-sizing:start -->", "<!-- placement-sizing:end -->"


def run(log=lambda s: print(s, file=sys.stderr, flush=True)) -> dict:
    import psutil

    from planner.demo import demo_job_file
    from planner.place.engine import SerialEngine, open_engine
    from planner.place.grid import default_grid, own_placement
    from planner.place.screen import SCREEN_RATIO
    from planner.place.search import run_study
    from planner.place.spec import JobSpec, job_of
    from planner.place.study import evaluate_placement

    spec = JobSpec.from_file(demo_job_file())
    job = job_of(spec)
    grid = default_grid(job)
    own = own_placement(job)
    load0 = os.getloadavg()[0]
    if not evaluate_placement(spec, own).feasible:  # also the serial warm-up
        raise SystemExit("the demo's own placement has no plan: nothing to compare")
    placements = list({q.key: q for q in [own, *grid.placements()]}.values())
    plans = len(placements)
    chunks = [placements[i::CHUNKS] for i in range(CHUNKS)]

    def keyed(chunk):
        return [(f"{spec.digest[:16]}-{q.key}", q) for q in chunk]

    log("placement: LocalCluster(2) ...")
    t = time.perf_counter()
    eng = open_engine("local", workers=2)
    try:
        start_s = time.perf_counter() - t
        t = time.perf_counter()
        eng.run_on_workers(evaluate_placement, spec, own)
        warm_s = time.perf_counter() - t
        workers = [psutil.Process(pid) for pid in eng.run_on_workers(os.getpid).values()]
        serial_res, cluster_res = {}, {}
        serial_s = serial_cpu = cluster_s = worker_cpu = bare_s = 0.0
        with _bare_pool(spec, own) as pool:
            for k, chunk in enumerate(chunks):  # interleaved: all three see the same load
                log(f"placement: round {k + 1}/{CHUNKS} ({len(chunk)} placements): serial, two "
                    "bare processes, LocalCluster(2) ...")
                t, c = time.perf_counter(), time.process_time()
                out = SerialEngine().map(evaluate_placement, spec, spec.digest, keyed(chunk))
                serial_s += time.perf_counter() - t
                serial_cpu += time.process_time() - c
                serial_res.update(out.results)
                t = time.perf_counter()
                list(pool.map(evaluate_placement, [spec] * len(chunk), chunk))
                bare_s += time.perf_counter() - t
                c = sum(_cpu(w) for w in workers)
                t = time.perf_counter()
                out = eng.map(evaluate_placement, spec, spec.digest, keyed(chunk))
                cluster_s += time.perf_counter() - t
                worker_cpu += sum(_cpu(w) for w in workers) - c
                cluster_res.update(out.results)
        if len(cluster_res) != plans or any(cluster_res[k] != serial_res[k] for k in serial_res):
            raise SystemExit("LocalCluster results differ from the serial ones: nothing to time")
        log(f"placement: {NOOP_TASKS} trivial tasks ...")
        items = [(f"noop-{i}", i) for i in range(NOOP_TASKS)]
        noop = eng.map(operator.add, 0, "noop", items)
        if len(noop.results) != NOOP_TASKS:
            raise SystemExit("trivial tasks went missing")
        log("placement: screen + refinement on the cluster ...")
        t = time.perf_counter()
        screened = run_study(spec, grid, eng, screen=SCREEN_RATIO, refine_best=True)
        screened_s = time.perf_counter() - t
    finally:
        eng.close()

    results = list(serial_res.values())
    grid_keys = {q.key for q in grid.placements()}
    ok = [r for r in results if r.feasible and r.placement.key in grid_keys]
    full_best = min(ok, key=lambda r: r.score) if ok else None
    own_res = next(r for r in results if r.placement.key == own.key)
    kept = {r.placement.key for r in screened.results}
    feas = [r.wall_time for r in results if r.feasible]
    infeas = [r.wall_time for r in results if not r.feasible]
    screen_walls = [s.wall_time for s in screened.screen or []]
    ref = screened.refinement
    return {
        "machine": {"nproc": len(os.sched_getaffinity(0)), "load_1min_start": load0,
                    "load_1min_end": os.getloadavg()[0]},
        "grid": {"shape": list(grid.shape), "placements": len(grid), "plans": plans},
        "rounds": CHUNKS, "serial_s": serial_s, "serial_cpu_s": serial_cpu,
        "cluster": {"workers": 2, "start_s": start_s, "warm_up_s": warm_s, "study_s": cluster_s,
                    "speedup": serial_s / cluster_s, "identical_to_serial": True,
                    "worker_cpu_share": worker_cpu / (2 * cluster_s)},
        "bare": {"processes": 2, "study_s": bare_s, "speedup": serial_s / bare_s,
                 "dask_vs_bare": bare_s / cluster_s},
        "per_placement_s": {"mean": serial_s / plans,
                            "feasible_median": statistics.median(feas) if feas else None,
                            "feasible_max": max(feas) if feas else None,
                            "infeasible_median": statistics.median(infeas) if infeas else None,
                            "feasible": len(feas), "infeasible": len(infeas)},
        "scheduler": {"tasks": NOOP_TASKS, "wall_s": noop.wall_time,
                      "per_task_ms": 1e3 * noop.wall_time / NOOP_TASKS},
        "screen": {"ratio": SCREEN_RATIO, "screened": len(screened.screen or []),
                   "pruned": len(screened.pruned),
                   "pruning_ratio": len(screened.pruned) / max(1, len(screened.screen or [])),
                   "per_screen_median_s": statistics.median(screen_walls) if screen_walls else None,
                   "per_screen_mean_s": (statistics.fmean(screen_walls) if screen_walls else None),
                   "kept_full_grid_best": full_best is not None and full_best.placement.key in kept,
                   "study_s": screened_s},
        "best_vs_own": {
            "own": own.as_json(), "own_cycle_s": own_res.cycle_time,
            "grid_best": full_best.placement.as_json() if full_best else None,
            "grid_best_cycle_s": full_best.cycle_time if full_best else None,
            "refined_best": screened.best.placement.as_json() if screened.best else None,
            "refined_best_cycle_s": screened.best.cycle_time if screened.best else None,
            "refine_plans": len(ref.evaluated) if ref else 0,
        },
    }


def _warm(spec, own) -> None:
    from planner.place.study import evaluate_placement

    evaluate_placement(spec, own)


@contextlib.contextmanager
def _bare_pool(spec, own):
    """Two warmed-up bare processes (the machine's ceiling, no scheduler)."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    ctx = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(2, mp_context=ctx, initializer=_warm, initargs=(spec, own)) as pool:
        list(pool.map(_warm, [spec, spec], [own, own]))  # both processes started and warm
        yield pool


def _cpu(p) -> float:
    c = p.cpu_times()
    return c.user + c.system


def sizing(r: dict) -> dict:
    """Workers for the sizing question, and the worker count where the scheduler binds."""
    c = r["per_placement_s"]["mean"]
    eff = r["cluster"]["speedup"] / r["cluster"]["workers"]
    o = r["scheduler"]["per_task_ms"] * 1e-3
    plans = SIZING_PLACEMENTS * SIZING_JOBS
    s = r["screen"]
    keep = 1.0 - s["pruning_ratio"]
    c_screen = (s["per_screen_mean_s"] or 0.0) + keep * c
    return {
        "plans": plans, "plan_s": c, "efficiency": eff, "task_overhead_s": o,
        "workers_full": math.ceil(plans * c / (SIZING_WALL_S * eff)),
        "workers_screened": math.ceil(plans * c_screen / (SIZING_WALL_S * eff)),
        "screened_plan_s": c_screen,
        "task_rate_needed_per_s": plans / SIZING_WALL_S,
        "task_rate_needed_screened_per_s": 2 * plans / SIZING_WALL_S,
        "scheduler_tasks_per_s": 1.0 / o,
        "scheduler_binds_at_workers": math.floor(c / o),
        "scheduler_binds_at_workers_screen": math.floor((s["per_screen_mean_s"] or c) / o),
    }


def markdown(r: dict) -> str:
    cl, pp, sc, bo = r["cluster"], r["per_placement_s"], r["screen"], r["best_vs_own"]
    g = r["grid"]
    m = r["machine"]
    share = cl["worker_cpu_share"]
    busy = ("" if m["load_1min_start"] < 1.5 * m["nproc"] and share > 0.85 else
            f" The machine was shared (1-minute load {m['load_1min_start']:.1f} → "
            f"{m['load_1min_end']:.1f} on {m['nproc']} cores; each worker got {100 * share:.0f} % "
            "of a core): the absolute times are slower than on a quiet machine, and the speed-up "
            "is bounded by the bare-process row, not by the scheduler.")
    lines = [
        "| measure | serial (baseline) | LocalCluster(2) | ratio |", "|---|---:|---:|---:|",
        f"| {g['plans']} plans of the default grid ({' × '.join(map(str, g['shape']))}) + own, "
        f"interleaved in {r['rounds']} rounds | "
        f"{r['serial_s']:.1f} s | {cl['study_s']:.1f} s | **{cl['speedup']:.2f}×** "
        f"({'met' if cl['speedup'] >= TARGET_SPEEDUP else 'NOT met'}: ≥ {TARGET_SPEEDUP}×) |",
        f"| the workers' share of a core each while the cluster planned (1 = a core each) | | "
        f"{cl['worker_cpu_share']:.2f} | |",
        f"| the same on two bare processes (the machine's ceiling, no scheduler) | "
        f"{r['serial_s']:.1f} s | {r['bare']['study_s']:.1f} s | {r['bare']['speedup']:.2f}× "
        f"(Dask reaches {100 * r['bare']['dask_vs_bare']:.0f} % of it) |",
        "",
        "| figure | value |", "|---|---|",
        f"| per placement, mean over the grid (serial wall / plans) | {pp['mean']:.3f} s |",
        f"| per placement with a plan, median / max | {pp['feasible_median']:.3f} / "
        f"{pp['feasible_max']:.3f} s ({pp['feasible']} placements) |",
        f"| per placement without a plan (out of reach), median | "
        f"{(pp['infeasible_median'] or float('nan')):.3f} s ({pp['infeasible']} placements) |",
        f"| scheduler overhead per task ({r['scheduler']['tasks']} trivial tasks, same engine) | "
        f"{r['scheduler']['per_task_ms']:.2f} ms |",
        f"| LocalCluster start / warm-up (one plan per worker) | {cl['start_s']:.1f} s / "
        f"{cl['warm_up_s']:.1f} s |",
        f"| results identical to serial | {'yes' if cl['identical_to_serial'] else 'no'} |",
        f"| screen (ratio {sc['ratio']}): pruned | {sc['pruned']} of {sc['screened']} "
        f"({100 * sc['pruning_ratio']:.0f} %), {sc['per_screen_median_s']:.3f} s a screen "
        "(median) |",
        f"| screen kept the full grid's best | {'yes' if sc['kept_full_grid_best'] else 'NO'} |",
        f"| demo's own $BASE {_where(bo['own'])} | cycle {bo['own_cycle_s']:.1f} s |",
        f"| best of the grid {_where(bo['grid_best'])} | cycle {bo['grid_best_cycle_s']:.1f} s "
        f"({100 * (1 - bo['grid_best_cycle_s'] / bo['own_cycle_s']):.1f} % faster) |",
        f"| refined best {_where(bo['refined_best'])} ({bo['refine_plans']} plans) | cycle "
        f"{bo['refined_best_cycle_s']:.1f} s "
        f"({100 * (1 - bo['refined_best_cycle_s'] / bo['own_cycle_s']):.1f} % faster) |",
    ]
    return "\n".join(lines) + ("\n\n" + busy.strip() if busy else "")


def _where(p: dict | None) -> str:
    return "—" if p is None else f"[{p['x_mm']:g}, {p['y_mm']:g}, {p['z_mm']:g}] mm"


def sizing_markdown(r: dict) -> str:
    s = sizing(r)
    return "\n".join([
        f"From `benchmarks/placement.py` (its run of the tables above): a demo plan costs "
        f"{s['plan_s']:.2f} s of one core on average over the default grid (unreachable placements "
        f"cost more than reachable ones: their IK fails at every sample), two workers ran at "
        f"{100 * s['efficiency']:.0f} % parallel efficiency, and a task that does nothing costs "
        f"{1e3 * s['task_overhead_s']:.2f} ms end to end through the same engine.",
        "",
        "| question | estimate |", "|---|---|",
        f"| plans of a {SIZING_PLACEMENTS:,}-placement × {SIZING_JOBS}-job study | "
        f"{s['plans']:,} |",
        f"| workers (one core each) to finish in one hour, every placement planned | "
        f"**{s['workers_full']:,}** |",
        f"| the same with the screen first (keeps {100 * (1 - r['screen']['pruning_ratio']):.0f} %;"
        f" {s['screened_plan_s']:.2f} s a placement) | **{s['workers_screened']:,}** |",
        f"| tasks the scheduler must hand out | {s['task_rate_needed_per_s']:.0f} /s "
        f"({s['task_rate_needed_screened_per_s']:.0f} /s with the screen) |",
        f"| what one scheduler handed out here (1 / overhead per task) | "
        f"{s['scheduler_tasks_per_s']:,.0f} /s |",
        f"| workers beyond which the scheduler is the bottleneck (plan cost / task overhead) | "
        f"≈ {s['scheduler_binds_at_workers']:,} (≈ {s['scheduler_binds_at_workers_screen']:,} "
        "for the screen's cheaper tasks) |",
    ])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--docs", action="store_true",
                    help=f"write the sizing estimate into {PAGE.relative_to(ROOT)}")
    args = ap.parse_args()
    r = run()
    r["sizing"] = sizing(r)
    print(json.dumps(r, indent=2) if args.json else markdown(r) + "\n\n" + sizing_markdown(r))
    if args.docs:
        from run_all import replace_block

        if replace_block(PAGE, SIZING_START, SIZING_END, markdown(r) + "\n\n" + sizing_markdown(r)):
            print(f"wrote {PAGE}", file=sys.stderr)


if __name__ == "__main__":
    main()
