"""G-code (RS274/NGC as CAM posts write it): the reader and its options; conventions and limits
(``MAX_ARC_TURNS``, ``ARC_MIN_RADIUS``, …) in :mod:`robot_io.gcode.reader`. The ``_``-modules are
the interpreter's parts, private to this package."""

from robot_io.gcode.reader import GcodeOptions, GcodeReader, read_gcode, read_gcode_text

__all__ = ["GcodeOptions", "GcodeReader", "read_gcode", "read_gcode_text"]
