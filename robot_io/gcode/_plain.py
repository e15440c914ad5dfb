"""Plain G-code lines in bulk (private): the fast path of :mod:`robot_io.gcode._interp`.

Most lines a 3-axis CAM post writes are *plain*: ``N123 X1.5 Y-2. F300``, ``G1X2.249Y0.1258``.
:func:`scan_plain_lines` classifies every line of the program at once with numpy (a few passes
of byte tests over the whole text, no Python per line) and reads the numbers of the plain ones
with one ``np.fromstring`` call; :func:`execute_plain` then executes a run of consecutive plain
lines as array operations (the modal motion, feed and each axis are forward-filled) and hands its
moves to the store in one block. Short programs (< :data:`MIN_RUN` lines), programs read with a
rotary kinematics, and programs whose runs of at least :data:`MIN_RUN` plain lines cover less
than :data:`MIN_SHARE` of the lines are not scanned at all.

A line is plain when, upper-cased, it consists of words ``N``, ``G``, ``X``, ``Y``, ``Z``, ``F``
(each a letter, optional blanks, one number in the reader's format — sign, digits, at most one
point, at least one digit, at most :data:`MAX_NUMBER_CHARS` characters) separated by spaces or
tabs, with a trailing CR at most, where no letter but N occurs twice, every G is ``G0`` or ``G1``
written with digits only, every value is at most ``MAX_WORD_VALUE`` in size and every F is
positive. Anything else — comments, other words (``O`` among them), parameters ``#`` and
expressions ``[…]`` (their bytes are not in the scan's classes), anything malformed — makes the
line not plain, and the interpreter reads it as before. Being plain is only a promise about the text:
:func:`execute_plain` also requires a modal state it can reproduce exactly (absolute G90, G94,
no rotary kinematics or rotary words so far, G0/G1 in force, the position known) and stops at
the first feed move without a feed rate, leaving that line to the interpreter and its error
message. So the interpreter stays the single definition of what a program means; the bulk path
gives the same floats because it does the same IEEE operations (``float`` and ``fromstring``
both round correctly; ``v · scale`` and ``F · scale / 60`` in the same order).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from robot_io.gcode import _words as W
from robot_io.gcode._moves import START_PREVIOUS, START_UNKNOWN

if TYPE_CHECKING:
    from robot_io.gcode._interp import _Run

__all__ = ["MAX_NUMBER_CHARS", "MIN_RUN", "MIN_SHARE", "PlainLines", "execute_plain", "plain_spans",
           "scan_plain_lines"]

#: Longest number (characters, sign and point included) the scan reads; longer ones are left to
#: the interpreter (which also checks ``MAX_WORD_VALUE`` for them).
MAX_NUMBER_CHARS = 17
#: Shortest run of plain lines executed in bulk: below it the fixed cost of the array operations
#: (~40 µs a run) exceeds what the interpreter needs for the lines (~3 µs a plain line); measured
#: break-even at about 16 lines.
MIN_RUN = 16

#: Smallest share of a program's lines in such runs for the numbers to be read in bulk at all:
#: below it (a program of arcs or 5-axis words with the odd plain stretch) the scan would cost
#: more than it saves.
MIN_SHARE = 0.1

# byte classes
_BAD, _DIGIT, _DOT, _SIGN, _BLANK, _LETTER, _CR, _NL = range(8)
_CLASS = np.zeros(256, np.uint8)
_CLASS[np.frombuffer(b"0123456789", np.uint8)] = _DIGIT
_CLASS[ord(".")] = _DOT
_CLASS[[ord("+"), ord("-")]] = _SIGN
_CLASS[[ord(" "), ord("\t")]] = _BLANK
_CLASS[np.frombuffer(b"NGXYZFngxyzf", np.uint8)] = _LETTER
_CLASS[ord("\r")] = _CR
_CLASS[ord("\n")] = _NL
#: per-byte weights whose sums over a number give its digit, point and sign counts at once
_COUNT_W = np.zeros(256, np.uint16)
_COUNT_W[np.frombuffer(b"0123456789", np.uint8)] = 1024
_COUNT_W[ord(".")] = 32
_COUNT_W[[ord("+"), ord("-")]] = 1
_UPPER = 0xDF   # ASCII letter & 0xDF → upper case


@dataclass
class PlainLines:
    """Per-line result of the scan (index = line number - 1); values in program units.

    Attributes:
        ok: the line is plain, shape (L,).
        x, y, z, f: the X/Y/Z/F word, NaN where absent, shape (L,).
        g: 0.0 for G0, 1.0 for G1, NaN where absent, shape (L,).
        col0: column of the first X/Y/Z word (1-based), 0 where none, shape (L,).
        has_axis: the line has an X, Y or Z word, shape (L,).
        nonblank: the line has a word, shape (L,).
    """

    ok: np.ndarray
    x: np.ndarray
    y: np.ndarray
    z: np.ndarray
    f: np.ndarray
    g: np.ndarray
    col0: np.ndarray
    has_axis: np.ndarray
    nonblank: np.ndarray


def scan_plain_lines(text: str, n_lines: int, min_run: int = MIN_RUN) -> PlainLines | None:
    """Classify and read the lines of ``text`` (split at ``"\\n"`` into ``n_lines`` lines);
    ``None`` when there is no run of ``min_run`` plain lines (the numbers are then not read)."""
    # one byte per character (columns stay right), and a final newline so that every line ends
    # in one
    b = np.frombuffer(text.encode("ascii", "replace") + b"\n", np.uint8)
    cls = _CLASS[b]
    nl = np.flatnonzero(cls == _NL)
    if nl.size != n_lines:
        return None
    line_start = np.empty(n_lines, np.int64)
    line_start[0] = 0
    line_start[1:] = nl[:-1] + 1
    # a line is spoilt by a byte the scan does not read, or by a position found below
    ok = ~np.logical_or.reduceat(cls == _BAD, line_start)
    bad_at: list[np.ndarray] = []       # byte positions
    cr = np.flatnonzero(cls == _CR)
    bad_at.append(cr[b[cr + 1] != 10])   # CR only at the end of a line
    # numbers: maximal runs of digits, points and signs
    is_num = (cls - np.uint8(_DIGIT)) < 3                      # DIGIT, DOT, SIGN (uint8 wraps)
    starts_num = np.empty_like(is_num)
    starts_num[0] = is_num[0]
    np.greater(is_num[1:], is_num[:-1], out=starts_num[1:])
    ends_num = np.empty_like(is_num)
    ends_num[-1] = is_num[-1]
    np.greater(is_num[:-1], is_num[1:], out=ends_num[:-1])
    num_start = np.flatnonzero(starts_num)
    if num_start.size == 0:
        return None
    run_len = np.flatnonzero(ends_num) - num_start + 1
    # digit, point and sign counts of each number in one sum (bytes between numbers weigh 0);
    # the uint16 fields are exact for runs up to MAX_NUMBER_CHARS long, longer ones are
    # rejected on their length alone
    run_sum = np.add.reduceat(_COUNT_W[b], num_start)
    n_digits, n_points, n_signs = run_sum >> 10, (run_sum >> 5) & 31, run_sum & 31
    good_run = ((run_len <= MAX_NUMBER_CHARS) & (n_digits >= 1) & (n_points <= 1)
                & (n_signs == (cls[num_start] == _SIGN)))
    bad_at.append(num_start[~good_run])
    # tokens: a letter or the start of a number (newlines only count the lines); a line must
    # read letter, number, letter, ..., number
    is_letter = cls == _LETTER
    tok_mask = is_letter | starts_num
    tok_mask[nl] = True
    tok = np.flatnonzero(tok_mask)
    tok_cls = cls[tok]
    tok_nl = tok_cls == _NL
    tok_line = np.cumsum(tok_nl)
    word_tok = ~tok_nl
    tok, tok_line, tok_letter = tok[word_tok], tok_line[word_tok], tok_cls[word_tok] == _LETTER
    same = tok_line[1:] == tok_line[:-1]
    bad_lines = [tok_line[1:][same & (tok_letter[1:] == tok_letter[:-1])]]
    first = np.concatenate(([True], ~same))
    last = np.concatenate((~same, [True]))
    bad_lines.append(tok_line[(first & ~tok_letter) | (last & tok_letter)])
    ok[np.searchsorted(nl, np.concatenate(bad_at))] = False
    ok[np.concatenate(bad_lines)] = False
    if not _has_run(ok, min_run):   # not worth reading the numbers
        return None
    # the numbers: blank out everything else (bad numbers become "0" to keep the count)
    keep = np.where(is_num, b, np.uint8(32))
    if not good_run.all():
        drop = np.zeros(b.size + 1, np.int8)  # runs are disjoint: +1 at a start, -1 past its end
        drop[num_start[~good_run]] = 1
        drop[(num_start + run_len)[~good_run]] = -1
        keep[np.cumsum(drop[:-1]).astype(bool)] = 32
        keep[num_start[~good_run]] = ord("0")
    values = np.fromstring(keep.tobytes(), dtype=float, sep=" ")
    if values.size != num_start.size:
        return None
    # words: each letter with the number token after it (lines where that fails are bad above)
    wi = np.flatnonzero(tok_letter)
    num_index = np.cumsum(~tok_letter) - 1                      # token → number index
    wnum = num_index[np.minimum(wi + 1, tok.size - 1)]
    wpos = tok[wi]
    wletter = b[wpos] & _UPPER
    wline = tok_line[wi]
    wval = values[wnum]
    wcol = wpos - line_start[wline] + 1
    out: dict[str, np.ndarray] = {}
    for ch in "XYZFG":
        sel = np.flatnonzero(wletter == ord(ch))
        lines = wline[sel]
        v = wval[sel]
        bad_lines.append(lines[1:][lines[1:] == lines[:-1]])    # a second X (… G) on a line
        if ch == "G":
            num = wnum[sel]
            bad_lines.append(lines[~(((v == 0.0) | (v == 1.0)) & (n_points[num] == 0)
                                     & (n_signs[num] == 0) & (run_len[num] <= 3))])
        else:
            bad_lines.append(lines[~(np.abs(v) <= W.MAX_WORD_VALUE)])
            if ch == "F":
                bad_lines.append(lines[~(v > 0.0)])
        col = np.full(n_lines, math.nan)
        col[lines] = v
        out[ch] = col
    axis = np.flatnonzero((wletter == ord("X")) | (wletter == ord("Y")) | (wletter == ord("Z")))
    axis_line = wline[axis]
    starts_line = np.ones(axis.size, bool)
    starts_line[1:] = axis_line[1:] != axis_line[:-1]
    first_axis = axis[starts_line]
    col0 = np.zeros(n_lines, np.int64)
    col0[wline[first_axis]] = wcol[first_axis]
    has_axis = np.zeros(n_lines, bool)
    has_axis[axis_line] = True
    nonblank = np.zeros(n_lines, bool)
    nonblank[tok_line] = True
    ok[np.concatenate(bad_lines)] = False
    if not _has_run(ok, min_run):
        return None
    return PlainLines(ok=ok, x=out["X"], y=out["Y"], z=out["Z"], f=out["F"], g=out["G"],
                      col0=col0, has_axis=has_axis, nonblank=nonblank)


def _runs(ok: np.ndarray, min_run: int) -> tuple[np.ndarray, np.ndarray]:
    edges = np.diff(np.concatenate(([0], ok.view(np.int8), [0])))
    starts = np.flatnonzero(edges == 1)
    stops = np.flatnonzero(edges == -1)
    long = stops - starts >= min_run
    return starts[long], stops[long]


def _has_run(ok: np.ndarray, min_run: int) -> bool:
    """Worth the bulk path: runs of ``min_run`` lines cover :data:`MIN_SHARE` of the lines."""
    starts, stops = _runs(ok, min_run)
    return int((stops - starts).sum()) >= MIN_SHARE * ok.size and starts.size > 0


def plain_spans(scan: PlainLines, min_run: int = MIN_RUN) -> list[tuple[int, int]]:
    """Runs ``[a, b)`` of at least ``min_run`` consecutive plain lines (0-based line indices)."""
    starts, stops = _runs(scan.ok, min_run)
    return list(zip(starts.tolist(), stops.tolist(), strict=True))


def _ffill(v: np.ndarray, initial: float) -> np.ndarray:
    """``v`` with every NaN replaced by the last value before it (``initial`` at the start)."""
    idx = np.where(np.isnan(v), -1, np.arange(v.size))
    np.maximum.accumulate(idx, out=idx)
    out = v[np.maximum(idx, 0)]
    out[idx < 0] = initial
    return out


def execute_plain(run: _Run, scan: PlainLines, a: int, b: int) -> int:
    """Execute the plain lines ``[a, b)`` (0-based) as the interpreter would; returns the index
    of the first line not executed (``a`` when the modal state needs the interpreter)."""
    st = run.st
    pos = st.pos
    if (run.ended or run.kin is not None or run.rot_used or not st.absolute or st.inverse_time
            or (st.motion != 0 and st.motion != 10)
            or pos[0] is None or pos[1] is None or pos[2] is None):
        return a
    motion = _ffill(scan.g[a:b], 0.0 if st.motion == 0 else 1.0)
    feed_raw = _ffill(scan.f[a:b], math.nan if st.feed_raw is None else st.feed_raw)
    idx = np.flatnonzero(scan.has_axis[a:b])           # lines with a move
    feeding = motion[idx] != 0.0
    no_feed = np.flatnonzero(feeding & np.isnan(feed_raw[idx]))
    if no_feed.size:   # "feed move without a feed rate": the interpreter reports it
        stop = a + int(idx[no_feed[0]])
        return execute_plain(run, scan, a, stop) if stop > a else a
    scale = st.scale
    x = _ffill(scan.x[a:b] * scale, pos[0])
    y = _ffill(scan.y[a:b] * scale, pos[1])
    z = _ffill(scan.z[a:b] * scale, pos[2])
    if idx.size:
        tips = np.empty((idx.size, 3))
        tips[:, 0] = x[idx]
        tips[:, 1] = y[idx]
        tips[:, 2] = z[idx]
        feeds = np.where(feeding, feed_raw[idx] * scale / 60.0, math.nan)
        start = run.last_tip
        if start is not None and start is run.initial_tip and not run.store.count:
            return a   # rare (initial_position, and the first move is plain): the interpreter
        if start is None:
            run.meta["unknown_start_moves"] += 1
            flag = START_UNKNOWN
        else:
            flag = START_PREVIOUS
        spindle = None if st.spindle_s is None else (st.spindle_s if st.spindle_on else 0.0)
        run.store.add_block(tips, feeding.astype(np.int8), idx + (a + 1), scan.col0[a + idx],
                            feeds, flag, spindle, st.tool)
        run.last_tip = (float(tips[-1, 0]), float(tips[-1, 1]), float(tips[-1, 2]))
        if run.units is None and run.default_units_line is None:
            run.default_units_line = a + int(idx[0]) + 1
    new_motion = 0 if motion[-1] == 0.0 else 10
    if (st.cycle_r is not None or st.cycle_z is not None) and (
            new_motion != st.motion or np.any(motion[1:] != motion[:-1])):
        st.cycle_r = st.cycle_z = None
    st.motion = new_motion
    st.pos = [float(x[-1]), float(y[-1]), float(z[-1])]
    st.feed_raw = None if math.isnan(feed_raw[-1]) else float(feed_raw[-1])
    nb = np.flatnonzero(scan.nonblank[a:b])
    if nb.size:
        if not run.first_line:
            run.first_line = a + int(nb[0]) + 1
        run.line = a + int(nb[-1]) + 1
        run.started = True
    return b
