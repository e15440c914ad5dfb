"""``cctmill inspect FILE|JOB.toml``: a CAM program's summary, or a job placed in its cell."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from planner.cli._common import add_output, add_reader_flags, reader_options

__all__ = ["inspect_table", "register"]


def inspect_table(summary: dict) -> str:
    bbox = summary["bbox_m"]
    feeds = summary["feed_mm_min"]
    rows = [
        f"file          {summary['file']}",
        f"format        {summary['format']} ({summary['units']})",
        f"moves         {summary['moves']}  (rapids {summary['rapids']}, arcs {summary['arcs']}"
        f", inverse-time {summary['inverse_time_moves']})",
        f"length        {summary['length_m']:.4f} m  (cutting {summary['cutting_length_m']:.4f} m)",
    ]
    if bbox:
        rows.append("bbox          " + "  ".join(
            f"{ax} {lo * 1e3:.3f}..{hi * 1e3:.3f}" for ax, lo, hi in zip("XYZ", *bbox,
                                                                        strict=True)) + " mm")
    if feeds:
        rows.append(f"feed          {feeds['min']:.1f} .. {feeds['max']:.1f} mm/min")
    n_axes = summary.get("tool_axes", 0)
    if not summary["has_tool_axis"]:
        axis = "+z only (3-axis)" if n_axes else "none given (3-axis)"
    elif summary.get("tool_axis_turning_moves", 0) == 0:
        axis = f"{n_axes} distinct ax{'is' if n_axes == 1 else 'es'} (indexed 3+2)"
    else:
        axis = (f"{n_axes} distinct axes, turned during {summary['tool_axis_turning_moves']} "
                "feed moves (simultaneous 5-axis)")
    rows.append(f"tool axis     {axis}")
    if summary["skipped"]:
        rows.append("skipped       " + ", ".join(f"{k} {v}" for k, v in
                                                sorted(summary["skipped"].items())))
    groups = summary.get("warning_groups")
    if groups is None:
        rows.append(f"warnings      {len(summary['warnings'])}")
        rows += [f"  {w}" for w in summary["warnings"][:20]]
        if len(summary["warnings"]) > 20:
            rows.append(f"  ... {len(summary['warnings']) - 20} more (use --json)")
    else:
        total = sum(g["count"] for g in groups)
        rows.append(f"warnings      {total}" + (f" ({len(groups)} kinds; every one with --json)"
                                                if total > len(groups) else ""))
        for g in groups:
            more = f" ({g['count']} in all)" if g["count"] > 1 else ""
            rows.append(f"  {g['kind']}: {g['first']}: {g['message']}{more}")
    return "\n".join(rows)


def _cmd_inspect(args: argparse.Namespace) -> int:
    from robot_io.readers import read_toolpath
    from robot_io.toolpath import summarize

    target = Path(args.file)
    if target.suffix.lower() == ".toml":
        from planner.job import load_job
        from planner.prepare import inspect_job, prepare

        job = load_job(target)
        # progress bars on stderr, on a terminal only (planner/_progress.py): silent in scripts
        prep = prepare(job, progress=True)
        out = inspect_job(prep)
        infeasible = None
        if out["reachability"]["all_reachable"]:  # a job that cannot be cut fails as in plan
            from planner.plan import PlanInfeasibleError, check_feasible

            try:
                check_feasible(prep, progress=True)
            except PlanInfeasibleError as e:
                infeasible = str(e)
            out["feasible"] = {"ok": infeasible is None, "reason": infeasible}
        if args.plot:
            from planner.report.plots import plot_path_kinematics

            e, k = prep.engagement, prep.kinematics
            plot_path_kinematics(prep.path.s, k.q, prep.robot.data.lower, prep.robot.data.upper,
                                 k.joint_names, k.reachable, e.a_e, e.a_p, e.mode, args.plot,
                                 title=f"{job.job.name}: joints and engagement along the path")
        if args.json:
            print(json.dumps(out, indent=2))
        else:
            for tp in out["toolpaths"]:
                print(inspect_table(tp))
            r, e = out["reachability"], out["engagement"]
            print(f"samples       {out['samples']} over {out['path_length_m']:.4f} m")
            print(f"reachable     {'all' if r['all_reachable'] else 'NO'}"
                  f" ({r['unreachable_samples']} unreachable)")
            for line in r["problems"]:
                print(f"  {line}")
            for name, (lo, hi) in r["joint_range_deg"].items():
                print(f"  {name} {lo:8.2f} .. {hi:8.2f} deg")
            print(f"engagement    {e['source']}: " + ", ".join(f"{k} {v}" for k, v in e["modes"].items()))
            for key in ("ae_mm", "ap_mm"):
                if e[key]:
                    print(f"  {key[:2]} {e[key]['min']:.3f} / {e[key]['mean']:.3f} / "
                          f"{e[key]['max']:.3f} mm (min/mean/max)")
            if "feasible" in out:
                print(f"feasible      {'yes' if infeasible is None else 'NO'}"
                      + ("" if infeasible is None else f" ({infeasible})"))
            for w in e["warnings"] + out["warnings"]:
                print(f"  warning: {w}")
            if args.plot:
                print(f"plot: {args.plot}")
        if not out["reachability"]["all_reachable"]:
            r = out["reachability"]
            first = r["problems"][0] if r["problems"] else ""
            print(f"cctmill inspect: error: {r['unreachable_samples']} samples of job "
                  f"{out['job']} cannot be reached; {first}".rstrip("; "), file=sys.stderr)
            return 2
        if infeasible is not None:
            print(f"cctmill inspect: error: job {out['job']} cannot be cut: {infeasible}",
                  file=sys.stderr)
            return 2
        return 0
    from robot_io.diagnostics import group_warnings
    from robot_io.options import speaking

    with speaking("cli"):
        tp = read_toolpath(target, strict=not args.lenient, format=args.format,
                           **reader_options(args))
    summary = summarize(tp)
    summary["warning_groups"] = [g.as_json() for g in group_warnings([tp])]
    print(json.dumps(summary, indent=2) if args.json else inspect_table(summary))
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``inspect``."""
    pi = sub.add_parser("inspect", help="summary of a toolpath file, or of a job (reachability, "
                                       "engagement)")
    pi.add_argument("file", help="toolpath (.nc/.ngc/.apt/.cl/.src) or job file (.toml)")
    pi.add_argument("--json", action="store_true", help="print JSON (SI)")
    add_reader_flags(pi)
    add_output(pi, "--plot", kind="file", metavar="FILE.png",
                    help="(job) joint angles and engagement along the path")
    pi.set_defaults(run=_cmd_inspect)
