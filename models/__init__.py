"""cctmill physics: robot kinematics and inertia, stiffness (conventional and CCT), cutting forces,
mode-coupling chatter, the time-domain milling simulation and its Floquet criterion, static
deflection and compensation. No file or network I/O beyond reading the shipped data files.

Everything symbolic is CasADi; :func:`point_function` is the one Function the planner maps along a
path, :class:`PointModel` its numeric face.
"""

from __future__ import annotations

import importlib
from typing import Any

#: Where each public name lives; imported on first use (PEP 562, type checkers see the module's
#: ``__getattr__``; import from the module itself for its types), so that importing one part
#: of the package (a data type, the errors) does not load the rest.
_EXPORTS: dict[str, tuple[str, ...]] = {
    "models.analysis": (
        "CUT_LAYOUT", "Cut", "MASS_MODELS", "ModelParameters", "OUTPUTS", "PARAM_LAYOUT", "PROCESS_MODELS",
        "point_function",
    ),
    "models.cutting": ("MILLING_MODES",),
    "models.deflection": ("compensate", "estimate_radial_depth", "path_deflection"),
    "models.dynamics": ("SimulationResult", "simulate"),
    "models.errors": (
        "CctmillError", "DataFileError", "InputError", "SingularPoseError", "UnknownDataError",
        "UnreachablePoseError",
    ),
    "models.floquet": ("FloquetResult", "floquet", "floquet_margin", "path_floquet"),
    "models.point": ("CRITERIA", "PointAnalysis", "PointModel", "StabilityCharacteristic"),
    "models.robot": ("DEFAULT_ROBOT", "Robot", "RobotData", "available_robots", "load_robot"),
    "models.structure": ("Structure", "pose_structure"),
    "models.tooling": (
        "Material", "Tool", "available_materials", "available_tools", "load_material", "load_tool",
    ),
}
_SOURCES = {name: module for module, names in _EXPORTS.items() for name in names}

__all__ = sorted(_SOURCES)

def __getattr__(name: str) -> Any:
    if name not in _SOURCES:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(_SOURCES[name]), name)


def __dir__() -> list[str]:
    return __all__
