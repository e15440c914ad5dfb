"""IIR chatter detector: streaming equals one-shot filtering, its gain and notches against measured
sinusoids, a quiet chart on stable cutting, faster detection than the DWT on the same growing
chatter, the registry, the supervisor with ``detector="iir"`` and the benchmark's quick run."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest
from _plans import NATURAL_HZ, ONE_SECTION, TOOTH_HZ, ApplyingLink, make_plan

from models.errors import InputError
from planner.plan_file import load_plan
from planner.supervisor import Supervisor, SupervisorConfig
from planner.supervisor.detector import Detector, select_level
from planner.supervisor.detector_iir import IirBandMonitor, IirDetector, iir_band, iir_sos
from planner.supervisor.detectors import DETECTORS, make_detector
from planner.supervisor.loop import VirtualClock, run_loop
from planner.supervisor.metrics import episode_metrics
from planner.supervisor.session import simulated_sigma
from planner.supervisor.sim_cut import CutScenario, SimulatedCut

BENCH = str(Path(__file__).resolve().parents[1] / "benchmarks")
if BENCH not in sys.path:
    sys.path.insert(0, BENCH)

FS = 10_000.0
F_C = math.sqrt(NATURAL_HZ[0] * NATURAL_HZ[1])


def _choice():
    return select_level(FS, F_C, TOOTH_HZ)


def _steady_amplitude(det: IirDetector, f_hz: float, seconds: float = 3.0) -> float:
    """Peak |band| over the last second of a unit sinusoid at f_hz (the filter settled)."""
    t = np.arange(int(seconds * FS)) / FS
    mon = det._new_monitor()
    tb, d = mon.push(t, np.sin(2 * math.pi * f_hz * t + 0.3))
    return float(np.max(np.abs(d[tb > seconds - 1.0])))


def test_chunked_filtering_equals_one_shot(rng):
    det = IirDetector(FS, _choice())
    x = 100.0 + rng.normal(size=30_000)
    t = np.arange(x.size) / FS
    t_one, d_one = det._new_monitor().push(t, x)
    mon = det._new_monitor()
    parts = []
    cuts = np.sort(rng.choice(np.arange(1, x.size), size=60, replace=False))
    for a, b in zip(np.r_[0, cuts], np.r_[cuts, x.size], strict=True):
        parts.append(mon.push(t[a:b], x[a:b]))
    t_ch = np.concatenate([p[0] for p in parts])
    d_ch = np.concatenate([p[1] for p in parts])
    np.testing.assert_array_equal(t_ch, t_one)
    np.testing.assert_allclose(d_ch, d_one, rtol=0, atol=1e-9)
    assert t_one.size and t_one[0] >= (mon.length - 1) / FS     # first value after settling
    assert np.allclose(np.diff(t_one), mon.stride / FS)


def test_gain_matches_the_measured_amplitude_of_a_sinusoid():
    det = IirDetector(FS, _choice())
    for f in (F_C, 0.9 * F_C, 1.1 * F_C, 20.0):
        measured = _steady_amplitude(det, f)
        assert measured == pytest.approx(det.gain(f), rel=0.01), f
    assert det.gain(F_C) == pytest.approx(1.0, rel=0.01)   # the band-pass's centre


def test_notches_remove_the_tooth_line():
    choice = _choice()
    det = IirDetector(FS, choice)
    assert det.notched_hz and det.notched_hz[0] == pytest.approx(TOOTH_HZ)
    assert not det.tooth_in_band
    bare = IirBandMonitor(FS, iir_sos(FS, det.band_hz, None)[0], 32)
    t = np.arange(int(3 * FS)) / FS
    tooth = 70.0 * np.sin(2 * math.pi * TOOTH_HZ * t) + 28.0 * np.sin(4 * math.pi * TOOTH_HZ * t)
    tb_bare, d_bare = bare.push(t, tooth)
    tb, d = det._new_monitor().push(t, tooth)
    late = tb > 2.0
    assert np.max(np.abs(d_bare[tb_bare > 2.0])) > 2.0   # the band-pass alone leaks newtons
    assert np.max(np.abs(d[late])) < 0.05          # the notches take the line out
    assert det.gain(TOOTH_HZ) < 1e-3 and det.gain(2 * TOOTH_HZ) < 1e-3


def _cut_force(rng, seconds, mean_F=140.0):
    t = np.arange(int(seconds * FS)) / FS
    y = mean_F * (1 + 0.5 * np.sin(2 * math.pi * TOOTH_HZ * t + 1.0)
                  + 0.2 * np.sin(4 * math.pi * TOOTH_HZ * t + 2.0))
    y += 0.005 * mean_F * np.sin(2 * math.pi * F_C * t + 0.5) + rng.normal(0.0, 0.3, t.size)
    return t, y


def test_stable_cutting_raises_no_alarm(rng):
    alpha = SupervisorConfig().alpha_f
    det = make_detector("iir", FS, _choice(), alpha, None, "db4")
    det.learn(_cut_force(rng, 2.0)[1])
    t, y = _cut_force(rng, 20.0)
    alarms = 0
    for k in range(0, t.size, 40):     # the supervisor's 4 ms steps
        out = det.update(t[k:k + 40], y[k:k + 40], expected_mean=140.0)
        alarms += out.alarm
    assert alarms == 0
    assert det.ucl == pytest.approx(4.01 * det.sigma, rel=1e-3)


def test_growing_chatter_is_detected_faster_by_iir_than_dwt():
    from detector_speed import default_detectors, detection_delays

    # the same four seeded onsets through both detectors, each run learning its own sigma
    r = detection_delays(default_detectors(6e-5), 4, seed=11, alphas=(6e-5,))
    dwt, iir = r["dwt"][6e-5], r["iir"][6e-5]
    assert dwt["missed"] == iir["missed"] == 0
    for a, b in zip(iir["delay_s"], dwt["delay_s"], strict=True):   # the same onsets
        assert a < b - 0.05
    assert max(iir["delay_periods"]) < 1.0 and np.median(dwt["delay_periods"]) > 1.5


def test_make_detector_refuses_an_unknown_name():
    assert set(DETECTORS) == {"dwt", "iir"}
    assert type(make_detector("dwt", FS, _choice(), 6e-5, None, "db4")) is Detector
    with pytest.raises(InputError, match="not a detector"):
        make_detector("kalman", FS, _choice(), 6e-5, None, "db4")


def test_iir_band_edges():
    lo, hi = iir_band(F_C, 1.0)
    assert math.sqrt(lo * hi) == pytest.approx(F_C) and hi / lo == pytest.approx(2.0)
    with pytest.raises(InputError):
        iir_sos(FS, (20.0, 10.0))


def _supervised(tmp_path, detector: str):
    plan = load_plan(make_plan(tmp_path / detector, ONE_SECTION))
    cfg = SupervisorConfig(detector=detector)
    sc = CutScenario(onset_s=1.0, seed=3)
    sigma = simulated_sigma(plan, FS, sc, cfg)
    clk = VirtualClock()
    link = ApplyingLink()
    cut = SimulatedCut(plan, link.read_override, FS, sc, clock=clk)
    sup = Supervisor(plan, FS, sigma=sigma, config=cfg)
    run_loop(sup, cut, link, 2.2, 0.004, clock=clk, sleep=clk.sleep)
    return sup, episode_metrics(sup, cut.truth, sup.level.chatter_hz, sc.onset_s, cut.start_clock_s)


def test_supervisor_with_the_iir_detector_detects_chatter(tmp_path):
    sup, m = _supervised(tmp_path, "iir")
    assert isinstance(sup.detector, IirDetector)
    assert sup.episodes and m and m[0].onset_to_alarm_s > 0
    assert m[0].detection_delay_s is not None and m[0].detection_delay_s < 0.08
    _, m_dwt = _supervised(tmp_path, "dwt")
    assert m_dwt and m[0].alarm_s < m_dwt[0].alarm_s - 0.05


def test_benchmark_quick_run_returns_its_table(capsys):
    import detector_speed

    r = detector_speed.main(["--quick", "--json"])
    assert {"rows", "hours", "onsets", "sigma", "filter_delay_ms", "feed_steps", "entries",
            "exits", "target", "wall_s"} <= set(r)
    names = {row["detector"] for row in r["rows"]}
    assert names == {"dwt", "iir"}
    for row in r["rows"]:
        assert {"delay_periods", "delay_ms", "false_alarms_per_hour", "target_met",
                "alpha_f"} <= set(row)
        assert row["detected"] == row["onsets"]
    assert r["entries"] > 0 and r["feed_steps"] > 0
    md = detector_speed.markdown(r)
    assert "| iir |" in md and "| dwt (default) |" in md
    assert capsys.readouterr().out.strip().startswith("{")


@pytest.mark.parametrize("name", ["dwt", "iir"])
def test_benchmark_chart_agrees_with_the_detectors_own_steps(name, rng):
    """The benchmark judges per band value what Detector.update judges per 4 ms step: an entry, a
    feed step, then growing chatter give the same alarm (none before the chatter) either way."""
    from detector_speed import _allowance, _band

    det = make_detector(name, FS, _choice(), 6e-5, None, "db4")
    det.learn(_cut_force(rng, 2.0)[1])
    t = np.arange(int(6.0 * FS)) / FS
    expected = np.where(t < 1.0, 0.0, np.where(t < 3.0, 140.0, 110.0))
    real = np.interp(t, [0, 1.01, 1.04, 3.0, 3.05, 6], [0, 0, 140, 140, 110, 110])
    _, y = _cut_force(rng, 6.0, mean_F=real)
    y += np.where(t >= 4.0, 0.05 * np.exp(25.0 * (t - 4.0)), 0.0) * np.sin(2 * math.pi * F_C * t)
    tb, d, dm = _band(det, iter([(t, y, expected)]))
    over = d > det.ucl + _allowance(tb, dm)
    first_bench = float(tb[over][0])
    first_step = None
    for k in range(0, t.size, 40):
        out = det.update(t[k:k + 40], y[k:k + 40], expected_mean=float(expected[k]))
        if out.alarm:
            first_step = float(t[min(k + 39, t.size - 1)])
            break
    assert first_step is not None and first_bench > 4.0
    assert abs(first_step - first_bench) <= 0.005
