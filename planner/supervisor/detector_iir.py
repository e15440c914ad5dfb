"""Fast chatter detector: a causal IIR band-pass at the predicted chatter frequency, with notches at
the tooth-passing harmonics, monitored with the DWT detector's control chart (docs/supervisor.md,
"Detectors").

**Why.** A band filter's output cannot follow a change of the chatter amplitude faster than about
1/(π B) for a band B Hz wide (the envelope time constant of a resonator). The thesis's DWT band is
one octave wide too, but its db4 filter at level 9 is an FIR 3,578 taps long whose energy centroid
lies 0.18 s (two chatter periods at 11 Hz) behind its newest sample. A Butterworth band-pass over
the same octave (prototype order 2: four poles) has its energy centroid 60 ms (0.66 period)
behind: the band answers within a period. What the short filter gives up is selectivity: its four
poles leave the tooth-passing line at 3 f_c only 23 dB down (db4: 51 dB), not enough to keep that
line (here 0.5 F̄: tens of newtons) out of a band whose limit is a few newtons. The tooth
frequencies are known from the plan (spindle speed × flutes), so second-order notches
(:func:`scipy.signal.iirnotch`) at f_t, 2 f_t, … take them out where the band-pass alone cannot,
at little delay at f_c. Band-pass energy at the expected chatter frequency is one of the classic
online chatter indicators (see Quintana and Ciurana, "Chatter in machining processes: a review",
IJMTM 2011); the choice between it and the DWT is made by measurement in
``benchmarks/detector_speed.py`` (docs/supervisor.md, "Detectors": about 0.7 chatter periods
median against the DWT's 2.1, at the same α_f and false alarms per hour).

**Band.** :data:`BAND_OCTAVES` wide, geometrically centred on the expected chatter frequency f_c
(the same f_c the DWT's level rule uses), Butterworth of order :data:`ORDER` (2·ORDER poles).
**Notches** at k f_t for k = 1 … :data:`TOOTH_HARMONICS` below the Nyquist frequency and at least
:data:`NOTCH_CLEAR_OCTAVES` outside the band (a tooth line inside the band cannot be removed without
removing chatter: then ``tooth_in_band`` is flagged, as the DWT does), quality factor
:data:`NOTCH_Q`.

**Streaming** (:class:`IirBandMonitor`): :func:`scipy.signal.sosfilt` with its state carried across
chunks (``zi``), so chunked and one-shot filtering agree to rounding. The state starts at the
filter's steady state for the first sample (:func:`scipy.signal.sosfilt_zi` × x₀): a signal that
begins at a mean force of 100 N does not ring. Band values are taken at the DWT's rate (every
2^j / :data:`~planner.supervisor.detector.OVERSAMPLE` samples for the level j of the same
:class:`~planner.supervisor.detector.LevelChoice`), so α_f is a rate per band value of the same
meaning for both detectors, and the first one after :attr:`IirBandMonitor.length` samples (the
impulse response's settling time).

**Chart and transients**: inherited unchanged from :class:`~planner.supervisor.detector.Detector`
(UCL = L_c σ, Φ(L_c) = 1 − α_f/2, σ the RMS band of stable cutting, the expected-mean-force
allowance through the same band filter).
"""

from __future__ import annotations

import math

import numpy as np
from scipy import signal

from models.errors import InputError
from planner.supervisor.detector import OVERSAMPLE, Detector, LevelChoice

__all__ = [
    "BAND_OCTAVES",
    "NOTCH_CLEAR_OCTAVES",
    "NOTCH_Q",
    "ORDER",
    "SETTLE_ENERGY",
    "TOOTH_HARMONICS",
    "IirBandMonitor",
    "IirDetector",
    "iir_band",
    "iir_sos",
]

#: Width of the band-pass [octaves], geometrically centred on f_c (the DWT's detail band is one
#: octave as well). On the tuning seed a wider band answers faster (2 octaves: 0.41 periods median)
#: and passes more cutting-force noise (11 against 5 false alarms per hour at α_f = 6e-5).
BAND_OCTAVES = 1.0
#: Butterworth prototype order (the band-pass has twice as many poles). Chosen with
#: ``benchmarks/detector_speed.py --tune`` on its tuning seed: order 1 answers faster (0.44 against
#: 0.75 periods median at α_f = 1e-7) but leaves the tooth line only 12 dB down before the notches;
#: both met the target there (≤ 1.5 periods at ≤ 1 false alarm per hour).
ORDER = 2
#: Tooth-passing harmonics notched (the simulated cut carries two; real cuts carry more).
TOOTH_HARMONICS = 4
#: Quality factor of each notch (−3 dB width k f_t / Q).
NOTCH_Q = 8.0
#: A tooth harmonic is notched only this far [octaves] outside the band's edges.
NOTCH_CLEAR_OCTAVES = 0.25
#: The band filter has settled when the impulse response's remaining energy is below this fraction
#: of its total (defines the warm-up length and the truncation of the energy centroid).
SETTLE_ENERGY = 1e-6
#: Longest impulse response considered [s] (a band of a fraction of a hertz would ring longer).
MAX_SETTLE_S = 10.0


def iir_band(chatter_hz: float, octaves: float = BAND_OCTAVES) -> tuple[float, float]:
    """The band-pass edges (f_c 2^(−octaves/2), f_c 2^(octaves/2)) [Hz]."""
    h = 2.0 ** (octaves / 2.0)
    return chatter_hz / h, chatter_hz * h


def iir_sos(fs_hz: float, band_hz: tuple[float, float], tooth_hz: float | None = None,
            order: int = ORDER, harmonics: int = TOOTH_HARMONICS,
            notch_q: float = NOTCH_Q) -> tuple[np.ndarray, list[float]]:
    """Second-order sections of the band-pass and its tooth notches; return (sos, notched [Hz]).

    Args:
        fs_hz: sample rate [Hz].
        band_hz: band-pass edges [Hz], 0 < lo < hi < f_s/2.
        tooth_hz: tooth-passing frequency [Hz] (None: no notches).
        order: Butterworth prototype order.
        harmonics: notch k f_t for k = 1 … harmonics.
        notch_q: notch quality factor.

    Raises:
        InputError: band edges out of (0, f_s/2) or not increasing, order < 1.
    """
    lo, hi = band_hz
    if not (math.isfinite(fs_hz) and fs_hz > 0):
        raise InputError("fs_hz", f"sample rate must be positive, got {fs_hz:g} Hz")
    if not (0 < lo < hi < fs_hz / 2):
        raise InputError("band", f"{lo:.4g}-{hi:.4g} Hz must lie in (0, f_s/2 = {fs_hz / 2:.4g} Hz) "
                         "with the lower edge first: raise the sample rate")
    if order < 1:
        raise InputError("order", f"must be >= 1, got {order}")
    sos = [signal.butter(order, [lo, hi], btype="bandpass", fs=fs_hz, output="sos")]
    notched: list[float] = []
    clear = 2.0**NOTCH_CLEAR_OCTAVES
    if tooth_hz is not None and math.isfinite(tooth_hz) and tooth_hz > 0:
        for k in range(1, harmonics + 1):
            f = k * tooth_hz
            if f >= 0.45 * fs_hz:
                break
            if lo / clear < f < hi * clear:
                continue
            b, a = signal.iirnotch(f, notch_q, fs=fs_hz)
            sos.append(signal.tf2sos(b, a))
            notched.append(f)
    return np.vstack(sos), notched


class IirBandMonitor:
    """Streaming output of the IIR band filter (see the module docstring); same interface as
    :class:`~planner.supervisor.detector.BandMonitor`.

    Args:
        fs_hz: sample rate [Hz].
        sos: second-order sections (:func:`iir_sos`).
        stride: one band value every this many samples.
    """

    def __init__(self, fs_hz: float, sos: np.ndarray, stride: int) -> None:
        self.fs_hz = float(fs_hz)
        self.sos = np.asarray(sos, dtype=float)
        self.stride = max(1, int(stride))
        self._zi_unit = signal.sosfilt_zi(self.sos)
        n_max = int(MAX_SETTLE_S * self.fs_hz)
        imp = np.zeros(n_max)
        imp[0] = 1.0
        h = signal.sosfilt(self.sos, imp)
        e = np.cumsum(h * h)
        settle = int(np.searchsorted(e, (1.0 - SETTLE_ENERGY) * e[-1])) + 1
        #: the impulse response up to its settling time (energy centroid, tests)
        self.impulse = h[:settle]
        self.reset()

    @property
    def length(self) -> int:
        """Settling time of the filter [samples]; the first band value needs this many samples."""
        return int(self.impulse.size)

    @property
    def ready(self) -> bool:
        return self._n >= self.length

    def reset(self) -> None:
        """Forget the signal (after a gap): the next band value needs a full settling time again."""
        self._n = 0
        self._zi: np.ndarray | None = None

    def push(self, t_s: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Append samples; return (t_s, band) of the band values due in them (stamped with the
        time of the sample they are the output at)."""
        v = np.asarray(values, dtype=float)
        n_new = v.shape[0]
        if n_new == 0:
            return np.zeros(0), np.zeros(0)
        if self._zi is None:
            self._zi = self._zi_unit * v[0]
        y, self._zi = signal.sosfilt(self.sos, v, zi=self._zi)
        first = max(self._n, self.length - 1)
        m0 = first + (-(first + 1)) % self.stride
        idx = np.arange(m0, self._n + n_new, self.stride) - self._n
        self._n += n_new
        return np.asarray(t_s, dtype=float)[idx], y[idx]


class IirDetector(Detector):
    """IIR band-pass + tooth notches with the DWT detector's chart; same interface as
    :class:`~planner.supervisor.detector.Detector`.

    Args:
        fs_hz: sample rate [Hz].
        choice: the DWT level choice of the same plan (its f_c, f_t and band-value rate are used).
        alpha_f: false-alarm rate per band value.
        sigma: σ of the band in stable cutting (signal unit); None until :meth:`learn`.
        wavelet: ignored (the interface of :class:`Detector`).
        band_hz: band-pass edges [Hz] (None: :func:`iir_band` of f_c).
        order: Butterworth prototype order.
        notch_q: quality factor of the tooth notches.
    """

    def __init__(self, fs_hz: float, choice: LevelChoice, alpha_f: float = 6e-5,
                 sigma: float | None = None, wavelet: str = "", *,
                 band_hz: tuple[float, float] | None = None, order: int = ORDER,
                 notch_q: float = NOTCH_Q) -> None:
        self.band_hz = band_hz if band_hz is not None else iir_band(choice.chatter_hz)
        self.sos, self.notched_hz = iir_sos(fs_hz, self.band_hz, choice.tooth_hz, order,
                                            notch_q=notch_q)
        #: a tooth harmonic lies in the band (or too near to notch): σ then includes it
        self.tooth_in_band = choice.tooth_hz is not None and not any(
            abs(f - choice.tooth_hz) < 1e-9 for f in self.notched_hz)
        self._stride = max(1, 2**choice.level // OVERSAMPLE)
        super().__init__(fs_hz, choice, alpha_f, sigma, wavelet)

    def _new_monitor(self) -> IirBandMonitor:  # type: ignore[override]
        return IirBandMonitor(self.fs_hz, self.sos, self._stride)

    def gain(self, f_hz: float) -> float:
        """|H(f)| of the band filter: band value per unit sinusoid amplitude at f [Hz]."""
        _, h = signal.sosfreqz(self.sos, worN=[float(f_hz)], fs=self.fs_hz)
        return float(abs(h[0]))

    @property
    def delay_s(self) -> float:
        """How long the band lags its input [s]: the energy centroid of the impulse response (the
        DWT detector's definition)."""
        g2 = self.monitor.impulse**2
        return float(np.sum(np.arange(g2.size) * g2) / np.sum(g2)) / self.fs_hz

    @property
    def reason(self) -> str:
        """The band in one sentence (the session's summary)."""
        notch = ", ".join(f"{f:.3g}" for f in self.notched_hz) or "none"
        return (f"IIR band-pass {self.band_hz[0]:.3g}-{self.band_hz[1]:.3g} Hz around f_c "
                f"{self.choice.chatter_hz:.3g} Hz, tooth notches at {notch} Hz")
