"""cctmill physics: robot kinematics and inertia, stiffness (conventional and CCT), cutting forces,
mode-coupling chatter. No file or network I/O beyond reading the shipped data files.

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
from models.errors import (
    CctmillError,
    DataFileError,
    InputError,
    SingularPoseError,
    UnknownDataError,
    UnreachablePoseError,
)
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
    "InputError",
    "Material",
    "ModelParameters",
    "PointAnalysis",
    "PointModel",
    "Robot",
    "RobotData",
    "SingularPoseError",
    "StabilityCharacteristic",
    "Tool",
    "UnknownDataError",
    "UnreachablePoseError",
    "available_materials",
    "available_robots",
    "available_tools",
    "load_material",
    "load_robot",
    "load_tool",
    "point_function",
]
