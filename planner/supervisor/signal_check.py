"""Is a chunk of signal samples fit to judge chatter on? (the supervisor's first check a step).

A chunk is refused — dropped, counted, and the step holds the override — when it is not two
1-D arrays of numbers of one shape, holds a non-finite sample or one beyond the plausible range
(a broken sensor or a unit slip), is a stuck sensor's run of identical values, or its stamps do
not increase, within the chunk or after the previous chunk's (stamps more than
:data:`~planner.supervisor.step.RESTART_BACK_S` before those are a restarted source, accepted).
"""

from __future__ import annotations

import numpy as np

from planner.supervisor.step import RESTART_BACK_S
from robot_io.signals.base import SignalChunk

__all__ = ["chunk_problem"]


def chunk_problem(chunk: SignalChunk, plausible_max: float, stuck_samples: int,
                  last_t: float | None) -> str:
    """Why the chunk cannot be used, in words, or ``""`` if it can.

    Args:
        chunk: the samples (times [s] and values, the signal's unit).
        plausible_max: largest plausible |sample| (the signal's unit).
        stuck_samples: a chunk of at least this many identical samples is a stuck sensor.
        last_t: the last time stamp of the previous chunk used [s], or None.
    """
    t, v = chunk.t_s, chunk.values
    if not (isinstance(t, np.ndarray) and isinstance(v, np.ndarray)):
        return "chunk without sample arrays"
    if t.shape != v.shape or t.ndim != 1:
        return "chunk arrays of different shapes"
    if not (np.issubdtype(t.dtype, np.number) and np.issubdtype(v.dtype, np.number)):
        return f"samples of type {v.dtype}, not numbers"
    if not (np.all(np.isfinite(v)) and np.all(np.isfinite(t))):
        return "non-finite samples"
    if np.max(np.abs(v)) > plausible_max:
        return f"|sample| {np.max(np.abs(v)):.4g} over the plausible {plausible_max:.4g}"
    if v.size >= stuck_samples and np.all(v == v[0]):
        return f"{v.size} identical samples (stuck sensor)"
    if v.size > 1 and not np.all(np.diff(t) > 0):
        return "time stamps not increasing"
    if last_t is not None and last_t - RESTART_BACK_S <= t[0] <= last_t:
        return "time stamps before the previous chunk's"
    return ""
