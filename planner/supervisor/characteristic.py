"""What a plan section's stability characteristic says at run time (read by the supervisor and the
simulated cut).

A cut section of the plan carries its stability characteristic at its tightest sample
(:class:`planner.plan_file.SectionCharacteristic`: feeds [m/s], margin [N/m], force [N]). From it:

- :func:`margin_at`, :func:`force_at`: linear interpolation in feed (clamped at the ends);
- :func:`stabilising_direction`: the sign of d margin / d feed at the current feed, by central
  difference over the characteristic's grid. When the relative slope
  |d margin / d feed| · f / max|margin| is below :data:`FLAT_MARGIN_REL` the characteristic offers
  no stabilising direction (docs/model.md §9: with the ``oriented`` process model the feed hardly changes
  stability) and the answer is 0;
- :func:`feed_limit_for_force`: the largest feed whose interpolated force stays under a limit;
- :func:`chatter_frequency`: the expected chatter frequency of the section (mode coupling: the
  two modes coalesce between the natural frequencies f1 and f2, so √(f1 f2)).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from planner.plan_file import PlanSection

__all__ = [
    "FLAT_MARGIN_REL",
    "Characteristic",
    "characteristic_of",
    "chatter_frequency",
    "feed_limit_for_force",
    "force_at",
    "margin_at",
    "stabilising_direction",
]

#: Relative margin slope |dm/df| · f / max|m| under which feed is taken to have no effect on
#: stability (a 10 % feed change moving the margin by less than 0.5 % of its scale).
FLAT_MARGIN_REL = 0.05
#: A feed below this [m/s] is taken as this for the relative slope (no division by a zero feed).
_FEED_TINY = 1e-15


class Characteristic:
    """A section's characteristic as arrays, SI.

    Attributes:
        feeds: feeds [m/s], shape (k,), increasing.
        margin: chatter margin [N/m], (k,); force: resultant average force [N], (k,).
        margin_scale: the largest |margin| [N/m] (1 when there is none), the scale of "flat".
    """

    def __init__(self, feeds: Any, margin: Any, force: Any) -> None:
        f = np.asarray(feeds, dtype=float)
        order = np.argsort(f)
        self.feeds = f[order]
        self.margin = np.asarray(margin, dtype=float)[order]
        self.force = np.asarray(force, dtype=float)[order]
        if not (self.feeds.size >= 2 and self.margin.shape == self.feeds.shape
                and self.force.shape == self.feeds.shape):
            raise ValueError("characteristic needs >= 2 feeds with one margin and force each")
        scale = np.nanmax(np.abs(self.margin))
        self.margin_scale = float(scale) if np.isfinite(scale) and scale > 0 else 1.0


def characteristic_of(section: PlanSection) -> Characteristic | None:
    """The characteristic of a plan section, or None (air/rapid sections, or none or malformed)."""
    ch = section.characteristic
    if section.kind != "cut" or ch is None:
        return None
    try:
        return Characteristic(ch.feeds, ch.margin, ch.force)
    except (TypeError, ValueError):
        return None


def margin_at(ch: Characteristic, feed: float) -> float:
    """Stability margin [N/m] at a feed [m/s]."""
    return float(np.interp(feed, ch.feeds, ch.margin))


def force_at(ch: Characteristic, feed: float) -> float:
    """Resultant cutting force [N] at a feed [m/s]."""
    return float(np.interp(feed, ch.feeds, ch.force))


def stabilising_direction(ch: Characteristic, feed: float) -> tuple[int, float]:
    """(direction, relative slope) at a feed [m/s]: −1 lower the feed, +1 raise it, 0 no
    stabilising direction."""
    f = ch.feeds
    span = 0.5 * float(np.min(np.diff(f))) if f.size > 1 else 1.0
    lo = max(f[0], feed - span)
    hi = min(f[-1], feed + span)
    if hi <= lo:
        lo, hi = f[0], f[1]
    slope = (margin_at(ch, hi) - margin_at(ch, lo)) / (hi - lo)
    rel = slope * max(feed, _FEED_TINY) / ch.margin_scale
    if not math.isfinite(rel) or abs(rel) < FLAT_MARGIN_REL:
        return 0, rel if math.isfinite(rel) else 0.0
    return (1 if slope > 0 else -1), rel


def feed_limit_for_force(ch: Characteristic, force_max: float) -> float:
    """Largest feed [m/s] with interpolated force ≤ ``force_max`` [N] (∞ if the whole range is
    under; the lowest feed of the grid if even that is over)."""
    F = ch.force
    f = ch.feeds
    over = np.flatnonzero(F > force_max)
    if over.size == 0:
        return math.inf
    k = int(over[0])
    if k == 0:
        return float(f[0])
    # linear inverse interpolation on the segment that crosses the limit
    F0, F1 = F[k - 1], F[k]
    return float(f[k - 1] + (force_max - F0) / (F1 - F0) * (f[k] - f[k - 1]))


def chatter_frequency(section: PlanSection, default_hz: float) -> float:
    """Expected chatter frequency [Hz]: √(f1 f2) of the section's natural frequencies, else the
    default (the thesis measured ≈ 11 Hz on its KR210)."""
    if section.natural_frequencies is None:
        return default_hz
    f1, f2 = section.natural_frequencies
    if f1 > 0 and f2 > 0 and math.isfinite(f1 * f2):
        return math.sqrt(f1 * f2)
    return default_hz
