"""``cctmill plan JOB1.toml JOB2.toml … -o OUT``: the batch form of ``cctmill plan`` (one engine,
one folder per job; :func:`planner.batch.plan_batch`)."""

from __future__ import annotations

import argparse
import json
import sys

from models.errors import InputError

__all__ = ["plan_batch_command"]


def plan_batch_command(args: argparse.Namespace) -> int:
    """Run a batch from ``cctmill plan``'s arguments; print one line per job."""
    if args.demo:
        raise InputError("plan", "give job files or --demo, not both")
    if args.safety_factor is not None and not args.safety_factor >= 1.0:
        raise InputError("--safety-factor", "must be >= 1 (f_real = f_max / safety factor)")
    from planner.batch import BatchOptions, plan_batch
    from planner.cli.export import krl_options
    from planner.job import load_job
    from planner.place.engine import open_engine, resolve_scheduler

    jobs = list(args.job)
    first = load_job(jobs[0])
    address = resolve_scheduler(args.scheduler, first.plan.scheduler)
    opts = BatchOptions(args.method, args.safety_factor, krl_options(args) if args.krl else None)
    print(f"batch of {len(jobs)} jobs on {address}", file=sys.stderr)
    try:
        with open_engine(address, args.workers) as engine:
            res = plan_batch(jobs, args.output, engine, opts, progress=not args.json)
    except KeyboardInterrupt:
        print("cctmill plan: interrupted", file=sys.stderr)
        return 130
    if args.json:
        print(json.dumps(res.as_json(), indent=2))
    else:
        width = max(len(j.job_file) for j in res.jobs)
        for j in res.jobs:
            what = (f"cycle {j.cycle_time:8.2f} s  {j.folder}" if j.ok
                    else f"no plan: {j.error}: {j.reason}")
            print(f"{j.job_file:{width}}  {what}")
        print(f"{sum(j.ok for j in res.jobs)} of {len(res.jobs)} jobs planned in "
              f"{res.wall_time:.1f} s on {res.engine} ({res.workers} workers); "
              f"summary: {args.output}/batch.json")
    if res.interrupted:
        return 130
    return 0 if res.ok else 2
