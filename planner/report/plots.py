"""Plots for people. Matplotlib with the non-interactive Agg backend; files written atomically."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from models.point import StabilityCharacteristic
from planner._atomic import atomic_path

__all__ = ["new_figure", "plot_characteristic", "plot_path_kinematics", "save_figure"]


def new_figure(**kw):
    """``(pyplot, figure)`` on the Agg backend (no display needed); ``kw`` go to ``plt.figure``."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return plt, plt.figure(**kw)


def save_figure(plt, fig, title: str, path: str | os.PathLike) -> Path:
    """Title, tight layout, atomic PNG write, close."""
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    with atomic_path(path, suffix=".png") as tmp:
        fig.savefig(tmp, format="png")
    plt.close(fig)
    return Path(path)


def _spans(mask: np.ndarray) -> list[tuple[int, int]]:
    """Index runs [i, j] where ``mask`` is True."""
    runs, start = [], None
    for i, m in enumerate(mask):
        if m and start is None:
            start = i
        if not m and start is not None:
            runs.append((start, i - 1))
            start = None
    if start is not None:
        runs.append((start, len(mask) - 1))
    return runs


def plot_characteristic(ch: StabilityCharacteristic, path: str | os.PathLike,
                        title: str = "Stability characteristic") -> Path:
    """γ and margin against feed, unstable regions shaded, force limit marked. Writes a PNG.

    Args:
        ch: the characteristic (SI).
        path: output PNG path.
        title: plot title.
    """
    plt, fig = new_figure(figsize=(8.0, 6.0), dpi=110)
    feed_mm_s = ch.feeds * 1e3
    ax_g, ax_m = fig.subplots(2, 1, sharex=True)
    gamma_window = ch.points[0].criterion == "gamma_window" if ch.points else False
    ax_g.plot(feed_mm_s, np.degrees(ch.gamma), color="tab:blue", lw=2, label="γ")
    ax_g.set_ylabel("γ: force → K_max direction [deg]")
    margin = np.degrees(ch.margin) if gamma_window else ch.margin
    ax_m.plot(feed_mm_s, margin, color="tab:green", lw=2, label="stability margin")
    ax_m.axhline(0.0, color="k", lw=0.8)
    ax_m.set_ylabel("margin [deg]" if gamma_window else "margin [N/m]")
    ax_m.set_xlabel("feed [mm/s]")
    half = (feed_mm_s[1] - feed_mm_s[0]) / 2 if feed_mm_s.size > 1 else 0.5
    for ax in (ax_g, ax_m):
        for i, j in _spans(~ch.stable):
            ax.axvspan(feed_mm_s[i] - half, feed_mm_s[j] + half, color="tab:red", alpha=0.15,
                       lw=0, label="unstable" if ax is ax_m and i == _spans(~ch.stable)[0][0]
                       else None)
        for i, j in _spans(ch.force > ch.force_limit):
            ax.axvspan(feed_mm_s[i] - half, feed_mm_s[j] + half, color="tab:orange", alpha=0.15,
                       lw=0, hatch="//")
        ax.grid(alpha=0.3)
    over = np.flatnonzero(ch.force > ch.force_limit)
    if over.size:
        ax_m.axvline(feed_mm_s[over[0]], color="tab:orange", ls="--",
                     label=f"force limit {ch.force_limit:.0f} N")
    if ch.feed_limit > 0:
        ax_m.axvline(ch.feed_limit * 1e3, color="k", ls=":",
                     label=f"feed limit {ch.feed_limit * 1e3:.2f} mm/s ({ch.binding})")
    ax_f = ax_m.twinx()
    ax_f.plot(feed_mm_s, ch.force, color="tab:orange", lw=1, alpha=0.7)
    ax_f.axhline(ch.force_limit, color="tab:orange", lw=0.8, ls="--")
    ax_f.set_ylabel("|F| [N]", color="tab:orange")
    ax_m.legend(loc="best", fontsize=8)
    p = ch.points[0] if ch.points else None
    if p is not None:
        title += f"  ({p.process_model} process model, {p.mass_model} mass, {p.criterion})"
    return save_figure(plt, fig, title, path)


def plot_path_kinematics(s: np.ndarray, q: np.ndarray, lower: np.ndarray, upper: np.ndarray,
                         joint_names: tuple[str, ...], reachable: np.ndarray, a_e: np.ndarray,
                         a_p: np.ndarray, mode: np.ndarray, path: str | os.PathLike,
                         title: str = "Path kinematics and engagement") -> Path:
    """Joint angles (against their limits) and engagement along the path. Writes a PNG.

    Args:
        s: arc length [m], shape (n,).
        q: joints [rad], shape (n, nq).
        lower, upper: joint limits [rad], shape (nq,).
        joint_names: names for the legend.
        reachable: shape (n,), bool (unreachable stretches are shaded red).
        a_e, a_p: radial/axial depth [m], shape (n,).
        mode: milling mode codes (0 up, 1 down, 2 slot, −1 air), shape (n,).
        path: output PNG.
    """
    plt, fig = new_figure(figsize=(10.0, 7.5), dpi=100)
    ax_q, ax_e = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": [3, 2]})
    frac = (q - lower) / (upper - lower)
    for i, name in enumerate(joint_names):
        ax_q.plot(s, frac[:, i] * 100.0, lw=1.5,
                  label=f"{name} [{np.degrees(q[:, i]).min():.0f}, "
                        f"{np.degrees(q[:, i]).max():.0f}] deg")
    ax_q.axhspan(90, 100, color="tab:red", alpha=0.08)
    ax_q.axhspan(0, 10, color="tab:red", alpha=0.08)
    ax_q.set_ylim(-2, 102)
    ax_q.set_ylabel("joint position in its range [%]\n(0 = lower, 100 = upper limit)")
    ax_q.legend(loc="upper left", fontsize=7, ncol=3)
    colors = {-1: "white", 0: "tab:blue", 1: "tab:green", 2: "tab:purple"}
    labels = {-1: "air", 0: "up", 1: "down", 2: "slot"}
    for ax in (ax_q, ax_e):
        for i, j in _spans(~reachable):
            ax.axvspan(s[i], s[j], color="tab:red", alpha=0.3, lw=0)
        ax.grid(alpha=0.3)
    seen = set()
    for code in (0, 1, 2):
        for i, j in _spans(mode == code):
            ax_e.axvspan(s[i], s[j], color=colors[code], alpha=0.12, lw=0,
                         label=None if code in seen else labels[code])
            seen.add(code)
    ax_e.plot(s, a_e * 1e3, color="k", lw=1.5, label="a_e (radial)")
    ax_e.plot(s, a_p * 1e3, color="tab:orange", lw=1.5, label="a_p (axial)")
    ax_e.set_ylabel("depth of cut [mm]")
    ax_e.set_xlabel("path length s [m]")
    ax_e.legend(loc="upper left", fontsize=7, ncol=5)
    return save_figure(plt, fig, title, path)
