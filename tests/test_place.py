"""Placement studies, serially: grids and placements, one placement's plan as a result (never a
crash), the screen, the refinement, the study's files and the command, the batch form of ``plan``,
the scheduler's choice, Ctrl-C. A small job (a 160 mm rectangle, fixed engagement: ~0.1 s a plan)
keeps it fast; the Dask engines are tested in ``test_place_dask.py``."""

from __future__ import annotations

import json
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest

from models.errors import InputError
from planner.job import load_job, parse_job
from planner.place.engine import (
    SCHEDULER_ENV,
    EngineError,
    SerialEngine,
    open_engine,
    resolve_scheduler,
)
from planner.place.grid import Axis, Placement, PlacementGrid, default_grid, own_placement
from planner.place.refine import MAX_EVALUATIONS, SNAP_MM, refine
from planner.place.screen import ScreenResult, screen_placement, select
from planner.place.search import run_study
from planner.place.spec import JobSpec, cache_info, job_at, job_of
from planner.place.study import PlacementResult, evaluate_placement

PROGRAM = """G21 G90
G0 X0 Y0 Z20
G0 Z2
G1 Z-5 F600
G1 X60 F1200
G1 Y30
G1 X0
G0 Z20
M30
"""

JOB = """material = "al6061"
[job]
name = "small"
toolpath = ["small.nc"]
[cell]
base_mm = [1500.0, -60.0, 400.0]
tcp_mm = [320.0, 0.0, 0.0]
[spindle]
rpm = 4000.0
mass_kg = 100.0
[limits]
deflection_tol_mm = 0.2
feed_min_mm_s = 0.5
feed_max_mm_s = 40.0
cam_feed_scale_max = 2.0
[engagement]
source = "fixed"
ae_mm = 5.0
ap_mm = 5.0
[model]
mass_model = "robot"
[kinematics]
choose_for_stiffness = true
"""

#: Out of the arm's reach (5 m from the base).
FAR = Placement.from_mm_deg(5000.0, 0.0, 0.0, 0.0)


def _write_job(folder: Path, name: str = "small", base_mm: str = "[1500.0, -60.0, 400.0]") -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "small.nc").write_text(PROGRAM, encoding="utf-8")
    p = folder / f"{name}.toml"
    p.write_text(JOB.replace("[1500.0, -60.0, 400.0]", base_mm), encoding="utf-8")
    return p


@pytest.fixture(scope="module")
def job_file(tmp_path_factory) -> Path:
    return _write_job(tmp_path_factory.mktemp("small"))


@pytest.fixture(scope="module")
def spec(job_file) -> JobSpec:
    return JobSpec.from_file(job_file)


@pytest.mark.parametrize(("lo", "hi", "n", "match"), [
    (0.0, 1.0, 0, "at least one value"),
    (1.0, 1.0, 3, "lo < hi"),
    (2.0, 1.0, 2, "lo < hi"),
    (math.nan, 1.0, 2, "finite"),
])
def test_bad_axes_are_refused(lo, hi, n, match):
    with pytest.raises(InputError, match=match):
        Axis(lo, hi, n)


def test_grid_order_keys_and_units():
    g = PlacementGrid(Axis(1.2, 1.5, 2), Axis.single(-0.06), Axis(0.0, 0.8, 3),
                      Axis(0.0, math.radians(30.0), 2))
    ps = g.placements()
    assert len(ps) == len(g) == 12 and g.shape == (2, 1, 3, 2)
    assert ps[0].as_json() == {"x_mm": 1200.0, "y_mm": -60.0, "z_mm": 0.0, "yaw_deg": 0.0}
    assert ps[1].yaw_deg == 30.0 and ps[2].z == 0.4  # yaw innermost, then z
    assert len({p.key for p in ps}) == 12
    # the mm → m → mm round trip gives the job file's numbers back exactly
    assert Placement.from_mm_deg(1500.0, -60.0, 400.0, 0.0).base_mm == [1500.0, -60.0, 400.0]
    assert g.as_json()["z_mm"] == [0.0, 400.0, 800.0]


def test_default_grid_is_around_the_own_placement_inside_the_reach(spec):
    job = job_of(spec)
    g = default_grid(job)
    own = own_placement(job)
    assert g.shape == (5, 5, 3, 1) and g.yaw.lo == own.yaw
    for axis, c in zip(g.axes[:3], (own.x, own.y, own.z), strict=True):
        assert axis.lo <= c <= axis.hi and axis.hi - axis.lo <= 1.2 + 1e-9
    assert own.key in {p.key for p in g.placements()}  # odd counts: the own is a grid point


def test_job_at_moves_only_the_base(spec, job_file):
    p = Placement.from_mm_deg(1200.0, 10.0, 800.0, 15.0)
    moved = job_at(spec, p)
    doc = tomllib.loads(job_file.read_text(encoding="utf-8"))
    doc["cell"]["base_mm"] = [1200.0, 10.0, 800.0]
    doc["cell"]["base_abc_deg"] = [15.0, 0.0, 0.0]
    assert moved == parse_job(doc, str(job_file), job_file.parent.resolve())


def test_the_own_placement_is_the_plan_of_the_job_file(spec, job_file):
    from planner.plan import plan_job

    res = plan_job(load_job(job_file))
    r = evaluate_placement(spec, own_placement(job_of(spec)))
    assert r.feasible and r.cycle_time == res.cycle_time and r.cut_time == res.cut_time
    assert sum(r.binding_counts.values()) == len(res.plan_sections)
    assert r.margin_min == float(res.evaluation.margin.min())
    assert PlacementResult.from_json(r.as_json()) == r


def test_an_unreachable_placement_is_a_result_with_its_reason(spec):
    r = evaluate_placement(spec, FAR)
    assert not r.feasible and r.cycle_time is None and r.score == math.inf
    assert r.error == "UnreachablePoseError" and not r.internal
    assert "reach" in r.reason and "small.nc" in r.reason


def test_an_unexpected_error_is_a_result_marked_internal(spec, monkeypatch):
    import planner.plan

    def boom(*a, **k):
        raise RuntimeError("casadi said no")

    monkeypatch.setattr(planner.plan, "plan_job", boom)
    r = evaluate_placement(spec, own_placement(job_of(spec)))
    assert not r.feasible and r.internal and r.reason == "RuntimeError: casadi said no"


def test_a_worker_without_the_files_plans_from_the_shipped_bytes(tmp_path):
    f = _write_job(tmp_path / "gone")
    spec = JobSpec.from_file(f)
    (tmp_path / "gone" / "small.nc").unlink()  # as on a machine that does not share the disk
    r = evaluate_placement(spec, FAR)
    assert r.error == "UnreachablePoseError"
    assert str(tmp_path / "gone" / "small.nc") in r.reason  # the user's path, not the copy's
    assert cache_info()["copied"] >= 1
    assert evaluate_placement(spec, own_placement(job_of(spec))).feasible


def test_the_screen_estimates_the_cut_and_finds_the_unreachable(spec):
    own = own_placement(job_of(spec))
    s = screen_placement(spec, own)
    r = evaluate_placement(spec, own)
    assert s.feasible and 0.8 * r.cut_time < s.cut_time_estimate < 1.2 * r.cut_time
    far = screen_placement(spec, FAR)
    assert not far.feasible and far.reason.startswith("screen: ") and "reach" in far.reason


def test_select_keeps_the_feasible_within_the_ratio():
    p = [Placement.from_mm_deg(float(i), 0.0, 0.0, 0.0) for i in range(4)]
    rs = [ScreenResult(p[0], True, 10.0), ScreenResult(p[1], True, 12.9),
          ScreenResult(p[2], True, 13.1), ScreenResult(p[3], False, reason="screen: reach")]
    assert select(rs, 1.3) == [p[0], p[1]]
    assert select(rs[3:], 1.3) == []


def _bowl(ps: list[Placement]) -> list[PlacementResult]:
    """A smooth objective with its minimum at x 1.62 m, z 0.5 m; no plan beyond x 1.75 m."""
    out = []
    for p in ps:
        if p.x > 1.75:
            out.append(PlacementResult(p, False, reason="out of reach", error="Unreachable"))
        else:
            out.append(PlacementResult(p, True, cycle_time=100.0 + ((p.x - 1.62) / 0.1) ** 2
                                       + ((p.z - 0.5) / 0.1) ** 2))
    return out


def test_refine_walks_to_the_minimum_of_a_bowl_within_its_budget():
    grid = PlacementGrid(Axis(1.2, 1.8, 3), Axis.single(-0.06), Axis(0.0, 0.8, 3),
                         Axis.single(0.0))
    start = _bowl([Placement(1.5, -0.06, 0.4, 0.0)])[0]
    calls: list[int] = []

    def evaluate(ps):
        calls.append(len(ps))
        return _bowl(ps)

    res = refine(evaluate, start, grid)
    assert res.axes == ("x", "z") and calls[0] == 2  # the simplex's two new vertices at once
    assert len(res.evaluated) <= MAX_EVALUATIONS
    b = res.best.placement
    assert res.best.score < start.score and abs(b.x - 1.62) < 0.01 and abs(b.z - 0.5) < 0.01
    assert b.y == -0.06 and b.yaw == 0.0  # the grid's single values stay
    for r in res.evaluated:  # snapped to the setter's resolution, inside the box
        for v in r.placement.base_mm:
            assert abs(v / SNAP_MM - round(v / SNAP_MM)) < 1e-6
        assert 1.2 - 1e-9 <= r.placement.x <= 1.8 + 1e-9


def test_refine_needs_a_varied_axis_and_a_feasible_start():
    grid = PlacementGrid(*(Axis.single(v) for v in (1.5, -0.06, 0.4, 0.0)))
    start = _bowl([Placement(1.5, -0.06, 0.4, 0.0)])[0]
    res = refine(_bowl, start, grid)
    assert res.best is start and res.evaluated == [] and res.message == "nothing to refine"


def test_serial_study_finds_the_best_and_ranks_by_the_plan(spec):
    grid = PlacementGrid(Axis(1.2, 1.8, 3), Axis.single(-0.06), Axis(0.4, 0.8, 2),
                         Axis.single(0.0))
    with SerialEngine() as eng:
        study = run_study(spec, grid, eng, screen=1.3)
    assert study.screen is not None and len(study.screen) == len(grid)
    kept = {r.placement.key for r in study.results}
    assert kept | {p.key for p in study.pruned} == {p.key for p in grid.placements()}
    best = study.best
    assert best is not None and best.score == min(r.score for r in study.candidates())
    assert study.speedup == study.own.score / best.score
    doc = study.as_json()
    assert doc["complete"] and doc["counts"]["pruned_by_screen"] == len(study.pruned)
    json.dumps(doc, allow_nan=False)  # place.json is strict JSON


def test_place_command_writes_place_json_heatmap_and_the_best_report(job_file, tmp_path, capsys):
    from planner.cli import main

    out = tmp_path / "place"
    rc = main(["place", str(job_file), "-o", str(out), "--x-mm", "1200:1800:3", "--y-mm", "-60",
               "--z-mm", "400:800:2", "--scheduler", "none", "--refine", "--refine-plans", "6"])
    text = capsys.readouterr().out
    assert rc == 0
    assert "best $BASE: base_mm = [" in text and "% faster" in text
    doc = json.loads((out / "place.json").read_text(encoding="utf-8"))
    assert doc["schema"] == "cctmill.place/1" and doc["complete"]
    grid_rows = [r for r in doc["placements"] if r["stage"] == "grid"]
    assert len(grid_rows) == 6 and len({(r["x_mm"], r["z_mm"]) for r in grid_rows}) == 6
    for r in doc["placements"]:
        assert r["feasible"] == (r["cycle_time_s"] is not None) == (r["reason"] is None)
    assert doc["refine"]["plans"] <= 6
    assert doc["best"]["cycle_time_s"] <= min(r["cycle_time_s"] for r in grid_rows if r["feasible"])
    assert not list(out.glob(".place.json.*"))  # atomic: no temporary left behind
    png = out / "place_heatmap.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    report = (out / "best" / "report.html").read_text(encoding="utf-8")
    assert 'id="placement"' in report and "fastest placements" in report
    best_plan = json.loads((out / "best" / "plan.json").read_text(encoding="utf-8"))
    assert best_plan["cycle_time_s"] == pytest.approx(doc["best"]["cycle_time_s"], rel=1e-12)


@pytest.mark.parametrize(("argv", "match"), [
    (["--x-mm", "1:2"], "A:B:N"),
    (["--z-mm", "400:800:0"], "at least one value"),
    (["--yaw-deg", "a:b:2"], "A:B:N"),
    (["--scheduler", "somewhere"], "not a scheduler"),
])
def test_place_command_refuses_bad_ranges_in_one_line(job_file, tmp_path, capsys, argv, match):
    from planner.cli import main

    rc = main(["place", str(job_file), "-o", str(tmp_path / "o"), "--y-mm", "-60",
               "--x-mm", "1500", "--z-mm", "400", *argv])
    err = capsys.readouterr().err
    assert rc == 2 and match in err and err.count("\n") <= 2


def test_the_scheduler_is_the_flag_then_the_environment_then_the_job(monkeypatch):
    monkeypatch.delenv(SCHEDULER_ENV, raising=False)
    assert resolve_scheduler() == "local"
    assert resolve_scheduler(None, "none") == "none"
    monkeypatch.setenv(SCHEDULER_ENV, "tcp://10.0.0.5:8786")
    assert resolve_scheduler(None, "none") == "tcp://10.0.0.5:8786"
    assert resolve_scheduler("none", "local") == "none"
    with pytest.raises(EngineError, match="CCTMILL_SCHEDULER: 'x' is not a scheduler"):
        monkeypatch.setenv(SCHEDULER_ENV, "x")
        resolve_scheduler()


def test_no_scheduler_at_the_address_says_how_to_start_one(monkeypatch):
    import socket

    import planner.place.engine as engine

    monkeypatch.setattr(engine, "CONNECT_TIMEOUT", 1.0)
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    with pytest.raises(EngineError, match="no Dask scheduler answers there.*dask scheduler"):
        open_engine(f"tcp://127.0.0.1:{port}")


def test_ctrl_c_stops_the_study_and_writes_what_finished(spec, tmp_path, monkeypatch):
    import planner.place.search as search
    from planner.place.outputs import write_place_outputs

    calls = []

    def interrupted_at_the_third(s, p):
        calls.append(p)
        if len(calls) == 3:
            raise KeyboardInterrupt
        return evaluate_placement(s, p)

    monkeypatch.setattr(search, "evaluate_placement", interrupted_at_the_third)
    grid = PlacementGrid(Axis(1.2, 1.8, 3), Axis.single(-0.06), Axis.single(0.4), Axis.single(0.0))
    with SerialEngine() as eng:
        study = run_study(spec, grid, eng, refine_best=True)
    assert study.interrupted and study.refinement is None
    assert len(study.candidates()) == 2
    files = write_place_outputs(study, spec, tmp_path)
    doc = json.loads(files["place"].read_text(encoding="utf-8"))
    assert doc["interrupted"] and not doc["complete"]
    assert len({(r["x_mm"], r["z_mm"]) for r in doc["placements"]}) == 2  # own = a grid point
    assert "best_report" not in files and not (tmp_path / "best").exists()


def test_batch_plans_every_job_into_its_own_folder(tmp_path, capsys):
    from planner.batch import folder_names
    from planner.cli import main

    a = _write_job(tmp_path / "a", "job")
    b = _write_job(tmp_path / "b", "job", base_mm="[1200.0, -60.0, 800.0]")
    far = _write_job(tmp_path / "c", "far", base_mm="[5000.0, 0.0, 0.0]")
    assert folder_names([a, b, far]) == ["job", "job-2", "far"]
    out = tmp_path / "out"
    rc = main(["plan", str(a), str(b), str(far), "-o", str(out), "--scheduler", "none"])
    text = capsys.readouterr().out
    assert rc == 2 and "2 of 3 jobs planned" in text and "UnreachablePoseError" in text
    doc = json.loads((out / "batch.json").read_text(encoding="utf-8"))
    assert [j["ok"] for j in doc["jobs"]] == [True, True, False]
    for j, name in zip(doc["jobs"][:2], ("job", "job-2"), strict=True):
        plan = json.loads((out / name / "plan.json").read_text(encoding="utf-8"))
        assert plan["cycle_time_s"] == pytest.approx(j["cycle_time_s"], rel=1e-12)
        assert (out / name / "report.html").is_file()
    assert not (out / "far").exists()
    assert doc["jobs"][0]["cycle_time_s"] != doc["jobs"][1]["cycle_time_s"]  # moved base


def test_engine_keys_must_be_unique():
    with pytest.raises(ValueError, match="unique"):
        SerialEngine().map(lambda s, i: i, None, "k", [("a", 1), ("a", 2)])
    out = SerialEngine().map(lambda s, i: 1 / i, None, "k", [("a", 1), ("b", 0)])
    assert out.results == {"a": 1.0} and "ZeroDivisionError" in out.failed["b"]
    assert np.isfinite(out.wall_time)
