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
from robot_io.options import OPTION_FORMATS, fix, option_name
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
    except FileNotFoundError as e:
        raise ToolpathError(str(p), 0, 0, "not found; check the path") from e
    except OSError as e:
        raise ToolpathError(str(p), 0, 0, f"cannot read the file ({e.strerror}); check the path "
                            "and its permissions") from e
    for fmt, reader in READERS.items():
        if reader.sniff(head):
            return fmt
    raise ToolpathError(str(p), 0, 0, "unknown toolpath format; name the file .nc/.ngc (G-code), "
                        ".apt/.cl (APT/CL) or .src (KUKA KRL), or give the format "
                        f"({fix('format', 'gcode')}, apt or krl)")


def read_toolpath(path: str | os.PathLike, strict: bool = True, format: str | None = None,
                  **options: Any) -> Toolpath:
    """Read a toolpath file in any supported format.

    Args:
        path: the file.
        strict: fail on the first problem (default) or collect warnings and go on.
        format: ``"gcode"``, ``"apt"`` or ``"krl"``; default: detected.
        options: passed to the reader (e.g. ``rotary="xyzac-trunnion"`` for G-code); an option of
            another format is refused, naming the formats it applies to.

    The toolpath's warnings end with the plausibility checks of
    :func:`robot_io.diagnostics.plausibility_warnings` (units that look swapped, feeds beyond a
    milling robot, a part wider than any cell).
    """
    from robot_io.diagnostics import plausibility_warnings

    p = Path(path)
    if not p.exists():
        raise ToolpathError(str(p), 0, 0, "not found; check the path")
    if not p.is_file():
        raise ToolpathError(str(p), 0, 0, "is not a file; give a toolpath file")
    if format is not None and format not in READERS:
        raise ToolpathError(str(p), 0, 0, f"unknown format {format!r}; use one of "
                            f"{', '.join(READERS)} ({option_name('format')})")
    fmt = format or detect_format(p)
    reader = READERS[fmt]
    for k in options:
        formats = OPTION_FORMATS.get(k, ())
        if formats and "*" not in formats and fmt not in formats:
            shown = " and ".join(_FORMAT_NAMES[f] for f in formats)
            raise ToolpathError(str(p), 0, 0, f"{option_name(k)} applies to {shown} programs "
                                f"only; this file is {_FORMAT_NAMES[fmt]} (leave it out)")
    tp = reader.read(str(p), strict=strict, **options)
    tp.warnings.extend(plausibility_warnings(tp))
    return tp


#: How messages name the formats.
_FORMAT_NAMES = {"gcode": "G-code", "apt": "APT/CL", "krl": "KUKA KRL"}
