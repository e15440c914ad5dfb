"""Tests of the KRL reader's control blocks and motion data (robot_io.krl._loops, _conditions, _bas).

The programs are written here for these tests, in the shape robot-milling converters give them: a
``.dat`` array of FRAMEs (``PTS[k]={X …}`` lines) and a ``.src`` that loops over it, and KUKA
inline-form folds with LDAT/PDAT/FDAT data. Expected values come from the literals: point k of the
test array is (k/10, (k² mod 50)/2, −1) mm with A 0, B 90, C 0 (no three in a row on a line, so
CIRC through them is defined), and a loop over it must give exactly
what the same points written out one LIN per line give.
"""

from __future__ import annotations

import re
import time
from pathlib import Path

import numpy as np
import pytest

from robot_io.krl import _loops, _program
from robot_io.krl.reader import MAX_UNROLLED_MOVES, read_krl, read_krl_text
from robot_io.options import speaking
from robot_io.toolpath import MoveKind, ToolpathError

MM = 1e-3
#: Points of the converter-style test program (the size the issue reports).
N_POINTS = 4682
#: Reading it must stay well inside this [s]; it takes about 0.2 s (see the final report).
READ_TIME_LIMIT = 2.5


def _point(k: int) -> tuple[float, float, float]:
    return (k / 10, (k * k % 50) / 2, -1.0)


def _dat(n: int, size: int = 5000, name: str = "prog") -> str:
    lines = [f"DEFDAT {name}", f"DECL FRAME PTS[{size}]"]
    lines += [f"PTS[{k}]={{X {x:.3f},Y {y:.3f},Z {z:.3f},A 0.000,B 90.000,C 0.000}}"
              for k in range(1, n + 1) for x, y, z in [_point(k)]]
    return "\n".join(lines + ["ENDDAT", ""])


#: Feed set, robot at (0, 0, 10) mm pointing down, I and J declared; the body starts at line 6.
PRE = "DEF t( )\nDECL INT I, J\n$VEL.CP = 0.001\nPTP {X 0,Y 0,Z 10,A 0,B 90,C 0}\n;body\n"
DAT = _dat(12, size=20, name="t").replace("ENDDAT", "DECL INT N=4\nDECL BOOL FINISH=TRUE\n"
                                           "DECL INT MODE=2\nENDDAT")


def _read(body: str, dat: str | None = DAT, **kw):
    return read_krl_text(PRE + body + "\nEND\n", dat, **kw)


def _ends_mm(tp, first: int = 1) -> np.ndarray:
    return np.array([m.end for m in tp.moves[first:]]) / MM


def _pts(ks) -> np.ndarray:
    return np.array([_point(k) for k in ks])


# --------------------------------------------------------------------------- the converter program
def _converter_program(folder: Path) -> Path:
    src = [
        "&ACCESS RVP", "&REL 1", "DEF prog( )", "DECL INT I",
        ";FOLD INI", "  BAS (#INITMOV,0 )", ";ENDFOLD (INI)",
        "$BASE = {FRAME: X 800,Y -200,Z 450,A 0,B 0,C 0}",
        "$TOOL = {FRAME: X 0,Y 0,Z 250,A 0,B -90,C 0}",
        "$APO.CDIS = 0.5", "$VEL.CP = 0.002",
        "PTP {X 0,Y 0,Z 50,A 0,B 90,C 0}",
        f"FOR I = 1 TO {N_POINTS}",
        "  LIN PTS[I] C_DIS",
        "ENDFOR",
        "END", "",
    ]
    (folder / "prog.src").write_text("\r\n".join(src))
    (folder / "prog.dat").write_text(_dat(N_POINTS).replace("\n", "\r\n"))
    return folder / "prog.src"


def test_converter_for_loop_over_a_dat_array(tmp_path: Path) -> None:
    path = _converter_program(tmp_path)
    t0 = time.perf_counter()
    tp = read_krl(path)
    dt = time.perf_counter() - t0
    assert len(tp.moves) == 1 + N_POINTS and tp.warnings == []
    np.testing.assert_allclose(_ends_mm(tp), _pts(range(1, N_POINTS + 1)), atol=1e-9)
    lins = tp.moves[1:]
    assert {m.kind for m in lins} == {MoveKind.LINEAR} and {m.feed for m in lins} == {0.002}
    assert {m.source.line for m in lins} == {14} and lins[0].source.column == 7
    assert [m.extra["loop"] for m in lins[:3]] == [{"I": 1}, {"I": 2}, {"I": 3}]
    assert lins[16].extra["loop"] == {"I": 17} and "loop" not in tp.moves[0].extra
    assert lins[0].extra["approx"] == "C_DIS" and lins[0].extra["apo_cdis"] == 0.5 * MM
    np.testing.assert_allclose(lins[1].start, np.array(_point(1)) * MM, atol=1e-12)
    np.testing.assert_allclose(lins[0].tool_axis, [0, 0, 1], atol=1e-12)
    assert tp.meta["base"]["matrix"][0, 3] == pytest.approx(0.8)
    assert dt < READ_TIME_LIMIT, f"{N_POINTS} looped points took {dt:.2f} s (about 0.2 s expected)"


def test_loop_equals_the_program_written_out(tmp_path: Path) -> None:
    looped = _read("FOR I = 1 TO 12\nLIN PTS[I] C_DIS\nENDFOR")
    straight = _read("\n".join(f"LIN PTS[{k}] C_DIS" for k in range(1, 13)))
    np.testing.assert_array_equal(_ends_mm(looped), _ends_mm(straight))
    for a, b in zip(looped.moves, straight.moves, strict=True):
        assert (a.kind, a.feed, a.extra["abc_deg"]) == (b.kind, b.feed, b.extra["abc_deg"])
        np.testing.assert_array_equal(a.tool_axis, b.tool_axis)
    assert looped.skipped == straight.skipped


def test_the_data_fast_path_agrees_with_the_tokenizer(monkeypatch: pytest.MonkeyPatch) -> None:
    body = "FOR I = 1 TO 12\nLIN PTS[I]\nENDFOR"
    dat = DAT.replace("DECL INT N=4", "DECL GLOBAL E6POS XG={E6POS: X 1,Y 2,Z 3,A 4,B 5,C 6}\n"
                      "DECL INT N=4")
    fast = _read(body + "\nLIN XG", dat)
    monkeypatch.setattr(_program, "fast_data", lambda code: None)
    slow = _read(body + "\nLIN XG", dat)
    np.testing.assert_array_equal(_ends_mm(fast), _ends_mm(slow))
    assert [m.extra for m in fast.moves] == [m.extra for m in slow.moves]


# --------------------------------------------------------------------------- what loops may hold
@pytest.mark.parametrize(("body", "ks"), [
    ("FOR I = N TO 1 STEP -1\nLIN PTS[I]\nENDFOR", [4, 3, 2, 1]),
    ("FOR I = 2 TO 9 STEP 3\nLIN PTS[I]\nENDFOR", [2, 5, 8]),
    ("FOR I = 1 TO N - 1\nLIN PTS[I+1]\nENDFOR", [2, 3, 4]),
    ("FOR I = 3 TO 2\nLIN PTS[I]\nENDFOR\nLIN PTS[7]", [7]),          # no iteration
    ("for i = 1 to 2\n  lin pts[2*i] c_dis\nendfor", [2, 4]),            # case-insensitive
])
def test_bounds_steps_and_index_expressions(body, ks) -> None:
    np.testing.assert_allclose(_ends_mm(_read(body)), _pts(ks), atol=1e-12)


def test_nested_loops_record_every_counter() -> None:
    tp = _read("FOR I = 1 TO 2\nFOR J = 0 TO 4 STEP 2\nLIN PTS[3*I+J]\nENDFOR\nENDFOR")
    np.testing.assert_allclose(_ends_mm(tp), _pts([3, 5, 7, 6, 8, 10]), atol=1e-12)
    assert [m.extra["loop"] for m in tp.moves[1:3]] == [{"I": 1, "J": 0}, {"I": 1, "J": 2}]
    assert {m.source.line for m in tp.moves[1:]} == {8}


def test_feed_branches_and_arcs_inside_a_loop() -> None:
    # the first point is approached with PTP, the others cut at a feed that grows with I
    tp = _read("FOR I = 1 TO 3\nIF I == 1 THEN\nPTP PTS[I]\nELSE\n$VEL.CP = 0.001 * I\n"
               "LIN PTS[I] C_DIS\nENDIF\nENDFOR")
    assert [m.kind for m in tp.moves[1:]] == [MoveKind.RAPID, MoveKind.LINEAR, MoveKind.LINEAR]
    assert [m.feed for m in tp.moves[1:]] == [None, 0.002, 0.003]
    assert [m.source.line for m in tp.moves[1:]] == [8, 11, 11]
    arcs = _read("FOR I = 1 TO 5 STEP 2\nCIRC PTS[I], PTS[I+1]\nENDFOR")
    assert [m.kind for m in arcs.moves[1:]] == [MoveKind.ARC_CCW] * 3
    np.testing.assert_allclose(_ends_mm(arcs), _pts([2, 4, 6]), atol=1e-12)
    np.testing.assert_allclose(arcs.moves[2].extra["aux"], np.array(_point(3)) * MM)


def test_arrays_and_counters_declared_in_the_src_or_the_dat() -> None:
    src = ("DEF t( )\nDECL E6POS P[3]\nP[1]={X 1,Y 0,Z 0,A 0,B 90,C 0}\n"
           "P[2]={X 2,Y 0,Z 0,A 0,B 90,C 0}\nP[3]={X 3,Y 0,Z 0,A 0,B 90,C 0}\n$VEL.CP = 0.001\n"
           "FOR K = 1 TO 3\nLIN P[K]\nENDFOR\nEND\n")
    tp = read_krl_text(src, "DEFDAT t\nDECL INT K\nENDDAT\n")
    np.testing.assert_allclose(_ends_mm(tp, 0)[:, 0], [1, 2, 3])
    assert tp.moves[2].extra["loop"] == {"K": 3} and tp.warnings == []


def test_a_loop_without_motion_runs_so_later_moves_see_its_data() -> None:
    tp = _read("FOR I = 1 TO 3\nPTS[I].Z = PTS[I].Z - 2\nENDFOR\nFOR I = 1 TO 3\nLIN PTS[I]\n"
               "ENDFOR\nFOR I = 1 TO $NUM_AX\n$VEL_AXIS[I] = 100\nENDFOR")
    np.testing.assert_allclose(_ends_mm(tp)[:, 2], [-3, -3, -3])
    assert tp.skipped["control_flow"] == 1          # the loop over $NUM_AX cannot be run


def test_loops_in_called_routines_and_return() -> None:
    src = ("DEF t( )\nDECL INT I\n$VEL.CP = 0.001\nFOR I = 1 TO 2\nROW( )\nENDFOR\nEND\n"
           "DEF ROW( )\nDECL INT I\nFOR I = 1 TO 3\nLIN PTS[I]\nIF I == 2 THEN\nRETURN\nENDIF\n"
           "ENDFOR\nEND\n")
    tp = read_krl_text(src, DAT)
    np.testing.assert_allclose(_ends_mm(tp, 0), _pts([1, 2, 1, 2]), atol=1e-12)
    assert [m.extra["loop"] for m in tp.moves] == [{"I": 1}, {"I": 2}] * 2   # the inner I


def test_if_outside_loops_runs_the_branch_the_program_decides() -> None:
    cases = [("FINISH", 1), ("NOT FINISH", 2), ("(N > 3) AND FINISH", 1), ("MODE == 3", 2),
             ("(N * 2 - 1 >= 7) EXOR FINISH", 2), ("#ROUGH == #ROUGH", 1), ("N <> 4", 2)]
    for cond, k in cases:
        tp = _read(f"IF {cond} THEN\nLIN PTS[1]\nELSE\nLIN PTS[2]\nENDIF")
        np.testing.assert_allclose(_ends_mm(tp), _pts([k]), atol=1e-12, err_msg=cond)
    assert len(_read("IF FALSE THEN\nLIN PTS[1]\nENDIF").moves) == 1


# --------------------------------------------------------------------------- refused, with why
LOOP_ERRORS = [
    # body (from line 6), line, column, reason regex, category
    ("FOR I = 1 TO 14\nLIN PTS[I]\nENDFOR", 7, 5,
     r"the value of PTS\[13\] is not known here \(PTS\[13\] is declared at <string>\.dat:2, "
     r"never set .* a line PTS\[13\]=\{X ….* \(at I = 13 of the FOR loop at line 6\)",
     "unknown_value"),
    ("LIN PTS[21]", 6, 5, r"PTS\[21\]: the index 21 is outside the array PTS\[20\]",
     "unknown_value"),
    ("FOR I = 1 TO $NUM_AX\nLIN PTS[I]\nENDFOR", 6, 1,
     r"LIN at line 7 is inside FOR … ENDFOR \(lines 6–8\): its bounds are not known here "
     r"\(the reader does not know the value of the system variable \$NUM_AX", "control_flow"),
    ("FOR Q = 1 TO 3\nLIN PTS[Q]\nENDFOR", 6, 1,
     r"LIN at line 7 .*: its counter Q is not declared; declare it \(DECL INT Q\)",
     "control_flow"),
    ("DECL REAL R\nFOR R = 1 TO 3\nLIN PTS[1]\nENDFOR", 7, 5,
     r"the FOR counter R is declared REAL; KRL counts with a plain INT", "control_flow"),
    ("FOR I = 1 TO 3\nI = I + 1\nLIN PTS[I]\nENDFOR", 6, 5,
     r"line 7 inside this FOR … ENDFOR \(lines 6–9\) sets its counter I", "control_flow"),
    ("FOR I = 1 TO 3 STEP 0\nLIN PTS[1]\nENDFOR", 6, 21, r"STEP 0 never ends the loop",
     "control_flow"),
    ("FOR I = 1 TO N / 3\nLIN PTS[1]\nENDFOR", 6, 14,
     r"the end of a FOR loop must be a whole number", "control_flow"),
    ("FOR I = 1 3\nLIN PTS[1]\nENDFOR", 6, 11, r"expected TO and the end value", "syntax"),
    ("WHILE I < 3\nLIN PTS[1]\nENDWHILE", 6, 1,
     r"LIN at line 7 is inside WHILE … ENDWHILE \(lines 6–8\): how often a WHILE loop runs "
     r"depends on its condition, tested on the robot at run time", "control_flow"),
    ("REPEAT\nLIN PTS[1]\nUNTIL I > 3", 6, 1, r".*REPEAT … UNTIL loop runs depends on its condition",
     "control_flow"),
    ("LOOP\nLIN PTS[1]\nENDLOOP", 6, 1, r".*: a LOOP runs until an EXIT decided on the robot",
     "control_flow"),
    ("SWITCH MODE\nCASE 2\nLIN PTS[1]\nENDSWITCH", 6, 1, r"LIN at line 8 .*: which CASE runs is decided",
     "control_flow"),
    ("IF $IN[3] THEN\nLIN PTS[1]\nENDIF", 6, 1,
     r"LIN at line 7 is inside IF … ENDIF \(lines 6–8\): its condition depends on run-time state "
     r"\(the reader does not know the value of the system variable \$IN\[3\]", "control_flow"),
    ("IF N > 3 AND FINISH THEN\nLIN PTS[1]\nENDIF", 6, 1,
     r".*AND needs TRUE/FALSE on both sides \(in KRL AND binds tighter than a comparison",
     "control_flow"),
    ("FOR I = 1 TO 2\nIF $IN[I] THEN\nLIN PTS[I]\nENDIF\nENDFOR", 7, 1,
     r"LIN at line 8 .*: its condition depends on run-time state .* \(at I = 1 of the FOR "
     r"loop at line 6\)",
     "control_flow"),
]


@pytest.mark.parametrize(("body", "line", "col", "reason", "category"), LOOP_ERRORS,
                         ids=[e[0].split("\n")[0] for e in LOOP_ERRORS])
def test_loop_errors_strict(body, line, col, reason, category) -> None:
    with pytest.raises(ToolpathError, match=re.escape(f"<string>:{line}:{col}: ") + reason):
        _read(body)


@pytest.mark.parametrize(("body", "line", "col", "reason", "category"), LOOP_ERRORS,
                         ids=[e[0].split("\n")[0] for e in LOOP_ERRORS])
def test_loop_errors_lenient_are_counted(body, line, col, reason, category) -> None:
    tp = _read(body, strict=False)
    hits = [w for w in tp.warnings if w.category == category]
    assert hits and re.search(reason, hits[0].message)
    assert (hits[0].source.line, hits[0].source.column) == (line, col)
    assert tp.skipped[category] >= 1 and tp.moves[0].end[2] == pytest.approx(0.01)


def test_lenient_reading_goes_on_after_a_missing_element() -> None:
    tp = _read("FOR I = 10 TO 14\nLIN PTS[I]\nENDFOR\nLIN PTS[1]", strict=False)
    np.testing.assert_allclose(_ends_mm(tp), _pts([10, 11, 12, 1]), atol=1e-12)
    assert tp.skipped["unknown_value"] == 2 and tp.moves[-1].start is None


def test_the_counter_is_undefined_after_its_loop() -> None:
    with pytest.raises(ToolpathError, match=r"<string>:9:9: the value of I is not known here "
                       r"\(the reader leaves I undefined after its FOR loop at <string>:6\)"):
        _read("FOR I = 1 TO 3\nLIN PTS[I]\nENDFOR\nLIN PTS[I]")


def test_unroll_limit_refuses_before_and_while_unrolling(monkeypatch) -> None:
    assert MAX_UNROLLED_MOVES == _loops.MAX_UNROLLED_MOVES == 1_000_000
    fix = r"check the bounds, or split the path into programs of fewer points"
    with pytest.raises(ToolpathError, match=r"<string>:6:1: this FOR loop makes 5000000 moves "
                       r"\(2500000 iterations × 2\), more than the reader unrolls "
                       r"\(MAX_UNROLLED_MOVES = 1000000 in all loops\): " + fix):
        _read("FOR I = 1 TO 2500000\nLIN PTS[1]\nLIN PTS[2]\nENDFOR", strict=False)
    # the check counts the moves of all loops so far: an inner loop is refused when its moves
    # and those the outer iterations made are over
    monkeypatch.setattr(_loops, "MAX_UNROLLED_MOVES", 10)
    with pytest.raises(ToolpathError, match=r"<string>:7:1: this FOR loop makes 4 moves .* "
                       r"\(at I = 3 of the FOR loop at line 6\)"):
        _read("FOR I = 1 TO 3\nFOR J = 1 TO 4\nLIN PTS[J]\nENDFOR\nENDFOR")
    # motion the check cannot count ahead (inside an IF) is stopped once the total is over
    for strict in (True, False):
        with pytest.raises(ToolpathError, match=r"<string>:6:1: the loops have made more than "
                           r"10 moves by I = 11 \(MAX_UNROLLED_MOVES.*" + fix):
            _read("FOR I = 1 TO 12\nIF TRUE THEN\nLIN PTS[I]\nENDIF\nENDFOR", strict=strict)


# --------------------------------------------------------------------------- inline forms
INLINE_SRC = """DEF prog( )
;FOLD PTP P1 Vel=75 % PDAT1 Tool[1] Base[1];%{PE}%R 8.3.31,%MKUKATPBASIS,%CMOVE,%VPTP,%P 1:PTP
$BWDSTART=FALSE
PDAT_ACT=PPDAT1
FDAT_ACT=FP1
BAS(#PTP_PARAMS,75)
PTP XP1
;ENDFOLD
;FOLD LIN P2 CONT Vel=0.2 m/s CPDAT1 Tool[1] Base[1];%{PE}%R 8.3.31,%MKUKATPBASIS,%CMOVE,%VLIN
$BWDSTART=FALSE
LDAT_ACT=LCPDAT1
FDAT_ACT=FP2
BAS(#CP_PARAMS,0.2)
LIN XP2 C_DIS C_DIS
;ENDFOLD
;FOLD CIRC P3 P4 Vel=0.01 m/s CPDAT2;%{PE}
LDAT_ACT=LCPDAT2
BAS(#CP_PARAMS,0.01)
CIRC XP3, XP4 C_DIS C_DIS
;ENDFOLD
$VEL.CP = LCPDAT2.VEL
LIN XP1
BAS(#CP_PARAMS, LDAT_ACT.VEL)
LIN XP2
LDAT_ACT=LCPDAT1
BAS(#CP_DAT)
LIN XP1
BAS(#PTP_DAT)
PTP XP2
END
"""
INLINE_DAT = """DEFDAT prog
DECL E6POS XP1={X 10,Y 0,Z 5,A 0,B 90,C 0,S 2,T 35,E1 0.0,E2 0.0}
DECL E6POS XP2={X 20,Y 0,Z 5,A 0,B 90,C 0,S 2,T 35,E1 0.0,E2 0.0}
DECL E6POS XP3={X 30,Y 10,Z 5,A 0,B 90,C 0}
DECL E6POS XP4={X 20,Y 20,Z 5,A 0,B 90,C 0}
DECL FDAT FP1={TOOL_NO 1,BASE_NO 1,IPO_FRAME #BASE,POINT2[] " "}
DECL FDAT FP2={TOOL_NO 1,BASE_NO 1,IPO_FRAME #BASE,POINT2[] " ",TQ_STATE FALSE}
DECL PDAT PPDAT1={VEL 40.0,ACC 100.0,APO_DIST 100.0,APO_MODE #CPTP}
DECL LDAT LCPDAT1={VEL 0.15,ACC 100.0,APO_DIST 100.0,APO_FAC 50.0,ORI_TYP #VAR,CIRC_TYP #BASE,JERK_FAC 50.0}
DECL LDAT LCPDAT2={VEL 0.05,ACC 100.0,APO_DIST 100.0,APO_FAC 50.0,ORI_TYP #VAR,CIRC_TYP #BASE,JERK_FAC 50.0}
ENDDAT
"""


def test_inline_form_speeds_from_bas_and_ldat_pdat() -> None:
    tp = read_krl_text(INLINE_SRC, INLINE_DAT)
    assert [m.kind for m in tp.moves] == [MoveKind.RAPID, MoveKind.LINEAR, MoveKind.ARC_CCW,
                                          MoveKind.LINEAR, MoveKind.LINEAR, MoveKind.LINEAR,
                                          MoveKind.RAPID]
    # BAS(#CP_PARAMS, v) is the form's Vel [m/s] (not the LDAT's VEL); $VEL.CP = LCPDAT2.VEL,
    # BAS(#CP_PARAMS, LDAT_ACT.VEL) with LDAT_ACT = LCPDAT2, BAS(#CP_DAT) with LCPDAT1
    assert [m.feed for m in tp.moves] == [None, 0.2, 0.01, 0.05, 0.05, 0.15, None]
    # PTP: % of the axes' maximum, from BAS(#PTP_PARAMS, 75), then PDAT_ACT = PPDAT1 (VEL 40)
    assert [tp.moves[i].extra.get("ptp_velocity_pct") for i in (0, 1, 6)] == [75.0, None, 40.0]
    assert tp.moves[1].extra["approx"] == "C_DIS" and [m.tool for m in tp.moves] == [1] * 7
    assert tp.meta["base"]["name"] == "BASE_DATA[1]" and tp.warnings == []


def test_cp_dat_needs_a_known_ldat() -> None:
    text = "DEF t( )\nPTP {X 0,Y 0,Z 10,A 0,B 90,C 0}\nBAS(#CP_DAT)\nLIN {X 1}\nEND\n"
    with pytest.raises(ToolpathError, match=r"<string>:3:5: BAS\(#CP_DAT\) sets the path speed "
                       r"from LDAT_ACT\.VEL, which is not known here \(LDAT_ACT is not set in "
                       r"the program\); set LDAT_ACT to an LDAT of the \.dat first"):
        read_krl_text(text)


# --------------------------------------------------------------------------- messages
def test_fixes_speak_the_interface_in_use() -> None:
    spline = "SPLINE\nSPL {X 1,Y 2,Z 3}\nENDSPLINE"
    forms = {"python": "strict=False", "cli": "--lenient", "job": "[job] strict = false"}
    for interface, form in forms.items():
        with speaking(interface):
            with pytest.raises(ToolpathError) as err:
                _read(spline)
            tp = _read("$BASE = BASE_DATA[2]\nLIN PTS[1]", strict=False)
        assert f"read with {form} to skip it" in str(err.value)
        # a warning (made in lenient mode) does not advise reading leniently
        assert "(moves are then read" in tp.warnings[0].message
        assert form not in tp.warnings[0].message
        if interface != "python":
            assert "strict=False" not in str(err.value) + tp.warnings[0].message
    with speaking("cli"), pytest.raises(ToolpathError, match=re.escape(
            "or pass ignore_calls=['SUB_PAGE'] (Python API) if it does not move")):
        _read("SUB_PAGE( )")


def test_defdat_of_text_input_is_checked_against_the_def() -> None:
    assert _read("LIN PTS[1]").warnings == []
    tp = _read("LIN PTS[1]", DAT.replace("DEFDAT t", "DEFDAT other"))
    assert [w.category for w in tp.warnings] == ["module_name"]
