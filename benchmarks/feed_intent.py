"""The programmed feed as the user's intent: what the round-two rules change on the demo job.

All in this run, on the bundled demo job, ``optimize`` and ``thesis`` each (toppra-timed cycle):

* **baseline — round one's rules**: air moves at ``feed_max``, a plunge's programmed feed over its
  whole air run (the lateral moves after it included), rapids at the rapid speed; no cap from the
  programmed feed or the tool. Emulated here on this run's plan (its cut sections kept, the non-cut
  sections rebuilt by the old rule and re-timed), so the figure is of this code, not a pasted one.
* **air/plunge fix**: air moves as programmed (capped by the rapid speed), a plunge's feed over
  the plunge only; still no programmed-feed or tool cap.
* **+ tool chip load**: the tool's largest feed per tooth caps every ceiling.
* **default factor 1.0**: no cut faster than its programmed feed (what a job gets by default).
* **the demo's factor 2.0**: the bracket program is written at F1200 where the process allows more;
  the demo lets the planner raise feeds up to twice the programmed one (= feed_max_mm_s).

Every plan is run through the independent checker. Run from the repository root:
``python benchmarks/feed_intent.py [--json]``.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tomllib
from dataclasses import replace
from importlib import resources
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))


def _job(scale: float):
    from planner.job import parse_job

    demo = Path(str(resources.files("planner").joinpath("data/demo/demo_job.toml")))
    doc = tomllib.loads(demo.read_text(encoding="utf-8"))
    doc["limits"]["cam_feed_scale_max"] = scale
    return parse_job(doc, str(demo), demo.parent)


def _round_one_cycle(res) -> float:
    """The cycle of ``res`` with its non-cut sections rebuilt by round one's rule, re-timed."""
    import numpy as np

    from planner.sections import AIR, CUT, RAPID, kind_runs
    from planner.timing import time_path

    lim, path = res.limits, res.prep.path
    feed = res.feed.copy()
    plunge = res.prep.engagement.plunge
    for a, b, kind in kind_runs(res.kinds):
        if kind == RAPID:
            feed[a:b] = lim.rapid_speed
        elif kind == AIR:
            f = lim.feed_max
            if plunge is not None and np.any(plunge[a:b]):
                p = path.feed[a:b][plunge[a:b]]
                p = p[np.isfinite(p)]
                if p.size:
                    f = float(np.clip(p.min(), lim.feed_min, lim.feed_max))
            feed[a:b] = f
        else:
            assert kind == CUT
    data = res.prep.robot.data
    return time_path(path.s, res.prep.kinematics.q, feed, data.velocity, data.acceleration,
                     lim.path_acc_max, lim.path_jerk_max).cycle_time


def run() -> dict:
    from planner.check import check_result
    from planner.plan import plan_prepared
    from planner.prepare import prepare

    out: dict = {"methods": {}}
    for method in ("optimize", "thesis"):
        rows: dict = {}
        prep1 = prepare(_job(1.0))
        no_tool = replace(prep1, tool=replace(prep1.tool, feed_per_tooth_max=None))
        free = replace(plan_prepared(prep1, method).limits, cam_feed_scale_max=math.inf)
        res = plan_prepared(no_tool, method, limits=free)
        if method == "optimize" and not res.solver.success:
            raise SystemExit(f"optimize did not converge ({res.solver.status}): nothing to time")
        rows["round_one"] = {"cycle_time_s": _round_one_cycle(res), "check_ok": None}
        variants = [("air_plunge_fix", no_tool, free), ("tool_chip_load", prep1, free),
                    ("default_factor_1", prep1, None)]
        prep2 = prepare(_job(2.0))
        variants.append(("demo_factor_2", prep2, None))
        for name, prep, limits in variants:
            r = plan_prepared(prep, method, limits=limits)
            if method == "optimize" and not r.solver.success:
                raise SystemExit(f"{name}: optimize did not converge ({r.solver.status}): "
                                 "nothing to time")
            rep = check_result(r)
            rows[name] = {"cycle_time_s": r.cycle_time, "cut_time_s": r.cut_time,
                          "check_ok": rep.ok, "violations": len(rep.violations),
                          "binding_counts": _counts(r)}
        base = rows["round_one"]["cycle_time_s"]
        for row in rows.values():
            row["vs_round_one"] = row["cycle_time_s"] / base
        out["methods"][method] = rows
    return out


def _counts(res) -> dict:
    counts: dict = {}
    for s in res.plan_sections:
        counts[s.binding] = counts.get(s.binding, 0) + 1
    return counts


def markdown(r: dict) -> str:
    lines = ["| method | rules | cycle [s] | vs round one | checker |", "|---|---|---:|---:|---|"]
    names = {"round_one": "round one (air at feed_max, plunge feed over the air run)",
             "air_plunge_fix": "air as programmed, plunge over the plunge only",
             "tool_chip_load": "+ the tool's largest chip load",
             "default_factor_1": "+ programmed feed × 1.0 (the default)",
             "demo_factor_2": "+ programmed feed × 2.0 (the demo job)"}
    for method, rows in r["methods"].items():
        for key, row in rows.items():
            ok = "—" if row["check_ok"] is None else ("0 violations" if row["check_ok"]
                                                       else f"{row['violations']} violations")
            lines.append(f"| {method} | {names[key]} | {row['cycle_time_s']:.1f} | "
                         f"{row['vs_round_one']:.3f} | {ok} |")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    r = run()
    print(json.dumps(r, indent=2) if args.json else markdown(r))


if __name__ == "__main__":
    main()
