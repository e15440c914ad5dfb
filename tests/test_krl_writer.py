"""Tests of the KUKA KRL writer (robot_io.krl) and the KRL lint (robot_io.krl.lint).

Every program the writer produces here goes through the lint (our own checker of KUKA_IO.md §1:
ASCII, CRLF, identifiers, DEF/END and folds, $VEL.CP decimals and range, page sizes, no page break
before a CIRC, .src/.dat pairs, declared variables) and is read back with robot_io.krl.reader:
poses within 0.001 mm / 0.001°, feeds exactly. The lint is itself tested on broken programs, so it
can fail.
"""

from __future__ import annotations

import math
import os
import re
from pathlib import Path

import numpy as np
import pytest

from models.errors import CctmillError
from robot_io.krl import (
    CONTROLLERS,
    KrlError,
    KrlFrame,
    KrlMove,
    KrlProgramSpec,
    KrlSection,
    ascii_comment,
    render_krl,
    sanitize_identifier,
    write_krl,
)
from robot_io.krl.lint import lint_krl
from robot_io.krl.reader import abc_to_matrix, read_krl

SEED = 20240611
HOME = (0.0, -90.0, 90.0, 0.0, 45.0, 0.0)
POS_TOL_MM = 1e-3
ANG_TOL_DEG = 1e-3


def _lint_clean(files: dict[str, str], controller: str) -> None:
    problems = lint_krl(files, controller=controller,
                        vel_cp_max=CONTROLLERS[controller].vel_cp_max)
    assert not problems, "\n".join(str(p) for p in problems[:20])


def _rot_angle_deg(abc1, abc2) -> float:
    r = abc_to_matrix(*abc1).T @ abc_to_matrix(*abc2)
    return math.degrees(math.acos(max(-1.0, min(1.0, (np.trace(r) - 1) / 2))))


def _small_program() -> tuple[list[KrlSection], list[KrlMove]]:
    """A pocket side, a 90° CIRC, a 270° arc as two CIRCs, a tilted wall, a retract."""
    secs = [KrlSection(0.0012345678, "cut", "chatter", "first γ-limited wall, 5° lead"),
            KrlSection(0.002, "cut", "force"),
            KrlSection(0.05, "air", "feed_max")]
    s2 = math.sqrt(0.5)
    mv = [
        KrlMove("LIN", (0, 0, 10, 0, 90, 0), 0),
        KrlMove("LIN", (0, 0, -2, 0, 90, 0), 0),
        KrlMove("LIN", (40, 0, -2, 0, 90, 0), 0),
        # quarter circle about (40, 10): (40,0) → (50,10)
        KrlMove("CIRC", (50, 10, -2, 0, 90, 0), 1, aux=(40 + 10 * s2, 10 - 10 * s2, -2, 0, 90, 0)),
        # 270° about (40, 10) from (50, 10) as two CIRCs: → (30, 10) → (40, 0)... via top
        KrlMove("CIRC", (30, 10, -2, 0, 90, 0), 1, aux=(40, 20, -2, 0, 90, 0)),
        KrlMove("CIRC", (40 - 10 * s2, 10 - 10 * s2, -2, 0, 90, 0), 1,
                aux=(40 - 10 * math.cos(math.radians(22.5)),
                     10 - 10 * math.sin(math.radians(22.5)), -2, 0, 90, 0)),
        KrlMove("LIN", (60, 60, -2, 90, 60, 12.5), 1),
        KrlMove("LIN", (60, 60, 50, 90, 60, 12.5), 2, approx=False),
    ]
    return secs, mv


def _check_round_trip(path: Path, sections, moves) -> None:
    tp = read_krl(path)
    cart = [m for m in moves if m.kind != "PTP"]
    assert len(tp.moves) == len(cart)
    for got, want in zip(tp.moves, cart, strict=True):
        np.testing.assert_allclose(got.end * 1e3, want.target[:3], atol=POS_TOL_MM, rtol=0)
        assert _rot_angle_deg(got.extra["abc_deg"], want.target[3:]) < ANG_TOL_DEG
        assert got.feed == sections[want.section].feed_m_s      # exactly
        if want.kind == "CIRC":
            np.testing.assert_allclose(got.extra["aux"] * 1e3, want.aux[:3], atol=POS_TOL_MM,
                                       rtol=0)
        assert (got.extra.get("approx") == "C_DIS") == want.approx


def _dat_feeds(files: dict[str, str], name: str) -> dict[str, float]:
    dat = files[f"{name}.dat"]
    return {m.group(1): float(m.group(2)) for m in
            re.finditer(r"DECL GLOBAL REAL (\w+)=([0-9.]+)", dat)}


# --------------------------------------------------------------------------- lint on output
@pytest.mark.parametrize("controller", ["krc2", "krc4"])
@pytest.mark.parametrize("hook", ["none", "kvp", "rsi"])
@pytest.mark.parametrize("frames", ["literal", "index"])
def test_small_program_lints_and_reads_back(tmp_path, controller, hook, frames) -> None:
    if hook == "rsi" and controller == "krc2":
        pytest.skip("refused on KR C2 (tested below)")
    secs, mv = _small_program()
    base: KrlFrame | int = KrlFrame((800, -200, 450), (30, 0, 0)) if frames == "literal" else 2
    tool: KrlFrame | int = KrlFrame((0, 0, 250), (0, -90, 0)) if frames == "literal" else 1
    spec = KrlProgramSpec("MILL_TEST", HOME, controller=controller, base=base, tool=tool,
                          override_hook=hook, comments=("job: bracket — Δ plane, µm",),
                          end_axes_deg=HOME)
    out = render_krl(spec, secs, mv, notes=("path pre-compensated (test note)",))
    assert out.pages == ()
    assert list(out.files) == ["MILL_TEST.src", "MILL_TEST.dat"]
    _lint_clean(out.files, controller)
    paths = write_krl(spec, secs, mv, tmp_path, notes=("path pre-compensated (test note)",))
    assert [p.name for p in paths] == list(out.files)
    for p in paths:
        assert p.read_bytes() == out.files[p.name].encode("ascii")
    _check_round_trip(paths[0], secs, mv)
    tp = read_krl(paths[0])
    if frames == "literal":
        np.testing.assert_allclose(tp.meta["base"]["matrix"][:3, 3], [0.8, -0.2, 0.45])
    else:
        assert tp.meta["base"]["name"] == "BASE_DATA[2]" and tp.meta["tool"]["index"] == 1
    feeds = _dat_feeds(out.files, "MILL_TEST")
    assert feeds == {f"MILL_TEST_F00{k}": s.feed_m_s for k, s in enumerate(secs, 1)}
    src = out.files["MILL_TEST.src"]
    assert "BAS (#INITMOV,0 )" in src and "PTP $AXIS_ACT" in src
    assert ";FOLD section 1: cut, 1.234568 mm/s, bound by chatter" in src
    assert "; first gamma-limited wall, 5deg lead" in src
    assert ("EXT BAS (BAS_COMMAND :IN,REAL :IN )" in src) == (controller == "krc2")
    assert ("MILL_TEST_SEC = 2" in src) == (hook != "none")
    assert ("RSI_ON(#RELATIVE,#IPO)" in src) == (hook == "rsi")
    # $VEL.CP comes before each section's first motion
    lines = src.split("\r\n")
    for k in (1, 2, 3):
        i = lines.index(next(x for x in lines if x.startswith(f";FOLD section {k}:")))
        first_motion = next(j for j in range(i, len(lines))
                            if lines[j].startswith(("LIN", "CIRC")))
        assert any(x.startswith(f"$VEL.CP = MILL_TEST_F00{k}") for x in lines[i:first_motion])


def test_feed_literal_exact_and_at_least_six_decimals() -> None:
    secs = [KrlSection(0.0015), KrlSection(0.001234567891234), KrlSection(1e-4 / 3)]
    mv = [KrlMove("LIN", (i, 0, 0, 0, 90, 0), i) for i in range(3)]
    out = render_krl(KrlProgramSpec("FEEDS", HOME), secs, mv)
    dat = out.files["FEEDS.dat"]
    lits = re.findall(r"DECL GLOBAL REAL FEEDS_F00\d=([0-9.]+)", dat)
    assert lits[0] == "0.001500"
    assert all(len(x.split(".")[1]) >= 6 for x in lits)
    assert [float(x) for x in lits] == [s.feed_m_s for s in secs]


# --------------------------------------------------------------------------- paging
def _long_job(rng, n_sections: int, n_moves: int) -> tuple[list[KrlSection], list[KrlMove]]:
    """A zig-zag with CIRC pairs (two halves of one arc) sprinkled in, some sections much longer
    than a page."""
    sizes = rng.integers(5, 60, n_sections).astype(float)
    sizes[[i for i in (3, 7) if i < n_sections]] = 40 * sizes.mean()   # far longer than a page
    sizes = np.maximum(1, np.round(sizes / sizes.sum() * n_moves)).astype(int)
    secs = [KrlSection(float(f), "cut", b) for f, b in
            zip(rng.uniform(5e-4, 2e-3, n_sections), rng.choice(["chatter", "force"], n_sections),
                strict=True)]
    mv: list[KrlMove] = []
    x = y = 0.0
    for k, size in enumerate(sizes):
        j = 0
        while j < size:
            a = float(rng.uniform(-30, 30))
            if j > 0 and j + 2 <= size and rng.random() < 0.1:
                # a full half circle of radius 5 as two CIRCs, about (x, y + 5)
                c = (x, y + 5)
                mv.append(KrlMove("CIRC", (c[0] + 5, c[1], 0, a, 90, 0), k,
                                  aux=(c[0] + 5 * math.sin(math.pi / 4),
                                       c[1] - 5 * math.cos(math.pi / 4), 0, a, 90, 0)))
                mv.append(KrlMove("CIRC", (c[0], c[1] + 5, 0, a, 90, 0), k,
                                  aux=(c[0] + 5 * math.cos(math.pi / 4),
                                       c[1] + 5 * math.sin(math.pi / 4), 0, a, 90, 0)))
                x, y = c[0], c[1] + 5
                j += 2
                continue
            x += float(rng.uniform(0.5, 2.0))
            y += float(rng.uniform(-1, 1))
            mv.append(KrlMove("LIN", (x, y, -1.5, a, 90.0, float(rng.uniform(-5, 5))), k))
            j += 1
    mv[-1] = KrlMove(mv[-1].kind, mv[-1].target, mv[-1].section, mv[-1].aux, approx=False)
    return secs, mv


def test_long_job_pages_on_krc2_and_reads_back(tmp_path) -> None:
    rng = np.random.default_rng(SEED)
    secs, mv = _long_job(rng, 30, 12_000)
    assert len(mv) >= 10_000
    spec = KrlProgramSpec("LONG_JOB", HOME, controller="krc2", override_hook="kvp")
    out = render_krl(spec, secs, mv)
    limit = CONTROLLERS["krc2"].page_lines
    assert len(out.pages) >= 6
    assert set(out.files) == {f"{n}.{e}" for n in ("LONG_JOB", *out.pages) for e in ("src", "dat")}
    for name, text in out.files.items():
        assert text.count("\r\n") <= limit, name
    _lint_clean(out.files, "krc2")
    main = out.files["LONG_JOB.src"]
    calls = re.findall(r"^(LONG_JOB_\d{3})\( \)", main, re.M)
    assert calls == list(out.pages)
    # breaks at section boundaries except inside the two long sections, never before a CIRC
    continued = 0
    for p in out.pages:
        body = out.files[f"{p}.src"].split("\r\n")
        first_motion = next(x for x in body if x.startswith(("LIN", "CIRC")))
        assert first_motion.startswith("LIN")
        first_fold = next(x for x in body if x.startswith(";FOLD section"))
        if "(continued)" in first_fold:
            continued += 1
            k = int(first_fold.split()[2].rstrip(":"))
            assert k in (4, 8)                        # sections 3 and 7 (0-based) are long
            i = body.index(first_fold)
            assert body[i + 1].startswith("; section") and "re-issued" in body[i + 1]
            assert any(x.startswith(f"$VEL.CP = LONG_JOB_F{k:03d}") for x in body[i:i + 5])
            assert any(x == f"LONG_JOB_SEC = {k}" for x in body[i:i + 5])
    assert continued >= 2
    paths = write_krl(spec, secs, mv, tmp_path)
    _lint_clean({p.name: p.read_bytes() for p in paths}, "krc2")
    _check_round_trip(paths[0], secs, mv)
    # each page also reads on its own, given the main .dat (where the feeds are)
    per_page = [read_krl(p, global_dat=[paths[1]]) for p in paths if p.suffix == ".src"][1:]
    assert sum(len(t.moves) for t in per_page) == len(mv)
    assert all(t.moves[0].feed is not None for t in per_page)


def test_krc4_pages_are_shorter(tmp_path) -> None:
    rng = np.random.default_rng(SEED + 1)
    secs, mv = _long_job(rng, 12, 8_000)
    n = {c: len(render_krl(KrlProgramSpec("PAGED", HOME, controller=c), secs, mv).pages)
         for c in ("krc2", "krc4")}
    assert n["krc4"] > n["krc2"] >= 2
    out = render_krl(KrlProgramSpec("PAGED", HOME, controller="krc4"), secs, mv)
    assert max(t.count("\r\n") for t in out.files.values()) <= 1400
    _lint_clean(out.files, "krc4")


def test_sections_that_fit_are_never_split() -> None:
    secs = [KrlSection(0.001 + 1e-5 * k) for k in range(8)]
    mv = [KrlMove("LIN", (j, k, 0, 0, 90, 0), k) for k in range(8) for j in range(60)]
    out = render_krl(KrlProgramSpec("SPLIT", HOME, page_lines=150), secs, mv)
    assert len(out.pages) == 4
    for p in out.pages:
        assert "(continued)" not in out.files[f"{p}.src"]
        assert out.files[f"{p}.src"].count("\r\n") <= 150


# --------------------------------------------------------------------------- refusals
_SEC = [KrlSection(0.001)]
_MV = [KrlMove("LIN", (0, 0, 0, 0, 90, 0), 0)]


@pytest.mark.parametrize("spec, sections, moves, field, match", [
    (KrlProgramSpec("A" * 25, HOME), _SEC, _MV, "name", r"25 characters; KRL allows at most 24"),
    (KrlProgramSpec("A" * 20, HOME), _SEC, _MV, "name", r"at most 19 long"),
    (KrlProgramSpec("1ST_PART", HOME), _SEC, _MV, "name", r"must not start with a digit"),
    (KrlProgramSpec("MILL-1", HOME), _SEC, _MV, "name", r"letters A-Z"),
    (KrlProgramSpec("FRÄSEN", HOME), _SEC, _MV, "name", r"letters A-Z"),
    (KrlProgramSpec("$MILL", HOME), _SEC, _MV, "name", r"must not contain '\$'"),
    (KrlProgramSpec("CIRC", HOME), _SEC, _MV, "name", r"keyword"),
    (KrlProgramSpec("", HOME), _SEC, _MV, "name", r"empty"),
    (KrlProgramSpec("P", HOME), [KrlSection(0.0)], _MV, "section 1 feed", r"must be > 0"),
    (KrlProgramSpec("P", HOME), [KrlSection(-0.001)], _MV, "section 1 feed", r"must be > 0"),
    (KrlProgramSpec("P", HOME), [KrlSection(math.nan)], _MV, "section 1 feed", r"not a number"),
    (KrlProgramSpec("P", HOME), [KrlSection(math.inf)], _MV, "section 1 feed", r"not a number"),
    (KrlProgramSpec("P", HOME), [KrlSection(2.5)], _MV, "section 1 feed", r"above KR C4.*mm/s"),
    (KrlProgramSpec("P", HOME), [KrlSection(0.001), KrlSection(0.0)],
     [_MV[0], KrlMove("LIN", (1, 0, 0, 0, 90, 0), 1)], "section 2 feed", r"must be > 0"),
    (KrlProgramSpec("P", HOME, controller="krc2", override_hook="rsi"), _SEC, _MV,
     "override_hook", r"KR C4.*kvp"),
    (KrlProgramSpec("P", HOME, override_hook="udp"), _SEC, _MV, "override_hook", r"unknown"),
    (KrlProgramSpec("P", HOME, controller="krc5"), _SEC, _MV, "controller", r"krc2, krc4"),
    (KrlProgramSpec("P", HOME, advance=0), _SEC, _MV, "advance", r"1\.\.5"),
    (KrlProgramSpec("P", HOME, apo_cdis_mm=math.nan), _SEC, _MV, "apo_cdis_mm", r"> 0"),
    (KrlProgramSpec("P", HOME, base=33), _SEC, _MV, "base", r"1\.\.32"),
    (KrlProgramSpec("P", HOME, tool=0), _SEC, _MV, "tool", r"1\.\.16"),
    (KrlProgramSpec("P", (0, 0, 0, math.nan, 0, 0)), _SEC, _MV, "bco_axes_deg", r"finite"),
    (KrlProgramSpec("P", HOME, page_lines=5000), _SEC, _MV, "page_lines", r"100\.\.1400"),
    (KrlProgramSpec("P", HOME), [], _MV, "sections", r"at least one"),
    (KrlProgramSpec("P", HOME), _SEC, [], "moves", r"at least one"),
    (KrlProgramSpec("P", HOME), _SEC, [KrlMove("LIN", (0, 0, math.nan, 0, 90, 0), 0)], "move 0",
     r"finite"),
    (KrlProgramSpec("P", HOME), _SEC, [KrlMove("LIN", (0, 0, 2e6, 0, 90, 0), 0)], "move 0",
     r"below"),
    (KrlProgramSpec("P", HOME), _SEC, [KrlMove("LIN", (0, 0, 0, 0, 90), 0)], "move 0",
     r"6 numbers"),
    (KrlProgramSpec("P", HOME), _SEC, [KrlMove("SPLINE", (0, 0, 0, 0, 90, 0), 0)], "move 0",
     r"PTP, LIN, CIRC"),
    (KrlProgramSpec("P", HOME), _SEC, [KrlMove("CIRC", (1, 1, 0, 0, 90, 0), 0,
                                               aux=(0.5, 0.2, 0, 0, 90, 0))], "move 0",
     r"cannot follow a joint PTP"),
    (KrlProgramSpec("P", HOME), _SEC, [_MV[0], KrlMove("CIRC", (1, 1, 0, 0, 90, 0), 0)],
     "move 1", r"auxiliary"),
    (KrlProgramSpec("P", HOME), _SEC, [KrlMove("LIN", (0, 0, 0, 0, 90, 0), 1)], "move 0",
     r"not an index"),
    (KrlProgramSpec("P", HOME), [KrlSection(0.001), KrlSection(0.001)],
     [KrlMove("LIN", (0, 0, 0, 0, 90, 0), 1), KrlMove("LIN", (1, 0, 0, 0, 90, 0), 0)],
     "move 1", r"contiguous"),
    (KrlProgramSpec("P", HOME), [KrlSection(0.001), KrlSection(0.001)], _MV, "sections",
     r"section 2 has no moves"),
])
def test_writer_refuses(spec, sections, moves, field, match) -> None:
    with pytest.raises(KrlError, match=match) as e:
        render_krl(spec, sections, moves)
    assert e.value.field == field
    assert isinstance(e.value, CctmillError)


def test_longest_name_still_pages() -> None:
    mv = [KrlMove("LIN", (j, 0, 0, 0, 90, 0), 0) for j in range(300)]
    out = render_krl(KrlProgramSpec("A" * 19, HOME, page_lines=100), _SEC, mv)
    assert len(out.pages) == 4 and all(len(p) <= 24 for p in (*out.pages, *out.feed_names))
    _lint_clean(out.files, "krc4")


@pytest.mark.parametrize("text, want", [
    ("γ ≤ 5° — wall", "gamma <= 5deg - wall"),
    ("Überschnitt für Teil", "Uberschnitt fur Teil"),
    ("δ = 3 µm ± 1", "delta = 3 um +/- 1"),
    ("中文 kept? no", " kept? no"),
    ("tab\tand\nnewline", "tab and newline"),
])
def test_comments_are_transliterated_or_dropped(text, want) -> None:
    assert ascii_comment(text) == want
    sec = [KrlSection(0.001, "cut", "chatter", text)]
    out = render_krl(KrlProgramSpec("P", HOME, comments=(text,)), sec, _MV)
    src = out.files["P.src"]
    assert src.isascii()
    assert f"; {want}".rstrip() + "\r\n" in src
    _lint_clean(out.files, "krc4")


@pytest.mark.parametrize("text, want", [
    ("bracket contour", "bracket_contour"), ("2024-part#7", "P2024_part_7"),
    ("Gehäuse Δ", "Gehause_Delta"), ("", "CCT_PROG"), ("END", "END_P"),
    ("a" * 40, "a" * 24),
])
def test_sanitize_identifier(text, want) -> None:
    assert sanitize_identifier(text) == want


# --------------------------------------------------------------------------- atomicity
def _snapshot(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir())}


def test_refused_program_touches_no_file(tmp_path) -> None:
    secs, mv = _small_program()
    spec = KrlProgramSpec("ATOMIC", HOME)
    write_krl(spec, secs, mv, tmp_path)
    before = _snapshot(tmp_path)
    bad = [*secs[:-1], KrlSection(math.nan, "air")]          # NaN in the last section
    with pytest.raises(KrlError, match="section 3 feed"):
        write_krl(spec, bad, mv, tmp_path)
    assert _snapshot(tmp_path) == before
    fresh = tmp_path / "fresh"
    with pytest.raises(KrlError):
        write_krl(spec, bad, mv, fresh)
    assert not fresh.exists() or not any(fresh.iterdir())


def test_io_failure_mid_way_leaves_previous_files(tmp_path, monkeypatch) -> None:
    rng = np.random.default_rng(SEED)
    secs, mv = _long_job(rng, 10, 3_000)
    spec = KrlProgramSpec("ATOMIC", HOME, controller="krc4")
    write_krl(spec, secs[:1], [m for m in mv if m.section == 0], tmp_path)
    before = _snapshot(tmp_path)
    real = os.fdopen
    calls = {"n": 0}

    def failing(fd, *a, **k):
        calls["n"] += 1
        if calls["n"] == 3:
            os.close(fd)
            raise OSError(28, "No space left on device")
        return real(fd, *a, **k)

    monkeypatch.setattr(os, "fdopen", failing)
    with pytest.raises(OSError, match="No space"):
        write_krl(spec, secs, mv, tmp_path)
    monkeypatch.undo()
    assert calls["n"] == 3
    assert _snapshot(tmp_path) == before                  # no temporaries, nothing replaced


def test_directory_in_the_way_is_refused_before_writing(tmp_path) -> None:
    secs, mv = _small_program()
    (tmp_path / "BLOCK.dat").mkdir()
    with pytest.raises(KrlError, match="BLOCK.dat.*not a file"):
        write_krl(KrlProgramSpec("BLOCK", HOME), secs, mv, tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["BLOCK.dat"]


# --------------------------------------------------------------------------- the lint itself
def _good() -> dict[str, str]:
    rng = np.random.default_rng(SEED)
    secs, mv = _long_job(rng, 6, 900)
    return dict(render_krl(KrlProgramSpec("LINTME", HOME, controller="krc4", page_lines=200,
                                          override_hook="kvp"), secs, mv).files)


def _sub(files: dict[str, str], name: str, old: str, new: str, count: int = 1) -> dict[str, str]:
    out = dict(files)
    assert old in out[name], old
    out[name] = out[name].replace(old, new, count)
    return out


@pytest.mark.parametrize("mutate, rule", [
    (lambda f: _sub(f, "LINTME.src", "\r\n", "\n", 3), "crlf"),
    (lambda f: _sub(f, "LINTME.src", "&COMMENT cctmill", "&COMMENT cctmill \u00e9"), "ascii"),
    (lambda f: _sub(f, "LINTME.dat", "LINTME_F001=", "LINTME_F001_THIS_IS_TOO_LONG_X="), "identifier"),
    (lambda f: {**f, "LINTME.dat": re.sub(r"LINTME_F002=([0-9.]+)", "LINTME_F002=0.00150",
                                          f["LINTME.dat"])}, "vel_cp"),
    (lambda f: {**f, "LINTME.dat": re.sub(r"LINTME_F002=([0-9.]+)", "LINTME_F002=0.000000",
                                          f["LINTME.dat"])}, "vel_cp"),
    (lambda f: {**f, "LINTME.dat": re.sub(r"LINTME_F002=([0-9.]+)", "LINTME_F002=2.500000",
                                          f["LINTME.dat"])}, "vel_cp"),
    (lambda f: {k: v for k, v in f.items() if k != "LINTME_001.dat"}, "pair"),
    (lambda f: _sub(f, "LINTME_001.src", ";ENDFOLD", "; (fold end removed)"), "fold"),
    (lambda f: _sub(f, "LINTME_001.src", "\r\nEND\r\n", "\r\n"), "structure"),
    (lambda f: _sub(f, "LINTME_001.src", "DEF LINTME_001( )", "DEF OTHER( )"), "structure"),
    (lambda f: _sub(f, "LINTME_001.dat", "DEFDAT LINTME_001", "DEFDAT OTHER"), "structure"),
    (lambda f: _sub(f, "LINTME.src", "LINTME_002( ) ;", "LINTME_099( ) ;"), "call"),
    (lambda f: _sub(f, "LINTME.src", "EXT LINTME_002( )\r\n", ""), "call"),
    (lambda f: _sub(f, "LINTME_001.src", "$VEL.CP = LINTME_F001", "$VEL.CP = LINTME_F999"),
     "vel_cp"),
    (lambda f: _sub(f, "LINTME_001.src", "LINTME_SEC = 1", "LINTME_SECTION = 1"), "undeclared"),
    (lambda f: _sub(f, "LINTME.src", "$APO.CDIS = ", "$APO.CPTP = "), "approx"),
    (lambda f: _sub(f, "LINTME_001.src", "$VEL.CP = LINTME_F001", "; feed removed"),
     "feed_first"),
    (lambda f: _sub(f, "LINTME_001.src", ",C ", ",Q ", 1), "motion"),
    (lambda f: _sub(f, "LINTME.src", "DEF LINTME( )", "DEF LINTME( )\r\n&REL 2"), "header"),
    (lambda f: {**f, "LINTME_001.src": f["LINTME_001.src"].replace(
        "END\r\n", "\r\n".join(["; pad"] * 1500) + "\r\nEND\r\n")}, "page_size"),
    (lambda f: {**f, "LINTME_002.src": re.sub(
        r"\nLIN \{([^}]*)\} C_DIS", r"\nCIRC {\1},{\1} C_DIS", f["LINTME_002.src"], count=1)},
     "circ_break"),
])
def test_lint_catches(mutate, rule) -> None:
    good = _good()
    assert lint_krl(good) == []
    assert "LINTME_002.src" in good
    problems = lint_krl(mutate(good))
    assert rule in {p.rule for p in problems}, [str(p) for p in problems]


def test_lint_reads_a_folder(tmp_path) -> None:
    secs, mv = _small_program()
    write_krl(KrlProgramSpec("FOLDER", HOME), secs, mv, tmp_path)
    assert lint_krl(tmp_path) == []
    (tmp_path / "FOLDER.src").write_bytes((tmp_path / "FOLDER.src").read_bytes().replace(
        b"\r\n", b"\n"))
    assert {p.rule for p in lint_krl(tmp_path)} == {"crlf"}


def test_shorter_export_removes_its_own_stale_pages(tmp_path) -> None:
    mv = [KrlMove("LIN", (j, 0, 0, 0, 90, 0), 0) for j in range(600)]
    long_paths = write_krl(KrlProgramSpec("STALE", HOME, page_lines=100), _SEC, mv, tmp_path)
    assert len(long_paths) > 6
    (tmp_path / "STALE_999.src").write_text("user file\r\n")      # not ours: kept
    short = write_krl(KrlProgramSpec("STALE", HOME, page_lines=100), _SEC, mv[:150], tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        [p.name for p in short] + ["STALE_999.src"])
    assert lint_krl({p.name: p.read_bytes() for p in short}) == []


def test_a_page_of_circs_without_a_lin_is_refused() -> None:
    mv = [_MV[0]]
    for j in range(200):        # 200 quarter circles in a row, no LIN between them
        x0 = 10.0 * j
        mv.append(KrlMove("CIRC", (x0 + 10, 0, 0, 0, 90, 0), 0,
                          aux=(x0 + 5, 5, 0, 0, 90, 0)))
    with pytest.raises(KrlError, match="CIRCs without a LIN between them"):
        render_krl(KrlProgramSpec("ARCS", HOME, page_lines=100), _SEC, mv)
    out = render_krl(KrlProgramSpec("ARCS", HOME), _SEC, mv)     # fits one module: fine
    _lint_clean(out.files, "krc4")


def test_joint_ptp_inside_a_section(tmp_path) -> None:
    secs = [KrlSection(0.001), KrlSection(0.2, "rapid", "robot")]
    mv = [KrlMove("LIN", (0, 0, 5, 0, 90, 0), 0), KrlMove("LIN", (10, 0, 5, 0, 90, 0), 0),
          KrlMove("PTP", (5.0, -80.0, 100.0, 0.0, 60.0, 5.0), 1),
          KrlMove("LIN", (20, 0, 50, 0, 90, 0), 1, approx=False)]
    paths = write_krl(KrlProgramSpec("WITH_PTP", HOME), secs, mv, tmp_path)
    _lint_clean({p.name: p.read_bytes() for p in paths}, "krc4")
    src = paths[0].read_bytes().decode("ascii")
    assert "PTP {A1 5.0000,A2 -80.0000,A3 100.0000,A4 0.0000,A5 60.0000,A6 5.0000}\r\n" in src
    tp = read_krl(paths[0])
    assert [m["axes_deg"] for m in tp.meta["joint_moves"] if m["axes_deg"]][-1]["A5"] == 60.0
    _check_round_trip(paths[0], secs, mv)
    assert tp.moves[-1].start is None            # after a joint move the start is not known
