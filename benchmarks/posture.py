"""Posture along the path: cycle times with today's posture and with the rotation about the tool
axis chosen along the whole path (:mod:`planner.posture`), on the demo cell and the off-axis cell.

For each cell (``planner/data/demo/demo_job.toml``, spindle on the A6 axis, and
``planner/data/demo_offaxis/demo_offaxis_job.toml``, spindle mounted off it — docs/posture.md):

* the thesis baseline (today's posture, the thesis section algorithm: docs/model.md §8);
* every other feed method of the planner (``optimize``, and any method the planner has beside
  ``thesis`` and ``constant``), with today's posture and with the path posture;
* the *pointwise bound*: every cut sample at its own ceiling (a section per sample), toppra-timed —
  the fastest any feed plan could be with that posture;
* the same with ``[export] compensate_deflection``: the deflection tolerance then holds
  u·‖δ‖ + the change of δ along each LIN (:meth:`planner.limits.Limits.deflection_held`,
  u = ``deflection_model_uncertainty``), as the export's compensation leaves it;
* the posture itself: the DP's estimate of the cut time today / chosen, the offset range, the
  largest rate, the independent posture check (continuity, rate, limits, wrist), and its wall time;
* the independent plan checker (:mod:`planner.check`) on every posture plan.

Then the long job: the off-axis cell sampled every 0.15 mm (10,649 samples), prepared with the path
posture and planned, in a child process (its own peak memory, ``ru_maxrss``).

Targets (issue): on the off-axis cell the fastest method with the posture at least 25 % shorter
than the thesis; the 10,649-sample job planned with the posture in < 30 s, peak memory < 2 GB.

Run from the repository root: ``python benchmarks/posture.py [--json]``.
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import time
import tomllib
from importlib import resources
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

TARGET_GAIN = 0.25        # off-axis cell: posture plan ≥ 25 % shorter than the thesis
TARGET_LONG_S = 30.0      # long job planned with the posture in < 30 s
TARGET_LONG_MB = 2048.0   # peak memory < 2 GB
LONG_STEP_MM = 0.15       # sample spacing of the long job [mm]
CELLS = {"demo": "data/demo/demo_job.toml", "offaxis": "data/demo_offaxis/demo_offaxis_job.toml"}


def _job(cell: str, step_mm: float | None = None):
    from planner.job import parse_job

    path = Path(str(resources.files("planner").joinpath(CELLS[cell])))
    doc = tomllib.loads(path.read_text(encoding="utf-8"))
    if step_mm is not None:
        doc["path"]["step_max_mm"] = step_mm
        doc["job"]["name"] += "_long"
    return parse_job(doc, str(path), path.parent)


def _methods() -> list[str]:
    from planner.plan import METHODS

    return [m for m in METHODS if m not in ("thesis", "constant")]


def _pointwise(res) -> dict:
    """The pointwise bound of a profiled plan: every cut sample at its own ceiling, toppra-timed
    with the joint speed and acceleration and the path acceleration, no jerk limit (the bound the
    feed profile is measured against; ``benchmarks/plan_speed.py``)."""
    import numpy as np

    from planner.sections import CUT, step_lengths

    feed = res.feed.copy()
    feed[res.model.index] = res.ceilings.feed
    ds = step_lengths(res.prep.path.s)
    cut = res.kinds == CUT
    return {"cycle_time_s": res.profile.bound_cycle_time,
            "cut_time_s": float(np.sum(ds[cut] / feed[cut]))}


def _row(res, check: bool) -> dict:
    row = {"cycle_time_s": res.cycle_time, "cut_time_s": res.cut_time,
           "sections": len(res.sections)}
    if check:
        from planner.check import check_result

        rep = check_result(res)
        row.update({"check_ok": rep.ok, "violations": len(rep.violations)})
    return row


def _compensated_row(res, check: bool) -> dict:
    """A plan under the compensated deflection rule: the independent checker holds
    u·‖δ‖ + ‖δ_k − δ_(k−1)‖ itself (:mod:`planner.check`); the largest ‖δ‖ and held value beside."""
    row = _row(res, check)
    row.update({"deflection_max_mm": float(res.evaluation.deflection_norm.max() * 1e3),
                "deflection_held_max_mm": float(res.evaluation.deflection_held.max() * 1e3)})
    return row


def run_cell(cell: str, check: bool = True) -> dict:
    """Every plan of one cell, today's posture and the path posture."""
    import dataclasses

    import numpy as np

    from planner.limits import Limits
    from planner.plan import plan_prepared
    from planner.posture import check_posture
    from planner.prepare import prepare

    job = _job(cell)
    t = time.perf_counter()
    today = prepare(job, posture="first_sample")
    prep_s = time.perf_counter() - t
    t = time.perf_counter()
    path = prepare(job, posture="path")
    path_s = time.perf_counter() - t
    po = path.posture
    pc = check_posture(path, po.offset, job.kinematics.posture_rate_deg_per_mm)
    out: dict = {"cell": cell, "samples": len(today.path), "prepare_s": prep_s,
                 "prepare_posture_s": path_s, "plans": {}}
    comp = dataclasses.replace(Limits.from_job(job), compensate_deflection=True)
    th = plan_prepared(today, "thesis")
    out["plans"]["thesis"] = _row(th, check)
    for m in _methods():
        r0 = plan_prepared(today, m)
        r1 = plan_prepared(path, m)
        out["plans"][m] = _row(r0, check)
        out["plans"][m + "+posture"] = _row(r1, check)
        r2 = plan_prepared(path, m, limits=comp)
        out["plans"][m + "+posture+compensation"] = _compensated_row(r2, check)
        if r0.profile is not None:
            out["pointwise"] = _pointwise(r0)
            out["pointwise+posture"] = _pointwise(r1)
            out["pointwise+posture+compensation"] = _pointwise(r2)
    off = np.degrees(po.offset)
    out["posture"] = {
        "dp_cut_time_today_s": po.time_today, "dp_cut_time_chosen_s": po.time_chosen,
        "dp_gain": po.gain, "offset_deg": [float(off.min()), float(off.max())],
        "rate_max_deg_per_mm": float(np.degrees(po.rate_max) * 1e-3),
        "rate_bound_deg_per_mm": job.kinematics.posture_rate_deg_per_mm,
        "stations": int(po.stations.size), "rows": int(po.rows.size),
        "fallback": po.fallback, "check_ok": pc.ok, "wall_s": po.wall_times,
    }
    best = min(v["cycle_time_s"] for k, v in out["plans"].items() if k.endswith("+posture"))
    out["best_posture_cycle_s"] = best
    out["gain_vs_thesis"] = 1.0 - best / out["plans"]["thesis"]["cycle_time_s"]
    return out


def run_long() -> dict:
    """The off-axis cell every 0.15 mm, prepared with the path posture and planned."""
    from planner.plan import plan_prepared
    from planner.prepare import prepare

    job = _job("offaxis", LONG_STEP_MM)
    t = time.perf_counter()
    prep = prepare(job, posture="path")
    prep_s = time.perf_counter() - t
    method = _methods()[0]
    t = time.perf_counter()
    res = plan_prepared(prep, method)
    plan_s = time.perf_counter() - t
    return {"samples": len(prep.path), "method": method, "prepare_s": prep_s, "plan_s": plan_s,
            "total_s": prep_s + plan_s, "posture_s": prep.wall_times.get("posture_s"),
            "posture_stages_s": prep.posture.wall_times, "posture_gain": prep.posture.gain,
            "fallback": prep.posture.fallback, "cycle_time_s": res.cycle_time,
            "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0}


def _child_long() -> dict:
    cmd = [sys.executable, str(Path(__file__).resolve()), "--child-long"]
    proc = subprocess.run(cmd, capture_output=True, text=True, check=True, cwd=str(ROOT))
    return json.loads(proc.stdout.strip().splitlines()[-1])


def run(long: bool = True, check: bool = True) -> dict:
    cells = {c: run_cell(c, check) for c in CELLS}
    out: dict = {"cells": cells}
    targets = {"offaxis_gain": cells["offaxis"]["gain_vs_thesis"] >= TARGET_GAIN,
               "posture_checked_ok": all(c["posture"]["check_ok"] for c in cells.values())}
    if check:
        targets["every_plan_checked_ok"] = all(p["check_ok"] for c in cells.values()
                                               for p in c["plans"].values())
    if long:
        lg = _child_long()
        out["long"] = lg
        targets["long_time"] = lg["total_s"] < TARGET_LONG_S
        targets["long_memory"] = lg["peak_rss_mb"] < TARGET_LONG_MB
    out["targets"] = targets
    return out


def markdown(r: dict) -> str:
    lines = ["| cell | plan | cycle [s] | vs thesis | cut Σ L/f [s] | sections | checker |",
             "|---|---|---:|---:|---:|---:|---|"]
    for name, c in r["cells"].items():
        th = c["plans"]["thesis"]["cycle_time_s"]
        rows = list(c["plans"].items()) + [
            ("pointwise bound", c["pointwise"]),
            ("pointwise bound+posture", c["pointwise+posture"]),
            ("pointwise bound+posture+compensation", c["pointwise+posture+compensation"])]
        for plan, p in rows:
            chk = ("—" if "check_ok" not in p else
                   "0 violations" if p["check_ok"] else f"{p['violations']} violations")
            lines.append(f"| {name} | {plan} | {p['cycle_time_s']:.1f} | "
                         f"{100 * (1 - p['cycle_time_s'] / th):+.1f} % | {p['cut_time_s']:.1f} | "
                         f"{p.get('sections', '—')} | {chk} |")
    lines += ["", "| cell | DP cut time today → chosen [s] | gain | offset [deg] | rate max / bound "
              "[deg/mm] | posture check | posture wall [s] |", "|---|---:|---:|---:|---:|---|---:|"]
    for name, c in r["cells"].items():
        p = c["posture"]
        lines.append(f"| {name} | {p['dp_cut_time_today_s']:.1f} → {p['dp_cut_time_chosen_s']:.1f} "
                     f"| {100 * p['dp_gain']:.1f} % | {p['offset_deg'][0]:.0f} … "
                     f"{p['offset_deg'][1]:.0f} | {p['rate_max_deg_per_mm']:.2f} / "
                     f"{p['rate_bound_deg_per_mm']:.2f} | {'ok' if p['check_ok'] else 'FAILED'}"
                     f"{' (fallback: ' + p['fallback'] + ')' if p['fallback'] else ''} | "
                     f"{max(c['prepare_posture_s'] - c['prepare_s'], 0.0):.1f} |")
    t = r["targets"]
    off = r["cells"]["offaxis"]
    lines += ["", f"Off-axis cell: the fastest plan with the path posture is "
              f"{100 * off['gain_vs_thesis']:.1f} % shorter than the thesis (target ≥ "
              f"{100 * TARGET_GAIN:.0f} %: {'met' if t['offaxis_gain'] else 'NOT met'})."]
    if "long" in r:
        lg = r["long"]
        lines.append(f"Long job: {lg['samples']:,} samples prepared with the path posture and "
                     f"planned ({lg['method']}) in {lg['total_s']:.1f} s (posture "
                     f"{lg['posture_s']:.1f} s; target < {TARGET_LONG_S:.0f} s: "
                     f"{'met' if t['long_time'] else 'NOT met'}), peak memory "
                     f"{lg['peak_rss_mb']:.0f} MB (target < 2 GB: "
                     f"{'met' if t['long_memory'] else 'NOT met'}).")
    return "\n".join(lines)


def summary_rows(r: dict) -> list[tuple[str, str, str, str]]:
    """Rows of the performance page's summary table: (what, measured, target, verdict)."""

    def verdict(ok: bool) -> str:
        return "met" if ok else "NOT met"

    off, t = r["cells"]["offaxis"], r["targets"]
    rows = [("posture: off-axis cell, fastest plan with the path posture vs thesis",
             f"{off['best_posture_cycle_s']:.1f} vs {off['plans']['thesis']['cycle_time_s']:.1f} s "
             f"({100 * off['gain_vs_thesis']:.1f} % shorter; DP cut-time estimate "
             f"{100 * off['posture']['dp_gain']:.1f} % below today's posture)",
             f"≥ {100 * TARGET_GAIN:.0f} % shorter than thesis", verdict(t["offaxis_gain"]))]
    if "long" in r:
        lg = r["long"]
        rows.append((f"posture: {lg['samples']:,}-sample off-axis job with the path posture, "
                     "prepared + planned, peak memory",
                     f"{lg['total_s']:.1f} s (posture {lg['posture_s']:.1f} s), "
                     f"{lg['peak_rss_mb']:.0f} MB", f"< {TARGET_LONG_S:.0f} s, < 2 GB",
                     verdict(t["long_time"] and t["long_memory"])))
    return rows


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--json", action="store_true", help="print JSON")
    ap.add_argument("--no-long", action="store_true", help="skip the 10,649-sample job")
    ap.add_argument("--no-check", action="store_true", help="skip the plan checker")
    ap.add_argument("--child-long", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child_long:
        print(json.dumps(run_long()))
        return {}
    r = run(long=not args.no_long, check=not args.no_check)
    print(json.dumps(r, indent=2) if args.json else markdown(r))
    return r


if __name__ == "__main__":
    main()
