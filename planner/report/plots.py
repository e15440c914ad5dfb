"""Plots for people. Matplotlib with the non-interactive Agg backend; files written atomically."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from models.point import StabilityCharacteristic
from planner._atomic import atomic_path

__all__ = ["DENSE_SAMPLES", "PLOT_BINS", "bin_edges", "binned", "crossings", "draw_density", "draw_series",
           "legend_outside",
           "new_figure", "plot_characteristic", "plot_path_kinematics", "save_figure"]


def new_figure(**kw):
    """``(pyplot, figure)`` on the Agg backend (no display needed); ``kw`` go to ``plt.figure``."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return plt, plt.figure(**kw)


def save_figure(plt, fig, title: str, path: str | os.PathLike, bottom: float = 0.0) -> Path:
    """Title, tight layout (the lowest ``bottom`` of the figure, 0..1, left to a figure legend),
    atomic PNG write, close."""
    fig.suptitle(title, fontsize=10)
    fig.tight_layout(rect=(0.0, bottom, 1.0, 1.0))
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


def crossings(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Where ``y`` changes sign between grid points of ``x``, linearly interpolated."""
    x = np.asarray(x, float)
    y = np.asarray(y, float)
    i = np.flatnonzero((y[:-1] <= 0) != (y[1:] <= 0))
    y0, y1 = y[i], y[i + 1]
    t = np.where(y1 != y0, -y0 / np.where(y1 != y0, y1 - y0, 1.0), 0.5)
    return x[i] + np.clip(t, 0.0, 1.0) * (x[i + 1] - x[i])


def _runs(x: np.ndarray, mask: np.ndarray, at: np.ndarray) -> list[tuple[float, float]]:
    """The stretches of ``x`` where ``mask`` holds, their ends at the crossings ``at`` (the
    interpolated change) when one lies in the grid step, else at the grid point."""
    out = []
    for i, j in _spans(mask):
        lo, hi = x[i], x[j]
        if i > 0:
            inside = at[(at >= x[i - 1]) & (at <= x[i])]
            lo = float(inside[0]) if inside.size else lo
        if j < x.size - 1:
            inside = at[(at >= x[j]) & (at <= x[j + 1])]
            hi = float(inside[0]) if inside.size else hi
        out.append((lo, hi))
    return out


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
    stable = np.asarray(ch.stable, bool)
    over_mask = np.asarray(ch.force, float) > ch.force_limit
    force_at = crossings(feed_mm_s, np.asarray(ch.force, float) - ch.force_limit)
    margin_at = crossings(feed_mm_s, np.where(stable, 1.0, -1.0) if gamma_window
                          else np.asarray(ch.margin, float))
    for ax in (ax_g, ax_m):
        for lo, hi in _runs(feed_mm_s, ~stable, margin_at):
            ax.axvspan(lo, hi, color="tab:red", alpha=0.15, lw=0,
                       label="unstable" if ax is ax_m and lo == _runs(feed_mm_s, ~stable,
                                                                      margin_at)[0][0] else None)
        for lo, hi in _runs(feed_mm_s, over_mask, force_at):
            ax.axvspan(lo, hi, color="tab:orange", alpha=0.15, lw=0, hatch="//")
        ax.grid(alpha=0.3)
    # the force limit, once: where the force crosses it (interpolated between the grid's feeds)
    if over_mask.any():
        f_star = force_at[0] if force_at.size else feed_mm_s[np.flatnonzero(over_mask)[0]]
        grid = (f"; the grid's feed limit {ch.feed_limit * 1e3:.2f} mm/s"
                if ch.binding in ("force", "both") else "")
        for ax in (ax_g, ax_m):
            ax.axvline(f_star, color="tab:orange", ls="--", lw=1.2,
                       label=(f"force reaches {ch.force_limit:.0f} N at {f_star:.2f} mm/s{grid}"
                              if ax is ax_m else None))
    if ch.feed_limit > 0 and ch.binding not in ("force", "both", "feed_max"):
        ax_m.axvline(ch.feed_limit * 1e3, color="k", ls=":",
                     label=f"feed limit {ch.feed_limit * 1e3:.2f} mm/s ({ch.binding}, grid)")
    ax_f = ax_m.twinx()
    ax_f.plot(feed_mm_s, ch.force, color="tab:orange", lw=1, alpha=0.7)
    ax_f.axhline(ch.force_limit, color="tab:orange", lw=0.8, ls="--")
    ax_f.set_ylabel("|F| [N]", color="tab:orange")
    handles, labels = ax_m.get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", fontsize=8, ncol=2, frameon=False)
    p = ch.points[0] if ch.points else None
    if p is not None:
        title += f"  ({p.process_model} process model, {p.mass_model} mass, {p.criterion})"
    return save_figure(plt, fig, title, path, bottom=0.06)


def _deg(rad: float) -> str:
    """An angle [rad] in whole degrees, without a "-0"."""
    return f"{round(float(np.degrees(rad))) + 0:d}"


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
    from matplotlib.patches import Patch

    s = np.asarray(s, float)
    dense = s.size > DENSE_SAMPLES
    edges = bin_edges(s) if s.size else np.array([0.0, 1.0])
    plt, fig = new_figure(figsize=(12.0, 8.0), dpi=100)
    ax_q, ax_m, ax_e = fig.subplots(3, 1, sharex=True,
                                    gridspec_kw={"height_ratios": [3, 0.35, 2]})
    frac = (q - lower) / (upper - lower)
    for i, name in enumerate(joint_names):
        # the legend gives the joint's limits (its range is the plot: 0 % lower, 100 % upper)
        label = (f"{name} limits [{_deg(lower[i])}, {_deg(upper[i])}] deg, "
                 f"used {_deg(q[:, i].min())}…{_deg(q[:, i].max())}")
        draw_series(ax_q, s, frac[:, i] * 100.0, f"C{i}", label, line="median", spread=None,
                    edges=edges if dense else None, lw=1.5)
    ax_q.axhspan(90, 100, color="tab:red", alpha=0.08)
    ax_q.axhspan(0, 10, color="tab:red", alpha=0.08)
    ax_q.set_ylim(-2, 102)
    ax_q.set_ylabel("joint position in its range [%]\n(0 = lower, 100 = upper limit)")
    legend_outside(ax_q)
    colors = {-1: "white", 0: "tab:blue", 1: "tab:green", 2: "tab:purple"}
    labels = {-1: "air", 0: "up", 1: "down", 2: "slot"}
    for ax in (ax_q, ax_e):
        for i, j in _spans(~reachable):
            ax.axvspan(s[i], s[j], color="tab:red", alpha=0.3, lw=0)
        ax.grid(alpha=0.3)
    # the milling mode as a strip of its own: per bin the share of each mode's samples
    mode = np.asarray(mode)
    present = [c for c in (0, 1, 2, -1) if np.any(mode == c)]
    if dense:
        counts = np.vstack([np.histogram(s[mode == c], bins=edges)[0] for c in present]) \
            if present else np.zeros((0, edges.size - 1))
        total = np.maximum(counts.sum(axis=0), 1)
        bottom = np.zeros(edges.size - 1)
        for c, k in zip(present, counts, strict=True):
            ax_m.bar(edges[:-1], k / total, width=np.diff(edges), bottom=bottom, align="edge",
                     color=colors[c] if c >= 0 else "0.85", lw=0)
            bottom += k / total
    else:
        for c in present:
            for i, j in _spans(mode == c):
                ax_m.axvspan(s[i], s[min(j + 1, s.size - 1)], color=colors[c] if c >= 0 else "0.85",
                             lw=0)
    ax_m.set_ylim(0, 1)
    ax_m.set_yticks([])
    ax_m.set_ylabel("mode", rotation=0, ha="right", va="center")
    ax_m.legend([Patch(color=colors[c] if c >= 0 else "0.85") for c in present],
                [labels[c] for c in present], fontsize=7, loc="upper left", bbox_to_anchor=(1.005, 1.0),
                borderaxespad=0.0, ncol=len(present) or 1)
    draw_series(ax_e, s, a_e * 1e3, "k", "a_e (radial)", line="max", edges=edges if dense else None,
                lw=1.2)
    draw_series(ax_e, s, a_p * 1e3, "tab:orange", "a_p (axial)", line="max",
                edges=edges if dense else None, lw=1.2)
    ax_e.set_ylabel("depth of cut [mm]")
    ax_e.set_xlabel("path length s [m]")
    legend_outside(ax_e)
    if dense:
        title += f" ({s.size:,} samples, drawn per {np.diff(edges)[0] * 1e3:.0f} mm bin)"
    return save_figure(plt, fig, title, path)


#: A panel with more samples than this is drawn per bin of the path length (a line through each
#: bin's statistic, its spread shaded): 28,000 samples on 1,000 pixels are ink, not a curve.
DENSE_SAMPLES = 3000
#: Bins of a dense panel (about one and a half pixels each at the report's width).
PLOT_BINS = 600


def bin_edges(s: np.ndarray, bins: int = PLOT_BINS) -> np.ndarray:
    """``bins + 1`` equally spaced edges over ``s`` [m] (monotonic arc length)."""
    lo, hi = float(np.nanmin(s)), float(np.nanmax(s))
    return np.linspace(lo, hi if hi > lo else lo + 1.0, bins + 1)


def binned(s: np.ndarray, v: np.ndarray, edges: np.ndarray,
           stats: tuple[str, ...] = ("min", "median", "max")) -> dict[str, np.ndarray]:
    """Per bin of ``edges`` (over the non-decreasing ``s``), each statistic of the finite values
    of ``v``: ``min``, ``max``, ``median``, ``p25``, ``p75``; NaN in a bin with none. Also
    ``centre``, the bins' centres."""
    s = np.asarray(s, float)
    v = np.asarray(v, float)
    cut = np.searchsorted(s, edges[1:-1], side="right")
    starts = np.concatenate([[0], cut])
    stops = np.concatenate([cut, [s.size]])
    out = {k: np.full(edges.size - 1, np.nan) for k in stats}
    q = {"min": 0.0, "p25": 25.0, "median": 50.0, "p75": 75.0, "max": 100.0}
    for b, (a, z) in enumerate(zip(starts, stops, strict=True)):
        w = v[a:z]
        w = w[np.isfinite(w)]
        if w.size:
            vals = np.percentile(w, [q[k] for k in stats])
            for k, x in zip(stats, vals, strict=True):
                out[k][b] = x
    out["centre"] = 0.5 * (edges[:-1] + edges[1:])
    return out


def draw_series(ax, s: np.ndarray, v: np.ndarray, colour, label: str, line: str = "median",
                spread: tuple[str, str] | None = ("min", "max"), edges: np.ndarray | None = None,
                **kw) -> None:
    """``v`` against ``s``: as it is when short, else per bin (``edges``): a line through each
    bin's ``line`` statistic and ``spread`` shaded. The label says which."""
    if edges is None or s.size <= DENSE_SAMPLES:
        ax.plot(s, v, color=colour, label=label, **kw)
        return
    stats = (line,) if spread is None else tuple(dict.fromkeys((line, *spread)))
    b = binned(s, v, edges, stats)
    what = {"median": "median", "max": "largest", "min": "smallest"}.get(line, line)
    ax.plot(b["centre"], b[line], color=colour, label=f"{label}, {what} per bin",
            **{k: x for k, x in kw.items() if k != "drawstyle"})
    if spread is not None:
        ax.fill_between(b["centre"], b[spread[0]], b[spread[1]], color=colour, alpha=0.22, lw=0,
                        label=f"{spread[0]}–{spread[1]} per bin" if spread != ("min", "max")
                        else "range per bin")


def draw_density(ax, s: np.ndarray, v: np.ndarray, edges: np.ndarray, lo: float, hi: float,
                 label: str, cmap: str = "Greys", levels: int = 60) -> None:
    """How many samples of each bin of ``s`` take each value of ``v`` in [lo, hi], as a shaded
    image (darker: more samples): a quantity that flips between two values (γ across a zig-zag)
    reads as two lines, not as a block of ink."""
    from matplotlib.colors import LogNorm

    ok = np.isfinite(v)
    counts, _, _ = np.histogram2d(np.asarray(s, float)[ok], np.asarray(v, float)[ok],
                                  bins=[edges, np.linspace(lo, hi, levels + 1)])
    counts = np.ma.masked_equal(counts.T, 0)
    if counts.count():
        ax.pcolormesh(edges, np.linspace(lo, hi, levels + 1), counts, cmap=cmap,
                      norm=LogNorm(vmin=0.2, vmax=max(float(counts.max()), 2.0)), shading="flat",
                      rasterized=True)
    from matplotlib.patches import Patch

    ax.legend([Patch(color="0.35")], [label], fontsize=7, loc="upper left", bbox_to_anchor=(1.005, 1.0),
              borderaxespad=0.0)


def legend_outside(ax, **kw) -> None:
    """The legend to the right of the axes, out of the data."""
    kw.setdefault("fontsize", 7)
    ax.legend(loc="upper left", bbox_to_anchor=(1.005, 1.0), borderaxespad=0.0, **kw)
