"""``cctmill simulate`` and ``--criterion floquet`` on analyze/stability (CLI contract)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from planner.cli import main

CASE1 = ["--joints-deg", "-96.42,-29.26,99.08,-9.95,83.23,-160.5", "--feed-dir", "0,1,0",
         "--radial-dir", "1,0,0", "--ae-mm", "15.24", "--ap-mm", "5.08"]
#: A cut the Floquet criterion calls stable at Case 1's pose (4000 rpm, a_e 5 mm, a_p 0.5 mm).
STABLE = ["--joints-deg", "-96.42,-29.26,99.08,-9.95,83.23,-160.5", "--feed-dir", "0,1,0",
          "--radial-dir", "1,0,0", "--ae-mm", "5", "--ap-mm", "0.5", "--rpm", "4000",
          "--feed-mm-s", "13"]


def _json(capsys, argv):
    assert main(argv) == 0
    return json.loads(capsys.readouterr().out)


def test_simulate_json_contract_on_case1(capsys):
    out = _json(capsys, ["simulate", *CASE1, "--feed-mm-s", "1", "--duration-s", "1", "--json"])
    for key in ("f_peak_N", "f_pv_N", "iterations_mean", "dominant_frequency_hz",
                "stable_predicted"):
        assert key in out
    # Case 1 at 1000 rpm: the averaged eigen model says stable, Floquet (the default) does not
    assert out["criterion"] == "floquet" and out["stable_predicted"] is False
    assert out["stable_eigen"] is True and out["floquet_spectral_radius"] > 1.0
    assert out["iterations_mean"] >= 1.0 and out["tooth_frequency_hz"] == pytest.approx(1000 / 30)
    assert len(out["natural_frequencies_hz"]) == 2


def test_simulate_stable_cut_writes_signal_and_plot(capsys, tmp_path):
    csv, png = tmp_path / "signal.csv", tmp_path / "sim.png"
    out = _json(capsys, ["simulate", *STABLE, "--duration-s", "0.5", "--fs-hz", "2000",
                         "--out", str(csv), "--plot", str(png), "--noise-n", "0.5", "--json"])
    assert out["stable_predicted"] is True and out["static_model_valid"] is True
    data = np.loadtxt(csv, delimiter=",", skiprows=1)
    assert data.shape[1] == 8 and data.shape[0] == pytest.approx(0.5 * 2000 + 1, abs=1)
    assert np.all(np.diff(data[:, 0]) == pytest.approx(1 / 2000))
    resultant = np.linalg.norm(data[:, 1:4], axis=1)
    assert np.std(data[:, 4] - resultant) == pytest.approx(0.5, rel=0.2)
    assert png.stat().st_size > 1000
    header = csv.read_text().splitlines()[0]
    assert header.startswith("time_s,fx_o_N")


def test_simulate_first_iteration_and_no_regeneration_flags(capsys):
    base = ["simulate", *STABLE, "--duration-s", "0.3", "--json"]
    first = _json(capsys, [*base, "--first-iteration", "--no-regeneration"])
    assert first["iterate"] is False and first["regeneration"] is False
    assert first["iterations_mean"] == 1.0
    periodic = _json(capsys, [*base, "--initial", "periodic", "--perturbation-um", "0.01"])
    assert periodic["initial"] == "periodic" and periodic["f_pv_over_f_peak"] < 0.05
    table = main(["simulate", *STABLE, "--duration-s", "0.3"])
    assert table == 0
    text = capsys.readouterr().out
    assert "F_peak" in text and "floquet: stable" in text


@pytest.mark.parametrize(("flags", "match"), [
    (["--duration-s", "0"], "--duration-s"),
    (["--fs-hz", "-5"], "--fs-hz"),
    (["--damping-ratio", "1.5"], "--damping-ratio"),
    (["--noise-n", "-1"], "--noise-n"),
    (["--perturbation-um", "nan"], "--perturbation-um"),
])
def test_simulate_user_errors_exit_2(capsys, flags, match):
    assert main(["simulate", *STABLE, *flags]) == 2
    err = capsys.readouterr().err
    assert err.startswith("cctmill simulate: error:") and match in err


def test_analyze_and_stability_accept_the_floquet_criterion(capsys):
    out = _json(capsys, ["analyze", *CASE1, "--feed-mm-s", "1", "--json", "--criterion",
                         "floquet", "--mass", "robot", "--process-model", "oriented"])
    assert out["criterion"] == "floquet" and out["stable"] is False
    assert out["stable_eigen"] is True and out["floquet_spectral_radius"] > 1.0
    rows = _json(capsys, ["stability", *STABLE[:-2], "--feed-range-mm-s", "5:15:3", "--json",
                          "--criterion", "floquet"])
    assert len(rows) == 3 and all(r["stable"] for r in rows)
    assert all(r["floquet_spectral_radius"] < 1.0 for r in rows)
