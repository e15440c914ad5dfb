"""NX CLSF spline motion of the APT/CL interpreter (private): ``NURBS/``, its ``KNOT/`` and
``CNTRL/`` records, and the linear moves that follow the curve within the chord tolerance;
conventions (and the evidence for them) in :mod:`robot_io.apt.reader`.

The curve is a clamped cubic B-spline whose first control point is the tool position: the
``KNOT`` values are the ends of its spans (the first span starts at 0), so the knot vector is
``0,0,0,0, k1 … kn, kn,kn,kn`` and there are ``n + 2`` ``CNTRL`` records. A fourth ``CNTRL`` number
is a weight (rational form; the tool position has weight 1).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from robot_io.apt import _records as rc
from robot_io.apt._frames import point
from robot_io.options import fix
from robot_io.toolpath import MoveKind

if TYPE_CHECKING:
    from robot_io.apt._interp import Run

__all__ = [
    "DEGREE",
    "RATIONAL_BOUND_SAFETY",
    "RATIONAL_REFINE_ROUNDS",
    "SPLINE_PARTS",
    "Polyline",
    "Spline",
    "close_spline",
    "cntrl",
    "flatten",
    "knot",
    "nurbs_",
]

#: Degree of the NX CLSF spline (order 4): the counts of every spline in the public samples.
DEGREE = 3
#: The records that continue an open spline; any other record closes it.
SPLINE_PARTS = frozenset({"KNOT", "CNTRL"})
#: A rational span's second-derivative bound is its sampled maximum times this [-] (the samples
#: can miss the peak); the chords are then checked and split until they hold (below).
RATIONAL_BOUND_SAFETY = 1.5
#: Times a rational span's chords are doubled at most when a check point misses the tolerance.
RATIONAL_REFINE_ROUNDS = 12
#: Points per rational span at which the second derivative is sampled.
_RATIONAL_SAMPLES = 9


@dataclass
class Spline:
    """A spline being read: its NURBS record, knots, control points [m] and weights."""

    rec: rc.Record
    index: int
    knots: list[float] = field(default_factory=list)
    points: list[rc.Vec] = field(default_factory=list)
    weights: list[float] = field(default_factory=list)
    first_cntrl: rc.Record | None = None
    last_knot: tuple[rc.Record, int] | None = None   # (KNOT record, field index) of the last knot
    repeats: int = 1          # how often the last knot value has come in a row
    broken: bool = False      # a record of it was malformed (lenient): dropped when it closes


@dataclass(frozen=True)
class Polyline:
    """A curve flattened to chords.

    Attributes:
        params: curve parameter at every vertex, the start included, shape (m + 1,).
        points: the vertices after the start [m], shape (m, 3); the last is the curve's end.
    """

    params: np.ndarray
    points: np.ndarray


# --------------------------------------------------------------------------- records
def _skip_spline() -> str:
    return f"fix the record or read leniently ({fix('strict', False)}) to skip the spline"


def nurbs_(run: Run, rec: rc.Record) -> None:
    sp = Spline(rec, run.spline_count)
    run.spline_count += 1
    run.spline = sp
    if run.fields(rec):
        sp.broken = True
        run.bad(rec.args_at, "NURBS/ takes no arguments (NX writes the spline as the KNOT/ and "
                f"CNTRL/ records after it); {_skip_spline()}", "bad_spline")
    if run.cycle is not None:
        sp.broken = True
        run.bad(None, f"NURBS inside a drilling cycle (CYCLE at line {run.cycle['line']}): end "
                f"the cycle with CYCLE/OFF before the spline, or {_skip_spline()}", "bad_spline")


def _open(run: Run, rec: rc.Record) -> Spline:
    if run.spline is None:
        run.bad(None, f"{rec.word} outside a spline: NX writes NURBS/, then the KNOT/ records, "
                f"then the CNTRL/ records; add the NURBS/ before it, or {rc.fix_or_skip()}",
                "bad_spline")
    return run.spline   # type: ignore[return-value]


def knot(run: Run, rec: rc.Record) -> None:
    sp = _open(run, rec)
    try:
        if sp.points:
            run.bad(None, f"KNOT after the spline's CNTRL records (NURBS at line {sp.rec.line}): "
                    f"the knots come first; {_skip_spline()}", "bad_spline")
        vals = run.numbers(rec, range(1, rc.MAX_RECORD_FIELDS + 1), "1 or more knot values")
        for i, v in enumerate(vals):
            prev = sp.knots[-1] if sp.knots else 0.0
            if v < prev or (not sp.knots and v <= 0):
                what = (f"{v:g} after {prev:g}: knot values must not decrease" if sp.knots else
                        f"{v:g}: the first knot ends the first span, which starts at 0 where "
                        "the tool is, so it must be > 0")
                run.bad(run.field_offset(rec, i), f"KNOT {what}; {_skip_spline()}", "bad_spline")
            sp.repeats = sp.repeats + 1 if sp.knots and v == prev else 1
            if sp.repeats > DEGREE:
                run.bad(run.field_offset(rec, i), f"KNOT {v:g} comes more than {DEGREE} times: "
                        f"the cubic spline would come apart there; {_skip_spline()}",
                        "bad_spline")
            sp.knots.append(v)
            sp.last_knot = (rec, i)
    except rc.Skip:
        sp.broken = True
        raise


def cntrl(run: Run, rec: rc.Record) -> None:
    sp = _open(run, rec)
    try:
        vals = run.numbers(rec, (3, 4), "3 numbers (x,y,z) or 4 (x,y,z,weight)")
        if sp.points and (len(vals) == 4) != bool(sp.weights):
            run.bad(None, "CNTRL: either every control point of a spline has a weight (4 "
                    f"numbers) or none has (NURBS at line {sp.rec.line}); {_skip_spline()}",
                    "bad_spline")
        if len(vals) == 4:
            if not vals[3] > 0:
                run.bad(run.field_offset(rec, 3), f"CNTRL weight must be positive, got "
                        f"{vals[3]:g}; {_skip_spline()}", "bad_spline")
            sp.weights.append(vals[3])
        sp.points.append(point(run, vals))
        if sp.first_cntrl is None:
            sp.first_cntrl = rec
    except rc.Skip:
        sp.broken = True
        raise


# --------------------------------------------------------------------------- the moves
def close_spline(run: Run) -> None:
    """Turn the open spline into moves (or a located problem) once its records have ended."""
    sp = run.spline
    assert sp is not None
    run.spline = None
    start = run.pos
    end = sp.points[-1] if sp.points else None
    if sp.broken:   # lenient only: its bad record was warned about and counted
        run.pos = end if end is not None else start
        run.warn(sp.rec.col, "spline_dropped", f"the spline of the NURBS at line {sp.rec.line} "
                 "is dropped (one of its records is bad, see above); the tool jumps to its last "
                 "control point", line=sp.rec.line)
        return
    k, m = len(sp.knots), len(sp.points)
    unit, s_mm = ("mm", 1e3) if run.scale == rc.MM else ("in", 1.0 / rc.INCH)
    if start is None:
        _bad(run, sp, None, "NURBS from an unknown position: the spline starts where the tool "
             "is; add a GOTO or FROM before it, or")
    if m == k + 3 and k >= 1:   # the start point written out as the first CNTRL
        gap = math.dist(sp.points[0], start)   # type: ignore[arg-type]
        if gap > rc.SPLINE_START_TOL:
            _bad(run, sp, sp.first_cntrl, f"the spline does not start at the tool position: its "
                 f"first CNTRL is {gap * s_mm:.4g} {unit} away (tolerance "
                 f"{rc.SPLINE_START_TOL * s_mm:.2g} {unit}), and {k} knot value"
                 f"{'s' if k != 1 else ''} with {m} CNTRL records make the first CNTRL the "
                 "start point; fix the spline, or")
        points, weights = sp.points[1:], sp.weights[1:]
        w0 = sp.weights[0] if sp.weights else 1.0
    elif m == k + 2 and k >= 1:
        points, weights, w0 = sp.points, sp.weights, 1.0
    else:
        _bad(run, sp, None, f"NURBS has {k} knot value{'s' if k != 1 else ''} and {m} CNTRL "
             f"record{'s' if m != 1 else ''}: NX writes {k + 2} CNTRL records for {k} knots "
             f"(the spans' ends; the tool position is the first control point, not written) — "
             "complete the spline, or")
    if k >= 2 and sp.knots[-1] <= sp.knots[-2]:
        krec, idx = sp.last_knot   # type: ignore[misc]
        _bad(run, sp, krec, f"the last KNOT value ({sp.knots[-1]:g}) must be greater than the "
             "one before it (it ends the last span); fix the knots, or", idx)
    ctrl = np.array([start, *points], dtype=float)
    w = None if not weights else np.array([w0, *weights])
    t = np.array([0.0] * (DEGREE + 1) + sp.knots + [sp.knots[-1]] * DEGREE)
    try:
        line = flatten(t, ctrl, w, run.opts.chord_tol, rc.MAX_SPLINE_MOVES)
    except _TooManyMoves as e:
        tol = run.opts.chord_tol
        wider = float(f"{tol * (e.moves / rc.MAX_SPLINE_MOVES) ** 2 * 1.1:.1g}")
        _bad(run, sp, None, f"the spline would need {e.moves:.0f} moves to stay within the chord "
             f"tolerance of {tol * s_mm:g} {unit} (at most {rc.MAX_SPLINE_MOVES}): check its "
             f"control points, or raise the tolerance ({fix('chord_tol', wider)}), or")
    if run.rapid:
        kind, feed = MoveKind.RAPID, None
        run.rapid = False
    else:
        kind, feed = MoveKind.LINEAR, run.move_feed(sp.rec)
    extra = {"spline": sp.index}
    pts = line.points.tolist()
    pts[-1] = list(points[-1])   # the clamped end is the last control point, exactly
    for p in pts:
        run.emit(sp.rec, kind, (p[0], p[1], p[2]), feed, extra=extra)
    run.meta["splines"].append({
        "index": sp.index, "line": sp.rec.line, "knots": k, "control_points": len(ctrl),
        "rational": w is not None, "moves": len(pts)})


def _bad(run: Run, sp: Spline, rec: rc.Record | None, reason: str, idx: int | None = None) -> None:
    """A spline that cannot be read: strict raises; lenient warns, puts the tool at its end."""
    where = rec if rec is not None else sp.rec
    if sp.points:
        run.pos = sp.points[-1]
    run.bad(None if idx is None else run.field_offset(where, idx),
            f"{reason} read leniently ({fix('strict', False)}) to skip the spline", "bad_spline",
            rec=where)


# --------------------------------------------------------------------------- flattening
class _TooManyMoves(Exception):
    def __init__(self, moves: float) -> None:
        super().__init__(moves)
        self.moves = moves


def flatten(t: np.ndarray, ctrl: np.ndarray, weights: np.ndarray | None, tol: float,
            max_moves: int) -> Polyline:
    """Chords of the cubic (rational when ``weights`` are given) B-spline with knot vector ``t``
    and control points ``ctrl`` [m], shape (n, 3), none farther than ``tol`` [m] from the curve.

    Each span [a, b] gets ``ceil(h·sqrt(M / (8·tol)))`` equal parameter steps, h = b − a, M a
    bound of |C''| on the span: the curve is then within h²M/8 of its linear interpolant, hence
    of the chord. For a polynomial span C'' is linear, so M is the larger end value (exact); for
    a rational span M is sampled (times :data:`RATIONAL_BOUND_SAFETY`) and every chord is checked
    at its quarter points and split until it holds. Raises ``_TooManyMoves`` beyond
    ``max_moves``.
    """
    from scipy.interpolate import BSpline  # only files with splines pay for the import

    n = len(ctrl)
    if weights is None:
        curve = BSpline(t, ctrl, DEGREE)

        def at(u: np.ndarray) -> np.ndarray:
            return curve(u)
    else:
        num = BSpline(t, ctrl * weights[:, None], DEGREE)
        den = BSpline(t, weights, DEGREE)

        def at(u: np.ndarray) -> np.ndarray:
            return num(u) / den(u)[:, None]
    breaks = np.unique(t[DEGREE:n + 1])
    a, h = breaks[:-1], np.diff(breaks)
    with np.errstate(over="ignore", invalid="ignore"):
        if weights is None:   # C'' linear on a span: its values at the ends from two inside
            # (evaluated inside the spans: a knot repeated 3 times leaves C'' undefined there)
            v1, v3 = curve(a + 0.25 * h, nu=2), curve(a + 0.75 * h, nu=2)
            ends = np.stack([1.5 * v1 - 0.5 * v3, 1.5 * v3 - 0.5 * v1])
            bound = np.linalg.norm(ends, axis=2).max(axis=0)
        else:
            f = (np.arange(_RATIONAL_SAMPLES) + 0.5) / _RATIONAL_SAMPLES
            u = (a[:, None] + h[:, None] * f).ravel()
            bound = _rational_d2(num, den, u).reshape(len(a), -1).max(axis=1)
            bound = bound * RATIONAL_BOUND_SAFETY
        steps = np.ceil(h * np.sqrt(bound / (8.0 * tol)))
    if not np.isfinite(steps).all() or steps.sum() > max_moves:
        raise _TooManyMoves(float(steps.sum()) if np.isfinite(steps).all() else math.inf)
    steps = np.maximum(steps, 1).astype(int)
    for _ in range(RATIONAL_REFINE_ROUNDS if weights is not None else 0):
        params = _params(a, h, steps, breaks[-1])
        pts = at(params)
        bad = _chord_misses(at, params, pts, tol)
        if not bad.any():
            break
        span = np.repeat(np.arange(len(a)), steps)
        steps[np.unique(span[bad])] *= 2
        if steps.sum() > max_moves:
            raise _TooManyMoves(float(steps.sum()))
    params = _params(a, h, steps, breaks[-1])
    return Polyline(params=params, points=at(params[1:]))


def _params(a: np.ndarray, h: np.ndarray, steps: np.ndarray, end: float) -> np.ndarray:
    """Equal parameter steps per span, the start of each span and the curve's end."""
    span = np.repeat(np.arange(len(a)), steps)
    first = np.repeat(np.cumsum(steps) - steps, steps)
    j = np.arange(int(steps.sum())) - first
    return np.append(a[span] + h[span] * j / steps[span], end)


def _chord_misses(at, params: np.ndarray, pts: np.ndarray, tol: float) -> np.ndarray:
    """Which chords (between consecutive ``params``) leave the curve by more than ``tol`` at a
    quarter point."""
    p0, p1 = pts[:-1], pts[1:]
    d = p1 - p0
    dd = np.einsum("ij,ij->i", d, d)
    worst = np.zeros(len(d))
    for f in (0.25, 0.5, 0.75):
        q = at(params[:-1] + f * np.diff(params)) - p0
        s = np.clip(np.einsum("ij,ij->i", q, d) / np.where(dd > 0, dd, 1.0), 0.0, 1.0)
        worst = np.maximum(worst, np.linalg.norm(q - s[:, None] * d, axis=1))
    return worst > tol


def _rational_d2(num, den, u: np.ndarray) -> np.ndarray:
    """|C''(u)| of the rational curve num/den."""
    a0, a1, a2 = num(u), num(u, nu=1), num(u, nu=2)
    w0, w1, w2 = den(u)[:, None], den(u, nu=1)[:, None], den(u, nu=2)[:, None]
    c0 = a0 / w0
    c1 = (a1 - w1 * c0) / w0
    c2 = (a2 - 2.0 * w1 * c1 - w2 * c0) / w0
    return np.linalg.norm(c2, axis=1)
