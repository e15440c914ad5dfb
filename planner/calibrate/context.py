"""The cell a calibration is about: robot, TCP, tool, nominal material and model options, from a job.

Records carry pose, cut and measurements; what they do not carry (the robot, the TCP, the nominal
parameters a fit starts from and the overlay is relative to) comes from the job file.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from models.analysis import ModelParameters
from models.errors import InputError
from models.point import PointModel
from models.robot import DEFAULT_ROBOT, Robot, load_robot
from models.tooling import Material, Tool, load_material, load_tool

__all__ = ["CalibrationContext"]


@dataclass(frozen=True)
class CalibrationContext:
    """The nominal cell (SI).

    Attributes:
        robot: robot data name.
        tcp: TCP in the flange frame [m], (3,).
        tool: the tool (job overrides applied).
        material: the nominal work material (its coefficients are the fit's reference).
        joint_stiffness_scale: the job's common joint stiffness scale [-].
        process_gain: the job's process gain [-].
        process_model, mass_model, criterion, cct: the job's model choices.
        spindle_mass [kg]; spindle_com [m] (3,) (None: the robot data's).
    """

    robot: str = DEFAULT_ROBOT
    tcp: tuple[float, ...] = (0.0, 0.0, 0.0)
    tool: Tool | None = None
    material: Material | None = None
    joint_stiffness_scale: float = 1.0
    process_gain: float = 1.0
    process_model: str = "thesis"
    mass_model: str = "robot"
    criterion: str = "eigen"
    cct: bool = True
    spindle_mass: float | None = None
    spindle_com: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        if self.tool is None:
            object.__setattr__(self, "tool", load_tool("em25_2f"))
        if self.material is None:
            object.__setattr__(self, "material", load_material("al6061"))
        if not self.joint_stiffness_scale > 0 or not self.process_gain > 0:
            raise InputError("joint_stiffness_scale/process_gain", "must be positive")

    @classmethod
    def from_job(cls, job) -> CalibrationContext:
        """The nominal cell of a validated job (:class:`planner.job.Job`)."""
        from planner.tool_limits import job_tool

        si = job.to_si()
        tool, _ = job_tool(job.tool.name, si.tool_radius, job.tool.flutes)
        material = load_material(job.material)
        fitted = job.calibration.coefficients()
        if fitted is not None:  # a calibration overlay's coefficients replace the file's
            material = Material(material.name, *(float(v) for v in fitted),
                                identified_with=tool.name)
        return cls(robot=job.cell.robot, tcp=tuple(float(v) for v in si.tcp), tool=tool,
                   material=material,
                   joint_stiffness_scale=job.cell.joint_stiffness_scale,
                   process_gain=job.model.process_gain, process_model=job.model.process_model,
                   mass_model=job.model.mass_model, criterion=job.model.chatter_criterion,
                   cct=job.model.cct, spindle_mass=job.spindle.mass_kg,
                   spindle_com=None if si.spindle_com is None else tuple(si.spindle_com))

    @classmethod
    def nominal_of(cls, job_file) -> CalibrationContext:
        """The cell of a job file *without* its calibration: robot data and material file as
        shipped (what a simulated truth is relative to)."""
        import tomllib
        from pathlib import Path

        from planner.job import JobError, parse_job

        p = Path(job_file)
        try:
            doc = tomllib.loads(p.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as e:
            raise JobError(str(p), [f"cannot read: {e}"]) from e
        doc.pop("calibration", None)
        return cls.from_job(parse_job(doc, str(p), p.parent.resolve()))

    def load_robot(self) -> Robot:
        return load_robot(self.robot)

    def params(self, joint_scale: np.ndarray | float = 1.0, coefficients: np.ndarray | None = None,
               process_gain: float | None = None) -> ModelParameters:
        """Model parameters with the job's values times ``joint_scale`` (per joint (6,) or
        common) and, where given, other coefficients [N/m², N/m] (6,) and process gain."""
        robot = self.load_robot()
        scale = np.broadcast_to(np.asarray(joint_scale, float), (6,))
        return ModelParameters(
            joint_stiffness=robot.data.joint_stiffness * self.joint_stiffness_scale * scale,
            coefficients=(self.material.coefficients() if coefficients is None
                          else np.asarray(coefficients, float)),
            cct=self.cct,
            process_gain=self.process_gain if process_gain is None else process_gain,
            tcp=np.asarray(self.tcp, float),
            spindle_mass=(robot.data.spindle_mass if self.spindle_mass is None
                          else self.spindle_mass),
            spindle_com=(robot.data.spindle_com if self.spindle_com is None
                         else np.asarray(self.spindle_com, float)))

    def point_model(self, params: ModelParameters | None = None,
                    criterion: str | None = None) -> PointModel:
        """The point model of this cell (``params``: :meth:`params` by default)."""
        return PointModel(self.load_robot(), params or self.params(), self.process_model,
                          self.mass_model, criterion or self.criterion,
                          helix_angle=self.tool.helix_angle)

    def with_(self, **changes) -> CalibrationContext:
        """A copy with fields changed."""
        return replace(self, **changes)
