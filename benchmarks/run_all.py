"""Run every benchmark and write one summary: stdout and ``out/benchmarks.md``.

- ``throughput.py``: poses per second of the point model (CCT stiffness + γ + margin), CasADi VM
  and compiled C against a per-pose numpy/pinocchio baseline measured in the same run;
- ``thesis_figures.py``: each published figure the physics core can recompute, and whether this
  model agrees;
- ``dynamics_speed.py``: simulated seconds per wall second of the 2-DOF milling simulation at
  5 kHz (vs real time and a naive per-step loop), the demo path's static wall error with and
  without mirror compensation, and the wall a simulated cut leaves with and without it;
- ``link_latency.py``: robot link latency over loopback (KVP write round trip, RSI reply time, worst
  case and p99, against a bare echo and the 4 ms / 12 ms controller cycle);
- ``supervisor_latency.py``: supervisor step latency (worst case, p99) against the 4 ms / 12 ms
  cycle, detection delay and closed-loop settling on the simulated cut against the thesis.

The summary table is printed; ``out/benchmarks.md`` holds it followed by both full tables (the
README's "Validation against the thesis" and "Performance" sections are pasted from there). The
file is written atomically (temporary file in ``out/``, then ``os.replace``).

Run from the repository root: ``python benchmarks/run_all.py [--n N] [--baseline-n M]``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
for _p in (str(REPO), str(HERE)):
    if _p not in sys.path:
        sys.path.insert(0, _p)

import dynamics_speed  # noqa: E402
import link_latency  # noqa: E402
import supervisor_latency  # noqa: E402
import thesis_figures  # noqa: E402
import throughput  # noqa: E402
import toolpath_speed  # noqa: E402

from planner._atomic import write_text_atomic  # noqa: E402

OUT = REPO / "out" / "benchmarks.md"


def summary(report: throughput.Report, figures: list[thesis_figures.Figure]) -> str:
    rows = report.rows
    base = rows[0]
    by_name = {r.variant: r for r in rows}
    best = by_name[report.best]
    vm = by_name.get("casadi VM  serial map, zero-copy buffer")
    lines = ["| benchmark | this run | target / published | verdict |", "|---|---|---|---|"]
    lines.append(f"| throughput: best variant ({best.variant}) | {best.rate:,.0f} poses/s, "
                 f"{best.ratio:,.0f}× baseline, 1e8 poses in {throughput._hms(best.hours_1e8)} "
                 f"| ≥ {throughput.TARGET_RATE:,.0f} poses/s and ≥ "
                 f"{throughput.TARGET_RATIO:.0f}× | {'met' if report.targets_met else 'NOT met'} |")
    if vm is not None:
        lines.append(f"| throughput: CasADi VM serial map | {vm.rate:,.0f} poses/s, "
                     f"{vm.ratio:,.0f}× baseline, 1e8 poses in {throughput._hms(vm.hours_1e8)} "
                     f"| (no target) | — |")
    lines.append(f"| throughput: per-pose numpy/pinocchio baseline | {base.rate:,.0f} poses/s, "
                 f"1e8 poses in {throughput._hms(base.hours_1e8)} | agrees with the kernel "
                 f"| {base.agreement.removeprefix('vs kernel: ')} |")
    for f in figures:
        cells = (f.figure, f.model, f.published, f.verdict)
        lines.append("| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |")
    m = report.machine
    lines.append("")
    lines.append(f"Machine: {m['nproc']} cores, {m['cpu']}; casadi {m['casadi']}, "
                 f"pinocchio {m['pinocchio']}, numpy {m['numpy']}, gcc {m['gcc']}.")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> str:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=100_000, help="poses for the throughput benchmark")
    ap.add_argument("--baseline-n", type=int, default=2_000,
                    help="poses for the per-pose baseline")
    ap.add_argument("--out", type=Path, default=OUT, help="summary file (default out/benchmarks.md)")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()

    def log(s: str) -> None:
        print(s, file=sys.stderr, flush=True)

    log("thesis figures ...")
    figures = thesis_figures.figures()
    log("throughput ...")
    report = throughput.run(args.n, args.baseline_n, log)
    log("toolpath import and IK speed ...")
    try:
        speed = {"parse": toolpath_speed.parse_speed(3), "ik": toolpath_speed.ik_speed(3)}
        speed_md = toolpath_speed.markdown(speed)
    except ImportError as e:
        speed_md = f"skipped: {e}"
    log("robot link latency ...")
    links = link_latency.run()
    log("dynamic simulation speed and deflection compensation ...")
    dynamics_md = dynamics_speed.report()
    log("online supervisor ...")
    supervisor_md = supervisor_latency.markdown(supervisor_latency.run(log=log))
    head, sep, machine = summary(report, figures).partition("\n\nMachine:")
    table = head + "".join("\n| " + " | ".join(row) + " |" for row in link_latency.summary_rows(links)) \
        + sep + machine
    doc = "\n\n".join([
        "# cctmill benchmarks",
        "## Summary", table,
        "## Validation against the thesis (benchmarks/thesis_figures.py)",
        thesis_figures.markdown(figures),
        "## Performance (benchmarks/throughput.py)", throughput.format_table(report),
        "## Toolpath import and path kinematics (benchmarks/toolpath_speed.py)", speed_md,
        "## Robot link latency (benchmarks/link_latency.py)", link_latency.markdown(links),
        "## Dynamic simulation and deflection compensation (benchmarks/dynamics_speed.py)",
        dynamics_md,
        "## Online supervisor (benchmarks/supervisor_latency.py)", supervisor_md,
        f"_Total wall time {time.perf_counter() - t0:.0f} s._",
    ]) + "\n"
    write_text_atomic(args.out, doc)
    print(table)
    print(f"\nwrote {args.out}")
    return doc


if __name__ == "__main__":
    main()
