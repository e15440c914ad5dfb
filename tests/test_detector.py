"""Wavelet chatter detector: the streaming band filter against PyWavelets, the level rule, the
control limit, the false-alarm rate on white noise, selectivity, and the expected-transient
allowance."""

from __future__ import annotations

import math
from statistics import NormalDist

import numpy as np
import pytest
import pywt

from models.errors import InputError
from planner.supervisor.detector import (
    BandMonitor,
    Detector,
    control_limit,
    detail_filter,
    select_level,
)

FS = 10_000.0


@pytest.mark.parametrize("wavelet,level", [("db4", 9), ("db2", 3), ("haar", 5), ("sym8", 6),
                                           ("db4", 1)])
def test_detail_filter_reproduces_wavedec(rng, wavelet, level):
    x = rng.normal(size=6000)
    g = detail_filter(wavelet, level)
    coeffs = pywt.wavedec(x, wavelet, mode="zero", level=level)[1]
    full = np.convolve(x, g)
    mine = full[2**level * (np.arange(coeffs.size) + 1) - 1]
    np.testing.assert_allclose(mine, coeffs, atol=1e-12)


@pytest.mark.parametrize("level", [3, 9])
def test_streaming_equals_batch_for_any_chunking(rng, level):
    x = rng.normal(size=12_000)
    t = np.arange(x.size) / FS
    mon = BandMonitor(level)
    outs_t, outs_d = [], []
    i = 0
    while i < x.size:
        n = int(rng.integers(1, 200))
        ti, di = mon.push(t[i:i + n], x[i:i + n])
        outs_t.append(ti)
        outs_d.append(di)
        i += n
    tt, dd = np.concatenate(outs_t), np.concatenate(outs_d)
    m = np.round(tt * FS).astype(int)
    full = np.convolve(x, mon.filter)
    assert m.size > 0 and m[0] == mon.length - 1 + (-(mon.length)) % mon.stride
    np.testing.assert_allclose(dd, full[m], atol=1e-12)
    assert np.all(np.diff(m) == mon.stride)
    # the decimated DWT grid is a subset of the streamed one, and matches pywt.wavedec
    coeffs = pywt.wavedec(x, mon.wavelet, mode="zero", level=level)[1]
    k = (m + 1) // 2**level - 1
    on_grid = (m + 1) % 2**level == 0
    np.testing.assert_allclose(dd[on_grid], coeffs[k[on_grid]], atol=1e-12)


def test_monitor_reset_needs_a_full_window_again(rng):
    mon = BandMonitor(4)
    x = rng.normal(size=500)
    mon.push(np.arange(500) / FS, x)
    assert mon.ready
    mon.reset()
    assert not mon.ready
    t, d = mon.push(np.arange(10) / FS, x[:10])
    assert d.size == 0


def test_level_rule_thesis_case():
    ch = select_level(FS, 11.0, 1000 * 2 / 60)
    assert ch.level == 9  # the thesis's level
    assert ch.band_hz[0] < 11.0 <= ch.band_hz[1]
    assert not ch.tooth_in_band


def test_level_rule_moves_off_the_tooth_line():
    ch = select_level(FS, 11.0, 15.0)  # f_t in level 9's band; f_c within 1/4 octave of level 10
    assert ch.level == 10 and not ch.tooth_in_band
    assert "excludes" in ch.reason


def test_level_rule_flags_an_unavoidable_tooth_line():
    ch = select_level(2000.0, 11.0, 15.0)
    assert ch.level == 7 and ch.tooth_in_band
    assert "sigma" in ch.reason


@pytest.mark.parametrize("fs,fc,match", [
    (0.0, 11.0, "sample rate"), (-5.0, 11.0, "sample rate"), (float("nan"), 11.0, "sample rate"),
    (FS, 6000.0, "f_s/2"), (FS, 0.0, "f_s/2"), (1e7, 1.0, "lower the sample rate"),
])
def test_level_rule_errors(fs, fc, match):
    with pytest.raises(InputError, match=match):
        select_level(fs, fc, None)


def test_control_limit_from_false_alarm_rate():
    lc = control_limit(6e-5)
    assert lc == pytest.approx(4.0, abs=0.02)  # the thesis's L_c = 4
    assert NormalDist().cdf(lc) == pytest.approx(1 - 6e-5 / 2, abs=1e-12)
    assert control_limit(0.05) == pytest.approx(1.959964, abs=1e-5)


@pytest.mark.parametrize("alpha", [0.0, 1.0, -1e-3, float("nan")])
def test_control_limit_rejects(alpha):
    with pytest.raises(InputError, match="alpha_f"):
        control_limit(alpha)


def test_false_alarm_rate_on_white_noise_matches_alpha(rng):
    # decimated detail coefficients of white Gaussian noise (orthonormal wavelet) are i.i.d.
    # N(0, sigma^2): the share over L_c sigma must be alpha_f.
    alpha = 0.01
    level = 3
    x = rng.normal(0.0, 2.0, size=400_000)
    det = Detector(FS, select_level(FS, FS / 2**level * 0.75), alpha_f=alpha)
    assert det.choice.level == level
    det.learn(x[:40_000])
    assert det.sigma == pytest.approx(2.0, rel=0.03)
    mon = BandMonitor(level)
    t, d = mon.push(np.arange(x.size) / FS, x)
    m = np.round(t * FS).astype(int)
    dec = d[(m + 1) % 2**level == 0]
    share = np.mean(np.abs(dec) > det.ucl)
    n = dec.size
    assert abs(share - alpha) < 4 * math.sqrt(alpha * (1 - alpha) / n)


def _tone(f, amp, n, phase=0.0):
    return amp * np.sin(2 * np.pi * f * np.arange(n) / FS + phase)


def test_band_sees_chatter_and_not_the_tooth_line(rng):
    n = 30_000
    ch = select_level(FS, 11.0, 33.3)
    det = Detector(FS, ch)
    stable = 100 + _tone(33.3, 50.0, n) + rng.normal(0, 0.5, n)
    det.learn(stable)
    t = np.arange(n) / FS
    quiet = Detector(FS, ch, sigma=det.sigma)
    outs = [quiet.update(t[i:i + 40], stable[i:i + 40]) for i in range(0, n, 40)]
    assert not any(o.alarm for o in outs)
    chatter = stable + _tone(11.0, 2.0, n)
    loud = Detector(FS, ch, sigma=det.sigma)
    outs = [loud.update(t[i:i + 40], chatter[i:i + 40]) for i in range(0, n, 40)]
    assert sum(o.alarm for o in outs) > 50
    # a tooth line twice as strong does not alarm: it lies outside the band
    louder_teeth = Detector(FS, ch, sigma=det.sigma)
    x = 100 + _tone(33.3, 100.0, n) + rng.normal(0, 0.5, n)
    assert not any(louder_teeth.update(t[i:i + 40], x[i:i + 40]).alarm for i in range(0, n, 40))


def test_expected_transient_allowance_prevents_the_feed_step_alarm(rng):
    n = 30_000
    ch = select_level(FS, 11.0, 33.3)
    t = np.arange(n) / FS
    mean = np.where(t < 1.5, 140.0, 80.0)  # feed step: mean force 140 N -> 80 N
    lag = np.exp(-np.clip(t - 1.5, 0, None) / 0.03)
    mean_real = np.where(t < 1.5, 140.0, 80.0 + 60.0 * lag)
    noise = rng.normal(0, 0.3, n) + 0.7 * np.sin(2 * np.pi * 11 * t)
    x = mean_real + noise
    ref = Detector(FS, ch)
    ref.learn(x[:12_000])

    def alarms(expected: bool) -> int:
        det = Detector(FS, ch, sigma=ref.sigma)
        count = 0
        for i in range(0, n, 40):
            # the supervisor commands the step 10 ms before the force moves
            e = float(np.where(t[i] + 0.01 < 1.5, 140.0, 80.0)) if expected else None
            count += det.update(t[i:i + 40], x[i:i + 40], e).alarm
        return count

    assert alarms(expected=False) > 0  # the step alone trips the plain chart
    assert alarms(expected=True) == 0
    del mean


def test_learn_errors(rng):
    det = Detector(FS, select_level(FS, 11.0, 33.3))
    with pytest.raises(InputError, match="need at least"):
        det.learn(rng.normal(size=1000))
    with pytest.raises(InputError, match="no content"):
        det.learn(np.full(20_000, 5.0))
    assert det.ucl == math.inf


def test_unknown_wavelet():
    with pytest.raises(InputError, match="wavelet"):
        detail_filter("nope", 3)
