"""What a plan section's stability characteristic says at run time (read by the supervisor and the
simulated cut).

A cut section of ``plan.json`` carries ``characteristic {feeds_mm_s, margin_N_per_m, gamma_deg,
force_N, stable}`` at its tightest sample (see :mod:`planner.plan_file`). From it:

- :func:`margin_at`, :func:`force_at`: linear interpolation in feed (clamped at the ends);
- :func:`stabilising_direction`: the sign of d margin / d feed at the current feed, by central
  difference over the characteristic's grid. When the relative slope
  |d margin / d feed| · f / max|margin| is below :data:`FLAT_MARGIN_REL` the characteristic offers
  no stabilising direction (SPEC §9: with the ``oriented`` process model the feed hardly changes
  stability) and the answer is 0;
- :func:`feed_limit_for_force`: the largest feed whose interpolated force stays under a limit;
- :func:`chatter_frequency`: the expected chatter frequency of the section (mode coupling: the
  two modes coalesce between the natural frequencies f1 and f2, so √(f1 f2)).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

__all__ = [
    "FLAT_MARGIN_REL",
    "Characteristic",
    "chatter_frequency",
    "characteristic_of",
    "feed_limit_for_force",
    "force_at",
    "margin_at",
    "stabilising_direction",
]

#: Relative margin slope |dm/df| · f / max|m| under which feed is taken to have no effect on
#: stability (a 10 % feed change moving the margin by less than 0.5 % of its scale).
FLAT_MARGIN_REL = 0.05


class Characteristic:
    """A section's characteristic as arrays (feeds in mm/s as in the file; margin N/m; force N).

    Attributes:
        feeds_mm_s, margin_N_per_m, force_N: shape (k,), feeds increasing.
    """

    def __init__(self, feeds_mm_s: Any, margin_N_per_m: Any, force_N: Any) -> None:
        f = np.asarray(feeds_mm_s, dtype=float)
        order = np.argsort(f)
        self.feeds_mm_s = f[order]
        self.margin_N_per_m = np.asarray(margin_N_per_m, dtype=float)[order]
        self.force_N = np.asarray(force_N, dtype=float)[order]
        if not (self.feeds_mm_s.size >= 2 and self.margin_N_per_m.shape == self.feeds_mm_s.shape
                and self.force_N.shape == self.feeds_mm_s.shape):
            raise ValueError("characteristic needs >= 2 feeds with one margin and force each")
        scale = np.nanmax(np.abs(self.margin_N_per_m))
        self.margin_scale = float(scale) if np.isfinite(scale) and scale > 0 else 1.0


def characteristic_of(section: dict[str, Any]) -> Characteristic | None:
    """The characteristic of a plan section, or None (air/rapid sections, or missing/malformed)."""
    ch = section.get("characteristic")
    if not isinstance(ch, dict):
        return None
    try:
        return Characteristic(ch["feeds_mm_s"], ch["margin_N_per_m"], ch["force_N"])
    except (KeyError, TypeError, ValueError):
        return None


def margin_at(ch: Characteristic, feed_mm_s: float) -> float:
    """Stability margin [N/m] at a feed [mm/s]."""
    return float(np.interp(feed_mm_s, ch.feeds_mm_s, ch.margin_N_per_m))


def force_at(ch: Characteristic, feed_mm_s: float) -> float:
    """Resultant cutting force [N] at a feed [mm/s]."""
    return float(np.interp(feed_mm_s, ch.feeds_mm_s, ch.force_N))


def stabilising_direction(ch: Characteristic, feed_mm_s: float) -> tuple[int, float]:
    """(direction, relative slope): −1 lower the feed, +1 raise it, 0 no stabilising direction."""
    f = ch.feeds_mm_s
    span = 0.5 * float(np.min(np.diff(f))) if f.size > 1 else 1.0
    lo = max(f[0], feed_mm_s - span)
    hi = min(f[-1], feed_mm_s + span)
    if hi <= lo:
        lo, hi = f[0], f[1]
    slope = (margin_at(ch, hi) - margin_at(ch, lo)) / (hi - lo)
    rel = slope * max(feed_mm_s, 1e-12) / ch.margin_scale
    if not math.isfinite(rel) or abs(rel) < FLAT_MARGIN_REL:
        return 0, rel if math.isfinite(rel) else 0.0
    return (1 if slope > 0 else -1), rel


def feed_limit_for_force(ch: Characteristic, force_max_N: float) -> float:
    """Largest feed [mm/s] with interpolated force ≤ ``force_max_N`` (∞ if the whole range is under;
    the lowest feed of the grid if even that is over)."""
    F = ch.force_N
    f = ch.feeds_mm_s
    over = np.flatnonzero(F > force_max_N)
    if over.size == 0:
        return math.inf
    k = int(over[0])
    if k == 0:
        return float(f[0])
    # linear inverse interpolation on the segment that crosses the limit
    F0, F1 = F[k - 1], F[k]
    return float(f[k - 1] + (force_max_N - F0) / (F1 - F0) * (f[k] - f[k - 1]))


def chatter_frequency(section: dict[str, Any], default_hz: float) -> float:
    """Expected chatter frequency [Hz]: √(f1 f2) of the section's natural frequencies, else the
    default (the thesis measured ≈ 11 Hz on its KR210)."""
    nf = section.get("natural_frequency_hz")
    try:
        f1, f2 = (float(x) for x in nf)  # type: ignore[union-attr]
    except (TypeError, ValueError):
        return default_hz
    if f1 > 0 and f2 > 0 and math.isfinite(f1 * f2):
        return math.sqrt(f1 * f2)
    return default_hz
