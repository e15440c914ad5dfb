"""APT/CL cutter-location data (SolidWorks CAM/CAMWorks, Siemens NX): the reader and its options;
conventions in :mod:`robot_io.apt.reader`. ``_records`` and ``_interp`` are private to this package."""

from robot_io.apt.reader import (
    ARC_MIN_RADIUS,
    AptOptions,
    AptReader,
    CYCLE_POSITION_TOL,
    FRAME_ORTHONORMAL_TOL,
    INCH,
    MAX_ARC_TURNS,
    MAX_NUMBER_CHARS,
    MAX_RECORD_FIELDS,
    MAX_WARNINGS_PER_CATEGORY,
    MM,
    TOOL_AXIS_NORM_TOL,
    read_apt,
    read_apt_text,
)

__all__ = [
    "ARC_MIN_RADIUS",
    "AptOptions",
    "AptReader",
    "CYCLE_POSITION_TOL",
    "FRAME_ORTHONORMAL_TOL",
    "INCH",
    "MAX_ARC_TURNS",
    "MAX_NUMBER_CHARS",
    "MAX_RECORD_FIELDS",
    "MAX_WARNINGS_PER_CATEGORY",
    "MM",
    "TOOL_AXIS_NORM_TOL",
    "read_apt",
    "read_apt_text",
]
