"""Test passes that imitate the job's own sections (planner/calibrate/testcuts.py: section
templates, the space-filling start along the job, value of information among them), the
``testcuts --design along-job`` command, and the planner's refusal when the calibrated boundary
asks for more margin than any feed gives."""

from __future__ import annotations

import dataclasses
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from planner.calibrate.context import CalibrationContext
from planner.calibrate.fit_boundary import fit_boundary
from planner.calibrate.testcuts import along_job_cuts, propose_along_job, section_templates
from planner.job import load_job
from planner.plan import PlanInfeasibleError, plan_job, plan_of_result

DEMO = Path(__file__).resolve().parents[1] / "planner" / "data" / "demo"


@pytest.fixture(scope="module")
def job():
    return load_job(DEMO / "demo_job.toml")


@pytest.fixture(scope="module")
def templates(job):
    return section_templates(plan_of_result(plan_job(job)), job.tool.name)


def test_one_template_per_cut_section_with_its_cut(job, templates):
    plan = plan_of_result(plan_job(job))
    cuts = [s for s in plan.sections if s.kind == "cut"]
    assert 0 < len(templates) <= len(cuts)
    for t in templates[:: max(1, len(templates) // 10)]:
        assert t.verdict == "unknown" and t.source["design"] == "job section"
        assert np.linalg.norm(t.feed_dir) == pytest.approx(1.0, abs=1e-5)
        assert abs(np.dot(t.feed_dir, t.radial_dir)) < 1e-5
        assert t.rpm == job.spindle.rpm and 0 < t.ap_mm <= 10.0 + 1e-9
        sec = plan.sections[t.source["section"] - 1]
        assert t.feed_mm_s == pytest.approx(sec.feed * 1e3, rel=1e-4)


def test_the_space_filling_start_spreads_depths_and_sections(templates):
    passes = along_job_cuts(templates, 8, (2.0, 12.0), seed=3)
    depths = np.array([p.ap_mm for p in passes])
    assert sorted(np.floor((depths - 2.0) / 10.0 * 8).astype(int)) == list(range(8))  # stratified
    assert len({p.source["section"] for p in passes}) == 8
    for p in passes:
        t = next(t for t in templates if t.source["section"] == p.source["section"])
        assert (p.joints_deg, p.feed_dir, p.ae_mm, p.feed_mm_s) == (t.joints_deg, t.feed_dir,
                                                                   t.ae_mm, t.feed_mm_s)


def test_value_of_information_along_the_job_aims_at_the_boundary(job, templates):
    ctx = CalibrationContext.from_job(job)
    rng = np.random.default_rng(0)
    start = along_job_cuts(templates, 16, (1.0, 12.0), seed=1)
    labelled = [dataclasses.replace(r, verdict="chatter" if r.ap_mm > 6.0 else "stable")
                for r in start]
    labelled = [dataclasses.replace(r, verdict="stable" if rng.random() < 0.1 and
                                    r.verdict == "chatter" else r.verdict) for r in labelled]
    picks = propose_along_job(ctx, fit_boundary(ctx, labelled), templates, 4, (1.0, 12.0),
                              every=10, grid_mm=0.5)
    assert len(picks) == 4 and len({(r.rpm, r.ap_mm) for r in picks}) == 4
    assert abs(picks[0].source["p_chatter"] - 0.5) < 0.35


def test_a_boundary_no_feed_satisfies_refuses_the_plan_naming_it(tmp_path):
    for f in DEMO.iterdir():
        shutil.copy(f, tmp_path / f.name)
    # a boundary saying "chatter above 5 mm whatever the margin" (almost: a tiny margin slope)
    (tmp_path / "o.toml").write_text(
        '[calibration]\nboundary_criterion = "eigen"\n'
        'boundary_features = ["margin", "ap_mm", "rpm"]\nboundary_mean = [4e5, 5.0, 4000.0]\n'
        'boundary_scale = [1e5, 1.0, 1000.0]\nboundary_coef = [-0.01, 4.0, 0.0]\n'
        'boundary_intercept = 0.0\n')
    text = (tmp_path / "demo_job.toml").read_text().replace(
        'chatter_criterion = "eigen"', 'chatter_criterion = "eigen"\nchatter_probability_max = 0.1')
    (tmp_path / "demo_job.toml").write_text(text + '\n[calibration]\noverlay = "o.toml"\n')
    with pytest.raises(PlanInfeasibleError, match=r"chatter limit cannot be met .* N/m that "
                                                  r"P\(chatter\) <= 0\.1 needs by the calibrated "
                                                  r"boundary at every feed .*the depths of cut\); "
                                                  r"the calibrated boundary accepts a_p <= "
                                                  r"(\d\.\d\d) mm at 4000 rpm here") as info:
        plan_job(load_job(tmp_path / "demo_job.toml"))
    assert info.value.constraint == "chatter"
    # the hint solves logit = ln(0.1/0.9) for a_p: 4 (a_p − 5) − 0.01 (m − 4e5)/1e5 at its margin
    margin = float(re.search(r"margin (\S+) N/m below", str(info.value)).group(1))
    depth = 5.0 + (np.log(1 / 9) + 0.01 * (margin - 4e5) / 1e5) / 4.0
    assert float(re.search(r"a_p <= (\S+) mm", str(info.value)).group(1)) == pytest.approx(
        depth, abs=0.01)


def test_testcuts_command_along_the_job_writes_krl_and_planned_records(tmp_path, capsys):
    from planner.calibrate.records import load_records
    from planner.cli import main

    for f in DEMO.iterdir():
        shutil.copy(f, tmp_path / f.name)
    rc = main(["testcuts", str(tmp_path / "demo_job.toml"), "-n", "5", "-o",
               str(tmp_path / "out"), "--design", "along-job", "--ap-range-mm", "2:8"])
    out = capsys.readouterr().out
    assert rc == 0 and "space-filling along the job" in out
    planned = load_records(tmp_path / "out" / "planned.jsonl")
    assert len(planned) == 5 and all(2.0 <= r.ap_mm <= 8.0 for r in planned)
    assert (tmp_path / "out" / "TESTCUTS.src").read_text().count("LIN") >= 5 * 3


def test_the_suggestion_is_the_fewest_levels_then_the_lowest_speed(job, templates):
    from planner.calibrate.fit_boundary import Boundary
    from planner.calibrate.suggest import rank_settings, suggest_levels_and_speed

    ctx = CalibrationContext.from_job(job)
    # logit = 2 (a_p − 5) − 4 (rpm − 12000) / 4000: P = 0.1 on the line a_p = 5 + 2 (rpm − 12000)
    # / 4000 − 1.0986; the margin carries no weight
    b = Boundary(criterion="eigen", mean=np.array([0.0, 5.0, 12000.0]),
                 scale=np.array([1.0, 1.0, 4000.0]), coef=np.array([0.0, 2.0, -4.0]),
                 intercept=0.0, covariance=np.zeros((4, 4)), n=0, n_chatter=0,
                 loo_accuracy=float("nan"), log_loss=float("nan"), brier=float("nan"),
                 margin_orders=True)
    few = templates[::20]
    pick = suggest_levels_and_speed(ctx, b, few, 0.1, 20.0, (4000.0, 20000.0), max_levels=4)
    # 1 level (20 mm) and 2 (10 mm) need more than 20,000 rpm; 3 levels (6.67 mm): the lowest
    # speed on the 500 rpm grid with 2 (6.667 − 5) − 4 (v − 12000)/4000 <= ln(1/9)
    assert pick is not None and pick.levels == 3
    need = 12000.0 + 1000.0 * (2 * (20 / 3 - 5) + np.log(9.0))
    assert need <= pick.rpm < need + 500.0 and pick.p_worst <= 0.1
    ranked = rank_settings(ctx, b, few, 20.0, (4000.0, 20000.0), max_levels=4)
    assert [c.levels for c in ranked] == sorted(c.levels for c in ranked)
    assert suggest_levels_and_speed(ctx, b, few, 0.1, 20.0, (4000.0, 8000.0), max_levels=2) is None
