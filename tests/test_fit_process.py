"""The process-gain fit (planner/calibrate/fit_process.py, docs/calibration.md): verdicts that
follow the eigen criterion at a known gain give that gain back inside its interval; verdicts no
gain explains, one verdict only, or another criterion are refused; the overlay carries the gain
to the job."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from planner.calibrate.context import CalibrationContext
from planner.calibrate.fit_boundary import criterion_margin
from planner.calibrate.fit_coefficients import FitRefused
from planner.calibrate.fit_process import fit_process_gain
from planner.calibrate.records import write_records
from planner.calibrate.testcuts import boundary_cuts
from planner.job import load_job

DEMO = Path(__file__).resolve().parents[1] / "planner" / "data" / "demo"
POSES = [(0.0, -70.7843, 112.2894, 0.0, 48.495, 0.0), (1.6236, -74.0789, 116.9107, 0.0, 47.1682, 0.0)]
TRUE_GAIN = 25.0


@pytest.fixture(scope="module")
def ctx() -> CalibrationContext:
    return CalibrationContext.from_job(load_job(DEMO / "demo_job.toml"))


def _cuts(ctx, n=24, seed=0):
    return boundary_cuts(ctx, POSES, n, rpm=(3000.0, 5000.0), ap_mm=(1.0, 10.0), ae_mm=12.7,
                         seed=seed)


def _by_criterion(ctx, cuts, gain, flips=0.0, seed=0):
    """Verdicts of the eigen criterion itself at ``gain`` × the job's, ``flips`` of them swapped."""
    rng = np.random.default_rng(seed)
    p = ctx.params(process_gain=ctx.process_gain * gain)
    out = []
    for r in cuts:
        chatter = criterion_margin(ctx, r, p) <= 0.0
        chatter ^= bool(rng.random() < flips)
        out.append(dataclasses.replace(r, verdict="chatter" if chatter else "stable"))
    return out


def test_verdicts_of_the_criterion_at_a_known_gain_give_it_back(ctx):
    recs = _by_criterion(ctx, _cuts(ctx, 30), TRUE_GAIN)
    assert 5 <= sum(r.verdict == "chatter" for r in recs) <= 25      # both sides of the boundary
    fit = fit_process_gain(ctx, recs)
    assert fit.gain_ci[0] <= TRUE_GAIN <= fit.gain_ci[1]
    assert fit.gain == pytest.approx(TRUE_GAIN, rel=0.3)
    assert fit.accuracy == 1.0 and fit.nominal_accuracy < 1.0
    # the interval's ends are the first gains outside it: 1.92 or more below the profile's peak
    for end in fit.gain_ci:
        i = int(np.argmin(abs(fit.grid - end)))
        if 0 < i < fit.grid.size - 1:
            assert fit.profile[i] < fit.profile.max() - 0.5 * 3.841


def test_noisy_verdicts_still_bound_the_gain(ctx):
    fit = fit_process_gain(ctx, _by_criterion(ctx, _cuts(ctx, 40, seed=3), TRUE_GAIN, 0.1, 1))
    assert fit.gain_ci[0] <= TRUE_GAIN <= fit.gain_ci[1]
    assert fit.gain_ci[1] / fit.gain_ci[0] < 10.0        # a bounded interval, not the whole range
    assert fit.accuracy >= 0.8


def test_verdicts_no_gain_explains_are_refused(ctx):
    # chatter at the shallow cuts, stable at the deep ones: the criterion's order reversed
    recs = [dataclasses.replace(r, verdict="chatter" if r.ap_mm < 5.0 else "stable")
            for r in _cuts(ctx, 24)]
    with pytest.raises(FitRefused, match=r"process fit refused: (the verdicts favour a gain at "
                                          r"the edge|no gain separates)"):
        fit_process_gain(ctx, recs)


def test_one_verdict_and_another_criterion_are_refused(ctx):
    stable = [dataclasses.replace(r, verdict="stable") for r in _cuts(ctx, 12)]
    with pytest.raises(FitRefused, match=r"at least 2 of each"):
        fit_process_gain(ctx, stable)
    with pytest.raises(FitRefused, match=r"the process gain enters the eigen criterion only"):
        fit_process_gain(ctx.with_(criterion="floquet"), stable)


def test_the_overlay_carries_the_gain_and_the_boundary_uses_it(tmp_path, ctx, capsys):
    import json
    import shutil

    from planner.cli import main

    for f in DEMO.iterdir():
        shutil.copy(f, tmp_path / f.name)
    write_records(tmp_path / "v.jsonl", _by_criterion(ctx, _cuts(ctx, 24), TRUE_GAIN))
    rc = main(["calibrate", str(tmp_path / "v.jsonl"), "--job", str(tmp_path / "demo_job.toml"),
               "-o", str(tmp_path / "o.toml"), "--fit", "process,boundary", "--json"])
    report = json.loads(capsys.readouterr().out)
    assert rc == 0 and report["process"]["gain_ci"][0] <= TRUE_GAIN <= report["process"]["gain_ci"][1]
    text = (tmp_path / "demo_job.toml").read_text()
    (tmp_path / "demo_job.toml").write_text(text + '\n[calibration]\noverlay = "o.toml"\n')
    job = load_job(tmp_path / "demo_job.toml")
    assert job.model.process_gain == pytest.approx(report["process"]["gain"], rel=1e-5)
    assert "process_gain" in (tmp_path / "o.toml").read_text()
