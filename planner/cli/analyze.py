"""``cctmill analyze`` and ``cctmill stability``: the point model at one pose.

Units at this edge carry their names (``--feed-mm-s``, ``--ae-mm``, ``--joints-deg``); JSON output
is SI (angles in degrees, named so).
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from models.errors import InputError
from planner.cli._common import add_output, add_point_flags, feed_range, point_setup
from planner.report.tables import analysis_json, analysis_table, characteristic_table

__all__ = ["register"]


def _cmd_analyze(args: argparse.Namespace) -> int:
    if not (np.isfinite(args.feed_mm_s) and args.feed_mm_s > 0):
        raise InputError("--feed-mm-s", f"must be positive, got {args.feed_mm_s}")
    model, q, cut = point_setup(args)
    a = model.analyze(q, cut, args.feed_mm_s * 1e-3)
    if args.json:
        print(json.dumps(analysis_json(a, model.params.cct), indent=2))
    else:
        print(analysis_table(a, model.params.cct))
    return 0


def _cmd_stability(args: argparse.Namespace) -> int:
    model, q, cut = point_setup(args)
    ch = model.characteristic(q, cut, feed_range(args.feed_range_mm_s), args.force_limit_n)
    if args.plot:
        from planner.report.plots import plot_characteristic

        plot_characteristic(ch, args.plot)
    if args.json:
        rows = []
        for p in ch.points:
            row = analysis_json(p, model.params.cct)
            row["feed_mm_s"] = p.feed * 1e3
            rows.append(row)
        print(json.dumps(rows, indent=2))
    else:
        print(characteristic_table(ch))
        if args.plot:
            print(f"plot: {args.plot}")
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``analyze`` and ``stability``."""
    pa = sub.add_parser("analyze", help="stiffness, forces and chatter verdict at one pose")
    add_point_flags(pa, with_feed=True)
    pa.set_defaults(run=_cmd_analyze)
    ps = sub.add_parser("stability", help="stability characteristic over a feed range")
    add_point_flags(ps, with_feed=False)
    ps.add_argument("--feed-range-mm-s", required=True, metavar="START:STOP:N",
                    help="feeds [mm/s], N evenly spaced values")
    ps.add_argument("--force-limit-n", type=float, default=300.0,
                    help="resultant force limit [N] (thesis: 300 N)")
    add_output(ps, "--plot", kind="file", metavar="FILE.png",
               help="write the characteristic as a plot")
    ps.set_defaults(run=_cmd_stability)
