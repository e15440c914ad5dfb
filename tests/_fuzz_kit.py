"""The machinery of the fuzz targets (``tests/fuzz_targets.py``): what an input is, how seeds are
mutated, and the rule every call is held to.

An input is a :class:`Case`: one or more named files (a toolpath, a ``.src`` with its ``.dat``, a
``plan.json`` with its ``samples.npz``, a packet, a stream of datagrams) and the options the calls
take. :func:`cases` turns seed cases into a hypothesis strategy of mutated ones: byte, token, number,
line and chunk edits, splices with other seeds, structured value edits, edits of the set of files,
and format-aware generators where they are cheap (:class:`Dialect`, one per file suffix).

The rule (:func:`run_calls`): each call returns a result that keeps its promises or raises one of
its documented errors, within :data:`LIMIT_S` seconds and without raising the process's peak
resident memory by more than :data:`LIMIT_MB` (per call: on Linux the high-water mark is reset
before each one). Anything else is a failure of the call.
"""

from __future__ import annotations

import functools
import hashlib
import io
import json
import math
import re
import resource
import shutil
import signal
import struct
import sys
import threading
import time
import traceback
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from hypothesis import strategies as st

__all__ = [
    "EDGE_NUMBERS",
    "FAILING",
    "HANG_S",
    "LIMIT_MB",
    "LIMIT_S",
    "BadResult",
    "Call",
    "CallOutcome",
    "Case",
    "Dialect",
    "Hang",
    "Verdict",
    "cases",
    "json_values",
    "npz_bytes",
    "numbers",
    "peak_rss_mb",
    "render_json",
    "render_toml",
    "run_calls",
    "shape_of",
]

#: Most one call may take [s].
LIMIT_S = 2.0
#: Most one call may raise the process's peak resident memory (RSS high-water mark) [MB].
LIMIT_MB = 500.0
#: A call still running after this long is interrupted (SIGALRM) and counted as slow [s].
HANG_S = 30.0

#: Numbers that parsers get wrong: huge, tiny, signed zero, non-finite spellings, too many digits,
#: integers past 32/64 bits, Python-only spellings (``1_000``, non-ASCII digits), broken forms.
EDGE_NUMBERS: tuple[bytes, ...] = (
    b"0", b"-0", b"1", b"-1", b"0.5", b".5", b"5.", b"-.5", b"1e308", b"-1e308", b"1e309", b"1e-320",
    b"9" * 400, b"1" + b"0" * 40, b"nan", b"NaN", b"inf", b"-inf", b"Infinity", b"1e+9999", b"1E5",
    b"4294967296", b"18446744073709551616", b"-2147483649", b"65535", b"65536", b"1_000", b"0x1F",
    b"1.2.3", b"1e", b"-", b"+", b".", b"--1", b"+-1", b"1e-", b"\xd9\xa1\xd9\xa2", b"\xef\xbc\x91",
    b"1\xc2\xa0", b"3.4028236e38", b"2.5e-324",
)
_NUMBER = re.compile(rb"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")
_ASSIGN = re.compile(rb'^(\s*"?[A-Za-z_$][\w.$-]*"?\s*[=:]\s*)(.+?)(,?)(\r?)$', re.M)


def numbers() -> st.SearchStrategy[bytes]:
    """Numbers as text: edges, ordinary integers and decimals, any float's repr."""
    return st.one_of(
        st.sampled_from(EDGE_NUMBERS),
        st.integers(-10**6, 10**6).map(lambda i: str(i).encode()),
        st.floats(-2000, 2000, allow_nan=False).map(lambda x: f"{x:.4f}".encode()),
        st.floats().map(lambda x: repr(x).encode()),
    )


# -- cases -------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Case:
    """One input: named files (the first is the main one) and the options of the calls."""

    files: Mapping[str, bytes]
    options: Mapping[str, Any] = field(default_factory=dict)

    @property
    def size(self) -> int:
        return sum(len(v) for v in self.files.values())

    def __repr__(self) -> str:   # what hypothesis prints: names and sizes, not 100 kB of bytes
        files = ", ".join(f"{n} ({len(d)} B)" for n, d in self.files.items())
        return f"Case({files}; options {dict(self.options)}; digest {self.digest()})"

    def _repr_pretty_(self, printer: Any, cycle: bool) -> None:   # hypothesis's pretty printer
        printer.text(repr(self))

    def digest(self) -> str:
        h = hashlib.sha1(json.dumps(dict(self.options), sort_keys=True, default=repr).encode())
        for name, data in self.files.items():
            h.update(name.encode() + b"\0" + str(len(data)).encode() + b"\0" + data)
        return h.hexdigest()[:16]

    def write(self, folder: Path) -> dict[str, Path]:
        """Empty ``folder`` (it must hold only a case's files) and write the files into it."""
        if folder.exists():
            shutil.rmtree(folder)
        folder.mkdir(parents=True)
        out = {}
        for name, data in self.files.items():
            out[name] = folder / name
            out[name].write_bytes(data)
        return out

    def save(self, folder: Path) -> None:
        """Write the case to be read back by :meth:`load` (files + ``case.json``)."""
        self.write(folder)
        meta = {"files": list(self.files), "options": dict(self.options)}
        (folder / "case.json").write_text(json.dumps(meta, indent=1, default=repr) + "\n")

    @classmethod
    def load(cls, folder: Path) -> Case:
        meta = json.loads((folder / "case.json").read_text())
        return cls({n: (folder / n).read_bytes() for n in meta["files"]}, meta.get("options", {}))


# -- mutation ------------------------------------------------------------------------------------------

Draw = Callable[[st.SearchStrategy[Any]], Any]
#: An edit of one file's bytes: ``op(draw, data, context) -> data``.
Op = Callable[[Draw, bytes, "_Context"], bytes]


@dataclass(frozen=True)
class Dialect:
    """How the files of one suffix are mutated.

    Attributes:
        text: line-oriented text (line edits, windows of big files) or binary (field edits).
        alphabet: the bytes that matter to the grammar (single-byte edits draw from it).
        tokens: words, delimiters and odd spellings dropped in or swapped in.
        lines: a generator of one grammatical line (or record), inserted by a line edit.
        ops: further edits special to the format (e.g. a structured edit of ``samples.npz``).
        values: rendered values for "replace the value of a ``key = value`` line" edits.
        weight: how often a file of this dialect is the one edited (relative).
        head_lines, window_lines: a big file is mostly cut to its first ``head_lines`` (units,
            modes), a window of up to ``window_lines`` lines somewhere and its last lines.
        max_bytes: an edited file is cut to this size.
    """

    text: bool = True
    alphabet: bytes = b""
    tokens: tuple[bytes, ...] = ()
    lines: st.SearchStrategy[bytes] | None = None
    ops: tuple[Op, ...] = ()
    values: st.SearchStrategy[bytes] | None = None
    weight: int = 1
    head_lines: int = 25
    window_lines: int = 250
    max_bytes: int = 256 * 1024


@dataclass(frozen=True)
class _Context:
    dialect: Dialect
    others: tuple[bytes, ...]       # the same suffix's files of every seed (splices, lines)


def _pos(draw: Draw, data: bytes) -> int:
    return draw(st.integers(0, len(data)))


def _op_byte(draw: Draw, data: bytes, ctx: _Context) -> bytes:
    pool = ctx.dialect.alphabet or bytes(range(256))
    b = bytes([draw(st.sampled_from(pool)) if draw(st.integers(0, 4)) else draw(st.integers(0, 255))])
    i = _pos(draw, data)
    how = draw(st.integers(0, 2))
    if how == 0:
        return data[:i] + b + data[i + 1:]
    if how == 1:
        return data[:i] + b + data[i:]
    return data[:i] + data[i + 1:]


def _op_token(draw: Draw, data: bytes, ctx: _Context) -> bytes:
    tok = draw(st.sampled_from(ctx.dialect.tokens or EDGE_NUMBERS))
    i = _pos(draw, data)
    if draw(st.booleans()):
        return data[:i] + tok + data[i:]
    return data[:i] + tok + data[i + len(tok):]


def _op_number(draw: Draw, data: bytes, ctx: _Context) -> bytes:
    found = list(_NUMBER.finditer(data))
    if not found:
        return _op_token(draw, data, ctx)
    m = found[draw(st.integers(0, len(found) - 1))]
    return data[:m.start()] + draw(numbers()) + data[m.end():]


def _op_value(draw: Draw, data: bytes, ctx: _Context) -> bytes:
    """The value of one ``key = value`` (TOML) or ``"key": value`` (JSON) line replaced."""
    found = list(_ASSIGN.finditer(data)) if ctx.dialect.values is not None else []
    if not found:
        return _op_number(draw, data, ctx)
    m = found[draw(st.integers(0, len(found) - 1))]
    return data[:m.start(2)] + draw(ctx.dialect.values) + data[m.end(2):]


def _lines_op(draw: Draw, data: bytes, ctx: _Context) -> bytes:
    lines = data.split(b"\n")
    i = draw(st.integers(0, len(lines) - 1))
    how = draw(st.integers(0, 5))
    if how == 0:
        del lines[i]
    elif how == 1:
        lines[i:i + 1] = [lines[i]] * draw(st.sampled_from([2, 3, 10, 200]))
    elif how == 2:
        j = draw(st.integers(0, len(lines) - 1))
        lines[i], lines[j] = lines[j], lines[i]
    elif how == 3:
        other = draw(st.sampled_from(ctx.others)).split(b"\n")
        lines.insert(i, other[draw(st.integers(0, len(other) - 1))])
    elif how == 4 and ctx.dialect.lines is not None:
        lines.insert(i, draw(ctx.dialect.lines))
    else:
        lines.insert(i, b" ".join(draw(st.lists(st.sampled_from(ctx.dialect.tokens or EDGE_NUMBERS),
                                                min_size=1, max_size=6))))
    return b"\n".join(lines)


def _op_chunk(draw: Draw, data: bytes, ctx: _Context) -> bytes:
    i = _pos(draw, data)
    j = min(len(data), i + draw(st.integers(1, 64)))
    if draw(st.booleans()):
        return data[:i] + data[j:]
    return data[:i] + data[i:j] * draw(st.sampled_from([2, 3, 16, 500])) + data[j:]


def _op_splice(draw: Draw, data: bytes, ctx: _Context) -> bytes:
    other = draw(st.sampled_from(ctx.others))
    if ctx.dialect.text:   # a window of a big file, not all of it
        other = _window(draw, other, ctx.dialect)
    return data[:_pos(draw, data)] + other[_pos(draw, other):]


def _op_newlines(draw: Draw, data: bytes, ctx: _Context) -> bytes:
    how = draw(st.integers(0, 5))
    if how == 0:
        return data.replace(b"\r\n", b"\n").replace(b"\n", b"\r\n")
    if how == 1:
        return data.replace(b"\r\n", b"\n").replace(b"\n", b"\r")
    if how == 2:
        return data.rstrip(b"\r\n")
    if how == 3:
        return b"\xef\xbb\xbf" + data                    # UTF-8 byte order mark
    if how == 4:
        return data.decode("utf-8", "replace").encode("utf-16")
    i = _pos(draw, data)
    return data[:i] + draw(st.sampled_from([b"\x00", b"\xe9", b"\xff", b"\xc3", b"\t", b"\x1a"])) + data[i:]


def _op_field(draw: Draw, data: bytes, ctx: _Context) -> bytes:
    """A 1/2/4/8-byte field overwritten with an edge integer or float, either byte order."""
    fmt = draw(st.sampled_from(["B", ">H", "<H", ">I", "<I", "<Q", "<f", "<d", ">d"]))
    size = struct.calcsize(fmt)
    i = draw(st.integers(0, max(0, len(data) - size)))
    if fmt[-1] in "fd":
        v = draw(st.sampled_from([0.0, -0.0, 1.0, -1.0, math.inf, -math.inf, math.nan, 1e-310, 1e308,
                                  3.4e38, 1e-45, 1e9, 2.0**32]))
        if fmt == "<f" and math.isfinite(v) and abs(v) > 3.4e38:
            v = math.inf                                   # past float32: its infinity
        raw = struct.pack(fmt, v)
    else:
        top = 2 ** (8 * size) - 1
        v = draw(st.sampled_from(sorted({0, 1, 2, 3, 4, 7, 10, 22, 100, 255, 256, 4095, 4096, 4097,
                                         0x7FFF, 0x8000, 0xFFFF, 0x10000, 2**31 - 1, 2**31, 2**32 - 1,
                                         len(data), len(data) - 4, len(data) - 7, len(data) + 1})))
        raw = struct.pack(fmt, min(max(v, 0), top))
    return data[:i] + raw + data[i + size:]


def _op_resize(draw: Draw, data: bytes, ctx: _Context) -> bytes:
    if draw(st.booleans()):
        return data[:_pos(draw, data)]
    return data + draw(st.binary(min_size=1, max_size=64))


def _op_prefix(draw: Draw, data: bytes, ctx: _Context) -> bytes:
    tok = draw(st.sampled_from(ctx.dialect.tokens or (b"\x00",)))
    return tok + data[len(tok):] if draw(st.booleans()) else tok + data


_TEXT_OPS: tuple[Op, ...] = (_op_byte, _op_token, _op_number, _op_value, _lines_op, _lines_op,
                             _op_chunk, _op_splice, _op_newlines)
_BINARY_OPS: tuple[Op, ...] = (_op_byte, _op_byte, _op_field, _op_field, _op_chunk, _op_splice,
                               _op_resize, _op_prefix, _op_token)


def _window(draw: Draw, data: bytes, d: Dialect) -> bytes:
    lines = data.split(b"\n")
    n = len(lines)
    if n <= d.head_lines + d.window_lines + 3:
        return data
    start = draw(st.integers(d.head_lines, n - 3))
    stop = min(n - 3, start + draw(st.integers(1, d.window_lines)))
    return b"\n".join(lines[:d.head_lines] + lines[start:stop] + lines[-3:])


def _dialect(dialects: Mapping[str, Dialect], name: str) -> Dialect:
    suffix = Path(name).suffix.lower()
    return dialects.get(suffix) or dialects.get("*") or Dialect()


@st.composite
def _mutated(draw: Draw, seeds: tuple[Case, ...], dialects: Mapping[str, Dialect],
             others: Mapping[str, tuple[bytes, ...]], options: st.SearchStrategy[dict[str, Any]],
             whole: bool, files_edits: str) -> Case:
    base = draw(st.sampled_from(seeds))
    files = dict(base.files)
    names = [n for n in files for _ in range(_dialect(dialects, n).weight)]
    for _ in range(draw(st.integers(1, 2)) if len(files) > 1 else 1):
        name = draw(st.sampled_from(names))
        d = _dialect(dialects, name)
        data = files[name]
        if d.text and not (whole and draw(st.integers(0, 49)) == 49):   # 0 is what hypothesis tries first
            data = _window(draw, data, d)
        ctx = _Context(d, others.get(Path(name).suffix.lower()) or (data,))
        ops = (_TEXT_OPS if d.text else _BINARY_OPS) + d.ops
        for _ in range(draw(st.integers(0, 6))):
            data = draw(st.sampled_from(ops))(draw, data, ctx)[:d.max_bytes]
        files[name] = data
    if files_edits and len(files) > 1 and draw(st.integers(0, 3)) == 0:
        files = _edit_files(draw, files, files_edits)
    return Case(files, draw(options))


def _edit_files(draw: Draw, files: dict[str, bytes], how: str) -> dict[str, bytes]:
    """Drop, repeat or reorder files (``how="stream"``: datagrams, renumbered), or drop a
    companion file and change the case of a name (``how="companions"``: the first file stays)."""
    items = list(files.items())
    if how == "stream":
        for _ in range(draw(st.integers(1, 4))):
            i = draw(st.integers(0, len(items) - 1))
            j = draw(st.integers(0, len(items)))
            edit = draw(st.integers(0, 2))
            if edit == 0 and len(items) > 1:
                del items[i]
            elif edit == 1:
                items.insert(j, items[i])
            else:
                items.insert(j, items.pop(i))
        return {f"{k:03d}.bin": v for k, (_, v) in enumerate(items)}
    i = draw(st.integers(1, len(items) - 1))
    if draw(st.booleans()):
        del items[i]
    else:
        name, data = items[i]
        items[i] = (draw(st.sampled_from([name.upper(), name.lower(), name.swapcase()])), data)
    return dict(items)


def cases(seeds: Sequence[Case], dialects: Mapping[str, Dialect],
          options: st.SearchStrategy[dict[str, Any]] | None = None,
          generated: st.SearchStrategy[Case] | None = None, whole: bool = True,
          files_edits: str = "") -> st.SearchStrategy[Case]:
    """Mutated seeds (and, a quarter of the time, ``generated`` cases).

    Args:
        seeds: the cases to start from (at least one).
        dialects: by file suffix (``"*"``: any other).
        options: the calls' options, drawn for every case (default: none).
        generated: format-aware generated cases, if any.
        whole: a big text file is edited whole one time in fifty (else always in a window).
        files_edits: ``"stream"`` or ``"companions"`` to edit the set of files too.
    """
    if not seeds:
        raise ValueError("no seeds")
    others: dict[str, tuple[bytes, ...]] = {}
    for seed in seeds:
        for name, data in seed.files.items():
            suffix = Path(name).suffix.lower()
            others[suffix] = (*others.get(suffix, ()), data)
    mutated = _mutated(tuple(seeds), dialects, others, st.just({}) if options is None else options,
                       whole, files_edits)
    return mutated if generated is None else st.one_of(mutated, mutated, mutated, generated)


# -- structured values -------------------------------------------------------------------------------

_EDGE_VALUES: list[Any] = [None, True, False, 0, -1, 1.5, 1e308, -1e308, math.inf, -math.inf, math.nan,
                           10**400, 2**63, -(2**63) - 1, "", "3", "fixed", "zmap", "free", "cut", [], {},
                           [1, 2, 3], [0.0] * 6, {"a": 1}, [[[[[[]]]]]]]


def json_values() -> st.SearchStrategy[Any]:
    """JSON/TOML-ish values with the edges that crash readers."""
    return st.recursive(
        st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=8)
        | st.sampled_from(_EDGE_VALUES),
        lambda inner: st.lists(inner, max_size=7) | st.dictionaries(st.text(max_size=6), inner, max_size=4),
        max_leaves=12)


def render_json(v: Any) -> bytes:
    return json.dumps(v, allow_nan=True).encode()


def render_toml(v: Any) -> bytes:
    """A TOML spelling of ``v`` (``None`` becomes the invalid ``null``: a parse error too)."""
    if v is None:
        return b"null"
    if isinstance(v, bool):
        return b"true" if v else b"false"
    if isinstance(v, int):
        return str(v).encode()
    if isinstance(v, float):
        return (b"nan" if math.isnan(v) else b"inf" if v == math.inf else b"-inf" if v == -math.inf
                else repr(v).encode())
    if isinstance(v, str):
        return json.dumps(v).encode()
    if isinstance(v, list):
        return b"[" + b", ".join(render_toml(x) for x in v) + b"]"
    return (b"{" + b", ".join(render_json(str(k)) + b" = " + render_toml(x) for k, x in v.items())
            + b"}")


# -- the rule ------------------------------------------------------------------------------------------

class BadResult(Exception):
    """A call returned, but its result breaks what the call promises (e.g. a toolpath of infinite
    length, timestamps that go back)."""


class Hang(BaseException):
    """Raised by the alarm in a call that runs past :data:`HANG_S` (a BaseException, so that a
    parser's ``except Exception`` does not swallow it)."""


@dataclass(frozen=True)
class Call:
    """One call of an input.

    Attributes:
        label: its name in reports (``"strict"``, ``"parse_rob"`` …).
        fn: takes the value of the call before (None for the first) and returns ``(signature,
            value)``: a short description of the result's shape (for the corpus) and the value
            a later call may use. It raises :class:`BadResult` for a broken promise.
        documented: the exceptions the call may raise.
        error_ok: says what is wrong with a documented error (``None``: nothing), e.g. a
            toolpath error that does not name the file.
        needs_previous: run only when the call before returned a result.
    """

    label: str
    fn: Callable[[Any], tuple[str, Any]]
    documented: tuple[type[BaseException], ...] = ()
    error_ok: Callable[[BaseException], str | None] | None = None
    needs_previous: bool = False


@dataclass(frozen=True)
class CallOutcome:
    """What one call did. ``status``: ``"result"``, ``"error"`` (documented), ``"undocumented"``,
    ``"bad"`` (a broken result or a malformed documented error), ``"slow"`` (interrupted),
    ``"memory"`` (MemoryError) or ``"skipped"``."""

    label: str
    status: str
    signature: str
    seconds: float
    rss_mb: float
    detail: str = ""


#: The statuses that break the rule by themselves (slow and memory also by the measured bounds).
FAILING = ("undocumented", "bad", "slow", "memory")


@dataclass(frozen=True)
class Verdict:
    """The outcomes of one input's calls."""

    calls: tuple[CallOutcome, ...]

    @property
    def seconds(self) -> float:
        return max((c.seconds for c in self.calls), default=0.0)

    @property
    def rss_mb(self) -> float:
        return max((c.rss_mb for c in self.calls), default=0.0)

    @property
    def signature(self) -> str:
        return " | ".join(f"{c.label}: {c.signature}" for c in self.calls)

    def kinds(self) -> set[str]:
        """Which parts of the rule the input breaks: ``undocumented``, ``bad``, ``slow``, ``memory``."""
        out = {c.status for c in self.calls if c.status in ("undocumented", "bad")}
        if any(c.seconds > LIMIT_S or c.status == "slow" for c in self.calls):
            out.add("slow")
        if any(c.rss_mb > LIMIT_MB or c.status == "memory" for c in self.calls):
            out.add("memory")
        return out

    def report(self) -> str:
        rows = [f"{c.label}: {c.status} in {c.seconds:.3f} s, +{c.rss_mb:.0f} MB peak RSS: {c.signature}"
                + (f"\n{c.detail}" if c.detail else "") for c in self.calls]
        return "\n".join(rows)


def peak_rss_mb() -> float:
    """The process's resident memory high-water mark [MB] (Linux reports KiB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def _status_mb(*keys: bytes) -> list[float]:
    with open("/proc/self/status", "rb") as f:
        found = {line.split(b":")[0]: float(line.split()[1]) / 1024.0 for line in f
                 if line.startswith(keys)}
    return [found[k] for k in keys]


class _Memory:
    """How much one call raises the peak resident memory above what the process held before it
    [MB]. On Linux the high-water mark is reset before each call (``/proc/self/clear_refs``), so
    the growth is the call's own even after an earlier input set a higher peak; elsewhere it is
    the growth of ``getrusage``'s lifetime peak."""

    def __init__(self) -> None:
        try:
            with open("/proc/self/clear_refs", "w") as f:
                f.write("5")
            _status_mb(b"VmHWM", b"VmRSS")
            self.exact = True
        except (OSError, KeyError, ValueError, IndexError):
            self.exact = False

    def start(self) -> float:
        if not self.exact:
            return peak_rss_mb()
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")   # VmHWM := VmRSS
        return _status_mb(b"VmRSS")[0]

    def growth(self, start: float) -> float:
        return (_status_mb(b"VmHWM")[0] if self.exact else peak_rss_mb()) - start


@functools.cache
def _memory() -> _Memory:
    return _Memory()


def shape_of(text: str, limit: int = 90) -> str:
    """A message with its paths, numbers and quoted parts blanked: the same kind of problem reads the
    same."""
    s = re.sub(r"(?<![\w.])/[^\s:'\"]+", "<path>", text)
    s = re.sub(r"'[^']*'|\"[^\"]*\"", "'…'", s)
    s = re.sub(r"\d+(\.\d+)?(e[-+]?\d+)?", "#", s)
    return s[:limit]


class _Alarm:
    """SIGALRM after ``seconds`` raising :class:`Hang` (main thread only; else a no-op)."""

    def __init__(self, seconds: float) -> None:
        self.seconds = seconds
        self.armed = seconds > 0 and threading.current_thread() is threading.main_thread()

    def _fire(self, signum: int, frame: Any) -> None:
        raise Hang(f"interrupted after {self.seconds:g} s")

    def __enter__(self) -> _Alarm:
        if self.armed:
            self._old = signal.signal(signal.SIGALRM, self._fire)
            signal.setitimer(signal.ITIMER_REAL, self.seconds)
        return self

    def __exit__(self, *exc: object) -> None:
        if self.armed:
            signal.setitimer(signal.ITIMER_REAL, 0)
            signal.signal(signal.SIGALRM, self._old)


def _one(call: Call, previous: Any, hang_s: float) -> tuple[CallOutcome, Any]:
    memory = _memory()
    rss0 = memory.start()
    t0 = time.perf_counter()
    value = None
    unraisable: list[str] = []      # e.g. a file left open by the call (a ResourceWarning in __del__)
    hook = sys.unraisablehook
    sys.unraisablehook = lambda u: unraisable.append(f"{type(u.exc_value).__name__}: {u.exc_value}")
    try:
        try:
            with _Alarm(hang_s):
                signature, value = call.fn(previous)
            status, detail = "result", ""
        except Hang as e:
            status, signature, detail = "slow", str(e), _where(e)
        except MemoryError as e:
            status, signature, detail = "memory", "MemoryError", _where(e)
        except BadResult as e:
            status, signature, detail = "bad", f"broken result: {e}", _where(e)
        except call.documented as e:
            problem = call.error_ok(e) if call.error_ok is not None else None
            if problem is None:
                status, signature, detail = "error", f"{type(e).__name__}: {shape_of(str(e))}", ""
            else:
                status, signature, detail = "bad", f"malformed {type(e).__name__}: {problem}", str(e)[:500]
        except Exception as e:   # the rule's point: anything else is a finding, recorded, not raised
            status, signature, detail = ("undocumented", f"{type(e).__name__}: {shape_of(str(e))}",
                                         _where(e))
    finally:                     # the exception and its frames are gone by now: what they held too
        sys.unraisablehook = hook
    seconds = time.perf_counter() - t0
    if unraisable and status in ("result", "error"):
        status, signature = "undocumented", f"unraisable {shape_of(unraisable[0])}"
        detail = "\n".join(unraisable)
    return CallOutcome(call.label, status, signature, seconds, memory.growth(rss0), detail), value


def _where(e: BaseException) -> str:
    return "".join(traceback.format_exception(type(e), e, e.__traceback__, limit=-12))


def run_calls(calls: Sequence[Call], hang_s: float = HANG_S) -> Verdict:
    """Run an input's calls in order and judge each (see the module docstring)."""
    out: list[CallOutcome] = []
    previous: Any = None
    last_ok = True
    for call in calls:
        if call.needs_previous and not last_ok:
            out.append(CallOutcome(call.label, "skipped", "-", 0.0, 0.0))
            continue
        outcome, value = _one(call, previous, hang_s)
        out.append(outcome)
        previous, last_ok = value, outcome.status == "result"
    return Verdict(tuple(out))


def npz_bytes(arrays: Mapping[str, np.ndarray], compressed: bool = True) -> bytes:
    """``arrays`` as the bytes of an ``.npz`` file."""
    buf = io.BytesIO()
    (np.savez_compressed if compressed else np.savez)(buf, **arrays)
    return buf.getvalue()
