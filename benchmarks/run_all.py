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
  cycle, detection delay and closed-loop settling on the simulated cut against the thesis;
- ``plan_speed.py``: cycle time of optimize vs thesis vs constant on the demo job and a
  10,000-sample job, planning wall time, IPOPT iterations, peak memory, independent check;
- ``krl_round_trip.py``: KRL write → read round trip of the demo plan and a paged long job.

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

import contextlib  # noqa: E402
import io  # noqa: E402

import dynamics_speed  # noqa: E402
import krl_round_trip  # noqa: E402
import link_latency  # noqa: E402
import plan_speed  # noqa: E402
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


def _verdict(ok: bool) -> str:
    return "met" if ok else "NOT met"


def _more_rows(speed: dict, plans: dict, krl_rows: list[dict], sup: dict,
               dynamics_md: str) -> list[tuple[str, str, str, str]]:
    """Summary rows of the toolpath, planner, KRL, supervisor and dynamics benchmarks."""
    rows = []
    p = speed.get("parse", {}) if isinstance(speed, dict) else {}
    if "ratio_vs_tokenise" in p:
        rows.append(("toolpath: read_gcode vs pygcode Line, largest shared file",
                     f"{p['ratio_vs_tokenise']:.1f}× (worst {p['ratio_cctmill_vs_tokenise_worst']:.1f}×); "
                     f"with every Move built {p['ratio_cctmill_moves_vs_tokenise']:.1f}×",
                     "≥ 10× pygcode", _verdict(p["ratio_vs_tokenise"] >= 10)))
    d, lg, t = plans["demo"]["methods"], plans["long"], plans["targets"]
    rows.append(("planner: demo cycle time, optimize vs thesis vs constant",
                 f"{d['optimize']['cycle_time_s']:.1f} / {d['thesis']['cycle_time_s']:.1f} / "
                 f"{d['constant']['cycle_time_s']:.1f} s ({100 * plans['demo_gain_vs_thesis']:.1f} % "
                 "shorter than thesis; no plan with sections ≥ the job's section_length_min can "
                 "cut more than "
                 f"{100 * plans['demo_cut_gain_ceiling']:.1f} % faster than thesis)",
                 "≥ 20 % shorter than thesis", _verdict(t["demo_gain"])))
    rows.append((f"planner: {lg['samples']:,}-sample job planned (prepare + plan), peak memory",
                 f"{lg['methods']['optimize']['total_s']:.2f} s, {lg['peak_rss_mb']:.0f} MB; "
                 f"IPOPT {lg['methods']['optimize']['ipopt_iterations']} iterations",
                 "< 10 s, < 2 GB", _verdict(t["long_time"] and t["long_memory"])))
    rows.append(("planner: independent check of every plan (every sample)",
                 "0 violations" if t["every_plan_checked_ok"] else "violations found",
                 "none", _verdict(t["every_plan_checked_ok"])))
    worst_pos = max(r["pos_err_mm"] for r in krl_rows)
    worst_ang = max(r["ang_err_deg"] for r in krl_rows)
    exact = all(r["feeds_exact"] and r["lint"] == 0 for r in krl_rows)
    rows.append(("KRL: write → read round trip (demo + paged long job)",
                 f"worst {worst_pos:.1e} mm, {worst_ang:.1e} deg; feeds exact and lint clean: "
                 f"{'yes' if exact else 'no'}", "0.001 mm, 0.001 deg, feeds exact",
                 _verdict(worst_pos <= 1e-3 and worst_ang <= 1e-3 and exact)))
    st = sup["step"]["intrinsic"]
    rows.append(("supervisor: step latency (per-step minimum of identical runs), worst",
                 f"{st['max_ms']:.3f} ms (p99 {st['p99_ms']:.3f} ms)", "well inside 4 ms",
                 _verdict(sup["step"]["of_cycle_intrinsic"]["4ms"] < 0.5)))
    db4 = sup["closed_loop"].get("db4")
    if db4:
        det, settle = db4["detection_delay_ms"]["max"], db4["settling_ms"]["max"]
        rows.append(("supervisor: detection delay / closed-loop settling (db4, worst)",
                     f"{det:.0f} ms / {settle:.0f} ms" if det is not None and settle is not None
                     else "no episode", "thesis ≈ 5 ms / 0.27–0.3 s",
                     f"detection {_verdict(det is not None and det <= 5)}, settling "
                     f"{_verdict(settle is not None and settle <= 300)}"))
    first = next((line for line in dynamics_md.splitlines() if line.startswith("| ") and "met" in line), None)
    if first:
        cells = [c.strip() for c in first.strip("|").split("|")]
        rows.append((f"dynamics: {cells[0]}", f"{cells[1]} sim s / wall s", "≥ 1 at 5 kHz",
                     "met" if cells[-1].endswith("met") and "NOT" not in cells[-1] else "NOT met"))
    return rows


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
    sup = supervisor_latency.run(log=log)
    supervisor_md = supervisor_latency.markdown(sup)
    log("feed planner ...")
    plans = plan_speed.run()
    plan_md = plan_speed.markdown(plans)
    log("KRL round trip ...")
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        krl_rows = krl_round_trip.main()
    krl_md = buf.getvalue().strip()
    rows = [*link_latency.summary_rows(links), *_more_rows(speed, plans, krl_rows, sup, dynamics_md)]
    head, sep, machine = summary(report, figures).partition("\n\nMachine:")
    table = head + "".join("\n| " + " | ".join(row) + " |" for row in rows) + sep + machine
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
        "## Feed planner (benchmarks/plan_speed.py)", plan_md,
        "## KRL export round trip (benchmarks/krl_round_trip.py)", krl_md,
        f"_Total wall time {time.perf_counter() - t0:.0f} s._",
    ]) + "\n"
    write_text_atomic(args.out, doc)
    print(table)
    print(f"\nwrote {args.out}")
    return doc


if __name__ == "__main__":
    main()
