"""The Cramér–Rao bound of a test-pass design (planner/calibrate/design_bound.py) against the
spread of the fitted coefficients over many noisy repetitions, and the design search."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from planner.calibrate.context import CalibrationContext
from planner.calibrate.design_bound import best_design, coefficient_bound
from planner.calibrate.fit_coefficients import design_rows, fit_coefficients
from planner.calibrate.testcuts import identification_cuts
from planner.job import load_job

DEMO = Path(__file__).resolve().parents[1] / "planner" / "data" / "demo"
POSES = [(0.0, -70.0, 110.0, 0.0, 50.0, 0.0), (20.0, -60.0, 100.0, 0.0, 50.0, 0.0)]
SIGMA_ABS, SIGMA_REL = 0.5, 0.01


@pytest.fixture(scope="module")
def ctx() -> CalibrationContext:
    return CalibrationContext.from_job(load_job(DEMO / "demo_job.toml"))


@pytest.fixture(scope="module")
def planned(ctx):
    return identification_cuts(ctx, POSES, 12, rpm=12000.0, ae_mm=(25.4,), ap_mm=(2.0, 3.0),
                               milling="slot", feeds="ends", fz_min_mm=0.025)


def test_the_bound_is_the_spread_of_the_fit_with_known_weights(ctx, planned):
    """Weighted least squares with the true σ is efficient for a linear Gaussian model: over 300
    noisy repetitions the coefficients scatter by the bound (within the sampling error of a
    standard deviation from 300 draws, about 4 %, so 15 % can only fail on a wrong bound)."""
    k = ctx.material.coefficients() * 1.15
    bound = coefficient_bound(planned, ctx.tool, k, SIGMA_ABS, SIGMA_REL)
    rows = [design_rows(r, ctx.tool) for r in planned]
    rng = np.random.default_rng(5)
    fits = []
    for _ in range(300):
        recs = []
        for r, a in zip(planned, rows, strict=True):
            f = a @ k
            sigma = SIGMA_ABS + SIGMA_REL * float(np.linalg.norm(f))
            recs.append(dataclasses.replace(r, verdict="stable", force_std_n=sigma,
                                            force_n=tuple(f + rng.normal(0.0, sigma, 3))))
        fits.append(fit_coefficients(recs, ctx.tool, ctx.material).values)
    spread = np.std(np.asarray(fits) / k, axis=0)
    np.testing.assert_allclose(spread, bound, rtol=0.15)
    # the axial edge coefficient is the worst identified, by a wide margin
    assert np.argmax(bound) == 5 and bound[5] > 2 * bound[3]


def test_the_best_design_is_no_worse_than_any_in_its_candidates(ctx, planned):
    k = ctx.material.coefficients() * 1.15
    deeper = [dataclasses.replace(r, ap_mm=a) for r in planned[:2] for a in (2.0, 3.0, 6.0)]
    picked, bound = best_design(deeper, 12, ctx.tool, k, SIGMA_ABS, SIGMA_REL, starts=3)
    assert len(picked) == 12 and np.all(np.isfinite(bound))
    np.testing.assert_allclose(bound, coefficient_bound([deeper[i] for i in picked], ctx.tool, k,
                                                        SIGMA_ABS, SIGMA_REL))
    assert bound.max() <= coefficient_bound(planned, ctx.tool, k, SIGMA_ABS, SIGMA_REL).max()
    # every candidate alone at one feed cannot separate slope and intercept
    assert np.all(np.isinf(coefficient_bound([deeper[0]] * 12, ctx.tool, k)))


def test_testcuts_says_how_well_an_identification_design_can_fit(tmp_path, capsys):
    """``cctmill testcuts --design identification`` prints the design's Cramér–Rao bound at
    dynamometer noise beside the passes: the same numbers as the library's."""
    import shutil

    from planner.calibrate.records import load_records
    from planner.cli import main

    shutil.copy(DEMO / "demo_job.toml", tmp_path / "job.toml")
    shutil.copy(DEMO / "bracket_contour.nc", tmp_path)
    rc = main(["testcuts", str(tmp_path / "job.toml"), "-n", "8", "-o", str(tmp_path / "tc"),
               "--design", "identification"])
    out = capsys.readouterr().out
    assert rc == 0 and "best 1σ at 0.5 N + 1 % force noise" in out
    job_ctx = CalibrationContext.from_job(load_job(tmp_path / "job.toml"))
    planned = load_records(tmp_path / "tc" / "planned.jsonl")
    bound = coefficient_bound(planned, job_ctx.tool, job_ctx.material.coefficients())
    assert f"k_ae {100 * bound[5]:.1f} %" in out and f"k_tc {100 * bound[0]:.1f} %" in out
