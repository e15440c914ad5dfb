"""What the commands share: the one-line-error parser, output options, number lists, the point-model
flags."""

from __future__ import annotations

import argparse

import numpy as np

from models.analysis import MASS_MODELS, PROCESS_MODELS, Cut
from models.cutting import MILLING_MODES, available_materials
from models.errors import InputError
from models.point import CRITERIA, PointModel
from models.robot import DEFAULT_ROBOT, available_robots
from planner._atomic import OUTPUT_KINDS, check_output
from planner.point_setup import PointSetup

__all__ = [
    "Parser",
    "add_output",
    "add_point_flags",
    "add_reader_flags",
    "check_outputs",
    "feed_range",
    "floats",
    "point_setup",
    "reader_options",
]


class Parser(argparse.ArgumentParser):
    """argparse that reports a bad command line in one line (and exits 2)."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(2, f"{self.prog}: error: {message} (see --help)\n")


def add_output(p: argparse.ArgumentParser | argparse._ArgumentGroup, *names: str, kind: str,
               **kwargs) -> argparse.Action:
    """Add an option that names an output path (``kind``: ``folder``, ``file`` or ``append``, see
    :data:`planner._atomic.OUTPUT_KINDS`); :func:`check_outputs` checks every such option before
    the command runs. Every output option of a command is added this way."""
    if kind not in OUTPUT_KINDS:
        raise ValueError(f"kind must be one of {OUTPUT_KINDS}, got {kind!r}")
    action = p.add_argument(*names, **kwargs)
    outputs = tuple(p.get_default("output_paths") or ())
    p.set_defaults(output_paths=(*outputs, (action.dest, "/".join(names), kind)))
    return action


def check_outputs(args: argparse.Namespace) -> None:
    """Raise :class:`planner._atomic.OutputError` (naming the option and the path) for the first
    output option of :func:`add_output` whose path cannot be written — before any work, so a long
    plan is not lost to a typo in ``-o``."""
    for dest, flag, kind in getattr(args, "output_paths", ()):
        value = getattr(args, dest, None)
        if value:
            check_output(value, kind, flag)


def floats(text: str, n: int, flag: str) -> np.ndarray:
    try:
        values = np.array([float(v) for v in text.split(",")])
    except ValueError:
        raise InputError(flag, f"{text!r} is not {n} comma-separated numbers") from None
    if values.size != n or not np.all(np.isfinite(values)):
        raise InputError(flag, f"need {n} finite comma-separated numbers, got {text!r}")
    return values


def add_reader_flags(p: argparse.ArgumentParser) -> None:
    """The toolpath reader's options as flags (those a job sets in its ``[job]`` table)."""
    from robot_io.rotary import ROTARY_KINEMATICS

    g = p.add_argument_group("reading the toolpath")
    g.add_argument("--lenient", action="store_true",
                   help="collect problems as warnings instead of stopping at the first")
    g.add_argument("--format", choices=("gcode", "apt", "krl"),
                   help="toolpath format (default: from the extension, else the content)")
    g.add_argument("--units", choices=("mm", "inch"),
                   help="units of a program that declares none (G20/G21, UNITS/ win)")
    g.add_argument("--rotary", choices=["none", *ROTARY_KINEMATICS],
                   help="G-code A/B/C kinematics (table-table, LinuxCNC's trt order)")
    g.add_argument("--apply-frames", action="store_true",
                   help="APT/CL: map points through the CSYS/MSYS setup frame (CL data written "
                        "in local setup coordinates)")
    g.add_argument("--circle-direction", choices=("auto", "ccw", "cw"),
                   help="APT/CL: how a CIRCLE turns about its i,j,k (auto: NX's 11-field form "
                        "clockwise, SolidWorks CAM's 6-field form counter-clockwise)")
    g.add_argument("--initial-position-mm", metavar="X,Y,Z",
                   help="G-code: the tool position before the first move [mm]")
    g.add_argument("--chord-tol-mm", type=float, metavar="MM",
                   help="APT/CL: largest chord error when splines become straight moves [mm] "
                        "(default 0.01)")
    g.add_argument("--arc-radius-tol-mm", type=float, metavar="MM",
                   help="G-code and APT/CL: allowed start/end radius mismatch of an arc [mm] "
                        "(default the larger of 0.002 mm and 0.1 %% of the radius)")


def reader_options(args: argparse.Namespace) -> dict:
    """The reader keyword options (SI) of the flags of :func:`add_reader_flags` that were given."""
    out: dict = {}
    if args.units:
        out["default_units"] = args.units
    if args.rotary:
        out["rotary"] = args.rotary
    if args.apply_frames:
        out["apply_frames"] = True
    if args.circle_direction:
        out["circle_direction"] = args.circle_direction
    if args.initial_position_mm:
        out["initial_position"] = tuple(
            floats(args.initial_position_mm, 3, "--initial-position-mm") * 1e-3)
    for flag, key in (("chord_tol_mm", "chord_tol"), ("arc_radius_tol_mm", "arc_radius_tol")):
        v = getattr(args, flag)
        if v is not None:
            if not (np.isfinite(v) and v > 0):
                raise InputError("--" + flag.replace("_", "-"), f"must be a positive length in "
                                 f"mm, got {v}")
            out[key] = v * 1e-3
    return out


def add_point_flags(p: argparse.ArgumentParser, with_feed: bool) -> None:
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


#: PointSetup fields → the flags that set them (a library message names the field; the CLI's the flag).
_FLAG_OF = {"joints_deg": "--joints-deg", "feed_dir": "--feed-dir", "radial_dir": "--radial-dir",
            "ae_mm": "--ae-mm", "ap_mm": "--ap-mm", "tcp_mm": "--tcp-mm", "rpm": "--rpm",
            "flutes": "--flutes", "diameter_mm": "--diameter-mm", "gamma_window_deg": "--gamma-window-deg",
            "joint_stiffness_scale": "--joint-stiffness-scale"}


def point_setup(args: argparse.Namespace) -> tuple[PointModel, np.ndarray, Cut]:
    """The point model, joints and cut the point flags describe (:class:`PointSetup`)."""
    setup = PointSetup(
        joints_deg=tuple(floats(args.joints_deg, 6, "--joints-deg")),
        feed_dir=tuple(floats(args.feed_dir, 3, "--feed-dir")),
        radial_dir=tuple(floats(args.radial_dir, 3, "--radial-dir")),
        ap_mm=args.ap_mm, ae_mm=args.ae_mm, tcp_mm=tuple(floats(args.tcp_mm, 3, "--tcp-mm")),
        rpm=args.rpm, flutes=args.flutes, diameter_mm=args.diameter_mm, milling=args.milling,
        material=args.material, robot=args.robot, cct=not args.no_cct, mass_model=args.mass,
        process_model=args.process_model, criterion=args.criterion,
        gamma_window_deg=tuple(floats(args.gamma_window_deg, 2, "--gamma-window-deg")),
        joint_stiffness_scale=args.joint_stiffness_scale, process_gain=args.process_gain,
        spindle_kg=args.spindle_kg)
    try:
        return setup.build()
    except InputError as e:
        if e.field in _FLAG_OF:
            raise InputError(_FLAG_OF[e.field], str(e).split(": ", 1)[1]) from None
        raise


def feed_range(text: str) -> np.ndarray:
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
