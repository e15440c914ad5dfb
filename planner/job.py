"""The job file: one TOML document describing the cell, the tool, the cut and the limits.

Validated with pydantic; every problem is reported in the user's terms — the table and key, what is
wrong, how to fix it — and all problems at once. Units are part of the key names
(``feed_max_mm_s``, ``tcp_mm``, ``base_abc_deg``); a key with a different unit suffix is an unknown
key and the message suggests the known one. Types are strict: a number in quotes (``rpm = "4000"``)
is refused, not converted; a length or rate far beyond any milling value (:data:`SANE_MAX`) is a
unit slip and refused with what to type; the seed joints are checked against the robot's limits.
Everything is converted to SI once, by :meth:`Job.to_si` (and
:meth:`planner.limits.Limits.from_job` for the limits), never inside the models.
The tables' models live in :mod:`planner.job_schema` (handed on here); this module reads the
file, says each problem in the user's terms and generates the key reference.

Example (see ``planner/data/demo/demo_job.toml`` for a complete one)::

    [job]
    name = "wall"
    toolpath = ["wall.nc"]          # relative to this file

    [cell]
    robot = "kr210_r2700_extra"
    base_mm = [1500.0, -300.0, 400.0]   # $BASE: workpiece frame in the robot base
    base_abc_deg = [0.0, 0.0, 0.0]
    tcp_mm = [300.0, 0.0, 0.0]          # $TOOL: TCP in the flange frame
    tcp_abc_deg = [0.0, 0.0, 0.0]

    [tool]
    name = "em25_2f"

    [limits]
    force_max_n = 300.0
"""

from __future__ import annotations

import difflib
import json
import tomllib
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import ValidationError

from models.errors import CctmillError, UnknownDataError
from models.robot import load_robot
from planner.job_schema import (
    SANE_MAX,
    TABLES,
    CalibrationSection,
    CellSection,
    EngagementSection,
    Job,
    JobSection,
    JobSI,
    KinematicsSection,
    LimitsSection,
    ModelSection,
    PathSection,
    PlanSettings,
    SaneMax,
    SpindleSection,
    StockSection,
    ToolSection,
)

__all__ = [
    "CalibrationSection",
    "CellSection",
    "EngagementSection",
    "Job",
    "JobError",
    "JobSI",
    "JobSection",
    "KEY_DOCS",
    "KinematicsSection",
    "LimitsSection",
    "MAX_DEPTH",
    "ModelSection",
    "PathSection",
    "PlanSettings",
    "SANE_MAX",
    "SaneMax",
    "SpindleSection",
    "StockSection",
    "ToolSection",
    "load_job",
    "parse_job",
    "reference_markdown",
]


class JobError(CctmillError):
    """A job file is not valid.

    Attributes:
        file: the job file.
        problems: one line per problem, ``[table] key: what is wrong; how to fix``.
    """

    def __init__(self, file: str, problems: list[str]) -> None:
        self.file = file
        self.problems = problems
        if len(problems) == 1:
            super().__init__(f"{file}: {problems[0]}")
        else:
            super().__init__(f"{file}: {len(problems)} problems:\n  " + "\n  ".join(problems))


#: One line per key for the generated reference (a test checks every schema field has one).
KEY_DOCS: dict[str, str] = {
    "material": "material data file name (`cctmill materials` lists the shipped ones)",
    "job.name": "job name, used for output names",
    "job.toolpath": "toolpath file(s), G-code / APT-CL / KRL, relative to the job file; read in order",
    "job.strict": "stop at the first problem in a toolpath (false: collect warnings and go on)",
    "job.format": "toolpath format (gcode, apt, krl); default: from the extension, else the content",
    "job.units": "units of a toolpath that declares none (mm or inch; G20/G21, UNITS/ win)",
    "job.rotary": "G-code A/B/C kinematics: none, xyzac-trunnion or xyzbc-trunnion (table-table)",
    "job.apply_frames": "APT/CL: map points through the CSYS/MSYS setup frame (CL data in local "
                        "setup coordinates)",
    "job.circle_direction": "APT/CL: how a CIRCLE turns about its i,j,k (auto: NX's 11-field form "
                            "clockwise, SolidWorks CAM's 6-field form counter-clockwise)",
    "job.initial_position_mm": "G-code: the tool position before the first move [mm]",
    "job.arc_radius_tol_mm": "G-code and APT/CL: allowed start/end radius mismatch of an arc [mm] "
                             "(default: the larger of 0.002 mm and 0.1 % of the radius)",
    "cell.robot": "robot data name (URDF + TOML in models/data/robots; `cctmill robots`)",
    "cell.base_mm": "$BASE origin: the workpiece frame in the robot base [mm]",
    "cell.base_abc_deg": "$BASE orientation, KUKA A, B, C [deg] (R = Rz(A) Ry(B) Rx(C))",
    "cell.tcp_mm": "$TOOL origin: the tool tip in the flange frame [mm]",
    "cell.tcp_abc_deg": "$TOOL orientation [deg]; the tool axis is the TCP's +x",
    "cell.joint_stiffness_scale": "multiplies the robot's joint stiffness (calibration)",
    "tool.name": "tool data file name (`cctmill tools` lists the library)",
    "tool.diameter_mm": "override the tool diameter [mm]",
    "tool.flutes": "override the number of flutes",
    "spindle.rpm": "spindle speed [rpm]",
    "spindle.mass_kg": "spindle point mass [kg] (default: robot data)",
    "spindle.com_mm": "spindle centre of mass in the flange frame [mm] (default: robot data)",
    "spindle.power_max_kw": "spindle power limit [kW]",
    "limits.force_max_n": "resultant cutting force limit [N] (thesis: 300 N for the KR210)",
    "limits.deflection_tol_mm": "static deflection tolerance at the TCP [mm]",
    "limits.feed_min_mm_s": "lowest feed a section may get [mm/s]",
    "limits.feed_max_mm_s": "highest feed a section may get [mm/s]",
    "limits.feed_change_max_mm_s": "largest feed change between neighbouring sections [mm/s]",
    "limits.margin_min_n_per_m": "required chatter stability margin [N/m]",
    "limits.section_length_min_mm": "shortest section the planner may make [mm]",
    "limits.path_acc_max_m_s2": "path acceleration of feed transitions [m/s²] (ruckig)",
    "limits.path_jerk_max_m_s3": "path jerk of feed transitions [m/s³] (ruckig)",
    "limits.rapid_mm_s": "path speed bound on rapid (G0) moves [mm/s]; the joints limit it further",
    "limits.cam_feed_scale_max": "no cut runs faster than its programmed feed times this (1: only "
                                 "slow down where the process needs it; larger: raise feeds up "
                                 "to feed_max_mm_s)",
    "engagement.source": "fixed (per operation, below), zmap (3-axis height map of the stock: helices, "
                         "ramps, pockets) or stock (2.5-D levels); default zmap with an "
                         "[engagement.stock] table, else fixed",
    "engagement.ae_mm": "radial depth of cut [mm] (fixed)",
    "engagement.ap_mm": "axial depth of cut [mm] (fixed)",
    "engagement.milling": "up, down or slot (fixed)",
    "engagement.stock": "the stock table (source = zmap or stock)",
    "stock.box_mm": "stock outline as [xmin, ymin, xmax, ymax] in the workpiece frame [mm]",
    "stock.outline_mm": "stock outline as a polygon [[x, y], ...] [mm]",
    "stock.z_bottom_mm": "stock bottom [mm]",
    "stock.z_top_mm": "stock top [mm]",
    "stock.zmap_cell_mm": "Z-map cell size [mm] (source = zmap); default R/10 of the tool: a_e and "
                          "a_p errors of about a cell where several cuts meet",
    "model.process_model": "thesis (rank one, default) or oriented (Tlusty)",
    "model.mass_model": "isotropic (stiffness only) or robot (CRBA + spindle)",
    "model.chatter_criterion": "eigen, floquet (exact for the time-periodic cut, docs/model.md §6) or "
                               "gamma_window",
    "model.gamma_window_deg": "calibrated [γ_lo, γ_hi] for gamma_window [deg]",
    "model.process_gain": "multiplies the process stiffness K_p (calibration)",
    "model.cct": "include the force-dependent CCT stiffness term",
    "plan.method": "optimize (CasADi + IPOPT), thesis (docs/model.md §8 section algorithm) or constant",
    "plan.safety_factor": "thesis method: f_real = f_max / safety_factor",
    "plan.thesis_section_length_mm": "thesis method: the initial section length L_s [mm]",
    "plan.section_change_cost_s": "optimize: time-equivalent cost of a feed change of feed_max "
                                  "[s] (fewer, longer sections)",
    "plan.scheduler": "where placement studies and batch plans run: none (serial), local (a Dask "
                      "cluster of this machine's cores) or tcp://HOST:PORT; --scheduler and "
                      "$CCTMILL_SCHEDULER win (docs/placement.md)",
    "path.chord_tol_mm": "largest arc chord error [mm]",
    "path.step_max_mm": "largest distance between path samples [mm]",
    "kinematics.seed_joints_deg": "joint angles to start the first IK solve from [deg], within the "
                                  "robot's joint limits",
    "kinematics.tool_rotation": "free: the rotation about the tool axis is chosen (continuity, "
                                "limits); fixed: held at tool_rotation_deg",
    "kinematics.tool_rotation_deg": "rotation about the tool axis when fixed [deg]",
    "kinematics.choose_for_stiffness": "pick the free rotation at the first sample for stiffness",
    "model.chatter_probability_max": "largest P(chatter) a section may have by the calibrated "
                                     "boundary (docs/calibration.md); none: not required",
    "model.limit_confidence": "probability with which the force limit and the deflection "
                              "tolerance hold under the calibration's parameter uncertainty "
                              "(docs/calibration.md); 0.5: plan on the fitted values",
    "calibration.coefficient_covariance": "covariance of the fitted k_tc .. k_ae, SI, 36 values "
                                          "row by row",
    "calibration.joint_stiffness_scale_std": "relative standard error of the fitted joint "
                                             "stiffness scale [-]",
    "calibration.overlay": "overlay file from cctmill calibrate, relative to this file; its "
                           "[cell], [model], [calibration] keys replace these",
    "calibration.k_tc": "fitted tangential cutting coefficient [N/m²] (replaces the material's)",
    "calibration.k_rc": "fitted radial cutting coefficient [N/m²]",
    "calibration.k_ac": "fitted axial cutting coefficient [N/m²]",
    "calibration.k_te": "fitted tangential edge coefficient [N/m]",
    "calibration.k_re": "fitted radial edge coefficient [N/m]",
    "calibration.k_ae": "fitted axial edge coefficient [N/m]",
    "calibration.boundary_criterion": "the criterion whose margin the boundary was fitted on",
    "calibration.boundary_features": "the boundary's features: margin, ap_mm, rpm",
    "calibration.boundary_mean": "feature means of the boundary's standardisation",
    "calibration.boundary_scale": "feature standard deviations of the boundary's standardisation",
    "calibration.boundary_coef": "logistic coefficients of the standardised features",
    "calibration.boundary_intercept": "logistic intercept: logit P(chatter) = intercept + coef·x̃",
    "calibration.records": "the cut record files the calibration used",
    "calibration.fitted_utc": "when the calibration was made (UTC)",
    "calibration.report": "the fit-quality report (JSON) written beside the overlay",
    "limits.deflection_model_uncertainty": "share of the predicted deflection the model may get "
                                           "wrong [-]; with [export] compensate_deflection the "
                                           "tolerance holds this share of ‖δ‖ plus the change of "
                                           "δ along each LIN (docs/posture.md)",
    "export.compensate_deflection": "the KRL export will move the path by -δ (export "
                                    "--compensate-deflection): plan for what compensation leaves",
    "kinematics.posture": "first_sample: the free rotation is chosen at the first sample only; "
                          "path: along the whole path for the feed ceilings (docs/posture.md)",
    "kinematics.posture_rate_deg_per_mm": "largest change of the rotation about the tool axis "
                                          "per mm of path, posture = \"path\" [deg/mm]",
}


def reference_markdown() -> str:
    """The job file reference (one table per TOML table), generated from the schema."""
    out = []
    tables = [("(top level)", None, {"material": Job.model_fields["material"]})]
    for name in ("job", "cell", "tool", "spindle", "limits", "engagement", "stock", "model",
                 "plan", "path", "kinematics", "calibration", "export"):
        model = TABLES[name]
        tables.append(("[engagement.stock]" if name == "stock" else f"[{name}]", name,
                       model.model_fields))
    for title, prefix, fields in tables:
        out += [f"**{title}**", "", "| key | default | meaning |", "|---|---|---|"]
        for key, info in fields.items():
            doc = KEY_DOCS[f"{prefix}.{key}" if prefix else key]
            sane = SANE_MAX.get(f"{prefix}.{key}")
            if sane is not None:
                doc += f"; at most {sane.bound:g} {sane.unit} ({sane.why})"
            default = "required" if info.is_required() else f"`{json.dumps(info.default)}`"
            if info.default is None:
                default = "—"
            out.append(f"| `{key}` | {default} | {doc} |")
        out.append("")
    return "\n".join(out).rstrip() + "\n"


def _known_keys(loc: tuple) -> list[str]:
    """Keys allowed at the table that contains ``loc[-1]``."""
    if len(loc) == 1:
        return [k for k in Job.model_fields if k != "folder"]
    table = str(loc[-2])
    model = TABLES.get(table)
    return list(model.model_fields) if model else []


#: What a value of each type error should have been, in TOML's words.
_EXPECTED = {"float_type": "a number", "int_type": "a whole number", "bool_type": "true or false",
             "string_type": "a string in quotes", "list_type": "an array [...]",
             "model_type": "a table", "model_attributes_type": "a table", "dict_type": "a table"}


def _toml_value(v: Any) -> str:
    """A parsed value as the user wrote it (strings quoted, booleans lower case, tables and arrays
    by kind: their content can be long)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return f"the string {json.dumps(v[:40] + ('…' if len(v) > 40 else ''), ensure_ascii=False)}"
    if isinstance(v, dict):
        return "a table"
    if isinstance(v, list):
        return "an array"
    return repr(v)


def _unquoted(kind: str, v: Any) -> bool:
    """``v`` is a string that would be a valid number or boolean without its quotes."""
    if not isinstance(v, str) or kind not in ("float_type", "int_type", "bool_type"):
        return False
    t = v.strip()
    if kind == "bool_type":
        return t in ("true", "false")
    try:
        x = float(t)
    except ValueError:
        return False
    return np.isfinite(x) and (kind == "float_type" or x == int(x))


def _describe(err: dict) -> str:
    loc = tuple(err["loc"])
    names = [i for i, p in enumerate(loc) if isinstance(p, str)]
    last = names[-1] if names else -1
    where = ".".join(str(p) for p in loc[:last]) if last > 0 else ""
    key = (str(loc[last]) if last >= 0 else "") + "".join(f"[{p}]" for p in loc[last + 1:])
    prefix = f"[{where}] {key}" if where else key
    kind = err["type"]
    v = err.get("input")
    if kind == "extra_forbidden":
        known = _known_keys(loc)
        stem = key.rsplit("_", 2)[0] if "_" in key else key
        close = difflib.get_close_matches(key, known, n=1, cutoff=0.5) or [
            k for k in known if k.startswith(stem)][:1]
        units = " (units are part of key names)" if close and "_" in key else ""
        hint = f"; did you mean {close[0]!r}?{units}" if close else (
            f"; known keys: {', '.join(known)}" if known else "")
        return f"{prefix}: unknown key{hint}"
    if kind == "missing":
        return f"{prefix}: missing; add it"
    if kind in _EXPECTED:
        fix = ""
        if _unquoted(kind, v):
            fix = (f"; write it without quotes: {loc[last]} = {str(v).strip()}"
                   if last == len(loc) - 1 else "; write the number without quotes")
        return f"{prefix}: must be {_EXPECTED[kind]}, got {_toml_value(v)}{fix}"
    sane = SANE_MAX.get(".".join(str(p) for p in loc[-2:]))
    if kind == "less_than_equal" and sane is not None and isinstance(v, int | float):
        return (f"{prefix}: {v:g} {sane.unit} is above {sane.bound:g} {sane.unit}: {sane.why}; "
                + sane.fix.format(v=v, v_1e3=v / 1000, v_60=v / 60))
    if kind.startswith(("greater_than", "less_than")):
        return f"{prefix}: {err['msg'].lower()} (got {v!r})"
    if kind == "value_error":
        return f"{'[' + '.'.join(str(p) for p in loc) + '] ' if loc else ''}" \
               f"{err['msg'].removeprefix('Value error, ')}"
    return f"{prefix}: {err['msg']} (got {v!r})"


#: Deepest nesting of tables and arrays a job file may have: the schema's deepest value is 5 levels
#: down (``[engagement.stock] outline_mm = [[x, y], …]``); the bound stops a nesting bomb before
#: the validator or a message's repr recurses through it.
MAX_DEPTH = 16


def _depth(doc: Any, limit: int) -> int:
    """How deep tables and arrays nest in a parsed document, counted up to ``limit + 1``
    (iterative: a nesting bomb never meets a recursion limit here)."""
    top, stack = 0, [(doc, 1)]
    while stack and top <= limit:
        v, d = stack.pop()
        items = v.values() if isinstance(v, dict) else v if isinstance(v, list) else None
        if items is not None:
            top = max(top, d)
            stack.extend((x, d + 1) for x in items if isinstance(x, dict | list))
    return top


def parse_job(doc: dict, file: str = "<job>", folder: str | Path = ".") -> Job:
    """Validate a parsed TOML document; raise :class:`JobError` listing every problem (the robot's
    data is checked once the schema holds: its name, the seed joints against its limits)."""
    if not isinstance(doc, dict):
        raise JobError(file, [f"not a job document (a TOML table), got {type(doc).__name__}"])
    if _depth(doc, MAX_DEPTH) > MAX_DEPTH:
        raise JobError(file, [f"tables and arrays nest more than {MAX_DEPTH} deep; a job file "
                              "needs at most 5 (see docs/job.md)"])
    from planner.calibrate.overlay import merge_overlay

    doc, overlay_problems = merge_overlay(doc, folder)
    if overlay_problems:
        raise JobError(file, overlay_problems)
    try:
        job = Job.model_validate({**doc, "folder": str(folder)})
    except ValidationError as e:
        raise JobError(file, [_describe(err) for err in e.errors()]) from None
    problems = _robot_problems(job)
    if problems:
        raise JobError(file, problems)
    return job


def _robot_problems(job: Job) -> list[str]:
    """What the robot's data refuses in a valid job: an unknown robot, seed joints outside their
    limits (one line per joint)."""
    try:
        data = load_robot(job.cell.robot).data
    except UnknownDataError as e:
        return [f"[cell] robot: {e}"]
    seed = job.kinematics.seed_joints_deg
    if seed is None:
        return []
    lower, upper = np.degrees(data.lower), np.degrees(data.upper)
    return [f"[kinematics] seed_joints_deg: {name} = {q:g} deg is outside its limits "
            f"{lo:g} .. {hi:g} deg ({data.name}); give a seed within them"
            for name, q, lo, hi in zip(data.joint_names, seed, lower, upper, strict=True)
            if not lo <= q <= hi]


def load_job(path: str | Path) -> Job:
    """Read and validate a job file (UTF-8 TOML).

    Raises:
        JobError: unreadable, not UTF-8, not TOML, nested deeper than :data:`MAX_DEPTH`, or not a
            valid job (every problem listed).
    """
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except UnicodeDecodeError as e:
        line = e.object[:e.start].count(b"\n") + 1
        raise JobError(str(p), [f"not UTF-8 text (byte 0x{e.object[e.start]:02x} on line {line}); "
                                "save the job file as UTF-8"]) from None
    except OSError as e:
        raise JobError(str(p), [f"cannot read: {e.strerror or e}"]) from e
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise JobError(str(p), [f"not valid TOML: {e}"]) from e
    except RecursionError:
        raise JobError(str(p), ["not valid TOML: arrays or inline tables nest too deep to read; a "
                                "job file needs at most 5 levels"]) from None
    except ValueError as e:      # a value TOML parses but Python cannot hold (e.g. 5000 digits)
        raise JobError(str(p), [f"not valid TOML: {str(e).split(';')[0]}"]) from None
    return parse_job(doc, str(p), p.parent.resolve())
