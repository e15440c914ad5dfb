"""Atomic file output: write to a temporary file in the same folder, then ``os.replace``.

A crash or an error half-way leaves the previous file (or none), never a truncated one. Every
failure to write is one :class:`OutputError` naming the path, and :func:`check_output` finds the
common ones (a file where a folder should be, a read-only folder, a missing one that will not be
made) before the work that would produce the output starts.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path

from models.errors import CctmillError

__all__ = ["OUTPUT_KINDS", "OutputError", "atomic_path", "check_output", "output_errors",
           "write_text_atomic"]

#: How an output path is written: ``folder`` — files go into it, it is made with its parents;
#: ``file`` — written atomically, its folder made if missing; ``append`` — a file opened for
#: appending (a log), whose folder must exist.
OUTPUT_KINDS = ("folder", "file", "append")

#: The fix an :class:`OutputError` suggests unless the caller knows a better one.
_DEFAULT_FIX = "choose another output folder"


class OutputError(CctmillError):
    """An output cannot be written.

    Attributes:
        path: the output as given (a file or a folder).
        reason: why, in words (the system's, or what is in the way).
        flag: the option that named the path (``"-o/--output"``), or None.
    """

    def __init__(self, path: str | os.PathLike, reason: str, fix: str = _DEFAULT_FIX,
                 flag: str | None = None) -> None:
        where = f"{flag} {path}" if flag else f"{path}"
        super().__init__(f"{where}: cannot write: {reason}; {fix}")
        self.path = str(path)
        self.reason = reason
        self.flag = flag


def _existing_ancestor(p: Path) -> Path:
    """``p`` or its nearest ancestor that exists (``.`` and ``/`` always do)."""
    while not (p.exists() or p.is_symlink()) and p.parent != p:
        p = p.parent
    return p


def check_output(path: str | os.PathLike, kind: str = "file", flag: str | None = None) -> Path:
    """Raise :class:`OutputError` now if ``path`` cannot be written as ``kind`` (see
    :data:`OUTPUT_KINDS`); return it as a Path. Nothing is created.

    Called before the work whose result goes to ``path``, so a long plan is not lost to a file
    name where a folder should be. The write itself may still fail (a full disk); the writers
    raise :class:`OutputError` then.

    Raises:
        OutputError: ``path`` (or, for a file, its folder) is in the way or not writable, or
            (``append``) its folder does not exist; ``flag`` is named in the message.
        ValueError: ``kind`` is not one of :data:`OUTPUT_KINDS` (a programming error).
    """
    if kind not in OUTPUT_KINDS:
        raise ValueError(f"kind must be one of {OUTPUT_KINDS}, got {kind!r}")
    p = Path(path)
    fix = "choose another output folder" if kind == "folder" else "choose another path"

    def fail(reason: str, how: str = fix) -> OutputError:
        return OutputError(p, reason, how, flag)

    try:
        if kind == "folder":
            if p.exists() and not p.is_dir():
                raise fail("it is a file, not a folder", "give a folder name (it is made if "
                                                         "missing)")
            folder = p
        else:
            if p.is_dir():
                raise fail("it is a folder", "give a file name (e.g. one inside it)")
            if kind == "append" and p.exists() and not os.access(p, os.W_OK):
                raise fail("the file is not writable (permission denied)")
            folder = p.parent
        here = _existing_ancestor(folder)
        if not here.is_dir():
            raise fail(f"{here} is a file, not a folder")
        if here != folder and kind == "append":
            raise fail(f"folder {folder} does not exist",
                       f"create it first (mkdir -p {folder}) or {fix}")
        if not os.access(here, os.W_OK | os.X_OK):
            made = "" if here == folder else f", where {folder.name} would be made,"
            raise fail(f"folder {here}{made} is not writable (permission denied)")
    except OSError as e:          # a folder on the way that cannot even be looked at
        raise fail(e.strerror or str(e)) from e
    return p


@contextlib.contextmanager
def output_errors(*paths: str | os.PathLike | None, unnamed: bool = True) -> Iterator[None]:
    """Turn an ``OSError`` raised inside the block while writing one of ``paths`` (a file, or a
    folder and what is in it) into :class:`OutputError` naming the file.

    ``unnamed``: an ``OSError`` with no file name (``ENOSPC`` from a write) is also an output
    error (the block does nothing but write); False where the block also talks to other things.
    """
    targets = [Path(p) for p in paths if p is not None]
    try:
        yield
    except OSError as e:
        name = e.filename
        if name is None:
            if not unnamed or not targets:
                raise
            name = targets[0]
        elif not any(Path(name) == t or t in Path(name).parents for t in targets):
            raise
        raise OutputError(name, e.strerror or str(e)) from e


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, suffix: str | None = None) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on success move it over ``path``, else delete it.

    Raises:
        OutputError: the folder cannot be made, or the file cannot be created, written or
            replaced (an ``OSError`` of the block about the temporary file, or unnamed).
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
        try:
            yield tmp_path
        except OSError as e:
            if e.filename is not None and Path(e.filename) != tmp_path:
                raise
            raise OutputError(target, e.strerror or str(e)) from e
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
