"""The job file's schema: one pydantic model per TOML table, and :class:`JobSI`, its numbers in SI.

Types are strict (a number in quotes is refused, not converted), every number is finite, and the
keys where a unit slip gives a value far beyond any milling job have an upper bound with its reason
(:data:`SANE_MAX`). Loading a file, the messages and the generated reference: :mod:`planner.job`.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

from models.robot import DEFAULT_ROBOT
from robot_io.krl.frames import frame_from_mm_deg

__all__ = [
    "CellSection",
    "EngagementSection",
    "ExportSection",
    "Job",
    "JobSI",
    "JobSection",
    "KinematicsSection",
    "LimitsSection",
    "ModelSection",
    "PathSection",
    "PlanSettings",
    "SANE_MAX",
    "SaneMax",
    "SpindleSection",
    "StockSection",
    "TABLES",
    "ToolSection",
]

Vec3 = Annotated[list[float], Field(min_length=3, max_length=3)]
Vec6 = Annotated[list[float], Field(min_length=6, max_length=6)]
PosFloat = Annotated[float, Field(gt=0, allow_inf_nan=False)]
NonNegFloat = Annotated[float, Field(ge=0, allow_inf_nan=False)]


@dataclass(frozen=True)
class SaneMax:
    """The largest value a key may have: anything above it is no milling value but a unit slip.

    Attributes:
        bound: the largest value accepted, in the key's unit.
        unit: that unit, as written after a number.
        why: why no real job goes above it.
        fix: what to type instead, a format string of the value typed ``v``, ``v_1e3``
            (``v / 1000``) and ``v_60`` (``v / 60``).
    """

    bound: float
    unit: str
    why: str
    fix: str


#: Upper bounds of the keys where a unit slip gives a value far beyond any milling job (micrometres
#: typed as millimetres, mm/min as mm/s, W as kW), refused with what to type (``table.key``).
SANE_MAX: dict[str, SaneMax] = {
    "limits.deflection_tol_mm": SaneMax(
        5.0, "mm", "a robot-milled wall is held to tenths of a millimetre",
        "if you meant micrometres, {v:g} µm is deflection_tol_mm = {v_1e3:g}"),
    "path.chord_tol_mm": SaneMax(
        1.0, "mm", "arcs sampled coarser than 1 mm no longer follow the part",
        "if you meant micrometres, {v:g} µm is chord_tol_mm = {v_1e3:g}"),
    "limits.rapid_mm_s": SaneMax(
        10_000.0, "mm/s", "no industrial arm moves its TCP at 10 m/s",
        "the key is in mm/s: {v:g} mm/min is rapid_mm_s = {v_60:g}"),
    "limits.path_acc_max_m_s2": SaneMax(
        100.0, "m/s²", "an arm's path accelerates at a few m/s², 100 m/s² is 10 g",
        "the key is in m/s²: {v:g} mm/s² is path_acc_max_m_s2 = {v_1e3:g}"),
    "spindle.power_max_kw": SaneMax(
        100.0, "kW", "a spindle a robot carries delivers some tens of kW",
        "the key is in kW: {v:g} W is power_max_kw = {v_1e3:g}"),
    "spindle.rpm": SaneMax(
        100_000.0, "rpm", "no milling spindle turns faster",
        "check the number (the key is in revolutions per minute)"),
}


def _upto(key: str) -> Any:
    """The field constraint of a positive finite number at most ``SANE_MAX[key].bound``."""
    return Field(gt=0, le=SANE_MAX[key].bound, allow_inf_nan=False)

class _Section(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False, strict=True)


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

    rpm: Annotated[float, _upto("spindle.rpm")] = 1000.0
    mass_kg: NonNegFloat | None = None
    com_mm: Vec3 | None = None
    power_max_kw: Annotated[float, _upto("spindle.power_max_kw")] = 10.0


class LimitsSection(_Section):
    """``[limits]``: what no section may exceed."""

    force_max_n: PosFloat = 300.0
    deflection_tol_mm: Annotated[float, _upto("limits.deflection_tol_mm")] = 0.1
    feed_min_mm_s: PosFloat = 0.1
    feed_max_mm_s: PosFloat = 50.0
    feed_change_max_mm_s: PosFloat | None = None
    margin_min_n_per_m: NonNegFloat = 0.0
    section_length_min_mm: PosFloat = 10.0
    path_acc_max_m_s2: Annotated[float, _upto("limits.path_acc_max_m_s2")] = 1.0
    path_jerk_max_m_s3: PosFloat = 10.0
    rapid_mm_s: Annotated[float, _upto("limits.rapid_mm_s")] = 250.0
    cam_feed_scale_max: PosFloat = 1.0
    deflection_model_uncertainty: Annotated[float, Field(ge=0.0, le=1.0, allow_inf_nan=False)] = 0.3

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
    chatter_probability_max: Annotated[float, Field(gt=0.0, lt=1.0, allow_inf_nan=False)] | None = None
    limit_confidence: Annotated[float, Field(ge=0.5, lt=1.0, allow_inf_nan=False)] = 0.95


class CalibrationSection(_Section):
    """``[calibration]``: an overlay from ``cctmill calibrate`` and the values it fitted
    (docs/calibration.md); the coefficients are SI (N/m², N/m)."""

    overlay: str | None = None
    k_tc: PosFloat | None = None
    k_rc: float | None = None
    k_ac: float | None = None
    k_te: float | None = None
    k_re: float | None = None
    k_ae: float | None = None
    boundary_criterion: Literal["eigen", "floquet", "gamma_window"] | None = None
    boundary_features: list[str] = []
    boundary_mean: Annotated[list[float], Field(min_length=3, max_length=3)] | None = None
    boundary_scale: Annotated[list[float], Field(min_length=3, max_length=3)] | None = None
    boundary_coef: Annotated[list[float], Field(min_length=3, max_length=3)] | None = None
    boundary_intercept: float | None = None
    coefficient_covariance: Annotated[list[float], Field(min_length=36, max_length=36)] | None = None
    joint_stiffness_scale_std: NonNegFloat | None = None
    records: list[str] = []
    fitted_utc: str | None = None
    report: str | None = None

    @model_validator(mode="after")
    def _all_six(self) -> CalibrationSection:
        given = [k for k in ("k_tc", "k_rc", "k_ac", "k_te", "k_re", "k_ae")
                 if getattr(self, k) is not None]
        if given and len(given) != 6:
            raise ValueError("give all six cutting coefficients k_tc .. k_ae or none")
        if self.coefficient_covariance is not None:
            cov = np.asarray(self.coefficient_covariance, float).reshape(6, 6)
            if not given:
                raise ValueError("coefficient_covariance needs the six coefficients k_tc .. k_ae")
            if not np.all(np.isfinite(cov)) or np.any(np.diag(cov) < 0.0):
                raise ValueError("coefficient_covariance must be finite with a non-negative "
                                 "diagonal (a covariance matrix, row by row)")
        return self

    def coefficients(self) -> np.ndarray | None:
        """The fitted coefficients [k_tc .. k_ae] (6,), or None."""
        if self.k_tc is None:
            return None
        return np.array([self.k_tc, self.k_rc, self.k_ac, self.k_te, self.k_re, self.k_ae], float)


class PlanSettings(_Section):
    """``[plan]``: how ``cctmill plan`` chooses sections and feeds."""

    method: Literal["optimize", "sections", "thesis", "constant"] = "optimize"
    safety_factor: Annotated[float, Field(ge=1.0, allow_inf_nan=False)] = 1.1
    thesis_section_length_mm: PosFloat = 100.0
    section_change_cost_s: NonNegFloat = 0.02
    scheduler: str | None = None


class PathSection(_Section):
    """``[path]``: sampling of the toolpath."""

    chord_tol_mm: Annotated[float, _upto("path.chord_tol_mm")] = 0.01
    step_max_mm: PosFloat = 2.0


class ExportSection(_Section):
    """``[export]``: how the plan will be exported (what the planner must hold for it)."""

    compensate_deflection: bool = False


class KinematicsSection(_Section):
    """``[kinematics]``: inverse kinematics along the path."""

    seed_joints_deg: Vec6 | None = None
    tool_rotation: Literal["free", "fixed"] = "free"
    tool_rotation_deg: float = 0.0
    choose_for_stiffness: bool = False
    posture: Literal["first_sample", "path"] = "first_sample"
    posture_rate_deg_per_mm: Annotated[float, Field(gt=0.0, le=10.0, allow_inf_nan=False)] = 1.0


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
    export: ExportSection = ExportSection()
    calibration: CalibrationSection = CalibrationSection()
    folder: str = "."

    def material_coefficients(self) -> np.ndarray:
        """Cutting coefficients [k_tc .. k_ae] (6,), SI: the calibration's, else the material's."""
        fitted = self.calibration.coefficients()
        if fitted is not None:
            return fitted
        from models.tooling import load_material

        return load_material(self.material).coefficients()

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



#: The TOML tables by name (``stock``: ``[engagement.stock]``) → their models.
TABLES: dict[str, type[BaseModel]] = {
    "job": JobSection, "cell": CellSection, "tool": ToolSection, "spindle": SpindleSection,
    "limits": LimitsSection, "engagement": EngagementSection, "model": ModelSection,
    "plan": PlanSettings, "path": PathSection, "kinematics": KinematicsSection,
    "stock": StockSection, "calibration": CalibrationSection, "export": ExportSection}
