"""``cctmill`` command line: a thin shell over library calls.

Units at this edge carry their names (``--feed-mm-s``, ``--ae-mm``, ``--joints-deg``); everything is
converted to SI before it reaches :mod:`models`, and JSON output is SI (angles in degrees, named so).
Errors a user can cause print one line ``cctmill <command>: error: ...`` and exit with status 2;
no traceback.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from models.analysis import MASS_MODELS, PROCESS_MODELS, Cut, ModelParameters
from models.cutting import MILLING_MODES, available_materials, load_material
from models.errors import CctmillError, InputError
from models.point import CRITERIA, PointModel
from models.robot import DEFAULT_ROBOT, available_robots, load_robot
from planner._atomic import write_text_atomic
from planner.report.tables import analysis_json, analysis_table, characteristic_table

__all__ = ["build_parser", "main"]

#: Modules that add one subcommand each: ``register(sub)`` adds its parser and sets ``run``.
#: One module per command keeps this shell thin and the commands apart.
_COMMAND_MODULES: tuple[str, ...] = ("planner.cli.export", "planner.cli.plan",
                                     "planner.cli.robot_sim", "planner.cli.simulate",
                                     "planner.cli.supervise")

#: The thesis's Case 1 (pose, frame and cut), used by ``cctmill demo``.
CASE1 = {
    "joints_deg": "-96.42,-29.26,99.08,-9.95,83.23,-160.5",
    "feed_dir": "0,1,0", "radial_dir": "1,0,0", "feed_mm_s": 1.0, "ae_mm": 15.24, "ap_mm": 5.08,
    "feed_range_mm_s": "0.5:8:31",
}


class _Parser(argparse.ArgumentParser):
    """argparse that reports a bad command line in one line (and exits 2)."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(2, f"{self.prog}: error: {message} (see --help)\n")


def _floats(text: str, n: int, flag: str) -> np.ndarray:
    try:
        values = np.array([float(v) for v in text.split(",")])
    except ValueError:
        raise InputError(flag, f"{text!r} is not {n} comma-separated numbers") from None
    if values.size != n or not np.all(np.isfinite(values)):
        raise InputError(flag, f"need {n} finite comma-separated numbers, got {text!r}")
    return values


def _add_point_flags(p: argparse.ArgumentParser, with_feed: bool) -> None:
    g = p.add_argument_group("pose and cut (units in the flag names)")
    g.add_argument("--joints-deg", required=True, metavar="A1,..,A6",
                   help="KUKA axis values A1..A6 [deg]")
    g.add_argument("--feed-dir", required=True, metavar="X,Y,Z",
                   help="feed direction Z_o in base axes")
    g.add_argument("--radial-dir", required=True, metavar="X,Y,Z",
                   help="radial direction X_o in base axes: the cutting edge at immersion 0; in up "
                        "milling the material lies on +X_o, in down milling on -X_o. "
                        "Y_o = Z_o x X_o runs along the axial depth (should be the tool axis)")
    if with_feed:
        g.add_argument("--feed-mm-s", required=True, type=float, help="feed speed [mm/s]")
    g.add_argument("--ae-mm", type=float, help="radial depth of cut [mm] (slot: the diameter)")
    g.add_argument("--ap-mm", required=True, type=float, help="axial depth of cut [mm]")
    g.add_argument("--tcp-mm", default="0,0,0", metavar="X,Y,Z",
                   help="TCP offset in the flange frame [mm] (default 0,0,0)")
    g.add_argument("--rpm", type=float, default=1000.0, help="spindle speed [rpm] (default 1000)")
    g.add_argument("--flutes", type=int, default=2, help="number of flutes (default 2)")
    g.add_argument("--diameter-mm", type=float, default=25.4, help="tool diameter [mm]")
    g.add_argument("--milling", choices=sorted(MILLING_MODES), default="up",
                   help="up, down or slot (default up)")
    g.add_argument("--material", default="al6061",
                   help=f"material data file (shipped: {', '.join(available_materials())})")
    m = p.add_argument_group("model")
    m.add_argument("--robot", default=DEFAULT_ROBOT,
                   help=f"robot data (shipped: {', '.join(available_robots())})")
    m.add_argument("--no-cct", action="store_true",
                   help="conventional stiffness (no force-dependent CCT term)")
    m.add_argument("--mass", choices=MASS_MODELS, default="isotropic",
                   help="mass model: isotropic (stiffness only) or robot (CRBA + spindle; gives "
                        "the 2-DOF natural frequencies)")
    m.add_argument("--process-model", choices=PROCESS_MODELS, default="thesis",
                   help="process stiffness: thesis (rank one, default) or oriented (Tlusty)")
    m.add_argument("--criterion", choices=CRITERIA, default="eigen",
                   help="stability criterion (default eigen)")
    m.add_argument("--gamma-window-deg", default="-90,90", metavar="LO,HI",
                   help="calibrated gamma window for --criterion gamma_window [deg]")
    m.add_argument("--joint-stiffness-scale", type=float, default=1.0,
                   help="multiply the robot's joint stiffness (calibration)")
    m.add_argument("--process-gain", type=float, default=1.0,
                   help="multiply the process stiffness K_p (calibration)")
    m.add_argument("--spindle-kg", type=float, default=None,
                   help="spindle point mass [kg] (default from the robot data)")
    p.add_argument("--json", action="store_true", help="print JSON (SI) instead of a table")


def _setup(args: argparse.Namespace) -> tuple[PointModel, np.ndarray, Cut]:
    robot = load_robot(args.robot)
    material = load_material(args.material)
    q = np.radians(_floats(args.joints_deg, robot.nq, "--joints-deg"))
    tcp = _floats(args.tcp_mm, 3, "--tcp-mm") * 1e-3
    radius = args.diameter_mm * 1e-3 / 2.0
    if args.ae_mm is None:
        if args.milling != "slot":
            raise InputError("--ae-mm", "required for up and down milling")
        a_e = 2.0 * radius
    else:
        a_e = args.ae_mm * 1e-3
    if not args.joint_stiffness_scale > 0:
        raise InputError("--joint-stiffness-scale", "must be positive")
    lo, hi = np.radians(_floats(args.gamma_window_deg, 2, "--gamma-window-deg"))
    if not lo < hi:
        raise InputError("--gamma-window-deg", "LO must be below HI")
    try:
        cut = Cut(feed_dir=_floats(args.feed_dir, 3, "--feed-dir"),
                  radial_dir=_floats(args.radial_dir, 3, "--radial-dir"), a_e=a_e,
                  a_p=args.ap_mm * 1e-3, mode=args.milling,
                  spindle_speed=args.rpm * 2.0 * np.pi / 60.0, flutes=args.flutes,
                  radius=radius)
    except InputError as e:
        flag = {"radial direction": "--radial-dir", "feed direction": "--feed-dir",
                "radial depth": "--ae-mm", "axial depth": "--ap-mm", "spindle speed": "--rpm",
                "tool radius": "--diameter-mm", "flutes": "--flutes"}.get(e.field, e.field)
        raise InputError(flag, str(e).split(": ", 1)[1]) from None
    params = ModelParameters(
        joint_stiffness=robot.data.joint_stiffness * args.joint_stiffness_scale,
        coefficients=material.coefficients(), cct=not args.no_cct,
        process_gain=args.process_gain, tcp=tcp, gamma_window=(float(lo), float(hi)),
        spindle_mass=robot.data.spindle_mass if args.spindle_kg is None else args.spindle_kg,
        spindle_com=robot.data.spindle_com)
    model = PointModel(robot, params, args.process_model, args.mass, args.criterion)
    return model, q, cut


def _cmd_analyze(args: argparse.Namespace) -> int:
    if not (np.isfinite(args.feed_mm_s) and args.feed_mm_s > 0):
        raise InputError("--feed-mm-s", f"must be positive, got {args.feed_mm_s}")
    model, q, cut = _setup(args)
    a = model.analyze(q, cut, args.feed_mm_s * 1e-3)
    if args.json:
        print(json.dumps(analysis_json(a, model.params.cct), indent=2))
    else:
        print(analysis_table(a, model.params.cct))
    return 0


def _feed_range(text: str) -> np.ndarray:
    parts = text.split(":")
    if len(parts) != 3:
        raise InputError("--feed-range-mm-s", f"need START:STOP:N, got {text!r}")
    try:
        start, stop, n = float(parts[0]), float(parts[1]), int(parts[2])
    except ValueError:
        raise InputError("--feed-range-mm-s", f"need START:STOP:N numbers, got {text!r}") from None
    if not (0 < start < stop and n >= 2):
        raise InputError("--feed-range-mm-s", "need 0 < START < STOP and N >= 2")
    return np.linspace(start, stop, n) * 1e-3


def _cmd_stability(args: argparse.Namespace) -> int:
    model, q, cut = _setup(args)
    ch = model.characteristic(q, cut, _feed_range(args.feed_range_mm_s), args.force_limit_n)
    if args.plot:
        from planner.report.plots import plot_characteristic

        plot_characteristic(ch, args.plot)
    if args.json:
        rows = []
        for p in ch.points:
            row = analysis_json(p, model.params.cct)
            row["feed_mm_s"] = p.feed * 1e3
            rows.append(row)
        print(json.dumps(rows, indent=2))
    else:
        print(characteristic_table(ch))
        if args.plot:
            print(f"plot: {args.plot}")
    return 0


def _cmd_demo(args: argparse.Namespace) -> int:
    """The physics core on the thesis's Case 1: analysis JSON, characteristic JSON and plot."""
    out = Path(args.output)
    out.mkdir(parents=True, exist_ok=True)
    parser = build_parser()
    base = ["--joints-deg", CASE1["joints_deg"], "--feed-dir", CASE1["feed_dir"],
            "--radial-dir", CASE1["radial_dir"], "--ae-mm", str(CASE1["ae_mm"]),
            "--ap-mm", str(CASE1["ap_mm"])]
    written = []
    from planner.report.plots import plot_characteristic

    for process in PROCESS_MODELS:
        for mass in MASS_MODELS:
            flags = ["--mass", mass, "--process-model", process]
            a_args = parser.parse_args(_join_negative_values(
                ["analyze", *base, "--feed-mm-s", str(CASE1["feed_mm_s"]), *flags]))
            model, q, cut = _setup(a_args)
            a = model.analyze(q, cut, CASE1["feed_mm_s"] * 1e-3)
            stem = f"case1_{process}_{mass}"
            path = out / f"{stem}_analysis.json"
            write_text_atomic(path, json.dumps(analysis_json(a, True), indent=2) + "\n")
            written.append(path)
            print(f"== Thesis Case 1: {process} process model, {mass} mass ==")
            print(analysis_table(a, True))
            ch = model.characteristic(q, cut, _feed_range(CASE1["feed_range_mm_s"]), 300.0)
            png = out / f"{stem}_stability.png"
            plot_characteristic(ch, png, title="Thesis Case 1")
            written.append(png)
            print(f"feed limit {ch.feed_limit * 1e3:.2f} mm/s, bound by {ch.binding}\n")
    from planner.demo import run_demo_job

    demo = run_demo_job(out)
    written += demo.written
    for line in demo.lines:
        print(line + "\n")
    print("wrote:")
    for w in written:
        print(f"  {w}")
    for note in demo.notes:
        print(f"note: {note}")
    h = demo.headline
    print(f"\nheadline: cycle time {h['cycle_time_s']:.1f} s vs {h['thesis_cycle_time_s']:.1f} s "
          f"for the thesis baseline ({100 * h['cycle_time_gain_vs_thesis']:.1f} % shorter); worst "
          f"predicted deflection {h['deflection_max_mm']:.3f} mm (normal to the wall "
          f"{h['deflection_normal_max_mm']:.3f} mm); chatter episodes caught "
          f"{h['chatter_episodes_caught']}")
    print(f"open {out / 'report.html'} (the plan) and {out / 'supervise.png'} (the supervised run)")
    return 0


def _inspect_table(summary: dict) -> str:
    bbox = summary["bbox_m"]
    feeds = summary["feed_mm_min"]
    rows = [
        f"file          {summary['file']}",
        f"format        {summary['format']} ({summary['units']})",
        f"moves         {summary['moves']}  (rapids {summary['rapids']}, arcs {summary['arcs']}"
        f", inverse-time {summary['inverse_time_moves']})",
        f"length        {summary['length_m']:.4f} m  (cutting {summary['cutting_length_m']:.4f} m)",
    ]
    if bbox:
        rows.append("bbox          " + "  ".join(
            f"{ax} {lo * 1e3:.3f}..{hi * 1e3:.3f}" for ax, lo, hi in zip("XYZ", *bbox,
                                                                        strict=True)) + " mm")
    if feeds:
        rows.append(f"feed          {feeds['min']:.1f} .. {feeds['max']:.1f} mm/min")
    axis = "yes (5-axis / tool-axis vectors)" if summary["has_tool_axis"] else "no (3-axis)"
    rows.append(f"tool axis     {axis}")
    if summary["skipped"]:
        rows.append("skipped       " + ", ".join(f"{k} {v}" for k, v in
                                                sorted(summary["skipped"].items())))
    rows.append(f"warnings      {len(summary['warnings'])}")
    rows += [f"  {w}" for w in summary["warnings"][:20]]
    if len(summary["warnings"]) > 20:
        rows.append(f"  ... {len(summary['warnings']) - 20} more (use --json)")
    return "\n".join(rows)


def _cmd_inspect(args: argparse.Namespace) -> int:
    from robot_io.readers import read_toolpath
    from robot_io.toolpath import summarize

    target = Path(args.file)
    if target.suffix.lower() == ".toml":
        from planner.job import load_job
        from planner.prepare import inspect_job, prepare

        job = load_job(target)
        prep = prepare(job)
        out = inspect_job(prep)
        if args.plot:
            from planner.report.plots import plot_path_kinematics

            e, k = prep.engagement, prep.kinematics
            plot_path_kinematics(prep.path.s, k.q, prep.robot.data.lower, prep.robot.data.upper,
                                 k.joint_names, k.reachable, e.a_e, e.a_p, e.mode, args.plot,
                                 title=f"{job.job.name}: joints and engagement along the path")
        if args.json:
            print(json.dumps(out, indent=2))
        else:
            for tp in out["toolpaths"]:
                print(_inspect_table(tp))
            r, e = out["reachability"], out["engagement"]
            print(f"samples       {out['samples']} over {out['path_length_m']:.4f} m")
            print(f"reachable     {'all' if r['all_reachable'] else 'NO'}"
                  f" ({r['unreachable_samples']} unreachable)")
            for line in r["problems"]:
                print(f"  {line}")
            for name, (lo, hi) in r["joint_range_deg"].items():
                print(f"  {name} {lo:8.2f} .. {hi:8.2f} deg")
            print(f"engagement    {e['source']}: " + ", ".join(f"{k} {v}" for k, v in e["modes"].items()))
            for key in ("ae_mm", "ap_mm"):
                if e[key]:
                    print(f"  {key[:2]} {e[key]['min']:.3f} / {e[key]['mean']:.3f} / "
                          f"{e[key]['max']:.3f} mm (min/mean/max)")
            if args.plot:
                print(f"plot: {args.plot}")
        return 0
    options = {"rotary": args.rotary} if args.rotary else {}
    tp = read_toolpath(target, strict=not args.lenient, **options)
    summary = summarize(tp)
    print(json.dumps(summary, indent=2) if args.json else _inspect_table(summary))
    return 0


def build_parser() -> argparse.ArgumentParser:
    """The ``cctmill`` argument parser (subcommands analyze, stability, demo)."""
    parser = _Parser(prog="cctmill", description="Planner and supervisor for robotic milling.")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    pa = sub.add_parser("analyze", help="stiffness, forces and chatter verdict at one pose")
    _add_point_flags(pa, with_feed=True)
    pa.set_defaults(run=_cmd_analyze)
    ps = sub.add_parser("stability", help="stability characteristic over a feed range")
    _add_point_flags(ps, with_feed=False)
    ps.add_argument("--feed-range-mm-s", required=True, metavar="START:STOP:N",
                    help="feeds [mm/s], N evenly spaced values")
    ps.add_argument("--force-limit-n", type=float, default=300.0,
                    help="resultant force limit [N] (thesis: 300 N)")
    ps.add_argument("--plot", metavar="FILE.png", help="write the characteristic as a plot")
    ps.set_defaults(run=_cmd_stability)
    pi = sub.add_parser("inspect", help="summary of a toolpath file, or of a job (reachability, "
                                       "engagement)")
    pi.add_argument("file", help="toolpath (.nc/.ngc/.apt/.cl/.src) or job file (.toml)")
    pi.add_argument("--json", action="store_true", help="print JSON (SI)")
    pi.add_argument("--lenient", action="store_true",
                    help="collect problems as warnings instead of stopping at the first")
    pi.add_argument("--rotary", choices=["none", "xyzac-trunnion"],
                    help="G-code rotary-axis kinematics for A/B/C words")
    pi.add_argument("--plot", metavar="FILE.png",
                    help="(job) joint angles and engagement along the path")
    pi.set_defaults(run=_cmd_inspect)
    pd = sub.add_parser("demo", help="run the bundled example and write its outputs")
    pd.add_argument("-o", "--output", default="out", help="output folder (default out/)")
    pd.set_defaults(run=_cmd_demo)
    import importlib

    for name in _COMMAND_MODULES:
        importlib.import_module(name).register(sub)
    return parser


def _join_negative_values(argv: Sequence[str]) -> list[str]:
    """``--joints-deg -96.4,-29.3,...`` → ``--joints-deg=-96.4,...``.

    argparse takes a value that starts with ``-`` and is not a plain number for an option; no cctmill
    option starts with a digit, so a ``-`` followed by a digit or ``.`` is always a value.
    """
    out: list[str] = []
    for tok in argv:
        if (out and out[-1].startswith("--") and "=" not in out[-1]
                and re.match(r"^-[0-9.]", tok)):
            out[-1] = f"{out[-1]}={tok}"
        else:
            out.append(tok)
    return out


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``cctmill`` console script."""
    parser = build_parser()
    args = parser.parse_args(_join_negative_values(sys.argv[1:] if argv is None else argv))
    try:
        return int(args.run(args))
    except CctmillError as e:
        print(f"cctmill {args.command}: error: {e}", file=sys.stderr)
        return 2
    except BrokenPipeError:
        return 0


if __name__ == "__main__":
    raise SystemExit(main())
