"""Tests of the G-code reader (robot_io.gcode) and the trunnion kinematics (robot_io.rotary).

The shared CAM programs are pinned against numbers derived *without* this reader (see the comment
above ``SHARED``); semantics are checked on small programs against hand-computed values; malformed
input is table-driven; a seeded fuzz test checks that nothing but ToolpathError ever escapes.
"""

from __future__ import annotations

import dataclasses
import math
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import mutate

from models.errors import InputError
from robot_io.gcode import GcodeReader, read_gcode, read_gcode_text
from robot_io.rotary import make_rotary_kinematics
from robot_io.toolpath import Move, MoveKind, ToolpathError, summarize

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "toolpaths"
MM = 1e-3
IN = 0.0254
PRE = "G21 G90 G17 F100\nG0 X0 Y0 Z0\n"   # two-line preamble: mm, absolute, XY, feed, at origin


def _data(name: str) -> Path:
    path = DATA / name
    if not path.is_file():
        pytest.skip(f"shared toolpath data not found at {path} (expected the repo next to "
                    "../shared/data/toolpaths)")
    return path


# --------------------------------------------------------------------------- shared programs
# Pinned values, all derived independently of cctmill:
#   moves   = awk/grep count of motion lines after stripping comments,
#             `sed -e 's/([^)]*)//g' -e 's/;.*//' F | tr a-z A-Z | grep -cE '[XYZ] *[-+.0-9]'`,
#             minus the first move when its end has an axis never programmed before (cameo: Z,
#             flower: X/Y, fusion: Z, boat: X/Y — the reader skips it as "unknown_position"),
#             plus rotary-only lines (`… | awk '/[AC] *[-+.0-9]/ && !/[XYZ] *[-+.0-9]/'`: boat 13,
#             impeller 1; they are zero-length moves of the tip in TCP mode).
#   rapids/arcs = the same awk count split by the modal G0/G1/G2/G3 in force (minus the skipped
#             first rapid); inverse = awk count of feed-mode lines between G93 and G94.
#   length, bbox = a throw-away independent modal parse (~60 lines, not kept): strip
#             comments, re.findall letter/number pairs, modal G0–G3, G17/G18 I/J/K arcs with the
#             sweep from atan2(...) mod 2π (G2 negative), length r·|sweep| (hypot with the helix
#             travel), box = end points + the cardinal points k·90° strictly inside each sweep;
#             tip = XYZ words for the 5-axis files (M428 TCP). Its one-line essence:
#             `for L, v in re.findall(r"([A-Z])\s*([-+]?[0-9]*\.?[0-9]*)", line): ...`.
#   Fusion bbox tolerance 1e-8 m: its arcs ending at have start radius 3.6000069 mm and
#   end radius 3.6 mm (rounded program); summarize draws the arc with the start radius, 6.9 nm
#   beyond the end point, the independent parse stops at the end point.
SHARED = {
    "camotics_cameo_nnumbered.nc": dict(
        kw={}, moves=35281, rapids=2, arcs=0, inverse=0, length=57.94514520192161,
        bbox=[[-75.0 * MM, -93.703 * MM, -6.0 * MM], [75.0 * MM, 93.297 * MM, 2.0 * MM]],
        bbox_tol=1e-9, warnings={"unknown_position": 1}, units="mm"),
    "camotics_flower_mold_inch.nc": dict(
        kw={}, moves=16559, rapids=6, arcs=0, inverse=0, length=24.544008917475832,
        bbox=[[0.0, 0.0, -0.3636 * IN], [2.249 * IN, 2.248 * IN, 0.2 * IN]],
        bbox_tol=1e-9, warnings={"unknown_position": 1}, units="inch"),
    "camotics_vcarve_openvoronoi.ngc": dict(
        kw={}, moves=4153, rapids=119, arcs=0, inverse=0, length=0.323605656119807,
        bbox=[[-0.0649 * IN, 0.0, -0.01617 * IN], [0.4831 * IN, 0.1903 * IN, 0.1 * IN]],
        bbox_tol=1e-9, warnings={}, units="inch"),
    "fusion360_1117_wall_28bit.nc": dict(
        kw={}, moves=4974, rapids=4, arcs=1994, inverse=0, length=26.86216900226796,
        bbox=[[-1.6 * MM, -1.6 * MM, -13.3 * MM], [229.6 * MM, 71.6 * MM, 10.0 * MM]],
        bbox_tol=1e-8, warnings={"unknown_position": 1}, units="mm"),
    "linuxcnc_boat_5ax_xyzac_hermle.ngc": dict(
        kw={"rotary": "xyzac-trunnion"}, moves=1831, rapids=92, arcs=4, inverse=1454,
        length=4.59975305453204,
        bbox=[[-49.969 * MM, -26.323 * MM, -13.25 * MM], [46.264 * MM, 22.345 * MM, 10.0 * MM]],
        bbox_tol=1e-9, warnings={"unknown_position": 1, "no_units": 1}, units="mm"),
    "linuxcnc_impeller_5ax_xyzac_G93.ngc": dict(
        kw={"rotary": "xyzac-trunnion"}, moves=4492, rapids=186, arcs=0, inverse=4306,
        length=4.290257648244458,
        bbox=[[-45.381 * MM, -44.995 * MM, -2.653 * MM], [42.87 * MM, 44.219 * MM, 40.0 * MM]],
        bbox_tol=1e-9, warnings={"no_units": 1}, units="mm"),
}


@pytest.mark.parametrize("name", sorted(SHARED))
def test_shared_program_reads_strict_with_pinned_summary(name: str) -> None:
    exp = SHARED[name]
    tp = read_gcode(_data(name), **exp["kw"])
    s = summarize(tp)
    assert s["moves"] == exp["moves"]
    assert s["rapids"] == exp["rapids"]
    assert s["arcs"] == exp["arcs"]
    assert s["inverse_time_moves"] == exp["inverse"]
    assert s["length_m"] == pytest.approx(exp["length"], rel=1e-6)
    np.testing.assert_allclose(s["bbox_m"], exp["bbox"], rtol=0, atol=exp["bbox_tol"])
    # only the listed warnings, each counted; nothing else skipped
    assert tp.meta["warning_counts"] == exp["warnings"]
    assert dict(tp.skipped) == {k: v for k, v in exp["warnings"].items() if k != "no_units"}
    assert tp.units == exp["units"]
    assert s["has_tool_axis"] == ("rotary" in exp["kw"])


def test_shared_program_feeds_and_meta() -> None:
    tp = read_gcode(_data("fusion360_1117_wall_28bit.nc"))
    feeds = {m.feed for m in tp.moves if m.kind != MoveKind.RAPID}
    assert sorted(feeds) == pytest.approx(np.array([333.3, 500, 1000]) * MM / 60)
    assert tp.meta["program"] == "1117_wall_28bit"
    assert tp.meta["work_offsets"] == ["G54"]
    assert {m.spindle_rpm for m in tp.moves} == {5000.0}
    assert {m.tool for m in tp.moves} == {1}
    # the six G18 ramp arcs: CW about +Y, a quarter turn down (2576: G18 G2 X214.98 Z-5.95 I0.28)
    g18 = [m for m in tp.moves if m.is_arc and m.normal[1] == 1.0]
    assert len(g18) == 6
    assert all(m.kind == MoveKind.ARC_CW for m in g18)
    assert g18[0].source.line == 2576
    assert g18[0].length == pytest.approx(0.28 * MM * math.pi / 2)
    inch = read_gcode(_data("camotics_flower_mold_inch.nc"))
    assert sorted({m.feed for m in inch.moves if m.kind != MoveKind.RAPID}) == pytest.approx(
        [8 * IN / 60, 20 * IN / 60])


def test_impeller_tcp_tool_axis_and_inverse_time() -> None:
    tp = read_gcode(_data("linuxcnc_impeller_5ax_xyzac_G93.ngc"), rotary="xyzac-trunnion")
    assert tp.meta["tcp_switches"] == [(4, "tcp"), (4509, "identity")]
    first_cut = next(m for m in tp.moves if m.kind == MoveKind.LINEAR)
    # line 10: G1 X 6.302 Y -11.560 Z 27.743 A -71.841 C -35.930 F 318 (M428: XYZ = tool tip)
    assert first_cut.source.line == 10
    np.testing.assert_allclose(first_cut.end, np.array([6.302, -11.560, 27.743]) * MM, atol=1e-12)
    # hand: (sin C sin A, cos C sin A, cos A) at A -71.841°, C -35.930° — radially out of the hub
    np.testing.assert_allclose(first_cut.tool_axis, [0.5575712, -0.7694059, 0.3116551],
                               atol=1e-6)
    assert first_cut.duration == pytest.approx(60 / 318)
    assert first_cut.feed is None
    assert first_cut.extra == pytest.approx({"A": math.radians(-71.841),
                                             "C": math.radians(-35.930)})
    assert all(abs(np.linalg.norm(m.tool_axis) - 1) < 1e-12 for m in tp.moves)


def test_five_axis_files_need_a_kinematics_choice() -> None:
    path = _data("linuxcnc_impeller_5ax_xyzac_G93.ngc")
    line8 = path.read_text().splitlines()[7]
    col = line8.index("A") + 1
    with pytest.raises(ToolpathError, match=rf":8:{col}: rotary word A but no rotary kinematics "
                       r".*line 4 announces TCP.*rotary='xyzac-trunnion'"):
        read_gcode(path)
    tp = read_gcode(path, strict=False)
    assert tp.skipped["rotary_word"] == 2 * 4491        # every A and C word (grep: 4491 each)
    assert tp.meta["warning_counts"]["rotary_ignored"] == tp.skipped["rotary_word"]
    assert len([w for w in tp.warnings if w.category == "rotary_ignored"]) == 50   # capped
    assert tp.moves[0].extra == pytest.approx({"A": math.radians(-71.841),
                                               "C": math.radians(-35.930)})
    assert tp.moves[0].tool_axis is None


# --------------------------------------------------------------------------- malformed input
MALFORMED = [
    # id, program, strict message (after "<string>:"), lenient warning category
    ("truncated_word", PRE + "G1 X", r"3:4: word 'X' without a number", "malformed_word"),
    ("truncated_sign", PRE + "G1 Y1 X-", r"3:7: word 'X-' without a number", "malformed_word"),
    ("unknown_g", PRE + "G1 X1 G7.3", r"3:7: unknown G code G7.3; read with strict=False",
     "unknown_g"),
    ("unsupported_g92", PRE + "G92 X0", r"3:1: unsupported G code G92", "unknown_g"),
    ("unknown_m", PRE + "M77", r"3:1: unknown M code M77; read with strict=False", "unknown_m"),
    ("arc_radius", PRE + "G2 X10 Y0 I4 J0", r"3:4: arc radius differs at start \(4\) and end "
     r"\(6\)", "arc_radius"),
    ("r_too_small", PRE + "G2 X10 Y0 R4", r"3:11: R 4 is smaller than half the chord \(5\)",
     "bad_arc"),
    ("r_full_circle", PRE + "G2 X0 Y0 R5", r"3:10: R-format arc with end = start", "bad_arc"),
    ("missing_feed", "G21\nG0 X0 Y0 Z0\nG1 X5", r"3:4: feed move without a feed rate",
     "missing_feed"),
    ("nan", PRE + "G1 X nan", r"3:4: malformed number in 'X NAN'", "malformed_word"),
    ("inf", PRE + "G1 Xinf", r"3:4: malformed number in 'XINF'", "malformed_word"),
    ("double_point", PRE + "G1 X1.2.3", r"3:4: malformed number in 'X1.2.3'", "malformed_word"),
    ("g93_no_f", PRE + "G93\nG1 X1", r"4:4: G93 \(inverse time\) feed move without F",
     "missing_feed"),
    ("g94_after_g93", PRE + "G93\nG1 X1 F10\nG94 G1 X2", r"5:8: feed move without a feed rate",
     "missing_feed"),
    ("k_on_g17_arc", PRE + "G2 X10 Y0 I5 J0 K1", r"3:17: K1 on a G17 arc", "arc_normal_word"),
    ("unclosed_comment", PRE + "G1 X1 (oops", r"3:7: comment '\(' is not closed",
     "unclosed_comment"),
    ("duplicate_word", PRE + "G1 X1 X2", r"3:7: second X word", "duplicate_word"),
    ("unset_named_parameter", PRE + "G1 X#<depth>", r"3:5: #<depth> is read before it is set",
     "unset_parameter"),
    ("bad_expression", PRE + "G1 X[1 + ]", r"3:10: expected a number", "bad_expression"),
    ("system_parameter", PRE + "G1 X#5221", r"3:5: #5221 \(G54–G59.3 work offset\) is machine "
     "state", "system_parameter"),
    ("expression_outside_word", PRE + "G1 [1 + 2]", r"3:4: an expression '\[…\]' must be the "
     "value of a word", "malformed_word"),
    ("nested_comment", PRE + "G1 X1 (T1 (6MM) FLAT)", r"3:7: comment at column 7 holds a '\('",
     "nested_comment"),
    ("out_of_range", PRE + "G1 X" + "9" * 15, r"3:4: X9+ is out of range", "malformed_word"),
    ("exponent", PRE + "G1 X1E5", r"3:6: word E is not read.*exponents", "unknown_word"),
    ("no_motion_mode", "G21 F100\nX1 Y1 Z1", r"2:1: axis words but no motion mode",
     "no_motion_mode"),
    ("rotary_without_kinematics", PRE + "G1 X1 A10", r"3:7: rotary word A but no rotary "
     r"kinematics", "rotary_ignored"),
    ("turns", PRE + "G3 X0 Y0 I5 P1.5", r"3:13: arc P \(turns\) must be an integer",
     "bad_arc"),
    ("absolute_centre", PRE + "G90.1 G2 X10 Y0 I5", r"3:10: G90.1 \(absolute arc centre\) needs "
     r"both I and J", "bad_arc"),
    ("garbage", PRE + "G1 X1 §", r"3:7: unexpected character '§'", "malformed_word"),
    ("o_word_sub", PRE + "o100 sub", r"3:1: o100 sub: no o100 endsub closes the subroutine",
     "o_word"),
    ("o_word_call", PRE + "o100 call", r"3:1: o100 call: no o100 sub in this file", "o_word"),
    ("o_word_later_number", PRE + "O2000", r"3:1: O2000: a bare O-number after the program "
     "start begins a Fanuc-style subprogram", "o_word"),
    ("fanuc_m98", PRE + "M98 P2000", r"3:1: M98: Fanuc subprogram calls are not supported",
     "o_word"),
    ("bad_feed", PRE + "G1 X1 F-5", r"3:7: F must be positive", "bad_feed"),
]


@pytest.mark.parametrize(("text", "message"), [(t, m) for _, t, m, _ in MALFORMED],
                         ids=[c[0] for c in MALFORMED])
def test_malformed_strict_raises_with_location(text: str, message: str) -> None:
    with pytest.raises(ToolpathError, match=r"^<string>:" + message):
        read_gcode_text(text)


@pytest.mark.parametrize(("text", "category"), [(t, c) for _, t, _, c in MALFORMED],
                         ids=[c[0] for c in MALFORMED])
def test_malformed_lenient_counts_a_warning(text: str, category: str) -> None:
    tp = read_gcode_text(text, strict=False)
    assert tp.meta["warning_counts"].get(category, 0) >= 1
    assert any(w.category == category for w in tp.warnings)


def test_lenient_skips_exactly_what_it_says() -> None:
    # an unknown code on a block with axis words skips the block (the words may belong to it);
    # without axis words only the code is skipped
    tp = read_gcode_text(PRE + "G1 X1 G7.3\nG7.3 G91\nG1 X1", strict=False)
    assert tp.skipped == {"unknown_g_block": 1, "unknown_g": 1}
    assert [m.end[0] for m in tp.moves] == [0.0, pytest.approx(1 * MM)]   # G91 was applied
    # a malformed word skips its block; the K of a G17 arc is ignored, the arc kept
    tp = read_gcode_text(PRE + "G1 X1.2.3 Y5\nG2 X10 Y0 I5 J0 K1", strict=False)
    assert tp.skipped == {"malformed_block": 1, "arc_normal_word": 1}
    assert [m.kind for m in tp.moves] == [MoveKind.RAPID, MoveKind.ARC_CW]
    # a missing feed leaves feed None and goes on
    tp = read_gcode_text("G21\nG0 X0 Y0 Z0\nG1 X5\nX6", strict=False)
    assert tp.skipped["missing_feed"] == 2 and tp.moves[-1].feed is None


def test_ten_megabyte_lines_are_linear() -> None:
    n = 10_000_000
    cases = [
        ("G1 X" + "1" * n + ".5.5", 4, "malformed number"),       # a 10 MB number, then garbage
        (" " * n + "G1 X1.2.3", n + 4, "malformed number"),        # bad word at column ~1e7
        ("G1 X1 (" + "c" * n + ") Y2 X", n + 13, "without a number"),
        ("G1 X1 (" + "(" * n, 7, "not closed"),
    ]
    for line, col, what in cases:
        t0 = time.perf_counter()
        with pytest.raises(ToolpathError, match=rf"^<string>:3:{col}: .*{what}"):
            read_gcode_text(PRE + line)
        assert time.perf_counter() - t0 < 5.0
    t0 = time.perf_counter()
    tp = read_gcode_text(PRE + "G1 X1 Y2 (" + "c" * n + ") Z3 ;" + "d" * n)
    assert time.perf_counter() - t0 < 5.0
    np.testing.assert_allclose(tp.moves[-1].end, [1 * MM, 2 * MM, 3 * MM])


def test_ten_megabytes_of_short_lines_are_linear() -> None:
    # the bulk scan works on the whole text at once: many lines, long numbers, long comments
    body = ("X" + "1" * 300 + ".5\n" + "(" + "c" * 300 + ")\n" + "G1 X1.5 Y2 Z-3\n" * 20) * 10_000
    t0 = time.perf_counter()
    tp = read_gcode_text(PRE + body, strict=False)
    assert time.perf_counter() - t0 < 5.0
    assert len(tp.moves) == 1 + 200_000 and tp.skipped == {"malformed_block": 10_000}
    t0 = time.perf_counter()
    with pytest.raises(ToolpathError, match=r"^<string>:3:1: X1+ is out of range"):
        read_gcode_text(PRE + body)
    assert time.perf_counter() - t0 < 5.0


FUZZ_PROGRAM = """%
O0042 (FUZZ)
G21 G90 G17 G94 (comment) ; tail
T1 M6
S8000 M3
G54 G0 X0 Y0 Z5
G1 Z-1 F300
X10.5 Y-2.25
G2 X20 Y-2.25 I4.75 J0
G3 X10 Y-2.25 R5
G18 G2 X11 Z-2 I1 K0
G17 G91 G1 X1 Y1
G90 G93 G1 X5 Y5 F20
G94 F400 G19 G3 Y6 Z-1 J1 K0
G17 G2 X5 Y6 Z-2 I1 J0 P2
/G0 Z10
G98 G81 X1 Y1 Z-2 R1
G80 G91 G28 Z0
G90 G0 X0 Y0 Z10
M5 M30
%
"""


def test_fuzz_only_toolpath_errors(rng: np.random.Generator, tmp_path: Path) -> None:
    base = FUZZ_PROGRAM.encode()
    read_gcode_text(FUZZ_PROGRAM)   # the seed program itself is valid
    alphabet = b"0123456789.+-XYZIJKRFGMPABCN ()%;/#\n\t\x00\xff\xe9"
    path = tmp_path / "fuzz.nc"
    outcomes = {"ok": 0, "error": 0}
    for case in range(300):
        path.write_bytes(mutate(base, alphabet, rng))
        rotary = "xyzac-trunnion" if case % 2 else None
        try:
            tp = read_gcode(path, rotary=rotary)
            summarize(tp)
            outcomes["ok"] += 1
        except ToolpathError:
            outcomes["error"] += 1
        summarize(read_gcode(path, strict=False, rotary=rotary))   # lenient never raises
    assert outcomes["ok"] > 0 and outcomes["error"] > 0


# --------------------------------------------------------------------------- semantics
def _ends_mm(tp) -> list[list[float]]:
    return [list(np.round(m.end / MM, 9)) for m in tp.moves]


def test_modal_motion_and_word_forms() -> None:
    tp = read_gcode_text("G21 G90 F600\nG0 X0 Y0 Z5\nG1 Z-1\nX10\nY10\nG0 Z5\nX0 Y0")
    assert [m.kind for m in tp.moves] == [MoveKind.RAPID] + [MoveKind.LINEAR] * 3 + [
        MoveKind.RAPID] * 2
    assert _ends_mm(tp) == [[0, 0, 5], [0, 0, -1], [10, 0, -1], [10, 10, -1], [10, 10, 5],
                            [0, 0, 5]]
    assert tp.moves[1].feed == pytest.approx(0.01)   # 600 mm/min
    assert tp.moves[0].start is None and tp.meta["unknown_start_moves"] == 1
    np.testing.assert_array_equal(tp.moves[2].start, tp.moves[1].end)
    packed = read_gcode_text("G21G90G0X1.5Y2Z.189\nG1X-75.Y+1.F300\n"
                             "G0  X  16.339  Y -25.409 (a) (b) Z\t-1 ; c (d)\nn10 x1 y2 z3")
    assert _ends_mm(packed) == [[1.5, 2, 0.189], [-75, 1, 0.189], [16.339, -25.409, -1],
                                [1, 2, 3]]
    assert packed.moves[2].source.column == 5


def test_incremental_and_inch() -> None:
    tp = read_gcode_text("G21 G90 F100\nG0 X1 Y1 Z1\nG91\nG1 X1 Y2 Z3\nX1\nG90 X0")
    assert _ends_mm(tp) == [[1, 1, 1], [2, 3, 4], [3, 3, 4], [0, 3, 4]]
    tp = read_gcode_text("G20 G90 F10\nG0 X1 Y2 Z3\nG1 X2")
    np.testing.assert_allclose(tp.moves[-1].end, [2 * IN, 2 * IN, 3 * IN], atol=1e-15)
    assert tp.moves[-1].feed == pytest.approx(10 * IN / 60)
    assert tp.units == "inch" and tp.warnings == []
    # units default to mm with a warning; a late G20 warns about the moves before it
    tp = read_gcode_text("F1\nG0 X1 Y1 Z1\nG20\nG0 X1")
    assert tp.units == "inch"
    assert [w.category for w in tp.warnings] == ["moves_before_units"]
    assert _ends_mm(tp) == [[1, 1, 1], [25.4, 1, 1]]
    assert [w.category for w in read_gcode_text("G0 X1 Y1 Z1").warnings] == ["no_units"]


def test_arc_centre_modes() -> None:
    start = "G21 G17 F100\nG0 X10 Y0 Z0\n"
    inc = read_gcode_text(start + "G91.1 G3 X0 Y10 I-10 J0").moves[-1]
    ab = read_gcode_text(start + "G90.1 G3 X0 Y10 I0 J0").moves[-1]
    for m in (inc, ab):
        np.testing.assert_allclose(m.center, [0, 0, 0], atol=1e-15)
        assert m.kind == MoveKind.ARC_CCW
        assert m.length == pytest.approx(10 * MM * math.pi / 2)
    with pytest.raises(ToolpathError, match="arc radius differs"):
        read_gcode_text(start + "G90.1 G3 X0 Y10 I-10 J0")   # incremental numbers in G90.1


@pytest.mark.parametrize(("code", "r", "centre_y", "sweep_deg"), [
    ("G2", 10, -8.660254037844386, 60), ("G2", -10, 8.660254037844386, 300),
    ("G3", 10, 8.660254037844386, 60), ("G3", -10, -8.660254037844386, 300)])
def test_r_arcs_short_and_long(code: str, r: float, centre_y: float, sweep_deg: float) -> None:
    m = read_gcode_text(PRE + f"{code} X10 Y0 R{r}").moves[-1]
    np.testing.assert_allclose(m.center, [5 * MM, centre_y * MM, 0], atol=1e-15)
    assert m.length == pytest.approx(10 * MM * math.radians(sweep_deg))


def test_helix_full_circle_and_turns() -> None:
    helix = read_gcode_text(PRE + "G2 X0 Y0 Z-3 I5 J0").moves[-1]
    assert helix.length == pytest.approx(math.hypot(2 * math.pi * 5, 3) * MM)
    circle = read_gcode_text(PRE + "G3 X0 Y0 I5").moves[-1]
    assert circle.length == pytest.approx(2 * math.pi * 5 * MM)
    turns = read_gcode_text(PRE + "G3 X0 Y0 I5 P3").moves[-1]
    assert turns.turns == 2
    assert turns.length == pytest.approx(3 * 2 * math.pi * 5 * MM)
    np.testing.assert_allclose(summarize(read_gcode_text(PRE + "G3 X0 Y0 I5"))["bbox_m"],
                               [[0, -5 * MM, 0], [10 * MM, 5 * MM, 0]], atol=1e-15)
    # K0 on a G17 arc is harmless
    assert read_gcode_text(PRE + "G3 X0 Y0 I5 J0 K0").moves[-1].length == circle.length


@pytest.mark.parametrize(("text", "normal", "kind", "quarter_turns", "bbox_mm"), [
    # G18: plane (Z, X), normal +Y, seen from +Y; from the origin about the centre X1 Z0
    ("G18 G2 X1 Z-1 I1 K0", [0, 1, 0], MoveKind.ARC_CW, 1, [[0, 0, -1], [1, 0, 0]]),
    ("G18 G3 X1 Z-1 I1 K0", [0, 1, 0], MoveKind.ARC_CCW, 3, [[0, 0, -1], [2, 0, 1]]),
    # G19: plane (Y, Z), normal +X; about the centre Y1 Z0
    ("G19 G2 Y1 Z-1 J1 K0", [1, 0, 0], MoveKind.ARC_CW, 3, [[0, 0, -1], [0, 2, 1]]),
    ("G19 G3 Y1 Z-1 J1 K0", [1, 0, 0], MoveKind.ARC_CCW, 1, [[0, 0, -1], [0, 1, 0]]),
])
def test_g18_g19_normals_and_sense(text: str, normal: list, kind: MoveKind, quarter_turns: int,
                                   bbox_mm: list) -> None:
    tp = read_gcode_text(PRE + text)
    m = tp.moves[-1]
    np.testing.assert_array_equal(m.normal, normal)
    assert m.kind == kind
    assert m.length == pytest.approx(quarter_turns * math.pi / 2 * MM)
    np.testing.assert_allclose(summarize(tp)["bbox_m"], np.array(bbox_mm) * MM, atol=1e-15)


@pytest.mark.parametrize(("text", "centre_mm"), [
    ("G18 G2 X1 Z-1 R1", [1, 0, 0]), ("G18 G3 X1 Z-1 R-1", [1, 0, 0]),
    ("G18 G3 X1 Z-1 R1", [0, 0, -1]), ("G19 G3 Y1 Z-1 R1", [0, 1, 0]),
    ("G19 G2 Y1 Z-1 R1", [0, 0, -1])])
def test_r_arcs_in_g18_g19_match_the_ijk_sense(text: str, centre_mm: list) -> None:
    # the short arc goes the way the quarter-turn I/J/K arcs above go, so the plane axis order
    # (Z, X) of G18 and (Y, Z) of G19 decides which side of the chord the centre is on
    m = read_gcode_text(PRE + text).moves[-1]
    np.testing.assert_allclose(m.center, np.array(centre_mm) * MM, atol=1e-15)


def test_inverse_time_duration() -> None:
    tp = read_gcode_text("G21 G93\nG0 X0 Y0 Z0\nG1 X10 F30\nG2 X20 Y0 I5 F120\nG0 X0")
    assert [m.duration for m in tp.moves] == [None, pytest.approx(2.0), pytest.approx(0.5), None]
    assert all(m.feed is None for m in tp.moves)
    assert summarize(tp)["inverse_time_moves"] == 2


def test_g28_leaves_position_unknown() -> None:
    text = "G21 F100\nG0 X0 Y0 Z10\nG91 G28 Z0\nG90 G0 X5 Y5\nG0 Z2\nG1 X6"
    tp = read_gcode_text(text)
    assert _ends_mm(tp) == [[0, 0, 10], [5, 5, 2], [6, 5, 2]]
    assert [m.start is None for m in tp.moves] == [True, True, False]
    assert tp.skipped == {"unknown_position": 1}
    assert tp.meta["homing_blocks"] == 1 and tp.meta["unknown_start_moves"] == 2
    known = read_gcode_text(text, home_position=(0.0, 0.0, 0.1),
                            initial_position=(0.0, 0.0, 0.0))
    assert _ends_mm(known) == [[0, 0, 10], [0, 0, 100], [5, 5, 100], [5, 5, 2], [6, 5, 2]]
    assert all(m.start is not None for m in known.moves)
    # G28 through an intermediate point; G53 machine moves are skipped and unknown afterwards
    tp = read_gcode_text("G21 F100\nG0 X0 Y0 Z10\nG28 Z20\nG53 G0 Z0\nG0 Z5")
    assert _ends_mm(tp) == [[0, 0, 10], [0, 0, 20], [0, 0, 5]]
    assert tp.moves[-1].start is None
    assert tp.skipped == {"machine_coordinates": 1}


def test_canned_cycles() -> None:
    tp = read_gcode_text("G21 G90 G17 F100\nG0 X0 Y0 Z10\nG99 G81 X1 Y2 Z-3 R2\nX5\n"
                         "G98 G81 X6 Z-4 R1 L1\nG80\nG0 Z-1\nG81 X7 Y7 Z-5 R0\n"
                         "G91 G81 X1 Z-2 R-1 L2\nG90 G80\nG83 X20 Y20 Z-5 R1 Q1\nG80\n")
    ends = _ends_mm(tp)
    assert ends[1:5] == [[1, 2, 10], [1, 2, 2], [1, 2, -3], [1, 2, 2]]        # G99: back to R
    assert ends[5:8] == [[5, 2, 2], [5, 2, -3], [5, 2, 2]]                     # modal repeat
    assert ends[8:12] == [[6, 2, 2], [6, 2, 1], [6, 2, -4], [6, 2, 2]]        # G98: initial Z
    assert ends[13:17] == [[6, 2, 0], [7, 7, 0], [7, 7, -5], [7, 7, 0]]       # below R first
    assert ends[17:] == [[8, 7, 0], [8, 7, -1], [8, 7, -3], [8, 7, 0],
                         [9, 7, 0], [9, 7, -1], [9, 7, -3], [9, 7, 0]]        # G91 L2
    assert [m.kind for m in tp.moves[1:5]] == [MoveKind.RAPID, MoveKind.RAPID, MoveKind.LINEAR,
                                               MoveKind.RAPID]
    assert tp.skipped == {"canned_cycle_not_expanded": 1}
    assert [w.category for w in tp.warnings] == ["canned_cycle_not_expanded"]


def test_program_structure_words() -> None:
    text = ("%\nO1234\nG21 G90 G40 G49 G64 P0.01 G80 G43 H1 F100\nS5000 M3 T7 M6 M8\n"
            "/G0 X1 Y1 Z1\nG41 D1 G1 X2\nM101\nM428\nM429\nG4 P0.5\nM5\nG1 X3\nM30\nG0 X9\n%\n")
    tp = read_gcode_text(text)
    assert tp.meta["program"] == "O1234"
    assert tp.meta["block_delete_lines"] == 1 and tp.meta["dwell_s"] == 0.5
    assert tp.meta["tcp_switches"] == [(8, "tcp"), (9, "identity")]
    assert tp.meta["warning_counts"] == {"block_delete": 1, "cutter_compensation": 1,
                                         "user_mcode": 1, "after_program_end": 1}
    assert tp.skipped == {"user_mcode": 1, "after_program_end": 1}
    assert [m.spindle_rpm for m in tp.moves] == [5000.0, 5000.0, 0.0]
    assert {m.tool for m in tp.moves} == {7}
    assert _ends_mm(tp)[-1] == [3, 1, 1]


def test_xyzac_kinematics_hand_examples() -> None:
    kin = make_rotary_kinematics("xyzac-trunnion")
    # A 90°, C 90°: Rx(-90)·(1,2,3) = (1,3,-2); Rz(-90)·(1,3,-2) = (3,-1,-2); axis Rz(-90)·(0,1,0)
    np.testing.assert_allclose(kin.tip((1.0, 2.0, 3.0), math.pi / 2, math.pi / 2), [3, -1, -2],
                               atol=1e-15)
    np.testing.assert_allclose(kin.tool_axis(math.pi / 2, math.pi / 2), [1, 0, 0], atol=1e-15)
    np.testing.assert_allclose(kin.tool_axis(math.radians(30), 0.0), [0, 0.5, math.sqrt(3) / 2])
    # pivot 10 above the origin, A 90°: (0,0,-10) tilts to (0,-10,0), + pivot → (0,-10,10)
    piv = make_rotary_kinematics("xyzac-trunnion", pivot=(0, 0, 10))
    np.testing.assert_allclose(piv.tip((0, 0, 0), math.pi / 2, 0), [0, -10, 10], atol=1e-14)
    # the reader: identity kinematics (no M428) vs TCP (M428)
    text = "G21 F100\nG0 X1 Y2 Z3 A90 C90\n"
    m = read_gcode_text(text, rotary="xyzac-trunnion").moves[0]
    np.testing.assert_allclose(m.end, [3 * MM, -1 * MM, -2 * MM], atol=1e-15)
    np.testing.assert_allclose(m.tool_axis, [1, 0, 0], atol=1e-15)
    assert m.extra == pytest.approx({"A": math.pi / 2, "C": math.pi / 2})
    m = read_gcode_text("M428\n" + text, rotary="xyzac-trunnion").moves[0]
    np.testing.assert_allclose(m.end, [1 * MM, 2 * MM, 3 * MM], atol=1e-15)
    np.testing.assert_allclose(m.tool_axis, [1, 0, 0], atol=1e-15)
    m = read_gcode_text("M428\n" + text, rotary="xyzac-trunnion", tcp=False).moves[0]
    np.testing.assert_allclose(m.end, [3 * MM, -1 * MM, -2 * MM], atol=1e-15)
    # an arc in identity kinematics is turned with the table: A 90° maps the XY plane normal +Z
    # to (0, sin 90°, cos 90°) = +Y in the workpiece
    arc = read_gcode_text("G21 F100\nG0 X0 Y0 Z0 A90 C0\nG3 X0 Y0 I5",
                          rotary="xyzac-trunnion").moves[-1]
    np.testing.assert_allclose(arc.normal, [0, 1, 0], atol=1e-15)
    assert arc.length == pytest.approx(2 * math.pi * 5 * MM)


def test_trunnion_matches_linuxcnc_forward_kinematics(rng: np.random.Generator) -> None:
    """Oracle: LinuxCNC trtfuncs.c xyzacKinematicsForward / xyzbcKinematicsForward, transcribed."""
    for _ in range(50):
        j = rng.uniform(-0.2, 0.2, 3)
        rp = rng.uniform(-0.1, 0.1, 3)
        dx, dy, dz = rng.uniform(-0.05, 0.05, 3)
        a, c = rng.uniform(-math.pi, math.pi, 2)
        sa, ca, sc, cc = math.sin(a), math.cos(a), math.sin(c), math.cos(c)
        ac = make_rotary_kinematics("xyzac-trunnion", pivot=rp, c_offset=(0, dy, dz))
        expect = [cc * (j[0] - rp[0]) + sc * ca * (j[1] - dy - rp[1])
                  + sc * sa * (j[2] - dz - rp[2]) + sc * dy + rp[0],
                  -sc * (j[0] - rp[0]) + cc * ca * (j[1] - dy - rp[1])
                  + cc * sa * (j[2] - dz - rp[2]) + cc * dy + rp[1],
                  -sa * (j[1] - dy - rp[1]) + ca * (j[2] - dz - rp[2]) + dz + rp[2]]
        np.testing.assert_allclose(ac.tip(tuple(j), a, c), expect, atol=1e-14)
        np.testing.assert_allclose(ac.machine(ac.tip(tuple(j), a, c), a, c), j, atol=1e-14)
        bc = make_rotary_kinematics("xyzbc-trunnion", pivot=rp, c_offset=(dx, 0, dz))
        b = a
        sb, cb = sa, ca
        expect = [cc * cb * (j[0] - dx - rp[0]) + sc * (j[1] - rp[1])
                  - cc * sb * (j[2] - dz - rp[2]) + cc * dx + rp[0],
                  -sc * cb * (j[0] - dx - rp[0]) + cc * (j[1] - rp[1])
                  + sc * sb * (j[2] - dz - rp[2]) - sc * dx + rp[1],
                  sb * (j[0] - dx - rp[0]) + cb * (j[2] - dz - rp[2]) + dz + rp[2]]
        np.testing.assert_allclose(bc.tip(tuple(j), b, c), expect, atol=1e-14)


def test_moves_are_real_frozen_dataclasses() -> None:
    tp = read_gcode_text(PRE + "G1 X1\nG2 X3 Y0 I1\n", rotary="xyzac-trunnion", tcp=True)
    names = [f.name for f in dataclasses.fields(Move)]
    for m in tp.moves:
        assert list(vars(m)) == names
        assert vars(Move(**vars(m))) == vars(m)
        assert not m.end.flags.writeable
        with pytest.raises(dataclasses.FrozenInstanceError):
            m.feed = 1.0  # type: ignore[misc]
        assert str(m.source) == f"<string>:{m.source.line}:{m.source.column}"
    assert tp.moves[1].start is tp.moves[0].end


def test_reader_object_options_and_file_errors(tmp_path: Path) -> None:
    path = tmp_path / "p.nc"
    path.write_bytes(b"(caf\xe9)\nG21 F1\nG0 X1 Y2 Z3\n")
    tp = GcodeReader().read(str(path))
    assert tp.meta["encoding"] == "latin-1" and tp.format == "gcode"
    assert tp.moves[0].source.file == str(path)
    with pytest.raises(InputError, match="unknown G-code reader option"):
        read_gcode(path, speed=2)
    with pytest.raises(InputError, match="rotary"):
        read_gcode(path, rotary="xyz-spindle")
    with pytest.raises(ToolpathError, match="cannot read the file|not found"):
        read_gcode(tmp_path / "missing.nc")


# --------------------------------------------------------------------------- bulk path, move list
def _same(a, b) -> bool:
    """Equal to the bit (floats by their hex form, arrays by bytes, dtype and write flag)."""
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return (isinstance(a, np.ndarray) and isinstance(b, np.ndarray) and a.shape == b.shape
                and a.dtype == b.dtype and a.tobytes() == b.tobytes()
                and a.flags.writeable == b.flags.writeable)
    if type(a) is not type(b):
        return False
    if isinstance(a, float):
        return a.hex() == b.hex()
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, (list, tuple)):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    if dataclasses.is_dataclass(a):
        return _same(vars(a), vars(b))
    return a == b


def _read_both_ways(text: str, strict: bool, **kw):
    """(bulk, interpreter-only) outcomes: a Toolpath or the ToolpathError message."""
    from robot_io.gcode import GcodeOptions
    from robot_io.gcode._interp import run_program

    out = []
    for plain in (True, False):
        opts = GcodeOptions.from_kwargs(**kw)
        try:
            out.append(run_program(text, "<string>", strict, opts, plain=plain))
        except ToolpathError as e:
            out.append(str(e))
    return out


def _assert_same_reading(fast, ref) -> None:
    if isinstance(ref, str) or isinstance(fast, str):
        assert fast == ref
        return
    assert len(fast.moves) == len(ref.moves)
    fm, rm = list(fast.moves), list(ref.moves)
    for i, (a, b) in enumerate(zip(fm, rm, strict=True)):
        assert _same(a, b), f"move {i}: {a} != {b}"
        if i:
            assert (a.start is fm[i - 1].end) == (b.start is rm[i - 1].end)
    assert [(str(w), w.category) for w in fast.warnings] == [
        (str(w), w.category) for w in ref.warnings]
    assert dict(fast.skipped) == dict(ref.skipped)
    assert _same(fast.meta, ref.meta) and fast.units == ref.units


@pytest.fixture
def bulk_lines(monkeypatch: pytest.MonkeyPatch) -> dict[str, int]:
    """Counts the lines the bulk path executes (``["lines"]``) and the reads that used it."""
    from robot_io.gcode import _interp as _gcode_interp

    count = {"lines": 0, "calls": 0}
    real = _gcode_interp.execute_plain

    def counting(run, scan, a, b):
        c = real(run, scan, a, b)
        count["lines"] += c - a
        count["calls"] += c > a
        return c

    monkeypatch.setattr(_gcode_interp, "execute_plain", counting)
    return count


@pytest.mark.parametrize("name", sorted(SHARED))
def test_bulk_path_reads_the_shared_programs_like_the_interpreter(
        name: str, bulk_lines: dict[str, int]) -> None:
    text = _data(name).read_text()
    for strict in (True, False):
        fast, ref = _read_both_ways(text, strict, **SHARED[name]["kw"])
        _assert_same_reading(fast, ref)
    # the 3-axis CAM programs are almost all plain lines and go through the bulk path
    share = bulk_lines["lines"] / 2 / (text.count("\n") + 1)
    if name.startswith("camotics_"):
        assert share > 0.99
    elif "5ax" in name:
        assert share == 0.0   # rotary kinematics: every line through the interpreter


def _plain_program(rng: np.random.Generator) -> str:
    """A random program of mostly plain lines (packed, spaced, N words, lower case, CRLF) with
    a few lines that need the interpreter (modes, arcs, comments, program end, rotary words)."""
    special = ["G91", "G90", "G20", "G21", "G93", "G94", "M30", "(note)", "; tail", "%", "/X1",
               "G2 X1 Y1 I1 J0", "T2 M6", "S900 M3", "M5", "G28", "G81 X1 Y1 Z-1 R1", "G80",
               "M428", "G0 A10", "F0", "G1", "G0", "", " \t"]

    def num() -> str:
        v = rng.uniform(-200, 200)
        return [f"{v:.3f}", f"{v:.0f}.", f"{int(v)}", f"{v:.4f}".replace("0.", ".", 1),
                f"{abs(v):+.2f}", "-0", f"{v:.6f}"][int(rng.integers(7))]

    lines = ["G21 G90 G17"] if rng.random() < 0.7 else []
    if rng.random() < 0.7:
        lines.append(f"G0 X{num()} Y{num()} Z{num()}")
    if rng.random() < 0.6:
        lines.append(f"G1 F{rng.uniform(1, 900):.1f}")
    for _ in range(int(rng.integers(20, 120))):
        if rng.random() < 0.04:
            lines.append(special[int(rng.integers(len(special)))])
            continue
        words = [f"N{int(rng.integers(0, 99999))}"] if rng.random() < 0.3 else []
        if rng.random() < 0.08:
            words.append(["G0", "G1", "G00", "G01", "g1", "G 1", "G001"][int(rng.integers(7))])
        words += [k + num() for k in "XYZ" if rng.random() < 0.5]
        if rng.random() < 0.05:
            words.append("F" + num().lstrip("-+"))
        if rng.random() < 0.1:
            rng.shuffle(words)
        line = ("" if rng.random() < 0.3 else " ").join(words)
        lines.append(line.lower() if rng.random() < 0.05 else line)
    return ("\r\n" if rng.random() < 0.15 else "\n").join(lines)


def test_bulk_path_matches_the_interpreter_on_random_programs(
        rng: np.random.Generator, bulk_lines: dict[str, int]) -> None:
    alphabet = b"0123456789.+-XYZIJKRFGMPABCN ()%;/#\n\t\r\x00\xff\xe9xyzfgn"
    outcomes = {"ok": 0, "error": 0}
    for case in range(160):
        text = _plain_program(rng)
        if case % 2:
            text = mutate(text.encode(), alphabet, rng, edits=25).decode("latin-1")
        kw = [{}, {"rotary": "xyzac-trunnion"}, {"initial_position": (0.001, 0.0, 0.0)},
              {"default_units": "inch"}][case % 4]
        for strict in (True, False):
            fast, ref = _read_both_ways(text, strict, **kw)
            _assert_same_reading(fast, ref)
            outcomes["error" if isinstance(ref, str) else "ok"] += 1
    assert outcomes["ok"] > 100 and outcomes["error"] > 20
    assert bulk_lines["calls"] > 100 and bulk_lines["lines"] > 3000   # the bulk path did run


def test_move_list_reads_like_a_list() -> None:
    text = PRE + "".join(f"G1 X{i} Y{i % 7}\n" for i in range(40))
    tp = read_gcode_text(text)
    moves = tp.moves
    assert type(moves).__name__ == "MoveList" and len(moves) == 41
    assert moves[-1] is moves[40] and moves[3] is moves[3]
    assert moves[2].start is moves[1].end and moves[0].start is None
    assert [m.source.line for m in moves[1:4]] == [3, 4, 5]
    assert moves[::20] == [moves[0], moves[20], moves[40]]
    assert list(moves) == moves and moves == list(moves)
    np.testing.assert_array_equal(moves.ends, np.array([m.end for m in moves]))
    assert not moves.ends.flags.writeable
    assert moves[40].feed == pytest.approx(100 * MM / 60) and moves[0].feed is None
    m = moves[40]   # plain Python scalars, as the interpreter makes them
    assert type(m.feed) is float and type(m.source.line) is int and type(m.source.column) is int
    assert m.spindle_rpm is None and m.tool is None and m.extra == {} and m.turns == 0
    assert m.end.tolist() == [39 * MM, 4 * MM, 0.0] and m.kind == MoveKind.LINEAR
    with pytest.raises(IndexError):
        moves[41]
    # a move built on its own is the one iteration hands out later, and shares its end array
    again = read_gcode_text(text).moves
    m5 = again[5]
    built = list(again)
    assert built[5] is m5 and built[6].start is m5.end and _same(built, list(moves))
    assert "41 moves" in repr(moves)
    empty = read_gcode_text("G21\n").moves
    assert len(empty) == 0 and list(empty) == [] and empty == []
