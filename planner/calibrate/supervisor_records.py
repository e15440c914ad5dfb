"""The record of a section the supervisor ran: what ``cctmill supervise`` appends to its records file.

The supervisor knows the plan (pose, cut and feed of every section), the override the controller
applied, its detector's verdict and, from the signal, the mean force and the chatter frequency;
:func:`section_record` turns them into a :class:`~planner.calibrate.records.CutRecord` (the pose
and cut of the section's middle sample; the cut frame from the path's tangent and the tool axis)
and :func:`append_record` adds it to a JSON Lines file, one line per section, flushed, so a crash
keeps the records already written.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from models.cutting import MILLING_MODES
from planner.calibrate.records import CutRecord, dumps_record

__all__ = ["SectionRecorder", "append_record", "chain_on_cycle", "section_record"]

#: Step statuses during which the detector cannot judge the cut (signal missing, filters settling).
_BLIND = {"learning", "warmup", "hold", "safe", "error"}
#: A section is ``unknown`` when the detector was blind for more than this share of its steps [-].
BLIND_SHARE_MAX = 0.5

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


class SectionRecorder:
    """An ``on_cycle`` hook of the supervisor loop that appends one record per cut section it ran.

    Per section it counts the steps, the alarms and the blind steps, and averages the override the
    controller applied; when the section changes it appends the finished section's record
    (:func:`section_record`): ``chatter`` if any step alarmed, ``unknown`` if the detector was
    blind for more than :data:`BLIND_SHARE_MAX` of it, else ``stable``. Call :meth:`close` after
    the loop for the last section. It never raises into the loop: a failure is counted in
    :attr:`errors` (the last one in :attr:`last_error`).

    Args:
        plan: the plan the supervisor runs; path: the records file; tool: the tool data name.
        detector: named in the records' source; log: the event log, named likewise.
    """

    def __init__(self, plan: Any, path: str | os.PathLike, tool: str, detector: str | None = None,
                 log: str | None = None) -> None:
        self.plan, self.path, self.tool = plan, Path(path), tool
        self.detector, self.log = detector, log
        self.written = 0
        self.errors = 0
        self.last_error: str | None = None
        self._reset(None, 0.0)

    def _reset(self, section: int | None, now: float) -> None:
        self._section, self._t0 = section, now
        self._steps = self._alarms = self._blind = 0
        self._override_sum = 0.0

    def __call__(self, now: float, res: Any, applied: float | None, link: Any = None) -> None:
        try:
            if res.section != self._section:
                self._emit(now)
                self._reset(res.section, now)
            self._steps += 1
            self._alarms += bool(res.alarm)
            self._blind += str(res.status) in _BLIND
            self._override_sum += (res.override if applied is None else applied) / 100.0
        except Exception as e:  # noqa: BLE001 - the loop goes on; the failure is counted
            self.errors += 1
            self.last_error = repr(e)

    def _emit(self, now: float) -> None:
        if self._section is None or self._section < 0 or self._steps == 0:
            return
        verdict = ("chatter" if self._alarms else "unknown"
                   if self._blind > BLIND_SHARE_MAX * self._steps else "stable")
        rec = section_record(self.plan, self._section, verdict, self.tool,
                             override=self._override_sum / self._steps,
                             duration_s=max(now - self._t0, 1e-3), detector=self.detector,
                             log=self.log)
        if rec is not None:
            append_record(self.path, rec, sync=False)
            self.written += 1

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
