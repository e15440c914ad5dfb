"""Limits that hold with a stated probability under a calibration's uncertainty
(planner/limit_confidence.py): the affine design, the first-order standard errors against a Monte
Carlo over the coefficients, and the plan's ceilings on the bound."""

from __future__ import annotations

import dataclasses
from statistics import NormalDist

import numpy as np
import pytest

from models import cutting
from models.tooling import load_material
from planner.ceilings import PathModel
from planner.limit_confidence import LimitConfidence, limit_confidence

K = load_material("al6061").coefficients()
#: (c [m], a_e [m], a_p [m], mode, flutes, radius [m]) of three unlike cuts with one tool (a path
#: has one), and one with another.
CUTS = [(0.05e-3, 3e-3, 10e-3, "down", 2, 12.7e-3), (0.2e-3, 12.7e-3, 4e-3, "up", 2, 12.7e-3),
        (0.1e-3, 0.0, 2e-3, "slot", 2, 12.7e-3)]
OTHER_TOOL = (0.2e-3, 10e-3, 4e-3, "up", 3, 10e-3)


def _design(c, a_e, a_p, mode, n, r) -> np.ndarray:
    code = cutting.MILLING_MODES[mode]
    return np.asarray(cutting.coefficient_design_function()(c, a_e, a_p, code, n, r), float)


def _engagement(cuts) -> tuple:
    """(a_e, a_p, mode codes, flutes, radius) of ``cuts`` (one tool), as the path model passes
    them to :func:`limit_confidence`."""
    (_, _, _, _, n, r), = {(0, 0, 0, 0, c[4], c[5]) for c in cuts}
    return (np.array([c[1] for c in cuts]), np.array([c[2] for c in cuts]),
            np.array([cutting.MILLING_MODES[c[3]] for c in cuts]), n, r)


@pytest.mark.parametrize("cut", [*CUTS, OTHER_TOOL])
def test_the_mean_force_is_affine_in_the_chip_and_linear_in_k(cut):
    c, *rest = cut
    a0, a1 = _design(0.0, *rest), _design(1.0, *rest) - _design(0.0, *rest)
    np.testing.assert_allclose(_design(c, *rest), a0 + c * a1, rtol=1e-12, atol=1e-18)
    code = cutting.MILLING_MODES[rest[2]]
    force = np.asarray(cutting.average_force(c, rest[0], rest[1], code, rest[3], rest[4], K),
                       float).ravel()
    np.testing.assert_allclose(_design(c, *rest) @ K, force, rtol=1e-12)


def test_the_first_order_errors_match_a_monte_carlo_over_the_coefficients():
    """Σ_K: 3 % on the cutting, 10 % on the edge coefficients, k_tc and k_te anti-correlated (as
    a slope and an intercept are); stiffness 2 %. u_F against the spread of |F̄| over 40,000
    draws (the model is linear in K, so first order is exact up to the norm's curvature)."""
    rel = np.array([0.03, 0.03, 0.03, 0.10, 0.10, 0.10])
    corr = np.eye(6)
    corr[0, 3] = corr[3, 0] = -0.6
    cov = np.outer(rel * K, rel * K) * corr
    job = _Job(cov, 0.02, 0.95)
    tooth_f = 400.0
    conf = limit_confidence(job, *_engagement(CUTS), tooth_f)
    feeds = np.array([c[0] for c in CUTS]) * tooth_f
    force = np.array([_design(*c) @ K for c in CUTS])
    u_f, u_d = conf.relative_std(feeds, force, np.arange(len(CUTS)))
    draws = np.random.default_rng(3).multivariate_normal(K, cov, 40_000)
    for k, c in enumerate(CUTS):
        mags = np.linalg.norm(draws @ _design(*c).T, axis=1)
        assert u_f[k] == pytest.approx(mags.std() / np.linalg.norm(force[k]), rel=0.03)
        # the deflection's bound: the force error in its worst direction, plus the stiffness's
        a = _design(*c)
        worst = np.linalg.eigvalsh(a @ cov @ a.T)[-1]
        assert u_d[k] == pytest.approx(np.hypot(np.sqrt(worst) / np.linalg.norm(force[k]), 0.02))
        assert u_d[k] >= u_f[k]
    k_f, k_d = conf.factors(feeds, force, np.arange(len(CUTS)))
    z = NormalDist().inv_cdf(0.95)
    np.testing.assert_allclose(k_f, 1 + z * u_f)
    np.testing.assert_allclose(k_d, 1 + z * u_d)


def test_no_bound_without_a_stated_uncertainty_or_at_even_odds():
    eng = _engagement(CUTS)
    assert limit_confidence(_Job(None, None, 0.95), *eng, 400.0) is None
    assert limit_confidence(_Job(np.eye(6), 0.02, 0.5), *eng, 400.0) is None
    only_stiffness = limit_confidence(_Job(None, 0.02, 0.95), *eng, 400.0)
    assert isinstance(only_stiffness, LimitConfidence)
    force = np.array([_design(*c) @ K for c in CUTS])
    u_f, u_d = only_stiffness.relative_std(np.ones(3), force, np.arange(3))
    np.testing.assert_allclose(u_f, 0.0, atol=1e-15)
    np.testing.assert_allclose(u_d, 0.02)


def test_a_calibrated_demo_plans_its_ceilings_on_the_bound(demo_prepared):
    """The demo job with the material's coefficients given as a fit of 2 % / 8 % standard error
    and a 1.5 % stiffness scale: at every ceiling the bounded force and deflection meet their
    limits, where deflection binds the bound sits on the tolerance, the bounded plan is slower
    than the plan on the fitted values by about z·u, and the independent checker still passes."""
    bounded = PathModel(_calibrated(demo_prepared))
    plain = PathModel(demo_prepared)
    assert bounded.confidence is not None and plain.confidence is None
    ceil, ceil0 = bounded.ceilings(), plain.ceilings()
    ev = bounded.evaluate(ceil.feed)
    k_f, k_d = ev.confidence_factors.T
    lim = bounded.limits
    assert np.all(ev.force * k_f <= lim.force_max * (1 + 1e-9))
    assert np.all(ev.deflection_held * k_d <= lim.deflection_tol * (1 + 1e-9))
    defl = ceil.binding == "deflection"
    assert defl.sum() > 100
    np.testing.assert_allclose(ev.deflection_held[defl] * k_d[defl], lim.deflection_tol, rtol=2e-3)
    assert np.all(ev.deflection_held[defl] < lim.deflection_tol / 1.02)   # z·u_δ ≥ 1.645 × 1.5 %
    ratio = ceil.feed[defl] / ceil0.feed[defl]
    assert np.all(ratio < 1.0) and np.median(ratio) > 0.9
    # the plain model's evaluation carries no factors and is the same physics
    ev0 = plain.evaluate(ceil.feed)
    assert ev0.confidence_factors.size == 0
    np.testing.assert_allclose(ev0.force, ev.force)


def _calibrated(prep):
    """The prepared demo with its material's coefficients stated as a fit of 2 % (cutting) and
    8 % (edge) standard error and a 1.5 % stiffness scale."""
    job = prep.job
    rel = np.array([0.02, 0.02, 0.02, 0.08, 0.08, 0.08])
    doc = job.model_dump()
    doc["calibration"].update(dict(zip(("k_tc", "k_rc", "k_ac", "k_te", "k_re", "k_ae"),
                                       map(float, job.material_coefficients()), strict=True)))
    doc["calibration"]["coefficient_covariance"] = np.diag((rel * K) ** 2).ravel().tolist()
    doc["calibration"]["joint_stiffness_scale_std"] = 0.015
    return dataclasses.replace(prep, job=type(job).model_validate(doc))


def test_the_checker_holds_a_plan_to_the_bound(demo_prepared, demo_optimized):
    """The independent checker applies the same bound: the plan made on the fitted values breaks
    it where deflection binds, the plan made on the bound passes."""
    from planner.check import check_result
    from planner.plan import plan_prepared

    cal = _calibrated(demo_prepared)
    on_values = check_result(dataclasses.replace(demo_optimized, prep=cal))
    assert not on_values.ok and {v.constraint for v in on_values.violations} >= {"deflection"}
    assert on_values.worst_ratio["deflection"] > 1.02
    assert check_result(demo_optimized).ok
    bounded = check_result(plan_prepared(cal, "sections"))
    assert bounded.ok and bounded.worst_ratio["deflection"] <= 1.0 + 1e-6


def test_the_covariance_needs_the_coefficients_and_finite_values(demo_prepared):
    from pydantic import ValidationError

    job = demo_prepared.job
    doc = job.model_dump()
    doc["calibration"]["coefficient_covariance"] = np.eye(6).ravel().tolist()
    with pytest.raises(ValidationError, match="needs the six coefficients"):
        type(job).model_validate(doc)
    doc["calibration"].update({n: 1.0 for n in ("k_tc", "k_rc", "k_ac", "k_te", "k_re", "k_ae")})
    doc["calibration"]["coefficient_covariance"][7] = float("nan")
    with pytest.raises(ValidationError, match="finite"):
        type(job).model_validate(doc)
    doc["calibration"]["coefficient_covariance"] = (-np.eye(6)).ravel().tolist()
    with pytest.raises(ValidationError, match="non-negative diagonal"):
        type(job).model_validate(doc)
    doc["calibration"]["coefficient_covariance"] = [1.0] * 35
    with pytest.raises(ValidationError, match="36"):
        type(job).model_validate(doc)


@dataclasses.dataclass
class _Calibration:
    coefficient_covariance: list[float] | None
    joint_stiffness_scale_std: float | None


@dataclasses.dataclass
class _Model:
    limit_confidence: float


class _Job:
    """What :func:`limit_confidence` reads of a job."""

    def __init__(self, cov, stiffness_std, confidence) -> None:
        self.calibration = _Calibration(None if cov is None else np.ravel(cov).tolist(),
                                        stiffness_std)
        self.model = _Model(confidence)


def test_plan_says_how_the_calibration_uncertainty_tightened_the_limits(tmp_path, capsys):
    """A job whose [calibration] carries a covariance: ``cctmill plan`` prints the probability and
    the largest bounds, and plan.json's summary holds them; the nominal demo says nothing."""
    import json
    import shutil

    from planner.cli import main
    from planner.demo import demo_job_file

    demo = demo_job_file()
    shutil.copy(demo.parent / "bracket_contour.nc", tmp_path)
    cov = np.diag((0.03 * K) ** 2).ravel()
    coeffs = "\n".join(f"{n} = {v!r}" for n, v in zip(("k_tc", "k_rc", "k_ac", "k_te", "k_re",
                                                        "k_ae"), map(float, K), strict=True))
    text = demo.read_text(encoding="utf-8") + (
        f"\n[calibration]\n{coeffs}\ncoefficient_covariance = {[float(v) for v in cov]!r}\n"
        "joint_stiffness_scale_std = 0.01\n")
    (tmp_path / "job.toml").write_text(text, encoding="utf-8")
    rc = main(["plan", str(tmp_path / "job.toml"), "-o", str(tmp_path / "out")])
    out = capsys.readouterr().out
    assert rc == 0 and "limits held with probability 0.95" in out
    summary = json.loads((tmp_path / "out" / "plan.json").read_text())["summary"]
    conf = summary["limit_confidence"]
    assert conf["probability"] == 0.95 and conf["z"] == pytest.approx(1.6449, abs=1e-4)
    # independent 3 % errors on the six terms of |F̄| = Σ t_j give it at most 3 % (one term
    # alone) and at least 3 %/√6; the deflection adds the stiffness's 1 %
    z = conf["z"]
    assert 1 + z * 0.03 / 6**0.5 < conf["force_factor_max"] <= 1 + z * 0.03
    assert conf["deflection_factor_max"] >= max(conf["force_factor_max"], 1 + z * 0.01)
