"""The programmed feed as the user's intent: caps on the feed ceilings, feeds of the moves that do
not cut (docs/model.md §8).

The CAM program's F word is what its author asked for. By default the planner only *slows down*
where the process needs it, as an adaptive-feed controller does: no cut sample's ceiling exceeds
its programmed feed × ``[limits] cam_feed_scale_max`` (1.0 by default; a larger factor lets the
planner raise feeds up to ``feed_max_mm_s`` where the process allows). The binding label of a
sample held there is ``cam_feed``.

Moves that do not cut run as programmed: an air move (feed move in cleared space, or a plunge,
which the process model does not cover) at its programmed feed, capped by the rapid speed; a move
without a programmed feed at the lower of ``feed_max`` and the rapid speed; rapids at the rapid
speed. An air run whose moves are programmed at different feeds is split where the feed changes,
so a plunge's feed holds over the plunge only, not over the lateral moves after it.
"""

from __future__ import annotations

import numpy as np

from models.errors import InputError
from planner.ceilings import Ceilings
from planner.limits import Limits
from planner.path import PathSamples
from planner.sections import AIR, RAPID, Section

__all__ = [
    "CAM_FEED",
    "RAPID_BINDING",
    "apply_cam_feed",
    "cam_feed_caps",
    "check_rapid_above_feed",
    "non_cut_sections",
]

#: The binding label of a feed held at the programmed feed (× the allowed factor).
CAM_FEED = "cam_feed"
#: The binding label of a rapid move (the rapid speed).
RAPID_BINDING = "rapid"


def cam_feed_caps(path: PathSamples, index: np.ndarray, limits: Limits) -> np.ndarray:
    """Per engaged sample, the programmed feed × ``cam_feed_scale_max`` [m/s], shape (m,);
    ``inf`` where the program gives no feed (inverse-time moves).

    Raises:
        InputError: a cutting move is programmed below ``feed_min_mm_s`` (the plan would have
            to run it faster than its author asked); names the file and line.
    """
    prog = path.feed[index]
    caps = np.where(np.isfinite(prog), prog * limits.cam_feed_scale_max, np.inf)
    low = np.flatnonzero(caps < limits.feed_min * (1.0 - 1e-12))
    if low.size:
        k = int(index[low[0]])
        raise InputError("limits.feed_min_mm_s", (
            f"{path.where(k)} is programmed at {prog[low[0]] * 6e4:.1f} mm/min "
            f"({prog[low[0]] * 1e3:.3f} mm/s), below feed_min_mm_s {limits.feed_min * 1e3:g} "
            f"({low.size} cut samples): lower [limits] feed_min_mm_s, or raise "
            "cam_feed_scale_max"))
    return caps


def apply_cam_feed(ceil: Ceilings, caps: np.ndarray, label: str = CAM_FEED) -> Ceilings:
    """The ceilings with caps [m/s] (m,) applied: ``binding = label`` where the cap is the lower
    (the programmed-feed caps by default; ``planner.tool_limits`` passes the tool's)."""
    held = caps < ceil.feed
    feed = np.where(held, caps, ceil.feed)
    binding = np.where(held, label, ceil.binding).astype(str)
    return Ceilings(feed=feed, binding=binding, floor_violation=ceil.floor_violation,
                    evaluations=ceil.evaluations)


def _air_feed(prog: float, limits: Limits) -> tuple[float, str, str]:
    """(feed [m/s], binding, note) of an air stretch programmed at ``prog`` (NaN: none)."""
    ceiling = limits.rapid_speed
    if not np.isfinite(prog):
        f = min(limits.feed_max, ceiling)
        return f, "feed_max" if f == limits.feed_max else RAPID_BINDING, \
            "not engaged, no programmed feed: feed_max"
    if prog > ceiling:
        return ceiling, RAPID_BINDING, "not engaged: programmed feed above the rapid speed"
    return float(prog), CAM_FEED, "not engaged: programmed feed"


def non_cut_sections(runs: list[tuple[int, int, int]], path: PathSamples,
                     plunge: np.ndarray | None, limits: Limits) -> list[Section]:
    """The sections of the rapid and air runs (module docstring)."""
    out: list[Section] = []
    prog = path.feed
    ds = np.diff(path.s, prepend=path.s[0])
    for a, b, kind in runs:
        if kind == RAPID:
            out.append(Section(a, b, RAPID, limits.rapid_speed, RAPID_BINDING, "rapid move"))
            continue
        if kind != AIR:
            continue
        # split where the programmed feed (or plunge/not) changes; NaN == NaN here
        key = np.where(np.isfinite(prog[a:b]), prog[a:b], -1.0)
        pl = (plunge[a:b] if plunge is not None else np.zeros(b - a, bool)).copy()
        # a sample that adds no path (sample 0, a zero-length move) opens no section of its own
        for i in np.flatnonzero(ds[a:b] <= 0.0):
            if i > 0:
                key[i], pl[i] = key[i - 1], pl[i - 1]
            elif b - a > 1:
                key[0], pl[0] = key[1], pl[1]
        cuts = np.flatnonzero((key[1:] != key[:-1]) | (pl[1:] != pl[:-1])) + 1
        edges = [0, *cuts.tolist(), b - a]
        for i0, i1 in zip(edges[:-1], edges[1:], strict=True):
            f, binding, note = _air_feed(float(key[i0]) if key[i0] >= 0 else np.nan, limits)
            if pl[i0]:
                note = "plunge (not modelled): programmed feed"
            out.append(Section(a + i0, a + i1, AIR, f, binding, note))
    return out


def check_rapid_above_feed(limits: Limits) -> None:
    """Raise when ``feed_max`` exceeds the rapid speed (most often mm/min typed into a mm/s key)."""
    if limits.feed_max > limits.rapid_speed:
        raise InputError("limits.feed_max_mm_s", (
            f"{limits.feed_max * 1e3:g} mm/s is above rapid_mm_s {limits.rapid_speed * 1e3:g}: "
            f"the keys are in mm/s ({limits.feed_max * 1e3:g} mm/min would be "
            f"{limits.feed_max * 1e3 / 60:g} mm/s)"))
