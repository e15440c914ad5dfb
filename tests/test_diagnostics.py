"""Plausibility checks and grouped warnings (robot_io.diagnostics), and the tool-axis summary."""

from __future__ import annotations

from pathlib import Path

import pytest

from robot_io.diagnostics import WarningGroup, group_warnings, plausibility_warnings
from robot_io.gcode import read_gcode_text
from robot_io.readers import read_toolpath
from robot_io.toolpath import SourceRef, summarize

SHARED = Path(__file__).resolve().parents[2] / "shared" / "data" / "toolpaths"


def _kinds(tp) -> list[str]:
    return [w.category for w in plausibility_warnings(tp)]


def test_inch_program_written_in_mm_values_is_flagged():
    # 52 m wide and 64 m/min once read as inches
    tp = read_gcode_text("G20 G90\nG0 X0 Y0 Z10\nG1 Z-1 F2520\nG1 X2050 F2520\n")
    ws = plausibility_warnings(tp)
    assert [w.category for w in ws] == ["plausibility"]
    assert "look like millimetres" in ws[0].message and "G21" in ws[0].message


def test_feed_beyond_a_milling_robot_is_flagged():
    tp = read_gcode_text("G21 G90\nG0 X0 Y0 Z10\nG1 Z-1 F300\nG1 X100 F64000\n")
    ws = plausibility_warnings(tp)
    assert [w.category for w in ws] == ["plausibility"]
    assert "64.0 m/min" in ws[0].message and ws[0].source.line == 4


def test_part_wider_than_any_cell_is_flagged():
    tp = read_gcode_text("G21 G90\nG0 X0 Y0 Z10\nG1 Z-1 F300\nG1 X12000 F300\n")
    assert "more than twice the reach" in plausibility_warnings(tp)[0].message
    assert plausibility_warnings(tp, reach=7.0) == []


def test_mm_program_written_in_inches_is_flagged():
    tp = read_gcode_text("G21 G90\nG0 X0 Y0 Z0.1\nG1 Z-0.02 F0.4\nG1 X1.5 F0.4\n")
    assert "look like inches" in plausibility_warnings(tp)[0].message


def test_a_plausible_program_gets_no_warning():
    tp = read_gcode_text("G21 G90\nG0 X0 Y0 Z10\nG1 Z-1 F300\nG1 X200 F1200\n")
    assert plausibility_warnings(tp) == []


@pytest.mark.skipif(not SHARED.is_dir(), reason="../shared/data/toolpaths is not beside the repo")
def test_the_shared_programs_are_plausible():
    for p in sorted(SHARED.iterdir()):
        if p.suffix in (".nc", ".ngc", ".apt"):
            rotary = {"rotary": "xyzac-trunnion"} if "5ax" in p.name else {}
            tp = read_toolpath(p, strict=False, **rotary)
            assert [w for w in tp.warnings if w.category == "plausibility"] == [], p.name


def test_groups_count_beyond_the_kept_warnings():
    text = "G21 G90\nG0 X0 Y0 Z5\n" + "".join(f"G41 G1 X{i} F100\nG40\n" for i in range(80))
    tp = read_gcode_text(text, strict=False)
    groups = group_warnings([tp])
    by_kind = {g.kind: g for g in groups}
    assert by_kind, "cutter compensation must warn"
    g = next(iter(by_kind.values()))
    assert g.count >= len([w for w in tp.warnings if w.category == g.kind])
    back = WarningGroup.from_json(g.as_json())
    assert back == g
    assert WarningGroup.from_json({"kind": "k", "count": 1, "first": "x", "message": "m"}).first \
        == SourceRef("x", 0, 0)


@pytest.mark.parametrize(("text", "has", "n", "turning"), [
    ("G21\nG0 X0 Y0 Z0\nG1 X1 F100\n", False, 0, 0),
])
def test_gcode_without_axes_is_three_axis(text, has, n, turning):
    s = summarize(read_gcode_text(text))
    assert (s["has_tool_axis"], s["tool_axes"], s["tool_axis_turning_moves"]) == (has, n, turning)


def test_apt_tool_axis_only_counts_when_it_tilts():
    from robot_io.apt import read_apt_text

    plain = read_apt_text("UNITS/MM\nFEDRAT/100,MMPM\nGOTO/0,0,0,0,0,1\nGOTO/1,0,0,0,0,1\n")
    s = summarize(plain)
    assert not s["has_tool_axis"] and s["tool_axes"] == 1
    indexed = read_apt_text("UNITS/MM\nFEDRAT/100,MMPM\nGOTO/0,0,0,0,0,1\nGOTO/1,0,0,0,0,1\n"
                            "RAPID\nGOTO/1,0,5,0,1,0\nGOTO/2,0,5,0,1,0\n")
    s = summarize(indexed)
    assert s["has_tool_axis"] and s["tool_axes"] == 2 and s["tool_axis_turning_moves"] == 0
    five = read_apt_text("UNITS/MM\nFEDRAT/100,MMPM\nGOTO/0,0,0,0,0,1\n"
                         "GOTO/1,0,0,0,0.6,0.8\nGOTO/2,0,0,0,0.8,0.6\n")
    s = summarize(five)
    assert s["tool_axes"] == 3 and s["tool_axis_turning_moves"] == 2
