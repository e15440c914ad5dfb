"""The record of a section the supervisor ran: what ``cctmill supervise`` appends to its records file.

The supervisor knows the plan (pose, cut and feed of every section), the override the controller
applied, its detector's verdict and, from the signal, the mean force and the chatter frequency;
:func:`section_record` turns them into a :class:`~planner.calibrate.records.CutRecord` (the pose
and cut of the section's middle sample; the cut frame from the path's tangent and the tool axis)
and :func:`append_record` adds it to a JSON Lines file, one line per section, flushed, so a crash
keeps the records already written.

:class:`SectionRecorder` does both inside the loop, and sees the signal the supervisor reads
through :meth:`SectionRecorder.tap` (the source the loop reads, every chunk handed on):

- **mean force**: over the section's *steady part* only — whole tooth periods (1/f_t, f_t the
  section's tooth-passing frequency) that start at least :data:`SETTLE_S` (and
  :data:`SETTLE_PERIODS` tooth periods) after the section's first sample and end as long before
  its last, each holding all its samples (a gap in the signal, or samples that came while the
  supervisor held, went safe or failed, make a period partial; it is left out). The
  entry and exit transients (the feed step at the boundary, the path-speed lag, the supervisor's
  dead-reckoned boundary being a few ms off the true one) stay out, and the tooth ripple averages
  to zero. Fewer than :data:`MIN_STEADY_PERIODS` such periods: no mean force (not a wrong one).
  The record's feed is then the plan's × the override averaged over the same periods. A mean
  force is written only when the signal is one (``signal``, :data:`SIGNALS`): a 3-axis force on
  the tool in base or cut axes, or the simulated cut's resultant — the record always holds it in
  the cut frame (X_o, Y_o, Z_o; ``frame`` left at its default). A one-channel signal (a strain
  gauge, one force axis: ``scalar``) gives none.
- **chatter frequency**: for a section judged ``chatter``, the peak of the spectrum of the last
  :data:`CHATTER_WINDOW_S` of signal before its strongest alarm, searched in the detector's band
  (widened by :data:`BAND_SLACK_OCTAVES`, tooth harmonics left out): :func:`chatter_frequency_of`.
  Any signal gives it (a frequency needs no unit).
"""

from __future__ import annotations

import collections
import dataclasses
import math
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from models.cutting import MILLING_MODES
from planner.calibrate.records import CutRecord, dumps_record

__all__ = [
    "BAND_SLACK_OCTAVES",
    "CHATTER_WINDOW_S",
    "MIN_CHATTER_PERIODS",
    "MIN_STEADY_PERIODS",
    "SETTLE_PERIODS",
    "SETTLE_S",
    "SIGNALS",
    "SectionRecorder",
    "append_record",
    "chain_on_cycle",
    "chatter_frequency_of",
    "model_force_direction",
    "section_record",
]

#: Step statuses during which the detector cannot judge the cut (signal missing, filters settling).
_BLIND = {"learning", "warmup", "hold", "safe", "error"}
#: A section is ``unknown`` when the detector was blind for more than this share of its steps [-].
BLIND_SHARE_MAX = 0.5
#: What the recorder's samples are: ``scalar`` one channel of its own unit (a strain gauge, one
#: force axis: no mean force); ``resultant`` the resultant force |F| on the tool [N] (the
#: simulated cut; the mean force is its mean along the model's direction,
#: :func:`model_force_direction`); ``force_base``, ``force_cut`` a 3-axis force on the tool [N],
#: values of shape (n, 3), in robot base axes or in the cut frame (X_o, Y_o, Z_o).
SIGNALS = ("scalar", "resultant", "force_base", "force_cut")
#: Signal left out of a section's mean force after its first and before its last sample [s]:
#: five time constants of the simulated path-speed lag (30 ms: what is left of a feed step is
#: 0.7 % of it, and decays within the next 30 ms), the controller's response to a feed step, and
#: the supervisor's dead-reckoned boundary a few ms off the true one.
SETTLE_S = 0.15
#: ... and at least this many tooth periods at each end [-] (a slow spindle's first engagement).
SETTLE_PERIODS = 3
#: Fewest whole tooth periods in the steady part for a mean force [-]: 10 periods leave the
#: forced response at the chatter frequency (~1/3 of the tooth frequency) averaged to a few % of
#: its own amplitude.
MIN_STEADY_PERIODS = 10
#: Signal kept for the chatter frequency, ending at the section's strongest alarm [s]: eleven
#: periods of the KR210's ~11 Hz mode; the spectrum's bins are 1/this apart before interpolation.
CHATTER_WINDOW_S = 1.0
#: Fewest periods of the band's lowest frequency in that window for a frequency [-].
MIN_CHATTER_PERIODS = 4
#: The frequency is searched in the detector's band widened by this on each side [octaves]
#: (wavelet bands are soft: docs/model.md §9).
BAND_SLACK_OCTAVES = 0.25
#: Statuses whose samples are not averaged: holding (a stuck or implausible signal among the
#: reasons), the signal lost, the supervisor's internal failure.
_UNTRUSTED = {"hold", "safe", "error"}

_MODE_NAMES = {code: name for name, code in MILLING_MODES.items()}


def section_record(plan: Any, section: int, verdict: str, tool: str, override: float = 1.0,
                   force_mean_n: np.ndarray | None = None, force_frame: str = "base",
                   chatter_hz: float | None = None, duration_s: float | None = None,
                   detector: str | None = None, log: str | None = None) -> CutRecord | None:
    """The record of plan section ``section`` (index from 0) as it ran; None for air and rapid
    sections and sections without an engagement.

    Args:
        plan: the :class:`planner.plan_file.Plan` the supervisor runs.
        section: the section's index in ``plan.sections``.
        verdict: the detector's: ``stable``, ``chatter`` or ``unknown`` (no reliable signal).
        tool: the tool data name the plan was cut with (the plan carries diameter and flutes).
        override: the override the controller *applied* [-] (0..1]: the feed is the plan's × it.
        force_mean_n: the mean force on the tool over the section [N], (3,), in ``force_frame``
            (``base``: robot base axes; ``cut``: X_o, Y_o, Z_o), or None.
        chatter_hz: the chatter frequency the detector saw [Hz], or None.
        duration_s: how long the section ran [s]; detector, log: for the record's source.
    """
    sec = plan.sections[section]
    if sec.kind != "cut":
        return None
    smp = plan.samples
    lo, hi = sec.sample_start, sec.sample_stop
    mid = (lo + hi - 1) // 2
    a_p, a_e, mode = float(smp.a_p[mid]), float(smp.a_e[mid]), int(round(float(smp.mode[mid])))
    if not (np.isfinite(a_p) and a_p > 0 and mode in _MODE_NAMES):
        return None
    from robot_io.krl.frames import abc_to_matrix

    base = abc_to_matrix(*np.degrees(plan.base_abc))
    i0, i1 = max(lo, mid - 1), min(hi - 1, mid + 1)
    tangent = base @ (smp.position_wp[i1] - smp.position_wp[i0])
    if i1 == i0 or not np.linalg.norm(tangent) > 0:
        return None
    a = base @ np.asarray(smp.tool_axis_wp[mid], float)
    feed_dir = tangent - (tangent @ a) * a
    feed_dir /= np.linalg.norm(feed_dir)
    radial = np.cross(a, feed_dir)   # X_o = Y_o × Z_o with Y_o the tool axis (tip → spindle)
    radial /= np.linalg.norm(radial)
    name = _MODE_NAMES[mode]
    source: dict[str, Any] = {"kind": "supervisor", "section": sec.index + 1}
    if plan.path is not None:
        source["plan"] = str(plan.path)
    if detector:
        source["detector"] = detector
    if log:
        source["log"] = log
    return CutRecord(
        joints_deg=tuple(round(float(v), 4) for v in np.degrees(smp.q[mid])),
        feed_dir=tuple(round(float(v), 6) for v in feed_dir),
        radial_dir=tuple(round(float(v), 6) for v in radial),
        ap_mm=round(a_p * 1e3, 4), ae_mm=None if name == "slot" else round(a_e * 1e3, 4),
        rpm=float(plan.spindle_rpm), feed_mm_s=round(sec.feed * override * 1e3, 4),
        milling=name, tool=tool, material=plan.material,
        diameter_mm=None if plan.tool_diameter is None else round(plan.tool_diameter * 1e3, 4),
        flutes=plan.flutes, verdict=verdict, frame=force_frame,
        force_n=None if force_mean_n is None else tuple(round(float(v), 3) for v in force_mean_n),
        chatter_hz=chatter_hz, duration_s=duration_s, id=f"S{sec.index + 1:03d}", source=source)


def append_record(path: str | os.PathLike, record: CutRecord, sync: bool = True) -> None:
    """Append one record as a line to ``path`` (made if missing), flushed (and with ``sync``
    fsynced) to disk."""
    p = Path(path)
    with open(p, "a", encoding="utf-8") as fh:
        fh.write(dumps_record(record) + "\n")
        fh.flush()
        if sync:
            os.fsync(fh.fileno())


def chatter_frequency_of(values: Any, fs_hz: float, band_hz: tuple[float, float],
                         tooth_hz: float | None = None) -> float | None:
    """The chatter frequency in a stretch of signal [Hz]: the peak of its Hann-windowed spectrum
    (mean and linear trend removed: a feed ramp is no line) in ``band_hz`` widened by
    :data:`BAND_SLACK_OCTAVES`, the tooth harmonics k·``tooth_hz`` ± the window's main lobe left
    out, refined by a parabola through the log magnitudes of the peak bin and its neighbours.

    Args:
        values: the samples, shape (n,), at ``fs_hz`` [Hz].
        band_hz: the detector's band (lo, hi) [Hz].
        tooth_hz: the tooth-passing frequency [Hz], or None.

    Returns:
        The frequency [Hz], or None: the stretch holds fewer than :data:`MIN_CHATTER_PERIODS`
        periods of the band's lowest frequency, or the band is empty.
    """
    y = np.asarray(values, float)
    n = y.size
    lo = band_hz[0] * 2.0**-BAND_SLACK_OCTAVES
    hi = min(band_hz[1] * 2.0**BAND_SLACK_OCTAVES, 0.5 * fs_hz)
    if not (fs_hz > 0 and 0 < lo < hi and n / fs_hz * lo >= MIN_CHATTER_PERIODS
            and np.all(np.isfinite(y))):
        return None
    x = np.arange(n) - 0.5 * (n - 1)
    y = y - y.mean() - x * (x @ y) / (x @ x)
    nfft = 2 << max(0, (n - 1).bit_length())       # ≥ 2n: bins half the resolution apart
    mag = np.abs(np.fft.rfft(y * np.hanning(n), nfft))
    f = np.fft.rfftfreq(nfft, 1.0 / fs_hz)
    keep = (f >= lo) & (f <= hi)
    if tooth_hz and tooth_hz > 0:
        lobe = 2.0 * fs_hz / n                     # the Hann window's main-lobe half width [Hz]
        for k in range(1, int((hi + lobe) / tooth_hz) + 1):
            keep &= np.abs(f - k * tooth_hz) > lobe
    if not keep.any() or not mag[keep].max() > 0:
        return None
    i = int(np.flatnonzero(keep)[np.argmax(mag[keep])])
    peak = f[i]
    if 0 < i < mag.size - 1:
        a, b, c = np.log(np.maximum(mag[i - 1:i + 2], 1e-300))
        den = a - 2.0 * b + c
        if den < 0:
            peak += 0.5 * (a - c) / den * (f[1] - f[0])
    return float(peak)


def model_force_direction(plan: Any) -> Callable[[CutRecord], np.ndarray | None]:
    """The nominal model's mean force direction in a record's cut frame (docs/model.md §4: the
    plan's material coefficients, the record's engagement, feed per tooth and tool): a callable
    record → unit (3,), or None when the record lacks the tool's diameter or flutes.

    It turns the simulated cut's resultant (the only signal whose samples are |F|) into the
    3-axis mean force of a simulated sensor: a simulated run's records carry the simulated
    magnitude along the model's direction.
    """
    from models import cutting

    coefficients = plan.model_coefficients()   # a calibrated plan's, else the material file's

    def direction(rec: CutRecord) -> np.ndarray | None:
        if not rec.flutes or not rec.diameter_mm:
            return None
        radius = rec.diameter_mm * 5e-4
        a_e = 2.0 * radius if rec.milling == "slot" else rec.ae_mm * 1e-3
        c = cutting.feed_per_tooth(rec.feed(), rec.flutes, rec.rpm)
        f = np.asarray(cutting.average_force(c, a_e, rec.ap_mm * 1e-3, rec.milling, rec.flutes,
                                             radius, coefficients), float).reshape(3)
        size = float(np.linalg.norm(f))
        return f / size if math.isfinite(size) and size > 0 else None

    return direction


class _Tap:
    """The signal source the loop reads, handing every chunk on to a recorder
    (:meth:`SectionRecorder.tap`); everything else is the source's."""

    def __init__(self, source: Any, recorder: SectionRecorder) -> None:
        self._source, self._recorder = source, recorder

    def read(self, max_samples: int) -> Any:
        chunk = self._source.read(max_samples)
        self._recorder.samples(chunk)
        return chunk

    def close(self) -> None:
        self._source.close()

    def __getattr__(self, name: str) -> Any:   # fs_hz, stats, duration_s, ...
        if name.startswith("_"):
            raise AttributeError(name)
        return getattr(self._source, name)


class SectionRecorder:
    """An ``on_cycle`` hook of the supervisor loop that appends one record per cut section it ran.

    Per section it counts the steps, the alarms and the blind steps, and averages the override the
    controller applied; when the section changes it appends the finished section's record
    (:func:`section_record`): ``chatter`` if any step alarmed, ``unknown`` if the detector was
    blind for more than :data:`BLIND_SHARE_MAX` of it, else ``stable``. With the signal
    (:meth:`tap`, ``fs_hz``) the record also holds the mean force over the section's steady part
    and, for ``chatter``, the chatter frequency (the module docstring says how). Call
    :meth:`close` after the loop for the last section. It never raises into the loop: a failure
    is counted in :attr:`errors` (the last one in :attr:`last_error`).

    Args:
        plan: the plan the supervisor runs; path: the records file; tool: the tool data name.
        detector: named in the records' source; log: the event log, named likewise.
        fs_hz: the signal's sample rate [Hz] (None: the signal is not looked at).
        signal: what the samples are, one of :data:`SIGNALS`.
        band_hz: the detector's band (lo, hi) [Hz], where the chatter frequency is searched
            (None: no chatter frequency).
        direction: for ``signal="resultant"``, record → unit mean force direction in its cut
            frame (None: :func:`model_force_direction` of the plan).
    """

    def __init__(self, plan: Any, path: str | os.PathLike, tool: str, detector: str | None = None,
                 log: str | None = None, fs_hz: float | None = None, signal: str = "scalar",
                 band_hz: tuple[float, float] | None = None,
                 direction: Callable[[CutRecord], np.ndarray | None] | None = None) -> None:
        if signal not in SIGNALS:
            from models.errors import InputError

            raise InputError("signal", f"{signal!r}: use one of {', '.join(SIGNALS)}")
        self.plan, self.path, self.tool = plan, Path(path), tool
        self.detector, self.log = detector, log
        self.fs_hz = float(fs_hz) if fs_hz and math.isfinite(fs_hz) and fs_hz > 0 else None
        self.signal = signal
        self.band_hz = None if band_hz is None else (float(band_hz[0]), float(band_hz[1]))
        self._width = 3 if signal.startswith("force_") else 1
        #: records written; of them with a mean force, with a chatter frequency
        self.written = self.with_force = self.with_chatter_hz = 0
        self.errors = 0
        self.last_error: str | None = None
        if signal == "resultant" and direction is None:
            try:
                direction = model_force_direction(plan)
            except Exception as e:  # noqa: BLE001 - an unknown material: records without force
                self.last_error = f"no model force direction: {e!r}"
        self._direction = direction
        # section_record's import, made here rather than at the first section's end inside the
        # loop (~40 ms: ten 4 ms cycles)
        import robot_io.krl.frames  # noqa: F401
        self._pending: list[tuple[np.ndarray, np.ndarray]] = []
        self._reset(None, 0.0)

    def tap(self, source: Any) -> Any:
        """``source`` as the loop should read it: every chunk read also reaches this recorder."""
        return _Tap(source, self)

    def _tooth_frequency(self, section: int | None) -> float | None:
        """f_t of a plan section [Hz]: its own, else spindle speed × flutes / 60; None: unknown."""
        if section is None or not 0 <= section < len(self.plan.sections):
            return None
        f = getattr(self.plan.sections[section], "tooth_frequency", None)
        if not f:
            rpm, flutes = getattr(self.plan, "spindle_rpm", None), getattr(self.plan, "flutes", None)
            f = rpm * flutes / 60.0 if rpm and flutes else None
        return float(f) if f and math.isfinite(f) and f > 0 else None

    def _reset(self, section: int | None, now: float) -> None:
        self._section, self._t0 = section, now
        self._steps = self._alarms = self._blind = 0
        self._override_sum = 0.0
        self._tooth_hz = self._tooth_frequency(section)
        self._t_first: float | None = None
        self._t_last = -math.inf
        # per tooth period k (from the section's first sample): samples, their sums, Σ override
        self._n = np.zeros(0)
        self._sum = np.zeros((0, self._width))
        self._ov = np.zeros(0)
        self._ring: collections.deque[np.ndarray] = collections.deque()
        self._ring_n = 0
        self._peak = -math.inf
        self._window: np.ndarray | None = None

    def samples(self, chunk: Any) -> None:
        """A chunk the supervisor reads (the loop reads it before the step): its samples go to
        the section of the next :meth:`__call__`. Never raises."""
        try:
            if self.fs_hz is not None and len(chunk):
                self._pending.append((np.asarray(chunk.t_s, float),
                                      np.asarray(chunk.values, float)))
        except Exception as e:  # noqa: BLE001 - the loop goes on; the failure is counted
            self.errors += 1
            self.last_error = repr(e)

    def __call__(self, now: float, res: Any, applied: float | None, link: Any = None) -> None:
        try:
            pending, self._pending = self._pending, []
            if res.section != self._section:
                self._emit(now)
                self._reset(res.section, now)
            self._steps += 1
            self._alarms += bool(res.alarm)
            self._blind += str(res.status) in _BLIND
            override = (res.override if applied is None else applied) / 100.0
            self._override_sum += override
            if str(res.status) not in _UNTRUSTED:
                for t, v in pending:
                    self._take(t, v, override)
            if res.alarm and self._ring and res.band is not None and res.band >= self._peak:
                self._peak = float(res.band)
                self._window = np.concatenate(self._ring)
        except Exception as e:  # noqa: BLE001 - the loop goes on; the failure is counted
            self.errors += 1
            self.last_error = repr(e)

    def _take(self, t: np.ndarray, v: np.ndarray, override: float) -> None:
        """Add samples (t [s], (n,); values (n,) or (n, 3)) at an applied override [-]."""
        v = v.reshape(t.size, -1)
        if v.shape[1] != self._width:
            raise ValueError(f"signal {self.signal!r} needs {self._width} value(s) a sample, "
                             f"got {v.shape[1]}")
        good = np.isfinite(t) & np.all(np.isfinite(v), axis=1)
        if self._t_first is not None:
            good &= t > self._t_last          # a restarted clock: not this section's time line
        t, v = t[good], v[good]
        if not t.size:
            return
        if self._t_first is None:
            self._t_first = float(t[0])
        self._t_last = float(t[-1])
        y = v[:, 0] if self._width == 1 else np.linalg.norm(v, axis=1)
        self._ring.append(y)
        self._ring_n += y.size
        while self._ring and self._ring_n - self._ring[0].size >= CHATTER_WINDOW_S * self.fs_hz:
            self._ring_n -= self._ring.popleft().size
        if self.signal == "scalar" or self._tooth_hz is None:
            return                             # no mean force to take
        k = np.floor((t - self._t_first) * self._tooth_hz).astype(np.int64)
        lo, hi = int(k[0]), int(k[-1]) + 1
        if hi > self._n.size:
            grow = max(hi, 2 * self._n.size, 256) - self._n.size
            self._n = np.concatenate([self._n, np.zeros(grow)])
            self._sum = np.vstack([self._sum, np.zeros((grow, self._width))])
            self._ov = np.concatenate([self._ov, np.zeros(grow)])
        idx = k - lo
        count = np.bincount(idx, minlength=hi - lo)
        self._n[lo:hi] += count
        self._ov[lo:hi] += count * override
        for j in range(self._width):
            self._sum[lo:hi, j] += np.bincount(idx, weights=v[:, j], minlength=hi - lo)

    def _steady(self) -> tuple[np.ndarray, float, int] | None:
        """(mean value (width,), mean override [-], tooth periods) over the section's steady
        part, or None: too few whole periods (see the module docstring)."""
        ft = self._tooth_hz
        if ft is None or self._t_first is None or self.fs_hz is None or not self._n.size:
            return None
        settle = max(SETTLE_S, SETTLE_PERIODS / ft)
        start = self._t_first + np.arange(self._n.size) / ft
        tiny = 1e-9 / ft
        sel = ((self._n >= self.fs_hz / ft - 1.0) & (start >= self._t_first + settle - tiny)
               & (start + 1.0 / ft <= self._t_last - settle + tiny))
        periods = int(np.count_nonzero(sel))
        if periods < MIN_STEADY_PERIODS:
            return None
        count = float(self._n[sel].sum())
        return self._sum[sel].sum(axis=0) / count, float(self._ov[sel].sum()) / count, periods

    def _with_force(self, rec: CutRecord, mean: np.ndarray, periods: int) -> CutRecord:
        """The record with the steady mean force, in its cut frame."""
        if self.signal == "resultant":
            u = self._direction(rec) if self._direction is not None else None
            if u is None:
                return rec
            force, how = float(mean[0]) * np.asarray(u, float), "simulated resultant, model direction"
        elif self.signal == "force_base":
            force, how = rec.cut_axes().T @ mean, "3-axis signal, base axes"
        else:
            force, how = np.asarray(mean, float), "3-axis signal, cut frame"
        if not (np.all(np.isfinite(force)) and np.linalg.norm(force) > 0):
            return rec
        return dataclasses.replace(rec, force_n=tuple(round(float(v), 3) for v in force),
                                   frame="cut",
                                   source={**rec.source, "force": how, "force_periods": periods})

    def _emit(self, now: float) -> None:
        if self._section is None or self._section < 0 or self._steps == 0:
            return
        verdict = ("chatter" if self._alarms else "unknown"
                   if self._blind > BLIND_SHARE_MAX * self._steps else "stable")
        steady = self._steady() if self.signal != "scalar" else None
        chatter_hz = None
        if verdict == "chatter" and self._window is not None and self.band_hz is not None:
            f = chatter_frequency_of(self._window, self.fs_hz, self.band_hz, self._tooth_hz)
            chatter_hz = round(f, 2) if f is not None else None
        rec = section_record(self.plan, self._section, verdict, self.tool,
                             override=(self._override_sum / self._steps if steady is None
                                       else steady[1]),
                             chatter_hz=chatter_hz, duration_s=max(now - self._t0, 1e-3),
                             detector=self.detector, log=self.log)
        if rec is not None and steady is not None:
            rec = self._with_force(rec, steady[0], steady[2])
        if rec is not None:
            append_record(self.path, rec, sync=False)
            self.written += 1
            self.with_force += rec.force_n is not None
            self.with_chatter_hz += rec.chatter_hz is not None

    def close(self, now: float) -> None:
        """Append the last section's record (and fsync the file)."""
        try:
            self._emit(now)
            self._reset(None, now)
            if self.path.exists():
                with open(self.path, "a", encoding="utf-8") as fh:
                    os.fsync(fh.fileno())
        except Exception as e:  # noqa: BLE001
            self.errors += 1
            self.last_error = repr(e)


def chain_on_cycle(*hooks: Any) -> Any:
    """One ``on_cycle`` hook that calls each given hook in order (None entries skipped; None when
    none is left), so the recorder runs beside the online compensation."""
    live = [h for h in hooks if h is not None]
    if not live:
        return None
    if len(live) == 1:
        return live[0]

    def both(now: float, res: Any, applied: float | None, link: Any) -> None:
        for hook in live:
            hook(now, res, applied, link)

    return both
