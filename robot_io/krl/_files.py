"""Writing a set of files all or nothing (private helper of ``robot_io.krl``; ``robot_io`` may not
use ``planner._atomic``): every file goes to a temporary beside its target first, and only when
all are written are they moved into place with ``os.replace``.
"""

from __future__ import annotations

import os
import re
import tempfile
from pathlib import Path

__all__ = ["remove_stale_pages", "write_all"]


def _file_mode() -> int:
    """0666 less the process umask (what ``open()`` would give a new file)."""
    umask = os.umask(0)
    os.umask(umask)
    return 0o666 & ~umask


def write_all(folder: Path, files: dict[str, bytes]) -> list[Path]:
    """Write every file (name → bytes) to a temporary beside its target in ``folder``, then move
    them all into place; on any error the temporaries are removed and no target is touched
    (the caller checks beforehand that no target is a directory). Returns the targets."""
    folder.mkdir(parents=True, exist_ok=True)
    temps: list[tuple[Path, Path]] = []
    mode = _file_mode()
    try:
        for fname, data in files.items():
            fd, tmp = tempfile.mkstemp(prefix=f".{fname}.", suffix=".tmp", dir=folder)
            temps.append((Path(tmp), folder / fname))
            os.chmod(tmp, mode)            # mkstemp makes 0600; give the file the usual mode
            with os.fdopen(fd, "wb") as fh:
                fh.write(data)
                fh.flush()
                os.fsync(fh.fileno())
        for tmp, target in temps:
            os.replace(tmp, target)
    finally:
        for tmp, _ in temps:
            if tmp.exists():
                tmp.unlink()
    return [target for _, target in temps]


def remove_stale_pages(folder: Path, name: str, keep: set[str]) -> None:
    """Delete pages ``NAME_nnn.src/.dat`` an earlier, longer export of this program left behind
    (only files whose header says cctmill wrote them as a page of ``NAME``)."""
    pattern = re.compile(rf"{re.escape(name)}_\d{{3,}}\.(src|dat)\Z", re.IGNORECASE)
    mark = f"&COMMENT cctmill {name} page ".encode("ascii")
    for p in folder.iterdir():
        if p.name in keep or not pattern.match(p.name) or not p.is_file():
            continue
        try:
            with open(p, "rb") as fh:
                head = fh.read(200)
            if mark in head:
                p.unlink()
        except OSError:      # best effort: a stale page is never called
            continue
