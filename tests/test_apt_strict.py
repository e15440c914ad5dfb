"""Strict mode never skips geometry (issue 15): every APT/CL record is read, refused by name, or
path-neutral; lenient mode skips by record name and says what each skipped kind may change; the
messages name options in the words of the interface; GODLTA is read; an NX information listing
at the top of a file is passed over."""

from __future__ import annotations

import numpy as np
import pytest

from robot_io.apt import read_apt_text
from robot_io.apt._interp import HANDLERS
from robot_io.apt._words import MAY_CHANGE, PATH_NEUTRAL, REFUSED
from robot_io.options import speaking
from robot_io.toolpath import MoveKind, ToolpathError, summarize

MM = 1e-3
PRE = "UNITS/MM\nFEDRAT/600,MMPM\nRAPID\nGOTO/0,0,0\n"
REFUSED_ARGS = {"GOHOME": "", "ORIGIN": "/10,0,0", "ROTABL": "/90,CLW", "PREFUN": "/91",
                "PSIS": "/PL1", "COPY": "/1,TRANSL,10,0,0,3", "LOOPST": ""}


def _mm(v) -> list[float]:
    return [round(float(x) / MM, 9) for x in v]


# --------------------------------------------------------------------------- the classification
def test_every_word_is_read_refused_or_path_neutral_never_two():
    read = set(HANDLERS) - set(REFUSED)
    assert set(REFUSED) <= set(HANDLERS)
    assert not read & PATH_NEUTRAL and not set(REFUSED) & PATH_NEUTRAL
    assert {kind for _, kind in REFUSED.values()} <= set(MAY_CHANGE)
    # the motion, frame and modal words are read, not passed over
    for word in ("GOTO", "GODLTA", "FROM", "CIRCLE", "NURBS", "KNOT", "CNTRL", "UNITS", "CSYS",
                 "MSYS", "TLAXIS", "CUTCOM", "CYCLE", "FEDRAT", "RAPID", "MULTAX"):
        assert word in read


@pytest.mark.parametrize("word", sorted(PATH_NEUTRAL))
def test_path_neutral_records_change_nothing(word: str):
    body = "GOTO/1,0,0\nGOTO/1,2,0,0,0,1\nCIRCLE/1,1,0,0,0,1\nGOTO/1,0,0\n"
    plain = read_apt_text(PRE + body)
    record = f"{word}/ON\n" if word not in ("TOOL PATH",) else "TOOL PATH/OP1,TOOL,MILL\n"
    mixed = read_apt_text(PRE + record + body.replace("\n", "\n" + record, 2))
    assert summarize(mixed) == summarize(plain)
    assert [_mm(m.end) for m in mixed.moves] == [_mm(m.end) for m in plain.moves]
    assert mixed.warnings == [] and dict(mixed.skipped) == {}
    assert mixed.meta["ignored_records"] == {word: 3}


# --------------------------------------------------------------------------- refused by name
@pytest.mark.parametrize("word", sorted(REFUSED))
def test_refused_records_raise_in_strict_mode_with_what_they_change(word: str):
    text = PRE + "GOTO/1,0,0\n" + word + REFUSED_ARGS.get(word, "/1") + "\nGOTO/2,0,0\n"
    what, kind = REFUSED[word]
    with pytest.raises(ToolpathError) as err:
        read_apt_text(text, file="p.cls")
    e = err.value
    assert (e.file, e.line, e.column) == ("p.cls", 6, 1)
    assert e.reason.startswith(f"{word} {what}; this reader does not read it ({MAY_CHANGE[kind]})")
    assert "read leniently (strict=False) to skip it" in e.reason


@pytest.mark.parametrize("word", sorted(REFUSED))
def test_refused_records_are_skipped_by_name_in_lenient_mode(word: str):
    rec = word + REFUSED_ARGS.get(word, "/1")
    tp = read_apt_text(PRE + "GOTO/1,0,0\n" + rec + "\nGOTO/2,0,0\n" + rec + "\nGOTO/3,0,0\n",
                       strict=False)
    assert tp.skipped == {word: 2}
    assert [w.category for w in tp.warnings] == ["unsupported_record"]   # once per name
    kind = REFUSED[word][1]
    assert MAY_CHANGE[kind] in tp.warnings[0].message and tp.warnings[0].source.line == 6
    moved = kind == "move"
    assert (tp.moves[2].start is None) == moved    # after a skipped motion: position unknown
    assert [_mm(m.end) for m in tp.moves] == [[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0]]


def test_unknown_records_are_refused_in_strict_and_skipped_by_name_in_lenient() -> None:
    text = (PRE + "FOOBAR/1,2\nGOTO/1,0,0\nFOOBAR\nORIGIN/1,2,3\nTOOL PATH/X,TOOL,M\n"
            "PAINT/COLOR,3\nCOOLNT/ON\n$$ just a comment\n\nEND-OF-PATH")
    with pytest.raises(ToolpathError, match=r"^<string>:5:1: unknown record 'FOOBAR': it may move "
                       r"the tool .*read leniently \(strict=False\)"):
        read_apt_text(text)
    tp = read_apt_text(text, strict=False)
    assert tp.skipped == {"FOOBAR": 2, "ORIGIN": 1}
    assert tp.meta["warning_counts"] == {"unknown_record": 1, "unsupported_record": 1}
    assert [(w.source.line, w.source.column) for w in tp.warnings] == [(5, 1), (8, 1)]
    assert "'FOOBAR'" in tp.warnings[0].message and "may move" in tp.warnings[1].message
    assert tp.meta["record_counts"]["TOOL PATH"] == 1 and len(tp.moves) == 2
    assert tp.meta["ignored_records"] == {"TOOL PATH": 1, "PAINT": 1, "COOLNT": 1,
                                          "END-OF-PATH": 1}
    # the path-neutral records alone read strictly without a word
    tp = read_apt_text(PRE + "TOOL PATH/X,TOOL,M\nPAINT/COLOR,3\nCOOLNT/ON\nEND-OF-PATH")
    assert tp.warnings == [] and dict(tp.skipped) == {}


def test_refused_word_without_a_slash_is_still_refused():
    with pytest.raises(ToolpathError, match=r"^<string>:5:1: GOHOME sends the tool to its home"):
        read_apt_text(PRE + "GOHOME 1\n")


def test_unknown_records_and_assignments():
    with pytest.raises(ToolpathError, match=r"^<string>:5:3: unknown record 'SPINUP': it may "
                       r"move the tool or change how later records are read"):
        read_apt_text(PRE + "  SPINUP/1\n")
    with pytest.raises(ToolpathError, match=r"^<string>:5:1: R1=…: an assignment, which is an APT "
                       r"part-program statement: the file looks like APT source"):
        read_apt_text(PRE + "R1 = 25.0\n")
    tp = read_apt_text(PRE + "SPINUP/1\nGOTO/1,0,0\nSPINUP/2\nWOBBLE\n", strict=False)
    assert tp.skipped == {"SPINUP": 2, "WOBBLE": 1}
    assert tp.meta["warning_counts"] == {"unknown_record": 2}
    assert "may move the tool or change how later moves are read" in tp.warnings[0].message
    assert tp.moves[1].start is not None   # an unknown record does not lose the position


def test_cycle_types_other_than_drilling_are_refused():
    text = PRE + "CYCLE/MILL,FEDTO,5,MMPM,100,RAPTO,2\nGOTO/5,0,0\nCYCLE/OFF\nGOTO/6,0,0\n"
    with pytest.raises(ToolpathError, match=r"^<string>:5:7: CYCLE/MILL is not a drilling cycle "
                       r"this reader expands \(BORE, BRKCHP, CBORE, .*\): it may move the tool"):
        read_apt_text(text)
    tp = read_apt_text(text, strict=False)
    assert tp.skipped == {"unsupported_cycle": 1}
    assert [_mm(m.end) for m in tp.moves] == [[0, 0, 0], [5, 0, 0], [6, 0, 0]]


# --------------------------------------------------------------------------- GODLTA
def test_godlta_moves_by_a_delta_or_along_the_tool_axis():
    tp = read_apt_text(PRE + "GOTO/10,0,0,0,0.6,0.8\nGODLTA/5\nGODLTA/1,2,3\nRAPID\n"
                       "GODLTA/0,0,10\nGOTO/0,0,0")
    got = [(m.kind, _mm(m.end)) for m in tp.moves[2:5]]
    assert got == [(MoveKind.LINEAR, [10, 3, 4]), (MoveKind.LINEAR, [11, 5, 7]),
                   (MoveKind.RAPID, [11, 5, 17])]
    assert tp.moves[2].feed == pytest.approx(600 * MM / 60) and tp.moves[4].feed is None
    assert tp.moves[2].source.line == 6 and tp.moves[2].start is tp.moves[1].end
    # a delta is turned by the frame, not moved by it
    tp = read_apt_text(PRE + "MSYS/100,0,0,0,1,0,-1,0,0\nGOTO/0,0,0\nGODLTA/1,0,0",
                       apply_frames=True)
    assert _mm(tp.moves[-1].end) == [100, 1, 0]
    with pytest.raises(ToolpathError, match=r"^<string>:3:1: GODLTA from an unknown position"):
        read_apt_text("UNITS/MM\nFEDRAT/1\nGODLTA/1\n")
    with pytest.raises(ToolpathError, match=r"^<string>:5:11: GODLTA takes 1 number"):
        read_apt_text(PRE + "GODLTA/1,2\n")


def test_cutcom_forms():
    tp = read_apt_text(PRE + "CUTCOM/LEFT,XYPLAN\nGOTO/1,0,0\nCUTCOM/ON,RIGHT,12\nCUTCOM/OFF\n")
    assert tp.meta["warning_counts"] == {"cutter_compensation": 2}
    assert "CUTCOM/RIGHT" in tp.warnings[1].message
    with pytest.raises(ToolpathError, match=r"^<string>:5:8: CUTCOM word 'TANTO' is unknown"):
        read_apt_text(PRE + "CUTCOM/TANTO,LEFT\n")


def test_loadtl_sets_the_tool():
    tp = read_apt_text(PRE + "LOADTL/7\nGOTO/1,0,0\n")
    assert tp.moves[-1].tool == 7 and tp.warnings == []


# --------------------------------------------------------------------------- NX information listing
LISTING = ("===============================================================\n"
           "Information listing created by :  j.smith\n"
           "Date                           :  Tue Mar 12 10:41:07 2024\n"
           "Current work part              :  C:\\parts\\bracket_op20.prt\n"
           "Node name                      :  ws-cam-04\n"
           "===============================================================\n"
           "\n\n")


def test_nx_information_listing_header_is_passed_over_and_kept():
    tp = read_apt_text(LISTING + "TOOL PATH/OP20,TOOL,EM10\n" + PRE + "GOTO/1,2,3\n")
    assert tp.meta["listing_header"] == LISTING.strip("\n").split("\n")
    assert _mm(tp.moves[-1].end) == [1, 2, 3]
    assert tp.moves[-1].source.line == 14   # physical lines: the header still counts
    assert tp.warnings == [] and dict(tp.skipped) == {}
    # without the leading rule, with CRLF line ends
    crlf = (LISTING.split("\n", 1)[1] + PRE + "GOTO/1,2,3\n").replace("\n", "\r\n")
    tp = read_apt_text(crlf)
    assert tp.meta["listing_header"][0].startswith("Information listing created by")
    assert len(tp.meta["listing_header"]) == 5 and tp.moves[-1].source.line == 12
    # a plain file has none
    assert read_apt_text(PRE).meta["listing_header"] == []


def test_listing_header_only_at_the_top_and_only_when_complete():
    with pytest.raises(ToolpathError, match=r"^<string>:6:1: not an APT record: '====="):
        read_apt_text(PRE + "GOTO/1,2,3\n" + LISTING)
    with pytest.raises(ToolpathError, match=r"^<string>:6:1: unknown record 'INFORMATION LISTING "):
        read_apt_text(PRE + "GOTO/1,2,3\n" + LISTING.split("\n", 1)[1])
    # a header that never reaches its closing rule is no header: read as records, refused
    unclosed = LISTING.replace("=" * 63 + "\n\n\n", "") + PRE
    with pytest.raises(ToolpathError, match=r"^<string>:1:1: not an APT record"):
        read_apt_text(unclosed)
    assert read_apt_text(unclosed, strict=False).meta["listing_header"] == []


# --------------------------------------------------------------------------- messages per interface
def test_messages_name_options_as_the_interface_spells_them():
    cases = [
        (PRE + "SPINUP/1\n", {}, "--lenient", "[job] strict = false", "strict=False"),
        (PRE + "GOHOME\n", {}, "--lenient", "[job] strict = false", "strict=False"),
        (PRE + "GOTO/1,2x,3\n", {}, "--lenient", "[job] strict = false", "strict=False"),
        (PRE + "GOTO/10,0,0\nCIRCLE/0,0,0,0,0,1\nGOTO/0,10.1,0\n", {}, "--lenient",
         "[job] strict = false", "arc_radius_tol=0.00011"),
        (PRE + "NURBS/\nKNOT/1\nCNTRL/1,0,0\n", {}, "--lenient", "[job] strict = false",
         "strict=False"),
        (PRE + "NURBS/\nKNOT/0.5,1\nCNTRL/1,50,0\nCNTRL/2,-50,0\nCNTRL/3,50,0\nCNTRL/4,0,0\n",
         {"chord_tol": 1e-12}, "--chord-tol-mm", "[path] chord_tol_mm", "chord_tol="),
    ]
    for text, opts, cli, job, python in cases:
        for where, want in (("cli", cli), ("job", job), ("python", python)):
            with speaking(where):
                with pytest.raises(ToolpathError) as err:
                    read_apt_text(text, **opts)
            msg = str(err.value)
            assert want in msg, (where, msg)
            if where != "python":
                assert "strict=" not in msg and "='" not in msg and "=False" not in msg, msg


def test_warnings_name_options_as_the_interface_spells_them():
    with speaking("cli"):
        units = read_apt_text("FEDRAT/100,MMPM\nRAPID\nGOTO/1,2,3\n").warnings[0].message
        frames = read_apt_text(PRE + "TRNTYP/WORLD\nCSYS/1,0,0,0,0,1,0,0,0,0,1,0\n",
                               apply_frames=True).warnings[0].message
        skipped = read_apt_text(PRE + "SPINUP\n", strict=False).warnings[0].message
    assert "--units inch" in units and "='" not in units
    assert "--apply-frames" in frames and "=True" not in frames
    assert "strict" not in skipped
    units = read_apt_text("FEDRAT/100,MMPM\nRAPID\nGOTO/1,2,3\n").warnings[0].message
    assert "default_units='inch'" in units


def test_lenient_read_of_a_mixed_file_keeps_the_geometry_it_can():
    text = (PRE + "GOTO/10,0,0\nTHREAD/TURN,5\nGOTO/20,0,0\nPAINT/COLOR,3\nNURBS/\nKNOT/1\n"
            "CNTRL/25,5,0\nCNTRL/30,5,0\nCNTRL/35,0,0\nMYWORD/1\nGOTO/40,0,0\n")
    tp = read_apt_text(text, strict=False)
    assert tp.skipped == {"THREAD": 1, "MYWORD": 1}
    assert tp.moves[2].start is None and _mm(tp.moves[2].end) == [20, 0, 0]
    assert len(tp.meta["splines"]) == 1 and _mm(tp.moves[-1].start) == [35, 0, 0]
    np.testing.assert_allclose(tp.moves[-1].end, [40 * MM, 0, 0])
    assert {w.category for w in tp.warnings} == {"unsupported_record", "unknown_record"}
