"""``cctmill demo [-o OUT]``: the bundled example, end to end (:func:`planner.demo.run_demo`)."""

from __future__ import annotations

import argparse
from pathlib import Path

from planner.cli._common import add_output

__all__ = ["register"]


def _cmd_demo(args: argparse.Namespace) -> int:
    from planner.demo import run_demo

    out = Path(args.output)
    demo = run_demo(out)
    for line in demo.lines:
        print(line + "\n")
    print("wrote:")
    for w in demo.written:
        print(f"  {w}")
    for note in demo.notes:
        print(f"note: {note}")
    h = demo.headline
    print(f"\nheadline: cycle time {h['cycle_time_s']:.1f} s vs {h['thesis_cycle_time_s']:.1f} s "
          f"for the thesis baseline ({100 * h['cycle_time_gain_vs_thesis']:.1f} % shorter); worst "
          f"predicted deflection {h['deflection_max_mm']:.3f} mm (normal to the wall "
          f"{h['deflection_normal_max_mm']:.3f} mm); chatter episodes caught "
          f"{h['chatter_episodes_caught']}")
    print(f"open {out / 'report.html'} (the plan) and {out / 'supervise.png'} (the supervised run)")
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``demo``."""
    pd = sub.add_parser("demo", help="run the bundled example and write its outputs")
    add_output(pd, "-o", "--output", kind="folder", default="out",
               help="output folder (default out/; made if missing)")
    pd.set_defaults(run=_cmd_demo)
