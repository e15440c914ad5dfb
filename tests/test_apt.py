"""Tests of the APT/CL reader (robot_io.apt).

The shared SolidWorks CAM files are pinned against numbers derived *without* this reader (see the
comment above ``SHARED``); CIRCLE and CSYS conventions are checked on the real data and on
hand-computed examples; malformed input is table-driven; a seeded fuzz test checks that nothing
but ToolpathError ever escapes.
"""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import mutate

from models.errors import InputError
from robot_io.apt import AptReader, read_apt, read_apt_text
from robot_io.readers import read_toolpath
from robot_io.toolpath import MoveKind, ToolpathError, arc_geometry, summarize

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "toolpaths"
MM = 1e-3
IN = 0.0254
MMPM = MM / 60.0   # one mm/min [m/s]
# four-line preamble: mm, a feed, a rapid to the origin (so later moves have a known start)
PRE = "UNITS/MM\nFEDRAT/600,MMPM\nRAPID\nGOTO/0,0,0\n"


def _data(name: str) -> Path:
    path = DATA / name
    if not path.is_file():
        pytest.skip(f"shared toolpath data not found at {path} (expected the repo next to "
                    "../shared/data/toolpaths)")
    return path


def _mm(v: np.ndarray) -> list[float]:
    return list(np.round(np.asarray(v) / MM, 9))


# --------------------------------------------------------------------------- shared programs
# Pinned values, all derived independently of cctmill:
#   moves/rapids/arcs: `grep -c '^GOTO/'`, `grep -c '^RAPID'`, `grep -c '^CIRCLE/'` — exact for the
#     boss file (no cycles: 9814 / 775 / 1026); with drilling cycles the count comes from the
#     throw-away script below (each hole GOTO → rapid to p+RTRCTO·a unless already within 10 µm,
#     rapid to p+RAPTO·a, feed to p−FEDTO·a, rapid back to p+RTRCTO·a).
#   length, bbox: a throw-away ~50-line plain-Python script (not kept; `line.partition('/')`,
#     `float()` per field, math module only, millimetres): straight moves = math.dist; CIRCLE arcs
#     = r·angle with angle = atan2((e−c)·v, (e−c)·u) mod 2π (0 → 2π), u = (s−c)/r, v = axis × u
#     (counter-clockwise about the circle axis); the first move (unknown start) has no length;
#     bbox = all end points plus 40 001 points sampled along every arc (sampling error < 1e-11 m
#     here); the tool axis of GOTO i,j,k normalised, else the CSYS third column.
#   The script's output (mm): boss 272887.529258106, lo (-5.381909, -4.9375, -125.381909),
#     hi (120, 154.9375, 25); board 29938.924023703, lo (-52.5, 17.4999999107, -55),
#     hi (492.5, 150, 25); tilted 4488.623439084, lo (-38.637201, -8.8, -16.1029016875),
#     hi (38.868241, 48.8, 252.786043).
#   warnings: `grep -c '^CUTCOM/LEFT'` (81 and 42) — the only warnings these files give.
SHARED = {
    "solidworkscam_boss_3plus2.apt": dict(
        moves=9814, rapids=775, arcs=1026, length=272.887529258106,
        bbox=[[-5.381909 * MM, -4.9375 * MM, -125.381909 * MM], [120 * MM, 154.9375 * MM, 25 * MM]],
        warnings={"cutter_compensation": 81}, cycles=0),
    "solidworkscam_sacrifice_board.apt": dict(
        moves=574, rapids=230, arcs=70, length=29.938924023703,
        bbox=[[-52.5 * MM, 17.4999999107 * MM, -55 * MM], [492.5 * MM, 150 * MM, 25 * MM]],
        warnings={"cutter_compensation": 42}, cycles=4),
    "solidworkscam_tilted_axis.apt": dict(
        moves=194, rapids=46, arcs=0, length=4.488623439084,
        bbox=[[-38.637201 * MM, -8.8 * MM, -16.1029016875 * MM],
              [38.868241 * MM, 48.8 * MM, 252.786043 * MM]],
        warnings={}, cycles=2),
}


@pytest.mark.parametrize("name", sorted(SHARED))
def test_shared_program_reads_strict_with_pinned_summary(name: str) -> None:
    exp = SHARED[name]
    tp = read_apt(_data(name))
    s = summarize(tp)
    assert s["moves"] == exp["moves"]
    assert s["rapids"] == exp["rapids"]
    assert s["arcs"] == exp["arcs"]
    assert s["length_m"] == pytest.approx(exp["length"], rel=1e-11)
    np.testing.assert_allclose(s["bbox_m"], exp["bbox"], rtol=0, atol=1e-11)
    assert tp.meta["warning_counts"] == exp["warnings"]
    assert {w.category for w in tp.warnings} == set(exp["warnings"])
    assert dict(tp.skipped) == {}
    assert tp.units == "mm" and tp.format == "apt" and s["inverse_time_moves"] == 0
    assert s["has_tool_axis"] and all(m.tool_axis is not None for m in tp.moves)
    assert all(abs(np.linalg.norm(m.tool_axis) - 1) < 1e-12 for m in tp.moves)
    assert len(tp.meta["cycles"]) == exp["cycles"]
    assert tp.meta["program"] == "1"
    assert all(m.feed is not None and m.feed > 0 for m in tp.moves if m.kind != MoveKind.RAPID)
    for prev, m in zip(tp.moves, tp.moves[1:], strict=False):
        assert m.start is prev.end   # continuous, and shared


def test_shared_program_lenient_equals_strict() -> None:
    path = _data("solidworkscam_sacrifice_board.apt")
    strict, lenient = read_apt(path), read_apt(path, strict=False)
    assert summarize(strict) == summarize(lenient)


def test_shared_feeds_spindle_tools_and_meta() -> None:
    tp = read_apt(_data("solidworkscam_tilted_axis.apt"))
    # line 20: FEDRAT/125.,MMPM → the plunge at line 21
    plunge = next(m for m in tp.moves if m.source.line == 21)
    assert plunge.feed == pytest.approx(125 * MMPM) and plunge.kind == MoveKind.LINEAR
    assert plunge.spindle_rpm == 10156 and plunge.tool == 4
    assert sorted({round(m.feed / MMPM, 6) for m in tp.moves if m.feed}) == pytest.approx(
        [125, 127, 731.52, 1097.28, 6423.814368, 8565.085823])
    assert [c["tool"] for c in tp.meta["cutters"]] == [4, 6, 16]
    c0 = tp.meta["cutters"][0]
    assert c0["diameter_m"] == pytest.approx(16 * MM) and c0["corner_radius_m"] == 0
    assert c0["flute_length_m"] == pytest.approx(32 * MM)
    assert c0["extension_length_m"] == pytest.approx(60 * MM)
    assert tp.meta["selected_tools"] == [6, 16]
    assert tp.meta["trntyp"] == "WORLD"
    assert tp.meta["record_counts"]["GOTO"] == 184 and tp.meta["record_counts"]["FINI"] == 1
    # the expanded centre drill (line 323: DRILL, FEDTO 2.75344, RAPTO 3, RTRCTO 10, 731.52 mm/min)
    drill = [m for m in tp.moves if m.extra.get("cycle") == "DRILL"]
    assert [m.kind for m in drill] == [MoveKind.RAPID, MoveKind.LINEAR, MoveKind.RAPID] + [
        MoveKind.RAPID, MoveKind.RAPID, MoveKind.LINEAR, MoveKind.RAPID]
    a = np.array([-0.173648, 0, 0.984808]) / np.linalg.norm([-0.173648, 0, 0.984808])
    hole = np.array([15.756924, 10.0, -6.156343]) * MM
    np.testing.assert_allclose(drill[0].end, hole + 3 * MM * a, atol=1e-12)
    np.testing.assert_allclose(drill[1].end, hole - 2.75344 * MM * a, atol=1e-12)
    np.testing.assert_allclose(drill[2].end, hole + 10 * MM * a, atol=1e-12)
    assert drill[1].feed == pytest.approx(731.52 * MMPM)
    assert tp.meta["cycles"][1]["pecks_ignored"] and tp.meta["cycles"][1]["holes"] == 2


# --------------------------------------------------------------------------- CSYS on real data
def test_csys_layout_from_the_tilted_file() -> None:
    """CSYS is the APT matrix [R | t] row by row; R's columns are the setup axes in the frame the
    GOTOs are written in. Seen in the data: the GOTO i,j,k is R's third column, and in setup
    coordinates Rᵀ(p − t) the first facing pass lies at z = −1 mm and its approach at z = +3 mm
    (the transposed reading would put the pass on a slope across y)."""
    tp = read_apt(_data("solidworkscam_tilted_axis.apt"))
    frame = tp.meta["frames"][0]
    assert frame["record"] == "CSYS" and frame["line"] == 13
    r, t = np.array(frame["rotation"]), np.array(frame["origin_m"])
    np.testing.assert_allclose(r @ r.T, np.eye(3), atol=2e-6)
    assert np.linalg.det(r) == pytest.approx(1, abs=2e-6)
    for m in tp.moves:
        np.testing.assert_allclose(m.tool_axis, r[:, 2] / np.linalg.norm(r[:, 2]), atol=1e-15)
    local = {m.source.line: r.T @ (m.end - t) for m in tp.moves if m.source.line <= 45}
    assert local[19][2] == pytest.approx(3 * MM, abs=1e-8)            # approach
    passes = [ln for ln, m in zip(local, tp.moves, strict=False) if m.kind == MoveKind.LINEAR]
    assert passes == [21, 23, 25, 26, 28, 30, 31, 32, 34, 36, 37, 38, 40, 42, 43, 45]
    for line in passes:
        assert local[line][2] == pytest.approx(-1 * MM, abs=1e-8)     # the facing pass
    # the transposed reading (rows as axes) does not give a level pass
    zs = [r[2] @ tp.moves[i].end for i in range(3, 8)]
    assert max(zs) - min(zs) > 1 * MM


def test_all_shared_csys_third_columns_are_the_tool_axis() -> None:
    for name in SHARED:
        tp = read_apt(_data(name))
        frames = tp.meta["frames"]
        assert len(frames) == tp.meta["record_counts"]["CSYS"]
        lines = [f["line"] for f in frames] + [10**9]
        for m in tp.moves:
            k = max(i for i, ln in enumerate(lines) if ln < m.source.line)
            z = np.array(frames[k]["rotation"])[:, 2]
            np.testing.assert_allclose(m.tool_axis, z / np.linalg.norm(z), atol=1e-12)


# --------------------------------------------------------------------------- CIRCLE on real data
def _arc_tangent(m, p: np.ndarray) -> np.ndarray:
    """Unit direction of motion of arc ``m`` at its point ``p``."""
    sign = 1.0 if m.kind == MoveKind.ARC_CCW else -1.0
    t = sign * np.cross(m.normal, p - m.center)
    return t / np.linalg.norm(t)


@pytest.mark.parametrize("name", ["solidworkscam_boss_3plus2.apt",
                                  "solidworkscam_sacrifice_board.apt"])
def test_shared_arcs_lie_on_their_circles_and_turn_consistently(name: str) -> None:
    tp = read_apt(_data(name))
    arcs = [(i, m) for i, m in enumerate(tp.moves) if m.is_arc]
    assert len(arcs) == SHARED[name]["arcs"]
    tangent, opposite = 0, 0
    for i, m in arcs:
        geo = arc_geometry(m)
        # start and end on the circle: the file's 6-digit rounding leaves < 1 nm
        assert abs(geo["end_radius"] - geo["radius"]) < 1e-9
        assert abs(geo["axial"]) < 1e-12 and abs((m.start - m.center) @ m.normal) < 1e-12
        assert np.linalg.norm(m.center - m.start) == pytest.approx(geo["radius"], abs=1e-12)
        # direction: the arc's start tangent against the end direction of the move before it
        prev = tp.moves[i - 1]
        if prev.length == 0:
            continue
        t = _arc_tangent(m, m.start)
        d = _arc_tangent(prev, prev.end) if prev.is_arc else (prev.end - prev.start) / prev.length
        c = float(t @ d)
        tangent += c > 0.999
        opposite += c < -0.999
    # counter-clockwise about the CIRCLE axis: 588 (boss) and 42 (board) arcs continue the move
    # before them tangentially, 2 reverse (the independent script finds the same counts); the
    # opposite reading would swap the two numbers
    assert (tangent, opposite) == {"solidworkscam_boss_3plus2.apt": (588, 2),
                                   "solidworkscam_sacrifice_board.apt": (42, 0)}[name]


def test_shared_hole_contour_sweeps() -> None:
    # lines 90–95 of the board: lead-in arc of r 0.1 mm, the Ø5 mm hole contour, lead-out arc
    # (CIRCLE/…,0,0,1: counter-clockwise seen from +Z), sweeps from the coordinates by hand:
    # lead-in from −90° to atan2(0.004167, 0.099913) = 2.388°: 92.388°; the contour from
    # atan2(0.104167, 2.497829) = 2.388° to −2.388°: 355.224°
    tp = read_apt(_data("solidworkscam_sacrifice_board.apt"))
    arcs = [m for m in tp.moves if m.is_arc][:3]
    sweeps = [math.degrees(arc_geometry(m)["sweep"]) for m in arcs]
    assert sweeps == pytest.approx([92.388, 355.224, 92.388], abs=2e-3)
    assert [m.kind for m in arcs] == [MoveKind.ARC_CCW] * 3
    assert all(list(m.normal) == [0, 0, 1] for m in arcs)
    # the flipped side (CSYS z = −Z, CIRCLE axis 0,0,−1): clockwise about +Z
    flipped = [m for m in tp.moves if m.is_arc and m.tool_axis[2] < 0]
    assert flipped and all(m.kind == MoveKind.ARC_CCW and list(m.normal) == [0, 0, -1]
                           for m in flipped)


# --------------------------------------------------------------------------- CIRCLE semantics
def test_quarter_circle_length_and_direction() -> None:
    r = 10.0
    tp = read_apt_text(PRE + "GOTO/10,0,0\nCIRCLE/0,0,0,0,0,1\nGOTO/0,10,0")
    arc = tp.moves[-1]
    assert arc.kind == MoveKind.ARC_CCW and list(arc.normal) == [0, 0, 1]
    assert arc.length == pytest.approx(math.pi * r * MM / 2, rel=1e-14)
    assert arc.source.line == 6 and arc.feed == pytest.approx(600 * MMPM)
    # axis −Z: counter-clockwise about −Z is clockwise seen from +Z (G2)
    tp = read_apt_text(PRE + "GOTO/10,0,0\nCIRCLE/0,0,0,0,0,-1\nGOTO/0,-10,0")
    arc = tp.moves[-1]
    assert arc.kind == MoveKind.ARC_CW and list(arc.normal) == [0, 0, 1]
    assert arc.length == pytest.approx(math.pi * r * MM / 2, rel=1e-14)
    # the same end point the other way round is three quarters
    tp = read_apt_text(PRE + "GOTO/10,0,0\nCIRCLE/0,0,0,0,0,1\nGOTO/0,-10,0")
    assert tp.moves[-1].length == pytest.approx(3 * math.pi * r * MM / 2, rel=1e-14)


def test_nx_circle_eleven_fields_full_circle_and_helix() -> None:
    # NX: CIRCLE/x,y,z,i,j,k,r,tol,ratio,diameter,corner (the NX forum record, radius 0.5);
    # NX turns clockwise about i,j,k = (0,0,−1), i.e. counter-clockwise seen from +Z: from the
    # origin to (−0.5, 0.5) is a quarter
    tp = read_apt_text(PRE + "CIRCLE/-0.5,0,0,0,0,-1,0.5,0.002,0.5,1,0\nGOTO/-0.5,0.5,0")
    arc = tp.moves[-1]
    assert arc.kind == MoveKind.ARC_CCW
    assert arc.length == pytest.approx(math.pi * 0.5 * MM / 2, rel=1e-14)
    assert tp.meta["circle_directions"] == {"cw": 1}
    # full circle (end = start) and a helix with the centre given at the end height
    tp = read_apt_text(PRE + "GOTO/5,0,0\nCIRCLE/0,0,0,0,0,1\nGOTO/5,0,0\n"
                       "CIRCLE/0,0,-2,0,0,1,5,0.01,0.5,6,0\nGOTO/5,0,-2")
    full, helix = tp.moves[-2:]
    assert full.length == pytest.approx(2 * math.pi * 5 * MM, rel=1e-14)
    np.testing.assert_allclose(helix.center, [0, 0, 0], atol=1e-15)   # in the start plane
    assert helix.length == pytest.approx(math.hypot(2 * math.pi * 5, 2) * MM, rel=1e-14)
    # TIMES,n: n−1 extra turns, with a warning
    tp = read_apt_text(PRE + "GOTO/5,0,0\nCIRCLE/0,0,-1,0,0,1,5,0.01,0.5,6,0,TIMES,2\n"
                       "GOTO/5,0,-4")
    assert tp.moves[-1].turns == 1
    assert math.degrees(arc_geometry(tp.moves[-1])["sweep"]) == pytest.approx(-720)  # cw about +Z
    assert tp.meta["warning_counts"] == {"helix_turns": 1}


def test_circle_in_a_tilted_plane() -> None:
    # axis (0,−1,0): from +X towards +Z is counter-clockwise about −Y
    tp = read_apt_text(PRE + "GOTO/3,0,0\nCIRCLE/0,0,0,0,-1,0\nGOTO/0,0,3")
    arc = tp.moves[-1]
    assert math.degrees(arc_geometry(arc)["sweep"]) == pytest.approx(
        90 if arc.kind == MoveKind.ARC_CCW else -90)
    geo = arc_geometry(arc)
    mid = arc.center + geo["radius"] * (math.cos(geo["sweep"] / 2) * geo["u"]
                                        + math.sin(geo["sweep"] / 2) * geo["v"])
    np.testing.assert_allclose(mid / MM, [3 / math.sqrt(2), 0, 3 / math.sqrt(2)], atol=1e-12)


# --------------------------------------------------------------------------- CSYS semantics
CSYS_X90 = "CSYS/1,0,0,0, 0,0,-1,50, 0,1,0,0\n"   # axes x'=X, y'=Z, z'=−Y; origin (0, 50, 0) mm


def test_csys_transform_hand_example() -> None:
    text = (PRE + CSYS_X90 + "GOTO/10,20,30\nGOTO/10,20,30,0,0,1\n"
            "GOTO/13,20,30\nCIRCLE/10,20,30,0,0,1\nGOTO/10,23,30\nTLAXIS/1,0,0\nGOTO/0,0,0")
    # default: points as written, the frame in meta, its z axis the modal tool axis
    tp = read_apt_text(text)
    assert _mm(tp.moves[1].end) == [10, 20, 30]
    np.testing.assert_allclose(tp.moves[1].tool_axis, [0, -1, 0])
    np.testing.assert_allclose(tp.moves[2].tool_axis, [0, 0, 1])   # the GOTO's own i,j,k
    assert tp.meta["frames"] == [{"record": "CSYS", "line": 5, "origin_m": [0.0, 50 * MM, 0.0],
                                  "rotation": [[1, 0, 0], [0, 0, -1], [0, 1, 0]]}]
    # apply_frames: p = R·p_local + t, by hand R·(10,20,30) = (10,−30,20), + (0,50,0) = (10,20,20)
    tp = read_apt_text(text, apply_frames=True)
    assert _mm(tp.moves[1].end) == [10, 20, 20]
    np.testing.assert_allclose(tp.moves[1].tool_axis, [0, -1, 0], atol=1e-15)
    np.testing.assert_allclose(tp.moves[2].tool_axis, [0, -1, 0], atol=1e-15)  # R·(0,0,1)
    assert _mm(tp.moves[3].end) == [13, 20, 20]
    arc = tp.moves[4]   # centre R·(10,20,30)+t, axis R·(0,0,1) = (0,−1,0) = the tool axis
    assert _mm(arc.center) == [10, 20, 20] and _mm(arc.end) == [10, 20, 23]
    assert arc.kind == MoveKind.ARC_CCW and list(arc.normal) == [0, -1, 0]
    assert arc.length == pytest.approx(math.pi * 3 * MM / 2, rel=1e-14)
    np.testing.assert_allclose(tp.moves[5].tool_axis, [1, 0, 0])   # TLAXIS R·(1,0,0)
    assert _mm(tp.moves[5].end) == [0, 50, 0]                      # the frame origin


def test_msys_nine_numbers_and_world_warning() -> None:
    # MSYS/origin, x axis, y axis: 90° about Z, origin (100, 0, 0) mm
    tp = read_apt_text(PRE + "MSYS/100,0,0,0,1,0,-1,0,0\nGOTO/10,0,5", apply_frames=True)
    assert _mm(tp.moves[-1].end) == [100, 10, 5]
    np.testing.assert_allclose(tp.moves[-1].tool_axis, [0, 0, 1])
    # without apply_frames an MSYS changes nothing (NX data are in the MSYS frame as written)
    tp = read_apt_text(PRE + "MSYS/100,0,0,0,1,0,-1,0,0\nGOTO/10,0,5")
    assert _mm(tp.moves[-1].end) == [10, 0, 5] and tp.moves[-1].tool_axis is None
    tp = read_apt_text(PRE + "TRNTYP/WORLD,0,0,0\n" + CSYS_X90 + "GOTO/1,2,3", apply_frames=True)
    assert tp.meta["warning_counts"] == {"frames_on_world_data": 1}


# --------------------------------------------------------------------------- malformed input
MALFORMED = [
    # id, text, strict message (after "<string>:"), lenient warning category
    ("truncated", PRE + "GOTO/1,2", r"5:9: GOTO takes 3 numbers \(x,y,z\) or 6 .*got 2 numbers",
     "malformed_record"),
    ("seven_numbers", PRE + "GOTO/1,2,3,0,0,1,7", r"5:18: GOTO takes 3 numbers", "malformed_record"),
    ("bad_number", PRE + "GOTO/1,2x,3", r"5:8: GOTO: bad number '2x'", "malformed_record"),
    ("double_point", PRE + "GOTO/1,2,3.4.5", r"5:10: GOTO: bad number '3.4.5'", "malformed_record"),
    ("empty_field", PRE + "GOTO/1,,3", r"5:8: GOTO: missing number \(empty field\)",
     "malformed_record"),
    ("nan", PRE + "GOTO/1,NaN,3", r"5:8: GOTO: 'NaN' is not a finite number", "malformed_record"),
    ("inf", PRE + "GOTO/1,2,-inf", r"5:10: GOTO: '-inf' is not a finite number",
     "malformed_record"),
    ("overflow", PRE + "GOTO/1,2,1e999", r"5:10: GOTO: number '1e999' is out of range",
     "malformed_record"),
    ("zero_axis", PRE + "GOTO/1,2,3,0,0,0", r"5:12: GOTO: tool axis i,j,k \(0.0, 0.0, 0.0\) is a "
     r"zero vector", "malformed_record"),
    ("no_slash", PRE + "GOTO 1,2,3", r"5:6: GOTO: expected '/' after the major word",
     "malformed_record"),
    ("not_a_record", PRE + "  1,2,3", r"5:3: not an APT record: '1,2,3'", "malformed_record"),
    ("circle_no_goto", PRE + "CIRCLE/0,0,0,0,0,1\nFEDRAT/100,MMPM\nGOTO/1,0,0",
     r"5:1: CIRCLE is not followed by its end point GOTO \(found FEDRAT at line 6\)",
     "circle_without_goto"),
    ("circle_at_eof", PRE + "CIRCLE/0,0,0,0,0,1", r"5:1: CIRCLE is not followed by its end point "
     r"GOTO \(found the end of the file\)", "circle_without_goto"),
    ("circle_off", PRE + "GOTO/10,0,0\nCIRCLE/0,0,0,0,0,1\nGOTO/0,10.1,0",
     r"6:1: CIRCLE end point \(GOTO at line 7\) is off the circle: radius 10.1 mm against 10 mm",
     "arc_off_circle"),
    ("circle_radius", PRE + "GOTO/10,0,0\nCIRCLE/0,0,0,0,0,1,9,0.01,0.5,6,0\nGOTO/0,10,0",
     r"6:1: CIRCLE given radius is off the circle: radius 9 mm against 10 mm", "arc_off_circle"),
    ("circle_fields", PRE + "CIRCLE/0,0,0,0,0,1,5\nGOTO/1,0,0", r"5:21: CIRCLE takes 6 numbers",
     "malformed_record"),
    ("circle_zero_radius", PRE + "CIRCLE/0,0,0,0,0,1\nGOTO/0,0,0", r"5:1: CIRCLE centre "
     r"coincides with the arc's start point", "bad_arc"),
    ("circle_unknown_start", "UNITS/MM\nFEDRAT/1\nCIRCLE/0,0,0,0,0,1\nGOTO/1,0,0",
     r"3:1: CIRCLE from an unknown position", "bad_arc"),
    ("fedrat_unit", PRE + "FEDRAT/100,MMPS", r"5:12: FEDRAT unit 'MMPS' is unknown: use MMPM, IPM",
     "malformed_record"),
    ("fedrat_two_values", PRE + "FEDRAT/100,200", r"5:12: FEDRAT takes one feed value",
     "malformed_record"),
    ("fedrat_zero", PRE + "FEDRAT/MMPM,0", r"5:13: FEDRAT must be positive", "malformed_record"),
    ("missing_feed", "UNITS/MM\nRAPID\nGOTO/0,0,0\nGOTO/1,0,0",
     r"4:1: feed move before any FEDRAT: add FEDRAT/f,MMPM", "missing_feed"),
    ("per_rev_no_spindle", "UNITS/MM\nFEDRAT/0.1,MMPR\nRAPID\nGOTO/0,0,0\nGOTO/1,0,0",
     r"5:1: feed per revolution \(FEDRAT at line 2\) but no spindle speed",
     "feed_per_rev_without_spindle"),
    ("per_rev_spindle_off", "UNITS/MM\nSPINDL/1000,RPM\nSPINDL/OFF\nFEDRAT/0.1,MMPR\nGOTO/1,0,0",
     r"5:1: feed per revolution", "feed_per_rev_without_spindle"),
    ("units", PRE + "UNITS/FEET", r"5:7: UNITS takes MM or INCHES", "malformed_record"),
    ("csys_count", PRE + "CSYS/1,0,0,0,0,1,0,0,0,0,1", r"5:27: CSYS takes 12 numbers",
     "malformed_record"),
    ("csys_not_rotation", PRE + "CSYS/1,0,0,0,0,2,0,0,0,0,1,0", r"5:6: CSYS: the rotation part is "
     r"not a proper rotation", "malformed_record"),
    ("csys_mirror", PRE + "CSYS/-1,0,0,0,0,1,0,0,0,0,1,0", r"5:6: CSYS: the rotation part is not "
     r"a proper rotation .*det = -1", "malformed_record"),
    ("spindl_word", PRE + "SPINDL/1000,RPM,FAST", r"5:17: SPINDL word 'FAST' is unknown",
     "malformed_record"),
    ("spindl_sfm", PRE + "SPINDL/200,SFM", r"5:12: SPINDL surface speed \(SFM\) is not supported",
     "malformed_record"),
    ("cycle_no_depth", PRE + "CYCLE/DRILL,MMPM,100,RAPTO,2", r"5:7: CYCLE/DRILL needs FEDTO,depth",
     "malformed_record"),
    ("cycle_no_feed", PRE + "CYCLE/DRILL,FEDTO,5,RAPTO,2", r"5:7: CYCLE/DRILL needs its feed",
     "malformed_record"),
    ("cycle_pairs", PRE + "CYCLE/DRILL,FEDTO", r"5:13: CYCLE/DRILL: expected keyword,value pairs",
     "malformed_record"),
    ("load", PRE + "LOAD/TOOL,1.5", r"5:11: LOAD: tool number must be an integer",
     "malformed_record"),
    ("rapid_args", PRE + "RAPID/5", r"5:7: RAPID takes no arguments", "malformed_record"),
    ("continued_field", PRE + "GOTO/1,$\n  2x,3", r"5:3: GOTO: bad number '2x'.*\(on "
     r"continuation line 6\)", "malformed_record"),
    ("times", PRE + "GOTO/5,0,0\nCIRCLE/0,0,0,0,0,1,5,0.01,0.5,6,0,TIMES,1.5\nGOTO/5,0,0",
     r"6:41: CIRCLE TIMES must be an integer", "malformed_record"),
]


@pytest.mark.parametrize(("text", "message"), [(t, m) for _, t, m, _ in MALFORMED],
                         ids=[c[0] for c in MALFORMED])
def test_malformed_strict_raises_with_location(text: str, message: str) -> None:
    with pytest.raises(ToolpathError, match=r"^<string>:" + message):
        read_apt_text(text)


@pytest.mark.parametrize(("text", "category"), [(t, c) for _, t, _, c in MALFORMED],
                         ids=[c[0] for c in MALFORMED])
def test_malformed_lenient_counts_a_warning(text: str, category: str) -> None:
    tp = read_apt_text(text, strict=False)
    assert tp.meta["warning_counts"].get(category, 0) == 1
    assert [w.category for w in tp.warnings] == [category]
    summarize(tp)


def test_error_fields_and_lenient_skips_exactly_what_it_says() -> None:
    with pytest.raises(ToolpathError) as err:
        read_apt_text(PRE + "GOTO/1,2x,3", file="part.apt")
    e = err.value
    assert (e.file, e.line, e.column) == ("part.apt", 5, 8)
    assert "strict=False" in e.reason
    # a malformed GOTO is skipped, the next one starts where the tool really is
    tp = read_apt_text(PRE + "GOTO/1,2x,3\nGOTO/5,0,0", strict=False)
    assert tp.skipped == {"malformed_record": 1}
    assert [_mm(m.end) for m in tp.moves] == [[0, 0, 0], [5, 0, 0]]
    assert tp.moves[1].start is tp.moves[0].end
    # an orphan CIRCLE is dropped, the record after it is still read
    tp = read_apt_text(PRE + "CIRCLE/0,0,0,0,0,1\nFEDRAT/300,MMPM\nGOTO/1,0,0", strict=False)
    assert tp.skipped == {"circle_without_goto": 1}
    assert tp.moves[-1].kind == MoveKind.LINEAR and tp.moves[-1].feed == pytest.approx(300 * MMPM)
    # an arc off its circle is skipped; the tool is at its end afterwards
    tp = read_apt_text(PRE + "GOTO/10,0,0\nCIRCLE/0,0,0,0,0,1\nGOTO/0,11,0\nGOTO/0,20,0",
                       strict=False)
    assert tp.skipped == {"arc_off_circle": 1}
    assert _mm(tp.moves[-1].start) == [0, 11, 0]
    # feeds missing in lenient mode: Move.feed None, one warning until a FEDRAT comes
    tp = read_apt_text("UNITS/MM\nGOTO/0,0,0\nGOTO/1,0,0\nFEDRAT/10\nGOTO/2,0,0", strict=False)
    assert [m.feed for m in tp.moves][:2] == [None, None]
    assert tp.moves[2].feed == pytest.approx(10 * MMPM)
    assert tp.meta["warning_counts"] == {"missing_feed": 1}


def test_ten_megabyte_lines_are_linear() -> None:
    n = 10_000_000
    cases = [
        ("GOTO/1,2,3" + ",4" * (n // 2), 5 + 2 * 64 + 1, "more than 64 fields"),
        ("GOTO/" + "1" * n + ",2,3", 6, "longer than 40 characters"),
        ("GOTO/1," + " " * n + "2x,3", n + 8, "bad number '2x'"),
        ("FEDRAT/" + "M" * n, 8, "longer than 40 characters"),
        ("GOTO/1,2,3 " + "$" + " " * n + "\n4", 10, "bad number '3 4'"),   # joined: "3 4"
        ("Q" * n, 1, "unknown record 'QQQQ"),
    ]
    for line, col, what in cases:
        t0 = time.perf_counter()
        with pytest.raises(ToolpathError, match=rf"^<string>:5:{col}: .*({what})"):
            read_apt_text(PRE + line)
        assert time.perf_counter() - t0 < 5.0
    t0 = time.perf_counter()
    tp = read_apt_text(PRE + "PPRINT " + "$x" * (n // 2) + "\nGOTO/1,2,3 $$" + "c" * n
                       + "\n" + "Q" * n + "\nGOTO/4,5,6", strict=False)
    assert time.perf_counter() - t0 < 5.0
    assert [_mm(m.end) for m in tp.moves[1:]] == [[1, 2, 3], [4, 5, 6]]
    assert tp.skipped == {"Q" * 24 + "…": 1} and len(tp.warnings[0].message) < 200


FUZZ_PROGRAM = """PARTNO/FUZZ
UNITS/MM
CUTTER/10,1,4,1,0,0,50
LOAD/TOOL,3
SPINDL/8000,RPM,CLW
TLAXIS/0,0,1
MULTAX/ON
RAPID
GOTO/0,0,50
RAPID
GOTO/10,0,5,0,0,1
FEDRAT/300,MMPM
GOTO/10,0,-1
CIRCLE/0,0,-1,0,0,1
GOTO/0,10,-1
CIRCLE/0,0,-1,0,0,-1,10,0.01,0.5,10,1
GOTO/10,0,-1 $$ back
CSYS/1.,0,0,0,0,1.,0,0,0,0,1.,0
FEDRAT/MMPR,0.05
GOTO/20,0,$
  -1
CUTCOM/LEFT
GOTO/20,5,-1,0,0.6,0.8
CUTCOM/OFF
CYCLE/DRILL,FEDTO,5,MMPM,100,RAPTO,2,RTRCTO,10
GOTO/30,0,0,0,0,1
GOTO/40,0,0
CYCLE/OFF
COOLNT/OFF
PPRINT done $ really
FINI
"""


def test_fuzz_only_toolpath_errors(rng: np.random.Generator, tmp_path: Path) -> None:
    base = FUZZ_PROGRAM.encode()
    assert len(read_apt_text(FUZZ_PROGRAM).moves) == 15   # the seed program itself is valid
    alphabet = b"0123456789.+-,/$ eEGOTCIRLFDAPMXnai\n\t\x00\xff\xe9"
    path = tmp_path / "fuzz.apt"
    outcomes = {"ok": 0, "error": 0}
    for _ in range(300):
        path.write_bytes(mutate(base, alphabet, rng))
        try:
            summarize(read_apt(path))
            outcomes["ok"] += 1
        except ToolpathError:
            outcomes["error"] += 1
        summarize(read_apt(path, strict=False))   # lenient never raises
    # a mutated major word is an unknown record, refused in strict mode: most mutants fail
    assert outcomes["ok"] > 10 and outcomes["error"] > 200


# --------------------------------------------------------------------------- semantics
def test_continuation_comments_and_bom(tmp_path: Path) -> None:
    plain = read_apt_text(PRE + "GOTO/1.5,2,3,0,0,1\nGOTO/4,5,6")
    text = ("\ufeff$$ header comment, with commas / and slashes\n" + PRE
            + "GOTO/1.$\n5,2,   $ the rest of a continued line is ignored\n 3,0,$\n0,1 $$ tail\n"
            + "  $$ indented comment\n\ngoto / 4, 5, 6")
    tp = read_apt_text(text)
    assert [_mm(m.end) for m in tp.moves] == [_mm(m.end) for m in plain.moves]
    assert [m.source.line for m in tp.moves] == [5, 6, 12]   # where each record starts
    assert tp.moves[2].source.column == 1
    np.testing.assert_allclose(tp.moves[1].tool_axis, [0, 0, 1])
    path = tmp_path / "bom.apt"
    path.write_bytes(b"\xef\xbb\xbfPARTNO/BOM TEST\n" + PRE.encode() + b"GOTO/1,2,3\n")
    tp = read_apt(path)
    assert tp.meta["program"] == "BOM TEST" and tp.meta["encoding"] == "utf-8"
    assert _mm(tp.moves[-1].end) == [1, 2, 3]
    # free text keeps a single '$' that is not at the end of its line
    tp = read_apt_text("PARTNO costs $5 $$ comment\nPPRINT a,b/c $\n still text\n" + PRE)
    assert tp.meta["program"] == "costs $5" and tp.meta["record_counts"]["PPRINT"] == 1


def test_feed_word_orders_units_and_per_rev() -> None:
    tp = read_apt_text(PRE + "FEDRAT/125.,MMPM\nGOTO/1,0,0\nFEDRAT/MMPM,250.\nGOTO/2,0,0\n"
                       "FEDRAT/IPM,10\nGOTO/3,0,0\nFEDRAT/40\nGOTO/4,0,0\n"
                       "SPINDL/RPM,2000,CCLW\nFEDRAT/0.1,MMPR\nGOTO/5,0,0\n"
                       "SPINDL/1000\nGOTO/6,0,0\nFEDRAT/IPR,0.002\nGOTO/7,0,0\nSPINDL/OFF\n"
                       "RAPID\nGOTO/8,0,0\nSPINDL/ON\nFEDRAT/MMPM,100\nGOTO/9,0,0")
    feeds = [m.feed for m in tp.moves[1:]]
    assert feeds[7] is None   # the rapid
    assert feeds[:7] + feeds[8:] == pytest.approx(
        [125 * MMPM, 250 * MMPM, 10 * IN / 60, 40 * MMPM, 0.1 * MM * 2000 / 60,
         0.1 * MM * 1000 / 60, 0.002 * IN * 1000 / 60, 100 * MMPM], rel=1e-14)
    assert [m.spindle_rpm for m in tp.moves] == [None] * 5 + [2000, 1000, 1000, 0.0, 1000]


def test_rapid_applies_once_and_feed_is_modal() -> None:
    tp = read_apt_text("UNITS/MM\nRAPID\nGOTO/0,0,10\nFEDRAT/200,MMPM\nGOTO/0,0,0\nGOTO/5,0,0\n"
                       "RAPID/\nGOTO/5,0,10\nGOTO/6,0,10")
    assert [m.kind for m in tp.moves] == [MoveKind.RAPID, MoveKind.LINEAR, MoveKind.LINEAR,
                                          MoveKind.RAPID, MoveKind.LINEAR]
    assert [m.feed for m in tp.moves] == [None, pytest.approx(200 * MMPM),
                                          pytest.approx(200 * MMPM), None,
                                          pytest.approx(200 * MMPM)]
    assert tp.moves[0].start is None and _mm(tp.moves[1].start) == [0, 0, 10]


def test_modal_tool_axis() -> None:
    tp = read_apt_text(PRE + "GOTO/1,0,0\nGOTO/1,1,0,0,0.6,0.8\nGOTO/2,1,0\nTLAXIS/1,0,0\n"
                       "GOTO/3,1,0\nGOTO/3,1,0,0,0,2\nFROM/50,50,50\nGOTO/0,0,0")
    axes = [None if m.tool_axis is None else list(m.tool_axis) for m in tp.moves]
    assert axes == [None, None, [0, 0.6, 0.8], [0, 0.6, 0.8], [1, 0, 0], [0, 0, 1], [0, 0, 1]]
    assert tp.meta["warning_counts"] == {"axis_not_unit": 1}   # (0,0,2) normalised
    assert _mm(tp.moves[-1].start) == [50, 50, 50]              # FROM moved without a move
    assert not summarize(read_apt_text(PRE + "GOTO/1,2,3"))["has_tool_axis"]


def test_inch_units_scale_points_feeds_and_cutters() -> None:
    tp = read_apt_text("UNITS/INCHES\nCUTTER/0.5,0.02\nFEDRAT/10\nRAPID\nGOTO/1,2,3\n"
                       "CIRCLE/0,2,3,0,0,1\nGOTO/-1,2,3\nUNIT/MM\nGOTO/0,0,0")
    assert tp.units == "inch"
    np.testing.assert_allclose(tp.moves[0].end, [IN, 2 * IN, 3 * IN], rtol=1e-15)
    assert tp.moves[1].feed == pytest.approx(10 * IN / 60)
    assert tp.moves[1].length == pytest.approx(math.pi * IN, rel=1e-14)
    assert tp.meta["cutters"][0]["diameter_m"] == pytest.approx(0.5 * IN)
    assert tp.meta["cutters"][0]["corner_radius_m"] == pytest.approx(0.02 * IN)
    assert tp.moves[2].feed == pytest.approx(10 * IN / 60)   # feed kept as given (in/min)
    assert tp.meta["units_declared"] == [(1, "inch"), (8, "mm")]
    assert tp.meta["warning_counts"] == {"units_changed": 1}
    tp = read_apt_text("FEDRAT/10\nRAPID\nGOTO/1,2,3", default_units="inch")
    np.testing.assert_allclose(tp.moves[0].end, [IN, 2 * IN, 3 * IN], rtol=1e-15)
    assert tp.meta["warning_counts"] == {"no_units": 1} and tp.warnings[0].source.line == 1


def test_cycles_expand_by_hand() -> None:
    tp = read_apt_text(PRE + "RAPID\nGOTO/0,0,10\nCYCLE/DRILL,FEDTO,5,MMPM,100,RAPTO,2,RTRCTO,10\n"
                       "GOTO/0,0,0\nGOTO/20,0,0\nCYCLE/OFF\nRAPID\nGOTO/0,0,30\n"
                       "CYCLE/TAP,FEDTO,4,IPM,10,RAPTO,1\nGOTO/0,0,0,1,0,0\nCYCLE/OFF\nGOTO/1,1,1")
    got = [(m.kind.name[0], _mm(m.end), None if m.feed is None else round(m.feed / MMPM, 9),
            m.extra.get("cycle")) for m in tp.moves[2:]]
    assert got == [
        ("R", [0, 0, 2], None, "DRILL"), ("L", [0, 0, -5], 100, "DRILL"),
        ("R", [0, 0, 10], None, "DRILL"),
        ("R", [20, 0, 10], None, "DRILL"), ("R", [20, 0, 2], None, "DRILL"),
        ("L", [20, 0, -5], 100, "DRILL"), ("R", [20, 0, 10], None, "DRILL"),
        ("R", [0, 0, 30], None, None),
        # tapping along +X: no RTRCTO → back to RAPTO, at the feed
        ("R", [1, 0, 0], None, "TAP"), ("L", [-4, 0, 0], 254, "TAP"), ("L", [1, 0, 0], 254, "TAP"),
        ("L", [1, 1, 1], 600, None)]
    assert [c["holes"] for c in tp.meta["cycles"]] == [2, 1]


def test_spindle_tools_cutcom_fini_and_meta() -> None:
    tp = read_apt_text("PARTNO/P1\nUNITS/MM\nCUTTER/12,0,6,3.6,31,0,63\nCSI_SET_FLUTE_LENGTH/38\n"
                       "LOAD/TOOL,11\nSELECT/TOOL,2\nTOOLNO/2\nSPINDL/3500,RPM,CLW\n"
                       "TLDATA/MILL,10,1,75,0,0\nMULTAX/OFF\nFEDRAT/100\nCUTCOM/LEFT\n"
                       "CUTCOM/OFF\nRAPID\nGOTO/1,2,3\nFINI\nGOTO/4,5,6\nBOGUS")
    assert len(tp.moves) == 1 and tp.moves[0].tool == 2 and tp.moves[0].spindle_rpm == 3500
    assert tp.meta["program"] == "P1" and tp.meta["selected_tools"] == [2]
    assert tp.meta["multax"] is False
    cut = tp.meta["cutters"]
    assert cut[0]["tool"] == 11 and cut[0]["diameter_m"] == pytest.approx(12 * MM)
    assert cut[0]["height_m"] == pytest.approx(63 * MM)
    assert cut[0]["flute_length_m"] == pytest.approx(38 * MM)
    assert cut[1]["tldata"] == ["MILL", 10, 1, 75, 0, 0]
    assert tp.skipped == {"after_fini": 2}
    assert tp.meta["warning_counts"] == {"cutter_compensation": 1, "after_fini": 1}


def test_reader_object_options_and_file_errors(tmp_path: Path) -> None:
    path = tmp_path / "p.apt"
    path.write_bytes(b"PARTNO/caf\xe9\n" + PRE.encode() + b"GOTO/1,2,3\n")
    tp = AptReader().read(str(path))
    assert tp.meta["encoding"] == "latin-1" and tp.meta["program"] == "caf\u00e9"
    assert tp.format == "apt" and tp.moves[0].source.file == str(path)
    assert summarize(read_toolpath(path)) == summarize(tp)
    with pytest.raises(InputError, match="unknown APT reader option"):
        read_apt(path, speed=2)
    with pytest.raises(InputError, match="default_units"):
        read_apt_text(PRE, default_units="furlong")
    with pytest.raises(InputError, match="arc_radius_tol"):
        read_apt_text(PRE, arc_radius_tol=-1.0)
    with pytest.raises(ToolpathError, match="not found|cannot read the file"):
        read_apt(tmp_path / "missing.apt")
    # a wider arc tolerance accepts a coarse CAM rounding
    text = PRE + "GOTO/10,0,0\nCIRCLE/0,0,0,0,0,1\nGOTO/0,10.01,0"
    assert read_apt_text(text, arc_radius_tol=0.02 * MM).moves[-1].is_arc


def test_a_malformed_end_goto_takes_its_circle_along() -> None:
    tp = read_apt_text(PRE + "GOTO/10,0,0\nCIRCLE/0,0,0,0,0,1\nGOTO/0,1x,0\nGOTO/0,10,0",
                       strict=False)
    assert tp.skipped == {"malformed_record": 1}
    assert tp.moves[-1].kind == MoveKind.LINEAR and _mm(tp.moves[-1].end) == [0, 10, 0]
