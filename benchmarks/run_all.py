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
- ``krl_round_trip.py``: KRL write → read round trip of the demo plan and a paged long job;
- ``engagement_speed.py``: the Z-map engagement against the 2.5-D model (ms per sample, share of
  the planning wall time, agreement, a_p in the Fusion 360 program's helical bores);
- ``feed_intent.py``: what the programmed-feed rules change on the demo (round one's air/plunge
  rule as the baseline, then air as programmed, the tool's chip load, the CAM-feed factor);
- ``posture.py`` (run by ``plan_speed.py``): the rotation about the tool axis chosen along the
  path on the demo and the off-axis cell, and the compensation-aware deflection tolerance;
- ``detector_speed.py``: chatter detection delay in chatter periods and false alarms per hour of
  simulated stable cutting, the thesis's DWT against the IIR band-pass;
- ``compensation.py``: wall error of a simulated cut without compensation, with the offline mirror,
  with online RKorr and with both, and the RKorr step's cost;
- ``calibration.py``: cutting coefficients, stiffness scale and a stability boundary fitted from
  test cuts run in a simulated true cell whose hidden parameters differ from the nominal ones;
- ``calibration_loop.py``: the loop on the same truth: plan with the nominal model, test passes,
  calibrate, replan, every section of each plan simulated in the truth;
- ``placement.py``: a placement study of the demo serial against a LocalCluster of 2 workers,
  per-placement cost, scheduler overhead per task, the screen's pruning, best vs own ``$BASE``
  (and the sizing estimate of ``docs/placement.md``, its marked block).

The summary table is printed; ``out/benchmarks.md`` holds it followed by every full table. The
manual's pages are written from the same run, never pasted: ``docs/performance.md`` whole (an
introduction, the summary, the machine, every benchmark's table), and in ``docs/validation.md`` the
block between ``<!-- thesis-figures:start -->`` and ``<!-- thesis-figures:end -->``. Every file is
written atomically (temporary file beside it, then ``os.replace``).

A benchmark that fails (an import or a run) does not stop the others: its section says so with
the error, its summary rows are left out, every file is still written, and the exit status is 1.
The benchmark modules are imported only when their step runs, so that the child processes some of
them spawn (which re-import this file) never import them all.

Run from the repository root: ``python benchmarks/run_all.py [--n N] [--baseline-n M] [--no-docs]``.
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
import importlib  # noqa: E402
import io  # noqa: E402
import traceback  # noqa: E402
from collections.abc import Callable  # noqa: E402
from typing import Any  # noqa: E402

from planner._atomic import write_text_atomic  # noqa: E402

OUT = REPO / "out" / "benchmarks.md"
DOCS = REPO / "docs"
PERFORMANCE_PAGE = DOCS / "performance.md"
VALIDATION_PAGE = DOCS / "validation.md"
#: The generated block of docs/validation.md (the thesis figures table of the latest run).
FIGURES_START, FIGURES_END = "<!-- thesis-figures:start -->", "<!-- thesis-figures:end -->"
PLACEMENT_PAGE = DOCS / "placement.md"
SIZING_START, SIZING_END = "<!-- placement-sizing:start -->", "<!-- placement-sizing:end -->"

#: The first paragraph of docs/performance.md. No figure in it: figures come from the run below.
PAGE_INTRO = """\
This page is written by `benchmarks/run_all.py` (`make bench`) and is never edited by hand: every
figure on it comes from one run on the machine named under the summary, with the total wall time at
the end. Baselines are measured in the same run; solves are checked converged and results checked
against their baseline before anything is timed. Each benchmark also runs on its own
(`python benchmarks/<name>.py`). Timings on a shared virtual machine vary from run to run; the
benchmarks that run online (robot links, supervisor) report the worst case, not only the mean.
The thesis figures of the same run are judged in [Validation against the thesis](validation.md)."""

#: One short paragraph before each benchmark's tables (what is measured and how to read it).
SECTION_INTROS = {
    "throughput": """\
CCT translational stiffness, γ and stability margin of random reachable poses: the physics core's
one mapped CasADi Function against a per-pose numpy/pinocchio baseline. The thesis enumerated 1e8
poses for one table; the "1e8 poses" column says how long that takes here. Reaching the target needs
the compiled kernel *and* `Function.buffer()` on numpy memory: the ordinary Python call of a mapped
Function spends more time converting numpy ↔ DM than in the kernel.""",
    "toolpath": """\
pygcode (from the `bench` extra) timed in the same process, the repeats interleaved (CPU time). A
3-axis CAM program is almost all *plain* lines (only N/G0/G1/X/Y/Z/F words): the reader classifies
every line at once with numpy and executes long runs of plain lines as array operations
(`robot_io/gcode/_plain.py`); every other line goes through the line-by-line interpreter, which
stays the definition of what a line means (both give the same toolpath to the bit, tested). Moves
are stored as columns and `Toolpath.moves` builds each `Move` on first access, so code that walks
every `Move` pays for building them (the second row). Programs of arcs and 5-axis programs run line
by line. See [Toolpath readers](toolpaths.md).""",
    "links": """\
The peer runs in a child process, as a controller is another machine; both share this machine's
cores. The bare TCP and UDP echoes are the baseline: their tails are what the machine itself adds.
See [Robot links](links.md).""",
    "dynamics": """\
The naive baseline is the same model written as a per-step, per-edge Python loop, checked against
the kernel first. Then the demo path's static wall error normal to the wall with and without mirror
compensation, and the wall a simulated cut at the demo's worst sample leaves with and without it.
See [Dynamics and deflection](dynamics.md).""",
    "supervisor": """\
The closed loop is deterministic, so it runs several identical times and the per-step minimum
removes the preemption and steal time a shared machine adds at random moments; the wall-time row
shows what that noise does to a single run. Detection delay runs from chatter becoming visible to
the alarm, settling from the alarm to chatter under the visible level, both measured against the
simulated cut's true chatter amplitude. See [Online supervisor](supervisor.md).""",
    "planner": """\
Every method under identical limits. `thesis` is the thesis section algorithm
([model §8](model.md#8-toolpath-sections-feed-optimisation)) held at every sample, the baseline;
`thesis_as_published` is the same algorithm checking section midpoints only, whose violations the
independent checker counts. The split bound is the least cut time of any plan whose sections are at
least `section_length_min_mm` long; the pointwise ideal gives every sample its own ceiling. See
[Feed planning](planner.md) for how to read them.""",
    "engagement": """\
The baseline is the 2.5-D per-level model on the same samples, both checked before they are timed;
the share is of the whole `plan_job` wall time of the same job. See
[model §8](model.md#8-toolpath-sections-feed-optimisation).""",
    "feed_intent": """\
The baseline is round one's rule for the moves that do not cut (air at `feed_max`, a plunge's feed
over its whole air run), emulated on this run's plan and re-timed; then each round-two rule in
turn. Every plan passes the independent checker. See [Feed planning](planner.md).""",
    "detector": """\
How soon each chatter detector sees growing chatter, in periods of the chatter frequency (a 10–20
Hz band cannot be resolved in the thesis's "≈ 5 ms"), and how often it cries wolf in an hour of
simulated stable cutting with feed steps and entries and exits, at the same false-alarm rate α_f.""",
    "compensation": """\
Deflection compensation on a simulated wall whose true arm is 20 % softer than the model and whose
stock differs from the plan by ±1 mm: the offline mirror (`export --compensate-deflection`), online
RKorr through RSI, both, and the bound any feed-forward correction with that stiffness error has.""",
    "calibration": """\
The model learning from the cell's own cuts: a simulated true cell (joint stiffness ×0.7,
coefficients +15 %, process gain ×1.3, regeneration on) runs test passes with realistic force
noise; the fits recover what they can and say, with intervals, what the data cannot pin down.""",
    "calibration_loop": """\
The loop a cell would run: the nominal plan, test passes in the truth, `cctmill calibrate`, the
replan, and every cut section of each plan simulated in the truth at its planned feed; beside them
the plan made with the truth's own stiffness and coefficients.""",
    "placement": """\
The baseline is the same placement study run serially in this process; the LocalCluster's workers
are warmed up first (one plan each) and its results must equal the serial ones row for row before
the time counts. The scheduler overhead is the end-to-end cost of a task that does nothing, through
the same engine. See [Cell placement](placement.md) for the sizing estimate drawn from these
figures.""",
    "krl": """\
Write → lint → read back with our own KRL reader. "Absorbed" samples are plan samples inside a
CIRC; their distance is to the read-back arc. See [KRL export](krl.md).""",
}


SUMMARY_HEAD = ["| benchmark | this run | target / published | verdict |", "|---|---|---|---|"]


def throughput_rows(report) -> list[tuple[str, str, str, str]]:
    """Summary rows of ``throughput.py``: the best variant, the CasADi VM, the baseline."""
    import throughput

    rows = report.rows
    base = rows[0]
    by_name = {r.variant: r for r in rows}
    best = by_name[report.best]
    vm = by_name.get("casadi VM  serial map, zero-copy buffer")
    out = [(f"throughput: best variant ({best.variant})",
            f"{best.rate:,.0f} poses/s, {best.ratio:,.0f}× baseline, 1e8 poses in "
            f"{throughput._hms(best.hours_1e8)}",
            f"≥ {throughput.TARGET_RATE:,.0f} poses/s and ≥ {throughput.TARGET_RATIO:.0f}×",
            "met" if report.targets_met else "NOT met")]
    if vm is not None:
        out.append(("throughput: CasADi VM serial map",
                    f"{vm.rate:,.0f} poses/s, {vm.ratio:,.0f}× baseline, 1e8 poses in "
                    f"{throughput._hms(vm.hours_1e8)}", "(no target)", "—"))
    out.append(("throughput: per-pose numpy/pinocchio baseline",
                f"{base.rate:,.0f} poses/s, 1e8 poses in {throughput._hms(base.hours_1e8)}",
                "agrees with the kernel", base.agreement.removeprefix("vs kernel: ")))
    return out


def figure_rows(figures) -> list[tuple[str, str, str, str]]:
    """Summary rows of ``thesis_figures.py``: one per published figure."""
    return [(f.figure, f.model, f.published, f.verdict) for f in figures]


def machine_line(report) -> str:
    m = report.machine
    return (f"Machine: {m['nproc']} cores, {m['cpu']}; casadi {m['casadi']}, "
            f"pinocchio {m['pinocchio']}, numpy {m['numpy']}, gcc {m['gcc']}.")


def summary_table(rows: list[tuple[str, str, str, str]], machine: str | None) -> str:
    lines = list(SUMMARY_HEAD)
    for row in rows:
        lines.append("| " + " | ".join(c.replace("|", "\\|") for c in row) + " |")
    if machine:
        lines += ["", machine]
    return "\n".join(lines)


def _verdict(ok: bool) -> str:
    return "met" if ok else "NOT met"


def toolpath_rows(speed: dict) -> list[tuple[str, str, str, str]]:
    p = speed.get("parse", {}) if isinstance(speed, dict) else {}
    if "ratio_vs_tokenise" not in p:
        return []
    return [("toolpath: read_gcode vs pygcode Line, largest shared file",
             f"{p['ratio_vs_tokenise']:.1f}× (worst {p['ratio_cctmill_vs_tokenise_worst']:.1f}×); "
             f"with every Move built {p['ratio_cctmill_moves_vs_tokenise']:.1f}×",
             "≥ 10× pygcode", _verdict(p["ratio_vs_tokenise"] >= 10))]


def planner_rows(plans: dict) -> list[tuple[str, str, str, str]]:
    d, lg, t = plans["demo"]["methods"], plans["long"], plans["targets"]
    return [
        ("planner: demo cycle time, optimize vs thesis vs constant",
         f"{d['optimize']['cycle_time_s']:.1f} / {d['thesis']['cycle_time_s']:.1f} / "
         f"{d['constant']['cycle_time_s']:.1f} s ({100 * plans['demo_gain_vs_thesis']:.1f} % "
         "shorter than thesis; no plan with sections ≥ the job's section_length_min can "
         "cut more than "
         f"{100 * plans['demo_cut_gain_ceiling']:.1f} % faster than thesis)",
         "≥ 20 % shorter than thesis", _verdict(t["demo_gain"])),
        (f"planner: {lg['samples']:,}-sample job planned (prepare + plan), peak memory",
         f"{lg['methods']['optimize']['total_s']:.2f} s, {lg['peak_rss_mb']:.0f} MB; "
         f"IPOPT {lg['methods']['optimize']['ipopt_iterations']} iterations",
         "< 10 s, < 2 GB", _verdict(t["long_time"] and t["long_memory"])),
        ("planner: independent check of every plan (every sample)",
         "0 violations" if t["every_plan_checked_ok"] else "violations found",
         "none", _verdict(t["every_plan_checked_ok"])),
    ] + (_module("posture").summary_rows(plans["cells"]) if "cells" in plans else [])


def engagement_rows(r: dict) -> list[tuple[str, str, str, str]]:
    rows = []
    for name, key in (("demo", "demo"), ("Fusion 360 program", "fusion")):
        d = r[key]
        if "skipped" in d:
            continue
        cold = d["cold"]["share_of_plan"]
        rows.append((f"engagement (Z-map): {name}, {d['samples']:,} samples",
                     f"{d['zmap_ms_per_sample']:.3f} ms/sample, {100 * d['share_of_plan']:.1f} % of "
                     f"the planning wall time ({d['speedup_vs_stock']:.1f}× the 2.5-D model); "
                     f"{100 * cold:.1f} % in the first plan of a new process",
                     "< 20 % of planning", _verdict(d["share_of_plan"] < 0.20 and cold < 0.20)))
    return rows


def feed_intent_rows(r: dict) -> list[tuple[str, str, str, str]]:
    o = r["methods"]["optimize"]
    ok = all(row["check_ok"] in (None, True) for m in r["methods"].values() for row in m.values())
    return [("planner: demo cycle, round one's air/plunge rule → round two (optimize)",
             f"{o['round_one']['cycle_time_s']:.1f} → {o['demo_factor_2']['cycle_time_s']:.1f} s "
             f"(default factor 1: {o['default_factor_1']['cycle_time_s']:.1f} s)",
             "every plan checked clean", _verdict(ok))]


def placement_rows(r: dict) -> list[tuple[str, str, str, str]]:
    cl, sc, bo = r["cluster"], r["screen"], r["best_vs_own"]
    return [
        ("placement: demo study, LocalCluster(2) vs serial",
         f"{cl['speedup']:.2f}× ({r['grid']['plans']} plans; identical results); "
         f"{r['scheduler']['per_task_ms']:.2f} ms a trivial task", "≥ 1.7×",
         _verdict(cl["speedup"] >= 1.7)),
        ("placement: demo best $BASE vs its own (cycle)",
         f"{bo['refined_best_cycle_s']:.1f} s vs {bo['own_cycle_s']:.1f} s (grid best "
         f"{bo['grid_best_cycle_s']:.1f} s); the screen pruned {100 * sc['pruning_ratio']:.0f} %",
         "the screen keeps the full grid's best", _verdict(sc["kept_full_grid_best"])),
    ]


def krl_rows_summary(krl_rows: list[dict]) -> list[tuple[str, str, str, str]]:
    worst_pos = max(r["pos_err_mm"] for r in krl_rows)
    worst_ang = max(r["ang_err_deg"] for r in krl_rows)
    exact = all(r["feeds_exact"] and r["lint"] == 0 for r in krl_rows)
    return [("KRL: write → read round trip (demo + paged long job)",
             f"worst {worst_pos:.1e} mm, {worst_ang:.1e} deg; feeds exact and lint clean: "
             f"{'yes' if exact else 'no'}", "0.001 mm, 0.001 deg, feeds exact",
             _verdict(worst_pos <= 1e-3 and worst_ang <= 1e-3 and exact))]


def supervisor_rows(sup: dict) -> list[tuple[str, str, str, str]]:
    st = sup["step"]["intrinsic"]
    rows = [("supervisor: step latency (per-step minimum of identical runs), worst",
             f"{st['max_ms']:.3f} ms (p99 {st['p99_ms']:.3f} ms)", "well inside 4 ms",
             _verdict(sup["step"]["of_cycle_intrinsic"]["4ms"] < 0.5))]
    db4 = sup["closed_loop"].get("db4")
    if db4:
        det, settle = db4["detection_delay_ms"]["max"], db4["settling_ms"]["max"]
        rows.append(("supervisor: detection delay / closed-loop settling (db4, worst)",
                     f"{det:.0f} ms / {settle:.0f} ms" if det is not None and settle is not None
                     else "no episode", "thesis ≈ 5 ms / 0.27–0.3 s",
                     f"detection {_verdict(det is not None and det <= 5)}, settling "
                     f"{_verdict(settle is not None and settle <= 300)}"))
    return rows


def dynamics_rows(dynamics_md: str) -> list[tuple[str, str, str, str]]:
    first = next((line for line in dynamics_md.splitlines() if line.startswith("| ") and "met" in line), None)
    if not first:
        return []
    cells = [c.strip() for c in first.strip("|").split("|")]
    return [(f"dynamics: {cells[0]}", f"{cells[1]} sim s / wall s", "≥ 1 at 5 kHz",
             "met" if cells[-1].endswith("met") and "NOT" not in cells[-1] else "NOT met")]


class Step:
    """One benchmark: its result, its markdown and its summary rows — or the error that stopped it."""

    def __init__(self, key: str, title: str) -> None:
        self.key, self.title = key, title
        self.result: Any = None
        self.markdown = ""
        self.rows: list[tuple[str, str, str, str]] = []
        self.error: str | None = None
        self.seconds = 0.0

    def run(self, log: Callable[[str], None], fn: Callable[[], Any],
            markdown: Callable[[Any], str], rows: Callable[[Any], list] = lambda _r: []) -> Step:
        """``fn()`` → result; then its markdown and rows. Any exception is kept, not raised."""
        log(f"{self.title} ...")
        t0 = time.perf_counter()
        try:
            self.result = fn()
            self.markdown = markdown(self.result)
            self.rows = rows(self.result)
        except Exception as e:  # noqa: BLE001 - one failing benchmark must not stop the others
            last = traceback.extract_tb(e.__traceback__)[-1]
            self.error = (f"{type(e).__name__}: {e} "
                          f"({Path(last.filename).name}:{last.lineno})").replace("\n", " ")
            log(f"FAILED {self.title}: {self.error}")
        self.seconds = time.perf_counter() - t0
        return self

    def body(self) -> str:
        if self.error is None:
            return self.markdown
        return (f"**Not run in this run**: the benchmark failed with `{self.error}`. "
                "Its figures are missing here and in the summary; run `make bench` again once it "
                "is fixed.")


def _module(name: str):
    return importlib.import_module(name)


def main(argv: list[str] | None = None) -> tuple[str, bool]:
    """Run every benchmark, write the files; return the summary document and whether all ran."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=100_000, help="poses for the throughput benchmark")
    ap.add_argument("--baseline-n", type=int, default=2_000,
                    help="poses for the per-pose baseline")
    ap.add_argument("--out", type=Path, default=OUT, help="summary file (default out/benchmarks.md)")
    ap.add_argument("--docs", type=Path, default=PERFORMANCE_PAGE,
                    help="the manual's performance page (default docs/performance.md)")
    ap.add_argument("--no-docs", action="store_true",
                    help="write out/benchmarks.md only, not the manual's pages")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()

    def log(s: str) -> None:
        print(s, file=sys.stderr, flush=True)

    figures = Step("figures", "thesis figures").run(
        log, lambda: _module("thesis_figures").figures(),
        lambda f: _module("thesis_figures").markdown(f), figure_rows)
    throughput_step = Step("throughput", "Point model throughput (`benchmarks/throughput.py`)").run(
        log, lambda: _module("throughput").run(args.n, args.baseline_n, log),
        lambda r: _module("throughput").format_table(r), throughput_rows)

    def toolpath_run():
        tp = _module("toolpath_speed")
        try:
            return {"parse": tp.parse_speed(3), "ik": tp.ik_speed(3)}, None
        except ImportError as e:  # pygcode missing: the bench extra is not installed
            return {}, f"skipped: {e}"

    toolpath = Step("toolpath", "Toolpath import and path kinematics "
                    "(`benchmarks/toolpath_speed.py`)").run(
        log, toolpath_run,
        lambda r: r[1] if r[1] else _module("toolpath_speed").markdown(r[0]),
        lambda r: toolpath_rows(r[0]))
    links = Step("links", "Robot link latency (`benchmarks/link_latency.py`)").run(
        log, lambda: _module("link_latency").run(),
        lambda r: _module("link_latency").markdown(r),
        lambda r: _module("link_latency").summary_rows(r))
    dynamics = Step("dynamics", "Dynamic simulation and deflection compensation "
                    "(`benchmarks/dynamics_speed.py`)").run(
        log, lambda: _module("dynamics_speed").report(), lambda md: md, dynamics_rows)
    supervisor = Step("supervisor", "Online supervisor (`benchmarks/supervisor_latency.py`)").run(
        log, lambda: _module("supervisor_latency").run(log=log),
        lambda r: _module("supervisor_latency").markdown(r), supervisor_rows)
    planner = Step("planner", "Feed planner (`benchmarks/plan_speed.py`)").run(
        log, lambda: _module("plan_speed").run(), lambda r: _module("plan_speed").markdown(r),
        planner_rows)

    engagement = Step("engagement", "Engagement from the stock (`benchmarks/engagement_speed.py`)").run(
        log, lambda: _module("engagement_speed").run(),
        lambda r: _module("engagement_speed").markdown(r), engagement_rows)
    intent = Step("feed_intent", "The programmed feed as intent (`benchmarks/feed_intent.py`)").run(
        log, lambda: _module("feed_intent").run(), lambda r: _module("feed_intent").markdown(r),
        feed_intent_rows)

    def krl_run():
        buf = io.StringIO()
        with contextlib.redirect_stdout(buf):
            rows = _module("krl_round_trip").main()
        return rows, buf.getvalue().strip()

    krl = Step("krl", "KRL export round trip (`benchmarks/krl_round_trip.py`)").run(
        log, krl_run, lambda r: r[1], lambda r: krl_rows_summary(r[0]))
    detector = Step("detector", "Chatter detectors (`benchmarks/detector_speed.py`)").run(
        log, lambda: _module("detector_speed").run(log=log),
        lambda r: _module("detector_speed").markdown(r),
        lambda r: _module("detector_speed").summary_rows(r))
    compensation = Step("compensation", "Online deflection compensation "
                        "(`benchmarks/compensation.py`)").run(
        log, lambda: _module("compensation").run(log=log),
        lambda r: _module("compensation").markdown(r),
        lambda r: _module("compensation").summary_rows(r))
    calibration = Step("calibration", "Calibration from cuts on a simulated truth "
                       "(`benchmarks/calibration.py`)").run(
        log, lambda: _module("calibration").run(log=log),
        lambda r: _module("calibration").markdown(r),
        lambda r: _module("calibration").summary_rows(r))
    loop = Step("calibration_loop", "The calibration loop on the simulated truth "
                "(`benchmarks/calibration_loop.py`)").run(
        log, lambda: _module("calibration_loop").run(log=log),
        lambda r: _module("calibration_loop").markdown(r),
        lambda r: _module("calibration_loop").summary_rows(r))
    placement = Step("placement", "Placement studies on Dask (`benchmarks/placement.py`)").run(
        log, lambda: _module("placement").run(log),
        lambda r: _module("placement").markdown(r), placement_rows)

    # Summary order: throughput, thesis figures, links, toolpath, engagement, planner, feed intent,
    # KRL, supervisor, detectors, compensation, dynamics, placement.
    steps = [throughput_step, figures, links, toolpath, engagement, planner, intent, krl,
             supervisor, detector, compensation, dynamics, calibration, loop, placement]
    failed = [st for st in steps if st.error is not None]
    rows = [row for st in steps for row in st.rows]
    rows += [(f"{st.title}", "failed: see its section", "—", "not run") for st in failed]
    machine = machine_line(throughput_step.result) if throughput_step.error is None else None
    table = summary_table(rows, machine)
    total = f"_Total wall time {time.perf_counter() - t0:.0f} s._"
    sections = [throughput_step, toolpath, engagement, links, supervisor, detector, compensation,
                dynamics, calibration, loop, planner, intent, krl, placement]
    doc = "\n\n".join([
        "# cctmill benchmarks",
        "## Summary", table,
        "## Validation against the thesis (benchmarks/thesis_figures.py)", figures.body(),
        *(part for st in sections for part in (f"## {st.title}", st.body())),
        total,
    ]) + "\n"
    write_text_atomic(args.out, doc)
    print(table)
    print(f"\nwrote {args.out}")
    if not args.no_docs:
        write_text_atomic(args.docs, performance_page(table, sections, total))
        print(f"wrote {args.docs}")
        if figures.error is not None:
            log(f"note: thesis figures failed; {VALIDATION_PAGE} not changed")
        elif replace_block(VALIDATION_PAGE, FIGURES_START, FIGURES_END, figures.markdown):
            print(f"wrote {VALIDATION_PAGE} (thesis figures)")
        else:
            log(f"note: {VALIDATION_PAGE} has no {FIGURES_START} … {FIGURES_END} block; not changed")
        if placement.error is None and replace_block(
                PLACEMENT_PAGE, SIZING_START, SIZING_END,
                placement.markdown + "\n\n" + _module("placement").sizing_markdown(placement.result)):
            print(f"wrote {PLACEMENT_PAGE} (sizing estimate)")
    for st in failed:
        log(f"FAILED: {st.title}: {st.error}")
    return doc, not failed


def performance_page(table: str, sections: list[Step], total: str) -> str:
    """docs/performance.md: the introduction, the summary and machine, every benchmark's tables."""
    parts = ["# Performance",
             "<!-- Written by benchmarks/run_all.py (make bench). Do not edit: run make bench. -->",
             PAGE_INTRO, "## Summary", table]
    for st in sections:
        parts += [f"## {st.title}", SECTION_INTROS[st.key], st.body()]
    parts.append(total)
    return "\n\n".join(parts) + "\n"


def replace_block(path: Path, start: str, end: str, body: str) -> bool:
    """Replace what lies between the marker lines ``start`` and ``end`` of ``path`` by ``body``.

    Returns False (and changes nothing) when the file or either marker is missing.
    """
    if not path.exists():
        return False
    text = path.read_text(encoding="utf-8")
    i, j = text.find(start), text.find(end)
    if i < 0 or j < i:
        return False
    # Blank lines around the body, so Markdown does not read it as part of the comment.
    new = text[:i + len(start)] + "\n\n" + body.strip("\n") + "\n\n" + text[j:]
    if new != text:
        write_text_atomic(path, new)
    return True


if __name__ == "__main__":
    sys.exit(0 if main()[1] else 1)
