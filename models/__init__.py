"""cctmill physics: robot kinematics and inertia, stiffness (conventional and CCT), cutting forces,
mode-coupling chatter, the time-domain milling simulation and its Floquet criterion, static
deflection and compensation. No file or network I/O beyond reading the shipped data files.

Everything symbolic is CasADi; :func:`point_function` is the one Function the planner maps along a
path, :class:`PointModel` its numeric face.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

#: Where each public name lives; imported on first use (PEP 562), so that importing one part
#: of the package (a data type, the errors) does not load the rest.
_SOURCES = {
    "CRITERIA": "models.point",
    "CUT_LAYOUT": "models.analysis",
    "CctmillError": "models.errors",
    "Cut": "models.analysis",
    "DEFAULT_ROBOT": "models.robot",
    "DataFileError": "models.errors",
    "FloquetResult": "models.floquet",
    "InputError": "models.errors",
    "MASS_MODELS": "models.analysis",
    "MILLING_MODES": "models.cutting",
    "Material": "models.tooling",
    "ModelParameters": "models.analysis",
    "OUTPUTS": "models.analysis",
    "PARAM_LAYOUT": "models.analysis",
    "PROCESS_MODELS": "models.analysis",
    "PointAnalysis": "models.point",
    "PointModel": "models.point",
    "Robot": "models.robot",
    "RobotData": "models.robot",
    "SimulationResult": "models.dynamics",
    "SingularPoseError": "models.errors",
    "StabilityCharacteristic": "models.point",
    "Structure": "models.structure",
    "Tool": "models.tooling",
    "UnknownDataError": "models.errors",
    "UnreachablePoseError": "models.errors",
    "available_materials": "models.tooling",
    "available_robots": "models.robot",
    "available_tools": "models.tooling",
    "compensate": "models.deflection",
    "estimate_radial_depth": "models.deflection",
    "floquet": "models.floquet",
    "floquet_margin": "models.floquet",
    "load_material": "models.tooling",
    "load_robot": "models.robot",
    "load_tool": "models.tooling",
    "path_deflection": "models.deflection",
    "path_floquet": "models.floquet",
    "point_function": "models.analysis",
    "pose_structure": "models.structure",
    "simulate": "models.dynamics",
}

__all__ = [
    "CRITERIA",
    "CUT_LAYOUT",
    "CctmillError",
    "Cut",
    "DEFAULT_ROBOT",
    "DataFileError",
    "FloquetResult",
    "InputError",
    "MASS_MODELS",
    "MILLING_MODES",
    "Material",
    "ModelParameters",
    "OUTPUTS",
    "PARAM_LAYOUT",
    "PROCESS_MODELS",
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

if TYPE_CHECKING:  # for type checkers and IDEs: the same names, imported eagerly
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
    from models.cutting import MILLING_MODES
    from models.deflection import compensate, estimate_radial_depth, path_deflection
    from models.dynamics import SimulationResult, simulate
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
    from models.structure import Structure, pose_structure
    from models.tooling import Material, Tool, available_materials, available_tools, load_material, load_tool


def __getattr__(name: str) -> Any:
    if name not in _SOURCES:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(_SOURCES[name]), name)


def __dir__() -> list[str]:
    return __all__
