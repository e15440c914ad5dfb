"""Tests of the plan → KRL export (planner.export) and ``cctmill export``.

Plans are synthetic (written with planner.plan_file.write_plan, obeying its contract: sections
partition the samples, arc samples lie on their arc) plus the bundled demo job planned by
planner.plan.plan_job. Every export is linted (robot_io.krl.lint) and read back with
robot_io.krl.reader: each move target within 0.001 mm / 0.001°, every plan sample on the read-back
path within 0.001 mm, every section feed exactly the .dat value (and the plan's feed rounded down
to 1e-9 m/s).
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import replace
from importlib import resources
from pathlib import Path

import numpy as np
import pytest

from planner.cli import main
from planner.export import (
    CIRC_MAX_SWEEP_DEG,
    FEED_RESOLUTION_M_S,
    ExportError,
    export_plan,
    plan_to_krl,
)
from planner.plan_file import KINDS, SAMPLE_ARRAYS, PlanFileError, load_plan, write_plan
from robot_io.krl import KrlError
from robot_io.krl.lint import lint_krl
from robot_io.krl.reader import abc_to_matrix, read_krl
from robot_io.toolpath import MoveKind, arc_geometry

SEED = 20240611
POS_TOL_MM = 1e-3
ANG_TOL_DEG = 1e-3
HOME_RAD = np.radians([0.0, -90.0, 90.0, 0.0, 45.0, 0.0])


# --------------------------------------------------------------------------- synthetic plans
class _Builder:
    """Samples in the workpiece frame [m], with kinds, arc flags and move ids."""

    def __init__(self) -> None:
        self.p: list[np.ndarray] = []
        self.abc: list[tuple[float, float, float]] = []
        self.kind: list[int] = []
        self.arcs: list[bool] = []
        self.move: list[int] = []
        self.n_moves = 0

    def line(self, end_mm, kind: str, steps: int, abc=(0.0, 90.0, 0.0)) -> None:
        start = self.p[-1] if self.p else np.asarray(end_mm, float) * 1e-3
        end = np.asarray(end_mm, float) * 1e-3
        for t in np.arange(1, steps + 1) / steps if self.p else [1.0]:
            self._add(start + t * (end - start), kind, False, abc)
        self.n_moves += 1

    def arc(self, centre_mm, sweep_deg: float, kind: str, steps: int, dz_mm: float = 0.0,
            abc=(0.0, 90.0, 0.0)) -> None:
        c = np.asarray(centre_mm, float) * 1e-3
        start = self.p[-1]
        r0 = start - c
        radius = math.hypot(r0[0], r0[1])
        th0 = math.atan2(r0[1], r0[0])
        for t in np.arange(1, steps + 1) / steps:
            th = th0 + math.radians(sweep_deg) * t
            self._add(np.array([c[0] + radius * math.cos(th), c[1] + radius * math.sin(th),
                                start[2] + dz_mm * 1e-3 * t]), kind, True, abc)
        self.n_moves += 1

    def _add(self, p, kind, arc, abc) -> None:
        self.p.append(np.asarray(p, float))
        self.abc.append(tuple(abc))
        self.kind.append(KINDS.index(kind))
        self.arcs.append(arc)
        self.move.append(self.n_moves)


def _write_synthetic(folder: Path, b: _Builder, cuts: list[tuple[int, int, str, float, str]],
                     rng, solver_ok: bool = True, job_name: str = "bracket γ test") -> Path:
    n = len(b.p)
    samples = {k: np.zeros((n, *tail)) for k, tail in SAMPLE_ARRAYS.items()}
    pos = np.array(b.p)
    samples["position_wp_m"] = pos
    samples["abc_wp_deg"] = np.array(b.abc)
    samples["s_m"] = np.concatenate([[0], np.cumsum(np.linalg.norm(np.diff(pos, axis=0), axis=1))])
    samples["kind"] = np.array(b.kind)
    samples["arc"] = np.array(b.arcs)
    samples["move"] = np.array(b.move)
    q = np.tile(HOME_RAD, (n, 1)) + rng.normal(0, 0.01, (n, 6))
    q[0] = HOME_RAD
    samples["q_rad"] = q
    defl = rng.normal(0, 2e-5, (n, 3))
    defl[samples["kind"] == KINDS.index("rapid")] = np.nan
    samples["deflection_wp_m"] = defl
    section = np.zeros(n, int)
    rows = []
    for i, (a, stop, kind, feed_mm_s, binding) in enumerate(cuts):
        section[a:stop] = i + 1                  # the files number sections from 1
        rows.append({"index": i + 1, "kind": kind, "sample_start": a, "sample_stop": stop,
                     "s_start_m": float(samples["s_m"][a]),
                     "s_end_m": float(samples["s_m"][stop - 1]), "feed_mm_s": feed_mm_s,
                     "binding": binding, "margin_N_per_m": 1.5e4, "force_max_N": 120.0,
                     "line_start": 10 + i, "line_end": 11 + i, "file": "/jobs/part.nc"})
    samples["section"] = section
    samples["feed_mm_s"] = np.array([rows[s - 1]["feed_mm_s"] or 0.0 for s in section], float)
    data = {
        "method": "optimize", "job_name": job_name, "job_file": "/jobs/part.toml",
        "robot": "kr210_r2700_extra",
        "base_frame": {"xyz_mm": [1500.0, -60.0, 400.0], "abc_deg": [10.0, 0.0, 0.0]},
        "tool_frame": {"xyz_mm": [320.0, 0.0, 0.0], "abc_deg": [0.0, 0.0, 0.0]},
        "constraints": {}, "sections": rows, "cycle_time_s": 12.5,
        "solver": {"status": "Solve_Succeeded" if solver_ok else "Maximum_Iterations_Exceeded",
                   "success": solver_ok, "iterations": 12},
    }
    return write_plan(folder, data, samples)


def _demo_like(folder: Path, rng, **kw) -> Path:
    """Approach (rapid), plunge (air), a wall, a 90° arc, a 270° arc cut by a section boundary,
    a helix, a 5-axis arc, a retract."""
    b = _Builder()
    b.line((-10, 0, 50), "rapid", 1)
    b.line((-10, 0, 5), "rapid", 3)
    b.line((-10, 0, -2), "air", 4)
    b.line((40, 0, -2), "cut", 25, abc=(15.0, 90.0, 0.0))            # samples 8..32
    b.arc((40, 10, -2), 90, "cut", 12)                                # 33..44
    b.arc((40, 20, -2), 270, "cut", 40)                               # 45..84, split at 60
    b.arc((50, 20, -2), -180, "cut", 20, dz_mm=-1.0)                  # helix 85..104
    b.arc((60, 20, -3), 90, "cut", 10, abc=(0.0, 80.0, 0.0))          # tool axis turns? no
    b.line((70, 20, 30), "air", 10)
    n = len(b.p)
    # make the tool axis turn along the last arc (a 5-axis arc: must stay LINs)
    for j, i in enumerate(range(105, 115)):
        b.abc[i] = (0.0, 90.0 - 2.0 * (j + 1), 0.0)
    cuts = [(0, 4, "rapid", None, "robot"), (4, 8, "air", 5.0, "feed_max"),
            (8, 33, "cut", 1.2345678912, "chatter"), (33, 60, "cut", 2.0, "force"),
            (60, 105, "cut", 0.8, "deflection"), (105, 115, "cut", 1.1, "power"),
            (115, n, "air", 50.0, "feed_max")]
    return _write_synthetic(folder, b, cuts, rng, **kw)


def _point_on_move(p_mm: np.ndarray, move) -> float:
    """Distance [mm] from a point to the read-back move (segment or arc circle)."""
    if move.kind in (MoveKind.ARC_CW, MoveKind.ARC_CCW):
        c, nrm = move.center * 1e3, move.normal
        r = np.linalg.norm(move.end * 1e3 - c)
        d = p_mm - c
        off = d @ nrm
        return float(math.hypot(off, np.linalg.norm(d - off * nrm) - r))
    a, b = move.start * 1e3, move.end * 1e3
    t = np.clip((p_mm - a) @ (b - a) / max((b - a) @ (b - a), 1e-30), 0, 1)
    return float(np.linalg.norm(a + t * (b - a) - p_mm))


def _check_export(plan_path: Path, paths: list[Path], controller: str, compensate: bool = False,
                  **kw) -> dict:
    """Lint, read back and compare with the plan; return facts for further asserts."""
    assert lint_krl({p.name: p.read_bytes() for p in paths}, controller=controller) == []
    plan = load_plan(plan_path)
    prog = plan_to_krl(plan, controller=controller, compensate=compensate, **kw)
    tp = read_krl(paths[0])
    assert len(tp.moves) == len(prog.moves)
    s = plan.samples
    pos = s.position_wp - (np.nan_to_num(s.deflection_wp) if compensate else 0.0)
    pos_mm = pos * 1e3
    dat = "".join(p.read_text(encoding="ascii") for p in paths if p.suffix == ".dat")
    decl = {m.group(1): float(m.group(2))
            for m in re.finditer(r"DECL GLOBAL REAL (\w+_F\d+)=([0-9.]+)", dat)}
    names = sorted(decl)
    covered = np.zeros(len(pos), bool)
    prev_target = -1
    for got, want, i, feed in zip(tp.moves, prog.moves, prog.sample_of_move, prog.move_feeds,
                                  strict=True):
        assert got.kind == (MoveKind.ARC_CCW if want.kind == "CIRC" else MoveKind.LINEAR)
        # the move's target is plan sample i
        np.testing.assert_allclose(got.end * 1e3, pos_mm[i], atol=POS_TOL_MM, rtol=0)
        r = abc_to_matrix(*got.extra["abc_deg"]).T @ abc_to_matrix(*np.degrees(s.abc_wp[i]))
        assert math.degrees(math.acos(min(1.0, (np.trace(r) - 1) / 2))) < ANG_TOL_DEG
        # every sample the move absorbed lies on it
        for j in range(prev_target + 1, i):
            assert _point_on_move(pos_mm[j], got) < POS_TOL_MM, (j, got.kind)
        covered[prev_target + 1:i + 1] = True
        prev_target = i
        # feeds: exactly the .dat value; the plan's rounded down to the resolution
        k = int(s.section[i])
        # (a feed profile: the .dat value times the move's scale, test_feed_profile.py)
        assert got.feed == feed
        profiled = not np.all(s.feed[s.section == k] == plan.sections[k].feed)
        assert got.feed == decl[names[k]] or (profiled and got.feed <= s.feed[i])
        sec = plan.sections[k]
        if math.isfinite(sec.feed) and not profiled:
            assert 0 <= sec.feed - got.feed < FEED_RESOLUTION_M_S * 1.0001
    assert covered.all()
    return {"tp": tp, "prog": prog, "decl": decl}


# --------------------------------------------------------------------------- round trips
@pytest.mark.parametrize("controller", ["krc2", "krc4"])
def test_synthetic_plan_round_trip(tmp_path, controller) -> None:
    rng = np.random.default_rng(SEED)
    plan = _demo_like(tmp_path / "plan", rng)
    paths = export_plan(plan, tmp_path / "krl", controller=controller)
    assert [p.name for p in paths] == ["bracket_gamma_test.src", "bracket_gamma_test.dat"]
    facts = _check_export(plan, paths, controller)
    prog, tp = facts["prog"], facts["tp"]
    by_section = {}
    for m in prog.moves:
        by_section.setdefault(m.section, []).append(m.kind)
    assert set(by_section[2]) == {"LIN"}                        # the wall
    assert by_section[3].count("CIRC") == 2                     # 90° arc + part of the 270° one
    assert by_section[4].count("CIRC") >= 1                     # rest of the 270° arc
    assert by_section[4][-20:] == ["LIN"] * 20                  # the helix stays LINs
    assert set(by_section[5]) == {"LIN"}                        # tool axis turns: LINs
    for m in tp.moves:
        if m.kind == MoveKind.ARC_CCW:
            assert abs(math.degrees(arc_geometry(m)["sweep"])) <= CIRC_MAX_SWEEP_DEG + 1e-6
    assert facts["decl"]["bracket_gamma_test_F001"] == 0.2      # rapid: no planned feed
    assert facts["decl"]["bracket_gamma_test_F003"] == 0.001234567
    assert tp.moves[-1].extra.get("approx") is None             # the last move stops exactly
    src = paths[0].read_text(encoding="ascii")
    assert "bound by chatter" in src and "plan section 3; source lines 12-13 of part.nc" in src
    assert "$BASE = {FRAME: X 1500.0000,Y -60.0000,Z 400.0000,A 10.0000" in src


def test_compensation_mirrors_the_deflection(tmp_path) -> None:
    rng = np.random.default_rng(SEED)
    plan = _demo_like(tmp_path / "plan", rng)
    paths = export_plan(plan, tmp_path / "krl", compensate=True)
    facts = _check_export(plan, paths, "krc4", compensate=True)
    src = paths[0].read_text(encoding="ascii")
    assert "path pre-compensated: every position minus the predicted static deflection" in src
    # compensated arcs are no longer circles: no CIRC, all LINs
    assert {m.kind for m in facts["prog"].moves} == {"LIN"}
    targets = np.array([m.target[:3] for m in facts["prog"].moves])
    plain = load_plan(plan).samples.position_wp * 1e3
    assert facts["prog"].sample_of_move == tuple(range(len(plain)))
    assert np.abs(targets - plain).max() > 0.03                # it did move the path
    np.testing.assert_allclose(targets[:4], plain[:4], atol=1e-4)   # rapids (NaN) stay


def test_long_plan_pages_and_round_trips(tmp_path) -> None:
    rng = np.random.default_rng(SEED)
    b = _Builder()
    b.line((0, 0, 20), "rapid", 1)
    b.line((0, 0, -1), "air", 5)
    y = 0.0
    while len(b.p) < 12_000:
        y += 2.0
        b.line((300 if (y / 2) % 2 else 0, y, -1), "cut", 150)
        b.arc((300 if (y / 2) % 2 else 0, y + 1, -1), 180 if (y / 2) % 2 else -180, "cut", 6)
        y += 2.0
    n = len(b.p)
    bounds = [6, 2500, 2600, 9000, n]
    cuts = [(0, 1, "rapid", None, "robot"), (1, 6, "air", 5.0, "feed_max")]
    cuts += [(a, z, "cut", float(f), "chatter") for a, z, f in
             zip(bounds[:-1], bounds[1:], rng.uniform(0.5, 2.0, 4), strict=True)]
    plan = _write_synthetic(tmp_path / "plan", b, cuts, rng, job_name="long zigzag")
    paths = export_plan(plan, tmp_path / "krl", controller="krc2", override_hook="kvp")
    names = [p.name for p in paths]
    assert names[:2] == ["long_zigzag.src", "long_zigzag.dat"] and len(names) >= 14
    assert max(p.read_bytes().count(b"\r\n") for p in paths) <= 2000
    facts = _check_export(plan, paths, "krc2", override_hook="kvp")
    assert len(facts["prog"].moves) >= 10_000
    assert facts["tp"].meta["modules"][1].endswith("long_zigzag_001.src")


def test_demo_job_round_trip(tmp_path) -> None:
    from planner.job import load_job
    from planner.outputs import write_plan_outputs
    from planner.plan import plan_job

    job = load_job(str(resources.files("planner").joinpath("data/demo/demo_job.toml")))
    res = plan_job(job)
    plan = write_plan_outputs(res, tmp_path / "plan", report=False).files["plan"]
    for controller, hook in (("krc4", "rsi"), ("krc2", "kvp")):
        paths = export_plan(plan, tmp_path / controller, controller=controller,
                            override_hook=hook)
        facts = _check_export(plan, paths, controller, override_hook=hook)
        assert sum(m.kind == "CIRC" for m in facts["prog"].moves) > 0
        assert len(facts["decl"]) == len(load_plan(plan).sections)


# --------------------------------------------------------------------------- refusals
def test_unconverged_plan_is_refused(tmp_path) -> None:
    plan = _demo_like(tmp_path / "plan", np.random.default_rng(SEED), solver_ok=False)
    with pytest.raises(ExportError, match="did not converge.*Maximum_Iterations_Exceeded"):
        export_plan(plan, tmp_path / "krl")
    assert not (tmp_path / "krl").exists()


def test_nan_feed_names_the_section_and_writes_nothing(tmp_path) -> None:
    plan = _demo_like(tmp_path / "plan", np.random.default_rng(SEED))
    out = tmp_path / "krl"
    export_plan(plan, out)
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    loaded = load_plan(plan)
    secs = loaded.sections[:-1] + (replace(loaded.sections[-1], feed=math.nan),)  # NaN in memory
    with pytest.raises(KrlError, match="section 7 feed.*not a number"):
        export_plan(replace(loaded, sections=secs), out)
    assert {q.name: q.read_bytes() for q in out.iterdir()} == before
    doc = json.loads(plan.read_text(encoding="utf-8"))
    doc["sections"][-1]["feed_mm_s"] = None                     # null in the file: refused on load
    with np.load(plan.parent / "samples.npz") as z:
        arrays = {k: z[k] for k in z.files}
    write_plan(tmp_path / "plan", {k: v for k, v in doc.items()
                                   if k not in ("format", "version", "samples_file")}, arrays)
    with pytest.raises(PlanFileError, match=r"sections\[6\]\.feed_mm_s: .*got None"):
        export_plan(plan, out)
    assert {q.name: q.read_bytes() for q in out.iterdir()} == before


def test_bad_sections_are_refused(tmp_path) -> None:
    plan = _demo_like(tmp_path / "plan", np.random.default_rng(SEED))
    p = load_plan(plan)
    secs = list(p.sections)
    secs[2] = replace(secs[2], sample_start=secs[2].sample_start + 1)
    with pytest.raises(ExportError, match="partition the samples"):
        plan_to_krl(replace(p, sections=tuple(secs)))


# --------------------------------------------------------------------------- CLI
def test_cli_export(tmp_path, capsys) -> None:
    plan = _demo_like(tmp_path / "plan", np.random.default_rng(SEED))
    out = tmp_path / "krl"
    rc = main(["export", str(plan.parent), "-o", str(out), "--name", "PART_7",
               "--controller", "krc2", "--override-hook", "kvp", "--base-index", "3"])
    text = capsys.readouterr().out
    assert rc == 0
    assert "KRL program PART_7 for KR C2: 7 sections" in text and "1 page" in text
    assert re.search(r"^\s+3 cut\s+1\.234567 chatter\s+25$", text, re.M)
    assert sorted(p.name for p in out.iterdir()) == ["PART_7.dat", "PART_7.src"]
    assert "$BASE = BASE_DATA[3]" in (out / "PART_7.src").read_text(encoding="ascii")


@pytest.mark.parametrize("argv, match", [
    (["--name", "X" * 25], r"25 characters; KRL allows at most 24"),
    (["--name", "2PART"], r"must not start with a digit"),
    (["--controller", "krc2", "--override-hook", "rsi"], r"KR C4"),
    (["--apo-cdis-mm", "0"], r"APO.CDIS"),
])
def test_cli_export_errors(tmp_path, capsys, argv, match) -> None:
    plan = _demo_like(tmp_path / "plan", np.random.default_rng(SEED))
    rc = main(["export", str(plan), "-o", str(tmp_path / "krl"), *argv])
    err = capsys.readouterr().err
    assert rc == 2
    assert err.startswith("cctmill export: error:") and err.count("\n") == 1
    assert re.search(match, err)
    assert not (tmp_path / "krl").exists()


def test_cli_export_missing_plan(tmp_path, capsys) -> None:
    assert main(["export", str(tmp_path / "nope"), "-o", str(tmp_path / "krl")]) == 2
    assert "cctmill plan" in capsys.readouterr().err


def test_cli_plan_krl_flags(tmp_path, capsys) -> None:
    rc = main(["plan", "--demo", "-o", str(tmp_path), "--json", "--krl", "--name", "DEMO_KRC2",
               "--controller", "krc2", "--override-hook", "kvp", "--tool-index", "4"])
    doc = json.loads(capsys.readouterr().out)
    assert rc == 0
    assert [Path(p).name for p in doc["written"]["krl"]] == ["DEMO_KRC2.src", "DEMO_KRC2.dat"]
    assert lint_krl(tmp_path, controller="krc2") == []
    src = (tmp_path / "DEMO_KRC2.src").read_text(encoding="ascii")
    assert "$TOOL = TOOL_DATA[4]" in src and "DEMO_KRC2_SEC = 1" in src
    assert len(read_krl(tmp_path / "DEMO_KRC2.src").moves) > 100


def test_demo_writes_the_krl(tmp_path, capsys) -> None:
    assert main(["demo", "-o", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    krl = tmp_path / "krl"
    names = sorted(p.name for p in krl.iterdir())
    # no temporaries (the demo's feed profile writes more lines: it may be paged)
    assert names[:2] == ["bracket_contour.dat", "bracket_contour.src"]
    assert all(re.fullmatch(r"bracket_contour(_\d{3})?\.(src|dat)", x) for x in names), names
    assert str(krl / "bracket_contour.src") in out
    assert lint_krl(krl, controller="krc4") == []
    _check_export(tmp_path / "plan.json", [krl / n for n in [names[1], names[0], *names[2:]]],
                  "krc4")
