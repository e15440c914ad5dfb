"""Tests of the G-code reader's messages: a fix names the option as the interface in use spells it
(``robot_io.options.speaking``), messages are built when raised, Fanuc-style programs read with
their program number, and no message quotes the text of a comment."""

from __future__ import annotations

import pytest

from models.errors import InputError
from robot_io.gcode import read_gcode_text
from robot_io.options import speaking
from robot_io.toolpath import ToolpathError

PRE = "G21 G90 G17 F100\nG0 X0 Y0 Z0\n"

#: How each option must be named, per interface (written out here, not taken from options.py).
NAMED = {
    "python": {"strict": "strict=False", "rotary": "rotary='xyzac-trunnion'",
               "initial_position": "initial_position=(x, y, z)",
               "home_position": "home_position=(x, y, z)", "default_units": "default_units='inch'"},
    "cli": {"strict": "--lenient", "rotary": "--rotary xyzac-trunnion",
            "initial_position": "--initial-position-mm X,Y,Z",
            "home_position": "--home-position-mm X,Y,Z", "default_units": "--units inch"},
    "job": {"strict": "[job] strict = false", "rotary": '[job] rotary = "xyzac-trunnion"',
            "initial_position": "[job] initial_position_mm = [x, y, z]",
            "home_position": "[job] home_position_mm = [x, y, z]",
            "default_units": '[job] units = "inch"'},
}
#: Python keyword forms no CLI or job message may contain.
PYTHON_FORMS = ("=False", "='", "=True", "=(")

#: Every error or warning that tells the user to change an option: (id, program, category of
#: the message, options it names). Errors are read strictly, warnings either way.
OPTION_MESSAGES = [
    ("unknown_word", PRE + "G1 X1 U5", "unknown_word", ["strict"]),
    ("unknown_g", PRE + "G7.3", "unknown_g", ["strict"]),
    ("unsupported_g", PRE + "G92 X0", "unknown_g", ["strict"]),
    ("unknown_m", PRE + "M77", "unknown_m", ["strict"]),
    ("unused_arc_word", PRE + "G1 X1 I5", "unused_word", ["strict"]),
    ("arc_normal_word", PRE + "G2 X10 Y0 I5 J0 K1", "arc_normal_word", ["strict"]),
    ("canned_cycle_plane", PRE + "G18 G81 X1 Y1 Z-1 R1", "canned_cycle", ["strict"]),
    ("canned_cycle_words", PRE + "G81 X1 Y1", "canned_cycle", ["strict"]),
    ("rotary_word", PRE + "G1 X1 A10", "rotary_ignored", ["rotary", "strict"]),
    ("nested_comment", PRE + "(T1 (6MM) FLAT)", "nested_comment", ["strict"]),
    ("o_word_flow", PRE + "o100 call", "o_word", ["strict"]),
    ("later_program_number", PRE + "O2000", "o_word", ["strict"]),
    ("fanuc_m98", PRE + "M98 P2000", "o_word", ["strict"]),
    ("fanuc_m99", PRE + "M99", "o_word", ["strict"]),
    ("unknown_position", "G21 F100\nG0 X1", "unknown_position", ["initial_position"]),
    ("unknown_after_home", PRE + "G91 G28 Z0\nG90 G0 X5", "unknown_position", ["home_position"]),
    ("no_units", "F100\nG0 X0 Y0 Z0", "no_units", ["default_units"]),
]


def _messages(text: str, category: str) -> tuple[list[str], list[str]]:
    """(messages of ``category``, every message) of a strict and a lenient reading."""
    every: list[str] = []
    mine: list[str] = []
    try:
        tp = read_gcode_text(text)
        every += [w.message for w in tp.warnings]
        mine += [w.message for w in tp.warnings if w.category == category]
    except ToolpathError as e:
        every.append(str(e))
        mine.append(str(e))
    tp = read_gcode_text(text, strict=False)
    every += [w.message for w in tp.warnings]
    mine += [w.message for w in tp.warnings if w.category == category]
    return mine, every


@pytest.mark.parametrize("interface", ["python", "cli", "job"])
@pytest.mark.parametrize(("text", "category", "options"),
                         [c[1:] for c in OPTION_MESSAGES], ids=[c[0] for c in OPTION_MESSAGES])
def test_messages_name_the_option_as_the_interface_spells_it(
        interface: str, text: str, category: str, options: list[str]) -> None:
    with speaking(interface):
        mine, every = _messages(text, category)
    assert mine, f"no {category} message"
    strict_message = mine[0]
    for option in options:
        assert NAMED[interface][option] in strict_message, strict_message
    if interface != "python":
        for message in every:
            for form in PYTHON_FORMS:
                assert form not in message, message


def test_messages_are_built_when_raised() -> None:
    text = PRE + "G7.3"
    seen = []
    for interface in ("cli", "python", "job", "cli"):
        with speaking(interface), pytest.raises(ToolpathError) as e:
            read_gcode_text(text)
        seen.append(str(e.value))
    assert "--lenient" in seen[0] and "strict=False" in seen[1]
    assert "[job] strict = false" in seen[2] and seen[3] == seen[0]


@pytest.mark.parametrize(("interface", "name"), [("python", "rotary"), ("cli", "--rotary"),
                                                 ("job", "[job] rotary")])
def test_option_errors_name_the_option(interface: str, name: str) -> None:
    with speaking(interface), pytest.raises(InputError, match=r"unknown rotary kinematics") as e:
        read_gcode_text(PRE, rotary="xyz-spindle")
    assert str(e.value).startswith(f"{name}: ")
    with speaking(interface), pytest.raises(InputError) as e:
        read_gcode_text(PRE, default_units="furlong")
    assert str(e.value).split(":")[0] == {"python": "default_units", "cli": "--units",
                                          "job": "[job] units"}[interface]


# --------------------------------------------------------------------------- Fanuc style
#: Autodesk HSM / Fusion 360 Fanuc post style.
HSM = """%
O1001 (PART NAME)
(T1 D=6. CR=0. - ZMIN=-5. - FLAT END MILL)
N10 G90 G94 G17
N15 G21
N20 G28 G91 Z0.
N25 G90

(2D CONTOUR1)
N30 M6 T1
N35 S5000 M3
N40 G54
N45 M8
N50 G0 X0. Y0.
N55 G43 Z15. H1
N60 G0 Z5.
N65 G1 Z-1. F500.
N70 X10.
N75 Y10.
N80 G0 Z15.
N85 M9
N90 G28 G91 Z0.
N95 G90
N100 M30
%
"""


def test_a_fanuc_program_reads_with_its_program_number() -> None:
    for strict in (True, False):
        tp = read_gcode_text(HSM, strict=strict)
        assert tp.meta["program"] == "O1001" and tp.meta["program_number"] == 1001
        assert tp.meta["warning_counts"] == {"unknown_position": 1}   # N50: Z after G28
        assert [list(m.end / 1e-3) for m in tp.moves] == [
            [0, 0, 15], [0, 0, 5], [0, 0, -1], [10, 0, -1], [10, 10, -1], [10, 10, 15]]
        assert tp.meta["work_offsets"] == ["G54"] and {m.tool for m in tp.moves} == {1}
    for first in ("O1001", "O1001(PART NAME)", "o1001 ; PART", ":1001 (PART)", "N1 O1001",
                  "(HEADER)\nO1001"):
        tp = read_gcode_text(f"%\n{first}\n" + PRE)
        assert tp.meta["program_number"] == 1001 and tp.warnings == [], first
    with pytest.raises(ToolpathError, match=r"^<string>:1:7: unexpected 'PART' after the "
                       "program number"):
        read_gcode_text("O1001 PART NAME\n" + PRE)


#: Fanuc-style comments gone wrong: the distinctive comment words must never be quoted.
COMMENT_LEAKS = [
    # program, message expected (strict), what it quotes if anything
    (PRE + "(T1 (6MM) FLAT END MILL)", r"3:1: comment at column 1 holds a '\(' before its '\)' "
     r"at column 9", None),
    (PRE + "(T1 D=6.) FLAT END MILL)", r"3:11: a '\)' at column 24 closes no comment", None),
    (PRE + "O1001 (PART (A) FLAT END MILL)", r"3:7: comment at column 7 holds a '\('", None),
    (PRE + "G1 X1.2.3 (FLAT END MILL)", r"3:4: malformed number in 'X1.2.3'", "X1.2.3"),
    (PRE + "G1 X(FLAT END MILL)", r"3:4: word 'X' without a number", "X"),
    (PRE + "G1 X-(FLAT END MILL)", r"3:4: word 'X-' without a number", "X-"),
    (PRE + "G1 X1 §(FLAT END MILL)", r"3:7: unexpected character '§' in '§'", "§"),
    (PRE + "G1 X1 U5 (FLAT END MILL)", r"3:7: word U is not read", None),
    (PRE + "G1 X1 (FLAT END MILL", r"3:7: comment '\(' is not closed", None),
    (PRE + "G1 X[1 +(FLAT END MILL)]", r"3:9: expected a number, a parameter '#', '\[' or a "
     r"function, found '\('", None),
]


@pytest.mark.parametrize(("text", "message", "quoted"), COMMENT_LEAKS)
def test_no_message_quotes_a_comment(text: str, message: str, quoted: str | None) -> None:
    with pytest.raises(ToolpathError, match=r"^<string>:" + message) as e:
        read_gcode_text(text)
    messages = [str(e.value)] + [str(w) for w in read_gcode_text(text, strict=False).warnings]
    for m in messages:
        assert "FLAT" not in m and "MILL" not in m, m
    if quoted is not None:
        assert f"'{quoted}'" in str(e.value)


def test_a_nested_comment_is_one_comment_when_read_leniently() -> None:
    tp = read_gcode_text(PRE + "G1 X1 (T1 (6MM) FLAT) Y2", strict=False)
    assert tp.skipped == {"nested_comment": 1}
    assert list(tp.moves[-1].end / 1e-3) == [1, 2, 0]
    # an unbalanced '(' inside a comment with no later ')' is an ordinary comment, as before
    for line in ("G1 X1 (T1 ( FLAT) Y2", "G1 X1 (T1 ( FLAT) Y2 (NOTE)"):
        tp = read_gcode_text(PRE + line)
        assert tp.warnings == [] and list(tp.moves[-1].end / 1e-3) == [1, 2, 0]


def test_nested_comments_are_read_in_linear_time() -> None:
    import time

    for line, skipped in (("(a(b)" * 200_000, {}), ("(a(b)c)" * 200_000, {"nested_comment": 1})):
        t0 = time.perf_counter()
        tp = read_gcode_text(PRE + "G1 X1 " + line, strict=False)
        assert time.perf_counter() - t0 < 5.0
        assert {k: min(v, 1) for k, v in tp.skipped.items()} == skipped
