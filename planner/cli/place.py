"""``cctmill place JOB.toml -o OUT [--x-mm A:B:N] [--y-mm …] [--z-mm …] [--yaw-deg …] [--screen]
[--refine] [--scheduler ADDR]``: where to put the part (a placement study, docs/placement.md)."""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

from models.errors import InputError
from planner.cli._common import add_output
from planner.demo import demo_job_file

__all__ = ["axis_of", "register"]

#: Rows of the fastest placements printed.
_TOP = 8


def axis_of(text: str, flag: str, scale: float):
    """``A:B:N`` (or one value ``A``) in the flag's unit → a :class:`planner.place.grid.Axis` (SI,
    ``scale`` converts: 1e-3 for mm, π/180 for degrees)."""
    from planner.place.grid import Axis

    parts = text.split(":")
    try:
        if len(parts) == 1:
            return Axis.single(float(parts[0]) * scale)
        if len(parts) == 3:
            lo, hi, n = float(parts[0]), float(parts[1]), int(parts[2])
            if not (math.isfinite(lo) and math.isfinite(hi)):
                raise ValueError
            return Axis(lo * scale, hi * scale, n)
    except InputError as e:  # (an InputError is a ValueError: first)
        raise InputError(flag, str(e).split(": ", 1)[-1]) from None
    except ValueError:
        pass
    raise InputError(flag, f"{text!r} is not A:B:N (from A to B in N steps, N >= 1) or one value")


def _grid(args, job):
    from planner.place.grid import PlacementGrid, default_grid

    given = {name: getattr(args, f"{name}_{unit}") for name, unit in
             (("x", "mm"), ("y", "mm"), ("z", "mm"), ("yaw", "deg"))}
    base = default_grid(job) if any(v is None for k, v in given.items() if k != "yaw") else None
    axes = []
    for name in ("x", "y", "z", "yaw"):
        text = given[name]
        unit = "deg" if name == "yaw" else "mm"
        if text is not None:
            axes.append(axis_of(text, f"--{name}-{unit}", math.pi / 180 if name == "yaw" else 1e-3))
        elif name == "yaw":
            axes.append(axis_of(str(job.cell.base_abc_deg[0]), "--yaw-deg", math.pi / 180))
        else:
            axes.append(getattr(base, name))
    return PlacementGrid(*axes)


def _row(r) -> str:
    p = r.placement.as_json()
    where = f"{p['x_mm']:9.1f} {p['y_mm']:9.1f} {p['z_mm']:9.1f} {p['yaw_deg']:8.2f}"
    if r.feasible:
        binds = ", ".join(f"{k} {v}" for k, v in r.binding_counts.items())
        return f"{where}  {r.cycle_time:9.2f}  {binds}"
    return f"{where}  {'—':>9}  {r.error}"


def _cmd_place(args: argparse.Namespace) -> int:
    if args.demo == (args.job is not None):
        raise InputError("place", "give a JOB.toml or --demo (not both)")
    from planner.place.engine import open_engine, resolve_scheduler
    from planner.place.outputs import write_place_outputs
    from planner.place.search import run_study
    from planner.place.spec import JobSpec, job_of

    spec = JobSpec.from_file(demo_job_file() if args.demo else Path(args.job))
    job = job_of(spec)
    grid = _grid(args, job)
    address = resolve_scheduler(args.scheduler, job.plan.scheduler)
    print(f"placement study of {spec.name}: {len(grid)} placements "
          f"({' × '.join(str(n) for n in grid.shape)} in x, y, z, yaw) and the job's own, on "
          f"{address}", file=sys.stderr)
    try:
        with open_engine(address, args.workers) as engine:
            print(f"engine ready: {engine.address}, {engine.workers} worker"
                  f"{'s' if engine.workers != 1 else ''}", file=sys.stderr)
            study = run_study(spec, grid, engine, screen=args.screen, refine_best=args.refine,
                              max_refine=args.refine_plans, progress=not args.json)
    except KeyboardInterrupt:
        print("cctmill place: interrupted before any placement finished; nothing written",
              file=sys.stderr)
        return 130
    files = write_place_outputs(study, spec, args.output, best_plan=not args.no_best_plan,
                                progress=not args.json)
    doc = json.loads(files["place"].read_text(encoding="utf-8"))
    if args.json:
        doc.pop("placements", None)
        doc["written"] = {k: str(v) for k, v in files.items()}
        print(json.dumps(doc, indent=2))
    else:
        _print_summary(study, files, job.cell.base_abc_deg)
    if study.interrupted:
        print(f"cctmill place: interrupted: {len(study.candidates())} plans finished, written to "
              f"{files['place']}", file=sys.stderr)
        return 130
    if study.best is None:
        print(f"cctmill place: error: no placement has a plan (reasons in {files['place']})",
              file=sys.stderr)
        return 2
    return 0


def _print_summary(study, files, base_abc_deg) -> None:
    ok = sorted((r for r in study.candidates() if r.feasible), key=lambda r: r.score)
    seen: set[str] = set()
    print(f"{'x mm':>9} {'y mm':>9} {'z mm':>9} {'yaw deg':>8}  {'cycle s':>9}  sections by binding")
    for r in ok:
        if r.placement.key in seen:
            continue
        seen.add(r.placement.key)
        print(_row(r))
        if len(seen) >= _TOP:
            break
    n_bad = sum(not r.feasible for r in study.candidates())
    print(f"... {len(study.candidates())} plans, {n_bad} without a plan "
          f"({len(study.pruned)} more pruned by the screen); every one in {files['place']}")
    own, best = study.own, study.best
    if best is not None:
        b = best.placement.as_json()
        abc = [b["yaw_deg"], *base_abc_deg[1:]]
        print(f"\nbest $BASE: base_mm = [{b['x_mm']:g}, {b['y_mm']:g}, {b['z_mm']:g}], "
              f"base_abc_deg = [{abc[0]:g}, {abc[1]:g}, {abc[2]:g}]: cycle {best.cycle_time:.2f} s")
    if own is not None:
        if own.feasible and best is not None:
            print(f"own $BASE: cycle {own.cycle_time:.2f} s; the best is "
                  f"{100 * (1 - best.score / own.score):.1f} % faster ({own.score - best.score:.2f} s "
                  "a part)")
        elif not own.feasible:
            print(f"own $BASE has no plan: {own.reason}")
    if study.refinement is not None:
        ref = study.refinement
        print(f"refinement ({', '.join(ref.axes) or 'no axis'}): {len(ref.evaluated)} plans, "
              f"{ref.message}")
    if study.failed:
        print(f"{len(study.failed)} placements lost to dying workers (place.json 'failed')")
    print("wrote:")
    for k, v in files.items():
        print(f"  {k:26} {v}")


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``cctmill place``."""
    p = sub.add_parser("place", help="where to put the part: plan the job at a grid of $BASE "
                                     "placements (place.json, heat map, the best plan)")
    p.add_argument("job", nargs="?", help="job file (.toml)")
    p.add_argument("--demo", action="store_true", help="study the bundled demo job")
    add_output(p, "-o", "--output", kind="folder", default="out",
               help="output folder (default out/; made if missing)")
    g = p.add_argument_group("the grid ($BASE origin in the robot base; default: the robot's "
                             "reachable box around the job's own, docs/placement.md)")
    for name in ("x", "y", "z"):
        g.add_argument(f"--{name}-mm", metavar="A:B:N", help=f"$BASE {name} from A to B [mm] in N "
                                                             "values (or one value)")
    g.add_argument("--yaw-deg", metavar="A:B:N", help="$BASE A (rotation about the base z) from A "
                                                      "to B [deg] in N values (default: the job's)")
    p.add_argument("--screen", nargs="?", type=float, const=1.3, default=None, metavar="RATIO",
                   help="prune with the cheap screen (reach and ceilings at a subset of samples): "
                        "plan only placements estimated within RATIO of the best (default 1.3)")
    p.add_argument("--refine", action="store_true",
                   help="refine the best grid placement (Nelder–Mead over the axes the grid varies)")
    p.add_argument("--refine-plans", type=int, default=None, metavar="N",
                   help="plans the refinement may spend (default 30)")
    p.add_argument("--scheduler", metavar="ADDR",
                   help="none (serial), local (a cluster of this machine's cores, the default) or "
                        "a Dask scheduler address tcp://HOST:PORT (also $CCTMILL_SCHEDULER, or the "
                        "job's [plan] scheduler)")
    p.add_argument("--workers", type=int, default=None,
                   help="worker processes of a local cluster (default: the cores)")
    p.add_argument("--no-best-plan", action="store_true",
                   help="do not write the best placement's plan and report under OUT/best/")
    p.add_argument("--json", action="store_true", help="print the study summary as JSON")
    p.set_defaults(run=_cmd_place)
