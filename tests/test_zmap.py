"""Tests of planner/zmap.py (the Z-map engagement) against closed forms, and of the guards both stock
models share (a_p never negative, a_e never above the diameter, a tool below the stock bottom is a
warning naming the sample and its toolpath line).

Conventions as in tests/test_engagement.py: a vertical tool (a = +Z), X_o = a × f is the feed's left
seen from above; up milling has the material on +X_o, down milling on −X_o.

Tolerances. A boundary of the engaged arc that is the stock outline is exact (to the bisection,
≈ 1e-5 R); one that an earlier pass left is moved by the sliver tolerance (earlier passes clear
points within SLIVER_TOL = 20 µm of their disc: docs of planner.zmap), so a_e is within
SLIVER_TOL + 1 µm there. a_p is the exact height of the material left, except on ramps, where the
Z-map reads it within about one cell of the circle (the bound used below: the ramp's slope times
one cell).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from models.cutting import MILLING_MODES
from models.errors import InputError
from planner.engagement import AIR, Engagement, Stock, stock_engagement
from planner.zmap import CELL_FRACTION, DEPTH_TOL, SLIVER_TOL, default_cell, zmap_engagement

R = 6e-3  # tool radius [m]
CELL = default_cell(R)  # 0.6 mm
UP, DOWN, SLOT = MILLING_MODES["up"], MILLING_MODES["down"], MILLING_MODES["slot"]
Z_AXIS = np.array([0.0, 0.0, 1.0])
STEP = 0.5e-3  # sample spacing along the path [m]
AE_EXACT = 1e-6  # a_e against the stock outline [m]
AE_CUT = SLIVER_TOL + 1e-6  # a_e against a wall an earlier pass left [m]
SHARED = Path(__file__).resolve().parents[2] / "shared" / "data" / "toolpaths"
FUSION = SHARED / "fusion360_1117_wall_28bit.nc"


def box() -> Stock:
    """100 × 50 × 20 mm block, x 0..100 mm, y 0..50 mm, z 0..20 mm."""
    return Stock.box(0.0, 0.0, 0.1, 0.05, 0.0, 0.02)


def path(*legs: tuple[tuple[float, float, float], bool]) -> tuple[np.ndarray, np.ndarray]:
    """Samples of a polyline: the first leg's point is the start, each further leg (end point,
    cutting) is sampled every ≤ STEP; ``cutting`` marks the samples that end a feed move."""
    pts = [np.asarray(legs[0][0], float)]
    cut = [False]
    for end, cutting in legs[1:]:
        a, b = pts[-1], np.asarray(end, float)
        k = max(1, math.ceil(np.linalg.norm(b - a) / STEP))
        t = np.arange(1, k + 1) / k
        pts.extend(a + t[:, None] * (b - a))
        cut.extend([cutting] * k)
    return np.array(pts), np.array(cut)


def helix(centre: tuple[float, float], radius: float, z0: float, pitch: float, turns: float,
          per_turn: int = 180) -> tuple[np.ndarray, np.ndarray]:
    """A counter-clockwise helix descending ``pitch`` per turn from z0, and its cutting flags."""
    th = np.linspace(0.0, 2 * math.pi * turns, int(per_turn * turns) + 1)
    p = np.column_stack([centre[0] + radius * np.cos(th), centre[1] + radius * np.sin(th),
                         z0 - th / (2 * math.pi) * pitch])
    c = np.ones(th.size, bool)
    c[0] = False
    return p, c


def inside(p: np.ndarray, x0: float, x1: float) -> np.ndarray:
    """Samples whose tool centre lies between x0 and x1 [m]."""
    return (p[:, 0] > x0) & (p[:, 0] < x1)


# --------------------------------------------------------------------------------------------------
# slot, side cuts against the outline and against a cleared wall
# --------------------------------------------------------------------------------------------------


def test_full_width_slot() -> None:
    p, c = path(((-0.01, 0.025, 0.03), False), ((-0.01, 0.025, 0.015), False),
                ((0.11, 0.025, 0.015), True))
    e = zmap_engagement(p, Z_AXIS, c, R, box())
    full = inside(p, R + 1e-3, 0.1 - 1e-3) & c
    assert full.sum() > 100
    assert np.all(e.mode[full] == SLOT)
    np.testing.assert_allclose(e.a_e[full], 2 * R, rtol=0, atol=1e-12)
    np.testing.assert_allclose(e.a_p[full], 0.005, rtol=0, atol=1e-12)
    np.testing.assert_allclose(e.engaged_angle[full], math.pi, atol=1e-12)
    np.testing.assert_allclose(e.radial_dir[full], [[0, 1, 0]] * full.sum(), atol=1e-12)
    np.testing.assert_allclose(e.feed_dir[full], [[1, 0, 0]] * full.sum(), atol=1e-12)
    assert np.all(e.mode[p[:, 0] < -R] == AIR) and np.all(e.mode[p[:, 0] > 0.1 + R] == AIR)
    assert e.warnings == ()


A_E = 3e-3
OUTLINE_CASES = [  # (tool centre y, direction of travel, expected mode): as test_engagement.py
    (-R + A_E, +1, UP), (-R + A_E, -1, DOWN), (0.05 + R - A_E, +1, DOWN), (0.05 + R - A_E, -1, UP),
]


@pytest.mark.parametrize(("y", "direction", "expected"), OUTLINE_CASES)
def test_side_cut_against_the_outline_is_exact(y: float, direction: int, expected: int) -> None:
    x0, x1 = (-0.01, 0.11) if direction > 0 else (0.11, -0.01)
    p, c = path(((x0, y, 0.015), False), ((x1, y, 0.015), True))
    e = zmap_engagement(p, Z_AXIS, c, R, box())
    mid = inside(p, 0.02, 0.08)
    assert np.all(e.mode[mid] == expected)
    np.testing.assert_allclose(e.a_e[mid], A_E, rtol=0, atol=AE_EXACT)
    np.testing.assert_allclose(e.a_p[mid], 0.005, rtol=0, atol=1e-12)
    np.testing.assert_allclose(e.engaged_angle[mid], math.acos(1 - A_E / R), atol=1e-4)


# A slot along x at y = 25 mm clears y ∈ [25 − R, 25 + R]; a second pass at y = 25 ± D/4... no: at
# y = 25 ± a_e with a_e = D/4 = R/2 cuts the a_e-wide strip beyond the slot's wall. Material on +y
# with travel +x is on the feed's left (+X_o): up milling; travel −x: down; the mirror for −y.
WALL_CASES = [(+1, +1, UP), (+1, -1, DOWN), (-1, +1, DOWN), (-1, -1, UP)]


@pytest.mark.parametrize(("side", "direction", "expected"), WALL_CASES)
def test_quarter_diameter_beside_a_cleared_wall(side: int, direction: int, expected: int) -> None:
    a_e, y0, z = 0.5 * R, 0.025, 0.015
    x0, x1 = (-0.01, 0.11) if direction > 0 else (0.11, -0.01)
    y1 = y0 + side * a_e
    p, c = path(((-0.01, y0, 0.03), False), ((-0.01, y0, z), False), ((0.11, y0, z), True),
                ((0.11, y0, 0.03), False), ((x0, y1, 0.03), False), ((x0, y1, z), False),
                ((x1, y1, z), True))
    e = zmap_engagement(p, Z_AXIS, c, R, box())
    second = np.flatnonzero(inside(p, 0.02, 0.08) & np.isclose(p[:, 1], y1))
    assert second.size > 100 and second[0] > np.flatnonzero(np.isclose(p[:, 1], y0))[-1]
    assert np.all(e.mode[second] == expected), f"material on {side:+d}y, travel {direction:+d}x"
    np.testing.assert_allclose(e.a_e[second], a_e, rtol=0, atol=AE_CUT)
    np.testing.assert_allclose(e.a_p[second], 0.02 - z, rtol=0, atol=1e-12)
    np.testing.assert_allclose(e.engaged_angle[second], math.acos(1 - a_e / R), atol=1e-2)
    # The material lies on +X_o for up milling, on −X_o for down milling.
    sign = 1.0 if expected == UP else -1.0
    np.testing.assert_allclose(e.radial_dir[second] @ [0.0, side, 0.0], sign, atol=1e-12)


@pytest.mark.parametrize(("turn", "expected"), [(+1, UP), (-1, DOWN)])
def test_contour_around_a_round_boss(turn: int, expected: int) -> None:
    """A polygon outline (a round boss of radius r_w, 720 vertices): the tool centre on a circle
    d = r_w + R − 3 mm around it meets the boss where r_w² = R² + d² − 2 R d cos φ, and touches the
    finished contour at φ = 0 (counter-clockwise: the boss on the left, up) or π (down)."""
    r_w, depth, z = 0.02, 3e-3, 0.015
    d = r_w + R - depth
    ang = np.linspace(0.0, 2 * math.pi, 721)[:-1]
    boss = Stock(list(zip(0.05 + r_w * np.cos(ang), 0.025 + r_w * np.sin(ang), strict=True)),
                 0.0, 0.02)
    t = turn * np.linspace(0.0, 1.5 * math.pi, 600)
    p = np.column_stack([0.05 + d * np.cos(t), 0.025 + d * np.sin(t), np.full(t.size, z)])
    c = np.ones(t.size, bool)
    c[0] = False
    e = zmap_engagement(p, Z_AXIS, c, R, boss)
    mid = slice(100, 500)
    assert np.all(e.mode[mid] == expected)
    phi = math.acos((R**2 + d**2 - r_w**2) / (2 * R * d))
    np.testing.assert_allclose(e.engaged_angle[mid], phi, atol=1e-4)  # the polygon's chords
    np.testing.assert_allclose(e.a_p[mid], 0.005, atol=1e-12)
    es = stock_engagement(p, Z_AXIS, c, R, boss)
    np.testing.assert_allclose(e.a_e[mid], es.a_e[mid], atol=1e-6)


# --------------------------------------------------------------------------------------------------
# pocket: the second pass cuts the step-over, the second level the level step
# --------------------------------------------------------------------------------------------------


def test_pocket_step_over_and_level_step() -> None:
    step_over, x0, x1 = 0.5 * R, 0.02, 0.08
    legs: list[tuple[tuple[float, float, float], bool]] = [((x0, 0.01, 0.03), False)]
    ys = 0.01 + step_over * np.arange(6)
    for z in (0.017, 0.014):
        legs += [((x0, ys[0], 0.03), False), ((x0, ys[0], z), True)]  # plunge
        for k, y in enumerate(ys):
            xa, xb = (x0, x1) if k % 2 == 0 else (x1, x0)
            if k:
                legs.append(((xa, y, z), True))
            legs.append(((xb, y, z), True))
    p, c = path(*legs)
    e = zmap_engagement(p, Z_AXIS, c, R, box())
    for z in (0.017, 0.014):
        for k, y in enumerate(ys):
            sel = c & np.isclose(p[:, 2], z) & np.isclose(p[:, 1], y) & inside(p, x0 + R, x1 - R)
            assert sel.sum() > 50
            np.testing.assert_allclose(e.a_p[sel], 3e-3, rtol=0, atol=1e-9)  # the level step
            if k == 0:  # the first pass of each level: a slot (the level above is cleared above)
                assert np.all(e.mode[sel] == SLOT)
            else:  # passes alternate direction; the material is always on the +y side
                assert np.all(e.mode[sel] == (UP if k % 2 == 0 else DOWN))
                np.testing.assert_allclose(e.a_e[sel], step_over, rtol=0, atol=AE_CUT)
    plunges = c & (np.diff(p[:, 2], prepend=p[0, 2]) < -1e-6)
    assert plunges.sum() > 0 and np.all(e.plunge[plunges]) and np.all(e.mode[plunges] == AIR)
    # A pass retracing the last one finds nothing left.
    p2 = np.vstack([p, p[-1:] - [[0.03, 0.0, 0.0]]])
    e2 = zmap_engagement(p2, Z_AXIS, np.append(c, True), R, box())
    assert e2.mode[-1] == AIR


# --------------------------------------------------------------------------------------------------
# helix and ramp
# --------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("helix_radius", [0.5 * R, R / 7])
def test_helix_axial_depth_is_the_pitch(helix_radius: float) -> None:
    """Into solid stock from 1 mm above the top, 1 mm per turn: after the first turn in the stock
    the flank meets the material the turn before left, the pitch — not the depth below the top.
    The bore wall's height falls steeply inside the circle; the Z-map reads it within one cell:
    |a_p − p| ≤ slope · cell, slope = p / (2π r) of the helix (R/7: the Fusion 360 bores)."""
    pitch = 1e-3
    p, c = helix((0.05, 0.025), helix_radius, 0.021, pitch, 4.0)
    e = zmap_engagement(p, Z_AXIS, c, R, box())
    above = p[:, 2] > 0.02 + DEPTH_TOL
    settled = p[:, 2] < 0.02 - 1.05 * pitch  # a full turn inside the stock
    assert np.all(e.mode[above] == AIR)
    assert settled.sum() > 300 and np.all(e.mode[settled] != AIR)
    bound = pitch / (2 * math.pi * helix_radius) * CELL
    assert np.all(e.a_p[settled] <= pitch + DEPTH_TOL)
    assert np.all(e.a_p[settled] >= pitch - bound), e.a_p[settled].min()
    # The first turn into the stock meets the top: a_p = z_top − tip there.
    entering = (p[:, 2] < 0.02 - 0.1 * pitch) & (p[:, 2] > 0.02 - 0.9 * pitch)
    np.testing.assert_allclose(e.a_p[entering], 0.02 - p[entering, 2], atol=1e-9)


def test_ramp_axial_depth_grows_as_the_tool_descends() -> None:
    alpha = math.radians(3.0)
    x0, x1 = 0.01, 0.09
    z0 = 0.021
    z1 = z0 - (x1 - x0) * math.tan(alpha)
    p, c = path(((x0, 0.025, z0), False), ((x1, 0.025, z1), True))
    e = zmap_engagement(p, Z_AXIS, c, R, box())
    cutting = c & (p[:, 2] < 0.02 - DEPTH_TOL)
    assert cutting.sum() > 100
    assert np.all(e.mode[cutting] == SLOT)
    np.testing.assert_allclose(e.a_p[cutting], 0.02 - p[cutting, 2], rtol=0, atol=1e-12)
    assert np.all(np.diff(e.a_p[cutting]) > 0)
    assert np.all(e.mode[c & (p[:, 2] > 0.02 + 1e-9)] == AIR)
    # The ramp's feed direction is the 3-D step; X_o is horizontal and Y_o leans back from +Z.
    np.testing.assert_allclose(e.radial_dir[cutting], [[0, 1, 0]] * cutting.sum(), atol=1e-12)


# --------------------------------------------------------------------------------------------------
# guards of both stock models: below the stock bottom, a_p ≥ 0, a_e ≤ 2R
# --------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("model", ["zmap", "stock"])
def test_tool_below_the_stock_bottom_warns_and_a_p_is_never_negative(model: str) -> None:
    """A slot 5 mm below the bottom of a 20 mm block (a through cut), then a pass 3 mm lower along
    the same line: the first cuts the whole thickness (a_p = 20 mm, not 25), the second meets
    nothing — the 2.5-D rule alone gave it a_p = −5 mm (the "cleared" level under the stock)."""
    y = 0.025
    p, c = path(((-0.01, y, 0.03), False), ((-0.01, y, -0.005), False), ((0.11, y, -0.005), True),
                ((0.11, y, -0.008), False), ((-0.01, y, -0.008), True))
    lines = np.where(p[:, 2] > -0.006, 17, 23)

    def where(i: int) -> str:
        return f"part.nc:{lines[i]}"

    engage = zmap_engagement if model == "zmap" else stock_engagement
    e = engage(p, Z_AXIS, c, R, box(), where=where)
    first = c & inside(p, R + 1e-3, 0.1 - 1e-3) & np.isclose(p[:, 2], -0.005)
    second = c & np.isclose(p[:, 2], -0.008)
    assert np.all(e.mode[first] == SLOT)
    np.testing.assert_allclose(e.a_p[first], 0.02, atol=1e-9)
    assert np.all(e.mode[second] == AIR) and np.all(e.a_p[second] == 0.0)
    assert np.all(e.a_p >= 0.0) and np.all(e.a_e <= 2 * R)
    assert len(e.warnings) == 2
    assert "part.nc:17" in e.warnings[0] and "5.000 mm below the stock bottom" in e.warnings[0]
    assert "part.nc:23" in e.warnings[1] and "8.000 mm below" in e.warnings[1]
    assert "z_bottom_mm" in e.warnings[0]


def test_many_runs_below_the_bottom_are_counted_not_listed() -> None:
    legs: list[tuple[tuple[float, float, float], bool]] = [((0.02, 0.01, 0.03), False)]
    for k in range(14):
        y = 0.005 + 0.003 * k
        legs += [((0.02, y, 0.03), False), ((0.02, y, -0.001), False), ((0.03, y, -0.001), True)]
    p, c = path(*legs)
    e = zmap_engagement(p, Z_AXIS, c, R, box())
    assert len(e.warnings) == 11 and e.warnings[-1].startswith("… and 4 more runs")


def test_a_path_beside_the_stock_below_its_bottom_is_no_warning() -> None:
    p, c = path(((-0.03, 0.025, -0.005), False), ((-0.03, 0.06, -0.005), True))
    assert zmap_engagement(p, Z_AXIS, c, R, box()).warnings == ()


# --------------------------------------------------------------------------------------------------
# the Z-map and the 2.5-D model agree where both are right: the demo's contour
# --------------------------------------------------------------------------------------------------


def test_zmap_agrees_with_the_2p5d_model_on_the_demo_contour() -> None:
    """The demo (two 10 mm levels of an outside contour, climb milling, R = 12.7 mm, the default
    cell 1.27 mm): every mode agrees, a_p to 1 µm, a_e to 1 µm on the walls and to 0.05 mm where
    the loop closes on the crescent its lead-in arc left (a few samples)."""
    from importlib import resources

    from planner.job import load_job
    from planner.path import sample_toolpath
    from planner.prepare import read_job_toolpaths, tool_of

    job = load_job(str(resources.files("planner").joinpath("data/demo/demo_job.toml")))
    si = job.to_si()
    path_ = sample_toolpath(list(read_job_toolpaths(job, si.chord_tol)), np.eye(4), si.chord_tol,
                            si.step_max)
    stock = Stock.box(*si.stock_box, *si.stock_z)
    radius = tool_of(job).radius
    args = (path_.position_wp, path_.tool_axis_wp, path_.cutting, radius, stock)
    z, s = zmap_engagement(*args, where=path_.where), stock_engagement(*args)
    both = (z.mode >= 0) & (s.mode >= 0)
    assert both.sum() > 700
    assert np.array_equal(z.mode, s.mode)
    assert np.max(np.abs(z.a_p - s.a_p)) < 1e-6
    d_ae = np.abs(z.a_e - s.a_e)[both]
    assert np.percentile(d_ae, 95) < 1e-6 and d_ae.max() < 5e-5
    assert z.warnings == ()


# --------------------------------------------------------------------------------------------------
# the real Fusion 360 program: helical bores of 0.5 mm pitch
# --------------------------------------------------------------------------------------------------


@pytest.mark.slow
@pytest.mark.skipif(not FUSION.is_file(), reason=f"the shared Fusion 360 program is not at {FUSION}")
def test_fusion_helical_bores_a_p_is_the_pitch(tmp_path: Path) -> None:
    """``cctmill inspect`` of a job on fusion360_1117_wall_28bit.nc (2.8 mm flat end mill, a 14 mm
    block): the helical bores' a_p is at most the 0.5 mm pitch (before: up to the bore depth; the
    2.5-D model still gives 13.3 mm at the bottom of the 0.2 mm-radius helices)."""
    from planner.job import load_job
    from planner.prepare import inspect_job, prepare

    job_file = tmp_path / "fusion.toml"
    job_file.write_text(f"""
[job]
toolpath = ["{FUSION.as_posix()}"]
strict = false
[cell]
base_mm = [1500.0, -60.0, 400.0]
tcp_mm = [320.0, 0.0, 0.0]
[tool]
diameter_mm = 2.8
[engagement.stock]
box_mm = [0.0, 0.0, 228.0, 70.0]
z_bottom_mm = -14.0
z_top_mm = 0.0
""", encoding="utf-8")
    job = load_job(job_file)
    assert job.engagement.source == "zmap"  # the default with a stock table
    prep = prepare(job)
    summary = inspect_job(prep)
    assert summary["engagement"]["source"] == "zmap"
    e, path_ = prep.engagement, prep.path
    assert 0.0 < summary["engagement"]["ap_mm"]["min"] and summary["engagement"]["ae_mm"]["max"] <= 2.8
    bores = (path_.line >= 2571) & (path_.line <= 3717) & (e.mode >= 0)  # the "Bore1" operation
    bottoms = bores & (path_.position_wp[:, 2] < -0.0128)  # the last turn and the flat circles
    assert bores.sum() > 2000 and bottoms.sum() > 100
    # The pitch within slope × cell: 0.5 mm / (2π 0.2 mm) × 0.14 mm = 0.056 mm.
    assert e.a_p[bores].max() <= 0.5e-3 + 0.056e-3
    assert 0.45e-3 <= np.median(e.a_p[bottoms]) <= 0.5e-3
    assert e.warnings == ()  # nothing below the 14 mm block's bottom


# --------------------------------------------------------------------------------------------------
# the job's choice
# --------------------------------------------------------------------------------------------------

STOCK_TABLE = {"box_mm": [0.0, 0.0, 100.0, 50.0], "z_bottom_mm": -20.0, "z_top_mm": 0.0}


@pytest.mark.parametrize(("engagement", "source"), [
    ({"stock": STOCK_TABLE}, "zmap"),  # a stock table and no source: the Z-map
    ({"source": "stock", "stock": STOCK_TABLE}, "stock"),
    ({"source": "zmap", "stock": {**STOCK_TABLE, "zmap_cell_mm": 0.5}}, "zmap"),
    ({"ae_mm": 3.0, "ap_mm": 5.0}, "fixed"),
])
def test_job_engagement_source(engagement: dict, source: str) -> None:
    from planner.job import parse_job

    job = parse_job({"job": {"toolpath": "a.nc"}, "engagement": engagement})
    assert job.engagement.source == source
    if "zmap_cell_mm" in engagement.get("stock", {}):
        assert job.engagement.stock.zmap_cell() == pytest.approx(0.5e-3)
    elif job.engagement.stock is not None:
        assert job.engagement.stock.zmap_cell() is None


@pytest.mark.parametrize(("engagement", "match"), [
    ({"source": "zmap"}, r"source = 'zmap' needs an \[engagement.stock\] table"),
    ({"stock": {**STOCK_TABLE, "zmap_cell_mm": 0.0}}, r"zmap_cell_mm: input should be greater"),
])
def test_job_engagement_errors(engagement: dict, match: str) -> None:
    from planner.job import JobError, parse_job

    with pytest.raises(JobError, match=match):
        parse_job({"job": {"toolpath": "a.nc"}, "engagement": engagement}, "job.toml")


def test_prepare_uses_the_zmap_and_carries_its_warnings() -> None:
    """The demo job with ``source = "zmap"``: prepare() gives the 2.5-D model's modes and a_p (the
    contour is constant-height levels), and the engagement's warnings (none here)."""
    import tomllib
    from importlib import resources

    from planner.job import parse_job
    from planner.prepare import prepare

    demo = Path(str(resources.files("planner").joinpath("data/demo/demo_job.toml")))
    doc = tomllib.loads(demo.read_text(encoding="utf-8"))
    doc["engagement"]["source"] = "zmap"
    z = prepare(parse_job(doc, str(demo), demo.parent))
    doc["engagement"]["source"] = "stock"
    s = prepare(parse_job(doc, str(demo), demo.parent))
    assert np.array_equal(z.engagement.mode, s.engagement.mode)
    assert np.max(np.abs(z.engagement.a_p - s.engagement.a_p)) < 1e-6
    assert z.engagement.warnings == () and isinstance(z.engagement.warnings, tuple)
    # The frame is turned into the robot base like the other sources'.
    cut = z.engagement.mode >= 0
    np.testing.assert_allclose(z.engagement.radial_dir[cut], s.engagement.radial_dir[cut],
                               atol=1e-9)


# --------------------------------------------------------------------------------------------------
# errors
# --------------------------------------------------------------------------------------------------


def test_tilted_tool_is_refused_with_the_sample_and_line() -> None:
    p, c = path(((-0.01, 0.025, 0.015), False), ((0.11, 0.025, 0.015), True))
    tilted = np.array([math.sin(math.radians(1.0)), 0.0, math.cos(math.radians(1.0))])
    with pytest.raises(InputError, match=r"sample 1 \(job.nc:7\).*3-axis.*source = \"fixed\""):
        zmap_engagement(p, tilted, c, R, box(), where=lambda i: "job.nc:7")
    zmap_engagement(p, [0.0, 1e-4, 1.0], c, R, box())  # within VERTICAL_AXIS_TOL


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"cell": 0.6 * R}, r"zmap_cell_mm: the Z-map cell must lie in \(0, R/2\]"),
    ({"cell": 0.0}, "zmap_cell_mm"),
    ({"cell": 1e-6}, "larger .*zmap_cell_mm"),
    ({"sliver": -1.0}, "sliver"),
])
def test_bad_arguments(kwargs: dict, match: str) -> None:
    p, c = path(((0.0, 0.0, 0.0), False), ((0.01, 0.0, 0.0), True))
    with pytest.raises(InputError, match=match):
        zmap_engagement(p, Z_AXIS, c, R, box(), **kwargs)


@pytest.mark.parametrize(("call", "match"), [
    (lambda: zmap_engagement(np.zeros((4, 2)), Z_AXIS, np.ones(4, bool), R, box()), r"\(n, 3\)"),
    (lambda: zmap_engagement(np.zeros((4, 3)), Z_AXIS, np.ones(3, bool), R, box()), "cutting"),
    (lambda: zmap_engagement(np.zeros((4, 3)), Z_AXIS, np.ones(4, bool), 0.0, box()), "positive"),
    (lambda: zmap_engagement(np.zeros((4, 3)), Z_AXIS, np.ones(4, bool), R, "box"), "Stock"),
])
def test_bad_inputs(call, match: str) -> None:
    with pytest.raises(InputError, match=match):
        call()


def test_results_are_engagements_and_the_default_cell() -> None:
    e = zmap_engagement(np.zeros((0, 3)), Z_AXIS, np.zeros(0, bool), R, box())
    assert isinstance(e, Engagement) and len(e) == 0
    assert default_cell(R) == pytest.approx(CELL_FRACTION * R)


# --------------------------------------------------------------------------------------------------
# the batched grid update (planner._zmap_grid) is the one-step update
# --------------------------------------------------------------------------------------------------


def _one_step_sweep(grid, steps, k: int, radius: float):
    """Step k's sweep over its window, computed for that step alone (the formulas of the grid
    update): the window, the squared distances of the centres to the step's axis, the covered
    centres, the lowest tip height over them (inf where not covered)."""
    ax, ay, dx, dy = (float(c[k]) for c in (steps.ax, steps.ay, steps.dx, steps.dy))
    inv, za, dz = float(steps.inv[k]), float(steps.za[k]), float(steps.dz[k])
    r, r2, inv_c = radius, radius * radius, 1.0 / grid.cell
    i0 = max(math.ceil((min(ax, ax + dx) - r - grid.x0) * inv_c), 0)
    i1 = min(math.floor((max(ax, ax + dx) + r - grid.x0) * inv_c) + 1, grid.nx)
    j0 = max(math.ceil((min(ay, ay + dy) - r - grid.y0) * inv_c), 0)
    j1 = min(math.floor((max(ay, ay + dy) + r - grid.y0) * inv_c) + 1, grid.ny)
    if i0 >= i1 or j0 >= j1:
        return None
    rx, ry = grid.xc[i0:i1, None] - ax, grid.yc[None, j0:j1] - ay
    t = (rx * dx + ry * dy) * inv
    tc = np.clip(t, 0.0, 1.0)
    d2 = (rx - tc * dx) ** 2 + (ry - tc * dy) ** 2
    covered = d2 < r2
    if dz == 0.0:
        z = np.where(covered, za, np.inf)
    else:
        half = np.sqrt(np.maximum(r2 - (d2 - (t - tc) ** 2 / inv), 0.0) * inv)
        z = za + dz * np.clip(t + (half if dz < 0.0 else -half), 0.0, 1.0)
        z[~covered] = np.inf
    return (i0, i1, j0, j1), d2, covered, z


@pytest.mark.parametrize("cell", [CELL, R / 60])
def test_batched_grid_update_is_the_one_step_update(cell: float) -> None:
    """The grid computes the sweeps of a batch of steps at once (element by element the one-step
    formulas; at R/60 a window holds 14 400 cells and a batch a few steps), bit for bit, and
    cutting the steps a batch at a time leaves the grid as cutting them one by one: random level,
    sloped and vertical steps, and steps off the grid."""
    from planner._zmap_grid import HeightGrid, Steps

    rng = np.random.default_rng(7)
    n = 300
    pts = np.cumsum(rng.normal(0.0, 1.5e-3, (n, 3)) * [1.0, 1.0, 0.2], axis=0) + [0.05, 0.025, 0.018]
    pts[1::3, 2] = pts[0::3, 2]  # level steps
    pts[60, :2] = pts[59, :2]  # a vertical step
    pts[150:170, 0] += 1.0  # far off the grid
    clears = np.ones(n, bool)
    clears[[0, 50, 51]] = False
    sweep = np.flatnonzero(clears)
    steps = Steps(pts, clears)
    grids = [HeightGrid((0.0, 0.0, 0.1, 0.05), cell, 0.02, DEPTH_TOL, steps) for _ in range(2)]
    batch = grids[0]._geometry(sweep, R)
    assert 0 < len(batch) <= sweep.size
    for (k, i0, i1, j0, j1, d2, covered, z), kk in zip(batch, sweep, strict=False):
        ref = _one_step_sweep(grids[0], steps, int(kk), R)
        assert k == kk and (ref is None) == (d2 is None)
        if ref is not None:
            assert (i0, i1, j0, j1) == ref[0]
            np.testing.assert_array_equal(d2, ref[1])
            np.testing.assert_array_equal(covered, ref[2])
            np.testing.assert_array_equal(np.where(covered, z, np.inf), ref[3])
    grids[0].plan(sweep, R, compiled=False)
    grids[0].advance(sweep.size // 3)
    grids[0].advance(sweep.size)
    for k in sweep:
        grids[1].remove(int(k), R)
    for name in ("h", "owner", "dist", "last"):
        np.testing.assert_array_equal(getattr(grids[0], name), getattr(grids[1], name))
    assert np.any(grids[0].h < 0.02) and np.any(grids[0].owner[..., 2] >= 0)
    # the compiled loop (long paths) leaves the same grid, bit for bit, advanced in pieces too
    compiled = HeightGrid((0.0, 0.0, 0.1, 0.05), cell, 0.02, DEPTH_TOL, steps)
    compiled.plan(sweep, R, compiled=True)
    for count in (1, sweep.size // 3, sweep.size // 3, sweep.size):
        compiled.advance(count)
    for name in ("h", "owner", "dist", "last", "previous"):
        np.testing.assert_array_equal(getattr(compiled, name), getattr(grids[0], name))


def test_compiled_grid_is_chosen_for_long_paths_only(monkeypatch: pytest.MonkeyPatch) -> None:
    """By default the compiled loop cuts paths of COMPILED_STEPS steps or more, and every path
    once it is loaded; a short path in a fresh process keeps the numpy update (no 0.4 s load)."""
    import planner._zmap_grid as zg

    steps = zg.Steps(np.zeros((3, 3)), np.ones(3, bool))
    grid = zg.HeightGrid((0.0, 0.0, 0.01, 0.01), 1e-3, 0.0, DEPTH_TOL, steps)
    monkeypatch.setattr(zg, "_KERNEL", "planner._not_loaded")
    grid.plan(np.arange(3), R)
    assert not grid._compiled
    monkeypatch.setattr(zg, "COMPILED_STEPS", 3)
    grid.plan(np.arange(3), R)
    assert grid._compiled


def _demo_sampled(step_max_mm: float):
    """The demo job's path sampled every ``step_max_mm``, its stock and tool radius."""
    import tomllib
    from importlib import resources

    from planner.job import parse_job
    from planner.path import sample_toolpath
    from planner.prepare import read_job_toolpaths, tool_of

    demo = resources.files("planner").joinpath("data/demo/demo_job.toml")
    doc = tomllib.loads(demo.read_text(encoding="utf-8"))
    doc["path"]["step_max_mm"] = step_max_mm
    job = parse_job(doc, str(demo), Path(str(demo)).parent)
    si = job.to_si()
    path_ = sample_toolpath(list(read_job_toolpaths(job, si.chord_tol)), np.eye(4), si.chord_tol,
                            si.step_max)
    return path_, Stock.box(*si.stock_box, *si.stock_z), tool_of(job).radius


def test_compiled_and_numpy_engagement_agree_bit_for_bit(monkeypatch: pytest.MonkeyPatch) -> None:
    """The demo contour sampled every 0.5 mm (~3,000 steps, sloped lead-ins, both levels): the
    engagement read from the compiled grid is the numpy grid's, bit for bit."""
    import planner._zmap_grid as zg

    path_, stock, radius = _demo_sampled(0.5)
    args = (path_.position_wp, path_.tool_axis_wp, path_.cutting, radius, stock)
    results = []
    for threshold, kernel in ((10**12, "planner._not_loaded"), (0, zg._KERNEL)):
        monkeypatch.setattr(zg, "COMPILED_STEPS", threshold)
        monkeypatch.setattr(zg, "_KERNEL", kernel)
        results.append(zmap_engagement(*args, where=path_.where))
    numpy_, compiled = results
    assert np.sum(numpy_.mode >= 0) > 2_000
    for name in ("a_e", "a_p", "mode", "radial_dir", "engaged_angle", "feed_dir", "plunge"):
        np.testing.assert_array_equal(getattr(compiled, name), getattr(numpy_, name))
    assert compiled.warnings == numpy_.warnings


def test_fine_sampling_reads_what_the_level_above_removed() -> None:
    """The demo contour sampled every 0.15 mm (several steps to a 1.27 mm cell): on the second
    level (z = −20 mm) a_p is the 10 mm level step everywhere, as the 2.5-D model says — the probes
    on the first level's boundary are covered by steps further along than the cells' owners, and
    were read as the uncut 20 mm before."""
    path_, stock, radius = _demo_sampled(0.15)
    assert len(path_) > 10_000
    z = zmap_engagement(path_.position_wp, path_.tool_axis_wp, path_.cutting, radius, stock)
    engaged = z.mode >= 0
    assert engaged.sum() > 8_000
    assert z.a_p[engaged].max() <= 10e-3 + 1e-9
