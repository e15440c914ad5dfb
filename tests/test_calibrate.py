"""Calibration from cuts (planner/calibrate, docs/calibration.md): the records format, the fits, the
overlay the job reads, the command line, the simulated truth.

Synthetic records come from the closed-form mean forces and the CCT compliance with known
"true" parameters, so the fits have exact answers; noisy ones are seeded.
"""

from __future__ import annotations

import dataclasses
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from models import cutting
from models.errors import InputError
from planner.calibrate.context import CalibrationContext
from planner.calibrate.fit_coefficients import FitRefused, design_rows, fit_coefficients
from planner.calibrate.fit_stiffness import fit_stiffness, joint_terms
from planner.calibrate.overlay import merge_overlay
from planner.calibrate.records import (
    CutRecord,
    RecordError,
    dump_records,
    load_records,
    parse_record,
    write_records,
)
from planner.calibrate.testcuts import identification_cuts
from planner.job import JobError, load_job

DEMO = Path(__file__).resolve().parents[1] / "planner" / "data" / "demo"
#: Poses over the demo's stock top (from planner.calibrate.testcuts.job_test_poses) [deg].
POSES = [(0.0, -70.7843, 112.2894, 0.0, 48.495, 0.0), (1.6236, -74.0789, 116.9107, 0.0, 47.1682, 0.0),
         (1.4636, -67.4881, 107.4636, 0.0, 50.0246, 0.0), (-90.0, -55.0, 120.0, 10.0, 60.0, -170.0)]
TRUE_SCALE = 0.7
TRUE_FACTOR = np.array([1.15, 1.10, 1.20, 1.15, 0.9, 1.3])


@pytest.fixture(scope="module")
def ctx() -> CalibrationContext:
    return CalibrationContext.from_job(load_job(DEMO / "demo_job.toml"))


@pytest.fixture(scope="module")
def planned(ctx) -> list[CutRecord]:
    return identification_cuts(ctx, POSES, 12, rpm=12000.0, ae_mm=(25.4,), ap_mm=(1.0, 2.0),
                               milling="slot")


def synthetic(ctx: CalibrationContext, planned: list[CutRecord], rng=None, rel: float = 0.0,
              abs_n: float = 0.0, with_std: bool = False) -> list[CutRecord]:
    """Records of a true cell (coefficients × TRUE_FACTOR, joint stiffness × TRUE_SCALE) from the
    closed forms; Gaussian force noise σ = abs_n + rel |F| when ``rng`` is given."""
    k_true = ctx.material.coefficients() * TRUE_FACTOR
    k_theta = np.asarray(ctx.params(TRUE_SCALE).joint_stiffness, float)
    out = []
    for r in planned:
        f = design_rows(r, ctx.tool) @ k_true
        sigma = abs_n + rel * float(np.linalg.norm(f))
        probe = dataclasses.replace(r, force_n=tuple(f), verdict="stable")
        jv, k_c = joint_terms(ctx, probe)
        delta = jv @ np.linalg.solve(np.diag(k_theta) - k_c, jv.T @ probe.force_base())
        noisy = f + (rng.normal(0.0, sigma, 3) if rng is not None else 0.0)
        out.append(dataclasses.replace(
            probe, force_n=tuple(float(v) for v in noisy),
            force_std_n=sigma if with_std and sigma > 0 else None,
            deflection_mm=tuple(float(v) for v in probe.cut_axes().T @ delta * 1e3)))
    return out


# --------------------------------------------------------------------------------------------------
# Records
# --------------------------------------------------------------------------------------------------


def test_records_round_trip_through_json_lines(tmp_path, ctx, planned):
    records = synthetic(ctx, planned)
    path = write_records(tmp_path / "cuts.jsonl", records)
    assert load_records(path) == records
    first = json.loads(path.read_text().splitlines()[0])
    assert first["format"] == "cctmill-cut/1" and first["force_n"] and "frame" not in first


def test_comments_and_blank_lines_are_skipped(tmp_path, planned):
    text = "# cuts of 2 Dec\n\n" + dump_records(planned[:2]) + "\n"
    (tmp_path / "c.jsonl").write_text(text)
    assert len(load_records(tmp_path / "c.jsonl")) == 2


def test_force_in_base_axes_equals_the_same_force_in_the_cut_frame(planned):
    r = dataclasses.replace(planned[0], force_n=(30.0, -5.0, 12.0))
    base = dataclasses.replace(r, frame="base", force_n=tuple(r.force_base()))
    np.testing.assert_allclose(base.force_cut(), r.force_cut(), atol=1e-12)
    axes = r.cut_axes()
    np.testing.assert_allclose(axes.T @ axes, np.eye(3), atol=1e-9)
    np.testing.assert_allclose(np.cross(axes[:, 2], axes[:, 0]), axes[:, 1], atol=1e-9)  # Y = Z × X


GOOD = {"joints_deg": [0, -90, 90, 0, 45, 0], "feed_dir": [0, 1, 0], "radial_dir": [1, 0, 0],
        "ae_mm": 5.0, "ap_mm": 2.0, "rpm": 8000, "feed_mm_s": 20.0, "milling": "down",
        "tool": "em25_2f", "verdict": "stable"}


@pytest.mark.parametrize(("change", "match"), [
    ({"verdict": "wobbly"}, r"verdict: must be one of stable, chatter, unknown"),
    ({"ae_mm": None}, r"ae_mm: required for up and down milling"),
    ({"radial_dir": [1, 1, 0]}, r"radial_dir: must be orthogonal to feed_dir \(they are 45.00 deg"),
    ({"feed_mm_s": -3}, r"feed_mm_s: must be a positive number"),
    ({"rpm": 4e6}, r"rpm: 4e\+06 is beyond any milling value"),
    ({"joints_deg": [0, 1, 2]}, r"joints_deg: need six numbers"),
    ({"force_n": [1, 2]}, r"force_n: need three numbers"),
    ({"feed_mm_min": 3}, r"unknown keys feed_mm_min \(units are part of key names"),
    ({"source": {"kind": "rumour"}}, r"source: must be a table with kind one of"),
    ({"format": "cctmill-cut/9"}, r"format: 'cctmill-cut/9' is not 'cctmill-cut/1'"),
])
def test_a_bad_record_is_refused_with_file_line_and_reason(tmp_path, change, match):
    obj = {**GOOD, **change}
    obj = {k: v for k, v in obj.items() if v is not None}
    (tmp_path / "r.jsonl").write_text(json.dumps(GOOD) + "\n\n" + json.dumps(obj) + "\n")
    with pytest.raises(RecordError, match=match) as e:
        load_records(tmp_path / "r.jsonl")
    assert e.value.line == 3 and str(e.value).startswith(f"{tmp_path / 'r.jsonl'}:3: ")


def test_a_line_that_is_not_json_names_its_line(tmp_path):
    (tmp_path / "r.jsonl").write_text(json.dumps(GOOD) + "\n{'a': 1}\n")
    with pytest.raises(RecordError, match=r"r.jsonl:2: not JSON"):
        load_records(tmp_path / "r.jsonl")


def test_missing_keys_are_listed():
    with pytest.raises(RecordError, match=r"missing rpm, verdict"):
        parse_record({k: v for k, v in GOOD.items() if k not in ("rpm", "verdict")})


# --------------------------------------------------------------------------------------------------
# (a) cutting coefficients
# --------------------------------------------------------------------------------------------------


def test_design_rows_reproduce_the_closed_form_mean_force(ctx, planned):
    k = ctx.material.coefficients()
    for r in planned[:3]:
        c = cutting.feed_per_tooth(r.feed(), ctx.tool.flutes, r.rpm)
        f = np.asarray(cutting.average_force(c, 2 * ctx.tool.radius, r.ap_mm * 1e-3, "slot",
                                             ctx.tool.flutes, ctx.tool.radius, k), float).ravel()
        np.testing.assert_allclose(design_rows(r, ctx.tool) @ k, f, rtol=1e-12)


def test_noiseless_records_give_the_true_coefficients_exactly(ctx, planned):
    fit = fit_coefficients(synthetic(ctx, planned), ctx.tool, ctx.material)
    np.testing.assert_allclose(fit.values, ctx.material.coefficients() * TRUE_FACTOR, rtol=1e-8)
    assert fit.n_cuts == 12 and fit.dof == 30 and fit.residual_rms_n < 1e-6


def test_up_milling_at_one_radial_depth_identifies_all_six(ctx):
    cuts = identification_cuts(ctx, POSES[:2], 8, rpm=8000.0, ae_mm=(5.0,), ap_mm=(2.0,),
                               milling="up")
    fit = fit_coefficients(synthetic(ctx, cuts), ctx.tool, ctx.material)
    np.testing.assert_allclose(fit.values, ctx.material.coefficients() * TRUE_FACTOR, rtol=1e-7)


def test_the_two_level_design_alternates_the_ends_and_narrows_the_edge_intervals(ctx):
    kw = dict(rpm=12000.0, ae_mm=(25.4,), ap_mm=(2.0, 3.0), milling="slot")
    ends = identification_cuts(ctx, POSES, 12, feeds="ends", fz_min_mm=0.025, **kw)
    fz = np.array([r.feed_mm_s * 60.0 / (ctx.tool.flutes * r.rpm) for r in ends])
    np.testing.assert_allclose(fz, [0.025, 0.25] * 6, rtol=1e-9)
    spread = identification_cuts(ctx, POSES, 12, **kw)
    widths = []
    for cuts in (spread, ends):   # the same noise level, stated: the intervals are the design's
        recs = synthetic(ctx, cuts, np.random.default_rng(5), rel=0.01, abs_n=0.5, with_std=True)
        widths.append(fit_coefficients(recs, ctx.tool, ctx.material).relative_half_width())
    assert np.all(widths[1][3:] < 0.7 * widths[0][3:])   # the edge terms: intercepts at c = 0
    with pytest.raises(InputError, match="spread or ends"):
        identification_cuts(ctx, POSES, 4, feeds="middle", **kw)
    with pytest.raises(InputError, match="fz_min_mm"):
        identification_cuts(ctx, POSES, 4, feeds="ends", fz_min_mm=0.3, **kw)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_noisy_records_recover_the_cutting_coefficients_within_their_intervals(ctx, planned, seed):
    fit = fit_coefficients(synthetic(ctx, planned, np.random.default_rng(seed), rel=0.01,
                                     abs_n=0.5), ctx.tool, ctx.material)
    truth = ctx.material.coefficients() * TRUE_FACTOR
    assert np.all(np.abs(fit.values[:3] / truth[:3] - 1) < 0.10)   # the cutting coefficients
    assert np.all(fit.ci_low < fit.ci_high)


def test_the_95_percent_intervals_cover_the_truth_at_about_their_rate(ctx, planned):
    """With the records' stated σ (exact weights) 95 % intervals cover about 95 % of the time."""
    truth = ctx.material.coefficients() * TRUE_FACTOR
    clean = synthetic(ctx, planned)
    covered, n = np.zeros(6), 60
    for seed in range(n):
        rng = np.random.default_rng(seed)
        noisy = []
        for r in clean:
            sigma = 0.5 + 0.01 * float(np.linalg.norm(r.force_n))
            noisy.append(dataclasses.replace(r, force_std_n=sigma, force_n=tuple(
                np.asarray(r.force_n) + rng.normal(0.0, sigma, 3))))
        fit = fit_coefficients(noisy, ctx.tool, ctx.material)
        covered += (fit.ci_low <= truth) & (truth <= fit.ci_high)
    rate = covered / n
    assert np.all(rate >= 0.85), rate   # binomial: 95 % ± 2.8 % over 60 fits


def _refusal(ctx, records, match):
    with pytest.raises(FitRefused, match=match) as e:
        fit_coefficients(records, ctx.tool, ctx.material)
    assert e.value.what == "coefficients"


def test_too_few_cuts_are_refused(ctx, planned):
    _refusal(ctx, synthetic(ctx, planned)[:2], r"2 record\(s\) with a mean force .* need at least 3")


def test_one_feed_per_tooth_is_refused(ctx, planned):
    same = [dataclasses.replace(r, feed_mm_s=planned[0].feed_mm_s) for r in planned[:6]]
    _refusal(ctx, synthetic(ctx, same), r"one feed per tooth .* cannot be told apart")


def test_chatter_records_are_left_out_and_a_fit_of_them_alone_refused(ctx, planned):
    records = [dataclasses.replace(r, verdict="chatter") for r in synthetic(ctx, planned)]
    _refusal(ctx, records, r"0 record\(s\)")
    mixed = records[:3] + synthetic(ctx, planned)[3:]
    fit = fit_coefficients(mixed, ctx.tool, ctx.material)
    assert fit.n_cuts == 9 and len(fit.excluded) == 3 and "chatter" in fit.excluded[0][1]


def test_a_contradicting_record_is_refused_naming_it(ctx, planned):
    records = synthetic(ctx, planned, np.random.default_rng(5), rel=0.01, abs_n=0.5)
    bad = records[4]
    records[4] = dataclasses.replace(bad, force_n=tuple(1.3 * np.asarray(bad.force_n)))  # a slip
    _refusal(ctx, records, rf"record {bad.id} contradicts the others")


def test_records_that_contradict_the_model_as_a_whole_are_refused(ctx, planned):
    rng = np.random.default_rng(0)
    records = [dataclasses.replace(r, force_n=tuple(rng.normal(0.0, 50.0, 3)))
               for r in synthetic(ctx, planned)]
    with pytest.raises(FitRefused, match=r"contradict|positive in any metal"):
        fit_coefficients(records, ctx.tool, ctx.material)


def test_records_of_another_tool_are_refused(ctx, planned):
    records = synthetic(ctx, planned)
    records[0] = dataclasses.replace(records[0], tool="em12_3f")
    _refusal(ctx, records, r"cut with tool 'em12_3f', the job's is 'em25_2f'")


# --------------------------------------------------------------------------------------------------
# (b) joint stiffness scale
# --------------------------------------------------------------------------------------------------


def test_noiseless_deflections_give_the_true_stiffness_scale(ctx, planned):
    fit = fit_stiffness(ctx, synthetic(ctx, planned))
    assert fit.method == "deflection"
    assert fit.scale == pytest.approx(TRUE_SCALE, rel=1e-6)
    assert fit.scale_ci[0] <= TRUE_SCALE <= fit.scale_ci[1]


def test_noisy_deflections_give_the_scale_within_ten_percent(ctx, planned):
    rng = np.random.default_rng(7)
    records = [dataclasses.replace(r, deflection_mm=tuple(np.asarray(r.deflection_mm)
                                                          + rng.normal(0.0, 0.015, 3)))
               for r in synthetic(ctx, planned)]
    fit = fit_stiffness(ctx, records)
    assert abs(fit.scale / TRUE_SCALE - 1) < 0.10
    assert fit.scale_ci[0] < fit.scale < fit.scale_ci[1]


def test_poses_spread_over_the_workspace_resolve_the_joints_one_by_one(ctx):
    """With the arm in seven different postures each of A1..A5 carries its own deflection; A6 (the
    TCP on its axis) moves nothing and is held at the common scale."""
    poses = POSES + [(-40.0, -60.0, 100.0, 30.0, 60.0, 20.0), (40.0, -80.0, 130.0, -30.0, 40.0, -20.0),
                     (0.0, -45.0, 90.0, 60.0, 80.0, 0.0)]
    cuts = identification_cuts(ctx, poses, 14, rpm=12000.0, ae_mm=(25.4,), ap_mm=(2.0, 4.0),
                               milling="slot")
    true = np.array([0.5, 0.7, 0.7, 0.9, 0.7, 0.7])
    k_theta = np.asarray(ctx.params(true).joint_stiffness, float)
    records = []
    for r in synthetic(ctx, cuts):
        jv, k_c = joint_terms(ctx, r)
        d = jv @ np.linalg.solve(np.diag(k_theta) - k_c, jv.T @ r.force_base())
        records.append(dataclasses.replace(r, deflection_mm=tuple(r.cut_axes().T @ d * 1e3)))
    fit = fit_stiffness(ctx, records)
    assert fit.resolved == (True, True, True, True, True, False)
    np.testing.assert_allclose(fit.per_joint[:5], true[:5], rtol=1e-5)
    assert fit.per_joint[5] == pytest.approx(fit.scale)


def test_chatter_frequencies_alone_give_the_scale_as_the_squared_frequency_ratio(ctx, planned):
    from models.structure import pose_structure
    from planner.calibrate.fit_stiffness import record_cut

    robot, params = ctx.load_robot(), ctx.params()
    records = []
    for r in planned[:4]:
        f = pose_structure(robot, params, r.q(), record_cut(ctx, r), r.feed()).natural_frequencies_hz
        records.append(dataclasses.replace(r, verdict="chatter",
                                           chatter_hz=float(f[0]) * np.sqrt(TRUE_SCALE)))
    fit = fit_stiffness(ctx, records)
    assert fit.method == "frequency" and fit.per_joint is None
    assert fit.scale == pytest.approx(TRUE_SCALE, rel=1e-3)


def test_a_stiffness_fit_without_deflections_or_frequencies_is_refused(ctx, planned):
    records = [dataclasses.replace(r, deflection_mm=None) for r in synthetic(ctx, planned)]
    with pytest.raises(FitRefused, match=r"0 record\(s\) with a measured deflection"):
        fit_stiffness(ctx, records)


def test_a_record_outside_the_joint_limits_is_refused_naming_it(ctx, planned):
    records = synthetic(ctx, planned)
    records[2] = dataclasses.replace(records[2], joints_deg=(0.0, -70.0, 112.0, 0.0, 48.0, 400.0))
    with pytest.raises(FitRefused, match=rf"record {records[2].id}: A6 = 400.00 deg is outside"):
        fit_stiffness(ctx, records)


def test_deflections_in_the_wrong_unit_are_refused(ctx, planned):
    records = [dataclasses.replace(r, deflection_mm=tuple(np.asarray(r.deflection_mm) * 1e3))
               for r in synthetic(ctx, planned)]          # micrometres typed as millimetres
    with pytest.raises(FitRefused, match=r"outside .*wrong robot, TCP or unit"):
        fit_stiffness(ctx, records)


# --------------------------------------------------------------------------------------------------
# Overlay and command line
# --------------------------------------------------------------------------------------------------


@pytest.fixture()
def job_dir(tmp_path) -> Path:
    shutil.copy(DEMO / "demo_job.toml", tmp_path / "job.toml")
    shutil.copy(DEMO / "bracket_contour.nc", tmp_path)
    return tmp_path


def test_calibrate_command_writes_an_overlay_the_job_reads(job_dir, ctx, planned, capsys):
    from planner.cli import main

    write_records(job_dir / "cuts.jsonl", synthetic(ctx, planned))
    rc = main(["calibrate", str(job_dir / "cuts.jsonl"), "--job", str(job_dir / "job.toml"),
               "-o", str(job_dir / "cell.overlay.toml")])
    out = capsys.readouterr().out
    assert rc == 0 and "joint stiffness scale (deflection, 12 deflections): 0.7" in out
    report = json.loads((job_dir / "cell.overlay.report.json").read_text())
    assert report["coefficients"]["n_cuts"] == 12 and report["refused"] == {}
    with open(job_dir / "job.toml", "a") as fh:
        fh.write('\n[calibration]\noverlay = "cell.overlay.toml"\n')
    job = load_job(job_dir / "job.toml")
    assert job.cell.joint_stiffness_scale == pytest.approx(TRUE_SCALE, rel=1e-5)
    np.testing.assert_allclose(job.material_coefficients(),
                               ctx.material.coefficients() * TRUE_FACTOR, rtol=1e-5)
    assert job.cell.tcp_mm == [320.0, 0.0, 0.0]            # the job's own keys stay
    assert job.calibration.records == [str((job_dir / "cuts.jsonl").resolve())]
    # the fits' uncertainty travels with them: the planner bounds force and deflection with it
    cov = np.asarray(job.calibration.coefficient_covariance).reshape(6, 6)
    std = [report["coefficients"]["std"][n] for n in ("k_tc", "k_rc", "k_ac", "k_te", "k_re", "k_ae")]
    np.testing.assert_allclose(np.sqrt(np.diag(cov)), std, rtol=1e-5)
    assert job.calibration.joint_stiffness_scale_std == pytest.approx(
        report["stiffness"]["scale_log_std"], rel=1e-3)


def test_calibrate_command_reports_a_refused_fit_and_exits_2(job_dir, ctx, planned, capsys):
    from planner.cli import main

    write_records(job_dir / "few.jsonl", synthetic(ctx, planned)[:2])
    rc = main(["calibrate", str(job_dir / "few.jsonl"), "--job", str(job_dir / "job.toml"),
               "-o", str(job_dir / "o.toml"), "--fit", "coefficients"])
    err = capsys.readouterr().err
    assert rc == 2 and "need at least 3" in err and not (job_dir / "o.toml").exists()


def test_an_overlay_with_other_tables_is_refused(job_dir):
    (job_dir / "o.toml").write_text("[limits]\nforce_max_n = 900.0\n")
    with open(job_dir / "job.toml", "a") as fh:
        fh.write('\n[calibration]\noverlay = "o.toml"\n')
    with pytest.raises(JobError, match=r"holds \['limits'\]; an overlay holds only"):
        load_job(job_dir / "job.toml")


def test_a_missing_overlay_is_named(tmp_path):
    doc, problems = merge_overlay({"calibration": {"overlay": "nope.toml"}}, tmp_path)
    assert problems and "cannot read" in problems[0] and doc == {"calibration": {"overlay": "nope.toml"}}


def test_partial_coefficients_in_a_job_are_refused(job_dir):
    with open(job_dir / "job.toml", "a") as fh:
        fh.write("\n[calibration]\nk_tc = 1e9\n")
    with pytest.raises(JobError, match=r"give all six cutting coefficients"):
        load_job(job_dir / "job.toml")


# --------------------------------------------------------------------------------------------------
# The simulated truth
# --------------------------------------------------------------------------------------------------


def test_a_stable_simulated_cut_records_the_true_mean_force(ctx, planned):
    from planner.calibrate.truth import TruthCell, run_cuts

    truth = TruthCell(ctx, force_noise_n=0.0, force_noise_rel=0.0, deflection_noise_mm=0.0,
                      duration_s=0.3)
    [rec] = run_cuts(truth, planned[:1], seed=0)
    expected = design_rows(planned[0], ctx.tool) @ truth.coefficients()
    assert rec.verdict == "stable" and rec.source["kind"] == "simulated"
    np.testing.assert_allclose(rec.force_cut(), expected, rtol=0.03, atol=0.5)


# --------------------------------------------------------------------------------------------------
# (c) the probabilistic boundary
# --------------------------------------------------------------------------------------------------


def _labelled(ctx, n: int = 24, seed: int = 0) -> list[CutRecord]:
    """Records whose verdict follows a known rule: chatter iff a_p > 2 mm + 0.4 mm per 1000 rpm
    above 4000 rpm (a boundary in a_p and rpm the logistic model can express), with 10 % flips."""
    from planner.calibrate.testcuts import boundary_cuts

    rng = np.random.default_rng(seed)
    out = []
    for r in boundary_cuts(ctx, POSES[:2], n, rpm=(3000.0, 6000.0), ap_mm=(0.5, 4.0), ae_mm=6.0,
                           seed=seed):
        chatter = r.ap_mm > 2.0 + 0.4e-3 * (r.rpm - 4000.0)
        chatter ^= bool(rng.random() < 0.1)
        out.append(dataclasses.replace(r, verdict="chatter" if chatter else "stable"))
    return out


def test_the_boundary_learns_where_chatter_starts(ctx):
    from planner.calibrate.fit_boundary import fit_boundary, required_margin

    b = fit_boundary(ctx, _labelled(ctx, 40))
    assert b.n == 40 and b.loo_accuracy > 0.75
    assert b.coef[1] > 0 and b.coef[2] < 0          # deeper: more chatter; faster: less here
    lo, hi = b.probability(np.array([[b.mean[0], 1.0, 4000.0], [b.mean[0], 3.5, 4000.0]]))
    assert lo < 0.3 < 0.7 < hi
    for p in (0.05, 0.2):      # the required margin puts the point estimate exactly at p
        m = required_margin(b, p, 2.0, 4500.0)
        if np.isfinite(m):
            mu, _ = b.logit(np.array([[m, 2.0, 4500.0]]))
            assert 1 / (1 + np.exp(-mu[0])) == pytest.approx(p, rel=1e-6)


def test_a_boundary_from_one_verdict_is_refused(ctx):
    from planner.calibrate.fit_boundary import fit_boundary

    stable = [dataclasses.replace(r, verdict="stable") for r in _labelled(ctx, 12)]
    with pytest.raises(FitRefused, match=r"at least 2 of each: a boundary needs cuts on both sides"):
        fit_boundary(ctx, stable)


def test_value_of_information_aims_at_the_uncertain_boundary(ctx):
    from planner.calibrate.fit_boundary import fit_boundary
    from planner.calibrate.testcuts import propose_cuts

    b = fit_boundary(ctx, _labelled(ctx, 24))
    picks = propose_cuts(ctx, b, POSES[:1], 4, rpm=(3000.0, 6000.0), ap_mm=(0.5, 4.0), ae_mm=6.0,
                         grid=5)
    assert len({(r.rpm, r.ap_mm) for r in picks}) == 4                    # no repeats
    p = [r.source["p_chatter"] for r in picks]
    assert max(abs(v - 0.5) for v in p[:2]) < 0.35                        # near the boundary first


def test_a_job_requiring_a_probability_needs_a_boundary(job_dir):
    from planner.calibrate.fit_boundary import job_margin_floor

    with open(job_dir / "job.toml", "a") as fh:
        fh.write("\n")
    text = (job_dir / "job.toml").read_text().replace('chatter_criterion = "eigen"',
                                                      'chatter_criterion = "eigen"\n'
                                                      'chatter_probability_max = 0.1')
    (job_dir / "job.toml").write_text(text)
    job = load_job(job_dir / "job.toml")
    assert job.model.chatter_probability_max == 0.1
    with pytest.raises(InputError, match=r"needs a calibrated boundary"):
        job_margin_floor(job, 2e-3, 4000 * 2 * np.pi / 60)


def test_calibrate_writes_the_boundary_the_planner_reads(job_dir, ctx, capsys):
    from planner.calibrate.fit_boundary import job_margin_floor, margin_floors
    from planner.cli import main

    write_records(job_dir / "b.jsonl", _labelled(ctx, 24))
    rc = main(["calibrate", str(job_dir / "b.jsonl"), "--job", str(job_dir / "job.toml"),
               "-o", str(job_dir / "o.toml"), "--fit", "boundary"])
    assert rc == 0, capsys.readouterr().err
    text = (job_dir / "job.toml").read_text().replace(
        'chatter_criterion = "eigen"', 'chatter_criterion = "eigen"\nchatter_probability_max = 0.1')
    (job_dir / "job.toml").write_text(text + '\n[calibration]\noverlay = "o.toml"\n')
    job = load_job(job_dir / "job.toml")
    shallow = job_margin_floor(job, 1e-3, 4000 * 2 * np.pi / 60)
    deep = job_margin_floor(job, 3.5e-3, 4000 * 2 * np.pi / 60)
    assert shallow < deep                   # a deeper cut needs more margin for the same risk
    np.testing.assert_allclose(margin_floors(job, np.array([1e-3, 3.5e-3]), 4000 * 2 * np.pi / 60),
                               [shallow, deep])


# --------------------------------------------------------------------------------------------------
# Test cuts, KRL, the supervisor's records
# --------------------------------------------------------------------------------------------------


@pytest.mark.slow
def test_testcuts_command_writes_krl_and_records_of_the_simulated_truth(job_dir, capsys):
    from planner.cli import main
    from robot_io.krl.reader import read_krl

    (job_dir / "truth.toml").write_text("[truth]\njoint_scale = 0.7\ncoefficient_factor = 1.15\n"
                                        "duration_s = 0.25\n")
    rc = main(["testcuts", str(job_dir / "job.toml"), "-n", "3", "-o", str(job_dir / "tc"),
               "--simulate", str(job_dir / "truth.toml"), "--ap-range-mm", "0.5:2"])
    out = capsys.readouterr().out
    assert rc == 0 and "3 test passes (space-filling" in out
    planned = load_records(job_dir / "tc" / "planned.jsonl")
    ran = load_records(job_dir / "tc" / "records.jsonl")
    assert [r.id for r in planned] == [r.id for r in ran] and all(r.force_n for r in ran)
    assert {r.verdict for r in planned} == {"unknown"} and ran[0].source["kind"] == "simulated"
    toolpath = read_krl(job_dir / "tc" / "TESTCUTS.src")
    assert toolpath is not None


def test_a_supervised_section_becomes_a_record(ctx):
    from types import SimpleNamespace

    from planner.calibrate.supervisor_records import append_record, section_record

    n = 5
    pos = np.column_stack([np.linspace(0, 0.04, n), np.zeros(n), np.zeros(n)])
    samples = SimpleNamespace(
        q=np.radians(np.tile(POSES[0], (n, 1))), position_wp=pos,
        tool_axis_wp=np.tile([0.0, 0.0, 1.0], (n, 1)), a_p=np.full(n, 2e-3),
        a_e=np.full(n, 6e-3), mode=np.full(n, float(cutting.MILLING_MODES["down"])))
    sections = (SimpleNamespace(kind="air", index=0, sample_start=0, sample_stop=1, feed=0.05),
                SimpleNamespace(kind="cut", index=1, sample_start=1, sample_stop=n, feed=0.02))
    plan = SimpleNamespace(sections=sections, samples=samples, base_abc=(0.0, 0.0, 0.0),
                           path=None, spindle_rpm=4000.0, tool_diameter=0.0254, flutes=2,
                           material="al6061")
    assert section_record(plan, 0, "stable", "em25_2f") is None
    rec = section_record(plan, 1, "chatter", "em25_2f", override=0.5,
                         force_mean_n=np.array([10.0, 20.0, 5.0]), chatter_hz=14.2)
    assert rec.feed_mm_s == pytest.approx(10.0) and rec.milling == "down" and rec.ae_mm == 6.0
    np.testing.assert_allclose(rec.feed_dir, [1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(rec.radial_dir, [0, 1, 0], atol=1e-12)   # X_o = a × f
    assert rec.source == {"kind": "supervisor", "section": 2}
    import tempfile

    from planner.calibrate.supervisor_records import SectionRecorder

    with tempfile.TemporaryDirectory() as d:
        append_record(Path(d) / "r.jsonl", rec)
        append_record(Path(d) / "r.jsonl", rec)
        assert load_records(Path(d) / "r.jsonl") == [rec, rec]
        # The loop hook: one record per cut section, chatter if a step alarmed.
        rec_hook = SectionRecorder(plan, Path(d) / "run.jsonl", "em25_2f", detector="dwt")

        def step(section, alarm, status="ok"):
            return SimpleNamespace(section=section, alarm=alarm, status=status, override=80.0)

        for t, (sec, alarm) in enumerate([(0, False), (1, False), (1, True), (1, False)]):
            rec_hook(0.1 * t, step(sec, alarm), 50.0)
        rec_hook(1.0, step(None, False), 50.0)      # the end of the program
        rec_hook(1.0, "not a step", 50.0)           # a broken call is counted, never raised
        rec_hook.close(1.1)
        [run] = load_records(Path(d) / "run.jsonl")
        assert run.verdict == "chatter" and run.feed_mm_s == pytest.approx(10.0)
        assert run.source["detector"] == "dwt" and rec_hook.errors == 1


def test_importing_the_records_format_loads_no_physics():
    import subprocess
    import sys

    code = ("import sys, planner.calibrate, planner.calibrate.records; "
            "print(sorted(m for m in ('casadi', 'pinocchio', 'sklearn') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         cwd=Path(__file__).resolve().parents[1], timeout=120).stdout.strip()
    assert out == "[]"


def test_a_process_fit_without_chatter_records_is_reported_as_refused(job_dir, ctx, planned,
                                                                       capsys):
    from planner.cli import main

    write_records(job_dir / "cuts.jsonl", synthetic(ctx, planned))   # stable slots only
    rc = main(["calibrate", str(job_dir / "cuts.jsonl"), "--job", str(job_dir / "job.toml"),
               "-o", str(job_dir / "o.toml"), "--fit", "coefficients,process", "--json"])
    report = json.loads(capsys.readouterr().out)
    assert rc == 0 and "at least 2 of each" in report["refused"]["process"]
    assert report["stiffness"] is None and report["coefficients"]["n_cuts"] == 12
