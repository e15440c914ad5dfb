"""``cctmill plan JOB.toml -o OUTDIR [--method ...] [--safety-factor 1.1] [--demo] [--json]``."""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path

from models.errors import InputError
from planner.cli._common import add_output
from planner.cli.export import krl_options
from planner.demo import demo_job_file
from planner.plan import METHODS, PlanResult, limit_confidence_text

__all__ = ["register", "section_table"]

#: Files of one kind listed one by one; more are summarised (a paged KRL program has dozens).
_LISTED_FILES = 4


def section_table(res: PlanResult, limit: int = 40) -> str:
    """The sections as a readable table (the first ``limit`` rows, then a count); ``#`` numbers
    them from 1, as plan.json, the report and the KRL program do."""
    head = (f"{'#':>4} {'kind':5} {'s [m]':>15} {'feed mm/s':>9} {'binds':11} {'F max N':>8} "
            f"{'|δ| mm':>7} {'margin N/m':>10} {'γ deg':>7} {'t [s]':>7}  lines")
    out = [head, "-" * len(head)]

    def f(v, spec):
        return "—" if v is None else format(v, spec)

    rows = res.section_rows
    for r in rows[:limit]:
        out.append(f"{r['index']:>4} {r['kind']:5} {r['s_start_m']:7.3f}-{r['s_end_m']:<7.3f} "
                   f"{r['feed_mm_s']:9.3f} {r['binding']:11} {f(r['force_max_N'], '8.1f'):>8} "
                   f"{f(r['deflection_max_mm'], '7.3f'):>7} {f(r['margin_N_per_m'], '10.3g'):>10} "
                   f"{f(r['gamma_deg'], '7.2f'):>7} {r['time_s']:7.2f}  "
                   f"{r['line_start']}-{r['line_end']}")
    if len(rows) > limit:
        out.append(f"... {len(rows) - limit} more sections (plan.json, report.html)")
    return "\n".join(out)


def _cmd_plan(args: argparse.Namespace) -> int:
    if len(args.job) > 1:               # a batch: one folder per job (planner/cli/_batch.py)
        from planner.cli._batch import plan_batch_command

        return plan_batch_command(args)
    args.job = args.job[0] if args.job else None
    if args.demo == (args.job is not None):
        raise InputError("plan", "give a JOB.toml or --demo (not both)")
    job = demo_job_file() if args.demo else Path(args.job)
    out = Path(args.output)
    if args.safety_factor is not None and not args.safety_factor >= 1.0:
        raise InputError("--safety-factor", "must be >= 1 (f_real = f_max / safety factor)")
    from planner.job import load_job
    from planner.outputs import run_plan_job

    job_doc = load_job(job)
    krl = krl_options(args) if args.krl else None
    if krl is not None and job_doc.export.compensate_deflection and not krl.compensate:
        krl = dataclasses.replace(krl, compensate=True)   # the plan's tolerance assumes it
    outputs = run_plan_job(job_doc, out, args.method, args.safety_factor, krl=krl,
                           progress=not args.json)
    res, written = outputs.result, outputs.files
    if args.json:
        doc = json.loads(outputs.plan.path.read_text(encoding="utf-8"))  # type: ignore[union-attr]
        doc.pop("sections", None)
        doc["written"] = {k: [str(p) for p in v] if isinstance(v, list) else str(v)
                          for k, v in written.items()}
        print(json.dumps(doc, indent=2))
        return 0
    print(section_table(res))
    groups = outputs.plan.import_warnings
    if groups:
        total = sum(g.count for g in groups)
        kinds = f"{len(groups)} kind{'s' if len(groups) != 1 else ''}"
        print(f"\ntoolpath warnings: {total} ({kinds}; in plan.json import_warnings and "
              "report.html)")
        for g in groups:
            print(f"  {g.kind}: {g}")
    if outputs.plan.warnings:
        print("\nplan warnings:")
        for w in outputs.plan.warnings:
            print(f"  {w}")
    print(f"\n{res.method}: cycle {res.cycle_time:.2f} s (process {res.process_time:.2f} s), "
          f"{len(res.plan_sections)} sections; solver: {res.solver.describe()}")
    if res.profile is not None:
        low = res.profile.bound_cycle_time
        print(f"feed profile: the cycle is {100 * (res.cycle_time / low - 1):.2f} % above the "
              f"pointwise bound {low:.2f} s (every sample at its ceiling, no jerk limit: no feed "
              "plan under these limits is faster)")
    elif res.cut_time > 0:
        print(f"cutting {res.cut_time:.2f} s; no plan with sections >= "
              f"{res.limits.section_length_min * 1e3:g} mm can cut faster than "
              f"{res.cut_time_bound:.2f} s under these limits "
              f"({100 * (res.cut_time / res.cut_time_bound - 1):.1f} % above it)")
    conf = limit_confidence_text(res)
    if conf is not None:
        print(f"calibration uncertainty: {conf}")
    print("wrote:")
    for k, v in written.items():
        files = v if isinstance(v, list) else [v]
        if len(files) > _LISTED_FILES:
            print(f"  {k:22} {len(files)} files: {files[0]}, {files[1]} … {files[-1]}")
        else:
            for p in files:
                print(f"  {k:22} {p}")
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``cctmill plan``."""
    p = sub.add_parser("plan", help="choose sections and feeds for a job and time it "
                                    "(plan.json, samples.npz, report.html)")
    p.add_argument("job", nargs="*", help="job file (.toml); several: a batch on one engine, "
                                          "one folder per job under -o (docs/placement.md)")
    p.add_argument("--demo", action="store_true", help="plan the bundled demo job")
    add_output(p, "-o", "--output", kind="folder", default="out",
               help="output folder (default out/; made if missing)")
    p.add_argument("--method", choices=METHODS, default=None,
                   help="optimize (sections by CasADi + IPOPT, then a feed profile: a path speed "
                        "per sample; default), sections (one feed per section), thesis "
                        "(docs/model.md §8 section algorithm) or constant (the safe constant feed)")
    p.add_argument("--safety-factor", type=float, default=None,
                   help="thesis method: f_real = f_max / safety factor (default from the job, 1.1)")
    p.add_argument("--krl", action="store_true", help="also write the KUKA KRL program "
                                                      "(the KRL flags below, as cctmill export)")
    from planner.cli.export import add_krl_flags  # noqa: I001 - the KRL flags, shared

    add_krl_flags(p, with_output=False)
    p.add_argument("--json", action="store_true", help="print the plan summary as JSON")
    p.add_argument("--scheduler", metavar="ADDR", help="a batch's engine: none, local (default) or "
                                                       "tcp://HOST:PORT (cctmill place --help)")
    p.add_argument("--workers", type=int, default=None, help="a batch's local worker processes")
    p.set_defaults(run=_cmd_plan)
