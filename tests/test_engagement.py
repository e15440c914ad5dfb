"""Tests of planner/engagement.py: hand-made 2.5-D cuts whose engagement is known, the cutting-frame
convention (docs/model.md §4, right-hand cutter turning M03), and the input checks.

Convention under test (module docstring): Y_o = the tool axis a (tip → spindle), X_o = a × f. For a
vertical tool (a = +Z) seen from above, X_o is the feed turned 90° counter-clockwise (its left).
Up milling has the material on +X_o, down (climb) milling on −X_o.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from models.analysis import Cut
from models.cutting import MILLING_MODES
from models.errors import InputError
from planner.engagement import (
    AIR,
    ANGULAR_RESOLUTION,
    Engagement,
    Stock,
    fixed_engagement,
    stock_engagement,
)

R = 6e-3  # tool radius [m]
UP, DOWN, SLOT = MILLING_MODES["up"], MILLING_MODES["down"], MILLING_MODES["slot"]
Z_AXIS = np.array([0.0, 0.0, 1.0])
STEP = 0.5e-3  # sample spacing along the path [m]
# The arc's open end is refined by bisection to ANGULAR_RESOLUTION / 1024 (3.4e-5 rad at 2°), so a_e
# is resolved to R · 3.4e-5 ≈ 0.2 µm; the swept polygons' straight flanks are exact. 1 µm is safe.
AE_TOL = 1e-6  # [m]


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


def inside(p: np.ndarray, x0: float, x1: float) -> np.ndarray:
    """Samples whose tool centre lies between x0 and x1 [m]."""
    return (p[:, 0] > x0) & (p[:, 0] < x1)


# --------------------------------------------------------------------------------------------------
# 1. slot
# --------------------------------------------------------------------------------------------------


def test_slot_through_box() -> None:
    p, c = path(((-0.01, 0.025, 0.03), False), ((-0.01, 0.025, 0.015), False),
                ((0.11, 0.025, 0.015), True))
    e = stock_engagement(p, Z_AXIS, c, R, box())
    full = inside(p, R + 1e-3, 0.1 - 1e-3) & c  # tool front fully inside the stock
    assert full.sum() > 100
    assert np.all(e.mode[full] == SLOT)
    np.testing.assert_allclose(e.a_e[full], 2 * R, rtol=0, atol=1e-12)
    np.testing.assert_allclose(e.a_p[full], 0.02 - 0.015, rtol=0, atol=1e-12)
    np.testing.assert_allclose(e.engaged_angle[full], math.pi, atol=1e-12)
    # Frame: feed +x, X_o = +Z × +x = +y, Y_o = Z_o × X_o = +Z, the tool axis (tip → spindle).
    np.testing.assert_allclose(e.feed_dir[full], [[1, 0, 0]] * full.sum(), atol=1e-12)
    np.testing.assert_allclose(e.radial_dir[full], [[0, 1, 0]] * full.sum(), atol=1e-12)
    np.testing.assert_allclose(np.cross(e.feed_dir[full], e.radial_dir[full]),
                               [Z_AXIS] * full.sum(), atol=1e-12)
    # Before the stock and after it: air.
    assert np.all(e.mode[p[:, 0] < -R] == AIR)
    assert np.all(e.mode[p[:, 0] > 0.1 + R] == AIR)
    # Entering: the disc is partly in the stock, the arc touches both sides once past x = 0.
    entering = inside(p, -R + 1e-4, 0.0) & c
    assert np.all(e.mode[entering] != AIR) and np.all(e.a_e[entering] <= 2 * R + 1e-12)


# --------------------------------------------------------------------------------------------------
# 2. side cut along a straight wall: a_e and up/down for both directions of travel
# --------------------------------------------------------------------------------------------------

# The cutter turns clockwise seen from above (M03, right-hand cutter, axis +Z): ω = −Ω Z. The edge on
# the tool's +y side moves along ω × (R y) = +ΩR x; on the −y side along ω × (−R y) = −ΩR x.
# * Travel +x, material on +y (the tool's left): on that side the edge moves along the feed, parallel
#   to the wall the previous tooth left — it enters tangentially with zero chip that then grows:
#   up (conventional) milling. Material is on +X_o (X_o = Z × x = +y).
# * Travel +x, material on −y (right): the edge there moves against the feed; it enters at the
#   front with the thickest chip and leaves tangentially: down (climb) milling, material on −X_o.
# * Travel −x swaps left and right: material on −y is now on the left (X_o = Z × (−x) = −y) → up;
#   material on +y → down.
A_E = 3e-3  # radial overlap with the stock [m]
SIDE_CASES = [
    # (tool centre y, material side, direction of travel, expected mode)
    (-R + A_E, "+y", +1, UP),
    (-R + A_E, "+y", -1, DOWN),
    (0.05 + R - A_E, "-y", +1, DOWN),
    (0.05 + R - A_E, "-y", -1, UP),
]


@pytest.mark.parametrize(("y", "side", "direction", "expected"), SIDE_CASES)
def test_side_cut_radial_depth_and_mode(y: float, side: str, direction: int, expected: int) -> None:
    x0, x1 = (-0.01, 0.11) if direction > 0 else (0.11, -0.01)
    p, c = path(((x0, y, 0.015), False), ((x1, y, 0.015), True))
    e = stock_engagement(p, Z_AXIS, c, R, box())
    mid = inside(p, 0.02, 0.08)
    assert np.all(e.mode[mid] == expected), f"material on {side}, travel {direction:+d}"
    np.testing.assert_allclose(e.a_e[mid], A_E, rtol=0, atol=AE_TOL)
    np.testing.assert_allclose(e.a_p[mid], 0.005, rtol=0, atol=1e-12)
    np.testing.assert_allclose(e.engaged_angle[mid], math.acos(1 - A_E / R), atol=1e-3)
    # The material lies on +X_o for up milling, on −X_o for down milling.
    material_dir = np.array([0.0, 1.0 if side == "+y" else -1.0, 0.0])
    sign = 1.0 if expected == UP else -1.0
    np.testing.assert_allclose(e.radial_dir[mid] @ material_dir, sign, atol=1e-12)


# --------------------------------------------------------------------------------------------------
# 3. step-over: the second pass cuts exactly the step-over
# --------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("zigzag", [True, False])
def test_second_pass_cuts_the_step_over(zigzag: bool) -> None:
    # Pass 1 along +x overlaps the stock's +y edge (y = 50 mm) by 4 mm: material below, on its right
    # (−X_o): down milling. Pass 2 is 2 mm further into the stock: pass 1 cleared all but those 2 mm.
    z, y1, step_over = 0.015, 0.05 + R - 4e-3, 2e-3
    y2 = y1 - step_over
    legs = [((-0.01, y1, z), False), ((0.11, y1, z), True)]
    if zigzag:  # a short feed step-over, then back along −x: material on the left (+X_o = −y): up
        legs += [((0.11, y2, z), True), ((-0.01, y2, z), True)]
        second_mode = UP
    else:  # rapid back over the top, same direction: down again
        legs += [((0.11, y1, 0.03), False), ((-0.01, y2, 0.03), False), ((-0.01, y2, z), False),
                 ((0.11, y2, z), True)]
        second_mode = DOWN
    p, c = path(*legs)
    e = stock_engagement(p, Z_AXIS, c, R, box())
    mid = inside(p, 0.02, 0.08)
    first = mid & np.isclose(p[:, 1], y1)
    second = mid & np.isclose(p[:, 1], y2)
    assert first.sum() > 50 and second.sum() > 50
    assert np.all(e.mode[first] == DOWN)
    np.testing.assert_allclose(e.a_e[first], 4e-3, rtol=0, atol=AE_TOL)
    assert np.all(e.mode[second] == second_mode)
    np.testing.assert_allclose(e.a_e[second], step_over, rtol=0, atol=AE_TOL)
    # A third pass retracing the second exactly finds nothing left.
    p3 = np.vstack([p, [[0.11, y2, z]], [[0.05, y2, z]]])
    e3 = stock_engagement(p3, Z_AXIS, np.concatenate([c, [True, True]]), R, box())
    assert e3.mode[-1] == AIR and e3.a_e[-1] == 0.0


def test_pocket_levels_and_step_over() -> None:
    """A zig-zag pocket, two levels of 3 mm, step-over R/2 (several batches, some thousand samples)."""
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
    e = stock_engagement(p, Z_AXIS, c, R, box())
    assert p.shape[0] > 1000
    for z in (0.017, 0.014):
        for k, y in enumerate(ys):
            sel = c & np.isclose(p[:, 2], z) & np.isclose(p[:, 1], y) & inside(p, x0 + R, x1 - R)
            assert sel.sum() > 50
            # Level step: the first level cuts below the top, the second below the first.
            np.testing.assert_allclose(e.a_p[sel], 3e-3, rtol=0, atol=1e-9)
            if k == 0:
                assert np.all(e.mode[sel] == SLOT)
            else:  # passes alternate direction; the material is always on the +y side
                assert np.all(e.mode[sel] == (UP if k % 2 == 0 else DOWN))
                np.testing.assert_allclose(e.a_e[sel], step_over, rtol=0, atol=AE_TOL)
    plunges = c & (np.diff(p[:, 2], prepend=p[0, 2]) < -1e-6)
    assert plunges.sum() > 0 and np.all(e.plunge[plunges]) and np.all(e.mode[plunges] == AIR)


# --------------------------------------------------------------------------------------------------
# 4. air
# --------------------------------------------------------------------------------------------------


def test_air_moves() -> None:
    # Beside the stock (1 mm clear of the +y face), above it, and a rapid through it.
    p1, c1 = path(((-0.01, 0.05 + R + 1e-3, 0.015), False), ((0.11, 0.05 + R + 1e-3, 0.015), True))
    p2, c2 = path(((-0.01, 0.025, 0.025), False), ((0.11, 0.025, 0.025), True))
    p3, c3 = path(((-0.01, 0.025, 0.015), False), ((0.11, 0.025, 0.015), False))
    for p, c in ((p1, c1), (p2, c2), (p3, c3)):
        e = stock_engagement(p, Z_AXIS, c, R, box())
        assert np.all(e.mode == AIR)
        assert np.all(e.a_e == 0.0) and np.all(e.a_p == 0.0) and np.all(e.engaged_angle == 0.0)
        assert np.all(e.radial_dir == 0.0) and np.all(e.feed_dir == 0.0)
        assert not e.cutting.any()
    # A rapid clears nothing: a feed pass along the same line afterwards is a full slot.
    p = np.vstack([p3, p3[::-1]])
    c = np.concatenate([c3, np.ones(len(p3), bool)])
    e = stock_engagement(p, Z_AXIS, c, R, box())
    mid = c & inside(p, 0.02, 0.08)
    assert np.all(e.mode[mid] == SLOT)


# --------------------------------------------------------------------------------------------------
# 5. Z levels
# --------------------------------------------------------------------------------------------------


def test_second_level_axial_depth_is_the_level_step() -> None:
    y, top = 0.025, 0.02
    p, c = path(((-0.01, y, 0.03), False), ((-0.01, y, 0.017), False), ((0.11, y, 0.017), True),
                ((0.11, y, 0.014), False), ((-0.01, y, 0.014), True),
                # a third pass, 4 mm to the side at the second level: its arc runs partly under the
                # first level's slot and partly under the untouched top — the tallest wall counts
                ((-0.01, y + 4e-3, 0.014), False), ((0.11, y + 4e-3, 0.014), True))
    e = stock_engagement(p, Z_AXIS, c, R, box())
    mid = c & inside(p, 0.02, 0.08)
    lvl1 = mid & np.isclose(p[:, 2], 0.017)
    lvl2 = mid & np.isclose(p[:, 2], 0.014) & np.isclose(p[:, 1], y)
    side = mid & np.isclose(p[:, 1], y + 4e-3)
    np.testing.assert_allclose(e.a_p[lvl1], top - 0.017, atol=1e-12)
    np.testing.assert_allclose(e.a_p[lvl2], 0.017 - 0.014, atol=1e-12)  # not top − 0.014
    assert np.all(e.mode[lvl2] == SLOT)
    np.testing.assert_allclose(e.a_p[side], top - 0.014, atol=1e-12)
    # Travel +x 4 mm to the +y side of the slot at this level: the slot (on the right) is cleared
    # below the tool down to 14 mm by the pass before, so the material is on the left: up, a_e 4 mm.
    assert np.all(e.mode[side] == UP)
    np.testing.assert_allclose(e.a_e[side], 4e-3, atol=AE_TOL)


def test_level_tolerance_merges_rounding_only() -> None:
    # A second pass 5 µm lower is the same level (rounding, LEVEL_TOL = 10 µm): nothing left to cut.
    # 50 µm lower it is a floor pass of its own: a slot 50 µm deep.
    y = 0.025
    for dz, expect_air in ((5e-6, True), (5e-5, False)):
        p, c = path(((-0.01, y, 0.015), False), ((0.11, y, 0.015), True),
                    ((0.11, y, 0.015 - dz), False), ((-0.01, y, 0.015 - dz), True))
        e = stock_engagement(p, Z_AXIS, c, R, box())
        second = c & inside(p, 0.02, 0.08) & np.isclose(p[:, 2], 0.015 - dz, atol=0, rtol=1e-12)
        if expect_air:
            assert np.all(e.mode[second] == AIR)
        else:
            assert np.all(e.mode[second] == SLOT)
            np.testing.assert_allclose(e.a_p[second], dz, atol=1e-12)


# --------------------------------------------------------------------------------------------------
# 6. fixed engagement and the frame
# --------------------------------------------------------------------------------------------------


def test_fixed_engagement_frame(rng: np.random.Generator) -> None:
    n = 200
    feed = rng.normal(size=(n, 3))
    axis = rng.normal(size=(n, 3))
    cut = rng.random(n) < 0.8
    e = fixed_engagement(n, 3e-3, 5e-3, "down", feed, axis, cut, tool_radius=R)
    f = feed / np.linalg.norm(feed, axis=1, keepdims=True)
    a = axis / np.linalg.norm(axis, axis=1, keepdims=True)
    x = e.radial_dir[cut]
    np.testing.assert_allclose(np.linalg.norm(x, axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose(np.einsum("ij,ij->i", x, f[cut]), 0.0, atol=1e-12)  # X_o ⟂ Z_o
    np.testing.assert_allclose(np.einsum("ij,ij->i", x, a[cut]), 0.0, atol=1e-12)  # X_o ⟂ a
    # Y_o = Z_o × X_o is the tool axis' part normal to the feed, pointing towards the spindle.
    y_o = np.cross(f[cut], x)
    a_perp = a[cut] - np.einsum("ij,ij->i", a[cut], f[cut])[:, None] * f[cut]
    np.testing.assert_allclose(y_o, a_perp / np.linalg.norm(a_perp, axis=1, keepdims=True),
                               atol=1e-12)
    np.testing.assert_allclose(e.feed_dir[cut], f[cut], atol=1e-12)
    assert np.all(e.mode[cut] == DOWN) and np.all(e.mode[~cut] == AIR)
    assert np.all(e.a_e[cut] == 3e-3) and np.all(e.a_p[cut] == 5e-3)
    assert np.all(e.a_e[~cut] == 0) and np.all(e.radial_dir[~cut] == 0)
    np.testing.assert_allclose(e.engaged_angle[cut], math.acos(1 - 3e-3 / R))
    # Feed normal to the axis: Y_o is exactly the axis.
    f2 = np.cross(a, rng.normal(size=(n, 3)))
    e2 = fixed_engagement(n, 2 * R, 5e-3, "slot", f2, a, np.ones(n, bool), tool_radius=R)
    np.testing.assert_allclose(np.cross(e2.feed_dir, e2.radial_dir), a, atol=1e-12)
    np.testing.assert_allclose(e2.engaged_angle, math.pi)


def test_fixed_engagement_vertical_tool_left_normal_and_plunge() -> None:
    feed = np.array([[1.0, 0, 0], [0, 1.0, 0], [1.0, 0, -0.1], [0, 0, -1.0], [0, 0, 1.0]])
    e = fixed_engagement(5, 3e-3, 5e-3, "up", feed, Z_AXIS, np.ones(5, bool))
    # X_o is the feed turned 90° counter-clockwise seen from above (its left).
    np.testing.assert_allclose(e.radial_dir[:3], [[0, 1, 0], [-1, 0, 0], [0, 1, 0]], atol=1e-12)
    assert list(e.plunge) == [False, False, False, True, True]
    assert list(e.mode) == [UP, UP, UP, AIR, AIR]
    assert np.all(np.isnan(e.engaged_angle[:3]))  # no tool radius given


def test_fixed_and_stock_agree_on_the_frame_and_cut_accepts_it() -> None:
    y = 0.05 + R - A_E
    p, c = path(((0.11, y, 0.015), False), ((-0.01, y, 0.015), True))
    es = stock_engagement(p, Z_AXIS, c, R, box())
    mid = inside(p, 0.02, 0.08)
    ef = fixed_engagement(len(p), A_E, 5e-3, "up", es.feed_dir, Z_AXIS, mid, tool_radius=R)
    np.testing.assert_allclose(ef.radial_dir[mid], es.radial_dir[mid], atol=1e-12)
    np.testing.assert_allclose(ef.engaged_angle[mid], es.engaged_angle[mid], atol=1e-3)
    i = int(np.flatnonzero(mid)[0])
    mode = {v: k for k, v in MILLING_MODES.items()}[int(es.mode[i])]
    cut = Cut(feed_dir=es.feed_dir[i], radial_dir=es.radial_dir[i], a_e=float(es.a_e[i]),
              a_p=float(es.a_p[i]), mode=mode, spindle_speed=100.0, flutes=2, radius=R)
    np.testing.assert_allclose(cut.axial_dir, Z_AXIS, atol=1e-12)  # Y_o = tool axis, to spindle


# --------------------------------------------------------------------------------------------------
# 7. errors
# --------------------------------------------------------------------------------------------------


def test_tilted_tool_is_rejected() -> None:
    p, c = path(((-0.01, 0.025, 0.015), False), ((0.11, 0.025, 0.015), True))
    tilted = np.array([math.sin(math.radians(1.0)), 0.0, math.cos(math.radians(1.0))])
    with pytest.raises(InputError, match="needs a vertical tool.*use fixed engagement"):
        stock_engagement(p, tilted, c, R, box())
    # Rapids may carry any axis; a tilt within VERTICAL_AXIS_TOL passes.
    stock_engagement(p, [0.0, 1e-4, 1.0], c, R, box())
    # With the samples' source lines, the message names the line.
    with pytest.raises(InputError, match=r"sample 1 \(part.nc:12\): the tool axis"):
        stock_engagement(p, tilted, c, R, box(), where=lambda i: "part.nc:12")


def test_stock_a_e_never_exceeds_the_diameter_and_a_p_is_positive() -> None:
    """Every cutting sample of the 2.5-D model has 0 < a_e ≤ 2R and a_p > 0 (the guards)."""
    p, c = path(((-0.01, 0.025, 0.03), False), ((-0.01, 0.025, -0.005), False),
                ((0.11, 0.025, -0.005), True), ((0.11, 0.03, -0.008), True),
                ((-0.01, 0.03, -0.008), True))
    e = stock_engagement(p, Z_AXIS, c, R, box())
    cut = e.mode != AIR
    assert cut.sum() > 100
    assert np.all(e.a_e[cut] > 0) and np.all(e.a_e <= 2 * R) and np.all(e.a_p[cut] > 0)
    # Two runs in the stock, 5 and 8 mm below its bottom (the step-over beside it is outside).
    assert np.all(e.a_p >= 0) and len(e.warnings) == 2
    assert all("below the stock bottom" in w for w in e.warnings)


@pytest.mark.parametrize(("make", "match"), [
    (lambda: Stock.box(0, 0, 0.1, 0.05, 0.02, 0.02), "z_top .* must lie above z_bottom"),
    (lambda: Stock.box(0, 0, 0.1, 0.05, 0.03, 0.02), "z_top .* must lie above z_bottom"),
    (lambda: Stock.box(0, 0, 0.0, 0.05, 0.0, 0.02), "xmax > xmin"),
    (lambda: Stock([(0, 0), (0.1, 0)], 0.0, 0.02), "at least 3"),
    (lambda: Stock([(0, 0), (0.1, 0), (0.2, 0)], 0.0, 0.02), "no area"),
    (lambda: Stock([(0, 0), (0.1, 0.1), (0.1, 0), (0, 0.1)], 0.0, 0.02), "not a simple polygon"),
    (lambda: Stock([(0, 0), (0.1, 0), (0.1, math.nan)], 0.0, 0.02), "finite"),
    (lambda: Stock("abc", 0.0, 0.02), "pairs"),
])
def test_bad_stock(make, match: str) -> None:
    with pytest.raises(InputError, match=match):
        make()


@pytest.mark.parametrize(("call", "match"), [
    (lambda: stock_engagement(np.zeros((4, 2)), Z_AXIS, np.ones(4, bool), R, box()), r"shape \(n, 3\)"),
    (lambda: stock_engagement(np.zeros((4, 3)), Z_AXIS, np.ones(3, bool), R, box()), "cutting"),
    (lambda: stock_engagement(np.zeros((4, 3)), Z_AXIS, np.ones(4, bool), 0.0, box()), "positive"),
    (lambda: stock_engagement(np.zeros((4, 3)), np.zeros(3), np.ones(4, bool), R, box()), "zero"),
    (lambda: stock_engagement(np.zeros((4, 3)), Z_AXIS, np.ones(4, bool), R, "box"), "Stock"),
    (lambda: fixed_engagement(3, 1e-3, 1e-3, "sideways", np.eye(3), Z_AXIS, np.ones(3, bool)),
     "not one of"),
    (lambda: fixed_engagement(3, 1e-3, 0.0, "up", np.eye(3), Z_AXIS, np.ones(3, bool)), "positive"),
    (lambda: fixed_engagement(3, 1e-3, 1e-3, "up", np.zeros((3, 3)), Z_AXIS, np.ones(3, bool)),
     "no feed direction"),
    (lambda: fixed_engagement(3, 3 * R, 1e-3, "up", np.eye(3), Z_AXIS, np.ones(3, bool),
                              tool_radius=R), "exceeds the tool diameter"),
    (lambda: fixed_engagement(3, R, 1e-3, "slot", np.eye(3), Z_AXIS, np.ones(3, bool),
                              tool_radius=R), "full diameter"),
])
def test_bad_arguments(call, match: str) -> None:
    with pytest.raises(InputError, match=match):
        call()


def test_results_are_engagements() -> None:
    e = fixed_engagement(0, 1e-3, 1e-3, "up", np.zeros((0, 3)), Z_AXIS, np.zeros(0, bool))
    assert isinstance(e, Engagement) and len(e) == 0
    assert ANGULAR_RESOLUTION < math.radians(5)


# --------------------------------------------------------------------------------------------------
# curved path: the arc follows the geometry, not the straight-cut formula
# --------------------------------------------------------------------------------------------------


@pytest.mark.parametrize(("turn", "expected"), [(+1, UP), (-1, DOWN)])
def test_contour_around_a_round_boss(turn: int, expected: int) -> None:
    # A round boss of radius r_w (the stock), the tool centre on a circle d = r_w + R − 3 mm around
    # it. Counter-clockwise seen from above (turn +1) the boss is on the feed's left, +X_o: up
    # milling; clockwise it is on the right: down. The tool circle meets the uncut boss where
    # r_w² = R² + d² − 2 R d cos φ (law of cosines at the tool centre, φ from the direction to the
    # boss centre), and touches the finished contour at φ = 0 (up) or π (down).
    r_w, depth, z = 0.02, 3e-3, 0.015
    d = r_w + R - depth
    ang = np.linspace(0.0, 2 * math.pi, 721)[:-1]
    boss = Stock(list(zip(0.05 + r_w * np.cos(ang), 0.025 + r_w * np.sin(ang), strict=True)),
                 0.0, 0.02)
    t = turn * np.linspace(0.0, 1.5 * math.pi, 600)
    p = np.column_stack([0.05 + d * np.cos(t), 0.025 + d * np.sin(t), np.full(t.size, z)])
    c = np.ones(t.size, bool)
    c[0] = False
    e = stock_engagement(p, Z_AXIS, c, R, boss)
    mid = slice(100, 500)
    assert np.all(e.mode[mid] == expected)
    phi = math.acos((R**2 + d**2 - r_w**2) / (2 * R * d))
    # The boss polygon's chords lie ≤ r_w (1 − cos(π/720)) ≈ 0.2 µm inside the circle: ≈ 4e-5 rad.
    np.testing.assert_allclose(e.engaged_angle[mid], phi, atol=1e-4)
    # Narrower than the straight cut of the same depth (R (1 − cos φ) < 3 mm on a convex contour).
    assert np.all(e.a_e[mid] < depth)
    # X_o points to the boss centre for up milling, away from it for down milling (to within half
    # a step's turn, 0.004 rad: the frame follows the arriving step, the arc is measured about the
    # tangent).
    to_centre = np.array([0.05, 0.025, z]) - p[mid]
    to_centre /= np.linalg.norm(to_centre, axis=1, keepdims=True)
    np.testing.assert_allclose(np.einsum("ij,ij->i", e.radial_dir[mid], to_centre),
                               1.0 if expected == UP else -1.0, atol=1e-4)
    # The frame's feed is the arriving step, as PathSamples.feed_dir, so Cut accepts that pairing.
    chord = np.diff(p, axis=0)[99:499]
    chord /= np.linalg.norm(chord, axis=1, keepdims=True)
    np.testing.assert_allclose(e.feed_dir[mid], chord, atol=1e-12)
    mode = {v: k for k, v in MILLING_MODES.items()}[expected]
    for i in (150, 300, 450):
        Cut(feed_dir=chord[i - 100], radial_dir=e.radial_dir[i], a_e=float(e.a_e[i]),
            a_p=float(e.a_p[i]), mode=mode, spindle_speed=100.0, flutes=2, radius=R)


def test_helical_ramp_axial_depth_is_the_pitch() -> None:
    # A helix (radius 3 mm, 1 mm per turn) from 1 mm above the top down to 2 mm below it. On its last
    # turn the tool meets the material left under the turn before: a_p is the pitch (to the ramp
    # bands of RAMP_LEVEL_TOL = 0.1 mm), not the depth below the top.
    th = np.linspace(0.0, 6 * math.pi, 540)
    p = np.column_stack([0.05 + 3e-3 * np.cos(th), 0.025 + 3e-3 * np.sin(th),
                         0.021 - th / (2 * math.pi) * 1e-3])
    c = np.ones(th.size, bool)
    c[0] = False
    e = stock_engagement(p, Z_AXIS, c, R, box())
    first_turn = p[:, 2] > 0.02
    last_turn = th > 4.2 * math.pi
    assert np.all(e.mode[first_turn] == AIR)
    assert np.all(e.mode[last_turn] != AIR)
    assert np.all(np.abs(e.a_p[last_turn] - 1e-3) <= 1.1e-4)
