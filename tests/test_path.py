"""Path sampling: chord tolerance, arc length, frames, source lines."""

from __future__ import annotations

import math

import numpy as np
import pytest

from planner.path import sample_toolpath
from robot_io.krl.frames import frame_from_mm_deg as frame_matrix
from robot_io.toolpath import Move, MoveKind, SourceRef, Toolpath


def _tp(moves):
    return Toolpath("t.nc", "gcode", "mm", moves)


def _arc_program(radius=0.05, sweep_quarter=True):
    start = np.array([radius, 0.0, 0.0])
    end = np.array([0.0, radius, 0.0]) if sweep_quarter else start.copy()
    return _tp([
        Move(MoveKind.RAPID, None, start, SourceRef("t.nc", 3)),
        Move(MoveKind.ARC_CCW, start, end, SourceRef("t.nc", 4), feed=0.01,
             center=np.zeros(3), normal=np.array([0.0, 0.0, 1.0])),
    ])


@pytest.mark.parametrize("tol", [1e-4, 1e-5, 1e-6])
def test_arc_chords_respect_tolerance(tol):
    r = 0.05
    path = sample_toolpath([_arc_program(r)], np.eye(4), chord_tol=tol, step_max=1.0)
    p = path.position_wp
    assert np.allclose(np.linalg.norm(p[:, :2], axis=1), r, atol=1e-12)  # on the circle
    mids = 0.5 * (p[1:] + p[:-1])
    sagitta = r - np.linalg.norm(mids[:, :2], axis=1)
    assert sagitta.max() <= tol * (1 + 1e-9)
    assert sagitta.max() > 0.25 * tol  # not wastefully fine
    # chord length → arc length as the tolerance shrinks
    assert path.s[-1] == pytest.approx(math.pi * r / 2, rel=2 * tol / r + 1e-12)


def test_full_circle_and_step_max():
    path = sample_toolpath([_arc_program(0.02, sweep_quarter=False)], np.eye(4), 1e-3, 1e-3)
    assert path.s[-1] == pytest.approx(2 * math.pi * 0.02, rel=1e-3)
    assert np.max(np.diff(path.s)) <= 1e-3 + 1e-12


def test_base_frame_and_source_lines():
    base = frame_matrix([1500.0, -200.0, 300.0], [90.0, 0.0, 0.0])
    tp = _tp([
        Move(MoveKind.RAPID, None, np.array([0.0, 0.0, 0.01]), SourceRef("t.nc", 7)),
        Move(MoveKind.LINEAR, np.array([0.0, 0.0, 0.01]), np.array([0.1, 0.0, 0.01]),
             SourceRef("t.nc", 8), feed=0.02),
    ])
    path = sample_toolpath([tp], base, 1e-5, 0.01)
    assert len(path) == 11
    assert np.allclose(path.position[-1], [1.5, -0.2 + 0.1, 0.31])  # A = 90: x_wp → +y_base
    assert np.allclose(path.tool_axis, [0, 0, 1])  # 3-axis program: +Z of the workpiece
    assert path.line.tolist() == [7] + [8] * 10
    assert path.where(5) == "t.nc:8"
    assert not path.cutting[0] and path.cutting[1:].all()
    assert np.isnan(path.feed[0]) and np.allclose(path.feed[1:], 0.02)
    assert np.allclose(path.s[-1], 0.1)


def test_tool_axis_interpolates_between_moves():
    a0, a1 = np.array([0.0, 0.0, 1.0]), np.array([0.0, math.sin(0.3), math.cos(0.3)])
    tp = _tp([
        Move(MoveKind.RAPID, None, np.zeros(3), SourceRef("t", 1), tool_axis=a0),
        Move(MoveKind.LINEAR, np.zeros(3), np.array([0.01, 0, 0]), SourceRef("t", 2), feed=0.01,
             tool_axis=a1),
    ])
    path = sample_toolpath([tp], np.eye(4), 1e-5, 1e-3)
    assert np.allclose(np.linalg.norm(path.tool_axis, axis=1), 1.0)
    assert np.allclose(path.tool_axis[-1], a1)
    angles = np.arccos(np.clip(path.tool_axis @ a0, -1, 1))
    assert np.all(np.diff(angles) > 0)
