"""One entry point for every toolpath format: pick the reader by extension, else by content."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from robot_io.toolpath import Toolpath, ToolpathError

__all__ = ["FORMATS", "detect_format", "read_toolpath"]

#: Known formats and the file extensions that announce them.
FORMATS: dict[str, tuple[str, ...]] = {
    "gcode": (".nc", ".ngc", ".gcode", ".gc", ".tap", ".cnc", ".mpf", ".eia"),
    "apt": (".apt", ".cl", ".cls", ".aptsource"),
    "krl": (".src",),
}

#: How many bytes of a file are looked at to guess its format.
_SNIFF_BYTES = 4096


def detect_format(path: str | os.PathLike) -> str:
    """``"gcode"``, ``"apt"`` or ``"krl"`` from the extension, else from the first few KiB."""
    p = Path(path)
    ext = p.suffix.lower()
    for fmt, exts in FORMATS.items():
        if ext in exts:
            return fmt
    try:
        head = p.read_bytes()[:_SNIFF_BYTES].decode("utf-8", "replace").upper()
    except OSError as e:
        raise ToolpathError(str(p), 0, 0, f"cannot read: {e.strerror}") from e
    if "GOTO/" in head or "FEDRAT/" in head or "PARTNO" in head:
        return "apt"
    if "DEF " in head and ("LIN " in head or "PTP " in head or "END" in head):
        return "krl"
    if any(w in head for w in ("G0", "G1", "G2", "G3", "G90", "G21", "G20")):
        return "gcode"
    raise ToolpathError(str(p), 1, 0, "unknown toolpath format; name the file .nc/.ngc (G-code), "
                        ".apt/.cl (APT/CL) or .src (KUKA KRL), or pass format=")


def read_toolpath(path: str | os.PathLike, strict: bool = True, format: str | None = None,
                  **options: Any) -> Toolpath:
    """Read a toolpath file in any supported format.

    Args:
        path: the file.
        strict: fail on the first problem (default) or collect warnings and go on.
        format: ``"gcode"``, ``"apt"`` or ``"krl"``; default: detected.
        options: passed to the reader (e.g. ``rotary="xyzac-trunnion"`` for G-code).
    """
    p = Path(path)
    if not p.is_file():
        raise ToolpathError(str(p), 0, 0, "no such file")
    fmt = format or detect_format(p)
    if fmt == "gcode":
        from robot_io.gcode import read_gcode

        return read_gcode(str(p), strict=strict, **options)
    if fmt == "apt":
        from robot_io.apt import read_apt

        return read_apt(str(p), strict=strict, **options)
    if fmt == "krl":
        from robot_io.krl.reader import read_krl

        return read_krl(str(p), strict=strict, **options)
    raise ToolpathError(str(p), 0, 0, f"unknown format {fmt!r}; use one of {', '.join(FORMATS)}")
