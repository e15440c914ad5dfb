"""The job file: one TOML document describing the cell, the tool, the cut and the limits.

Validated with pydantic; every problem is reported in the user's terms — the table and key, what is
wrong, how to fix it — and all problems at once. Units are part of the key names
(``feed_max_mm_s``, ``tcp_mm``, ``base_abc_deg``); a key with a different unit suffix is an unknown
key and the message suggests the known one. Everything is converted to SI once, by
:meth:`Job.to_si` (and :meth:`planner.limits.Limits.from_job` for the limits), never inside the
models.

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
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from models.errors import CctmillError
from models.robot import DEFAULT_ROBOT
from robot_io.krl.frames import frame_from_mm_deg

__all__ = [
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
    "SpindleSection",
    "StockSection",
    "ToolSection",
    "load_job",
    "parse_job",
    "reference_markdown",
]

Vec3 = Annotated[list[float], Field(min_length=3, max_length=3)]
Vec6 = Annotated[list[float], Field(min_length=6, max_length=6)]
PosFloat = Annotated[float, Field(gt=0, allow_inf_nan=False)]
NonNegFloat = Annotated[float, Field(ge=0, allow_inf_nan=False)]


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


class _Section(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class JobSection(_Section):
    """``[job]``: name and toolpath files."""

    name: str = "job"
    toolpath: list[str] = Field(min_length=1)
    strict: bool = True
    format: Literal["gcode", "apt", "krl"] | None = None
    units: Literal["mm", "inch"] | None = None
    rotary: Literal["none", "xyzac-trunnion", "xyzbc-trunnion"] | None = None
    apply_frames: bool = False
    circle_direction: Literal["auto", "ccw", "cw"] | None = None
    initial_position_mm: Vec3 | None = None
    arc_radius_tol_mm: PosFloat | None = None

    def reader_options(self) -> dict[str, Any]:
        """The reader options this table sets (SI), for every format; ``planner.prepare`` hands
        each file the ones its format has."""
        out: dict[str, Any] = {}
        if self.units is not None:
            out["default_units"] = self.units
        if self.rotary is not None:
            out["rotary"] = self.rotary
        if self.apply_frames:
            out["apply_frames"] = True
        if self.circle_direction is not None:
            out["circle_direction"] = self.circle_direction
        if self.initial_position_mm is not None:
            out["initial_position"] = tuple(v * 1e-3 for v in self.initial_position_mm)
        if self.arc_radius_tol_mm is not None:
            out["arc_radius_tol"] = self.arc_radius_tol_mm * 1e-3
        return out

    @model_validator(mode="before")
    @classmethod
    def _one_path(cls, data: Any) -> Any:
        if isinstance(data, dict) and isinstance(data.get("toolpath"), str):
            data = {**data, "toolpath": [data["toolpath"]]}
        return data


class CellSection(_Section):
    """``[cell]``: robot, ``$BASE`` (workpiece frame in the robot base) and ``$TOOL`` (TCP)."""

    robot: str = DEFAULT_ROBOT
    base_mm: Vec3 = [0.0, 0.0, 0.0]
    base_abc_deg: Vec3 = [0.0, 0.0, 0.0]
    tcp_mm: Vec3 = [0.0, 0.0, 0.0]
    tcp_abc_deg: Vec3 = [0.0, 0.0, 0.0]
    joint_stiffness_scale: PosFloat = 1.0


class ToolSection(_Section):
    """``[tool]``: a tool data file, optionally overridden."""

    name: str = "em25_2f"
    diameter_mm: PosFloat | None = None
    flutes: Annotated[int, Field(ge=1, le=12)] | None = None


class SpindleSection(_Section):
    """``[spindle]``: speed, mass and power."""

    rpm: PosFloat = 1000.0
    mass_kg: NonNegFloat | None = None
    com_mm: Vec3 | None = None
    power_max_kw: PosFloat = 10.0


class LimitsSection(_Section):
    """``[limits]``: what no section may exceed."""

    force_max_n: PosFloat = 300.0
    deflection_tol_mm: PosFloat = 0.1
    feed_min_mm_s: PosFloat = 0.1
    feed_max_mm_s: PosFloat = 50.0
    feed_change_max_mm_s: PosFloat | None = None
    margin_min_n_per_m: NonNegFloat = 0.0
    section_length_min_mm: PosFloat = 10.0
    path_acc_max_m_s2: PosFloat = 1.0
    path_jerk_max_m_s3: PosFloat = 10.0
    rapid_mm_s: PosFloat = 250.0
    cam_feed_scale_max: PosFloat = 1.0

    @model_validator(mode="after")
    def _feed_range(self) -> LimitsSection:
        if self.feed_min_mm_s >= self.feed_max_mm_s:
            raise ValueError("feed_min_mm_s must be below feed_max_mm_s")
        if self.feed_max_mm_s > self.rapid_mm_s:
            raise ValueError(
                f"feed_max_mm_s {self.feed_max_mm_s:g} is above rapid_mm_s {self.rapid_mm_s:g}: "
                f"the keys are in mm/s ({self.feed_max_mm_s:g} mm/min would be "
                f"{self.feed_max_mm_s / 60:g} mm/s)")
        return self


class StockSection(_Section):
    """``[engagement.stock]``: a prismatic stock in the workpiece frame, and the Z-map's cell."""

    box_mm: Annotated[list[float], Field(min_length=4, max_length=4)] | None = None
    outline_mm: list[Annotated[list[float], Field(min_length=2, max_length=2)]] | None = None
    z_bottom_mm: float
    z_top_mm: float
    zmap_cell_mm: PosFloat | None = None

    def zmap_cell(self) -> float | None:
        """The Z-map cell size [m], or None for the default (:func:`planner.zmap.default_cell`)."""
        return None if self.zmap_cell_mm is None else self.zmap_cell_mm * 1e-3

    @model_validator(mode="after")
    def _shape(self) -> StockSection:
        if (self.box_mm is None) == (self.outline_mm is None):
            raise ValueError("give exactly one of box_mm = [xmin, ymin, xmax, ymax] or outline_mm")
        if self.box_mm is not None and not (self.box_mm[0] < self.box_mm[2]
                                            and self.box_mm[1] < self.box_mm[3]):
            raise ValueError("box_mm must be [xmin, ymin, xmax, ymax] with min < max")
        if self.outline_mm is not None and len(self.outline_mm) < 3:
            raise ValueError("outline_mm needs at least 3 points")
        if not self.z_top_mm > self.z_bottom_mm:
            raise ValueError("z_top_mm must be above z_bottom_mm")
        return self


class EngagementSection(_Section):
    """``[engagement]``: per operation (``fixed``) or from a stock model: ``zmap`` (3-axis height
    map, the default when an ``[engagement.stock]`` table is given) or ``stock`` (2.5-D levels)."""

    source: Literal["fixed", "stock", "zmap"] | None = None
    ae_mm: PosFloat | None = None
    ap_mm: PosFloat | None = None
    milling: Literal["up", "down", "slot"] = "down"
    stock: StockSection | None = None

    @model_validator(mode="before")
    @classmethod
    def _default_source(cls, data: Any) -> Any:
        if isinstance(data, dict) and data.get("source") is None:
            data = {**data, "source": "fixed" if data.get("stock") is None else "zmap"}
        return data

    @model_validator(mode="after")
    def _complete(self) -> EngagementSection:
        if self.source == "fixed" and (self.ap_mm is None or
                                       (self.ae_mm is None and self.milling != "slot")):
            raise ValueError("fixed engagement needs ae_mm and ap_mm (slot: ap_mm only)")
        if self.source in ("stock", "zmap") and self.stock is None:
            raise ValueError(f"source = {self.source!r} needs an [engagement.stock] table")
        return self


class ModelSection(_Section):
    """``[model]``: the physics choices and calibration knobs (docs/model.md §5)."""

    process_model: Literal["thesis", "oriented"] = "thesis"
    mass_model: Literal["isotropic", "robot"] = "isotropic"
    chatter_criterion: Literal["eigen", "floquet", "gamma_window"] = "eigen"
    gamma_window_deg: Annotated[list[float], Field(min_length=2, max_length=2)] = [-90.0, 90.0]
    process_gain: PosFloat = 1.0
    cct: bool = True


class PlanSettings(_Section):
    """``[plan]``: how ``cctmill plan`` chooses sections and feeds."""

    method: Literal["optimize", "thesis", "constant"] = "optimize"
    safety_factor: Annotated[float, Field(ge=1.0, allow_inf_nan=False)] = 1.1
    thesis_section_length_mm: PosFloat = 100.0
    section_change_cost_s: NonNegFloat = 0.02


class PathSection(_Section):
    """``[path]``: sampling of the toolpath."""

    chord_tol_mm: PosFloat = 0.01
    step_max_mm: PosFloat = 2.0


class KinematicsSection(_Section):
    """``[kinematics]``: inverse kinematics along the path."""

    seed_joints_deg: Vec6 | None = None
    tool_rotation: Literal["free", "fixed"] = "free"
    tool_rotation_deg: float = 0.0
    choose_for_stiffness: bool = False


class Job(_Section):
    """A whole job file, validated. ``folder`` is where relative paths resolve."""

    job: JobSection
    cell: CellSection = CellSection()
    tool: ToolSection = ToolSection()
    material: Annotated[str, Field(min_length=1)] = "al6061"
    spindle: SpindleSection = SpindleSection()
    limits: LimitsSection = LimitsSection()
    engagement: EngagementSection
    model: ModelSection = ModelSection()
    plan: PlanSettings = PlanSettings()
    path: PathSection = PathSection()
    kinematics: KinematicsSection = KinematicsSection()
    folder: str = "."

    def toolpath_files(self) -> list[Path]:
        """Absolute toolpath paths (relative ones resolve against the job file's folder)."""
        return [(Path(self.folder) / p).resolve() for p in self.job.toolpath]

    def base_frame(self) -> np.ndarray:
        """``$BASE`` as a 4×4 homogeneous transform (workpiece → robot base), SI."""
        return frame_from_mm_deg(self.cell.base_mm, self.cell.base_abc_deg)

    def tool_frame(self) -> np.ndarray:
        """``$TOOL`` as a 4×4 homogeneous transform (TCP → flange), SI."""
        return frame_from_mm_deg(self.cell.tcp_mm, self.cell.tcp_abc_deg)

    def to_si(self) -> JobSI:
        """The job's numbers in SI: the one place its mm, degrees and rpm are converted."""
        from planner.limits import Limits

        cell, kin, eng, spindle = self.cell, self.kinematics, self.engagement, self.spindle
        st = eng.stock
        return JobSI(
            base=self.base_frame(), tool=self.tool_frame(),
            base_xyz=tuple(v * 1e-3 for v in cell.base_mm),
            base_abc=tuple(float(np.radians(v)) for v in cell.base_abc_deg),
            tool_xyz=tuple(v * 1e-3 for v in cell.tcp_mm),
            tool_abc=tuple(float(np.radians(v)) for v in cell.tcp_abc_deg),
            tcp=np.asarray(cell.tcp_mm) * 1e-3,
            chord_tol=self.path.chord_tol_mm * 1e-3, step_max=self.path.step_max_mm * 1e-3,
            seed_joints=(np.radians(kin.seed_joints_deg) if kin.seed_joints_deg is not None
                         else None),
            tool_rotation=np.radians(kin.tool_rotation_deg),
            tool_radius=self.tool.diameter_mm * 5e-4 if self.tool.diameter_mm else None,
            a_e=None if eng.ae_mm is None else eng.ae_mm * 1e-3,
            a_p=None if eng.ap_mm is None else eng.ap_mm * 1e-3,
            stock_box=(None if st is None or st.box_mm is None
                       else tuple(v * 1e-3 for v in st.box_mm)),
            stock_outline=(None if st is None or st.outline_mm is None
                           else [(x * 1e-3, y * 1e-3) for x, y in st.outline_mm]),
            stock_z=None if st is None else (st.z_bottom_mm * 1e-3, st.z_top_mm * 1e-3),
            limits=Limits.from_job(self),
            spindle_speed=spindle.rpm * 2.0 * np.pi / 60.0,
            spindle_com=None if spindle.com_mm is None else np.asarray(spindle.com_mm) * 1e-3,
            gamma_window=tuple(np.radians(self.model.gamma_window_deg)),
            thesis_section_length=self.plan.thesis_section_length_mm * 1e-3)


@dataclass(frozen=True)
class JobSI:
    """A job's numbers in SI (:meth:`Job.to_si`); names as in the job without their units.

    Attributes:
        base, tool: ``$BASE`` and ``$TOOL`` as 4×4 transforms [m]; base_xyz/base_abc and
            tool_xyz/tool_abc the same as origin [m] (3,) and KUKA A, B, C [rad] (3,).
        tcp: the TCP in the flange frame [m], (3,).
        chord_tol, step_max: path sampling [m].
        seed_joints: IK seed [rad], (6,) or None; tool_rotation: the fixed rotation about the
            tool axis [rad].
        tool_radius: the job's tool radius [m] (None: the tool data's).
        a_e, a_p: fixed engagement [m] (None where not given).
        stock_box (x0, y0, x1, y1) [m] or stock_outline [(x, y)] [m], stock_z (bottom, top) [m].
        limits: the limits (:class:`planner.limits.Limits`).
        spindle_speed [rad/s]; spindle_com [m] (3,) or None; gamma_window (lo, hi) [rad].
        thesis_section_length: the thesis method's initial section length [m].
    """

    base: np.ndarray
    tool: np.ndarray
    base_xyz: tuple[float, ...]
    base_abc: tuple[float, ...]
    tool_xyz: tuple[float, ...]
    tool_abc: tuple[float, ...]
    tcp: np.ndarray
    chord_tol: float
    step_max: float
    seed_joints: np.ndarray | None
    tool_rotation: float
    tool_radius: float | None
    a_e: float | None
    a_p: float | None
    stock_box: tuple[float, ...] | None
    stock_outline: list[tuple[float, float]] | None
    stock_z: tuple[float, float] | None
    limits: Any
    spindle_speed: float
    spindle_com: np.ndarray | None
    gamma_window: tuple[float, ...]
    thesis_section_length: float


#: One line per key for the generated reference (a test checks every schema field has one).
KEY_DOCS: dict[str, str] = {
    "material": "material data file name (shipped: al6061)",
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
    "cell.robot": "robot data name (URDF + TOML in models/data/robots)",
    "cell.base_mm": "$BASE origin: the workpiece frame in the robot base [mm]",
    "cell.base_abc_deg": "$BASE orientation, KUKA A, B, C [deg] (R = Rz(A) Ry(B) Rx(C))",
    "cell.tcp_mm": "$TOOL origin: the tool tip in the flange frame [mm]",
    "cell.tcp_abc_deg": "$TOOL orientation [deg]; the tool axis is the TCP's +x",
    "cell.joint_stiffness_scale": "multiplies the robot's joint stiffness (calibration)",
    "tool.name": "tool data file name (shipped: em25_2f)",
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
    "path.chord_tol_mm": "largest arc chord error [mm]",
    "path.step_max_mm": "largest distance between path samples [mm]",
    "kinematics.seed_joints_deg": "joint angles to start the first IK solve from [deg]",
    "kinematics.tool_rotation": "free: the rotation about the tool axis is chosen (continuity, "
                                "limits); fixed: held at tool_rotation_deg",
    "kinematics.tool_rotation_deg": "rotation about the tool axis when fixed [deg]",
    "kinematics.choose_for_stiffness": "pick the free rotation at the first sample for stiffness",
}


def reference_markdown() -> str:
    """The job file reference (one table per TOML table), generated from the schema."""
    out = []
    tables = [("(top level)", None, {"material": Job.model_fields["material"]})]
    for name in ("job", "cell", "tool", "spindle", "limits", "engagement", "stock", "model",
                 "plan", "path", "kinematics"):
        model = _MODELS[name]
        tables.append(("[engagement.stock]" if name == "stock" else f"[{name}]", name,
                       model.model_fields))
    for title, prefix, fields in tables:
        out += [f"**{title}**", "", "| key | default | meaning |", "|---|---|---|"]
        for key, info in fields.items():
            doc = KEY_DOCS[f"{prefix}.{key}" if prefix else key]
            default = "required" if info.is_required() else f"`{json.dumps(info.default)}`"
            if info.default is None:
                default = "—"
            out.append(f"| `{key}` | {default} | {doc} |")
        out.append("")
    return "\n".join(out).rstrip() + "\n"


_MODELS = {"job": JobSection, "cell": CellSection, "tool": ToolSection,
           "spindle": SpindleSection, "limits": LimitsSection, "engagement": EngagementSection,
           "model": ModelSection, "plan": PlanSettings, "path": PathSection, "kinematics": KinematicsSection,
           "stock": StockSection}


def _known_keys(loc: tuple) -> list[str]:
    """Keys allowed at the table that contains ``loc[-1]``."""
    if len(loc) == 1:
        return [k for k in Job.model_fields if k != "folder"]
    table = str(loc[-2])
    model = _MODELS.get(table)
    return list(model.model_fields) if model else []


def _describe(err: dict) -> str:
    loc = tuple(err["loc"])
    where = ".".join(str(p) for p in loc[:-1])
    key = str(loc[-1]) if loc else ""
    prefix = f"[{where}] {key}" if where else key
    kind = err["type"]
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
    if kind.startswith(("greater_than", "less_than")):
        return f"{prefix}: {err['msg'].lower()} (got {err.get('input')!r})"
    if kind == "value_error":
        return f"{'[' + '.'.join(str(p) for p in loc) + '] ' if loc else ''}" \
               f"{err['msg'].removeprefix('Value error, ')}"
    return f"{prefix}: {err['msg']} (got {err.get('input')!r})"


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
    """Validate a parsed TOML document; raise :class:`JobError` listing every problem."""
    if not isinstance(doc, dict):
        raise JobError(file, [f"not a job document (a TOML table), got {type(doc).__name__}"])
    if _depth(doc, MAX_DEPTH) > MAX_DEPTH:
        raise JobError(file, [f"tables and arrays nest more than {MAX_DEPTH} deep; a job file "
                              "needs at most 5 (see docs/job.md)"])
    try:
        return Job.model_validate({**doc, "folder": str(folder)})
    except ValidationError as e:
        raise JobError(file, [_describe(err) for err in e.errors()]) from None


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
