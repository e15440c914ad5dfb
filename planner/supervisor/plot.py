"""Plot of a supervised run: the band against its limit, the override, and (simulated cuts) the
true chatter amplitude — what ``cctmill supervise --plot`` draws."""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from planner.report.plots import new_figure, save_figure
from planner.supervisor.policy import StepResult
from planner.supervisor.sim_cut import CutTruth

__all__ = ["RunTrace", "plot_run"]


@dataclass
class RunTrace:
    """Per-step record of a run (the loop's ``on_step`` appends to it).

    Lists of equal length: loop time since the start [s], band value (NaN when none), limit in
    force, commanded override [percent], status.
    """

    t_s: list[float] = field(default_factory=list)
    band: list[float] = field(default_factory=list)
    ucl: list[float] = field(default_factory=list)
    override: list[float] = field(default_factory=list)
    status: list[str] = field(default_factory=list)
    _t0: float | None = None

    def __call__(self, now: float, res: StepResult) -> None:
        if self._t0 is None:
            self._t0 = now
        self.t_s.append(now - self._t0)
        self.band.append(np.nan if res.band is None else res.band)
        self.ucl.append(res.ucl)
        self.override.append(res.override)
        self.status.append(res.status)


def plot_run(trace: RunTrace, path: str | os.PathLike, truth: CutTruth | None = None,
             title: str = "supervised cut") -> Path:
    """Three panels over time: band and limit; override (and the applied one); true chatter."""
    plt, fig = new_figure(figsize=(9, 7.5))
    t = np.asarray(trace.t_s)
    n = 3 if truth is not None else 2
    ax1 = fig.add_subplot(n, 1, 1)
    ucl = np.asarray(trace.ucl, dtype=float)
    ax1.plot(t, trace.band, lw=0.7, label="|band| (largest per step)")
    ax1.plot(t, np.where(np.isfinite(ucl), ucl, np.nan), "r", lw=1.0, label="limit (UCL + transient)")
    alarm = np.array([s == "alarm" for s in trace.status])
    if alarm.any():
        ax1.plot(t[alarm], np.asarray(trace.band)[alarm], "r.", ms=3, label="alarm (band over the limit)")
    held = np.array([s == "hold" for s in trace.status])
    if held.any():   # the supervisor cannot act: escalated at the floor, a link fault, no signal
        edges = np.flatnonzero(np.diff(np.concatenate([[0], held.astype(int), [0]])))
        for k, (a, b) in enumerate(zip(edges[::2], edges[1::2], strict=True)):
            ax1.axvspan(t[a], t[min(b, t.size - 1)], color="0.6", alpha=0.25, lw=0,
                        label="override held (escalated, link fault or no signal)"
                        if k == 0 else None)
    ax1.set_ylabel("band [signal unit: N for a force]")
    # above the panel, outside the data (the band fills the panel during chatter)
    ax1.legend(loc="lower left", bbox_to_anchor=(0.0, 1.01), ncol=2, fontsize=7, frameon=False)
    ax2 = fig.add_subplot(n, 1, 2, sharex=ax1)
    ax2.plot(t, trace.override, lw=1.0, label="commanded override")
    if truth is not None and truth.t_s:
        tr = truth.arrays()
        ax2.plot(tr["t_s"], tr["override"], "--", lw=0.8, label="applied by the controller")
    ax2.set_ylabel("override [%]")
    ax2.set_ylim(0, 105)
    ax2.legend(loc="lower left", fontsize=8)
    if truth is not None and truth.t_s:
        tr = truth.arrays()
        ax3 = fig.add_subplot(n, 1, 3, sharex=ax1)
        ax3.plot(tr["t_s"], tr["chatter_N"], lw=1.0, label="true chatter amplitude (simulation)")
        ax3.set_ylabel("chatter [N]")
        ax3.legend(loc="upper left", fontsize=8)
        ax3.set_xlabel("time [s]")
    else:
        ax2.set_xlabel("time [s]")
    return save_figure(plt, fig, title, path)
