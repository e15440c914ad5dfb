"""The move model's summary: the bounding box of arcs and helices in closed form."""

from __future__ import annotations

import math

import numpy as np

from robot_io.toolpath import Move, MoveKind, SourceRef, _arc_extremes, arc_geometry, summarize


def _dense(move: Move, k: int = 20001) -> np.ndarray:
    geo = arc_geometry(move)
    th = np.linspace(0.0, geo["sweep"], k)
    off = ((move.start - move.center) @ geo["normal"]) * geo["normal"]
    return (move.center + geo["radius"] * (np.cos(th)[:, None] * geo["u"]
                                           + np.sin(th)[:, None] * geo["v"])
            + off + geo["axial"] * (th / geo["sweep"])[:, None] * geo["normal"])


def _random_arc(rng: np.random.Generator) -> Move:
    n = rng.normal(size=3)
    n /= np.linalg.norm(n)
    c = rng.normal(size=3)
    a = rng.normal(size=3)
    a -= (a @ n) * n
    a *= rng.uniform(0.5, 2.0) / np.linalg.norm(a)
    b = np.cross(n, a)
    ang = rng.uniform(-math.pi, math.pi)
    start = c + a
    end = c + math.cos(ang) * a + math.sin(ang) * b + rng.uniform(-1, 1) * n
    kind = MoveKind.ARC_CCW if rng.random() < 0.5 else MoveKind.ARC_CW
    return Move(kind, start, end, SourceRef("f", 1), feed=1.0, center=c, normal=n,
                turns=int(rng.integers(0, 4)))


def test_arc_box_equals_the_dense_curve_box():
    rng = np.random.default_rng(7)
    for _ in range(200):
        m = _random_arc(rng)
        pts = _arc_extremes(m)
        dense = _dense(m)
        # exact: the box of the closed-form points contains the dense curve and is no larger
        # than it by more than the dense grid's own sagitta
        assert np.all(pts.min(axis=0) <= dense.min(axis=0) + 1e-12)
        assert np.all(pts.max(axis=0) >= dense.max(axis=0) - 1e-12)
        assert np.all(pts.min(axis=0) >= dense.min(axis=0) - 1e-6)
        assert np.all(pts.max(axis=0) <= dense.max(axis=0) + 1e-6)
        assert len(pts) <= 14


def test_many_turns_cost_no_more_than_one():
    """A P1000 helix (issue 22: the summary looped ~12k times per arc)."""
    m = Move(MoveKind.ARC_CW, np.array([1.0, 0, 0]), np.array([1.0, 0, -1.0]), SourceRef("f", 1),
             feed=1.0, center=np.zeros(3), normal=np.array([0, 0, 1.0]), turns=999)
    pts = _arc_extremes(m)
    assert len(pts) <= 14
    np.testing.assert_allclose(pts.min(axis=0), [-1, -1, -1], atol=1e-12)
    np.testing.assert_allclose(pts.max(axis=0), [1, 1, 0], atol=1e-12)
    from robot_io.toolpath import Toolpath

    s = summarize(Toolpath("f", "gcode", "mm", [m] * 100))
    assert s["length_m"] > 100 * 999 * 2 * math.pi
