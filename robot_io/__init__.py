"""cctmill I/O across the boundary: toolpath readers (G-code, APT/CL, KUKA KRL) into one plain move
model; the KRL writer and its lint; KUKA protocols and signal sources. Own plain data types; never
imports ``planner``."""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

#: Where each public name lives; imported on first use (PEP 562), so that importing one part
#: of the package (a toolpath reader, say) does not load the rest.
_SOURCES = {
    "FORMATS": "robot_io.readers",
    "KrlError": "robot_io.krl",
    "KrlFrame": "robot_io.krl",
    "KrlMove": "robot_io.krl",
    "KrlProgramSpec": "robot_io.krl",
    "KrlSection": "robot_io.krl",
    "KvpClient": "robot_io.links.kvp",
    "KvpConnection": "robot_io.links.kvp",
    "KvpSimServer": "robot_io.links.kvp_sim",
    "LinkError": "robot_io.links.base",
    "LinkStats": "robot_io.links.base",
    "LinkStatus": "robot_io.links.base",
    "LintProblem": "robot_io.krl.lint",
    "Move": "robot_io.toolpath",
    "MoveKind": "robot_io.toolpath",
    "MoveList": "robot_io.toolpath",
    "ProtocolError": "robot_io.links.base",
    "ReplaySource": "robot_io.signals.replay",
    "RobotLink": "robot_io.links.base",
    "RsiProcessServer": "robot_io.links.rsi_process",
    "RsiServer": "robot_io.links.rsi",
    "RsiSimController": "robot_io.links.rsi_sim",
    "SignalChunk": "robot_io.signals.base",
    "SignalFileError": "robot_io.signals.replay",
    "SignalSource": "robot_io.signals.base",
    "SourceRef": "robot_io.toolpath",
    "SourceStats": "robot_io.signals.base",
    "Toolpath": "robot_io.toolpath",
    "ToolpathError": "robot_io.toolpath",
    "ToolpathReader": "robot_io.toolpath",
    "ToolpathWarning": "robot_io.toolpath",
    "UdpSignalSender": "robot_io.signals.udp",
    "UdpSignalSource": "robot_io.signals.udp",
    "arc_geometry": "robot_io.toolpath",
    "detect_format": "robot_io.readers",
    "lint_krl": "robot_io.krl.lint",
    "load_signal": "robot_io.signals.replay",
    "read_apt": "robot_io.apt",
    "read_apt_text": "robot_io.apt",
    "read_gcode": "robot_io.gcode",
    "read_gcode_text": "robot_io.gcode",
    "read_krl": "robot_io.krl.reader",
    "read_krl_text": "robot_io.krl.reader",
    "read_toolpath": "robot_io.readers",
    "render_krl": "robot_io.krl",
    "summarize": "robot_io.toolpath",
    "write_krl": "robot_io.krl",
}

__all__ = [
    "FORMATS",
    "KrlError",
    "KrlFrame",
    "KrlMove",
    "KrlProgramSpec",
    "KrlSection",
    "KvpClient",
    "KvpConnection",
    "KvpSimServer",
    "LinkError",
    "LinkStats",
    "LinkStatus",
    "LintProblem",
    "Move",
    "MoveKind",
    "MoveList",
    "ProtocolError",
    "ReplaySource",
    "RobotLink",
    "RsiProcessServer",
    "RsiServer",
    "RsiSimController",
    "SignalChunk",
    "SignalFileError",
    "SignalSource",
    "SourceRef",
    "SourceStats",
    "Toolpath",
    "ToolpathError",
    "ToolpathReader",
    "ToolpathWarning",
    "UdpSignalSender",
    "UdpSignalSource",
    "arc_geometry",
    "detect_format",
    "lint_krl",
    "load_signal",
    "read_apt",
    "read_apt_text",
    "read_gcode",
    "read_gcode_text",
    "read_krl",
    "read_krl_text",
    "read_toolpath",
    "render_krl",
    "summarize",
    "write_krl",
]

if TYPE_CHECKING:  # for type checkers and IDEs: the same names, imported eagerly
    from robot_io.apt import read_apt, read_apt_text
    from robot_io.gcode import read_gcode, read_gcode_text
    from robot_io.krl import KrlError, KrlFrame, KrlMove, KrlProgramSpec, KrlSection, render_krl, write_krl
    from robot_io.krl.lint import LintProblem, lint_krl
    from robot_io.krl.reader import read_krl, read_krl_text
    from robot_io.links.base import LinkError, LinkStats, LinkStatus, ProtocolError, RobotLink
    from robot_io.links.kvp import KvpClient, KvpConnection
    from robot_io.links.kvp_sim import KvpSimServer
    from robot_io.links.rsi import RsiServer
    from robot_io.links.rsi_process import RsiProcessServer
    from robot_io.links.rsi_sim import RsiSimController
    from robot_io.readers import FORMATS, detect_format, read_toolpath
    from robot_io.signals.base import SignalChunk, SignalSource, SourceStats
    from robot_io.signals.replay import ReplaySource, SignalFileError, load_signal
    from robot_io.signals.udp import UdpSignalSender, UdpSignalSource
    from robot_io.toolpath import (
        Move,
        MoveKind,
        MoveList,
        SourceRef,
        Toolpath,
        ToolpathError,
        ToolpathReader,
        ToolpathWarning,
        arc_geometry,
        summarize,
    )


def __getattr__(name: str) -> Any:
    if name not in _SOURCES:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(_SOURCES[name]), name)


def __dir__() -> list[str]:
    return __all__
