"""G-code (RS274/NGC as CAM posts write it): the reader and its options; conventions in
:mod:`robot_io.gcode.reader`. The ``_``-modules are the interpreter's parts, private to this package."""

from robot_io.gcode.reader import (
    ARC_MIN_RADIUS,
    GcodeOptions,
    GcodeReader,
    INCH,
    MAX_ARC_TURNS,
    MAX_WARNINGS_PER_CATEGORY,
    MAX_WORD_VALUE,
    MM,
    read_gcode,
    read_gcode_text,
)

__all__ = [
    "ARC_MIN_RADIUS",
    "GcodeOptions",
    "GcodeReader",
    "INCH",
    "MAX_ARC_TURNS",
    "MAX_WARNINGS_PER_CATEGORY",
    "MAX_WORD_VALUE",
    "MM",
    "read_gcode",
    "read_gcode_text",
]
