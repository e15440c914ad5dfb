"""cctmill I/O across the boundary: toolpath readers (G-code, APT/CL, KUKA KRL) into one plain move
model; the KRL writer and its lint; KUKA protocols and signal sources. Own plain data types; never
imports ``planner``."""

from __future__ import annotations

import importlib
from typing import Any

#: Where each public name lives; imported on first use (PEP 562, type checkers see the module's
#: ``__getattr__``; import from the module itself for its types), so that importing one part
#: of the package (a toolpath reader, say) does not load the rest.
_EXPORTS: dict[str, tuple[str, ...]] = {
    "robot_io.apt": ("read_apt", "read_apt_text"),
    "robot_io.gcode": ("read_gcode", "read_gcode_text"),
    "robot_io.krl": (
        "KrlError", "KrlFrame", "KrlMove", "KrlProgramSpec", "KrlSection", "render_krl", "write_krl",
    ),
    "robot_io.krl.lint": ("LintProblem", "lint_krl"),
    "robot_io.krl.reader": ("read_krl", "read_krl_text"),
    "robot_io.links.base": ("LinkError", "LinkStats", "LinkStatus", "ProtocolError", "RobotLink"),
    "robot_io.links.kvp": ("KvpClient", "KvpConnection"),
    "robot_io.links.kvp_sim": ("KvpSimServer",),
    "robot_io.links.rsi": ("RsiServer",),
    "robot_io.links.rsi_config": ("RsiConfig", "load_rsi_config"),
    "robot_io.links.rsi_process": ("RsiProcessServer",),
    "robot_io.links.rsi_sim": ("RsiSimController",),
    "robot_io.readers": ("FORMATS", "detect_format", "read_toolpath"),
    "robot_io.signals.base": ("SignalChunk", "SignalSource", "SourceStats"),
    "robot_io.signals.replay": ("ReplaySource", "SignalFileError", "load_signal"),
    "robot_io.signals.udp": ("UdpSignalSender", "UdpSignalSource"),
    "robot_io.toolpath": (
        "Move", "MoveKind", "MoveList", "SourceRef", "Toolpath", "ToolpathError", "ToolpathReader",
        "ToolpathWarning", "arc_geometry", "summarize",
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
