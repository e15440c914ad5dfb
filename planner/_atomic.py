"""Atomic file output: write to a temporary file in the same folder, then ``os.replace``.

A crash or an error half-way leaves the previous file (or none), never a truncated one.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path

from models.errors import CctmillError

__all__ = ["OutputError", "atomic_path", "write_text_atomic"]


class OutputError(CctmillError):
    """An output file cannot be written (``path``: the file; the reason is the system's)."""

    def __init__(self, path: str | os.PathLike, reason: str) -> None:
        super().__init__(f"{path}: cannot write: {reason}; choose another output folder")
        self.path = str(path)


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, suffix: str | None = None) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on success move it over ``path``, else delete it.

    Raises:
        OutputError: the folder cannot be made, or the file cannot be created or replaced.
    """
    target = Path(path)
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.",
                                   suffix=suffix or target.suffix or ".tmp", dir=target.parent)
    except OSError as e:
        raise OutputError(target, e.strerror or str(e)) from e
    os.close(fd)
    tmp_path = Path(tmp)
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp_path, 0o666 & ~umask)  # mkstemp makes 0600; outputs are ordinary files
    try:
        yield tmp_path
        try:
            os.replace(tmp_path, target)
        except OSError as e:
            raise OutputError(target, e.strerror or str(e)) from e
    finally:
        if tmp_path.exists():
            tmp_path.unlink()


def write_text_atomic(path: str | os.PathLike, text: str, newline: str | None = None) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically; return the path."""
    with atomic_path(path) as tmp:
        with open(tmp, "w", encoding="utf-8", newline=newline) as fh:
            fh.write(text)
    return Path(path)
