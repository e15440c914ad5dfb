"""Toolpath import and path kinematics speed.

1. Parse speed on the largest shared G-code file: cctmill's reader (full interpretation into moves:
   modal state, units, arcs checked) against pygcode, an established Python G-code parser, measured in
   the same process. pygcode is timed two ways: tokenising each line (``Line``, the least it can do)
   and tokenising plus interpreting with its ``Machine`` (positions, like ours). Target: ≥ 10× pygcode.
2. Inverse kinematics samples per second along the bundled demo job's path (seeded LM with the free
   rotation about the tool axis; worst repeat reported too).

Run from the repository root: ``python benchmarks/toolpath_speed.py [--json] [--repeats 3]``.
pygcode is a benchmark-only dependency (``pip install -e '.[bench]'``); without it its rows are
skipped with the reason printed.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from importlib import resources
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

SHARED = ROOT.parent / "shared" / "data" / "toolpaths"
TARGET_RATIO = 10.0


def _largest_gcode() -> Path | None:
    files = [p for p in SHARED.glob("*") if p.suffix.lower() in (".nc", ".ngc")]
    return max(files, key=lambda p: p.stat().st_size) if files else None


def _time(fn, repeats: int) -> tuple[float, float]:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times), max(times)


def parse_speed(repeats: int) -> dict:
    from robot_io.gcode import read_gcode

    path = _largest_gcode()
    if path is None:
        return {"skipped": f"no shared G-code files at {SHARED}"}
    lines = path.read_text(encoding="utf-8", errors="replace").splitlines()
    n_lines = len(lines)
    tp = read_gcode(str(path))  # warm-up and correctness: must import strictly
    ours_best, ours_worst = _time(lambda: read_gcode(str(path)), repeats)
    out = {"file": path.name, "lines": n_lines, "moves": len(tp.moves),
           "cctmill_s": ours_best, "cctmill_worst_s": ours_worst,
           "cctmill_lines_per_s": n_lines / ours_best}
    try:
        import pygcode
    except ImportError:
        out["pygcode"] = "skipped: pygcode not installed (pip install -e '.[bench]')"
        return out

    def tokenise():
        for raw in lines:
            pygcode.Line(raw)

    def interpret():
        machine = pygcode.Machine()
        for raw in lines:
            line = pygcode.Line(raw)
            try:
                machine.process_block(line.block)
            except Exception:  # pygcode rejects some words it does not model; keep going
                pass

    tok_best, _ = _time(tokenise, max(1, repeats - 1))
    int_best, _ = _time(interpret, max(1, repeats - 1))
    out.update({
        "pygcode_version": getattr(pygcode, "__version__", "?"),
        "pygcode_tokenise_s": tok_best, "pygcode_interpret_s": int_best,
        "ratio_vs_tokenise": tok_best / ours_best, "ratio_vs_interpret": int_best / ours_best,
    })
    return out


def ik_speed(repeats: int) -> dict:
    from models.robot import load_robot
    from planner.ik import IKOptions, solve_path
    from planner.job import load_job
    from planner.path import sample_toolpath
    from robot_io.readers import read_toolpath

    job = load_job(str(resources.files("planner").joinpath("data/demo/demo_job.toml")))
    robot = load_robot(job.cell.robot)
    tps = [read_toolpath(p) for p in job.toolpath_files()]
    path = sample_toolpath(tps, job.base_frame(), job.path.chord_tol_mm * 1e-3,
                           job.path.step_max_mm * 1e-3)
    opts = IKOptions(choose_for_stiffness=job.kinematics.choose_for_stiffness)
    kin = solve_path(robot, path, job.tool_frame(), opts)
    if not kin.all_reachable:
        raise SystemExit(f"demo path not reachable: {kin.problems[:1]}")
    best, worst = _time(lambda: solve_path(robot, path, job.tool_frame(), opts), repeats)
    return {"samples": len(path), "ik_s": best, "ik_worst_s": worst,
            "samples_per_s": len(path) / best, "samples_per_s_worst": len(path) / worst,
            "iterations_mean": float(kin.iterations.mean()),
            "iterations_max": int(kin.iterations.max())}


def markdown(res: dict) -> str:
    """The results as Markdown."""
    out: list[str] = []
    p, k = res["parse"], res["ik"]
    if "skipped" in p:
        out.append(f"- parse: {p['skipped']}")
    else:
        out.append(f"- file: {p['file']} ({p['lines']:,} lines, {p['moves']:,} moves)")
        out.append("\n| reader | time (best of repeats) | lines/s | cctmill speed-up |")
        out.append("|---|---:|---:|---:|")
        out.append(f"| cctmill read_gcode (full interpretation) | {p['cctmill_s']:.3f} s "
              f"(worst {p['cctmill_worst_s']:.3f} s) | {p['cctmill_lines_per_s']:,.0f} | 1.0× |")
        if "pygcode_tokenise_s" in p:
            for key, label, ratio in (("pygcode_tokenise_s", "pygcode Line (tokenise only)",
                                       "ratio_vs_tokenise"),
                                      ("pygcode_interpret_s", "pygcode Line + Machine (interpret)",
                                       "ratio_vs_interpret")):
                ok = "met" if p[ratio] >= TARGET_RATIO else "NOT met"
                out.append(f"| {label} {p['pygcode_version']} | {p[key]:.3f} s | "
                      f"{p['lines'] / p[key]:,.0f} | {p[ratio]:.1f}× ({ok}, target ≥ "
                      f"{TARGET_RATIO:.0f}×) |")
        else:
            out.append(f"\n- pygcode: {p['pygcode']}")
    out.append(f"\n- IK along the demo path: {k['samples']:,} samples in {k['ik_s']:.3f} s → "
          f"{k['samples_per_s']:,.0f} samples/s (worst repeat {k['samples_per_s_worst']:,.0f}/s); "
          f"LM iterations mean {k['iterations_mean']:.2f}, max {k['iterations_max']}")
    return "\n".join(out)


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args(argv)
    res = {"parse": parse_speed(args.repeats), "ik": ik_speed(args.repeats)}
    if args.json:
        print(json.dumps(res, indent=2))
        return res
    print(markdown(res))
    return res


if __name__ == "__main__":
    main()
