"""Tests of the KUKA KRL reader (robot_io.krl.reader).

The fixtures in ``tests/data/krl`` are hand-written for these tests (no third-party program text):
``plain_inline.src`` (inline literals, INI fold, $BASE/$TOOL literals, BCO and joint PTPs, a CIRC, a
partial target), ``named_pair.src`` + ``NAMED_PAIR.DAT`` (CRLF, named positions, REAL feeds, arrays,
FRAME variable, BASE_DATA, a .dat whose name differs in case), and the paged program
``paged_main`` + ``paged_main_p001`` + ``Paged_Main_P002`` (main calling two pages, GLOBAL feeds,
a page with its own .dat and a local routine, CRLF, mixed-case file name). Expected values are
written out from the literals in those files; tool axes are computed by hand from A, B, C with
R = Rz(A)·Ry(B)·Rx(C) (the TCP x axis is (cosA·cosB, sinA·cosB, −sinB), the tool axis its negative).
"""

from __future__ import annotations

import math
import re
import time
from pathlib import Path

import numpy as np
import pytest

from models.errors import InputError
from robot_io.krl.reader import (
    KrlReader,
    abc_to_matrix,
    matrices_to_abc,
    matrix_to_abc,
    read_krl,
    read_krl_text,
)
from robot_io.readers import read_toolpath
from robot_io.toolpath import MoveKind, ToolpathError, arc_geometry, summarize

DATA = Path(__file__).resolve().parent / "data" / "krl"
MM = 1e-3
S = math.sqrt(0.5)
#: Preamble of the small programs: feed set, robot at (0, 0, 10) mm pointing down; body from line 4.
PRE = "DEF t( )\n$VEL.CP = 0.001\nPTP {X 0,Y 0,Z 10,A 0,B 90,C 0}\n"


def _prog(body: str) -> str:
    return PRE + body + "\nEND\n"


def _ends(tp) -> np.ndarray:
    return np.array([m.end for m in tp.moves])


def _axes(tp) -> np.ndarray:
    return np.array([m.tool_axis for m in tp.moves])


# --------------------------------------------------------------------------- fixtures
def test_plain_inline() -> None:
    tp = read_krl(DATA / "plain_inline.src")
    assert tp.format == "krl" and tp.units == "mm"
    assert [m.kind for m in tp.moves] == [MoveKind.RAPID, MoveKind.LINEAR, MoveKind.LINEAR,
                                          MoveKind.ARC_CCW, MoveKind.LINEAR, MoveKind.LINEAR]
    np.testing.assert_allclose(_ends(tp), np.array([
        [0, 0, 50], [0, 0, -2], [40, 0, -2], [60, 20, -2], [60, 60, -2], [60, 60, 50]]) * MM,
        atol=1e-12)
    assert [m.feed for m in tp.moves] == [None, 0.0015, 0.0015, 0.002, 0.002, 0.002]
    # A 0, B 90 → TCP x = (0, 0, −1) → tool axis (0, 0, 1); A 90, B 60 → x = (0, 0.5, −√3/2)
    down = [0.0, 0.0, 1.0]
    tilted = [0.0, -0.5, math.sqrt(3) / 2]
    np.testing.assert_allclose(_axes(tp), [down, down, down, down, tilted, tilted], atol=1e-12)
    # the partial target LIN {Z 50} kept X, Y and the orientation of the move before it
    assert tp.moves[5].extra["abc_deg"] == (90.0, 60.0, 0.0)
    first = tp.moves[0]
    assert first.start is None and first.extra["s"] == 6 and first.extra["t"] == 27
    assert first.extra["after_joint_move"]["axes_deg"]["A5"] == 45.0
    np.testing.assert_allclose(tp.moves[1].start, [0, 0, 0.05])
    assert tp.moves[1].extra["approx"] == "C_DIS" and tp.moves[1].extra["apo_cdis"] == 0.5 * MM
    assert tp.meta["unknown_start_moves"] == 1 and tp.meta["advance"] == 5
    assert [j["target"] for j in tp.meta["joint_moves"]] == ["$AXIS_ACT", None, None]
    base = tp.meta["base"]["matrix"]
    np.testing.assert_allclose(base[:3, 3], [0.8, -0.2, 0.45])
    np.testing.assert_allclose(base[:3, :3], np.eye(3), atol=1e-15)
    np.testing.assert_allclose(tp.meta["tool"]["matrix"][:3, 3], [0, 0, 0.25])
    np.testing.assert_allclose(tp.meta["tool"]["matrix"][:3, 0], [0, 0, 1], atol=1e-15)  # B −90
    assert dict(tp.skipped) == {"header": 4, "declaration": 1, "interrupt": 2, "bas": 1,
                                "system_variable": 3, "joint_move": 3, "io": 1, "wait": 1,
                                "halt": 1}
    assert tp.warnings == []
    assert tp.moves[3].source.line == 38 and tp.moves[3].source.column == 6


def test_named_pair_crlf_dat_case_insensitive() -> None:
    src = DATA / "named_pair.src"
    assert b"\r\n" in src.read_bytes() and not (DATA / "named_pair.dat").exists()
    tp = read_krl(src)
    assert [m.kind for m in tp.moves] == [MoveKind.RAPID] + [MoveKind.LINEAR] * 5
    np.testing.assert_allclose(_ends(tp), np.array([
        [10, 20, 30], [10, 20, -1.5], [50, 20, -1.5], [50, 60, -1.5], [10, 60, -1.5],
        [10, 20, 80]]) * MM, atol=1e-12)
    # V_S1 = 0.0012 (DECL GLOBAL REAL in the .dat), then V_S1 * 2
    assert [m.feed for m in tp.moves] == [None, 0.0012, 0.0012, 0.0012, 0.0024, 0.0024]
    # A 180, B 0, C 180 → x = (−1, 0, 0) → tool axis (1, 0, 0);
    # A 180, B 30 → x = (−cos30, 0, −sin30) → tool axis (cos30, 0, 1/2)
    side = [1.0, 0.0, 0.0]
    np.testing.assert_allclose(_axes(tp), [side] * 4 + [[math.sqrt(3) / 2, 0, 0.5], side],
                               atol=1e-12)
    assert [m.source.line for m in tp.moves] == [13, 16, 18, 19, 21, 23]   # CRLF: lines as written
    assert tp.moves[1].extra["s"] == 2 and tp.moves[1].extra["t"] == 35      # 'B010', 'B100011'
    assert tp.moves[1].extra["apo_cdis"] == 1.0 * MM and tp.moves[1].extra["approx"] == "C_DIS"
    assert tp.moves[0].start is None and tp.meta["joint_moves"][0]["axes_deg"]["A2"] == -90.0
    base, tool = tp.meta["base"], tp.meta["tool"]
    assert base["name"] == "BASE_DATA[3]" and base["index"] == 3
    np.testing.assert_allclose(base["matrix"][:3, 3], [1.0, 0.0, 0.3])
    np.testing.assert_allclose(base["matrix"][:3, 0], [0, 1, 0], atol=1e-15)        # A 90
    assert tool["name"] == "SPINDLE_TCP"
    np.testing.assert_allclose(tool["matrix"][:3, 3], [0, 0, 0.25])
    assert tp.meta["modules"] == [str(src)] and tp.warnings == []


def test_paged_program_follows_pages_in_order() -> None:
    tp = read_krl(DATA / "paged_main.src")
    assert [Path(m.source.file).name for m in tp.moves] == (
        ["paged_main_p001.src"] * 4 + ["Paged_Main_P002.src"] * 2)
    np.testing.assert_allclose(_ends(tp), np.array([
        [0, 0, 20], [0, 0, -1], [30, 0, -1], [30, 30, -1], [0, 30, -1], [0, 30, 20]]) * MM,
        atol=1e-12)
    assert [m.feed for m in tp.moves] == [None, 0.002, 0.002, 0.002, 0.001, 0.001]
    np.testing.assert_allclose(_axes(tp), [[0, 0, 1]] * 6, atol=1e-12)
    # page 2 starts where page 1 ended; the local routine's LIN uses page 2's own .dat
    np.testing.assert_allclose(tp.moves[4].start, [0.03, 0.03, -0.001])
    assert tp.moves[5].source.line == 9 and tp.moves[5].extra["t"] == 27
    assert [Path(p).name for p in tp.meta["modules"]] == [
        "paged_main.src", "paged_main_p001.src", "Paged_Main_P002.src"]
    assert tp.meta["base"]["name"] == "BASE_DATA[1]" and tp.meta["base"]["matrix"] is None
    assert [m.tool for m in tp.moves] == [1] * 6
    assert tp.skipped["joint_move"] == 2 and tp.warnings == []
    assert summarize(tp)["moves"] == 6


def test_global_dat_supplies_config_frames(tmp_path: Path) -> None:
    cfg = tmp_path / "config.dat"
    cfg.write_text("DEFDAT $CONFIG\nDECL FRAME BASE_DATA[32]\n"
                   "BASE_DATA[1]={X 500.0,Y 0.0,Z 0.0,A 0.0,B 0.0,C 0.0}\nENDDAT\n")
    tp = read_krl(DATA / "paged_main.src", global_dat=[cfg])
    np.testing.assert_allclose(tp.meta["base"]["matrix"][:3, 3], [0.5, 0, 0])


def test_lenient_reading_of_good_fixtures_matches_strict() -> None:
    for name in ("plain_inline.src", "named_pair.src", "paged_main.src"):
        a, b = read_krl(DATA / name), read_krl(DATA / name, strict=False)
        np.testing.assert_array_equal(_ends(a), _ends(b))
        assert a.skipped == b.skipped and b.warnings == []


def test_reader_object_and_dispatch() -> None:
    tp = KrlReader().read(str(DATA / "plain_inline.src"))
    assert len(tp.moves) == 6
    assert len(read_toolpath(DATA / "named_pair.src").moves) == 6
    with pytest.raises(InputError, match="applies to G-code programs only, not to KRL"):
        read_krl(DATA / "plain_inline.src", rotary="x")
    with pytest.raises(ToolpathError, match="not found"):
        read_krl(DATA / "nope.src")


# --------------------------------------------------------------------------- geometry
def test_abc_convention() -> None:
    x, y, z = np.eye(3)
    np.testing.assert_allclose(abc_to_matrix(90, 0, 0) @ x, y, atol=1e-15)    # A about z
    np.testing.assert_allclose(abc_to_matrix(0, 90, 0) @ x, -z, atol=1e-15)   # B about y
    np.testing.assert_allclose(abc_to_matrix(0, 0, 90) @ y, z, atol=1e-15)    # C about x
    # composition order: R = Rz(A)·Ry(B)·Rx(C), built here from the elementary rotations
    def rz(t):
        return np.array([[math.cos(t), -math.sin(t), 0], [math.sin(t), math.cos(t), 0], [0, 0, 1]])

    def ry(t):
        return np.array([[math.cos(t), 0, math.sin(t)], [0, 1, 0], [-math.sin(t), 0, math.cos(t)]])

    def rx(t):
        return np.array([[1, 0, 0], [0, math.cos(t), -math.sin(t)], [0, math.sin(t), math.cos(t)]])

    rng = np.random.default_rng(7)
    for a, b, c in rng.uniform(-179, 179, size=(20, 3)) * [1, 0.49, 1]:
        r = abc_to_matrix(a, b, c)
        np.testing.assert_allclose(r, rz(math.radians(a)) @ ry(math.radians(b))
                                   @ rx(math.radians(c)), atol=1e-14)
        np.testing.assert_allclose(matrix_to_abc(r), (a, b, c), atol=1e-9)
    # and through the reader: A 90 → TCP x along +Y → tool axis (0, −1, 0)
    tp = read_krl_text(_prog("LIN {X 1,Y 0,Z 10,A 90,B 0,C 0}"))
    np.testing.assert_allclose(tp.moves[-1].tool_axis, [0, -1, 0], atol=1e-15)


def _circ_prog(start, aux, end, tail: str = "") -> str:
    def lit(p):
        return "{" + ",".join(f"{k} {v:.10f}" for k, v in zip("XYZ", p, strict=True)) + \
            ",A 0,B 90,C 0}"
    return ("DEF t( )\n$VEL.CP = 0.002\n" + f"LIN {lit(start)}\nCIRC {lit(aux)},{lit(end)}{tail}"
            "\nEND\n")


def test_circ_quarter_circle() -> None:
    c, r = np.array([10.0, 20.0, 5.0]), 25.0
    start, aux, end = c + [r, 0, 0], c + [r * S, r * S, 0], c + [0, r, 0]
    m = read_krl_text(_circ_prog(start, aux, end)).moves[-1]
    assert m.kind == MoveKind.ARC_CCW and m.feed == 0.002
    np.testing.assert_allclose(m.center, c * MM, atol=1e-12)
    np.testing.assert_allclose(m.normal, [0, 0, 1], atol=1e-12)
    geo = arc_geometry(m)
    assert geo["radius"] == pytest.approx(r * MM, abs=1e-12)
    assert geo["sweep"] == pytest.approx(math.pi / 2, abs=1e-9)
    assert m.length == pytest.approx(math.pi * r * MM / 2, abs=1e-12)
    np.testing.assert_allclose(m.extra["aux"], aux * MM, atol=1e-15)
    # the same arc run backwards: the normal flips, the kind stays CCW about it
    back = read_krl_text(_circ_prog(end, aux, start)).moves[-1]
    np.testing.assert_allclose(back.normal, [0, 0, -1], atol=1e-12)
    assert arc_geometry(back)["sweep"] == pytest.approx(math.pi / 2, abs=1e-9)


def test_circ_three_quarter_and_tilted_plane() -> None:
    # start at 0°, aux at 180°, end at 270° in the XY plane: 3/4 of a circle of radius 10
    start, aux, end = np.array([10.0, 0, 0]), np.array([-10.0, 0, 0]), np.array([0, -10.0, 0])
    m = read_krl_text(_circ_prog(start, aux, end)).moves[-1]
    assert arc_geometry(m)["sweep"] == pytest.approx(1.5 * math.pi, abs=1e-9)
    np.testing.assert_allclose(m.normal, [0, 0, 1], atol=1e-12)
    # a circle in a tilted plane: centre and normal from the construction
    rot = abc_to_matrix(30, 40, 50)
    c = np.array([100.0, -50.0, 20.0])
    pts = [c + rot @ (7.5 * np.array([math.cos(t), math.sin(t), 0])) for t in (0.3, 1.9, 3.4)]
    m = read_krl_text(_circ_prog(*pts)).moves[-1]
    np.testing.assert_allclose(m.center, c * MM, atol=1e-12)
    np.testing.assert_allclose(m.normal, rot[:, 2], atol=1e-10)
    assert arc_geometry(m)["sweep"] == pytest.approx(3.1, abs=1e-9)


@pytest.mark.parametrize(("ca", "kind", "sweep", "end_deg", "turns"), [
    (180.0, MoveKind.ARC_CCW, math.pi, 180.0, 0),
    (-90.0, MoveKind.ARC_CW, -math.pi / 2, -90.0, 0),
    (360.0, MoveKind.ARC_CCW, 2 * math.pi, 0.0, 0),
    (450.0, MoveKind.ARC_CCW, 2.5 * math.pi, 90.0, 1),
])
def test_circ_circular_angle(ca, kind, sweep, end_deg, turns) -> None:
    # circle of radius 10 about the origin, start at 0°, aux at 45°, end at 60° (with CA the end
    # point only defines the circle; start → aux → end is counter-clockwise about +Z)
    start, aux = np.array([10.0, 0, 0]), 10 * np.array([S, S, 0])
    end = 10 * np.array([0.5, math.sqrt(3) / 2, 0])
    m = read_krl_text(_circ_prog(start, aux, end, f", CA {ca}")).moves[-1]
    assert m.kind == kind and m.turns == turns and m.extra["ca_deg"] == ca
    np.testing.assert_allclose(m.normal, [0, 0, 1], atol=1e-12)
    # the circle's points are written with 1e-10 mm resolution: compare to 1e-10 m
    np.testing.assert_allclose(m.end, 10 * MM * np.array(
        [math.cos(math.radians(end_deg)), math.sin(math.radians(end_deg)), 0]), atol=1e-10)
    assert arc_geometry(m)["sweep"] == pytest.approx(sweep, abs=1e-9)
    assert m.length == pytest.approx(10 * MM * abs(sweep), abs=1e-10)


def test_relative_moves() -> None:
    tp = read_krl_text(_prog("LIN_REL {X 5}\nLIN_REL {X 5} #TOOL\nPTP_REL {Z 2}\nPTP_REL {A1 10}\n"
                             "LIN {X 0,Y 0,Z 0}"))
    # B 90: the TCP x axis is −Z of the base, so 5 mm along tool x goes down
    np.testing.assert_allclose(_ends(tp)[1:4], np.array([[5, 0, 10], [5, 0, 5], [5, 0, 7]]) * MM,
                               atol=1e-12)
    assert tp.moves[3].kind == MoveKind.RAPID
    assert tp.moves[4].start is None and tp.moves[4].tool_axis is None   # after the joint move
    assert tp.meta["joint_moves"][-1]["relative"] is True


def test_base_change_is_expressed_in_the_first_base() -> None:
    tp = read_krl_text("DEF t( )\n$BASE = {FRAME: X 100,Y 0,Z 0,A 0,B 0,C 0}\n$VEL.CP = 0.001\n"
                       "PTP {X 0,Y 0,Z 10,A 0,B 90,C 0}\n"
                       "$BASE = {FRAME: X 100,Y 50,Z 0,A 90,B 0,C 0}\n"
                       "LIN {X 10,Y 0,Z 10,A 0,B 60,C 0}\nLIN {Z 20}\nEND\n")
    # (10, 0, 10) in base 2 = (100, 50, 0) + Rz(90)·(10, 0, 10) = (100, 60, 10) in the world
    # = (0, 60, 10) in base 1; TCP x of (A 0, B 60) is (1/2, 0, −√3/2), turned by Rz(90)
    np.testing.assert_allclose(tp.moves[1].end, [0, 0.06, 0.01], atol=1e-12)
    np.testing.assert_allclose(tp.moves[1].tool_axis, [0, -0.5, math.sqrt(3) / 2], atol=1e-12)
    np.testing.assert_allclose(tp.moves[1].extra["abc_deg"], (90, 60, 0), atol=1e-9)
    np.testing.assert_allclose(tp.moves[2].end, [0, 0.06, 0.02], atol=1e-12)  # partial target
    assert len(tp.meta["base_changes"]) == 1
    np.testing.assert_allclose(tp.meta["base"]["matrix"][:3, 3], [0.1, 0, 0])


def test_non_moving_statements_are_counted_not_warned() -> None:
    body = ("$OUT[3]=TRUE\nWAIT SEC 0\nWAIT FOR $IN[2]\nINTERRUPT ON 3\nBAS(#VEL_PTP,100)\n"
            "HALT\n$ORI_TYPE=#VAR\nIF $IN[1] THEN\n$OUT[2]=FALSE\nENDIF\nSET_CD_PARAMS(0)\n"
            "PULSE($OUT[4], TRUE, 0.5)\nTRIGGER WHEN DISTANCE=0 DELAY=0 DO $OUT[5]=TRUE\n"
            "DECL INT N\nN = 4\nFOO(1)\nLIN {X 5,Y 0,Z 10}")
    tp = read_krl_text(_prog(body), ignore_calls=["foo"])
    assert tp.warnings == [] and len(tp.moves) == 2
    assert {k: tp.skipped[k] for k in ("io", "wait", "interrupt", "bas", "halt", "control_flow",
                                       "builtin_call", "trigger", "ignored_call",
                                       "system_variable")} == {
        "io": 2, "wait": 2, "interrupt": 1, "bas": 1, "halt": 1, "control_flow": 1,
        "builtin_call": 1, "trigger": 1, "ignored_call": 1, "system_variable": 1}


def test_rsi_override_statements_do_not_disturb_the_path() -> None:
    # what a post that enables the RSI feed override around the cut may write (KUKA_IO §2.4)
    body = ("DECL RSIERR RET\nDECL INT CONTID\n"
            'RET = RSI_CREATE("cctmill_override.rsix", CONTID, TRUE)\n'
            "IF (RET <> RSIOK) THEN\nHALT\nENDIF\nRET = RSI_ON(#RELATIVE)\n$OV_PRO = 100\n"
            "LIN {X 20,Y 0,Z 10} C_DIS\nRET = RSI_OFF()\nRSI_OFF()\n")
    tp = read_krl_text(_prog(body))
    assert len(tp.moves) == 2 and tp.warnings == []
    assert tp.skipped["control_flow"] == 1 and tp.skipped["builtin_call"] == 1


def test_feed_from_bas_and_implausible_speed_warning() -> None:
    tp = read_krl_text("DEF t( )\nPTP {X 0,Y 0,Z 10,A 0,B 90,C 0}\nBAS(#CP_PARAMS, 0.25)\n"
                       "LIN {X 1}\n$VEL.CP = 5.0\nLIN {X 2}\nEND\n")
    assert [m.feed for m in tp.moves] == [None, 0.25, 5.0]
    assert [w.category for w in tp.warnings] == ["implausible_speed"]


# --------------------------------------------------------------------------- errors
ERRORS = [
    # body (from line 4), line, column, reason regex, category
    ("LIN {X 1,Y 2,Z 3", 4, 5, r"unbalanced '\{'", "syntax"),
    ("LIN {X 1,Y 2,Z 3}}", 4, 18, r"unexpected '\}'", "syntax"),
    ("LIN {X 1.2.3,Y 0,Z 0}", 4, 8, r"bad number '1\.2\.3'", "syntax"),
    ("LIN {X abc,Y 0,Z 0}", 4, 8, r"expected a number after X", "syntax"),
    ("LIN {X 1,Q 2,Z 0}", 4, 5, r"unknown component Q", "syntax"),
    ('$OUT[1] = "ab', 4, 11, r"unterminated string", "syntax"),
    ("LIN XP9", 4, 5, r"undeclared variable XP9: declare it", "undeclared"),
    ("$VEL.CP = V_NONE", 4, 11, r"undeclared variable V_NONE", "undeclared"),
    ("$VEL.CP = 0", 4, 11, r"\$VEL\.CP = 0 m/s: the path speed must be > 0", "bad_value"),
    ("LIN {X 1,Y 2,Z 3} C_FOO", 4, 19, r"unexpected 'C_FOO' after the target", "syntax"),
    ("SPLINE\nSPL {X 1,Y 2,Z 3}\nENDSPLINE", 4, 1, r"SPLINE \(spline motion\) is not supported",
     "unsupported_motion"),
    ("SLIN {X 1,Y 2,Z 3}", 4, 1, r"SLIN \(spline motion\)", "unsupported_motion"),
    ("LOOP\nLIN {X 1,Y 2,Z 3}\nENDLOOP", 4, 1, r"LIN at line 5 is inside LOOP", "control_flow"),
    ("FOR I = 1 TO 3\nPTP {X 1,Y 2,Z 3}\nENDFOR", 4, 1, r"PTP at line 5 is inside FOR",
     "control_flow"),
    ("IF $IN[1] THEN\nSUB_PAGE()\nENDIF", 4, 1, r"SUB_PAGE at line 5 is inside IF",
     "control_flow"),
    ("LOOP\nHALT", 4, 1, r"LOOP at line 4 has no ENDLOOP", "syntax"),
    ("ENDIF", 4, 1, r"ENDIF without a matching opening statement", "syntax"),
    ("GOTO M1", 4, 1, r"GOTO is not followed", "control_flow"),
    ("LIN_REL {A 10}", 4, 9, r"LIN_REL with a change of A is not supported", "unsupported_motion"),
    ("CIRC_REL {X 1},{X 2}", 4, 1, r"CIRC_REL is not supported", "unsupported_motion"),
    ("LIN {A1 0,A2 -90}", 4, 5, r"LIN needs a Cartesian target", "unsupported_motion"),
    ("CIRC {X 1,Y 0,Z 10},{X 2,Y 0,Z 10}", 4, 6,
     r"CIRC: start, auxiliary and end point lie on one line", "bad_arc"),
    ("CIRC {X 1,Y 1,Z 10},{X 0,Y 0,Z 10}", 4, 6, r"CIRC: the end point equals the start point",
     "bad_arc"),
    ("$BASE = BASE_DATA[2]", 4, 9, r"\$BASE changes after the first motion", "base_change"),
    ("FOO BAR", 4, 1, r"unknown statement 'FOO'", "unknown_statement"),
    ("SUB_PAGE()", 4, 1, r"SUB_PAGE\( \) is called but SUB_PAGE\.src is not in",
     "missing_module"),
    ("LIN XP1.X", 4, 5, r"expected a position", "syntax"),
    # pendant-style pseudo syntax and a bare INI do not compile on a controller (KUKA_IO §1.6 #5)
    ("PTP P1 Vel=80% PDAT1 Tool[1]", 4, 14, r"unexpected character '%'", "syntax"),
    ("INI", 4, 1, r"unknown statement 'INI' \(a bare INI is not KRL", "unknown_statement"),
]


@pytest.mark.parametrize(("body", "line", "col", "reason", "category"), ERRORS,
                         ids=[e[0].split("\n")[0] for e in ERRORS])
def test_errors_strict(body, line, col, reason, category) -> None:
    with pytest.raises(ToolpathError, match=re.escape(f"<string>:{line}:{col}: ") + reason):
        read_krl_text(_prog(body), "DEFDAT t\nDECL E6POS XP1={X 1,Y 2,Z 3}\nENDDAT\n")


@pytest.mark.parametrize(("body", "line", "col", "reason", "category"), ERRORS,
                         ids=[e[0].split("\n")[0] for e in ERRORS])
def test_errors_lenient_are_counted(body, line, col, reason, category) -> None:
    tp = read_krl_text(_prog(body), "DEFDAT t\nDECL E6POS XP1={X 1,Y 2,Z 3}\nENDDAT\n",
                       strict=False)
    hits = [w for w in tp.warnings if w.category == category]
    assert hits and re.search(reason, hits[0].message)
    assert (hits[0].source.line, hits[0].source.column) == (line, col)
    if category != "base_change":          # a frame change is applied, nothing is skipped
        assert tp.skipped[category] >= 1
    assert tp.moves[0].end[2] == pytest.approx(0.01)   # the preamble's PTP is still read


def test_lin_before_vel_cp() -> None:
    text = "DEF t( )\nPTP {X 0,Y 0,Z 10,A 0,B 90,C 0}\nLIN {X 1,Y 2,Z 3}\nEND\n"
    with pytest.raises(ToolpathError, match=re.escape("<string>:3:1: LIN before any $VEL.CP")):
        read_krl_text(text)
    tp = read_krl_text(text, strict=False)
    assert len(tp.moves) == 2 and tp.moves[1].feed is None
    assert [w.category for w in tp.warnings] == ["no_feed"]


def test_partial_target_needs_a_known_position() -> None:
    text = "DEF t( )\n$VEL.CP = 0.001\nPTP {A1 0,A2 -90,A3 90,A4 0,A5 0,A6 0}\nLIN {Z 5}\nEND\n"
    with pytest.raises(ToolpathError, match=re.escape("<string>:4:5: the target of LIN leaves "
                                                      "out X, Y")):
        read_krl_text(text)


def _write(folder: Path, files: dict[str, str]) -> None:
    for name, text in files.items():
        (folder / name).write_text(text)


def test_missing_sub_module(tmp_path: Path) -> None:
    _write(tmp_path, {
        "main.src": "DEF main( )\n$VEL.CP = 0.001\nmain_p001( )\nmain_p009( )\n"
                    "LIN {X 9,Y 9,Z 9}\nEND\n",
        "main_p001.src": "DEF main_p001( )\nLIN {X 1,Y 2,Z 3}\nEND\n",
    })
    path = tmp_path / "main.src"
    with pytest.raises(ToolpathError, match=re.escape(f"{path}:4:1: main_p009( ) is called but "
                                                      "main_p009.src is not in")):
        read_krl(path)
    tp = read_krl(path, strict=False)
    assert tp.skipped["missing_module"] == 1 and len(tp.moves) == 2
    assert tp.moves[1].start is None          # the skipped call may have moved the robot
    assert len(read_krl(path, ignore_calls=("MAIN_P009",)).moves) == 2


def test_recursive_page_call(tmp_path: Path) -> None:
    _write(tmp_path, {
        "main.src": "DEF main( )\n$VEL.CP = 0.001\nmain_p001( )\nEND\n",
        "main_p001.src": "DEF main_p001( )\nLIN {X 1,Y 2,Z 3}\nmain_p002( )\nEND\n",
        "main_p002.src": "DEF main_p002( )\nLIN {X 4,Y 5,Z 6}\n  main_p001( )\nEND\n",
    })
    p2 = tmp_path / "main_p002.src"
    with pytest.raises(ToolpathError, match=re.escape(f"{p2}:3:3: recursive call main_p001 → "
                                                      "main_p002 → main_p001")):
        read_krl(tmp_path / "main.src")
    tp = read_krl(tmp_path / "main.src", strict=False)
    assert tp.skipped["recursive_call"] == 1 and len(tp.moves) == 2


def test_structure_errors(tmp_path: Path) -> None:
    with pytest.raises(ToolpathError, match=re.escape("<string>:1:0: no DEF")):
        read_krl_text("; nothing here\n")
    with pytest.raises(ToolpathError, match=re.escape("<string>:3:0: t (line 1) has no END")):
        read_krl_text("DEF t( )\nHALT\n")
    with pytest.raises(ToolpathError, match=re.escape("<string>:1:1: statement outside DEF")):
        read_krl_text("HALT\nDEF t( )\nEND\n")
    with pytest.raises(ToolpathError, match=r"<string>\.dat:2:1: a \.dat must start with DEFDAT"):
        read_krl_text("DEF t( )\nEND\n", "\nDECL REAL V=1\n")
    # a DEF whose name differs from the file name only warns (it does not change the path)
    (tmp_path / "prog.src").write_text("DEF other( )\nEND\n")
    assert [w.category for w in read_krl(tmp_path / "prog.src").warnings] == ["module_name"]


# --------------------------------------------------------------------------- fuzz and speed
def test_fuzz_only_toolpath_errors(rng: np.random.Generator) -> None:
    texts = [((DATA / "plain_inline.src").read_text(), None),
             ((DATA / "named_pair.src").read_bytes().decode(),
              (DATA / "NAMED_PAIR.DAT").read_bytes().decode())]
    alphabet = "0123456789.+-,:;=*/{}[]()#$&'\" \t\r\nXYZABCSTEPLINDCRQ_\x00é"
    outcomes = {"ok": 0, "error": 0}
    for case in range(300):
        src, dat = texts[case % 2]
        target = list(dat) if (dat is not None and case % 4 == 3) else list(src)
        for _ in range(int(rng.integers(1, 6))):
            i = int(rng.integers(0, len(target)))
            op = int(rng.integers(0, 4))
            ch = alphabet[int(rng.integers(0, len(alphabet)))]
            if op == 0:
                target[i] = ch
            elif op == 1:
                target.insert(i, ch)
            elif op == 2:
                del target[i]
            else:                                  # duplicate a whole line
                lines = "".join(target).split("\n")
                k = int(rng.integers(0, len(lines)))
                target = list("\n".join(lines[:k + 1] + lines[k:]))
        mutated = "".join(target)
        s, d = (src, mutated) if (dat is not None and case % 4 == 3) else (mutated, dat)
        for strict in (True, False):
            try:
                tp = read_krl_text(s, d, strict=strict)
            except ToolpathError:
                outcomes["error"] += 1
            else:
                summarize(tp)
                outcomes["ok"] += 1
    assert outcomes["ok"] > 50 and outcomes["error"] > 50


def test_literal_fast_path_matches_general_path() -> None:
    # plain LIN/PTP literal lines take a one-regex fast path; variables and odd spellings take the
    # tokenizer: both must agree, case-insensitively
    lit = "{X -1.5E1,Y .25,Z 3.,A 10,B 20,C 30,S 6,T 27,E1 5}"
    fast = read_krl_text(_prog(f"lin {lit} c_dis"))
    slow = read_krl_text(_prog("LIN XQ C_DIS"), f"DEFDAT t\nDECL E6POS XQ={lit}\nENDDAT\n")
    spaced = read_krl_text(_prog("LIN { E6POS : X-15,Y 0.25 , Z 3 ,A 10,B 20,C 30,S 6,T 27,"
                                 "E1 5 }  C_DIS"))
    for tp in (fast, slow, spaced):
        m = tp.moves[-1]
        np.testing.assert_allclose(m.end, [-0.015, 0.00025, 0.003])
        assert m.extra["abc_deg"] == (10.0, 20.0, 30.0) and m.extra["external"] == {"E1": 5.0}
        assert m.extra["approx"] == "C_DIS" and (m.extra["s"], m.extra["t"]) == (6, 27)
        assert m.source.column == 5


def test_speed_of_a_long_program() -> None:
    lines = ["DEF big( )", "$VEL.CP = 0.002", "PTP {X 0,Y 0,Z 10,A 0,B 90,C 0}"]
    lines += [f"LIN {{X {i % 100}.5,Y {i // 100}.25,Z -1.000,A 0.000,B 90.000,C 0.000}} C_DIS"
              for i in range(10_000)]
    text = "\n".join(lines + ["END", ""])
    t0 = time.perf_counter()
    tp = read_krl_text(text)
    dt = time.perf_counter() - t0
    assert len(tp.moves) == 10_001
    assert dt < 2.5, f"10 000 LIN lines took {dt:.2f} s (about 0.5 s expected)"


def test_vectorised_abc_matches_the_scalar_one_and_its_gimbal_rule():
    rng = np.random.default_rng(11)
    abc = rng.uniform(-179, 179, size=(50, 3)) * [1, 0.49, 1]
    rots = [abc_to_matrix(*row) for row in abc]
    # B = ±90°: A and C are not separable; both functions put the turn into A (C = 0)
    rots += [abc_to_matrix(30.0, 90.0, 20.0), abc_to_matrix(-45.0, -90.0, 10.0)]
    many = matrices_to_abc(np.array(rots))
    for r, row in zip(rots, many, strict=True):
        np.testing.assert_allclose(row, matrix_to_abc(r), atol=1e-9)
        np.testing.assert_allclose(abc_to_matrix(*row), r, atol=1e-9)
    assert many[-1][2] == 0.0 and many[-2][2] == 0.0
