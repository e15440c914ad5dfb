"""cctmill I/O across the boundary: toolpath readers (G-code, APT/CL, KUKA KRL) into one plain move
model; later the KRL writer, KUKA protocols and signal sources. Own plain data types; never imports
``planner``."""

from robot_io.apt import read_apt, read_apt_text
from robot_io.gcode import read_gcode, read_gcode_text
from robot_io.krl_reader import read_krl, read_krl_text
from robot_io.readers import FORMATS, detect_format, read_toolpath
from robot_io.toolpath import (
    Move,
    MoveKind,
    SourceRef,
    Toolpath,
    ToolpathError,
    ToolpathReader,
    ToolpathWarning,
    arc_geometry,
    summarize,
)

__all__ = [
    "FORMATS",
    "Move",
    "MoveKind",
    "SourceRef",
    "Toolpath",
    "ToolpathError",
    "ToolpathReader",
    "ToolpathWarning",
    "arc_geometry",
    "detect_format",
    "read_apt",
    "read_apt_text",
    "read_gcode",
    "read_gcode_text",
    "read_krl",
    "read_krl_text",
    "read_toolpath",
    "summarize",
]
