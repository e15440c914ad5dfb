"""Tests of LinuxCNC parameters, expressions and O-words in the G-code reader.

Oracles: positions computed in the test with Python's own floats and ``math`` (degrees turned to
radians here, not by the reader), the LinuxCNC documentation's examples ("G-code overview":
``[2.0 / 3 * 1.5 - 5.5 / 11.0]`` is 0.5, ``#3=6 G1 X#3`` moves to the old #3, ``FIX[-2.8]`` is -3,
``FUP[-2.8]`` is -2), and hand values; errors are table-driven.
"""

from __future__ import annotations

import math
import time

import numpy as np
import pytest
from conftest import mutate

from robot_io.gcode import GcodeOptions, read_gcode_text
from robot_io.gcode._interp import run_program
from robot_io.gcode._plain import scan_plain_lines
from robot_io.toolpath import ToolpathError, summarize

MM = 1e-3
PRE = "G21 G90 G17 F100\nG0 X0 Y0 Z0\n"


def _x_mm(text: str, **kw) -> float:
    """X of the last move [mm] of ``PRE + text``."""
    return float(read_gcode_text(PRE + text, **kw).moves[-1].end[0] / MM)


# --------------------------------------------------------------------------- a LinuxCNC program
def _linuxcnc_program(n: int) -> tuple[str, list[tuple[float, float, float, float]]]:
    """A LinuxCNC-style program of about 4·n lines (a spiral written with parameters) and the
    end point [mm] and feed [mm/min] of every move, computed here."""
    lines = ["%", "(spiral, written with parameters in the LinuxCNC style)", "G21 G90 G17 G94",
             "#<depth> = -2.0", "#<_safe> = 5", "#<Feed Rate> = 600", "#1 = 10", "#2 = 1.5",
             "#10 = 11", "#11 = 3.5", "G0 X0 Y0 Z#<_safe>"]
    expect = [(0.0, 0.0, 5.0, math.nan)]
    r1, depth = 10.0, -2.0
    for k in range(n):
        angle = k * 7.5
        lines.append(f"#<angle> = [{k} * 7.5]")
        lines.append("#<r> = [#1 + #<angle> / 36]")
        lines.append(f"G1 X[#<r> * COS[#<angle>]] Y[#<r> * SIN[#<angle>]] "
                     f"Z[#<depth> - {k % 4} * 0.25] F[#<feedrate> + {k % 3} * 100]")
        r = r1 + angle / 36
        expect.append((r * math.cos(math.radians(angle)), r * math.sin(math.radians(angle)),
                       depth - (k % 4) * 0.25, 600.0 + (k % 3) * 100))
        if k % 50 == 49:
            # settings take effect after the line is read: X uses the old #1 and #<depth>
            lines.append("#1 = [#1 + 1] #<depth> = [#<depth> - 0.5] G0 X#1 Y##10 Z#<depth>")
            expect.append((r1, 3.5, depth, math.nan))
            r1 += 1.0
            depth -= 0.5
    lines += ["G0 Z#<_safe>", "M30", "%"]
    x, y = expect[-1][:2]
    expect.append((x, y, 5.0, math.nan))
    return "\n".join(lines) + "\n", expect


@pytest.mark.parametrize("strict", [True, False])
def test_a_linuxcnc_program_with_parameters_reads_every_move(strict: bool) -> None:
    text, expect = _linuxcnc_program(300)
    tp = read_gcode_text(text, strict=strict)
    assert len(tp.moves) == len(expect) == 308
    np.testing.assert_allclose(tp.moves.ends / MM, [e[:3] for e in expect], rtol=0, atol=1e-12)
    feeds = [m.feed for m in tp.moves if m.feed is not None]
    np.testing.assert_allclose(np.array(feeds) / (MM / 60), [e[3] for e in expect
                                                            if not math.isnan(e[3])])
    assert tp.warnings == [] and dict(tp.skipped) == {}
    assert text.count("\n") > 900


def test_parameter_lines_never_take_the_bulk_path() -> None:
    plain = "".join(f"G1 X{i} Y{i % 5}\n" for i in range(20))
    special = ["#1 = 5", "G1 X#1", "G1 X[1 + 2]", "o100 if [1]", "O1001", "G1 X1 ; #1",
               "G1 X[#1]", "#<a>=1"]
    text = PRE + plain + "\n".join(special) + "\n" + plain
    scan = scan_plain_lines(text, text.count("\n") + 1)
    assert scan is not None
    first = 2 + 20
    assert not scan.ok[first:first + len(special)].any()
    assert scan.ok[2:first].all() and scan.ok[first + len(special):-1].all()


def test_bulk_path_and_interpreter_agree_on_a_parameter_program() -> None:
    text, _ = _linuxcnc_program(40)
    body = "".join(f"G1 X{i * 0.5} Y#2\nX{i} Y{i % 3}\n" if i % 9 == 0 else f"X{i} Y{i % 3}\n"
                   for i in range(120))
    text = text.replace("G0 Z#<_safe>\nM30", body + "G0 Z#<_safe>\nM30")
    out = []
    for plain in (True, False):
        tp = run_program(text, "<string>", True, GcodeOptions(), plain=plain)
        out.append((tp.moves.ends.tobytes(), [m.source for m in tp.moves], tp.warnings,
                    dict(tp.skipped)))
    assert out[0] == out[1]


# --------------------------------------------------------------------------- expressions
@pytest.mark.parametrize(("expr", "value"), [
    ("[2.0 / 3 * 1.5 - 5.5 / 11.0]", 0.5),          # the LinuxCNC manual's example
    ("[9+8*7/6+5-4*3**2+1]", 9 + 8 * 7 / 6 + 5 - 4 * 3 ** 2 + 1),
    ("[1 + acos[0] - [2 ** [4.0/2]]]", 1 + 90 - 4),
    ("[-2**2]", 4.0),                               # a sign belongs to the value after it
    ("[2**3**2]", 64.0),                            # left to right within a group
    ("[1 + 2 EQ 3]", 1.0), ("[0.1 * 3 EQ 0.3]", 1.0), ("[1 NE 1.0000001]", 0.0),
    ("[1 LT 2 AND 3 GT 4]", 0.0), ("[1 OR 0 XOR 1]", 0.0), ("[2 GE 2]", 1.0), ("[2 LE 1]", 0.0),
    ("[7 MOD 3]", 1.0), ("[-7 MOD 3]", 2.0),        # never negative, as LinuxCNC
    ("FIX[-2.8]", -3.0), ("FUP[-2.8]", -2.0), ("FIX[2.8]", 2.0), ("FUP[2.8]", 3.0),
    ("ROUND[2.5]", 3.0), ("ROUND[-2.5]", -3.0), ("ABS[-3]", 3.0),
    ("SIN[30]", math.sin(math.radians(30))), ("COS[60]", math.cos(math.radians(60))),
    ("TAN[45]", math.tan(math.radians(45))), ("ASIN[1]", 90.0), ("ATAN[1]/[-1]", 135.0),
    ("SQRT[16]", 4.0), ("EXP[1]", math.e), ("LN[EXP[2]]", 2.0),
    ("-SIN[30]", -math.sin(math.radians(30))), ("- [1 + 1]", -2.0),
    ("[ 1 +[ 2 * 3 ] ]", 7.0), ("[[[[[1]]]]]", 1.0),
    ("EXISTS[#<nope>]", 0.0), ("[EXISTS[#<_x>] + EXISTS[#<a>]]", 2.0),
])
def test_expression_values(expr: str, value: float) -> None:
    assert _x_mm(f"#<a> = 1\nG1 X{expr}") == pytest.approx(value, rel=1e-12, abs=1e-12)
    assert _x_mm(f"#<a> = 1\nG1 X{expr.lower()}") == pytest.approx(value, rel=1e-12,
                                                                    abs=1e-12)


def test_parameter_rules() -> None:
    # a setting takes effect after every value on its line is read; the last one wins
    assert _x_mm("#3 = 15\n#3 = 6 G1 X#3") == 15.0
    assert _x_mm("#3 = 15 #3 = 6\nG1 X#3") == 6.0
    # '#' binds tighter than '+'; brackets and '#' give indirection
    assert _x_mm("#1 = 5 #3 = 15\nG1 X[#1+2]") == 7.0
    assert _x_mm("#1 = 5 #3 = 15\nG1 X#[1+2]") == 15.0
    assert _x_mm("#2 = 3 #3 = 15\nG1 X##2") == 15.0
    assert _x_mm("#2 = 3\n##2 = 8\nG1 X#3") == 8.0
    # names: case-insensitive, blanks ignored, _globals the same at the top level
    assert _x_mm("#<My Depth> = 4\nG1 X#<mydepth>") == 4.0
    assert _x_mm("#<_G> = 2\nG1 X[#<_g> * 3]") == 6.0
    # every word takes an expression: G, F, arc words, R
    tp = read_gcode_text(PRE + "#1 = 1 #<f> = 300\nG[#1] X5 F#<f>\n#<r> = 5\nG[#1 + 2] X15 R#<r>")
    assert tp.moves[-2].feed == pytest.approx(300 * MM / 60)
    assert tp.moves[-1].is_arc and tp.moves[-1].end[0] == pytest.approx(15 * MM)
    # the modelled machine state: current position and modes
    assert _x_mm("G1 X4\nG1 X[#<_x> + #5420 + #<_metric>]") == 9.0
    assert _x_mm("G20\nG1 X[#<_imperial>]") == pytest.approx(25.4)


def test_unset_parameters() -> None:
    # numbered: 0, as LinuxCNC, with one counted warning per parameter
    tp = read_gcode_text(PRE + "G1 X[#7 + 2]\nG1 Y#7\nG1 Z#8")
    assert tp.moves[-3].end[0] == pytest.approx(2 * MM)
    assert tp.meta["warning_counts"]["unset_numbered_parameter"] == 2
    assert str(tp.warnings[0]).startswith("<string>:3:6: #7 is read before it is set: 0")
    # named: an error (LinuxCNC refuses it too); lenient skips the line and its settings
    with pytest.raises(ToolpathError, match=r"^<string>:3:8: #<depth> is read before it is set"):
        read_gcode_text(PRE + "G1 X1 Z#<depth>")
    tp = read_gcode_text(PRE + "#1 = 4 G1 X1 Z#<depth>\nG1 X[#1 + 1]", strict=False)
    assert tp.skipped == {"unset_parameter": 1}
    assert tp.moves[-1].end[0] == pytest.approx(1 * MM)   # #1 = 4 was skipped with its line
    assert read_gcode_text(PRE + "#<d> = [EXISTS[#<d>]]\nG1 X#<d>").moves[-1].end[0] == 0.0


# --------------------------------------------------------------------------- errors
ERRORS = [
    # program, strict message after "<string>:", lenient category
    ("G1 X[1 + ]", r"3:10: expected a number, a parameter", "bad_expression"),
    ("G1 X[1 2]", r"3:8: expected an operator or '\]', found '2'", "bad_expression"),
    ("G1 X[1 + 2", r"3:5: '\[' is not closed with '\]'", "bad_expression"),
    ("G1 X[1 / 0]", r"3:8: division by zero", "bad_expression"),
    ("G1 X[1 MOD 0]", r"3:8: 1 MOD 0: modulus by zero", "bad_expression"),
    ("G1 XSQRT[-1]", r"3:5: SQRT of -1", "bad_expression"),
    ("G1 XACOS[2]", r"3:5: ACOS of 2", "bad_expression"),
    ("G1 XLN[0]", r"3:5: LN of 0", "bad_expression"),
    ("G1 X[-8 ** 0.5]", r"3:9: -8 \*\* 0.5: a negative number", "bad_expression"),
    ("G1 X[10 ** 400]", r"3:9: the result is not a finite number", "bad_expression"),
    ("G1 XEXP[1000]", r"3:5: EXP overflows", "bad_expression"),
    ("G1 X[1.2.3]", r"3:6: malformed number '1.2.3'", "bad_expression"),
    ("G1 X#1+2", r"3:7: unexpected character '\+'", "malformed_word"),   # LinuxCNC too
    ("G1 XATAN[1]", r"3:12: ATAN needs two arguments", "bad_expression"),
    ("G1 X[1e5]", r"3:7: expected an operator or '\]', found 'E5'", "bad_expression"),
    ("G1 X#1.5", r"3:5: a parameter number must be an integer, got 1.5", "bad_expression"),
    ("G1 X#0", r"3:5: parameter number #0 is out of range", "bad_parameter"),
    ("G1 X#9999", r"3:5: parameter number #9999 is out of range", "bad_parameter"),
    ("G1 X#<a", r"3:6: parameter name '<…' is not closed", "bad_expression"),
    ("G1 X#<>", r"3:6: empty parameter name", "bad_expression"),
    ("G1 X[EXISTS[#1]]", r"3:13: EXISTS takes one named parameter", "bad_expression"),
    ("G1 X#5221", r"3:5: #5221 \(G54–G59.3 work offset\) is machine state", "system_parameter"),
    ("G1 X#<_vmajor>", r"3:5: #<_vmajor> is machine state", "system_parameter"),
    ("#5221 = 1", r"3:1: setting #5221 \(G54–G59.3 work offset\) would change machine state",
     "system_parameter"),
    ("#<_x> = 1", r"3:1: #<_x> is a read-only predefined parameter", "system_parameter"),
    ("#1", r"3:3: #1 outside a word: a parameter setting needs '='", "bad_expression"),
    ("#1 =", r"3:5: #1 = needs a value", "bad_expression"),
    ("#1 = (ten)", r"3:6: #1 = needs a value", "bad_expression"),
    ("G1 X[1] X[2]", r"3:9: second X word", "duplicate_word"),
    ("G1 X[1000000000 * 10]", r"3:4: X = 1e\+10 \(an expression\) is out of range", "malformed_word"),
    ("G[1.23] X1", r"3:1: unknown G code G1.23", "unknown_g"),
    ("G1 [1 + 2]", r"3:4: an expression '\[…\]' must be the value of a word", "malformed_word"),
]


@pytest.mark.parametrize(("text", "message", "category"), ERRORS,
                         ids=[e[0] for e in ERRORS])
def test_expression_errors(text: str, message: str, category: str) -> None:
    with pytest.raises(ToolpathError, match=r"^<string>:" + message):
        read_gcode_text(PRE + text)
    tp = read_gcode_text(PRE + text, strict=False)
    assert tp.meta["warning_counts"].get(category, 0) >= 1


def test_long_expressions_are_linear_and_not_recursive() -> None:
    n = 200_000
    cases = [("G1 X" + "[" * n + "1" + "]" * n, None), ("G1 X" + "-[" * n + "1" + "]" * n, None),
             ("G1 X" + "[" * n, "is not closed"), ("#<" + "a" * n + "> = 1", None),
             ("G1 X[" + "1+" * n + "1]", None)]
    for line, error in cases:
        t0 = time.perf_counter()
        if error is None:
            read_gcode_text(PRE + line)
        else:
            with pytest.raises(ToolpathError, match=error):
                read_gcode_text(PRE + line)
        assert time.perf_counter() - t0 < 10.0


def test_fuzz_parameter_programs_only_raise_toolpath_errors(rng: np.random.Generator) -> None:
    text, _ = _linuxcnc_program(12)
    base = text.encode()
    alphabet = b"0123456789.+-#<>[]=*/XYZFGMOSINCQRT _\n()"
    outcomes = {"ok": 0, "error": 0}
    for _ in range(300):
        mutated = mutate(base, alphabet, rng, edits=8).decode("latin-1")
        try:
            summarize(read_gcode_text(mutated))
            outcomes["ok"] += 1
        except ToolpathError:
            outcomes["error"] += 1
        summarize(read_gcode_text(mutated, strict=False))   # lenient never raises
    assert outcomes["ok"] > 0 and outcomes["error"] > 0


# --------------------------------------------------------------------------- O-word flow control
def _ends(text: str, **kw) -> list[list[float]]:
    """End points [mm] of the moves after the preamble's first."""
    tp = read_gcode_text(PRE + text, **kw)
    return [[round(float(v) / MM, 9) for v in m.end] for m in tp.moves[1:]]


def test_a_spiral_written_as_a_loop_reads_like_the_one_written_out() -> None:
    _, expect = _linuxcnc_program(120)
    loop = ("""%
G21 G90 G17 G94
#<depth> = -2.0 #<_safe> = 5 #<feedrate> = 600 #1 = 10 #2 = 1.5 #10 = 11 #11 = 3.5
G0 X0 Y0 Z#<_safe>
#<k> = 0
o100 while [#<k> LT 120]
  #<angle> = [#<k> * 7.5]
  #<r> = [#1 + #<angle> / 36]
  G1 X[#<r> * COS[#<angle>]] Y[#<r> * SIN[#<angle>]] Z[#<depth> - [#<k> MOD 4] * 0.25] """
    """F[#<feedrate> + [#<k> MOD 3] * 100]
  o101 if [[#<k> MOD 50] EQ 49]
    #1 = [#1 + 1] #<depth> = [#<depth> - 0.5] G0 X#1 Y##10 Z#<depth>
  o101 endif
  #<k> = [#<k> + 1]
o100 endwhile
G0 Z#<_safe>
M30
%
""")
    tp = read_gcode_text(loop)
    np.testing.assert_allclose(tp.moves.ends / MM, [e[:3] for e in expect], rtol=0,
                               atol=1e-12)
    assert tp.warnings == []


def test_subroutines_run_with_their_arguments() -> None:
    square = """o<square> sub
  G1 X#1 Y0
  G1 Y#1
  G1 X0
  G1 Y0
  #<side> = #1 #<_last> = #1
  o<square> return [#1 * 4]
o<square> endsub
#1 = 99
o<square> call [10]
G1 Z#<_value>
o<square> call [5] (a comment between) [6]
G1 Z[#1 + #<_last>]
"""
    assert _ends(square) == [[10, 0, 0], [10, 10, 0], [0, 10, 0], [0, 0, 0], [0, 0, 40],
                             [5, 0, 40], [5, 5, 40], [0, 5, 40], [0, 0, 40], [0, 0, 104]]
    # the caller's #1 is back after the call; the sub's local #<side> is gone
    with pytest.raises(ToolpathError, match=r"#<side> is read before it is set"):
        read_gcode_text(PRE + square + "G1 X#<side>")
    # a call before the definition; a definition after M30 is no text after the program end
    tp = read_gcode_text(PRE + "o100 call [2] [3]\nG1 X#<_value>\nM30\no100 sub\nG1 X#1 Y#2\n"
                         "o100 endsub [#1 + #2]\n")
    assert [list(m.end / MM) for m in tp.moves[1:]] == [[2, 3, 0], [5, 3, 0]]
    assert tp.warnings == [] and tp.moves[1].source.line == 7
    # recursion
    assert _ends("o<f> sub\no1 if [#1 GT 0]\nG1 X#1\no<f> call [#1 - 1]\no1 endif\no<f> endsub\n"
                 "o<f> call [3]\n") == [[3, 0, 0], [2, 0, 0], [1, 0, 0]]


@pytest.mark.parametrize(("value", "x"), [(7, 100), (3, 3), (1, 99), (-1, 98)])
def test_conditionals(value: float, x: float) -> None:
    text = (f"#1 = {value}\no1 if [#1 GT 5]\nG1 X100\no1 elseif [#1 EQ 3]\nG1 X3\n"
            "o1 elseif [#1 GT 0]\nG1 X99\no1 else\nG1 X98\no1 endif\n"
            "o2 if [#1 LT 0]\nG1 Y1\no2 endif\n")
    assert _ends(text) == [[x, 0, 0]] + ([[x, 1, 0]] if value < 0 else [])


def test_loops() -> None:
    assert _ends("#1 = 0\no10 while [#1 LT 3]\n#1 = [#1 + 1]\nG1 X#1\no10 endwhile\nG1 Y1") == [
        [1, 0, 0], [2, 0, 0], [3, 0, 0], [3, 1, 0]]
    assert _ends("#1 = 5\no10 do\n#1 = [#1 + 1]\nG1 X#1\no10 while [#1 LT 3]") == [[6, 0, 0]]
    assert _ends("o10 repeat [3]\nG91 G1 X2\no10 endrepeat\no11 repeat [0]\nG1 Y9\n"
                 "o11 endrepeat") == [[2, 0, 0], [4, 0, 0], [6, 0, 0]]
    # break and continue; nested loops with their own labels
    text = ("#1 = 0\no10 while [1]\n#1 = [#1 + 1]\no11 if [#1 EQ 2]\no10 continue\no11 endif\n"
            "G1 X#1\no12 if [#1 GE 4]\no10 break\no12 endif\no10 endwhile\nG1 Y1")
    assert _ends(text) == [[1, 0, 0], [3, 0, 0], [4, 0, 0], [4, 1, 0]]
    grid = ("#1 = 0\no1 repeat [3]\n#2 = 0\no2 while [#2 LT 2]\nG1 X#1 Y#2\n#2 = [#2 + 1]\n"
            "o2 endwhile\n#1 = [#1 + 1]\no1 endrepeat")
    assert _ends(grid) == [[i, j, 0] for i in range(3) for j in range(2)]
    # plain lines inside a loop go through the bulk path and read the same
    body = "".join(f"G1 X{i} Y{i % 7}\n" for i in range(20))
    text = "o1 repeat [3]\n" + body + "o1 endrepeat\n"
    for plain in (True, False):
        tp = run_program(PRE + text, "<string>", True, GcodeOptions(), plain=plain)
        assert len(tp.moves) == 61 and tp.moves[-1].source.line == 23


def test_flow_limits(monkeypatch: pytest.MonkeyPatch) -> None:
    from robot_io.gcode import _oword

    monkeypatch.setattr(_oword, "MAX_LOOP_ITERATIONS", 50)
    endless = "o10 while [1]\nG1 X1\no10 endwhile\nG1 Y2"
    with pytest.raises(ToolpathError, match=r"^<string>:3:1: o10 while: the loop ran 50 "
                       r"times without ending"):
        read_gcode_text(PRE + endless)
    tp = read_gcode_text(PRE + endless, strict=False)
    assert len(tp.moves) == 1 + 50 + 1 and tp.skipped == {"o_word": 1}
    assert "it is left there and the lines after it are read" in tp.warnings[0].message
    tp = read_gcode_text(PRE + "o1 repeat [80]\nG91 G1 X1\no1 endrepeat", strict=False)
    assert len(tp.moves) == 1 + 50 and tp.meta["warning_counts"]["o_word"] == 1
    monkeypatch.setattr(_oword, "MAX_FLOW_STEPS", 120)
    tp = read_gcode_text(PRE + "o1 repeat [40]\no2 repeat [40]\nG91 G1 X1\no2 endrepeat\n"
                         "o1 endrepeat\nG90 G1 Y5", strict=False)
    assert "the rest of the program is not read" in tp.warnings[0].message
    assert tp.moves[-1].end[1] == 0.0   # the Y5 after the loops is not read
    with pytest.raises(ToolpathError, match=r"calls nest deeper than 100"):
        read_gcode_text(PRE + "o<f> sub\no<f> call\no<f> endsub\no<f> call\n")


FLOW_ERRORS = [
    ("o100 call", r"3:1: o100 call: no o100 sub in this file; fix the program"),
    ("o<part> call [1]", r"3:1: o<part> call: no o<part> sub in this file \(LinuxCNC would "
     r"look for the file part.ngc in its subroutine path"),
    ("o100 sub\nG1 X1", r"3:1: o100 sub: no o100 endsub closes the subroutine"),
    ("o100 return", r"3:1: o100 return: not inside a call of o100"),
    ("o1 if [0]\nG1 X1", r"3:1: o1 if: no o1 else/endif closes the if"),
    ("o1 while [1]\nG1 X1", r"3:1: o1 while: no o1 endwhile closes the loop"),
    ("o1 repeat [2]\nG1 X1", r"3:1: o1 repeat: no o1 endrepeat closes the loop"),
    ("o1 endwhile", r"3:1: o1 endwhile: not inside an o1 loop"),
    ("o1 break", r"3:1: o1 break: not inside an o1 loop"),
    ("o1 if #1\no1 endif", r"3:7: o1 if needs its value in brackets"),
    ("o1 if [1 +]\no1 endif", r"3:11: expected a number"),
    ("o1 if [1] G1 X5\no1 endif", r"3:11: o1 if: only its value in brackets and comments"),
    ("o1 do X5\no1 while [0]", r"3:7: o1 do: only its value in brackets"),
    ("o<a b", r"3:1: O<name> needs a keyword after it"),
    ("O<x> G1 X1", r"3:1: O<name> needs a keyword after it"),
]


@pytest.mark.parametrize(("text", "message"), FLOW_ERRORS, ids=[e[0] for e in FLOW_ERRORS])
def test_flow_errors(text: str, message: str) -> None:
    with pytest.raises(ToolpathError, match=r"^<string>:" + message):
        read_gcode_text(PRE + text)
    tp = read_gcode_text(PRE + text, strict=False)
    assert tp.warnings and all("strict" not in w.message for w in tp.warnings
                               if w.category == "o_word")


FLOW_PROGRAM = """%
O1001 (FLOW)
G21 G90 G17 G94 F300
G0 X0 Y0 Z5
o<pass> sub
  G1 Z#1
  G1 X[#2 * COS[30]] Y[#2 * SIN[30]]
  o<pass> return [#1 - 1]
o<pass> endsub
#<z> = 0
o10 repeat [3]
  o<pass> call [#<z>] [10]
  #<z> = #<_value>
  o11 if [#<z> LT -2]
    o10 break
  o11 elseif [#<z> EQ -1]
    G0 Z2
  o11 else
    G0 Z1
  o11 endif
o10 endrepeat
#1 = 0
o12 while [#1 LT 2]
  #1 = [#1 + 1]
  G1 X#1
o12 endwhile
o13 do
  #1 = [#1 - 1]
o13 while [#1 GT 0]
G0 Z5
M30
%
"""


def test_fuzz_flow_programs_only_raise_toolpath_errors(rng: np.random.Generator,
                                                       monkeypatch: pytest.MonkeyPatch) -> None:
    from robot_io.gcode import _oword

    monkeypatch.setattr(_oword, "MAX_LOOP_ITERATIONS", 100)
    monkeypatch.setattr(_oword, "MAX_FLOW_STEPS", 1000)
    tp = read_gcode_text(FLOW_PROGRAM)   # the seed program itself is valid
    assert tp.warnings == [] and tp.meta["program_number"] == 1001
    assert [list(np.round(m.end / MM, 9)) for m in tp.moves][:4] == [
        [0, 0, 5], [0, 0, 0], [round(10 * math.cos(math.radians(30)), 9), 5, 0],
        [round(10 * math.cos(math.radians(30)), 9), 5, 2]]
    alphabet = b"0123456789.+-#<>[]=*/XYZFGMOSINCQRTEDWHLPAB _\n()"
    outcomes = {"ok": 0, "error": 0}
    for _ in range(300):
        mutated = mutate(FLOW_PROGRAM.encode(), alphabet, rng, edits=6).decode("latin-1")
        try:
            summarize(read_gcode_text(mutated))
            outcomes["ok"] += 1
        except ToolpathError:
            outcomes["error"] += 1
        summarize(read_gcode_text(mutated, strict=False))   # lenient never raises
    assert outcomes["ok"] > 0 and outcomes["error"] > 0
