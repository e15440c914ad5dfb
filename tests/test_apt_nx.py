"""NX CLSF conventions of the APT/CL reader: the CIRCLE direction (clockwise about i,j,k, whatever
the MSYS), the SolidWorks CAM reading kept as it was, the undecided mixes refused, and NX's
drilling-cycle forms (``DRILL,DEEP``, ``FEDTO`` ≤ 0, ``RTRCTO,AUTO``).

The programs are small hand-written files in the form of the NX samples the evidence comes from
(robot_io.apt.reader's docstring): ``MSYS``, 11-field CIRCLEs, the GOTO after each CIRCLE."""

from __future__ import annotations

import math

import numpy as np
import pytest

from models.errors import InputError
from robot_io.apt import read_apt_text
from robot_io.options import speaking
from robot_io.toolpath import MoveKind, ToolpathError, arc_geometry

MM = 1e-3
NX_HEAD = ("TOOL PATH/CONTOUR,TOOL,MILL_20\nTLDATA/MILL,20.0000,0.0000,50.0000,0.0000,0.0000\n"
           "{msys}\n$$ centerline data\nPAINT/PATH\nRAPID\n{start}\nFEDRAT/MMPM,500.0000\n")
#: MCS x = world Y, y = world X: its z (x × y) is world −Z, as in the z-flipped NX samples.
MSYS_FLIPPED = "MSYS/10.0000,20.0000,3.0000,0.0000000,1.0000000,0.0000000,1.0000000,0.0000000,0.0000000"
MSYS_IDENTITY = "MSYS/0.0000,0.0000,0.0000,1.0000000,0.0000000,0.0000000,0.0000000,1.0000000,0.0000000"


def _nx(msys: str, start: str, body: str) -> str:
    return NX_HEAD.format(msys=msys, start=start) + body + "END-OF-PATH\n"


def _joins(tp) -> list[float]:
    """Angle [deg] between each arc's end tangents and the straight moves before and after it."""
    out = []
    moves = tp.moves
    for i, m in enumerate(moves):
        if not m.is_arc:
            continue
        g = arc_geometry(m)
        sgn = math.copysign(1.0, g["sweep"])
        t0 = sgn * g["v"]
        t1 = sgn * (-math.sin(g["sweep"]) * g["u"] + math.cos(g["sweep"]) * g["v"])
        for other, t in ((moves[i - 1], t0), (moves[i + 1], t1)):
            d = other.end - other.start
            c = float(np.dot(d / np.linalg.norm(d), t))
            out.append(math.degrees(math.acos(max(-1.0, min(1.0, c)))))
    return out


# --------------------------------------------------------------------------- CIRCLE direction
def test_nx_arc_under_z_flipped_msys_is_clockwise_about_its_axis() -> None:
    # heading +X below the centre, then a left turn to +Y: counter-clockwise seen from +Z, which
    # NX writes as axis (0,0,−1) (clockwise about it) — the MSYS z is world −Z here
    text = _nx(MSYS_FLIPPED, "GOTO/0.0000,-10.0000,0.0000,0.0000000,0.0000000,1.0000000",
               "GOTO/10.0000,-10.0000,0.0000\n"
               "CIRCLE/10.0000,0.0000,0.0000,0.0000000,0.0000000,-1.0000000,10.0000,0.0600,"
               "0.5000,20.0000,0.0000\nGOTO/20.0000,0.0000,0.0000\nGOTO/20.0000,10.0000,0.0000\n")
    tp = read_apt_text(text)
    arc = tp.moves[2]
    assert arc.kind == MoveKind.ARC_CCW   # about +Z (the tool axis)
    assert math.degrees(arc_geometry(arc)["sweep"]) == pytest.approx(90)
    assert arc.length == pytest.approx(math.pi * 10 / 2 * MM, rel=1e-12)
    assert max(_joins(tp)) < 1e-9
    assert tp.meta["circle_directions"] == {"cw": 1}
    # the old reading (counter-clockwise about i,j,k) is still there on request: 270°, kinked
    old = read_apt_text(text, circle_direction="ccw")
    assert math.degrees(arc_geometry(old.moves[2])["sweep"]) == pytest.approx(-270)
    assert min(_joins(old)) == pytest.approx(180)


def test_nx_arc_under_identity_msys_is_clockwise_about_its_axis() -> None:
    # heading +Y on the left, a right turn to +X over the top: clockwise seen from +Z, written
    # with axis (0,0,1) under an identity MSYS (the WEDM sample's case: an MSYS-frame rule that
    # reads the axis in another frame would leave it unchanged here and turn the wrong way)
    text = _nx(MSYS_IDENTITY, "GOTO/-10.0000,-10.0000,0.0000,0.0000000,0.0000000,1.0000000",
               "GOTO/-10.0000,0.0000,0.0000\n"
               "CIRCLE/0.0000,0.0000,0.0000,0.0000000,0.0000000,1.0000000,10.0000,0.0600,"
               "0.5000,20.0000,0.0000\nGOTO/0.0000,10.0000,0.0000\nGOTO/10.0000,10.0000,0.0000\n")
    tp = read_apt_text(text)
    arc = tp.moves[2]
    assert arc.kind == MoveKind.ARC_CW
    assert math.degrees(arc_geometry(arc)["sweep"]) == pytest.approx(-90)
    assert max(_joins(tp)) < 1e-9
    # apply_frames turns centre and axis alike: the direction does not change
    moved = read_apt_text(text, apply_frames=True)
    assert moved.moves[2].kind == MoveKind.ARC_CW
    assert max(_joins(moved)) < 1e-9


def test_solidworks_csys_arcs_stay_counter_clockwise_about_their_axis() -> None:
    pre = "UNITS/MM\nFEDRAT/600,MMPM\nRAPID\nGOTO/0,-10,0\n"
    # 6 fields under a CSYS: counter-clockwise about i,j,k, as before
    tp = read_apt_text(pre + "CSYS/1.,0,0,0,0,1.,0,0,0,0,1.,0\nGOTO/10,-10,0\n"
                       "CIRCLE/10,0,0,0,0,1\nGOTO/20,0,0\nGOTO/20,10,0")
    assert tp.moves[2].kind == MoveKind.ARC_CCW and max(_joins(tp)) < 1e-9
    assert tp.meta["circle_directions"] == {"ccw": 1}
    # the flipped side (CSYS z = −Z, axis 0,0,−1): clockwise seen from +Z, as before
    tp = read_apt_text(pre + "GOTO/20,-10,0\nCSYS/1.,0,0,0,0,-1.,0,0,0,0,-1.,0\nGOTO/10,-10,0\n"
                       "CIRCLE/10,0,0,0,0,-1\nGOTO/0,0,0\nGOTO/0,10,0")
    arc = tp.moves[3]   # stored about the tool axis −Z: counter-clockwise about it
    assert arc.kind == MoveKind.ARC_CCW and list(arc.normal) == [0, 0, -1]
    assert math.degrees(arc_geometry(arc)["sweep"]) == pytest.approx(90)
    assert max(_joins(tp)) < 1e-9


@pytest.mark.parametrize(("frame", "circle", "layout"), [
    (MSYS_IDENTITY, "CIRCLE/0,0,0,0,0,1", "6-field layout is SolidWorks CAM's"),
    ("CSYS/1.,0,0,0,0,1.,0,0,0,0,1.,0", "CIRCLE/0,0,0,0,0,1,10,0.06,0.5,20,0",
     "11-field layout is NX's"),
])
def test_undecided_circle_layouts_are_refused(frame: str, circle: str, layout: str) -> None:
    text = ("UNITS/MM\n" + frame + "\nFEDRAT/600,MMPM\nRAPID\nGOTO/-10,0,0\n" + circle
            + "\nGOTO/0,10,0\nGOTO/10,10,0\n")
    with pytest.raises(ToolpathError, match=rf"6:\d+: CIRCLE with \d+ fields after the "
                       rf"(MSYS|CSYS) at line 2: the {layout}.*no sample shows which way.*"
                       r"circle_direction='ccw' or circle_direction='cw'"):
        read_apt_text(text)
    with speaking("cli"), pytest.raises(ToolpathError, match=r"--circle-direction cw\).*"
                                        r"--lenient"):
        read_apt_text(text)
    tp = read_apt_text(text, strict=False)   # lenient: the CIRCLE is skipped, its GOTO a line
    assert tp.skipped == {"circle_direction_unknown": 1}
    assert [m.kind for m in tp.moves] == [MoveKind.RAPID, MoveKind.LINEAR, MoveKind.LINEAR]
    for rule, kind in (("cw", MoveKind.ARC_CW), ("ccw", MoveKind.ARC_CCW)):
        assert read_apt_text(text, circle_direction=rule).moves[1].kind == kind


def test_circle_direction_option_is_checked() -> None:
    with pytest.raises(InputError, match="circle_direction.*'auto', 'ccw', 'cw'"):
        read_apt_text("UNITS/MM\n", circle_direction="clockwise")


# --------------------------------------------------------------------------- NX drilling cycles
DRILL = ("TOOL PATH/DRILLING,TOOL,DRILL_8\nTLDATA/MILL,8.0000,0.0000,30.0000,0.0000,0.0000\n"
         + MSYS_IDENTITY + "\n$$ centerline data\nPAINT/PATH\n{cycle}\n"
         "GOTO/10.0000,0.0000,20.0000,0.0000000,0.0000000,1.0000000\n"
         "GOTO/-10.0000,0.0000,20.0000\nCYCLE/OFF\nEND-OF-PATH\n")


def _holes(tp) -> list[tuple[str, list[float]]]:
    return [(m.kind.value, [round(float(v) / MM, 9) for v in m.end]) for m in tp.moves]


@pytest.mark.parametrize("sub", ["DEEP", "BRKCHP"])
def test_nx_drill_subtype_after_drill(sub: str) -> None:
    tp = read_apt_text(DRILL.format(cycle=f"CYCLE/DRILL,{sub},RAPTO,3.0000,FEDTO,-5.0000,"
                                          "MMPM,250.0000"), default_units="mm")
    assert tp.meta["cycles"][0]["type"] == sub and tp.meta["cycles"][0]["holes"] == 2
    assert tp.meta["cycles"][0]["depth_m"] == pytest.approx(5 * MM)
    assert tp.meta["cycles"][0]["fedto_m"] == pytest.approx(-5 * MM)
    assert {m.extra["cycle"] for m in tp.moves} == {sub}
    # NX's negative FEDTO (an offset along the tool axis) is the same hole as a positive depth
    same = read_apt_text(DRILL.format(cycle=f"CYCLE/{sub},FEDTO,5,RAPTO,3,MMPM,250"),
                         default_units="mm")
    assert _holes(tp) == _holes(same)
    assert _holes(tp)[:3] == [("rapid", [10, 0, 23]), ("linear", [10, 0, 15]),
                              ("rapid", [10, 0, 23])]


def test_nx_zero_depth_drill_feeds_from_rapto_to_the_hole_point() -> None:
    # "standart drill.clsf": CYCLE/DRILL,RAPTO,3,FEDTO,0,MMPM,250 — a feed of RAPTO length
    tp = read_apt_text(DRILL.format(cycle="CYCLE/DRILL,RAPTO,3.0000,FEDTO,0.0000,MMPM,250.0000"),
                       default_units="mm")
    assert _holes(tp) == [("rapid", [10, 0, 23]), ("linear", [10, 0, 20]),
                          ("rapid", [10, 0, 23]), ("rapid", [-10, 0, 23]),
                          ("linear", [-10, 0, 20]), ("rapid", [-10, 0, 23])]
    assert tp.moves[1].feed == pytest.approx(250 * MM / 60)
    assert tp.meta["warning_counts"].get("zero_depth_cycle") == 1


def test_nx_retract_modes() -> None:
    auto = read_apt_text(DRILL.format(cycle="CYCLE/DRILL,RAPTO,3.0000,FEDTO,-5.0000,RTRCTO,AUTO,"
                                            "MMPM,250.0000"), default_units="mm")
    plain = read_apt_text(DRILL.format(cycle="CYCLE/DRILL,RAPTO,3,FEDTO,-5,MMPM,250"),
                          default_units="mm")
    assert _holes(auto) == _holes(plain)   # AUTO: back to the RAPTO point
    manual = read_apt_text(DRILL.format(cycle="CYCLE/DRILL,RAPTO,3.0000,FEDTO,-5.0000,RTRCTO,"
                                              "10.0000,MANUAL,MMPM,250.0000"), default_units="mm")
    assert _holes(manual)[:4] == [("rapid", [10, 0, 30]), ("rapid", [10, 0, 23]),
                                  ("linear", [10, 0, 15]), ("rapid", [10, 0, 30])]
