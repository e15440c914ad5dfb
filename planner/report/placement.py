"""The placement study in pictures and in the report: the heat map and the report's section.

:func:`plot_placement_heatmap` draws one panel per z level of the grid: the cycle time over the
x–y grid (the best over yaw where yaw varies), out-of-reach and infeasible placements crossed out,
the job's own placement and the best one marked. :func:`placement_section` is the HTML section the
report of the best placement's plan carries (``cctmill place`` writes it under ``best/``).
"""

from __future__ import annotations

import base64
import html
import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from planner._atomic import atomic_path
from planner.report.plots import new_figure

__all__ = ["placement_section", "plot_placement_heatmap"]

#: Cells per panel up to which each cell is labelled with its cycle time.
LABEL_CELLS = 144
#: Rows of the best placements listed in the report.
TOP_ROWS = 10


#: Markers of the job's own placement and the best one.
_OWN = {"marker": "*", "s": 260, "facecolor": "none", "edgecolor": "k", "linewidths": 1.4}
_BEST = {"marker": "o", "s": 330, "facecolor": "none", "edgecolor": "#1f3fbf", "linewidths": 2.0}


def _close(a: float, b: float) -> bool:
    return abs(a - b) <= 1e-6 * max(1.0, abs(a), abs(b))


def _on(v: float, values: np.ndarray) -> bool:
    """``v`` is one of the grid's ``values`` (the own placement may lie between them)."""
    return any(_close(v, float(u)) for u in values)


def plot_placement_heatmap(doc: dict[str, Any], path: str | os.PathLike) -> Path:
    """The heat map of a study (``doc``: its ``place.json`` document). Writes a PNG."""
    g = doc["grid"]
    xs, ys, zs = np.array(g["x_mm"]), np.array(g["y_mm"]), np.array(g["z_mm"])
    grid_rows = [r for r in doc["placements"] if r["stage"] in ("grid", "own")]
    screened_out = [r for r in (doc.get("screen") or {}).get("results", []) if not r["feasible"]]
    feasible = [r["cycle_time_s"] for r in doc["placements"] if r["feasible"]]
    vmin, vmax = (min(feasible), max(feasible)) if feasible else (0.0, 1.0)
    if vmax <= vmin:
        vmax = vmin + 1.0
    ncol = min(3, zs.size)
    nrow = math.ceil(zs.size / ncol)
    w = max(3.2, 0.75 * xs.size + 1.6)
    h = max(2.8, 0.55 * ys.size + 1.4)
    plt, fig = new_figure(figsize=(min(18.0, w * ncol + 1.2), min(20.0, h * nrow + 0.8)), dpi=100,
                          layout="constrained")
    axes = np.atleast_1d(fig.subplots(nrow, ncol, squeeze=False)).ravel()
    cmap = plt.get_cmap("RdYlGn_r").with_extremes(bad="0.85")
    best, own = doc.get("best"), doc.get("own")
    image = None
    for k, z in enumerate(zs):
        ax = axes[k]
        cyc = np.full((ys.size, xs.size), np.nan)
        state = np.zeros((ys.size, xs.size), int)  # 0 not planned (pruned), 1 infeasible, 2 ok
        for r in [*grid_rows, *screened_out]:
            if not (_close(r["z_mm"], z) and _on(r["x_mm"], xs) and _on(r["y_mm"], ys)):
                continue
            i = int(np.argmin(np.abs(ys - r["y_mm"])))
            j = int(np.argmin(np.abs(xs - r["x_mm"])))
            if r["feasible"]:
                if not (cyc[i, j] <= r["cycle_time_s"]):
                    cyc[i, j] = r["cycle_time_s"]
                state[i, j] = 2
            else:
                state[i, j] = max(state[i, j], 1)
        image = ax.imshow(np.ma.masked_invalid(cyc), origin="lower", cmap=cmap, vmin=vmin,
                          vmax=vmax, aspect="auto",
                          extent=(-0.5, xs.size - 0.5, -0.5, ys.size - 0.5))
        for i in range(ys.size):
            for j in range(xs.size):
                if state[i, j] == 1:
                    ax.text(j, i, "×", ha="center", va="center", fontsize=14, color="0.35")
                elif state[i, j] == 0:
                    ax.text(j, i, "•", ha="center", va="center", fontsize=9, color="0.5")
                elif xs.size * ys.size <= LABEL_CELLS:
                    ax.text(j, i, f"{cyc[i, j]:.0f}", ha="center", va="center", fontsize=8)
        for r, style in ((own, _OWN), (best, _BEST)):
            if r is None or not _close(r["z_mm"], z):
                continue
            jx = np.interp(r["x_mm"], xs, np.arange(xs.size)) if xs.size > 1 else 0.0
            iy = np.interp(r["y_mm"], ys, np.arange(ys.size)) if ys.size > 1 else 0.0
            ax.scatter([jx], [iy], zorder=3, **style)
        ax.set_xticks(range(xs.size), [f"{v:g}" for v in xs], fontsize=7, rotation=45)
        ax.set_yticks(range(ys.size), [f"{v:g}" for v in ys], fontsize=7)
        ax.set_xlabel("$BASE x [mm]")
        ax.set_ylabel("$BASE y [mm]")
        ax.set_title(f"z = {z:g} mm", fontsize=9)
    for ax in axes[zs.size:]:
        ax.set_visible(False)
    if image is not None:
        fig.colorbar(image, ax=list(axes[:zs.size]), label="cycle time [s]", shrink=0.9)
    yaw = g["yaw_deg"]
    yaw_note = (f"best over yaw {yaw[0]:g}…{yaw[-1]:g} deg" if len(yaw) > 1
                else f"yaw {yaw[0]:g} deg")
    from matplotlib.lines import Line2D

    def key(style, label):
        return Line2D([], [], ls="none", marker=style["marker"], markersize=9, label=label,
                      markerfacecolor="none", markeredgecolor=style["edgecolor"],
                      markeredgewidth=style["linewidths"])

    handles = [key(_OWN, "the job's own $BASE"), key(_BEST, "the best (grid or refined)"),
               Line2D([], [], ls="none", marker="x", color="0.35", label="no plan (reach, limits)")]
    if doc.get("screen"):
        handles.append(Line2D([], [], ls="none", marker=".", color="0.5",
                              label="pruned by the screen"))
    fig.legend(handles=handles, loc="outside lower center", ncol=4, fontsize=8, frameon=False)
    title = f"{doc['job']}: cycle time [s] by $BASE placement ({yaw_note})"
    fig.suptitle(title, fontsize=10)
    with atomic_path(path, suffix=".png") as tmp:  # constrained layout: no tight_layout here
        fig.savefig(tmp, format="png")
    plt.close(fig)
    return Path(path)


def _fmt(v: Any, spec: str) -> str:
    return "—" if v is None else format(v, spec)


def _img(path: Path) -> str:
    data = base64.b64encode(path.read_bytes()).decode("ascii")
    return f'<img alt="{html.escape(path.stem)}" src="data:image/png;base64,{data}">'


def _table(headers: list[str], rows: list[list[Any]]) -> str:
    out = ["<table>"]
    if any(headers):
        out.append("<tr>" + "".join(f"<th>{html.escape(h)}</th>" for h in headers) + "</tr>")
    out += ["<tr>" + "".join(f"<td>{html.escape(str(v))}</td>" for v in row) + "</tr>"
            for row in rows]
    out.append("</table>")
    return "\n".join(out)


def placement_section(doc: dict[str, Any], heatmap: Path | None = None) -> str:
    """The report's "Cell placement" section (HTML) of a study's ``place.json`` document."""
    best, own = doc.get("best"), doc.get("own")
    c = doc["counts"]
    lines = [
        ["placements planned", f"{c['planned']} ({c['feasible']} feasible; "
                               f"{c['pruned_by_screen']} pruned by the screen)"],
        ["own $BASE [mm, deg]", "—" if own is None else
         f"{own['x_mm']:g}, {own['y_mm']:g}, {own['z_mm']:g}; A {own['yaw_deg']:g}: cycle "
         f"{_fmt(own['cycle_time_s'], '.2f')} s" + ("" if own["feasible"] else
                                                    f" (no plan: {own['reason']})")],
        ["best $BASE [mm, deg]", "—" if best is None else
         f"{best['x_mm']:g}, {best['y_mm']:g}, {best['z_mm']:g}; A {best['yaw_deg']:g}: cycle "
         f"{best['cycle_time_s']:.2f} s"],
        ["own / best cycle", _fmt(doc.get("speedup_vs_own"), ".3f")],
        ["engine", f"{doc['engine']['scheduler']} ({doc['engine']['workers']} workers), "
                   f"{doc['wall_time_s']:.1f} s" + (" — interrupted: partial" if doc["interrupted"]
                                                    else "")],
    ]
    ok = sorted((r for r in doc["placements"] if r["feasible"]),
                key=lambda r: r["cycle_time_s"])[:TOP_ROWS]
    rows = [[r["stage"], f"{r['x_mm']:g}", f"{r['y_mm']:g}", f"{r['z_mm']:g}", f"{r['yaw_deg']:g}",
             f"{r['cycle_time_s']:.2f}", ", ".join(f"{k} {v}" for k, v in r["binding_counts"].items()),
             _fmt(r["worst_margin_N_per_m"], ".3g")] for r in ok]
    bad = [r for r in doc["placements"] if not r["feasible"]]
    reasons: dict[str, int] = {}
    for r in bad:
        reasons[r["error"] or "?"] = reasons.get(r["error"] or "?", 0) + 1
    parts = ['<h2 id="placement">Cell placement</h2>',
             '<p class="note">This plan is of the best placement of a placement study (place.json '
             'beside this folder): every placement is a full plan; the cycle times compare the '
             'same job at different $BASE.</p>',
             _table(["", ""], lines)]
    if heatmap is not None and Path(heatmap).exists():
        parts.append(_img(Path(heatmap)))
    parts += [f"<h3>The {len(ok)} fastest placements</h3>",
              _table(["stage", "x [mm]", "y [mm]", "z [mm]", "yaw [deg]", "cycle [s]",
                      "sections by binding", "worst margin [N/m]"], rows)]
    if bad:
        parts.append(f"<p>{len(bad)} placements have no plan: " + html.escape(
            ", ".join(f"{n} × {k}" for k, n in sorted(reasons.items()))) + ".</p>")
    return "\n".join(parts)
