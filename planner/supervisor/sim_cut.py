"""A simulated cut whose chatter answers the override the controller really applies.

This is the ``sim`` signal source of ``cctmill supervise`` and the plant of the end-to-end tests.
It is built from the plan's stability characteristic, not from a time-domain simulation of the
arm (:mod:`models.dynamics` runs at about 6–10 simulated seconds per wall second, too slow to be the
plant of a 4 ms loop), so it is a *behavioural* model:

- the path advances at the actual feed: planned section feed × applied override / 100, with a
  first-order lag ``feed_tau_s`` (the controller's path-speed response); the section follows from
  the arc length travelled;
- stable cutting: mean force F̄(f) from the section's ``force_N(feed)``, tooth-passing harmonics
  (f_t and 2 f_t) modulating it, a forced response of the arm mode at f_c (a fraction of F̄: cutting
  always excites the structure a little) and white measurement noise;
- chatter: a sinusoid at f_c whose amplitude a obeys da/dt = λ a, λ = +growth when the *true*
  margin at the actual feed is negative and −decay when it is positive (smoothed by tanh over 5 %
  of the margin scale); it is seeded at ``chatter_seed_N`` when unstable and saturates at
  ``chatter_max_N`` (the limit cycle of real chatter);
- model error: from ``onset_s`` on, the true margin at feed f is the plan's margin at
  f × ``boundary_shift`` (the cut has become less stable than planned: tool wear, a softer
  fixture), so the planned feed chatters and a lower one does not — the supervisor's job; and
  ``margin_offset_N_per_m`` is subtracted from it (an arm less stable than its model by that much
  at every feed: what the averaged eigen model misses where the Floquet criterion finds the cut
  unstable);
- signal loss: no samples between ``loss_s[0]`` and ``loss_s[1]`` (a broken DAQ cable).

Everything is seeded; time is the simulation's own (s since the first read, on ``clock``).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from planner.plan_file import Plan, PlanSection
from planner.supervisor.ceiling import planned_speed_at
from planner.supervisor.characteristic import (
    Characteristic,
    characteristic_of,
    chatter_frequency,
    margin_at,
)
from robot_io.signals.base import Backlog, SignalChunk, SourceStats

__all__ = ["CutScenario", "CutTruth", "SimulatedCut"]

#: Longest stretch of signal one generate() call produces [s] (after a stall the sim skips ahead).
MAX_GENERATE_S = 0.5


@dataclass(frozen=True)
class CutScenario:
    """Parameters of the simulated cut (forces in N, times in s, rates in 1/s)."""

    onset_s: float | None = None
    boundary_shift: float = 1.6
    margin_offset_N_per_m: float = 0.0
    noise_N: float = 0.3
    forced_ratio: float = 0.005
    tooth_ratio: tuple[float, float] = (0.5, 0.2)
    growth_1_s: float = 25.0
    decay_1_s: float = 30.0
    chatter_seed_N: float = 0.05
    chatter_max_N: float = 40.0
    feed_tau_s: float = 0.03
    loss_s: tuple[float, float] | None = None
    chatter_hz_default: float = 11.0
    seed: int = 0


@dataclass
class CutTruth:
    """What really happened, one row per generated block (for tests and benchmarks).

    Lists of equal length: block end time [s], arc length [m], actual feed [m/s], chatter amplitude
    [N], true margin [N/m], section (position in ``plan.sections``, from 0), applied override
    [percent].
    """

    t_s: list[float] = field(default_factory=list)
    s_m: list[float] = field(default_factory=list)
    feed: list[float] = field(default_factory=list)
    chatter_N: list[float] = field(default_factory=list)
    margin_N_per_m: list[float] = field(default_factory=list)
    section: list[int] = field(default_factory=list)
    override: list[float] = field(default_factory=list)

    def arrays(self) -> dict[str, np.ndarray]:
        return {k: np.asarray(v) for k, v in self.__dict__.items()}


class SimulatedCut:
    """Simulated force signal of a plan's cut (see the module docstring); a :class:`SignalSource`.

    Args:
        plan: the plan being cut.
        override_percent: the override the controller applies now [percent] (e.g. the simulated
            KukaVarProxy server's ``$OV_PRO``).
        fs_hz: sample rate [Hz].
        scenario: the cut's parameters.
        clock: monotonic clock [s].
        start_s: arc length where the cut starts [m].
    """

    def __init__(self, plan: Plan, override_percent: Callable[[], float], fs_hz: float = 10_000.0,
                 scenario: CutScenario | None = None, clock: Callable[[], float] | None = None,
                 start_s: float = 0.0) -> None:
        self.plan = plan
        self.fs_hz = float(fs_hz)
        self.sc = scenario or CutScenario()
        self.stats = SourceStats()
        self.truth = CutTruth()
        self._override = override_percent
        self._clock = clock or time.monotonic
        self._rng = np.random.default_rng(self.sc.seed)
        self._t0: float | None = None
        self._k = 0  # samples generated
        self._s = start_s
        self._feed: float | None = None
        self._a = 0.0
        self._chars: dict[int, Characteristic | None] = {}
        self._backlog = Backlog(int(4 * self.fs_hz))
        self._phase_f = float(self._rng.uniform(0, 2 * math.pi))
        self._phase_t = self._rng.uniform(0, 2 * math.pi, 2)

    # -- plant -------------------------------------------------------------------------------
    def _section(self) -> PlanSection:
        return self.plan.section_at(self._s)

    def _char(self, sec: PlanSection) -> Characteristic | None:
        if sec.index not in self._chars:
            self._chars[sec.index] = characteristic_of(sec)
        return self._chars[sec.index]

    @property
    def start_clock_s(self) -> float | None:
        """The clock's reading at simulation time 0 [s] (None before the first read)."""
        return self._t0

    def sim_time(self) -> float:
        """Simulation time now [s] (0 before the first read)."""
        return 0.0 if self._t0 is None else self._clock() - self._t0

    def generate(self) -> tuple[np.ndarray, np.ndarray]:
        """Produce the samples due by now; return (t_s, values). Empty while the signal is lost."""
        now = self._clock()
        if self._t0 is None:
            self._t0 = now
        due = int((now - self._t0) * self.fs_hz)
        n = due - self._k
        if n <= 0:
            return np.zeros(0), np.zeros(0)
        if n > MAX_GENERATE_S * self.fs_hz:  # stalled: skip ahead, keep the signal continuous
            self._k = due - int(MAX_GENERATE_S * self.fs_hz)
            n = due - self._k
        t = (self._k + np.arange(n)) / self.fs_hz
        dt = n / self.fs_hz
        self._k = due
        sc = self.sc
        sec = self._section()
        ch = self._char(sec)
        try:
            ov = float(self._override())
        except Exception:  # a broken provider must not stop the plant  # noqa: BLE001
            ov = 100.0
        if not math.isfinite(ov):
            ov = 100.0
        target = (planned_speed_at(self.plan, self._s, sec) * ov / 100.0
                  if sec.kind != "rapid" else 0.0)
        if self._feed is None:
            self._feed = target
        tau = max(sc.feed_tau_s, 1e-6)
        feed = target + (self._feed - target) * np.exp(-(t - t[0] + 1.0 / self.fs_hz) / tau)
        self._feed = float(feed[-1])
        self._s += float(np.mean(feed)) * dt
        f_c = chatter_frequency(sec, sc.chatter_hz_default)
        f_t = sec.tooth_frequency or 0.0
        if ch is None:
            mean_F = np.zeros(n)
            margin = math.inf
        else:
            mean_F = np.interp(feed, ch.feeds, ch.force)
            after = sc.onset_s is not None and t[0] >= sc.onset_s
            shift = sc.boundary_shift if after else 1.0
            margin = margin_at(ch, self._feed * shift) - (sc.margin_offset_N_per_m if after else 0.0)
        # chatter amplitude over this block
        if math.isfinite(margin):
            scale = 0.05 * (ch.margin_scale if ch is not None else 1.0)
            x = math.tanh(margin / scale)
            lam = -sc.decay_1_s * x if x > 0 else -sc.growth_1_s * x
            if margin < 0:
                self._a = max(self._a, sc.chatter_seed_N)
        else:
            lam = -sc.decay_1_s
        a = np.clip(self._a * np.exp(lam * (t - t[0] + 1.0 / self.fs_hz)), 0.0, sc.chatter_max_N)
        self._a = float(a[-1])
        tw = 2 * math.pi * t
        y = mean_F * (1.0 + sc.tooth_ratio[0] * np.sin(tw * f_t + self._phase_t[0])
                      + sc.tooth_ratio[1] * np.sin(2 * tw * f_t + self._phase_t[1]))
        y += sc.forced_ratio * mean_F * np.sin(tw * f_c + self._phase_f)
        y += a * np.sin(tw * f_c)
        y += self._rng.normal(0.0, sc.noise_N, n)
        tr = self.truth
        tr.t_s.append(float(t[-1]))
        tr.s_m.append(self._s)
        tr.feed.append(self._feed)
        tr.chatter_N.append(self._a)
        tr.margin_N_per_m.append(margin if math.isfinite(margin) else float("nan"))
        tr.section.append(sec.index)
        tr.override.append(ov)
        if sc.loss_s is not None and sc.loss_s[0] <= t[-1] < sc.loss_s[1]:
            return np.zeros(0), np.zeros(0)
        return t, y

    # -- SignalSource ------------------------------------------------------------------------
    def read(self, max_samples: int) -> SignalChunk:
        try:
            t, y = self.generate()
        except Exception as e:  # noqa: BLE001 - a source never raises into the loop
            self.stats.last_error = f"simulation failed: {e!r}"
            return SignalChunk(np.zeros(0), np.zeros(0), "error")
        if y.size:
            self.stats.packets += 1
            self.stats.overflow += self._backlog.push(t, y)
        t, y = self._backlog.pop(int(max_samples))
        self.stats.samples += y.shape[0]
        return SignalChunk(t, y, "ok")

    def close(self) -> None:
        pass
