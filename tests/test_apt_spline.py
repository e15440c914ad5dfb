"""NX CLSF splines in the APT/CL reader (NURBS/ KNOT/ CNTRL/, issue 15).

The flattened curve is checked against a de Boor evaluation written here (no scipy), against a
closed form (a rational cubic that is exactly a quarter circle), for its chord error (sampled
densely along every chord) and its exact end points; whole programs check the length, the feed,
the sources and the refusals. The spline files are written here in the form NX writes (a bare
``NURBS/``, ``KNOT/`` with the spans' ends, ``CNTRL/`` without the start point).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from conftest import mutate

from models.errors import InputError
from robot_io.apt import read_apt, read_apt_text
from robot_io.apt._spline import flatten
from robot_io.readers import read_toolpath
from robot_io.toolpath import MoveKind, ToolpathError, summarize

MM = 1e-3
MMPM = MM / 60.0
PRE = "UNITS/MM\nFEDRAT/MMPM,600\nRAPID\nGOTO/0,0,10,0,0,1\nGOTO/0,0,0\n"   # tool at the origin
# a cubic spline from the origin: 4 spans (knots at the spans' ends), 6 CNTRL records
SPLINE = ("NURBS/\nKNOT/0.25,0.5,0.75,1.0\nCNTRL/5,0,0\nCNTRL/10,6,0\nCNTRL/15,6,2\n"
          "CNTRL/20,-3,2\nCNTRL/25,0,0\nCNTRL/30,0,0\n")
SPLINE_CTRL = np.array([[0, 0, 0], [5, 0, 0], [10, 6, 0], [15, 6, 2], [20, -3, 2], [25, 0, 0],
                        [30, 0, 0]], dtype=float) * MM
SPLINE_KNOTS = [0.25, 0.5, 0.75, 1.0]


# --------------------------------------------------------------------------- an independent oracle
def de_boor(t: np.ndarray, ctrl: np.ndarray, weights: np.ndarray | None, u: float,
            p: int = 3) -> np.ndarray:
    """The point at ``u`` of the (rational) B-spline, by de Boor's algorithm in homogeneous
    coordinates (The NURBS Book, A2.1 and A4.1)."""
    n = len(ctrl)
    w = np.ones(n) if weights is None else np.asarray(weights, float)
    pw = np.column_stack([ctrl * w[:, None], w])
    if u >= t[n]:
        k = max(i for i in range(p, n) if t[i] < t[i + 1])   # the last non-empty span
    else:
        k = max(i for i in range(p, n) if t[i] <= u)
    d = [pw[j + k - p].copy() for j in range(p + 1)]
    for r in range(1, p + 1):
        for j in range(p, r - 1, -1):
            alpha = (u - t[j + k - p]) / (t[j + 1 + k - r] - t[j + k - p])
            d[j] = (1.0 - alpha) * d[j - 1] + alpha * d[j]
    return d[p][:3] / d[p][3]


def nx_knots(knots: list[float]) -> np.ndarray:
    """The full knot vector of the NX form: four zeros, the spans' ends, the end three more
    times."""
    return np.array([0.0] * 4 + list(knots) + [knots[-1]] * 3)


def _seg_dist(q: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance of points ``q`` (m, 3) to the segment a–b."""
    d = b - a
    s = np.clip((q - a) @ d / max(float(d @ d), 1e-300), 0.0, 1.0)
    return np.linalg.norm(q - (a + s[:, None] * d), axis=1)


def chord_errors(t, ctrl, weights, params: np.ndarray, pts: np.ndarray,
                 per_chord: int = 40) -> np.ndarray:
    """Largest distance of the curve from each chord, sampled at ``per_chord`` points inside."""
    verts = np.vstack([de_boor(t, ctrl, weights, params[0]), pts])
    out = np.empty(len(pts))
    for i in range(len(pts)):
        us = np.linspace(params[i], params[i + 1], per_chord + 2)[1:-1]
        q = np.array([de_boor(t, ctrl, weights, u) for u in us])
        out[i] = _seg_dist(q, verts[i], verts[i + 1]).max()
    return out


# --------------------------------------------------------------------------- the flattening
CURVES = {
    # id: (knots of the NX form, CNTRL points [mm] after the start (0,0,0), weights or None)
    "simple": (SPLINE_KNOTS, SPLINE_CTRL[1:] / MM, None),
    # repeated interior knots: a double (C1) and a triple (C0: a corner) knot
    "repeated_knots": ([0.2, 0.2, 0.5, 0.7, 0.7, 0.7, 1.0],
                       [[3, 4, 0], [8, 6, 1], [12, 2, 1], [15, 5, 0], [20, 9, 3], [24, 4, 3],
                        [28, 0, 1], [31, 2, 0], [35, 3, 0]], None),
    "rational": ([0.3, 0.3, 0.6, 1.0],
                 [[4, 5, 0], [9, 8, 2], [14, 1, 2], [19, 6, 0], [25, 2, 1], [30, 0, 0]],
                 [0.5, 2.5, 1.0, 0.3, 1.7, 1.0]),
    "scaled_domain": ([2.0, 5.0, 9.0], [[4, 5, 0], [9, 8, 2], [14, 1, 2], [19, 6, 0],
                                        [25, 2, 1]], None),
}


@pytest.mark.parametrize("name", sorted(CURVES))
@pytest.mark.parametrize("tol", [1e-4, 1e-5, 1e-6])
def test_flatten_follows_the_de_boor_curve_within_the_chord_tolerance(name: str, tol: float):
    knots, pts, weights = CURVES[name]
    ctrl = np.vstack([[0, 0, 0], np.array(pts, float)]) * MM
    w = None if weights is None else np.array([1.0, *weights])
    t = nx_knots(knots)
    line = flatten(t, ctrl, w, tol, 100_000)
    # every vertex is on the curve at its parameter (the oracle agrees to rounding)
    assert line.params[0] == 0 and line.params[-1] == knots[-1]
    assert np.all(np.diff(line.params) > 0)
    oracle = np.array([de_boor(t, ctrl, w, u) for u in line.params[1:]])
    np.testing.assert_allclose(line.points, oracle, rtol=0, atol=1e-15)
    np.testing.assert_allclose(line.points[-1], ctrl[-1], rtol=0, atol=1e-16)
    # the curve leaves no chord by more than the tolerance, and the chords are not wasted:
    # some come within a factor 4 of it (the |C''| bound is tight for a polynomial span)
    err = chord_errors(t, ctrl, w, line.params, line.points)
    assert err.max() <= tol * (1 + 1e-9)
    assert err.max() >= tol / 4 or len(line.points) == len(set(knots))


def test_flatten_moves_scale_like_the_inverse_root_of_the_tolerance():
    knots, pts, _ = CURVES["simple"]
    ctrl = np.vstack([[0, 0, 0], pts]) * MM
    counts = [len(flatten(nx_knots(knots), ctrl, None, tol, 100_000).points)
              for tol in (1e-4, 1e-6)]
    assert 7 < counts[1] / counts[0] < 13   # sqrt(100) = 10


def test_rational_cubic_quarter_circle_is_exact():
    """The rational quadratic quarter circle raised to degree 3: control points (1,0), (1,2−√2),
    (2−√2,1), (0,1) with weights 1, (1+√2)/3, (1+√2)/3, 1 — every vertex at radius R."""
    r = 40.0
    w = (1 + math.sqrt(2)) / 3
    c = 2 - math.sqrt(2)
    text = (f"UNITS/MM\nFEDRAT/MMPM,600\nRAPID\nGOTO/{r},0,0\nNURBS/\nKNOT/1.0\n"
            f"CNTRL/{r},{c * r},0,{w}\nCNTRL/{c * r},{r},0,{w}\nCNTRL/0,{r},0,1\n")
    tol = 1e-5
    tp = read_apt_text(text, chord_tol=tol)
    moves = [m for m in tp.moves if m.extra.get("spline") == 0]
    ends = np.array([m.end for m in moves])
    np.testing.assert_allclose(np.linalg.norm(ends[:, :2], axis=1), r * MM, rtol=0, atol=1e-12)
    chords = [np.linalg.norm(m.end - m.start) for m in moves]
    sagitta = max(r * MM - math.sqrt((r * MM) ** 2 - (c / 2) ** 2) for c in chords)
    assert tol / 4 < sagitta <= tol
    assert summarize(tp)["length_m"] == pytest.approx(math.pi * r * MM / 2, abs=tol)
    assert tp.meta["splines"][0]["rational"] and list(moves[-1].end) == [0, r * MM, 0]


# --------------------------------------------------------------------------- whole programs
def _dense_length(t, ctrl, weights=None, n=20001) -> float:
    pts = np.array([de_boor(t, ctrl, weights, u) for u in np.linspace(0, t[-1], n)])
    return float(np.linalg.norm(np.diff(pts, axis=0), axis=1).sum())


def test_spline_in_a_program_gives_the_curve_length_not_the_chord():
    text = PRE + SPLINE + "GOTO/40,0,0\nGOTO/40,10,0\n"
    spline_len = _dense_length(nx_knots(SPLINE_KNOTS), SPLINE_CTRL)
    expected = 10 * MM + spline_len + 10 * MM + 10 * MM
    # chords are shorter than the curve by about (8/3)·sagitta²/chord each: with the default
    # 10 µm a few µm in all, with 0.1 µm well under the oracle's own 0.2 µm
    assert summarize(read_apt_text(text, chord_tol=1e-7))["length_m"] == pytest.approx(
        expected, abs=2e-7)
    tp = read_apt_text(text)
    s = summarize(tp)
    assert expected - 2e-5 < s["length_m"] < expected
    straight = summarize(read_apt_text(PRE + "GOTO/30,0,0\nGOTO/40,0,0\nGOTO/40,10,0\n"))
    assert straight["length_m"] == pytest.approx(10 * MM + 30 * MM + 20 * MM)
    assert s["length_m"] - straight["length_m"] > 4 * MM   # the curve is 4.48 mm longer
    assert s["moves"] == 4 + tp.meta["splines"][0]["moves"]


def test_spline_moves_ends_feed_source_and_meta():
    text = PRE + "FEDRAT/MMPM,250\n" + SPLINE + "GOTO/40,0,0\n"
    tp = read_apt_text(text, file="part.cls")
    spl = [m for m in tp.moves if "spline" in m.extra]
    assert spl and all(m.extra == {"spline": 0} for m in spl)
    assert all(m.kind == MoveKind.LINEAR and m.feed == pytest.approx(250 * MMPM) for m in spl)
    assert {(m.source.file, m.source.line, m.source.column) for m in spl} == {("part.cls", 7, 1)}
    # continuous: starts at the GOTO before (the very array), ends exactly at the last CNTRL
    before = tp.moves[1]
    assert spl[0].start is before.end
    assert list(spl[-1].end) == [30 * MM, 0.0, 0.0]
    assert tp.moves[-1].start is spl[-1].end and tp.moves[-1].source.line == 15
    for a, b in zip(spl, spl[1:], strict=False):
        assert b.start is a.end
    assert all(list(m.tool_axis) == [0, 0, 1] for m in spl)   # the modal axis of the GOTO
    assert tp.meta["splines"] == [{"index": 0, "line": 7, "knots": 4, "control_points": 7,
                                   "rational": False, "moves": len(spl)}]
    assert tp.warnings == [] and dict(tp.skipped) == {}
    # end to end: every point of the curve (4001 samples) is within chord_tol of the moves
    t = nx_knots(SPLINE_KNOTS)
    curve = np.array([de_boor(t, SPLINE_CTRL, None, u) for u in np.linspace(0, 1, 4001)])
    dist = np.min([_seg_dist(curve, m.start, m.end) for m in spl], axis=0)
    assert dist.max() <= 1e-5


def test_consecutive_splines_rapid_inch_and_frames():
    # two splines back to back (NX writes no GOTO between): the second starts at the first's end
    two = PRE + SPLINE + "NURBS/\nKNOT/1\nCNTRL/35,0,0\nCNTRL/40,5,0\nCNTRL/45,5,0\n"
    tp = read_apt_text(two)
    idx = [m.extra["spline"] for m in tp.moves if "spline" in m.extra]
    assert idx == sorted(idx) and set(idx) == {0, 1}
    first_of_second = next(m for m in tp.moves if m.extra.get("spline") == 1)
    assert list(first_of_second.start) == [30 * MM, 0, 0] and first_of_second.source.line == 14
    # RAPID makes the spline a rapid; inches scale the control points, not the knots
    tp = read_apt_text("UNITS/INCHES\nFEDRAT/10\nRAPID\nGOTO/0,0,0\nRAPID\n" + SPLINE)
    spl = [m for m in tp.moves if "spline" in m.extra]
    assert all(m.kind == MoveKind.RAPID and m.feed is None for m in spl)
    assert list(spl[-1].end) == [30 * 0.0254, 0, 0]
    # apply_frames maps the control points (p = R·p + t); the curve maps with them
    msys = "MSYS/100,0,0,0,1,0,-1,0,0\n"   # 90° about Z, origin (100, 0, 0) mm
    plain = read_apt_text(PRE + SPLINE)
    moved = read_apt_text(PRE.replace("RAPID", msys + "RAPID") + SPLINE, apply_frames=True)
    rz = np.array([[0, -1, 0], [1, 0, 0], [0, 0, 1]])
    got = np.array([m.end for m in moved.moves])
    want = np.array([rz @ m.end + [100 * MM, 0, 0] for m in plain.moves])
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-15)


def test_start_point_written_as_the_first_cntrl_is_accepted_within_tolerance():
    explicit = PRE + SPLINE.replace("CNTRL/5,0,0", "CNTRL/0.000004,0,0\nCNTRL/5,0,0")
    a, b = summarize(read_apt_text(explicit)), summarize(read_apt_text(PRE + SPLINE))
    assert a == b
    with pytest.raises(ToolpathError, match=r"^<string>:8:1: the spline does not start at the "
                       r"tool position: its first CNTRL is 0.02 mm away \(tolerance 0.01 mm\)"):
        read_apt_text(explicit.replace("0.000004", "0.02"))


def test_nx_form_file_reads_strictly_with_its_splines(tmp_path: Path):
    """A file written in the NX CLSF form (tool path header, MSYS, PAINT, a bare NURBS/, the
    KNOT/ and CNTRL/ records, END-OF-PATH) is read in strict mode, splines and all."""
    path = tmp_path / "contour.cls"
    path.write_text("TOOL PATH/CONTOUR_1,TOOL,BALL_MILL_10\nTLDATA/MILL,10.0000,5.0000,75.0000,"
                    "0.0000,0.0000\nMSYS/0.0000,0.0000,0.0000,1.0000000,0.0000000,0.0000000,"
                    "0.0000000,1.0000000,0.0000000\n$$ centerline data\nPAINT/PATH\n"
                    "PAINT/SPEED,10\nLOAD/TOOL,3,ADJUST,3\nPAINT/COLOR,186\nRAPID\n"
                    "GOTO/0.0000,0.0000,10.0000,0.0000000,0.0000000,1.0000000\nPAINT/COLOR,42\n"
                    "FEDRAT/MMPM,250.0000\nGOTO/0.0000,0.0000,0.0000\nNURBS/\n"
                    "KNOT/0.2500000,0.5000000,0.7500000,1.0000000\nCNTRL/5.0000,0.0000,0.0000\n"
                    "CNTRL/10.0000,6.0000,0.0000\nCNTRL/15.0000,6.0000,2.0000\n"
                    "CNTRL/20.0000,-3.0000,2.0000\nCNTRL/25.0000,0.0000,0.0000\n"
                    "CNTRL/30.0000,0.0000,0.0000\nPAINT/COLOR,31\nGOTO/40.0000,0.0000,0.0000\n"
                    "PAINT/SPEED,10\nPAINT/TOOL,NOMORE\nEND-OF-PATH\n", encoding="utf-8")
    tp = read_toolpath(path)
    assert tp.format == "apt" and dict(tp.skipped) == {}
    assert [w.category for w in tp.warnings] == ["no_units"]
    assert summarize(tp)["length_m"] == pytest.approx(
        10 * MM + _dense_length(nx_knots(SPLINE_KNOTS), SPLINE_CTRL) + 10 * MM, abs=2e-5)
    assert tp.meta["ignored_records"]["PAINT"] == 7 and tp.meta["splines"][0]["moves"] > 20
    assert read_apt(path).meta["record_counts"]["CNTRL"] == 6


# --------------------------------------------------------------------------- refusals
BAD = [
    # id, text after PRE, strict message (after "<string>:"), line of the lenient warning
    ("decreasing_knot", SPLINE.replace("0.5,0.75", "0.75,0.5"),
     r"7:16: KNOT 0.5 after 0.75: knot values must not decrease"),
    ("decreasing_across_records", SPLINE.replace("KNOT/0.25,0.5,0.75,1.0",
                                                 "KNOT/0.25,0.5\nKNOT/0.4,0.75,1.0"),
     r"8:6: KNOT 0.4 after 0.5: knot values must not decrease"),
    ("knot_four_times", SPLINE.replace("0.25,0.5,0.75", "0.5,0.5,0.5,0.5"),
     r"7:18: KNOT 0.5 comes more than 3 times: the cubic spline would come apart"),
    ("first_knot_zero", SPLINE.replace("0.25,", "0,"),
     r"7:6: KNOT 0: the first knot ends the first span, which starts at 0"),
    ("last_knot_not_above", SPLINE.replace("0.75,1.0", "1.0,1.0"),
     r"7:19: the last KNOT value \(1\) must be greater than the one before"),
    ("too_few_cntrl", SPLINE.replace("CNTRL/25,0,0\n", ""),
     r"6:1: NURBS has 4 knot values and 5 CNTRL records: NX writes 6 CNTRL records for 4"),
    ("no_knots", "NURBS/\nCNTRL/1,0,0\nCNTRL/2,0,0\n", r"6:1: NURBS has 0 knot values"),
    ("zero_weight", SPLINE.replace("CNTRL/5,0,0", "CNTRL/5,0,0,0"),
     r"8:13: CNTRL weight must be positive, got 0"),
    ("negative_weight", SPLINE.replace("CNTRL/5,0,0", "CNTRL/5,0,0,-1"),
     r"8:13: CNTRL weight must be positive, got -1"),
    ("mixed_weights", SPLINE.replace("CNTRL/10,6,0", "CNTRL/10,6,0,1"),
     r"9:1: CNTRL: either every control point of a spline has a weight"),
    ("cntrl_fields", SPLINE.replace("CNTRL/10,6,0", "CNTRL/10,6"),
     r"9:11: CNTRL takes 3 numbers \(x,y,z\) or 4 \(x,y,z,weight\), got 2"),
    ("knot_after_cntrl", SPLINE + "KNOT/2\n", r"14:1: KNOT after the spline's CNTRL records"),
    ("knot_outside", "KNOT/0.5,1\n", r"6:1: KNOT outside a spline: NX writes NURBS/"),
    ("nurbs_args", SPLINE.replace("NURBS/", "NURBS/3"), r"6:7: NURBS/ takes no arguments"),
    ("nurbs_in_cycle", "CYCLE/DRILL,FEDTO,5,MMPM,100,RAPTO,2\n" + SPLINE + "CYCLE/OFF\n",
     r"7:1: NURBS inside a drilling cycle \(CYCLE at line 6\)"),
]


@pytest.mark.parametrize(("text", "message"), [(t, m) for _, t, m in BAD],
                         ids=[c[0] for c in BAD])
def test_bad_splines_are_refused_in_strict_mode_with_a_location(text: str, message: str):
    with pytest.raises(ToolpathError, match=r"^<string>:" + message + r".*(strict=False)"):
        read_apt_text(PRE + text + "GOTO/40,0,0\n")


@pytest.mark.parametrize("text", [t for _, t, _ in BAD], ids=[c[0] for c in BAD])
def test_bad_splines_are_dropped_in_lenient_mode(text: str):
    tp = read_apt_text(PRE + text + "GOTO/40,0,0\n", strict=False)
    assert tp.warnings and not any("spline" in m.extra for m in tp.moves)
    assert list(tp.moves[-1].end) == [40 * MM, 0, 0]
    summarize(tp)


def test_spline_from_an_unknown_position_and_too_many_moves():
    with pytest.raises(ToolpathError, match=r"^<string>:3:1: NURBS from an unknown position"):
        read_apt_text("UNITS/MM\nFEDRAT/MMPM,100\n" + SPLINE)
    with pytest.raises(ToolpathError, match=r"^<string>:6:1: the spline would need \d+ moves to "
                       r"stay within the chord tolerance of 1e-09 mm .*chord_tol=[0-9.e-]+ \(metres\)"):
        read_apt_text(PRE + SPLINE, chord_tol=1e-12)
    tp = read_apt_text(PRE + SPLINE + "GOTO/40,0,0", chord_tol=1e-12, strict=False)
    assert tp.meta["warning_counts"] == {"bad_spline": 1}
    assert _mm_list(tp.moves[-1].start) == [30, 0, 0]   # the tool put at the spline's end
    with pytest.raises(ToolpathError, match="feed move before any FEDRAT"):
        read_apt_text("UNITS/MM\nRAPID\nGOTO/0,0,0\n" + SPLINE)


def _mm_list(v) -> list[float]:
    return [round(float(x) / MM, 9) for x in v]


def test_chord_tol_option_is_validated():
    for bad in (0.0, -1e-5, math.nan, math.inf, "1e-5"):
        with pytest.raises(InputError, match="chord_tol"):
            read_apt_text(PRE, chord_tol=bad)
    fine = summarize(read_apt_text(PRE + SPLINE, chord_tol=1e-3))
    coarse = summarize(read_apt_text(PRE + SPLINE))
    assert fine["moves"] < coarse["moves"]


FUZZ = PRE + SPLINE + "GOTO/40,0,0\nNURBS/\nKNOT/0.3,0.3,1\nCNTRL/45,1,0,1\nCNTRL/50,4,1,2\n" \
    "CNTRL/55,2,0,0.5\nCNTRL/58,1,0,1\nCNTRL/60,0,0,1\nFINI\n"


def test_fuzz_splines_only_toolpath_errors(rng: np.random.Generator):
    assert len(read_apt_text(FUZZ).meta["splines"]) == 2
    alphabet = b"0123456789.+-,/$ eENURBSKOTCL\n\t"
    outcomes = {"ok": 0, "error": 0}
    for _ in range(200):
        text = mutate(FUZZ.encode(), alphabet, rng).decode("latin-1")
        try:
            summarize(read_apt_text(text))
            outcomes["ok"] += 1
        except ToolpathError:
            outcomes["error"] += 1
        summarize(read_apt_text(text, strict=False))   # lenient never raises
    assert outcomes["ok"] >= 5 and outcomes["error"] > 100   # (a mutated word is refused)
