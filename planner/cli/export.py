"""``cctmill export PLAN_DIR_OR_JSON -o OUTDIR``: a plan as a KUKA KRL program (``planner.export``)."""

from __future__ import annotations

import argparse
from pathlib import Path

from planner._atomic import output_errors
from planner.cli._common import add_output
from planner.export import krl_summary, plan_to_krl
from planner.outputs import KrlOptions
from robot_io.krl import CONTROLLERS, OVERRIDE_HOOKS, write_krl

__all__ = ["add_krl_flags", "export_from_args", "krl_options", "register", "run"]


def add_krl_flags(p: argparse.ArgumentParser, with_output: bool = True) -> None:
    """The KRL flags (shared with ``cctmill plan … --krl``)."""
    g = p.add_argument_group("KRL program")
    if with_output:
        add_output(g, "-o", "--output", kind="folder", required=True, metavar="OUTDIR",
                   help="folder for NAME.src, NAME.dat and any pages (made if missing)")
    g.add_argument("--name", help="program (module) name: a KRL name, at most 24 characters "
                                  "including the derived NAME_F001 (default: from the job name)")
    g.add_argument("--controller", choices=sorted(CONTROLLERS), default="krc4",
                   help="krc4 (pages of 1400 lines, RSI hook available) or krc2 (2000 lines)")
    g.add_argument("--compensate-deflection", action="store_true",
                   help="mirror-compensate the predicted static deflection (docs/model.md §7)")
    g.add_argument("--override-hook", choices=OVERRIDE_HOOKS, default="none",
                   help="supervisor hook: kvp (section number variable for KukaVarProxy) or rsi "
                        "(KR C4: RSI context with MAP2OV_PRO around the sections)")
    g.add_argument("--base-index", type=int, metavar="N",
                   help="$BASE = BASE_DATA[N] instead of the plan's frame literal")
    g.add_argument("--tool-index", type=int, metavar="N",
                   help="$TOOL = TOOL_DATA[N] instead of the plan's frame literal")
    g.add_argument("--apo-cdis-mm", type=float, default=0.1,
                   help="approximation distance $APO.CDIS [mm] (default 0.1)")
    g.add_argument("--advance", type=int, default=3, help="$ADVANCE, 1..5 (default 3)")


def krl_options(args: argparse.Namespace) -> KrlOptions:
    """The KRL options the flags ask for."""
    return KrlOptions(name=args.name, controller=args.controller,
                      compensate=args.compensate_deflection, override_hook=args.override_hook,
                      base_index=args.base_index, tool_index=args.tool_index,
                      apo_cdis_mm=args.apo_cdis_mm, advance=args.advance)


def export_from_args(plan: object, outdir: str, args: argparse.Namespace) -> list[Path]:
    """Export ``plan`` (a Plan or path) with the KRL flags of ``args``; print what was written."""
    prog = plan_to_krl(plan, **krl_options(args).kwargs())  # type: ignore[arg-type]
    summary = krl_summary(prog)
    with output_errors(outdir):
        paths = write_krl(prog.spec, prog.sections, prog.moves, outdir, prog.notes)
    print(f"KRL program {prog.spec.name} for {CONTROLLERS[prog.spec.controller].label}: "
          f"{summary['sections']} sections, {summary['moves']} moves ("
          + ", ".join(f"{k} {v}" for k, v in sorted(summary["by_kind"].items()))
          + f"), {summary['pages'] or 1} page{'s' if summary['pages'] > 1 else ''}"
          + (" + main" if summary["pages"] else "")
          + (", deflection-compensated" if args.compensate_deflection else ""))
    print(f"{'sec':>4} {'kind':<6} {'feed mm/s':>12} {'binding':<12} {'moves':>6}")
    counts = [0] * len(prog.sections)
    for m in prog.moves:
        counts[m.section] += 1
    for k, (sec, c) in enumerate(zip(prog.sections, counts, strict=True), 1):
        print(f"{k:>4} {sec.kind:<6} {sec.feed_m_s * 1e3:>12.6f} {sec.binding:<12} {c:>6}")
    print("wrote:")
    for p in paths:
        print(f"  {p}")
    return paths


def run(args: argparse.Namespace) -> int:
    """``cctmill export``."""
    export_from_args(args.plan, args.output, args)
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``cctmill export`` to the subcommands."""
    p = sub.add_parser("export", help="write a plan as a KUKA KRL program (.src/.dat, paged)",
                       description="Write a plan as a KUKA KRL program: NAME.src + NAME.dat "
                                   "(section feeds as DECL REAL values), paged into NAME_001… "
                                   "when long. All files are written atomically.")
    p.add_argument("plan", metavar="PLAN_DIR_OR_JSON", help="plan.json or the folder holding it")
    add_krl_flags(p)
    p.set_defaults(run=run)
