"""``cctmill supervise``: the online chatter supervisor against a signal and a controller.

::

    cctmill supervise --plan PLAN_DIR_OR_JSON --signal FILE|udp://HOST:PORT|sim
                      --robot sim|kvp://HOST:PORT|rsi://BIND_HOST:PORT
                      [--log events.jsonl] [--fs-hz N] [--alpha-f 6e-5] [--duration-s S] ...

A thin layer over :func:`planner.supervisor.session.supervise` (what the names mean is documented
there): parses the flags into a :class:`~planner.supervisor.session.SessionConfig` and a
:class:`~planner.supervisor.sim_cut.CutScenario`, runs, prints the summary as text or ``--json``.

Exit status: 0 when the run needed no operator, :data:`EXIT_OPERATOR_ALARM` (3) when it raised an
operator alarm (the controller did not apply the override, chatter escalated at the floor, or the
run ended inside a chatter episode), 2 for a user's mistake.
"""

from __future__ import annotations

import argparse
import json

from models.errors import InputError
from planner._atomic import output_errors
from planner.cli._common import add_output
from planner.display import quantity
from planner.plan_file import load_plan
from planner.supervisor.compensation import CompensationConfig
from planner.supervisor.detectors import DEFAULT_DETECTOR, DETECTORS
from planner.supervisor.metrics import episode_outcome_text, episode_timing_text
from planner.supervisor.policy import SupervisorConfig
from planner.supervisor.session import SessionConfig, supervise
from planner.supervisor.sim_cut import CutScenario

__all__ = ["EXIT_OPERATOR_ALARM", "register", "run"]

#: Exit status of a run that raised an operator alarm (its summary lists them).
EXIT_OPERATOR_ALARM = 3

#: Flags of the library's fields, for messages that name a field.
_FLAGS = {"alpha_f": "--alpha-f", "cycle": "--cycle-ms", "duration": "--duration-s",
          "fs_hz": "--fs-hz", "sigma": "--sigma", "robot": "--robot", "signal": "--signal",
          "sim_protocol": "--sim-protocol", "rsi_config": "--rsi-config",
          "compensation": "--compensate-rkorr", "max_position_mm": "--rkorr-max-mm",
          "max_rate_mm_s": "--rkorr-rate-mm-s"}


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``supervise`` subcommand."""
    p = sub.add_parser("supervise", help="online wavelet chatter supervisor: signal in, feed override out")
    p.add_argument("--plan", required=True, metavar="PLAN_DIR_OR_JSON", help="plan from `cctmill plan`")
    p.add_argument("--signal", required=True, metavar="FILE|udp://HOST:PORT|sim",
                   help="recorded CSV/NPY (replayed in real time), UDP sample stream to bind, or sim")
    p.add_argument("--robot", required=True, metavar="sim|kvp://HOST:PORT|rsi://BIND_HOST:PORT",
                   help="simulated controller over loopback, KukaVarProxy to connect to, or the RSI "
                        "server address to bind")
    p.add_argument("--rsi-config", metavar="ETHERNET.xml",
                   help="RSI: the controller's ETHERNET configuration (SENTYPE, correction element, "
                        "override tags; see docs/links.md)")
    p.add_argument("--signal-column", metavar="NAME",
                   help="CSV value column (default: the first non-time column; e.g. resultant_N "
                        "for a `cctmill simulate --out` record)")
    add_output(p, "--log", kind="append", metavar="events.jsonl",
               help="append every decision as JSON lines (in an existing folder)")
    p.add_argument("--fs-hz", type=float, help="sample rate [Hz] (files without a time column, sim; "
                                               "default 10000 for sim, from the stream for udp)")
    p.add_argument("--alpha-f", type=float, default=6e-5,
                   help="false-alarm rate per band value (default 6e-5: L_c = 4.0)")
    p.add_argument("--detector", choices=sorted(DETECTORS), default=DEFAULT_DETECTOR,
                   help="chatter detector: dwt (the thesis's wavelet band, default) or iir "
                        "(band-pass with tooth notches, faster; docs/supervisor.md)")
    p.add_argument("--duration-s", type=float, help="stop after this long [s] (default: sim 6 s, file: "
                                                     "its length, udp: until Ctrl-C)")
    p.add_argument("--cycle-ms", type=float, default=4.0, help="supervisor cycle [ms] (KR C4 4, KR C2 12)")
    p.add_argument("--sigma", type=float, help="band sigma of stable cutting (signal unit)")
    p.add_argument("--stable-s", type=float, default=1.0,
                   help="learn sigma from this much signal at the start [s] (default 1)")
    p.add_argument("--floor-pct", type=float, default=20.0, help="lowest override [%%] (default 20)")
    p.add_argument("--safe-pct", type=float, help="override when the signal is lost [%%] (default: floor)")
    p.add_argument("--start-mm", type=float, default=0.0, help="arc length where the cut starts [mm]")
    c = p.add_argument_group("online deflection compensation (RSI RKorr; docs/compensation.md)")
    c.add_argument("--compensate-rkorr", action="store_true",
                   help="send a Cartesian correction every cycle: mean force -> engagement -> deflection "
                        "-> RKorr (RSI links; off by default)")
    c.add_argument("--rkorr-frame", choices=["base", "tool"], default="base",
                   help="frame of the correction, as the POSCORR object's RefCorrSys (default base)")
    c.add_argument("--rkorr-max-mm", type=float, default=5.0,
                   help="bound of each component of the total correction [mm] (default 5, KUKA's POSCORR "
                        "example; rotations are bounded at 5 deg and stay zero)")
    c.add_argument("--rkorr-rate-mm-s", type=float, default=10.0,
                   help="largest speed of the correction [mm/s] (default 10)")
    c.add_argument("--rkorr-offline", action="store_true",
                   help="the program was exported with --compensate-deflection: correct only what the "
                        "plan's deflection did not")
    g = p.add_argument_group("simulation (--signal sim / --robot sim)")
    g.add_argument("--sim-protocol", choices=["kvp", "rsi"], default="kvp",
                   help="protocol of the simulated controller (default kvp)")
    g.add_argument("--chatter-onset-s", type=float, default=2.0,
                   help="when the cut becomes less stable than planned [s] (default 2; negative: never)")
    g.add_argument("--boundary-shift", type=float, default=1.6,
                   help="after the onset the true margin at feed f is the plan's at f x this (default 1.6)")
    g.add_argument("--margin-offset-n-per-m", type=float, default=0.0,
                   help="after the onset the true margin is also this much lower [N/m] (default 0)")
    g.add_argument("--signal-loss-s", metavar="A:B", help="no samples between A and B [s]")
    g.add_argument("--seed", type=int, default=0, help="noise seed")
    g.add_argument("--fast", action="store_true",
                   help="--signal sim with kvp://: run on a virtual clock (no sleeping)")
    add_output(p, "--plot", kind="file", metavar="FILE.png",
                   help="plot the band against its limit, the override and (sim) the true chatter")
    add_output(p, "--records", kind="append", metavar="CUTS.jsonl",
               help="append one cut record per section run, with the detector's verdict, the "
                    "chatter frequency seen and (a force signal in known axes: --signal sim) "
                    "the steady mean force, for cctmill calibrate (docs/calibration.md); needs "
                    "--tool")
    p.add_argument("--tool", metavar="NAME", help="the tool data name the records give (a name of "
                                                  "cctmill tools, the one the plan was made with)")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.set_defaults(run=run)


def _scenario(args: argparse.Namespace) -> CutScenario:
    loss = None
    if args.signal_loss_s:
        try:
            a, b = (float(x) for x in args.signal_loss_s.split(":"))
        except ValueError:
            raise InputError("--signal-loss-s", f"{args.signal_loss_s!r}: expected A:B seconds") from None
        if not 0 <= a < b:
            raise InputError("--signal-loss-s", "need 0 <= A < B")
        loss = (a, b)
    if not args.boundary_shift > 0:
        raise InputError("--boundary-shift", "must be positive")
    onset = args.chatter_onset_s if args.chatter_onset_s is not None and args.chatter_onset_s >= 0 else None
    return CutScenario(onset_s=onset, boundary_shift=args.boundary_shift, loss_s=loss, seed=args.seed,
                       margin_offset_N_per_m=args.margin_offset_n_per_m)


def session_config(args: argparse.Namespace) -> SessionConfig:
    """The session settings the flags ask for (SI)."""
    return SessionConfig(
        supervisor=SupervisorConfig(alpha_f=args.alpha_f, floor_pct=args.floor_pct,
                                    safe_pct=args.safe_pct, detector=args.detector),
        cycle=args.cycle_ms * 1e-3, duration=args.duration_s, fs_hz=args.fs_hz, sigma=args.sigma,
        learn=args.stable_s, start=args.start_mm * 1e-3, log=args.log, plot=args.plot,
        signal_column=args.signal_column, sim_protocol=args.sim_protocol, fast=args.fast,
        rsi_config=args.rsi_config,
        compensation=(CompensationConfig(cycle_s=args.cycle_ms * 1e-3, max_position_mm=args.rkorr_max_mm,
                                         max_rate_mm_s=args.rkorr_rate_mm_s, frame=args.rkorr_frame)
                      if args.compensate_rkorr else None),
        compensation_offline=args.rkorr_offline, records=args.records,
        records_tool=args.tool or "")


def run(args: argparse.Namespace) -> int:
    """``cctmill supervise``: run the session, print its summary (text or JSON)."""
    if args.records and not args.tool:
        raise InputError("--records", "needs --tool NAME: the records name the tool the plan was "
                         "made with (see cctmill tools)")
    plan = load_plan(args.plan)
    try:
        with output_errors(args.log, args.plot, args.records, unnamed=False):   # the log is opened inside
            summary = supervise(plan, args.signal, args.robot, session_config(args),
                                _scenario(args))
    except InputError as e:
        if e.field in _FLAGS:   # a library field: say it as the flag the user typed
            raise InputError(_FLAGS[e.field], str(e).split(": ", 1)[-1]) from None
        raise
    doc = summary.as_json()
    print(json.dumps(doc, indent=2) if args.json else _text(doc))
    return EXIT_OPERATOR_ALARM if summary.alarms else 0


def _g(x: float | None) -> str:
    return "(learning)" if x is None else f"{x:.4g}"


def _text(s: dict) -> str:
    rows = [f"plan          {s['plan']}",
            f"signal        {s['signal']} at {s['fs_hz']:g} Hz; robot {s['robot']}",
            f"detector      {s.get('detector_reason', s['level_reason'])}",
            f"chart         L_c {s['L_c']:.3f}, sigma {_g(s['sigma'])}, UCL {_g(s['ucl'])}"]
    if "steps" in s:
        lat = s["step_latency_ms"]
        rows.append(f"steps         {s['steps']} over {s['duration_s']:.2f} s: "
                    + ", ".join(f"{k} {v}" for k, v in sorted(s["status_counts"].items())))
        rows.append(f"step latency  p50 {quantity(lat['p50'], 'g', 'ms')}, p99 "
                    f"{quantity(lat['p99'], 'g', 'ms')}, max {quantity(lat['max'], 'g', 'ms')} "
                    f"(cycle {quantity(lat['cycle'], 'g', 'ms')}; overruns {s['overruns']})")
        final = quantity(s["final_override"], ".1f", "%", missing="none commanded")
        applied = quantity(s.get("final_applied_override"), ".0f", "%", missing="none reported")
        rows.append(f"override      final {final}; applied by the controller {applied}; "
                    f"link writes {s['link_writes']}, failures {s['link_failures']}, downs "
                    f"{s['link_downs']}, refused {s.get('link_refusals', 0)}, not followed "
                    f"{s.get('link_not_followed', 0)} (follow time "
                    f"{quantity(s.get('follow_ms'), 'g', 'ms')})")
    ls = s["link_stats"]
    rows.append("link          " + ", ".join(f"{k} {v}" for k, v in ls.items() if k != "last_error")
                + (f"; last error: {ls['last_error']}" if ls.get("last_error") else ""))
    ss = s["source_stats"]
    rows.append("source        " + ", ".join(f"{k} {v}" for k, v in ss.items() if k != "last_error"))
    rows.append(f"episodes      {len(s['episodes'])}")
    for e in s["episodes"]:
        timing = episode_timing_text(e)
        rows.append(f"  section {e['section']}: override {e['override_start']:.1f} -> "
                    f"{quantity(e['override_min'], '.1f')} % (direction {e['direction']:+d})"
                    + (f"; {timing}" if timing else "") + f"; {episode_outcome_text(e)}")
    alarms = s.get("alarms", [])
    rows.append(f"operator      {len(alarms)} alarm(s)" + (
        f" (exit status {EXIT_OPERATOR_ALARM})" if alarms else ": none needed"))
    for a in alarms:
        rows.append(f"  at {a['after_s']:.3f} s, section {a['section']}, {a['kind']}: {a['reason']}")
    comp = s.get("compensation")
    if comp:
        tot = ", ".join(f"{v:+.3f}" for v in comp["total"][:3])
        rows.append(f"RKorr         {comp['frame']} frame, {comp['mode']}: "
                    + ", ".join(f"{k} {v}" for k, v in sorted(comp["status_counts"].items()))
                    + f"; refused {comp['link_failures']}; total ({tot}) mm")
    rec = s.get("records")
    if rec:
        rows.append(f"records       {rec['written']} cut record(s) appended to {rec['file']}"
                    + (f"; {rec['errors']} failed ({rec['last_error']})" if rec["errors"] else ""))
    if s.get("log"):
        rows.append(f"log           {s['log']}")
    if s.get("plot"):
        rows.append(f"plot          {s['plot']}")
    return "\n".join(rows)

