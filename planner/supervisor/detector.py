"""Wavelet chatter detector: one DWT detail band monitored with a control chart (docs/model.md §9).

**Level rule** (:func:`select_level`). The level-j detail of a DWT at sample rate f_s covers the
band [f_s/2^(j+1), f_s/2^j]. Take the level whose band contains the expected chatter frequency f_c
(the 2-DOF natural frequency of the pose): j_c = ⌊log2(f_s/f_c)⌋. If the tooth-passing frequency
f_t also lies in that band, move to a neighbouring level when f_c lies within
:data:`EDGE_OCTAVES` of that level's band edge (wavelet bands are soft: a quarter octave outside the
nominal edge the filter still passes most of the chatter) and its band excludes f_t; otherwise keep
j_c and flag ``tooth_in_band`` (σ learned from stable cutting then includes the tooth line). With
f_s = 10 kHz, f_c ≈ 11 Hz and f_t = 33 Hz this gives level 9, the thesis's choice.

**Control chart.** UCL = L_c σ with Φ(L_c) = 1 − α_f/2 (:func:`control_limit`; α_f = 6e-5 gives
L_c ≈ 4.0, the thesis's value) and σ the RMS of the detail coefficients in stable cutting
(:meth:`Detector.learn`).

**Expected transients.** A planned feed change (a section boundary) or a large override change
steps the mean cutting force, and a step has energy in every band: the thesis's feed-step test.
The detector is told the mean force the model expects (``expected_mean``: the characteristic's
force at the commanded feed) and runs the same band filter over it; the chart's limit in force is
UCL + :data:`TRANSIENT_GAIN` · max |band of the expected mean| over the last
:data:`TRANSIENT_SLACK_S` (the real step lags the command by the link and the controller). When
the feed is steady that allowance is zero and the chart is the thesis's.

**Streaming scheme** (:class:`BandMonitor`). The level-j detail coefficients of ``pywt.wavedec``
are samples of one FIR filter (noble identities): g_j = ↑1(h) ⊛ ↑2(h) ⊛ … ⊛ ↑2^(j−2)(h) ⊛
↑2^(j−1)(g), with h and g PyWavelets' decomposition low- and high-pass filters and ↑m inserting
m − 1 zeros between taps; cD_j[k] = (x ⊛ g_j)[2^j (k+1) − 1] (PyWavelets'
``mode="zero"``; tested against ``pywt.wavedec``). The monitor evaluates the same filter every
``stride`` = 2^j / :data:`OVERSAMPLE` samples (a superset of the decimated grid: the undecimated
detail, sampled finely enough to see every chatter peak) on the newest samples only, so a step costs
O(OVERSAMPLE · filter length / 2^j) multiply-adds per input sample whatever the level.
"""

from __future__ import annotations

import collections
import math
from dataclasses import dataclass
from statistics import NormalDist

import numpy as np
import pywt

from models.errors import InputError

__all__ = [
    "DEFAULT_WAVELET",
    "EDGE_OCTAVES",
    "OVERSAMPLE",
    "TRANSIENT_GAIN",
    "TRANSIENT_SLACK_S",
    "BandMonitor",
    "Detector",
    "DetectorOutput",
    "LevelChoice",
    "control_limit",
    "detail_filter",
    "select_level",
]

#: Daubechies 4 (8 taps): short enough in time for a detection within a few chatter periods,
#: selective enough to keep the tooth line an octave away out of the band.
DEFAULT_WAVELET = "db4"
#: How far [octaves] outside a band's nominal edge f_c may lie for that band still to be used when
#: the band that contains f_c also contains the tooth-passing frequency.
EDGE_OCTAVES = 0.25
#: Band values computed per 2^j input samples (the decimated DWT computes one).
OVERSAMPLE = 16
#: Margin on the expected transient (the model's force may be off by this factor).
TRANSIENT_GAIN = 1.5
#: How long after the commanded change the real force step may come [s] (link + path response).
TRANSIENT_SLACK_S = 0.15
#: A band RMS below this fraction of the signal's peak is rounding, not content (a constant signal
#: leaves ~1e-16 through the filters, whose taps sum to zero only to machine precision).
NO_CONTENT_REL = 1e-12
#: Deepest level considered (f_s / 2^13 is below 1 Hz for any f_s up to 8 kHz).
MAX_LEVEL = 14


@dataclass(frozen=True)
class LevelChoice:
    """The DWT level chosen for a sample rate and the expected frequencies.

    Attributes:
        level: DWT level j (≥ 1).
        band_hz: the level's nominal detail band (f_s/2^(j+1), f_s/2^j) [Hz].
        chatter_hz: expected chatter frequency f_c [Hz].
        tooth_hz: tooth-passing frequency f_t [Hz], or None when unknown.
        tooth_in_band: f_t lies in the chosen band (it could not be kept out).
        reason: one sentence saying how the level was chosen.
    """

    level: int
    band_hz: tuple[float, float]
    chatter_hz: float
    tooth_hz: float | None
    tooth_in_band: bool
    reason: str


def _band(fs_hz: float, j: int) -> tuple[float, float]:
    return fs_hz / 2 ** (j + 1), fs_hz / 2**j


def _inside(f: float | None, band: tuple[float, float]) -> bool:
    return f is not None and band[0] < f <= band[1]


def select_level(fs_hz: float, chatter_hz: float, tooth_hz: float | None = None) -> LevelChoice:
    """Choose the DWT level by the rule in the module docstring.

    Args:
        fs_hz: sample rate [Hz].
        chatter_hz: expected chatter frequency [Hz] (2-DOF natural frequency of the pose).
        tooth_hz: tooth-passing frequency [Hz] (spindle speed × flutes / 60), if known.

    Raises:
        InputError: non-positive or non-finite rates, or f_c at or above the Nyquist frequency.
    """
    if not (math.isfinite(fs_hz) and fs_hz > 0):
        raise InputError("fs_hz", f"sample rate must be positive, got {fs_hz:g} Hz")
    if not (math.isfinite(chatter_hz) and 0 < chatter_hz < fs_hz / 2):
        raise InputError("chatter frequency", f"{chatter_hz:.6g} Hz must lie in (0, f_s/2 = "
                         f"{fs_hz / 2:.6g} Hz): raise the sample rate")
    jc = int(math.floor(math.log2(fs_hz / chatter_hz)))
    jc = max(1, jc)
    if jc > MAX_LEVEL:
        raise InputError("fs_hz", f"level {jc} needed for {chatter_hz:.6g} Hz at {fs_hz:.6g} Hz; lower the "
                         f"sample rate (at most level {MAX_LEVEL})")
    band = _band(fs_hz, jc)
    if not _inside(tooth_hz, band):
        return LevelChoice(jc, band, chatter_hz, tooth_hz, False,
                           f"level {jc}: band {band[0]:.3g}-{band[1]:.3g} Hz contains f_c "
                           f"{chatter_hz:.3g} Hz" + ("" if tooth_hz is None else
                                                     f" and excludes f_t {tooth_hz:.3g} Hz"))
    edge = 2.0**EDGE_OCTAVES
    for j in (jc - 1, jc + 1):
        if not 1 <= j <= MAX_LEVEL:
            continue
        lo, hi = _band(fs_hz, j)
        near = lo / edge < chatter_hz <= hi * edge
        if near and not _inside(tooth_hz, (lo, hi)):
            return LevelChoice(j, (lo, hi), chatter_hz, tooth_hz, False,
                               f"level {j}: f_t {tooth_hz:.3g} Hz lies in level {jc}'s band with f_c "
                               f"{chatter_hz:.3g} Hz; level {j} ({lo:.3g}-{hi:.3g} Hz) excludes it "
                               f"and f_c is within {EDGE_OCTAVES} octave of its edge")
    return LevelChoice(jc, band, chatter_hz, tooth_hz, True,
                       f"level {jc}: band {band[0]:.3g}-{band[1]:.3g} Hz contains f_c "
                       f"{chatter_hz:.3g} Hz and also f_t {tooth_hz:.3g} Hz, which no neighbouring "
                       "level can exclude; sigma from stable cutting includes the tooth line")


def control_limit(alpha_f: float) -> float:
    """L_c with Φ(L_c) = 1 − α_f/2 (two-sided false-alarm rate α_f per band value).

    Raises:
        InputError: α_f outside (0, 1).
    """
    if not (math.isfinite(alpha_f) and 0 < alpha_f < 1):
        raise InputError("alpha_f", f"false-alarm rate must lie in (0, 1), got {alpha_f:g}")
    return NormalDist().inv_cdf(1.0 - alpha_f / 2.0)


def detail_filter(wavelet: str, level: int) -> np.ndarray:
    """The FIR filter g_j whose output sampled at 2^j (k+1) − 1 is pywt's level-j detail."""
    try:
        w = pywt.Wavelet(wavelet)
    except ValueError as e:
        raise InputError("wavelet", f"{wavelet!r} is not a discrete wavelet PyWavelets knows ({e})") from e
    if level < 1:
        raise InputError("level", f"must be >= 1, got {level}")
    lo = np.asarray(w.dec_lo, dtype=float)
    hi = np.asarray(w.dec_hi, dtype=float)
    g = np.ones(1)
    for i in range(level):
        h = hi if i == level - 1 else lo
        up = np.zeros((h.size - 1) * 2**i + 1)
        up[:: 2**i] = h
        g = np.convolve(g, up)
    return g


class BandMonitor:
    """Streaming level-j detail of a sampled signal (see the module docstring).

    Args:
        level: DWT level j.
        wavelet: PyWavelets name (default :data:`DEFAULT_WAVELET`).
        oversample: band values per 2^j samples (power of two, ≤ 2^j).
    """

    def __init__(self, level: int, wavelet: str = DEFAULT_WAVELET, oversample: int = OVERSAMPLE) -> None:
        self.level = level
        self.wavelet = wavelet
        self.filter = detail_filter(wavelet, level)
        self._rev = np.ascontiguousarray(self.filter[::-1])
        self.stride = max(1, 2**level // max(1, oversample))
        self.reset()

    @property
    def length(self) -> int:
        """Filter length [samples]; the first band value needs this many samples."""
        return int(self.filter.size)

    @property
    def ready(self) -> bool:
        return self._n >= self.length

    def reset(self) -> None:
        """Forget the signal (after a gap): the next band value needs a full filter length again."""
        self._n = 0
        self._tail = np.zeros(0)
        self._tail_t = np.zeros(0)

    def push(self, t_s: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Append samples; return (t_s, detail) of the band values that became computable.

        A band value is stamped with the time of the newest sample under the filter.
        """
        v = np.asarray(values, dtype=float)
        n_new = v.shape[0]
        if n_new == 0:
            return np.zeros(0), np.zeros(0)
        L = self.length
        buf = np.concatenate((self._tail, v))
        buf_t = np.concatenate((self._tail_t, np.asarray(t_s, dtype=float)))
        start = self._n - self._tail.shape[0]  # global index of buf[0]
        n_end = self._n + n_new
        # outputs m (global index of the newest sample under the filter) with (m + 1) % stride == 0,
        # m >= L - 1 (full window) and m in the new samples
        first = max(self._n, L - 1)
        m0 = first + (-(first + 1)) % self.stride
        ms = np.arange(m0, n_end, self.stride)
        if ms.size:
            idx = ms - start
            windows = np.lib.stride_tricks.sliding_window_view(buf, L)[idx - (L - 1)]
            d = windows @ self._rev
            t_out = buf_t[idx]
        else:
            d = np.zeros(0)
            t_out = np.zeros(0)
        keep = min(L - 1, buf.shape[0])
        self._tail = buf[buf.shape[0] - keep:].copy()
        self._tail_t = buf_t[buf.shape[0] - keep:].copy()
        self._n = n_end
        return t_out, d


@dataclass(frozen=True)
class DetectorOutput:
    """What one update of the detector found.

    Attributes:
        band: largest |detail| among the band values computed in this update, or None when none was
            computed (not enough samples yet, or a chunk shorter than the stride).
        ucl: the control limit L_c σ (same unit as the signal).
        alarm: band > ucl.
        excess: (band − ucl) / ucl when alarmed, else 0.
        t_s: time stamp of the largest band value [s], or None.
        allowance: the expected-transient allowance included in ``ucl`` (0 when the feed is steady).
    """

    band: float | None
    ucl: float
    alarm: bool
    excess: float
    t_s: float | None
    allowance: float = 0.0


class Detector:
    """The band monitor plus its control chart.

    Args:
        fs_hz: sample rate [Hz].
        choice: the level (from :func:`select_level`).
        alpha_f: false-alarm rate per band value.
        sigma: σ of the band in stable cutting (signal unit); None until :meth:`learn`.
        wavelet: PyWavelets name.
    """

    def __init__(self, fs_hz: float, choice: LevelChoice, alpha_f: float = 6e-5,
                 sigma: float | None = None, wavelet: str = DEFAULT_WAVELET) -> None:
        self.fs_hz = fs_hz
        self.choice = choice
        self.alpha_f = alpha_f
        self.l_c = control_limit(alpha_f)
        self.wavelet = wavelet
        self.monitor = self._new_monitor()
        self._model = self._new_monitor()
        self._recent: collections.deque[tuple[float, float]] = collections.deque()
        self.sigma = sigma

    def _new_monitor(self) -> BandMonitor:
        """A fresh band filter (a subclass with another band filter overrides this)."""
        return BandMonitor(self.choice.level, self.wavelet)

    def gain(self, f_hz: float) -> float:
        """|G(f)| of the band filter: band value per unit sinusoid amplitude at f [Hz]."""
        g = self.monitor.filter
        w = 2 * math.pi * f_hz / self.fs_hz
        return float(abs(np.sum(g * np.exp(-1j * w * np.arange(g.size)))))

    def reset(self) -> None:
        """Forget the signal (after a gap or a bad chunk): band values resume after a warm-up."""
        self.monitor.reset()
        self._model.reset()
        self._recent.clear()

    @property
    def reason(self) -> str:
        """The band in one sentence (the session's summary)."""
        return f"DWT {self.wavelet} {self.choice.reason}"

    @property
    def ucl(self) -> float:
        return self.l_c * self.sigma if self.sigma is not None else math.inf

    @property
    def warmup_s(self) -> float:
        """Signal time before the first band value [s] (one filter length)."""
        return self.monitor.length / self.fs_hz

    @property
    def delay_s(self) -> float:
        """How long the band lags its input [s]: the energy centroid of the band filter (a
        Daubechies filter is not linear-phase; its centroid is near the middle: 0.179 s for db4 at
        level 9 and 10 kHz, the measured median detection delay being 0.18 s). A change of the
        chatter amplitude shows in the band about this much later."""
        g2 = self.monitor.filter**2
        return float(np.sum(np.arange(g2.size) * g2) / np.sum(g2)) / self.fs_hz

    def learn(self, values: np.ndarray) -> float:
        """Set σ to the RMS of the band over ``values`` (a stable-cutting record); return it.

        Raises:
            InputError: the record is shorter than twice the filter or its band is all zero.
        """
        v = np.asarray(values, dtype=float)
        if v.shape[0] < 2 * self.monitor.length:
            raise InputError("stable window", f"{v.shape[0]} samples; need at least "
                             f"{2 * self.monitor.length} ({2 * self.warmup_s:.2f} s) for the band "
                             f"filter (level {self.choice.level})")
        mon = self._new_monitor()
        _, d = mon.push(np.arange(v.shape[0]) / self.fs_hz, v)
        sigma = float(np.sqrt(np.mean(d * d)))
        scale = float(np.max(np.abs(v))) if v.size else 0.0
        if not (math.isfinite(sigma) and sigma > NO_CONTENT_REL * scale and sigma > 0):
            raise InputError("stable window", f"band RMS is {sigma:.4g}: the record has no content in "
                             f"the band {self.choice.band_hz[0]:.3g}-{self.choice.band_hz[1]:.3g} Hz")
        self.sigma = sigma
        return sigma

    def _allowance(self, t_s: np.ndarray, n: int, expected_mean: float | None) -> float:
        if expected_mean is None or not math.isfinite(expected_mean) or n == 0:
            return 0.0
        tm, dm = self._model.push(t_s, np.full(n, float(expected_mean)))
        if dm.size:
            self._recent.append((float(tm[-1]), float(np.max(np.abs(dm)))))
        horizon = float(t_s[-1]) - TRANSIENT_SLACK_S
        while self._recent and self._recent[0][0] < horizon:
            self._recent.popleft()
        return TRANSIENT_GAIN * max((a for _, a in self._recent), default=0.0)

    def observe(self, t_s: np.ndarray, values: np.ndarray,
                expected_mean: float | None = None) -> np.ndarray:
        """Feed samples without judging them (a learning window); return the new band values.

        Both band filters (signal and expected mean) stay warm, so the chart is ready the moment
        σ is known.
        """
        _, d = self.monitor.push(t_s, values)
        self._allowance(t_s, np.shape(values)[0], expected_mean)
        return d

    def update(self, t_s: np.ndarray, values: np.ndarray,
               expected_mean: float | None = None) -> DetectorOutput:
        """Feed samples (finite, consecutive); return the chart's verdict on the new band values.

        Args:
            t_s: sample times [s], shape (n,).
            values: samples, shape (n,).
            expected_mean: the mean force the model expects over these samples (signal unit), or
                None to skip the transient allowance.
        """
        t_out, d = self.monitor.push(t_s, values)
        allowance = self._allowance(t_s, np.shape(values)[0], expected_mean)
        ucl = self.ucl + allowance
        if d.size == 0:
            return DetectorOutput(None, ucl, False, 0.0, None, allowance)
        i = int(np.argmax(np.abs(d)))
        band = float(abs(d[i]))
        alarm = band > ucl
        return DetectorOutput(band, ucl, alarm, (band - ucl) / ucl if alarm else 0.0, float(t_out[i]),
                              allowance)
