"""``cctmill simulate``: the time-domain cut at one pose (docs/model.md §6), its verdicts and signals.

Thin shell over :func:`planner.simulation.simulate_point` (the simulation, Floquet, the point
model) and :func:`planner.simulation.write_signal_csv`. The pose/cut flags are those of
``cctmill analyze``; the model defaults differ: the ``oriented`` process model, the ``robot`` mass
and the ``floquet`` criterion (the exact one for the time-periodic cut) decide
``stable_predicted``.
"""

from __future__ import annotations

import argparse
import json
import math

import numpy as np

from models.cutter_geometry import DEFAULT_SLICES
from models.errors import InputError
from models.structure import DEFAULT_DAMPING_RATIO
from models.tooling import available_tools
from planner.simulation import SimulationOptions, simulate_point, write_signal_csv

__all__ = ["register"]


def register(sub) -> None:
    """Add the ``simulate`` subcommand to ``sub`` (argparse sub-parsers)."""
    from planner.cli._common import add_output, add_point_flags

    p = sub.add_parser(
        "simulate", help="time-domain simulation of the cut on the flexible arm (forces, chatter)",
        description="2-DOF time-domain simulation in the plane normal to the tool axis (X_o, Z_o) "
                    "with the arm's mass and stiffness at the pose, a helical cutter in axial "
                    "slices and the equilibrium chip thickness (docs/model.md §6). The verdict "
                    "stable_predicted comes from --criterion (default floquet).")
    add_point_flags(p, with_feed=True)
    g = p.add_argument_group("simulation")
    g.add_argument("--duration-s", type=float, default=2.0, help="simulated time [s] (default 2)")
    g.add_argument("--fs-hz", type=float, default=5000.0,
                   help="output sample rate [Hz] (default 5000); the integrator runs at least as "
                        "fast, with a whole number of steps per tooth period")
    mode = g.add_mutually_exclusive_group()
    mode.add_argument("--iterate", dest="iterate", action="store_true", default=True,
                      help="equilibrium chip thickness per step, to 1 %% force change (default)")
    mode.add_argument("--first-iteration", dest="iterate", action="store_false",
                      help="the thesis's first iteration: the structure answers the rigid-chip "
                           "force, the chip is updated once")
    g.add_argument("--no-regeneration", action="store_true",
                   help="smooth surface (no previous-flute waviness): the model Floquet judges")
    g.add_argument("--initial", choices=("static", "rest", "periodic"), default="static",
                   help="start at the static equilibrium (default: the entry transient follows), "
                        "at rest on the nominal path, or on the tooth-periodic motion of the "
                        "linearised cut (no entry transient; add --perturbation-um to see growth)")
    g.add_argument("--perturbation-um", type=float, default=0.0,
                   help="initial displacement along (X_o + Z_o)/sqrt(2) [um] (default 0)")
    g.add_argument("--damping-ratio", type=float, default=DEFAULT_DAMPING_RATIO,
                   help=f"modal damping ratio of both arm modes (default {DEFAULT_DAMPING_RATIO})")
    g.add_argument("--tool", default="em25_2f",
                   help=f"tool data for the helix angle (shipped: {', '.join(available_tools())})")
    g.add_argument("--slices", type=int, default=DEFAULT_SLICES, help="axial slices of the cutter")
    g.add_argument("--noise-n", type=float, default=0.0,
                   help="standard deviation of the force noise in --out [N] (default 0)")
    g.add_argument("--seed", type=int, default=0, help="noise seed (default 0)")
    add_output(g, "--out", kind="file", metavar="signal.csv",
                   help="write time, force, resultant, strain and displacement as CSV")
    add_output(g, "--plot", kind="file", metavar="FILE.png",
               help="plot the resultant force and its spectrum")
    p.set_defaults(run=run, process_model="oriented", mass="robot", criterion="floquet")


#: SimulationOptions fields → the flags that set them.
_FLAGS = {"duration": "--duration-s", "fs_hz": "--fs-hz", "damping_ratio": "--damping-ratio",
          "slices": "--slices", "perturbation": "--perturbation-um", "noise": "--noise-n"}


def _plot(sim, path: str) -> None:
    """Resultant force against time, and its spectrum over the analysis window."""
    from planner.report.plots import new_figure, save_figure

    plt, fig = new_figure(figsize=(9, 6))
    ax1, ax2 = fig.add_subplot(2, 1, 1), fig.add_subplot(2, 1, 2)
    ax1.plot(sim.time, np.linalg.norm(sim.force, axis=1), lw=0.6)
    ax1.axvspan(sim.window_start, sim.time[-1], color="0.9", label="analysis window")
    ax1.set_xlabel("time [s]")
    ax1.set_ylabel("|F| [N]")
    ax1.legend(loc="upper right")
    ax2.semilogy(sim.spectrum_hz, np.maximum(sim.spectrum, 1e-9), lw=0.8)
    ax2.set_xlim(0, min(sim.spectrum_hz[-1], 10.0 / sim.tooth_period))
    ax2.set_xlabel("frequency [Hz]")
    ax2.set_ylabel("|F| amplitude [N]")
    save_figure(plt, fig, f"F_peak {sim.f_peak:.1f} N, F_PV {sim.f_pv:.1f} N, growth "
          f"{sim.growth_rate:+.2f} 1/s ({'iterated' if sim.iterate else 'first iteration'}, "
          f"regeneration {'on' if sim.regeneration else 'off'})", path)


def run(args: argparse.Namespace) -> int:
    """Run ``cctmill simulate``; print JSON or a summary."""
    from planner.cli._common import point_setup

    if not (math.isfinite(args.feed_mm_s) and args.feed_mm_s > 0):
        raise InputError("--feed-mm-s", f"must be positive, got {args.feed_mm_s}")
    options = SimulationOptions(
        tool=args.tool, damping_ratio=args.damping_ratio, duration=args.duration_s,
        fs_hz=args.fs_hz, iterate=args.iterate, regeneration=not args.no_regeneration,
        slices=args.slices, initial=args.initial, perturbation=args.perturbation_um * 1e-6,
        noise=args.noise_n, seed=args.seed)
    try:
        options.check()
    except InputError as e:
        raise InputError(_FLAGS.get(e.field, e.field), str(e).split(": ", 1)[1]) from None
    model, q, cut = point_setup(args)
    report = simulate_point(model, q, cut, args.feed_mm_s * 1e-3, options)
    sim, fl, point, structure = report.sim, report.floquet, report.point, report.structure
    out = report.as_json()
    out["perturbation_um"] = args.perturbation_um  # as typed (the JSON's other values are SI)
    if args.out:
        write_signal_csv(report, args.out)
        out["out"] = args.out
    if args.plot:
        _plot(sim, args.plot)
        out["plot"] = args.plot
    if args.json:
        print(json.dumps(out, indent=2))
    else:
        verdict = "stable" if out["stable_predicted"] else "UNSTABLE"
        print(f"F_peak {sim.f_peak:.1f} N, F_PV {sim.f_pv:.1f} N "
              f"(F_PV/F_peak {100 * sim.dynamic_ratio:.1f} %: static force model "
              f"{'valid' if out['static_model_valid'] else 'NOT valid'})")
        print(f"iterations per step {sim.iterations_mean:.2f}, dominant force frequency "
              f"{sim.dominant_frequency_hz:.1f} Hz, vibration {sim.vibration_frequency_hz:.1f} Hz, "
              f"growth {sim.growth_rate:+.2f} 1/s")
        print(f"{report.criterion}: {verdict} (Floquet rho {fl.spectral_radius:.4f}, eigen "
              f"{'stable' if point.stable_eigen else 'unstable'}); modes "
              + ", ".join(f"{f:.1f}" for f in structure.natural_frequencies_hz)
              + f" Hz, tooth {1 / sim.tooth_period:.1f} Hz")
        for w in point.warnings:
            print(f"warning: {w}")
        for key in ("out", "plot"):
            if key in out:
                print(f"{key}: {out[key]}")
    return 0
