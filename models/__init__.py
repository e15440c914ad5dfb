"""cctmill physics: robot kinematics and inertia, stiffness (conventional and CCT), cutting forces,
mode-coupling chatter, the time-domain milling simulation and its Floquet criterion, static
deflection and compensation. No file or network I/O beyond reading the shipped data files.

Everything symbolic is CasADi; :func:`point_function` is the one Function the planner maps along a
path, :class:`PointModel` its numeric face.
"""

from models.analysis import (
    CUT_LAYOUT,
    MASS_MODELS,
    OUTPUTS,
    PARAM_LAYOUT,
    PROCESS_MODELS,
    Cut,
    ModelParameters,
    point_function,
)
from models.cutting import (
    MILLING_MODES,
    Material,
    Tool,
    available_materials,
    available_tools,
    load_material,
    load_tool,
)
from models.deflection import compensate, estimate_radial_depth, path_deflection
from models.dynamics import SimulationResult, Structure, pose_structure, simulate
from models.errors import (
    CctmillError,
    DataFileError,
    InputError,
    SingularPoseError,
    UnknownDataError,
    UnreachablePoseError,
)
from models.floquet import FloquetResult, floquet, floquet_margin, path_floquet
from models.point import CRITERIA, PointAnalysis, PointModel, StabilityCharacteristic
from models.robot import DEFAULT_ROBOT, Robot, RobotData, available_robots, load_robot

__all__ = [
    "CRITERIA",
    "CUT_LAYOUT",
    "DEFAULT_ROBOT",
    "MASS_MODELS",
    "MILLING_MODES",
    "OUTPUTS",
    "PARAM_LAYOUT",
    "PROCESS_MODELS",
    "CctmillError",
    "Cut",
    "DataFileError",
    "FloquetResult",
    "InputError",
    "Material",
    "ModelParameters",
    "PointAnalysis",
    "PointModel",
    "Robot",
    "RobotData",
    "SimulationResult",
    "SingularPoseError",
    "StabilityCharacteristic",
    "Structure",
    "Tool",
    "UnknownDataError",
    "UnreachablePoseError",
    "available_materials",
    "available_robots",
    "available_tools",
    "compensate",
    "estimate_radial_depth",
    "floquet",
    "floquet_margin",
    "load_material",
    "load_robot",
    "load_tool",
    "path_deflection",
    "path_floquet",
    "point_function",
    "pose_structure",
    "simulate",
]
