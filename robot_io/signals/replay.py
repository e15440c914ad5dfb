"""Replay of a recorded force/strain signal (CSV or NPY) as a :class:`SignalSource`.

File formats:

- **CSV**: an optional header line, then one sample per line. With two or more columns the time
  column is the one named ``t_s``, ``time_s``, ``time`` or ``t`` (else the first) in seconds, and
  the value column the first other one (or the one named by ``column``). With one column the sample
  rate must be given (``fs_hz``) and the samples are taken at ``i / fs_hz``. ``#`` starts a comment.
- **NPY**: shape (n,) with ``fs_hz`` given, or shape (n, 2) with columns [t_s, value].

Timestamps must be finite, increase strictly and lie within ±:data:`MAX_TIME_S` (a
recording of 31 years; a larger stamp is a corrupt file, not a signal). A bad file raises
:class:`SignalFileError` with the file, the line (CSV) and what to fix; reading the loaded replay
never raises.

Pacing: with ``realtime=True`` a read hands out the samples whose time has come on ``clock`` (the
first read starts the replay); otherwise every read hands out the next ``max_samples`` samples.
"""

from __future__ import annotations

import csv
import os
import time
import tokenize
from collections.abc import Callable
from pathlib import Path

import numpy as np

from models.errors import CctmillError
from robot_io.signals.base import SignalChunk, SourceStats, empty_chunk

__all__ = ["MAX_TIME_S", "ReplaySource", "SignalFileError", "load_signal"]

#: Largest |timestamp| read [s] (the readers' magnitude limit, as for coordinates).
MAX_TIME_S = 1e9

_TIME_NAMES = ("t_s", "time_s", "time", "t")
#: How a zip archive (an ``.npz``) begins: a file, or the end record of an empty archive.
_ZIP_MAGICS = (b"PK\x03\x04", b"PK\x05\x06")


class SignalFileError(CctmillError):
    """A recorded signal file cannot be used.

    Attributes:
        file: the file.
        line: 1-based line (CSV), 0 when the whole file is meant.
        reason: the problem and how to fix it.
    """

    def __init__(self, file: str, line: int, reason: str) -> None:
        self.file = file
        self.line = line
        self.reason = reason
        super().__init__(f"{file}:{line}: {reason}" if line else f"{file}: {reason}")


def _uniform(n: int, fs_hz: float | None, file: str) -> np.ndarray:
    if fs_hz is None:
        raise SignalFileError(file, 0, "one value per sample and no time column: give the sample "
                              "rate fs_hz")
    if not (np.isfinite(fs_hz) and fs_hz > 0):
        raise SignalFileError(file, 0, f"sample rate must be positive, got {fs_hz:g} Hz")
    if not (n - 1) / float(fs_hz) <= MAX_TIME_S:   # the last sample's time is not a time
        raise SignalFileError(file, 0, f"sample rate {fs_hz:g} Hz is too small: the times of {n} "
                              f"samples go beyond {MAX_TIME_S:g} s; give the rate in Hz")
    return np.arange(n) / float(fs_hz)


def _read_csv(p: Path, fs_hz: float | None, column: str | None) -> tuple[np.ndarray, np.ndarray]:
    file = str(p)
    try:
        text = p.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as e:
        raise SignalFileError(file, 0, f"not readable as UTF-8 text ({e})") from e
    rows: list[tuple[int, list[str]]] = []
    reader = csv.reader(text.splitlines())
    try:
        for lineno, row in enumerate(reader, start=1):
            cells = [c.strip() for c in row]
            if not cells or not any(cells) or cells[0].startswith("#"):
                continue
            rows.append((lineno, cells))
    except csv.Error as e:   # e.g. a field longer than the csv module's limit (128 KiB)
        raise SignalFileError(file, reader.line_num, f"not readable as CSV ({e})") from None
    if not rows:
        raise SignalFileError(file, 0, "no samples in the file")
    header: list[str] | None = None
    try:
        [float(c) for c in rows[0][1]]
    except ValueError:
        header = [c.lower() for c in rows[0][1]]
        rows = rows[1:]
    if not rows:
        raise SignalFileError(file, 0, "a header but no samples")
    width = len(rows[0][1])
    if header is not None and len(header) != width:
        raise SignalFileError(file, rows[0][0], f"{width} fields but the header names {len(header)}")
    names = header or [f"col{i}" for i in range(width)]
    t_col: int | None = None
    if width >= 2:
        t_col = next((names.index(n) for n in _TIME_NAMES if n in names), 0)
    if column is not None:
        if column.lower() not in names:
            raise SignalFileError(file, 0, f"no column {column!r}; columns: {', '.join(names)}")
        v_col = names.index(column.lower())
    else:
        v_col = next(i for i in range(width) if i != t_col)
    data = np.empty((len(rows), width))
    for i, (lineno, cells) in enumerate(rows):
        if len(cells) != width:
            raise SignalFileError(file, lineno, f"{len(cells)} fields, expected {width}")
        for j, c in enumerate(cells):
            try:
                data[i, j] = float(c)
            except ValueError:
                raise SignalFileError(file, lineno, f"field {j + 1} {c!r} is not a number") from None
    values = data[:, v_col]
    if t_col is None:
        return _uniform(values.shape[0], fs_hz, file), values
    t = data[:, t_col]
    big = np.flatnonzero(~(np.abs(t) <= MAX_TIME_S))
    if big.size:
        k = int(big[0])
        raise SignalFileError(file, rows[k][0], f"time {float(t[k]):.10g} s is not a finite time "
                              f"within ±{MAX_TIME_S:g} s")
    bad = np.flatnonzero(~(np.diff(t) > 0))
    if bad.size:
        k = int(bad[0]) + 1
        raise SignalFileError(file, rows[k][0], f"time {float(t[k]):.10g} does not increase strictly "
                              "(sort the file or drop duplicate rows)")
    return t, values


def _read_npy(p: Path, fs_hz: float | None) -> tuple[np.ndarray, np.ndarray]:
    file = str(p)
    try:
        with open(p, "rb") as f:
            zipped = f.read(len(_ZIP_MAGICS[0])) in _ZIP_MAGICS
        if zipped:   # np.load would open it as a table of arrays (and leak the file if damaged)
            raise SignalFileError(file, 0, "an .npz archive of arrays, not one array; save the "
                                  "signal with numpy.save")
        # memory-mapped, so a header declaring more data than the file holds is refused without
        # allocating it
        m = np.load(p, mmap_mode="r", allow_pickle=False)
    except (OSError, ValueError, EOFError, tokenize.TokenError) as e:
        # EOFError: an empty file; TokenError: a header numpy cannot tokenise (it tokenises old
        # headers to read them)
        raise SignalFileError(file, 0, f"not a readable .npy array ({e})") from e
    if m.dtype.kind not in "iuf":       # real numbers only (complex would lose its imaginary part)
        raise SignalFileError(file, 0, f"dtype {m.dtype} is not real numbers")
    a = np.array(m, dtype=float)       # a copy: the file is not held open
    del m
    if a.ndim == 1:
        return _uniform(a.shape[0], fs_hz, file), a
    if a.ndim == 2 and a.shape[1] == 2:
        t = a[:, 0]
        if not (np.all(np.abs(t) <= MAX_TIME_S) and np.all(np.diff(t) > 0)):
            raise SignalFileError(file, 0, "column 0 (time [s]) must be finite, within "
                                  f"±{MAX_TIME_S:g} s and increase strictly")
        return t, a[:, 1]
    raise SignalFileError(file, 0, f"shape {a.shape}: need (n,) with a sample rate (fs_hz), or "
                          "(n, 2) = [t_s, value]")


def load_signal(path: str | os.PathLike, fs_hz: float | None = None,
                column: str | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Read a recorded signal; return (t_s, values), both shape (n,), t in seconds.

    Args:
        path: ``.csv`` or ``.npy`` file (see the module docstring).
        fs_hz: sample rate [Hz], needed when the file has no time column.
        column: CSV value column name (default: the first non-time column).

    Raises:
        SignalFileError: the file is missing, malformed, or has no usable time base.
    """
    p = Path(path)
    if not p.is_file():
        raise SignalFileError(str(p), 0, "no such file")
    if p.suffix.lower() == ".npy":
        t, v = _read_npy(p, fs_hz)
    else:
        t, v = _read_csv(p, fs_hz, column)
    if v.shape[0] < 2:
        raise SignalFileError(str(p), 0, "need at least two samples")
    return t, v


class ReplaySource:
    """A recorded signal handed out chunk by chunk (see the module docstring for pacing).

    Args:
        t_s: sample times [s], shape (n,), increasing.
        values: samples, shape (n,).
        realtime: pace by ``clock`` instead of handing out as fast as asked.
        clock: monotonic clock [s] for realtime pacing (default ``time.monotonic``).
    """

    def __init__(self, t_s: np.ndarray, values: np.ndarray, realtime: bool = False,
                 clock: Callable[[], float] | None = None) -> None:
        self._t = np.asarray(t_s, dtype=float)
        self._v = np.asarray(values, dtype=float)
        if self._t.shape != self._v.shape or self._t.ndim != 1:
            raise ValueError("t_s and values must be 1-D arrays of the same length")
        dt = np.diff(self._t)
        self.fs_hz = float(1.0 / np.median(dt)) if dt.size else 0.0
        self.stats = SourceStats()
        self._realtime = realtime
        self._clock = clock or time.monotonic
        self._start: float | None = None
        self._i = 0

    @classmethod
    def from_file(cls, path: str | os.PathLike, fs_hz: float | None = None,
                  column: str | None = None, **kw) -> ReplaySource:
        """Load ``path`` with :func:`load_signal` and replay it."""
        t, v = load_signal(path, fs_hz, column)
        return cls(t, v, **kw)

    @property
    def duration_s(self) -> float:
        return float(self._t[-1] - self._t[0]) if self._t.size else 0.0

    def read(self, max_samples: int) -> SignalChunk:
        n = self._t.shape[0]
        if self._i >= n:
            return empty_chunk("end")
        stop = min(n, self._i + max(0, int(max_samples)))
        if self._realtime:
            now = self._clock()
            if self._start is None:
                self._start = now
            due = self._t[0] + (now - self._start)
            stop = min(stop, int(np.searchsorted(self._t, due, side="right")))
        chunk = SignalChunk(self._t[self._i:stop].copy(), self._v[self._i:stop].copy(), "ok")
        self._i = max(self._i, stop)
        self.stats.samples += len(chunk)
        self.stats.packets += 1
        return chunk

    def close(self) -> None:
        self._i = self._t.shape[0]
