"""The fuzz targets of issue 22: one per parser, each with its seeds, its mutations and its rule.

Not collected by pytest itself (no ``test_`` prefix): ``tests/test_fuzz_targets.py`` runs every
target for a few seconds in ``make test``, ``tests/fuzz_run.py`` (``make fuzz``) for minutes.

Targets (:data:`TARGETS`):

========== ======================================================= ==================================
name       calls                                                   documented errors
========== ======================================================= ==================================
gcode      ``read_toolpath`` of a .nc/.ngc (or extension-less)     ``ToolpathError`` naming the file
           file, strict and lenient, then ``summarize``
apt        the same for APT/CL                                     ``ToolpathError``
krl        the same for a ``.src`` with its ``.dat`` and pages     ``ToolpathError``
job        ``load_job`` of a TOML file, then ``to_si`` and the     ``JobError`` naming the file;
           reader options of what loads                            nothing from ``to_si``
plan       ``load_plan`` of ``plan.json`` + ``samples.npz``, then  ``PlanFileError`` naming the
           ``plan_to_krl`` and ``render_krl`` of what loads        file; any cctmill error to export
kvp        ``parse_request``, ``parse_reply`` and ``read_reply``   ``ProtocolError`` (and ``OSError``
           (over a socket pair) of one frame; repacking what       for the socket of read_reply)
           parses gives the same bytes (up to MAX_BODY_BYTES)
rsi        ``parse_rob`` and ``parse_sen`` of one datagram; a      ``ProtocolError``
           reply echoing a parsed IPOC parses back
udp        ``parse_samples`` of every datagram of a stream and     none: malformed datagrams are
           the stream through a ``UdpSignalSource`` (its receive   ``None``, counted and dropped
           step, no socket timing); timestamps increase, every
           datagram is counted once
signal     ``load_signal`` of a CSV or NPY file, replayed to its   ``SignalFileError`` naming the
           end; times finite and increasing                        file
========== ======================================================= ==================================

The rule of every call (:func:`_fuzz_kit.run_calls`): a result that keeps the promises above or a
documented error, within 2 s and 500 MB of peak RSS growth.

Seeds: the real CAM files of ``../shared/data/toolpaths`` (when present) and the bundled demo
program for the readers, the KRL fixtures of ``tests/data/krl`` and the KRL the exporter writes for
two small plans, the demo job, two plans planned from a shortened demo job (constant and optimised
feeds; planned when first asked for, so they are always in the current plan format), and packets
built with the links' own ``build_*``/``pack_*`` functions.
"""

from __future__ import annotations

import functools
import io
import math
import socket
import struct
import tempfile
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
from _fuzz_kit import (
    HANG_S,
    BadResult,
    Call,
    Case,
    Dialect,
    Verdict,
    cases,
    json_values,
    npz_bytes,
    numbers,
    render_json,
    render_toml,
    run_calls,
)
from hypothesis import strategies as st

from models.errors import CctmillError
from robot_io.links.base import ProtocolError
from robot_io.links.kvp import (
    FN_READ,
    FN_WRITE,
    MAX_BODY_BYTES,
    KvpRequest,
    pack_reply,
    pack_request,
    parse_reply,
    parse_request,
    read_reply,
)
from robot_io.links.rsi import build_rob, build_sen, parse_rob, parse_sen
from robot_io.readers import read_toolpath
from robot_io.signals.replay import ReplaySource, SignalFileError, load_signal
from robot_io.signals.udp import HEADER, MAGIC, MAX_LOSS_GAP, UdpSignalSource, pack_samples, parse_samples
from robot_io.toolpath import ToolpathError, summarize

__all__ = ["REPO", "SHARED", "TARGETS", "Target", "check"]

REPO = Path(__file__).resolve().parents[1]
#: The real CAM files (a sibling checkout; optional).
SHARED = REPO.parent / "shared" / "data" / "toolpaths"
DEMO = REPO / "planner" / "data" / "demo"
KRL_DATA = REPO / "tests" / "data" / "krl"


@dataclass(frozen=True)
class Target:
    """One parser under fuzzing.

    Attributes:
        name: as ``--target`` spells it.
        rule: what each input is held to, in one line.
        seeds: the seed cases (computed when first asked for, then cached).
        strategy: ``strategy(seeds, whole)``: mutated cases; ``whole=False`` keeps big files in
            windows (the suite's few seconds), ``True`` edits them whole now and then.
        calls: ``calls(case, folder)``: the calls of one input whose files are in ``folder``.
    """

    name: str
    rule: str
    seeds: Callable[[], list[Case]]
    strategy: Callable[[Sequence[Case], bool], st.SearchStrategy[Case]]
    calls: Callable[[Case, Path], list[Call]]


def check(target: Target, case: Case, folder: Path, hang_s: float = HANG_S) -> Verdict:
    """Write ``case`` into ``folder`` (emptied first: give each target a folder of its own) and
    judge its calls."""
    case.write(folder)
    return run_calls(target.calls(case, folder), hang_s)


def _files(folder: Path, pattern: str) -> list[Path]:
    return sorted(folder.glob(pattern)) if folder.is_dir() else []


# -- toolpath readers --------------------------------------------------------------------------------

def _toolpath_error_ok(folder: Path) -> Callable[[BaseException], str | None]:
    def ok(e: BaseException) -> str | None:
        assert isinstance(e, ToolpathError)
        if not str(e.file).startswith(str(folder)):
            return f"names {e.file!r}, no file of the input"
        if e.line < 0 or e.column < 0 or not e.reason.strip():
            return f"line {e.line}, column {e.column}, reason {e.reason!r}"
        return None
    return ok


def _read(path: Path, strict: bool, options: dict[str, Any]) -> tuple[str, Any]:
    tp = read_toolpath(path, strict=strict, **options)
    s = summarize(tp)
    box = s["bbox_m"] or [[0.0]]
    if not (math.isfinite(s["length_m"]) and all(math.isfinite(v) for row in box for v in row)):
        raise BadResult(f"length {s['length_m']} m, bounding box {box}")
    warned = sorted({w.category for w in tp.warnings})
    return f"{tp.format} moves={bool(s['moves'])} skipped={sorted(tp.skipped)} warned={warned}", None


def _reader_calls(case: Case, folder: Path) -> list[Call]:
    options = dict(case.options)
    path = folder / next(iter(case.files))
    if options.pop("sniff", False):            # no extension: the format is guessed from the text
        path = path.rename(path.with_suffix(""))
    ok = _toolpath_error_ok(folder)
    return [Call(label, functools.partial(lambda p, s, o, _: _read(p, s, o), path, strict, options),
                 (ToolpathError,), ok)
            for label, strict in (("strict", True), ("lenient", False))]


_G_CODES = [b"0", b"1", b"2", b"3", b"4", b"10", b"17", b"18", b"19", b"20", b"21", b"28", b"30",
            b"40", b"41", b"43", b"49", b"53", b"54", b"61", b"64", b"80", b"81", b"82", b"83",
            b"90", b"91", b"93", b"94", b"98", b"99", b"90.1", b"91.1", b"5.1", b"999"]
_G_EXPR = [b"[1+2]", b"[#1*2]", b"[SIN[30]]", b"[1/0]", b"[SQRT[-1]]", b"[#<_x>]", b"[2**2000]",
           b"[EXP[1000]]", b"[ATAN[1]/[0]]", b"#1", b"#5220", b"[1e308*10]", b"[[[[[[1]]]]]]",
           b"[" * 60 + b"1" + b"]" * 60, b"[#1 MOD 0]", b"[ACOS[2]]", b"[LN[0]]", b"[FIX[-1e300]]"]
_G_WORD = st.one_of(
    st.tuples(st.just(b"G"), st.sampled_from(_G_CODES)),
    st.tuples(st.just(b"M"), st.sampled_from([b"0", b"2", b"3", b"5", b"6", b"30", b"98", b"99",
                                              b"428", b"429"])),
    st.tuples(st.sampled_from(list(b"XYZABCIJKRFSPQLTHDEUVWN")).map(lambda c: bytes([c])),
              numbers() | st.sampled_from(_G_EXPR)),
).map(b"".join)
_G_STATEMENTS = [b"#1 = [#1 + 1]", b"#1 = 0", b"o100 while [#1 LT 5]", b"o100 endwhile",
                 b"o101 repeat [3]", b"o101 repeat [1e9]", b"o101 endrepeat", b"o102 if [#1 GT 2]",
                 b"o102 else", b"o102 endif", b"o103 sub", b"o103 endsub", b"o103 call [1]",
                 b"o104 do", b"o104 while [1]", b"o100 break", b"o100 continue", b"(comment)",
                 b"(MSG, hi)", b"(", b";", b"%", b"/G1 X1", b"#<x> = 5", b"M99", b"G10 L2 P1 X0",
                 b"o<sub> call", b"o105 return", b"#1=[#1*2]"]
GCODE_LINE = st.one_of(st.lists(_G_WORD, min_size=1, max_size=6).map(b" ".join),
                       st.sampled_from(_G_STATEMENTS))
GCODE = Dialect(alphabet=b"GMXYZABCIJKRFN0123456789.-+ ()[]#=;%\n/*",
                tokens=(b"G0", b"G1", b"G2", b"G3", b"G81", b"G83", b"G93", b"G20", b"G28", b"G91",
                        b"M428", b"M30", b"(", b")", b";", b"[", b"]", b"#1=", b"#<x>", b"o100 ",
                        b"while", b"endwhile", b"repeat", b"sub", b"endsub", b"call", b"if", b"else",
                        b"endif", b"L", b"P", b"R", b"%", b"N", b"/", b"**", b"ATAN", b"SQRT[",
                        b"EXP[", *_G_EXPR[:4]),
                lines=GCODE_LINE, max_bytes=1 << 20)

#: A program of the G-code features the real files lack (loops, subroutines, cycles, planes,
#: inverse time, inch), to mutate from.
GCODE_SEED = b"""%
(cctmill fuzz seed: G-code reader features in one program)
G21 G90 G17 G94
G0 X0 Y0 Z10
F600
G1 Z-1
G1 X20 Y0
G2 X30 Y10 I0 J10
G3 X20 Y20 R10
G18 G2 X30 Z-1 I5 K0
G17
#1 = 0
o100 while [#1 LT 3]
G1 X[20 + #1 * 2] Y[SIN[#1 * 30] * 5]
#1 = [#1 + 1]
o100 endwhile
o200 repeat [2]
G91 G1 X1
o200 endrepeat
G90
G81 X5 Y5 Z-3 R2 F300
X10
G80
G20 G1 X1 Y1
G21
G93 G1 X10 F2
G94 F600
G0 Z10 A10 C20
M30
%
"""


def _gcode_seeds() -> list[Case]:
    real = [p for suffix in (".nc", ".ngc") for p in _files(SHARED, f"*{suffix}")]
    return ([Case({f"fuzz{p.suffix}": p.read_bytes()}) for p in sorted(real)]
            + [Case({"fuzz.nc": (DEMO / "bracket_contour.nc").read_bytes()}),
               Case({"fuzz.ngc": GCODE_SEED})])


GCODE_OPTIONS = st.fixed_dictionaries({
    "sniff": st.sampled_from([False, False, False, True]),
    "rotary": st.sampled_from([None, None, "xyzac-trunnion", "xyzbc-trunnion"]),
    "default_units": st.sampled_from(["mm", "inch"]),
    "tcp": st.sampled_from([None, None, True, False]),
})


@st.composite
def _gcode_generated(draw: Any) -> Case:
    body = b"\n".join(draw(st.lists(GCODE_LINE, min_size=1, max_size=40)))
    return Case({"fuzz.nc": b"G21 G90 G17 F100\nG0 X0 Y0 Z5\n" + body + b"\nM30\n"}, draw(GCODE_OPTIONS))


def _gcode_strategy(seeds: Sequence[Case], whole: bool) -> st.SearchStrategy[Case]:
    return cases(seeds, {"*": GCODE}, GCODE_OPTIONS, _gcode_generated(), whole)


_APT_WORDS = [b"MMPM", b"IPM", b"RAPTO", b"FEDTO", b"TIMES", b"MM", b"INCHES", b"ON", b"OFF", b"STEP",
              b"RTRCTO", b"AUTO", b"DEEP", b"BRKCHP", b"RPM", b"CLW", b"TOOL"]
APT_LINE = st.one_of(
    st.tuples(st.sampled_from([b"GOTO/", b"FROM/", b"GODLTA/", b"CIRCLE/", b"TLAXIS/", b"FEDRAT/",
                               b"MSYS/", b"CSYS/", b"NURBS/", b"KNOT/", b"SPINDL/", b"CUTTER/",
                               b"CYCLE/DRILL,", b"CYCLE/DEEP,", b"LOADTL/", b"UNITS/", b"RAPID/",
                               b"TLDATA/MILL,", b"CYCLE/TAP,"]),
              st.lists(numbers() | st.sampled_from(_APT_WORDS), max_size=14).map(b",".join)).map(b"".join),
    st.sampled_from([b"RAPID", b"FINI", b"MULTAX/ON", b"MULTAX/OFF", b"CYCLE/OFF", b"UNITS/INCHES",
                     b"UNITS/MM", b"$$ x", b"PPRINT hello", b"GOTO/1,2,$", b"INSERT G1 X1", b"PARTNO x",
                     b"NURBS/", b"KNOT/0,0,0,1,1,1", b"CONTROL/1", b"GOTO/", b"/", b"$"]),
)
APT = Dialect(alphabet=b"GOTCIRLEFDA/,.-+0123456789$ \n",
              tokens=(b"GOTO/", b"CIRCLE/", b"FEDRAT/", b"RAPID", b"UNITS/", b"INCHES", b"MM", b"$", b"$$",
                      b",", b"/", b"MULTAX/ON", b"TLAXIS/", b"CYCLE/DRILL,", b"CYCLE/OFF", b"NURBS/",
                      b"KNOT/", b"MSYS/", b"CSYS/", b"FINI", b"FROM/", b"GODLTA/", b"TIMES", b"PPRINT",
                      b"INSERT", b"SPINDL/", b"FEDTO,", b"RAPTO,"),
              lines=APT_LINE, max_bytes=1 << 20)
APT_SEED = b"""PARTNO/FUZZ
UNITS/MM
MULTAX/ON
CUTTER/10,0
LOADTL/1
SPINDL/3000,RPM,CLW
RAPID
GOTO/0,0,10,0,0,1
FEDRAT/300,MMPM
GOTO/0,0,0,0,0,1
GOTO/10,0,0,0,0,1
CIRCLE/10,10,0,0,0,1
GOTO/20,10,0,0,0,1
TLAXIS/0,0.1,0.995
GOTO/20,20,0
CYCLE/DRILL,MMPM,100,RAPTO,2,FEDTO,-5
GOTO/30,30,0
GOTO/40,30,0
CYCLE/OFF
GODLTA/0,0,10
$$ a comment
GOTO/50,30,$
0
FINI
"""
APT_OPTIONS = st.fixed_dictionaries({
    "sniff": st.sampled_from([False, False, False, True]),
    "default_units": st.sampled_from(["mm", "inch"]),
    "apply_frames": st.booleans(),
    "circle_direction": st.sampled_from(["auto", "auto", "ccw", "cw"]),
})


def _apt_seeds() -> list[Case]:
    return [Case({"fuzz.apt": p.read_bytes()}) for p in _files(SHARED, "*.apt")] + [
        Case({"fuzz.apt": APT_SEED})]


@st.composite
def _apt_generated(draw: Any) -> Case:
    body = b"\n".join(draw(st.lists(APT_LINE, min_size=1, max_size=40)))
    return Case({"fuzz.apt": b"UNITS/MM\nFEDRAT/100,MMPM\nGOTO/0,0,0\n" + body + b"\nFINI\n"},
                draw(APT_OPTIONS))


def _apt_strategy(seeds: Sequence[Case], whole: bool) -> st.SearchStrategy[Case]:
    return cases(seeds, {"*": APT}, APT_OPTIONS, _apt_generated(), whole)


_KRL_POS = st.lists(st.tuples(st.sampled_from([b"X", b"Y", b"Z", b"A", b"B", b"C", b"S", b"T", b"E1",
                                               b"A1", b"A2", b"x", b"X"]), numbers()),
                    max_size=8).map(lambda kv: b"{" + b",".join(k + b" " + v for k, v in kv) + b"}")
KRL_LINE = st.one_of(
    st.tuples(st.sampled_from([b"LIN ", b"PTP ", b"LIN_REL ", b"PTP_REL ", b"SPL ", b"LIN E6POS: "]),
              _KRL_POS, st.sampled_from([b"", b" C_DIS", b" C_VEL", b" C_PTP", b" #TOOL", b" #BASE"])
              ).map(b"".join),
    st.tuples(st.just(b"CIRC "), _KRL_POS, st.just(b","), _KRL_POS,
              st.sampled_from([b"", b", CA 90", b", CA -400", b", CA 1e9", b" C_DIS"])).map(b"".join),
    st.tuples(st.sampled_from([b"$VEL.CP = ", b"$APO.CDIS = ", b"$ADVANCE = ", b"I = ", b"N = ",
                               b"$OV_PRO = ", b"WAIT SEC ", b"FOR I = 1 TO "]), numbers()).map(b"".join),
    st.tuples(st.sampled_from([b"$BASE = {FRAME: ", b"$TOOL = {FRAME: "]),
              st.lists(numbers(), min_size=6, max_size=6)).map(
        lambda t: t[0] + b",".join(k + b" " + v for k, v in zip(b"X Y Z A B C".split(), t[1], strict=True))
        + b"}"),
    st.sampled_from([b"FOR I = 1 TO 3", b"FOR I = 1 TO 100000", b"FOR I = 10 TO 1 STEP -1",
                     b"FOR I = 1 TO 5 STEP 0", b"ENDFOR", b"IF N > 1 THEN", b"ELSE", b"ENDIF",
                     b"WHILE TRUE", b"ENDWHILE", b"LOOP", b"ENDLOOP", b"REPEAT", b"UNTIL FALSE",
                     b"SWITCH N", b"CASE 1", b"ENDSWITCH", b"GOTO M1", b"M1:", b"EXIT", b"HALT",
                     b"fuzz( )", b"sub( )", b"BAS(#TOOL,1)", b"BAS(#BASE,0)", b"BAS(#VEL_CP,0.5)",
                     b"DECL INT I", b"DECL E6POS P[5]", b"LIN P[I] C_DIS", b"LIN PTS[I+1]",
                     b"$TOOL = TOOL_DATA[1]", b"$BASE = $NULLFRAME", b";FOLD x", b";ENDFOLD", b"END",
                     b"DEF sub( )", b"DEFFCT REAL f( )", b"ENDFCT", b"INTERRUPT ON 3",
                     b"$IPO_MODE = #TCP", b"PTP $AXIS_ACT", b"PTP XHOME", b"LIN XP1"]),
)
KRL_DAT_LINE = st.one_of(
    st.tuples(st.sampled_from([b"DECL E6POS P1=", b"DECL GLOBAL E6POS XP1=", b"PTS[1]=", b"PTS[4]=",
                               b"PTS[0]=", b"DECL FRAME F1=", b"DECL E6AXIS XHOME="]),
              _KRL_POS).map(b"".join),
    st.tuples(st.sampled_from([b"DECL REAL V=", b"DECL INT N=", b"DECL BOOL B=", b"DECL REAL V_S1="]),
              numbers()).map(b"".join),
    st.sampled_from([b"DEFDAT fuzz", b"ENDDAT", b"DECL E6POS PTS[3]", b"DECL E6POS PTS[100000000]",
                     b"DECL INT N", b"DECL E6POS PTS[3,3]", b"EXT BAS (BAS_COMMAND :IN,REAL :IN )",
                     b"DECL CONST REAL V=1", b"DECL E6POS XP1"]),
)
KRL = Dialect(alphabet=b"LINPTCRXYZABC{},: .-+0123456789$=[]();#&'\"\n",
              tokens=(b"LIN ", b"PTP ", b"CIRC ", b"{", b"}", b",", b"X ", b"A1 ", b"E6POS:", b"$VEL.CP=",
                      b"$BASE=", b"$TOOL=", b"BAS(#", b"FOR I=1 TO ", b"ENDFOR", b"IF ", b"THEN", b"ELSE",
                      b"ENDIF", b"WHILE ", b"ENDWHILE", b"DEF ", b"END", b";FOLD", b";ENDFOLD", b"DECL ",
                      b"INT ", b"E6POS ", b"[", b"]", b"=", b"C_DIS", b"CA ", b"#TOOL", b"LIN_REL ",
                      b"( )", b"&", b"'", b"\"", b"GLOBAL ", b"DEFFCT", b"ENDFCT", b"\r\n"),
              lines=KRL_LINE)
KRL_DAT = replace(KRL, lines=KRL_DAT_LINE)
KRL_SRC_SEED = b"""DEF fuzz( )
DECL INT I
$BASE = {FRAME: X 0,Y 0,Z 0,A 0,B 0,C 0}
$TOOL = {FRAME: X 0,Y 0,Z 200,A 0,B 90,C 0}
$VEL.CP = 0.002
PTP {X 0,Y 0,Z 50,A 0,B 90,C 0}
LIN {X 0,Y 0,Z 0} C_DIS
FOR I = 1 TO 3
  LIN PTS[I] C_DIS
ENDFOR
CIRC {X 20,Y 10,Z 0},{X 10,Y 20,Z 0}, CA 90
IF N > 1 THEN
  LIN_REL {X 5} #TOOL
ELSE
  LIN {Z 10}
ENDIF
BAS(#VEL_CP, 0.5)
LIN {X 0,Y 0,Z 10}
END
"""
KRL_DAT_SEED = b"""DEFDAT fuzz
DECL INT N = 2
DECL E6POS PTS[3]
PTS[1]={X 10,Y 0,Z 0,A 0,B 90,C 0}
PTS[2]={X 10,Y 10,Z 0,A 0,B 90,C 0}
PTS[3]={X 20,Y 0,Z 0,A 0,B 90,C 0}
ENDDAT
"""
#: The KRL fixtures as programs: main ``.src`` first, then what it reads beside it.
_KRL_FIXTURES = (("plain_inline.src",), ("named_pair.src", "NAMED_PAIR.DAT"),
                 ("paged_main.src", "paged_main.dat", "paged_main_p001.src", "Paged_Main_P002.src",
                  "paged_main_p002.dat"))


def _krl_seeds() -> list[Case]:
    out = [Case({"fuzz.src": KRL_SRC_SEED, "fuzz.dat": KRL_DAT_SEED}), Case({"fuzz.src": KRL_SRC_SEED})]
    out += [Case({n: (KRL_DATA / n).read_bytes() for n in names}) for names in _KRL_FIXTURES
            if all((KRL_DATA / n).is_file() for n in names)]
    return out + _exported_krl()


@functools.cache
def _exported_krl() -> list[Case]:
    """The KRL the exporter writes for the plan seeds, one page and (page_lines 100) paged."""
    from planner.export import plan_to_krl
    from planner.plan_file import load_plan
    from robot_io.krl.writer import render_krl

    out = []
    with tempfile.TemporaryDirectory(prefix="cctmill-fuzz-") as tmp:
        for k, seed in enumerate(_plan_seeds()):
            folder = Path(tmp) / str(k)
            seed.write(folder)
            prog = plan_to_krl(load_plan(folder))
            for spec in (prog.spec, replace(prog.spec, page_lines=100)):
                files = render_krl(spec, prog.sections, prog.moves, prog.notes).files
                main = f"{spec.name}.src"
                out.append(Case({main: files[main].encode(),
                                 **{n: v.encode() for n, v in files.items() if n != main}}))
    return out


def _krl_strategy(seeds: Sequence[Case], whole: bool) -> st.SearchStrategy[Case]:
    return cases(seeds, {".src": KRL, ".dat": KRL_DAT, "*": KRL}, st.just({}), _krl_generated(), whole,
                 files_edits="companions")


@st.composite
def _krl_generated(draw: Any) -> Case:
    src = (b"DEF fuzz( )\n$VEL.CP=0.001\nPTP {X 0,Y 0,Z 10,A 0,B 90,C 0}\n"
           + b"\n".join(draw(st.lists(KRL_LINE, min_size=1, max_size=30))) + b"\nEND\n")
    dat = b"DEFDAT fuzz\n" + b"\n".join(draw(st.lists(KRL_DAT_LINE, max_size=10))) + b"\nENDDAT\n"
    return Case({"fuzz.src": src, "fuzz.dat": dat} if draw(st.booleans()) else {"fuzz.src": src})


# -- job and plan files ------------------------------------------------------------------------------

TOML_TOKENS = (b"[", b"]", b"[[", b"]]", b"=", b"\"", b"'", b"'''", b'"""', b"{", b"}", b",", b"#", b".",
               b"true", b"false", b"inf", b"nan", b"1979-05-27T07:32:00Z", b"2023-02-30", b"0x1F", b"0o7",
               b"1_000", b"\\u0000", b"\\", b"\xe9", b"[job]", b"[cell]", b"[limits]", b"[engagement.stock]",
               b"toolpath = ", b"source = ", b"box_mm = ", b"outline_mm = ", b"strict = ", b"rotary = ")
JOB = Dialect(alphabet=b"[]{}\"=.,#\n0123456789aeEnf -_'", tokens=TOML_TOKENS,
              values=json_values().map(render_toml), head_lines=0, window_lines=10_000)


def _job_seeds() -> list[Case]:
    demo = (DEMO / "demo_job.toml").read_bytes()
    stock = b"[engagement.stock]\nbox_mm = [-3.0, -3.0, 203.0, 123.0]\nz_bottom_mm = -40.0\nz_top_mm = 0.0\n"
    fixed = demo.replace(stock, b"").replace(b'source = "zmap"',
                                             b'source = "fixed"\nae_mm = 5.0\nap_mm = 10.0')
    outline = demo.replace(b"box_mm = [-3.0, -3.0, 203.0, 123.0]",
                           b"outline_mm = [[-3.0, -3.0], [203.0, -3.0], [203.0, 123.0], [-3.0, 123.0]]")
    minimal = (b'[job]\ntoolpath = ["part.nc"]\nunits = "inch"\n\n[engagement]\nap_mm = 2.0\n'
               b'milling = "slot"\n\n[kinematics]\nseed_joints_deg = [0, -90, 90, 0, 45, 0]\n')
    return [Case({"job.toml": t}) for t in (demo, fixed, outline, minimal)]


def _job_calls(case: Case, folder: Path) -> list[Call]:
    from planner.job import JobError, load_job

    path = folder / "job.toml"

    def load(_: Any) -> tuple[str, Any]:
        return "Job", load_job(path)

    def use(job: Any) -> tuple[str, Any]:
        job.to_si()
        job.job.reader_options()
        job.toolpath_files()
        return "JobSI", None

    def ok(e: BaseException) -> str | None:
        assert isinstance(e, JobError)
        return None if e.file == str(path) and str(e).startswith(f"{path}: ") else "does not name the file"

    return [Call("load", load, (JobError,), ok), Call("to_si", use, (), None, needs_previous=True)]


def _job_strategy(seeds: Sequence[Case], whole: bool) -> st.SearchStrategy[Case]:
    return cases(seeds, {"*": JOB}, None, None, whole)


#: The demo job's first side of the contour: a plan of a few sections, planned in a second.
_SHORT_PROGRAM_LINES = 17


@functools.cache
def _plan_seeds() -> tuple[Case, ...]:
    """Two small plans (constant and optimised feeds) of the demo job cut to its first contour
    side, as ``cctmill plan`` saves them (planned here, so always in the current format)."""
    from planner.job import load_job
    from planner.plan import plan_prepared
    from planner.plan_file import Plan
    from planner.prepare import prepare

    out = []
    with tempfile.TemporaryDirectory(prefix="cctmill-fuzz-") as tmp:
        job = Path(tmp) / "demo_job.toml"
        job.write_bytes((DEMO / "demo_job.toml").read_bytes())
        lines = (DEMO / "bracket_contour.nc").read_bytes().splitlines(keepends=True)
        (Path(tmp) / "bracket_contour.nc").write_bytes(b"".join(lines[:_SHORT_PROGRAM_LINES])
                                                       + b"N160 G0 Z10.\nN170 M30\n%\n")
        prepared = prepare(load_job(job))
        for method in ("constant", "optimize"):
            folder = Path(tmp) / method
            Plan.from_result(plan_prepared(prepared, method)).save(folder)
            out.append(Case({n: (folder / n).read_bytes() for n in ("plan.json", "samples.npz")}))
    return tuple(out)


def _npz_edit(draw: Any, data: bytes, ctx: Any) -> bytes:
    """One array of a readable ``samples.npz`` dropped, cut, grown, retyped, reshaped or filled
    with non-finite or huge values, and the table saved again."""
    try:
        with np.load(io.BytesIO(data), allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
    except Exception:   # already damaged: a byte edit instead
        return data[:-1]
    if not arrays:
        return data
    name = draw(st.sampled_from(sorted(arrays)))
    a = arrays[name]
    how = draw(st.integers(0, 7))
    if how == 0:
        del arrays[name]
    elif how == 1:
        arrays[name] = a[:max(0, a.shape[0] - 1)] if a.ndim else a
    elif how == 2:
        arrays[name] = np.concatenate([a, a[:1]]) if a.ndim and a.shape[0] else a
    elif how == 3:
        kind = draw(st.sampled_from(["complex128", "U3", "bool", "int8", "float16", "uint64",
                                     "datetime64[s]"]))
        with np.errstate(all="ignore"), warnings.catch_warnings():  # the input, not the test
            warnings.simplefilter("ignore")
            arrays[name] = a.astype(kind)
    elif how == 4:
        arrays[name] = a.reshape(-1) if a.ndim > 1 else a.reshape(-1, 1)
    elif how == 5:
        arrays[name] = np.full(a.shape, draw(st.sampled_from([np.nan, np.inf, -np.inf, 1e308, -1.0,
                                                              2.0**63])))
    elif how == 6:
        arrays[name] = np.float64(1.0)
    else:
        arrays[draw(st.sampled_from(["extra", name + "_", ""]))] = a
    try:
        return npz_bytes(arrays, compressed=draw(st.booleans()))
    except (ValueError, TypeError):
        return data


JSON_TOKENS = (b"{", b"}", b"[", b"]", b":", b",", b"\"", b"null", b"true", b"false", b"NaN", b"Infinity",
               b"-Infinity", b"1e400", b"\\u0000", b"\\ud800", b"\"format\"", b"\"version\"",
               b"\"sections\"", b"\"samples_file\"", b"\"characteristic\"", b"\"feed_mm_s\"", b"[" * 40)
PLAN_JSON = Dialect(alphabet=b"[]{}\",:0123456789.-eE nul\n", tokens=JSON_TOKENS,
                    values=json_values().map(render_json), weight=4, head_lines=60, window_lines=100_000)
PLAN_NPZ = Dialect(text=False, tokens=(b"PK\x03\x04", b"\x93NUMPY", b"\x80\x04"), ops=(_npz_edit,) * 4,
                   max_bytes=1 << 20)


def _plan_calls(case: Case, folder: Path) -> list[Call]:
    from planner.export import plan_to_krl
    from planner.plan_file import PlanFileError, load_plan
    from robot_io.krl.writer import render_krl

    def load(_: Any) -> tuple[str, Any]:
        plan = load_plan(folder)
        return f"Plan sections={bool(plan.sections)}", plan

    def export(plan: Any) -> tuple[str, Any]:
        prog = plan_to_krl(plan)
        out = render_krl(prog.spec, prog.sections, prog.moves, prog.notes)
        return f"KRL pages={bool(out.pages)}", None

    def ok(e: BaseException) -> str | None:
        return None if str(e).startswith(str(folder)) and "\n" not in str(e) else "does not name the file"

    return [Call("load", load, (PlanFileError,), ok),
            Call("export", export, (CctmillError,), None, needs_previous=True)]


def _plan_strategy(seeds: Sequence[Case], whole: bool) -> st.SearchStrategy[Case]:
    return cases(seeds, {".json": PLAN_JSON, ".npz": PLAN_NPZ}, None, None, whole)


# -- wires ---------------------------------------------------------------------------------------------

_U16 = struct.Struct("!H")


def _kvp_seeds() -> list[Case]:
    frames = [pack_request(KvpRequest(7, FN_READ, "$OV_PRO")),
              pack_request(KvpRequest(8, FN_WRITE, "$OV_PRO", "55")),
              pack_request(KvpRequest(65535, FN_READ, "PING")),
              pack_request(KvpRequest(1, FN_WRITE, "$POS_ACT", "{E6POS: X 1.0,Y 2.0,Z 3.0}")),
              pack_reply(7, FN_READ, "100", True, True), pack_reply(7, FN_READ, "100", True, False),
              pack_reply(9, FN_READ, None, False, True), pack_reply(3, FN_WRITE, "PONG", True, False),
              _U16.pack(5) + _U16.pack(8) + bytes([FN_READ]) + _U16.pack(2) + b"ab" + b"\x00\x01\x00"]
    return [Case({"frame.bin": f}) for f in frames]


@st.composite
def _kvp_generated(draw: Any) -> Case:
    def u16(n: int) -> bytes:
        return _U16.pack(n % 65536)

    fn = draw(st.sampled_from([0, 1, 2, 3, 4, 255]))
    name = draw(st.sampled_from([b"$OV_PRO", b"PING", b"", b"\xff", b"$X" * 100, b"A" * 5000])
                | st.binary(max_size=30))
    value = draw(st.none() | st.binary(max_size=40)
                 | st.sampled_from([b"100", b"PONG", b"\x00", b"7" * 5000]))
    delta = st.sampled_from([0, 0, 0, 0, -1, 1, -3, 3, 6, 65535])
    if draw(st.booleans()):   # a request
        body = bytes([fn]) + u16(len(name) + draw(delta)) + name
        if value is not None:
            body += u16(len(value) + draw(delta)) + value
    else:                     # a reply
        v = value or b""
        body = (bytes([fn]) + u16(len(v) + draw(delta)) + v + b"\x00\x01"
                + bytes([draw(st.sampled_from([0, 1, 2, 255]))]))
        body = body[:len(body) - draw(st.sampled_from([0, 0, 0, 3]))] if draw(st.booleans()) else body
    frame = u16(draw(st.integers(0, 65535))) + u16(len(body) + draw(delta)) + body
    return Case({"frame.bin": frame})


def _kvp_calls(case: Case, folder: Path) -> list[Call]:
    frame = next(iter(case.files.values()))

    def request(_: Any) -> tuple[str, Any]:
        req = parse_request(frame)
        # the packer refuses bodies over MAX_BODY_BYTES (the server closes before parsing them)
        if req.function in (FN_READ, FN_WRITE) and len(frame) - 4 <= MAX_BODY_BYTES \
                and pack_request(req) != frame:
            raise BadResult(f"{req} packs to other bytes than it was parsed from")
        return f"request fn={req.function}", None

    def reply(_: Any) -> tuple[str, Any]:
        rep = parse_reply(frame)
        if rep.ok and pack_reply(rep.msg_id, rep.function, rep.value, True, rep.trailer_counted) != frame:
            raise BadResult(f"{rep} packs to other bytes than it was parsed from")
        return f"reply ok={rep.ok}", None

    def stream(_: Any) -> tuple[str, Any]:
        a, b = socket.socketpair()
        try:
            a.settimeout(1.0)
            b.sendall(frame)
            b.shutdown(socket.SHUT_WR)
            rep = read_reply(a)
        finally:
            a.close()
            b.close()
        return f"read ok={rep.ok}", None

    return [Call("parse_request", request, (ProtocolError,)), Call("parse_reply", reply, (ProtocolError,)),
            Call("read_reply", stream, (ProtocolError, OSError))]


KVP = Dialect(text=False, tokens=(b"\x00\x01\x01", b"\x00\x01\x00", b"$OV_PRO", b"PING", b"\xff\xff"),
              max_bytes=16 * 1024)


def _kvp_strategy(seeds: Sequence[Case], whole: bool) -> st.SearchStrategy[Case]:
    return cases(seeds, {"*": KVP}, None, _kvp_generated(), whole)


def _rsi_seeds() -> list[Case]:
    packets = [build_rob(1_000_000, (1368.8, 5.2, 876.6, 0.0, 90.0, 0.0), (0, -90, 90, 0, 45, 0), 0, 100),
               build_rob(18446744073709551615, None, None, None, None, "TYPE", dat=True),
               build_rob(5, (1e5, -1e5, 0.5, 360, -360, 0), None, 3, 0, precision=9),
               build_sen("1000000", 80), build_sen("1", None, correction="AKorr", dat=True, estr="<&>"),
               build_sen("42", -5, sentype="X", override_tag="OvPro", correction=None),
               b'<?xml version="1.0" encoding="ISO-8859-1"?>' + build_rob(7, None, None, 0, 50),
               b"<Rob Type='KUKA'><RIst X='1' Y='2' Z='3' A='4' B='5' C='6'></RIst>"
               b"<IPOC> 9 </IPOC></Rob>"]
    return [Case({"packet.xml": p}) for p in packets]


_RSI_TAGS = ["RIst", "RSol", "AIPos", "ASPos", "Delay", "RKorr", "AKorr", "Tech", "Dat", "OvPro", "OvProW",
             "IPOC", "EStr", "Digout", "x"]


@st.composite
def _rsi_generated(draw: Any) -> Case:
    def text(s: st.SearchStrategy[bytes]) -> str:
        return draw(s).decode("utf-8", "replace").replace("&", "&amp;").replace("<", "&lt;").replace('"', "")

    parts = []
    for _ in range(draw(st.integers(0, 8))):
        tag = draw(st.sampled_from(_RSI_TAGS))
        keys = st.sampled_from(["X", "A1", "D", "C", "TaskType", "x-y"])
        attrs = " ".join(f'{draw(keys)}="{text(numbers())}"' for _ in range(draw(st.integers(0, 4))))
        body = text(numbers() | st.sampled_from([b"", b"18446744073709551616", b"1 2", b"-1", b"9" * 30]))
        empty = attrs and draw(st.booleans())
        parts.append(f"<{tag} {attrs}/>" if empty else f"<{tag} {attrs}>{body}</{tag}>")
    ipoc = text(st.sampled_from([b"0", b"18446744073709551615", b"18446744073709551616", b"-1", b" 5 ",
                                 b"", b"\xd9\xa1"]))
    if draw(st.booleans()):
        parts.append(f"<IPOC>{ipoc}</IPOC>")
    root = draw(st.sampled_from(["Rob", "Sen", "rob", "SEN", "Dat", "x"]))
    decl = draw(st.sampled_from(["", '<?xml version="1.0"?>', '<?xml version="1.0" encoding="utf-16"?>',
                                 '<?xml version="1.0" encoding="latin-1"?>', '<?xml version="1.1"?>']))
    xml = f'{decl}<{root} Type="KUKA">{"".join(parts)}</{root}>'
    return Case({"packet.xml": xml.encode("utf-16" if "utf-16" in decl else "utf-8")})


def _rsi_calls(case: Case, folder: Path) -> list[Call]:
    data = next(iter(case.files.values()))

    def rob(_: Any) -> tuple[str, Any]:
        t = parse_rob(data)
        _ = (t.rist, t.aipos, t.delay, t.ov_pro)
        if parse_sen(build_sen(t.ipoc_text, 50)).ipoc != t.ipoc:
            raise BadResult(f"the reply echoing IPOC {t.ipoc_text!r} parses to another IPOC")
        return f"Rob poses={sorted(t.poses)[:4]} dat={t.dat}", None

    def sen(_: Any) -> tuple[str, Any]:
        t = parse_sen(data)
        return f"Sen override={t.override is not None} corrections={sorted(t.corrections)[:3]}", None

    return [Call("parse_rob", rob, (ProtocolError,)), Call("parse_sen", sen, (ProtocolError,))]


RSI = Dialect(alphabet=b'<>/="&;![]- ?abcdefgKLMNOPRSTXYZ0123456789.\x00\xff',
              tokens=(b"<IPOC>", b"</IPOC>", b"&amp;", b"&lol;", b"&#0;", b"&#x10FFFF;", b"<!DOCTYPE Rob>",
                      b'<!ENTITY a "x">', b"<![CDATA[1]]>", b"<?pi x?>", b"<!-- c -->", b'<Dat TaskType="b">',
                      b"</Dat>", b' X="nan"', b' X="1e999"', b' D="1e308"', b"<a>" * 40, b"\xef\xbb\xbf",
                      b'<?xml version="1.0" encoding="UTF-1"?>', b'encoding="utf-16"'),
              max_bytes=8 * 1024)


def _rsi_strategy(seeds: Sequence[Case], whole: bool) -> st.SearchStrategy[Case]:
    return cases(seeds, {"*": RSI}, None, _rsi_generated(), whole)


def _udp_seeds() -> list[Case]:
    rng = np.random.default_rng(22)
    steady = [pack_samples(1000 + k, 10.0 + k * 0.016, 1000.0, rng.normal(size=16)) for k in range(6)]
    restart = steady[:3] + [pack_samples(0, 0.0, 1000.0, np.ones(4)),
                            pack_samples(1, 0.004, 1000.0, np.ones(4))]
    late = [steady[0], steady[2], steady[1], steady[2], steady[3]]
    wrap = [pack_samples(2**32 - 2 + k, 5.0 + k * 1e-3, 1000.0, np.ones(1)) for k in range(4)]
    return [Case({f"{k:03d}.bin": d for k, d in enumerate(stream)})
            for stream in (steady, restart, late, wrap)]


@st.composite
def _udp_generated(draw: Any) -> Case:
    seq = draw(st.sampled_from([0, 1, 2**31, 2**32 - 1, 2**32 - 3]))
    t = draw(st.sampled_from([0.0, 1.0, 1e9, 1e300, -1.0, 5e-324]))
    fs = draw(st.sampled_from([1000.0, 1e4, 1e-30, 3e38, 1.0, 0.001]))
    out = {}
    for k in range(draw(st.integers(1, 12))):
        seq = (seq + draw(st.sampled_from([1, 1, 1, 0, 2, -1, -100, 70_000, 2**31, 2**32 - 1]))) % 2**32
        count = draw(st.sampled_from([1, 2, 10, 4096]))
        t += draw(st.sampled_from([count / fs, 0.0, -1.0, 1e-9, 1e10, math.nan]))
        values = np.full(count, draw(st.sampled_from([0.0, 1.0, np.nan, np.inf, -3e38])), "<f4")
        out[f"{k:03d}.bin"] = HEADER.pack(MAGIC, seq, t, fs, count) + values.tobytes()
    return Case(out)


def _udp_calls(case: Case, folder: Path) -> list[Call]:
    datagrams = list(case.files.values())

    def parse(_: Any) -> tuple[str, Any]:
        ok = 0
        for d in datagrams:
            p = parse_samples(d)
            if p is not None:
                seq, t0, fs, values = p
                if not (math.isfinite(t0) and math.isfinite(fs) and fs > 0 and values.dtype == np.float64
                        and values.shape == ((len(d) - HEADER.size) // 4,)):
                    raise BadResult(f"parsed as seq {seq}, t0 {t0}, fs {fs}, {values.shape} {values.dtype}")
                ok += 1
        return f"parsed {ok == len(datagrams)}", None

    def stream(_: Any) -> tuple[str, Any]:
        with UdpSignalSource(clock=lambda: 0.0) as src:
            for d in datagrams:
                src._accept(d)   # the receive step of read(), without the socket's timing
            last, n = -math.inf, 0
            while True:
                chunk = src.read(1000)
                if not len(chunk):
                    break
                t = chunk.t_s
                if t.shape != chunk.values.shape or not np.all(np.isfinite(t)) or not np.all(np.diff(t) > 0) \
                        or not t[0] > last:
                    raise BadResult(f"chunk times {t[:3]}… after {last}: not finite and increasing")
                last, n = float(t[-1]), n + t.size
            s = src.stats
        counted = s.packets + s.malformed + s.out_of_order
        if counted != len(datagrams) or min(s.lost, s.resyncs, s.backward_samples) < 0 \
                or s.lost > MAX_LOSS_GAP * len(datagrams) or n != s.samples:
            raise BadResult(f"{len(datagrams)} datagrams, {n} samples read, counted as {s}")
        return f"stream resyncs={bool(s.resyncs)} rebases={bool(s.rebases)} lost={bool(s.lost)}", None

    return [Call("parse_samples", parse), Call("stream", stream)]


UDP = Dialect(text=False, tokens=(MAGIC, b"CCTs", b"\x00" * 22), max_bytes=20 * 1024)


def _udp_strategy(seeds: Sequence[Case], whole: bool) -> st.SearchStrategy[Case]:
    return cases(seeds, {"*": UDP}, None, _udp_generated(), whole, files_edits="stream")


# -- recorded signals ------------------------------------------------------------------------------------

def _signal_seeds() -> list[Case]:
    rng = np.random.default_rng(22)
    t = np.arange(200) / 1000.0
    v = np.sin(2 * np.pi * 50 * t) + 0.1 * rng.normal(size=t.size)

    def npy(a: np.ndarray) -> bytes:
        buf = io.BytesIO()
        np.save(buf, a, allow_pickle=False)
        return buf.getvalue()

    two = "t_s,force_N\n" + "".join(f"{a:.6f},{b:.6f}\n" for a, b in zip(t, v, strict=True))
    one = "# force only\nvalue\n" + "".join(f"{b:.4f}\n" for b in v[:50])
    three = "time,fx,fy\n" + "".join(f"{a},{b},{-b}\r\n" for a, b in zip(t[:40], v[:40], strict=True))
    files = [("signal.csv", two.encode()), ("signal.csv", one.encode()), ("signal.csv", three.encode()),
             ("signal.npy", npy(v)), ("signal.npy", npy(np.column_stack([t, v]))),
             ("signal.npy", npy(v.astype("<i2")))]
    return [Case({name: data}, {"fs_hz": 1000.0, "column": None}) for name, data in files]


SIGNAL_OPTIONS = st.fixed_dictionaries({
    "fs_hz": st.sampled_from([None, None, 1000.0, 0.0, -5.0, math.nan, math.inf, 1e-300, 5e-324]),
    "column": st.sampled_from([None, None, None, "force_N", "fy", "t_s", "nope", ""]),
})
SIGNAL_CSV = Dialect(alphabet=b"0123456789.,-+eE;\"#\n\r tnaif", head_lines=3, window_lines=100,
                     tokens=(b",", b";", b"\"", b"#", b"t_s", b"time", b"force", b"nan", b"inf", b"\r",
                             b"\x00", b"\xef\xbb\xbf", b",,,", b"\"a,b\"", b"x" * 140_000),
                     max_bytes=512 * 1024)
SIGNAL_NPY = Dialect(text=False, tokens=(b"PK\x03\x04", b"\x80\x04", b"\x93NUMPY\x01\x00",
                                         b"\x93NUMPY\x03\x00", b"'descr': '|O'", b"'descr': '<c16'",
                                         b"'shape': (10, 3)", b"'shape': (99999999999,)",
                                         b"'fortran_order': True"),
                     max_bytes=64 * 1024)


def _signal_calls(case: Case, folder: Path) -> list[Call]:
    path = folder / next(iter(case.files))
    fs_hz, column = case.options.get("fs_hz"), case.options.get("column")

    def load(_: Any) -> tuple[str, Any]:
        t, v = load_signal(path, fs_hz, column)
        if t.shape != v.shape or t.ndim != 1 or t.size < 2 or not (np.all(np.isfinite(t))
                                                                    and np.all(np.diff(t) > 0)):
            raise BadResult(f"times {t[:3]}… of shape {t.shape}, values {v.shape}: not finite and increasing")
        src = ReplaySource(t, v)
        while src.read(64).status != "end":
            pass
        return f"signal {path.suffix}", None

    def ok(e: BaseException) -> str | None:
        assert isinstance(e, SignalFileError)
        return None if e.file == str(path) else f"names {e.file!r}"

    return [Call("load", load, (SignalFileError,), ok)]


def _signal_strategy(seeds: Sequence[Case], whole: bool) -> st.SearchStrategy[Case]:
    return cases(seeds, {".csv": SIGNAL_CSV, ".npy": SIGNAL_NPY}, SIGNAL_OPTIONS, None, whole)


TARGETS: dict[str, Target] = {t.name: t for t in (
    Target("gcode", "read_toolpath (strict, lenient) → a finite toolpath or a ToolpathError naming the file",
           functools.cache(_gcode_seeds), _gcode_strategy, _reader_calls),
    Target("apt", "read_toolpath (strict, lenient) → a finite toolpath or a ToolpathError naming the file",
           functools.cache(_apt_seeds), _apt_strategy, _reader_calls),
    Target("krl", "read_toolpath of .src (+ .dat, pages) → a finite toolpath or a ToolpathError",
           functools.cache(_krl_seeds), _krl_strategy, _reader_calls),
    Target("job", "load_job → a Job that converts to SI, or a JobError naming the file",
           functools.cache(_job_seeds), _job_strategy, _job_calls),
    Target("plan", "load_plan → a Plan the KRL exporter takes or refuses, or a PlanFileError naming the file",
           lambda: list(_plan_seeds()), _plan_strategy, _plan_calls),
    Target("kvp", "parse_request / parse_reply / read_reply → a frame that repacks to itself, or "
           "ProtocolError",
           functools.cache(_kvp_seeds), _kvp_strategy, _kvp_calls),
    Target("rsi", "parse_rob / parse_sen → a telegram (its IPOC echo parses back), or ProtocolError",
           functools.cache(_rsi_seeds), _rsi_strategy, _rsi_calls),
    Target("udp", "parse_samples and the receive step → increasing finite times, every datagram counted once",
           functools.cache(_udp_seeds), _udp_strategy, _udp_calls),
    Target("signal", "load_signal + replay → finite increasing times, or a SignalFileError naming the file",
           functools.cache(_signal_seeds), _signal_strategy, _signal_calls),
)}
