"""Simulated path speed of a controller under program override, shared by the simulated peers, and
the Cartesian path correction of an RSI controller (:class:`SimulatedCorrection`).

The path speed follows ``programmed_speed × override / 100`` with a first-order lag (time constant
``tau``), evaluated in closed form at any time, so no thread has to integrate it. Setting
:attr:`SimulatedPathSpeed.ignore_override` makes the controller keep its override whatever it is
sent (an override channel not wired to ``$OV_PRO``): the supervisor's link-fault tests use it with
either simulated peer.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from dataclasses import replace
from typing import Any

__all__ = [
    "POSCORR_LIMIT_DEG",
    "POSCORR_LIMIT_MM",
    "SimulatedCorrection",
    "SimulatedPathSpeed",
    "SimulatedPeer",
]

#: KUKA's example POSCORR limits of the total Cartesian correction (KUKA_IO.md §2.3).
POSCORR_LIMIT_MM = 5.0
POSCORR_LIMIT_DEG = 5.0
#: How a controller applies corrections (``RSI_ON(#RELATIVE)`` / ``RSI_ON(#ABSOLUTE)``).
_MODES = ("relative", "absolute")


class SimulatedPathSpeed:
    """Path speed [m/s] responding to ``$OV_PRO`` changes.

    Args:
        programmed_speed: ``$VEL.CP`` of the running motion [m/s].
        tau: time constant of the speed response to an override change [s] (0: immediate).
        override_percent: initial override [percent].
        clock: monotonic clock [s] (tests may pass a fake).
    """

    def __init__(self, programmed_speed: float = 1e-3, tau: float = 0.03, override_percent: float = 100.0,
                 clock: Callable[[], float] = time.monotonic) -> None:
        if not (programmed_speed >= 0 and tau >= 0):
            raise ValueError("programmed_speed and tau must be non-negative")
        self.programmed_speed = programmed_speed
        self.tau = tau
        self._clock = clock
        self._lock = threading.Lock()
        self._override = float(override_percent)
        self._t0 = clock()
        self._v0 = programmed_speed * self._override / 100.0
        self._s0 = 0.0
        #: when true, :meth:`set_override` changes nothing (a controller that does not apply it)
        self.ignore_override = False

    def _state(self, t: float) -> tuple[float, float]:
        """(speed [m/s], path position [m]) at time ``t``; caller holds the lock."""
        target = self.programmed_speed * self._override / 100.0
        dt = max(0.0, t - self._t0)
        if self.tau == 0:
            return target, self._s0 + target * dt
        decay = math.exp(-dt / self.tau)
        v = target + (self._v0 - target) * decay
        s = self._s0 + target * dt + (self._v0 - target) * self.tau * (1.0 - decay)
        return v, s

    @property
    def override_percent(self) -> float:
        with self._lock:
            return self._override

    def set_override(self, percent: float) -> None:
        """Apply a new override [percent] from now on (nothing when :attr:`ignore_override`)."""
        if self.ignore_override:
            return
        with self._lock:
            t = self._clock()
            self._v0, self._s0 = self._state(t)
            self._t0 = t
            self._override = float(percent)

    def speed(self) -> float:
        """Path speed now [m/s]."""
        with self._lock:
            return self._state(self._clock())[0]

    def position(self) -> float:
        """Path length travelled since start [m]."""
        with self._lock:
            return self._state(self._clock())[1]


class SimulatedPeer:
    """What the simulated KVP server and RSI controller share: a counter record and a path speed.

    A subclass sets ``self._lock`` (a lock), ``self._stats`` (a frozen dataclass of counters) and
    ``self.path`` (a :class:`SimulatedPathSpeed`) in its ``__init__``.
    """

    _lock: Any
    _stats: Any
    path: SimulatedPathSpeed

    @property
    def stats(self) -> Any:
        """A snapshot of the counters."""
        with self._lock:
            return self._stats

    @property
    def override_percent(self) -> float:
        """``$OV_PRO`` the simulated controller applies [percent]."""
        return self.path.override_percent

    def path_speed(self) -> float:
        """Simulated path speed now [m/s]."""
        return self.path.speed()

    def _count(self, **inc: int) -> None:
        with self._lock:
            s = self._stats
            self._stats = replace(s, **{k: getattr(s, k) + v for k, v in inc.items()})


class SimulatedCorrection:
    """The total Cartesian path correction (RKorr) of a controller running RSI.

    ``relative`` (``RSI_ON(#RELATIVE)``) adds every received correction to the total; ``absolute``
    holds the last received one. The total is capped per component at the POSCORR limits (±5 mm,
    ±5° in KUKA's example), as the controller's correction object does: a value beyond them is
    not applied beyond them (the real controller also stops the program at POSCORRMON; counted
    here in :attr:`capped`).

    Args:
        mode: ``"relative"`` or ``"absolute"``.
        limit_mm, limit_deg: POSCORR limits of the total [mm], [deg].
    """

    def __init__(self, mode: str = "relative", limit_mm: float = POSCORR_LIMIT_MM,
                 limit_deg: float = POSCORR_LIMIT_DEG) -> None:
        if mode not in _MODES:
            raise ValueError(f"correction mode {mode!r} is not one of {', '.join(_MODES)}")
        if not (limit_mm > 0 and limit_deg > 0):
            raise ValueError("the POSCORR limits must be positive")
        self.mode = mode
        self._limits = (limit_mm,) * 3 + (limit_deg,) * 3
        self._lock = threading.Lock()
        self._total = [0.0] * 6
        #: corrections that hit a POSCORR limit
        self.capped = 0

    def apply(self, values: tuple[float, ...] | list[float]) -> None:
        """Apply one received correction (X, Y, Z [mm], A, B, C [deg])."""
        with self._lock:
            new = ([t + v for t, v in zip(self._total, values, strict=True)] if self.mode == "relative"
                   else [float(v) for v in values])
            out = [min(max(v, -lim), lim) for v, lim in zip(new, self._limits, strict=True)]
            if out != new:
                self.capped += 1
            self._total = out

    @property
    def total(self) -> tuple[float, ...]:
        """The correction applied to the path now (X, Y, Z [mm], A, B, C [deg])."""
        with self._lock:
            return tuple(self._total)
