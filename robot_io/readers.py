"""The toolpath reader registry: one entry point for every format, the reader picked by extension,
else by content. Built from the reader classes (their ``format``, ``suffixes`` and ``sniff``), so
a format's extensions are written once, in its reader."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from robot_io.apt.reader import AptReader
from robot_io.gcode.reader import GcodeReader
from robot_io.krl.reader import KrlReader
from robot_io.toolpath import Toolpath, ToolpathError, ToolpathReader

__all__ = ["FORMATS", "READERS", "detect_format", "read_toolpath"]

#: Every reader by format, in the order their content is sniffed (APT and KRL words are more
#: specific than G-code's).
READERS: dict[str, ToolpathReader] = {r.format: r for r in (AptReader(), KrlReader(), GcodeReader())}
#: Known formats and the file extensions that announce them.
FORMATS: dict[str, tuple[str, ...]] = {name: r.suffixes for name, r in READERS.items()}

#: How many bytes of a file are looked at to guess its format.
_SNIFF_BYTES = 4096


def detect_format(path: str | os.PathLike) -> str:
    """``"gcode"``, ``"apt"`` or ``"krl"`` from the extension, else from the first few KiB."""
    p = Path(path)
    ext = p.suffix.lower()
    for fmt, reader in READERS.items():
        if ext in reader.suffixes:
            return fmt
    try:
        head = p.read_bytes()[:_SNIFF_BYTES].decode("utf-8", "replace").upper()
    except OSError as e:
        raise ToolpathError(str(p), 0, 0, f"cannot read: {e.strerror}") from e
    for fmt, reader in READERS.items():
        if reader.sniff(head):
            return fmt
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
    reader = READERS.get(fmt)
    if reader is None:
        raise ToolpathError(str(p), 0, 0, f"unknown format {fmt!r}; use one of {', '.join(READERS)}")
    return reader.read(str(p), strict=strict, **options)
