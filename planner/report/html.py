"""The plan report: plots along the path and one self-contained HTML page (images embedded).

``report.html`` opens offline in any browser: its headline (robot, $BASE/$TOOL, tool, rpm,
material), the toolpath in 3-D (:mod:`planner.report.view3d`), the plots, the limits and the
section table (a_e/a_p, the joint a robot-bound section waits for; long tables folded). The PNGs
beside it are the same images:

* ``plan_along_path.png`` — feed (planned, ceiling, timed), force, deflection, γ, margin and joint
  speeds against the path length, with every section's binding constraint as a colour band;
* ``plan_characteristics.png`` — the stability characteristic (margin, γ, force and deflection
  against feed) of the three tightest cut sections, with their planned feed marked.
"""

from __future__ import annotations

import base64
import html
import os
from pathlib import Path
from typing import Any

import numpy as np

from planner._atomic import write_text_atomic
from planner._progress import MIN_TOTAL, bar
from planner.display import quantity
from planner.report.plots import new_figure, save_figure
from planner.sections import CUT

__all__ = [
    "BINDING_COLOURS",
    "headline",
    "plot_along_path",
    "plot_characteristics",
    "tightest_sections",
    "write_report",
]

#: One colour per binding constraint (bands in the plots, cells in the table).
BINDING_COLOURS = {
    "chatter": "#d62728", "force": "#ff7f0e", "deflection": "#9467bd", "power": "#8c564b",
    "robot": "#1f77b4", "feed_max": "#2ca02c", "feed_change": "#7f7f7f",
    "cam_feed": "#17becf", "rapid": "#bcbd22", "tool": "#e377c2",
}


#: Sections drawn each as its own colour band; with more, the bands are aggregated per bin.
BANDS_MAX = 150


def binding_shares(rows: list[dict[str, Any]], edges: np.ndarray) -> dict[str, np.ndarray]:
    """Per bin of ``edges`` [m], the share of its path length each binding holds (0..1)."""
    xs = np.array([[r["s_start_m"], r["s_end_m"]] for r in rows], float).reshape(-1)
    out: dict[str, np.ndarray] = {}
    width = np.diff(edges)
    width[width <= 0] = 1.0
    for b in sorted({r["binding"] for r in rows}):
        grow = np.array([[0.0, r["s_end_m"] - r["s_start_m"]] if r["binding"] == b else [0.0, 0.0]
                         for r in rows]).reshape(-1)
        cum = np.cumsum(grow)           # length held by b up to each section boundary
        out[b] = np.clip(np.diff(np.interp(edges, xs, cum)) / width, 0.0, 1.0)
    return out


def _bands(ax, rows: list[dict[str, Any]], edges: np.ndarray) -> None:
    """Every section's binding as a faint band; with more than :data:`BANDS_MAX` sections, each
    bin's dominant binding, runs of equal bins merged."""
    if len(rows) <= BANDS_MAX:
        for r in rows:
            ax.axvspan(r["s_start_m"], r["s_end_m"], color=BINDING_COLOURS[r["binding"]],
                       alpha=0.13, lw=0)
        return
    shares = binding_shares(rows, edges)
    names = list(shares)
    top = np.argmax(np.vstack([shares[n] for n in names]), axis=0)
    start = 0
    for i in range(1, top.size + 1):
        if i == top.size or top[i] != top[start]:
            ax.axvspan(edges[start], edges[i], color=BINDING_COLOURS[names[top[start]]], alpha=0.13,
                       lw=0)
            start = i


def _binding_strip(ax, rows: list[dict[str, Any]], edges: np.ndarray) -> list[str]:
    """What binds, as a strip above the panels: each section's colour when few, else per bin the
    share of its length each binding holds (stacked). Returns the bindings shown."""
    if len(rows) <= BANDS_MAX:
        for r in rows:
            ax.axvspan(r["s_start_m"], r["s_end_m"], color=BINDING_COLOURS[r["binding"]], lw=0)
        names = sorted({r["binding"] for r in rows})
        ax.set_ylabel("binds", rotation=0, ha="right", va="center")
    else:
        shares = binding_shares(rows, edges)
        names = list(shares)
        bottom = np.zeros(edges.size - 1)
        for n in names:
            ax.bar(edges[:-1], shares[n], width=np.diff(edges), bottom=bottom, align="edge",
                   color=BINDING_COLOURS[n], lw=0)
            bottom += shares[n]
        ax.set_ylabel("binds\n(share\nper bin)", rotation=0, ha="right", va="center", fontsize=8)
    ax.set_ylim(0, 1)
    ax.set_yticks([])
    return names


def plot_along_path(res, path: str | os.PathLike) -> Path:
    """Feed, force, deflection, γ, margin and joint speeds along the path, with what binds each
    section as a strip on top. A long path is drawn per bin (:data:`planner.report.plots.
    DENSE_SAMPLES`), many sections aggregated (:data:`BANDS_MAX`). Writes a PNG."""
    from matplotlib.patches import Patch

    from planner.report.plots import (
        DENSE_SAMPLES,
        bin_edges,
        draw_density,
        draw_series,
        legend_outside,
    )

    prep, lim = res.prep, res.limits
    s = prep.path.s
    idx = res.model.index
    ev = res.evaluation
    rows = res.section_rows
    edges = bin_edges(s)
    dense = s.size > DENSE_SAMPLES
    plt, fig = new_figure(figsize=(13.0, 14.0), dpi=100)
    axes = fig.subplots(7, 1, sharex=True, gridspec_kw={"height_ratios": [0.35, 1, 1, 1, 1, 1, 1]})
    names = _binding_strip(axes[0], rows, edges)
    axes[0].legend([Patch(color=BINDING_COLOURS[b]) for b in names], names, fontsize=7,
                   loc="upper left", bbox_to_anchor=(1.005, 1.0), borderaxespad=0.0,
                   title="binds", title_fontsize=7)
    for ax in axes[1:6]:
        _bands(ax, rows, edges)

    def series(v: np.ndarray) -> np.ndarray:
        out = np.full(s.size, np.nan)
        out[idx] = v
        return out

    ax = axes[1]
    ceiling = series(res.ceilings.feed)
    cutting = res.kinds != 2
    draw_series(ax, s, np.where(cutting, ceiling, np.nan) * 1e3, "0.55", "feed ceiling (every limit)",
                line="min", spread=None, edges=edges, lw=0.8)
    draw_series(ax, s, np.where(cutting, res.feed, np.nan) * 1e3, "k", "planned feed",
                edges=edges, lw=1.2, drawstyle="steps-pre")
    draw_series(ax, s, np.where(cutting, res.timing.speed, np.nan) * 1e3, "#1f77b4",
                "timed path speed (toppra)", spread=None, edges=edges, lw=0.9)
    ax.set_ylabel("feed [mm/s]")
    ax.set_ylim(0, min(lim.feed_max * 1e3 * 1.05, np.nanmax(res.feed[cutting]) * 1e3 * 1.3 + 1))
    legend_outside(ax)
    ax = axes[2]
    draw_series(ax, s, series(ev.force), "#ff7f0e", "resultant force", line="max", edges=edges, lw=1.0)
    ax.axhline(lim.force_max, color="#ff7f0e", ls="--", lw=1.0, label=f"limit {lim.force_max:g} N")
    ax.set_ylabel("force [N]")
    legend_outside(ax)
    ax = axes[3]
    draw_series(ax, s, series(ev.deflection_norm) * 1e3, "#9467bd", "|δ| at the TCP", line="max",
                edges=edges, lw=1.0)
    draw_series(ax, s, series(np.abs(ev.deflection_normal)) * 1e3, "#9467bd",
                "|δ · X_o| (normal to the wall)", line="max", spread=None, edges=edges, lw=0.8, ls=":")
    ax.axhline(lim.deflection_tol * 1e3, color="#9467bd", ls="--", lw=1.0,
               label=f"tolerance {lim.deflection_tol * 1e3:g} mm")
    ax.set_ylabel("deflection [mm]")
    legend_outside(ax)
    ax = axes[4]
    gamma_deg = np.degrees(series(ev.gamma))
    if dense:
        draw_density(ax, s, gamma_deg, edges, -90.0, 90.0,
                     "γ (force to K_max): samples per bin, darker more")
    else:
        ax.plot(s, gamma_deg, color="k", lw=1.0, label="γ (force to K_max)")
        legend_outside(ax)
    ax.set_ylabel("γ [deg]")
    ax.set_ylim(-95, 95)
    ax.set_yticks([-90, -45, 0, 45, 90])
    ax = axes[5]
    m = series(ev.margin)
    draw_series(ax, s, m, "#d62728", f"margin ({prep.job.model.process_model} model)", line="min",
                edges=edges, lw=1.0)
    ax.axhline(max(lim.margin_min, 0.0), color="#d62728", ls="--", lw=1.0, label="required")
    ax.set_yscale("symlog", linthresh=1e3)
    top = float(np.nanmax(m)) if np.any(np.isfinite(m)) else 1e3
    # 0 and the decades above the linear band only (the default puts 10² on top of 0)
    ax.set_yticks([0.0] + [10.0 ** k for k in range(3, max(4, int(np.ceil(np.log10(max(top, 1e3)))) + 1))])
    ax.set_ylabel("chatter margin [N/m]")
    legend_outside(ax)
    ax = axes[6]
    vmax = prep.robot.data.velocity
    pct = 100.0 * res.timing.joint_speed / vmax
    for j in range(pct.shape[1]):
        draw_series(ax, s, pct[:, j], f"C{j}", prep.kinematics.joint_names[j], line="max",
                    spread=None, edges=edges, lw=0.9)
    ax.axhline(100.0, color="k", ls="--", lw=1.0, label="limit")
    ax.set_ylabel("joint speed [% of limit]")
    ax.set_xlabel("path length s [m]")
    ax.set_yscale("log")
    ax.set_ylim(1e-3, 150)
    legend_outside(ax, ncol=1)
    how = (f"; {s.size:,} samples drawn per {np.diff(edges)[0] * 1e3:.0f} mm bin" if dense else "")
    return save_figure(plt, fig, f"{prep.job.job.name}: {res.method} plan, cycle {res.cycle_time:.1f} s, "
                       f"{len(rows):,} sections (colour: what binds){how}", path)


def tightest_sections(rows: list[dict[str, Any]], k: int = 3) -> list[dict[str, Any]]:
    """The ``k`` cut sections with the lowest feed ceiling."""
    cut = [r for r in rows if r["kind"] == "cut" and r.get("characteristic")]
    return sorted(cut, key=lambda r: r["ceiling_min_mm_s"])[:k]


def _first_broken(ch: dict[str, Any], lim, f: np.ndarray, bad: np.ndarray) -> float:
    """The feed [mm/s] where the first limit breaks: interpolated between the last good and the
    first bad feed of the grid (force, deflection or margin crossing its limit), else the first
    bad feed."""
    from planner.report.plots import crossings

    if not bad.size:
        return float("nan")
    hi = f[bad[0]]
    lo = f[bad[0] - 1] if bad[0] > 0 else hi
    found = [hi]
    for v, limit in ((ch["force_N"], lim.force_max), (ch["deflection_mm"], lim.deflection_tol * 1e3),
                     (ch["margin_N_per_m"], None)):
        arr = np.asarray(v, float)
        y = arr - limit if limit is not None else max(lim.margin_min, 0.0) - arr
        if not np.all(np.isfinite(y)):
            continue
        x = crossings(f, y)
        found += [float(c) for c in x if lo <= c <= hi]
    return min(found)


def plot_characteristics(res, path: str | os.PathLike) -> Path:
    """Stability characteristics of the three tightest sections. Writes a PNG."""
    rows = tightest_sections(res.section_rows)
    lim = res.limits
    ncol = max(1, len(rows))
    plt, fig = new_figure(figsize=(4.0 * ncol, 10.0), dpi=100)
    axes = fig.subplots(4, ncol, squeeze=False, sharex="col")
    for j, r in enumerate(rows):
        ch = r["characteristic"]
        f = np.asarray(ch["feeds_mm_s"])
        bad = np.flatnonzero(~np.asarray(ch["ok"], bool))
        broken_at = _first_broken(ch, lim, f, bad)
        panels = [
            (np.asarray(ch["margin_N_per_m"]), "margin [N/m]", "#d62728", max(lim.margin_min, 0.0)),
            (np.asarray(ch["gamma_deg"]), "γ [deg]", "k", None),
            (np.asarray(ch["force_N"]), "force [N]", "#ff7f0e", lim.force_max),
            (np.asarray(ch["deflection_mm"]), "|δ| [mm]", "#9467bd", lim.deflection_tol * 1e3),
        ]
        for i, (v, label, colour, limit) in enumerate(panels):
            ax = axes[i, j]
            ax.plot(f, v, color=colour)
            if limit is not None and (i != 0 or limit > 0):
                ax.axhline(limit, color=colour, ls="--", lw=0.8)
            ax.axvline(r["feed_mm_s"], color="#1f77b4", lw=1.2)
            if bad.size:
                ax.axvspan(broken_at, f[-1], color="#d62728", alpha=0.07, lw=0)
            ax.set_xscale("log")
            ax.set_ylabel(label)
            ax.ticklabel_format(axis="y", style="sci", scilimits=(-3, 4))
        axes[0, j].set_title(f"section {r['index']} (line {r['line_start']}), binds "
                             f"{r['binding']}", fontsize=9)
        axes[-1, j].set_xlabel("feed [mm/s]")
    return save_figure(plt, fig, "Stability characteristic of the three tightest sections (blue: planned "
                 "feed; red shade: a limit broken)", path)


def _img(path: Path) -> str:
    data = base64.b64encode(path.read_bytes()).decode("ascii")
    return f'<img alt="{html.escape(path.stem)}" src="data:image/png;base64,{data}">'


def _table(headers: list[str], rows: list[list[Any]], colour_col: int | None = None,
           cls: str = "", more_after: int | None = None) -> str:
    """An HTML table; ``more_after``: the rows after the first so many in a ``tbody.more`` (hidden
    until the page's "show all" switch is on)."""
    out = [f'<table class="{cls}">' if cls else "<table>"]
    if any(headers):
        out.append("<tr>" + "".join(f"<th>{html.escape(h)}</th>" for h in headers) + "</tr>")
    for k, row in enumerate(rows):
        if more_after is not None and k == more_after:
            out.append('<tbody class="more">')
        cells = []
        for i, v in enumerate(row):
            style = ""
            if i == colour_col and v in BINDING_COLOURS:
                style = f' style="background:{BINDING_COLOURS[v]}33"'
            cells.append(f"<td{style}>{html.escape(str(v))}</td>")
        out.append("<tr>" + "".join(cells) + "</tr>")
    if more_after is not None and len(rows) > more_after:
        out.append("</tbody>")
    out.append("</table>")
    return "\n".join(out)


#: What a limit the plan does not hold (null in plan.json's ``constraints``) is shown as.
_NOT_LIMITED = "not limited"


def _limit_rows(lim, safety_factor: float) -> list[list[str]]:
    """The limits table: every value to 6 significant digits, a missing limit in words."""
    return [[k, quantity(v, "g", missing=_NOT_LIMITED) if k != "safety_factor"
             else quantity(v, "g")] for k, v in lim.as_json(safety_factor).items()]


def _section_row(r: dict[str, Any], engagement: dict[int, tuple[float, float]],
                 joints: dict[int, str]) -> list[str]:
    """One row of the section table (``r`` a plan.json section: ``index`` numbers from 1);
    ``engagement``: its largest a_e, a_p [m]; ``joints``: what holds a robot-bound section back.
    The columns up to ``lines`` are those of plan.json's order; the report's own come after."""
    lines = (f"{r['line_start']}–{r['line_end']}" if r.get("line_start") is not None
             else quantity(None))
    ae, ap = engagement.get(int(r["index"]), (None, None))
    return [str(r["index"]), r["kind"], quantity(r["s_start_m"], ".4f"),
            quantity(r["s_end_m"], ".4f"), quantity(r["feed_mm_s"], ".3f"), r["binding"],
            quantity(r["force_max_N"], ".1f"), quantity(r["deflection_max_mm"], ".3f"),
            quantity(r["margin_N_per_m"], ".3g"), quantity(r["gamma_deg"], ".2f"),
            quantity(r["time_s"], ".2f"), lines,
            quantity(None if ae is None else ae * 1e3, ".3f"),
            quantity(None if ap is None else ap * 1e3, ".3f"),
            joints.get(int(r["index"]), ""), r.get("note") or ""]


#: Section rows shown; the rest are one click away (a long job has thousands).
SECTION_ROWS_OPEN = 50
_SECTION_HEADERS = ["#", "kind", "s start [m]", "s end [m]", "feed [mm/s]", "binds", "force max [N]",
                    "|δ| max [mm]", "margin min [N/m]", "γ [deg]", "time [s]", "lines",
                    "a_e max [mm]", "a_p max [mm]", "robot limit (nearest, % of it)", "note"]


def _section_tables(res) -> str:
    """The section table, one table: the first :data:`SECTION_ROWS_OPEN` rows shown, the rest
    behind a "show all" switch (CSS only, no script); before it, the robot-bound sections with
    what holds each back."""
    from planner.report.tables import limiting_joints, section_engagement

    rows = res.section_rows
    eng, joints = section_engagement(res), limiting_joints(res)
    body = [_section_row(r, eng, joints) for r in rows]
    out = []
    robot = [r for r in rows if r["robot_limited"]]
    if robot:
        items = "".join(
            f"<li>section {r['index']} ({r['kind']}, lines {r['line_start']}–{r['line_end']}): "
            f"{html.escape(joints.get(int(r['index']), '—'))}</li>" for r in robot)
        out.append(f'<details><summary>{len(robot)} robot-bound section'
                   f'{"s" if len(robot) != 1 else ""}: what holds each back, nearest its limit (a '
                   "joint's speed or acceleration, or the path acceleration)</summary>"
                   f'<ul class="robot">{items}</ul></details>')
    if len(body) <= SECTION_ROWS_OPEN:
        out.append('<div class="wide">' + _table(_SECTION_HEADERS, body, colour_col=5,
                                                 cls="sections") + "</div>")
        return "\n".join(out)
    out.append(f'<input type="checkbox" id="all-sections" class="toggle"><label for="all-sections">'
               f"show all {len(body):,} sections (the first {SECTION_ROWS_OPEN} shown; every one "
               "in plan.json)</label>")
    out.append('<div class="wide">' + _table(_SECTION_HEADERS, body, colour_col=5, cls="sections",
                                             more_after=SECTION_ROWS_OPEN) + "</div>")
    return "\n".join(out)


def _frame(xyz_mm, abc_deg) -> str:
    """A KUKA frame as people read it: ``X … Y … Z … mm, A … B … C … deg``."""
    x, y, z = (float(v) for v in xyz_mm)
    a, b, c = (float(v) for v in abc_deg)
    return f"X {x:g} Y {y:g} Z {z:g} mm, A {a:g} B {b:g} C {c:g} deg"


def headline(res) -> dict[str, str]:
    """What was cut with what: rpm, tool, material, robot, $BASE and $TOOL (the report's first
    table)."""
    from planner.plan import limit_confidence_text

    prep = res.prep
    job, tool = prep.job, prep.tool
    out = {
        "robot": prep.robot.data.name,
        "$BASE (part in the robot base)": _frame(job.cell.base_mm, job.cell.base_abc_deg),
        "$TOOL (tool tip in the flange)": _frame(job.cell.tcp_mm, job.cell.tcp_abc_deg),
        "tool": f"{tool.name}: Ø {2e3 * tool.radius:g} mm, {tool.flutes} flute"
                f"{'s' if tool.flutes != 1 else ''}",
        "spindle": f"{job.spindle.rpm:g} rpm",
        "material": job.material,
        "toolpath": ", ".join(Path(p).name for p in prep.path.files),
    }
    conf = limit_confidence_text(res)
    if conf is not None:
        out["calibration uncertainty"] = conf
    return out


_CSS = """body{font-family:system-ui,sans-serif;margin:1.5em;max-width:1320px;color:#222}
h1{font-size:1.4em}h2{font-size:1.1em;margin-top:1.6em}table{border-collapse:collapse;font-size:.85em}
td,th{border:1px solid #ccc;padding:2px 6px;text-align:right}th{background:#f3f3f3}
img{max-width:100%;border:1px solid #ddd}.note{color:#555;font-size:.9em}
.warn{background:#fff4d6;border:1px solid #e0b040;padding:.4em .8em;margin:.8em 0}
.warn ul{margin:.3em 0;padding-left:1.2em}.warn li{font-size:.9em}
table.sections td{white-space:nowrap}
table.sections td:last-child{text-align:left;white-space:normal;min-width:14em;font-size:.9em}
.wide{overflow-x:auto;max-width:100%}
table.head td{text-align:left}table.head td:first-child{font-weight:600}
details{margin:.6em 0}summary,label{cursor:pointer;color:#1f4f8f}ul.robot{columns:2;font-size:.85em}
.toggle{margin:.6em .3em .6em 0}.toggle:not(:checked)~div table tbody.more{display:none}
.view3d{border:1px solid #ddd;margin:.4em 0}"""


def _warnings_box(res) -> str:
    """The headline box of what reading the toolpaths warned about (empty when nothing)."""
    from robot_io.diagnostics import group_warnings

    groups = group_warnings(res.prep.toolpaths)
    out = []
    if groups:
        total = sum(g.count for g in groups)
        items = "".join(
            f"<li><b>{html.escape(g.kind)}</b> ×{g.count} — first at "
            f"<code>{html.escape(str(g.first))}</code>: {html.escape(g.message)}</li>"
            for g in groups)
        out.append(f'<div class="warn"><b>Reading the toolpaths warned {total} time'
                   f'{"s" if total != 1 else ""} ({len(groups)} kind'
                   f'{"s" if len(groups) != 1 else ""}); the plan is of the path as read.</b>'
                   f"<ul>{items}</ul></div>")
    if res.warnings:
        items = "".join(f"<li><b>{html.escape(w.kind)}</b>: {html.escape(w.message)}</li>"
                        for w in res.warnings)
        out.append(f'<div class="warn"><b>The plan holds, but know this:</b><ul>{items}</ul>'
                   "</div>")
    return "\n".join(out)


def _posture_section(res) -> str:
    """The rotation about the tool axis chosen along the path, per cut section, and what it gained
    (the posture search's own estimate of the cut time); empty without a path posture."""
    posture = getattr(res.prep, "posture", None)
    if posture is None or posture.fallback:
        return ""
    from planner.posture import posture_by_section

    cut = [(n, sec) for n, sec in enumerate(res.sections, start=1) if sec.kind == CUT]
    rows = [[n, f"{r['offset_deg_mean']:.1f}", f"{r['offset_deg_min']:.1f} … {r['offset_deg_max']:.1f}",
             f"{r['time_today_s']:.2f}", f"{r['time_chosen_s']:.2f}", f"{100 * r['gain']:.1f} %"]
            for (n, _), r in zip(cut, posture_by_section(posture, [sec for _, sec in cut]), strict=True)]
    return (f"<h2>Tool posture along the path</h2>\n<p class=\"note\">The rotation about the tool "
            f"axis against the first-sample choice, per cut section (rate ≤ "
            f"{posture.rate_bound * 180 / np.pi * 1e-3:.2f}°/mm); cut time by the posture search's "
            f"estimate, today → chosen: {posture.time_today:.1f} → {posture.time_chosen:.1f} s "
            f"({100 * posture.gain:.1f} % less).</p>\n"
            + _table(["section", "rotation mean [deg]", "range [deg]", "cut time today [s]",
                      "chosen [s]", "gain"], rows, more_after=50 if len(rows) > 60 else None))


def write_report(res, folder: str | os.PathLike, sections: tuple[str, ...] = (),
                 progress: bool = False) -> dict[str, Path]:
    """Write the PNGs and ``report.html`` into ``folder``; return the paths by name. ``sections``:
    more HTML sections at the end (a placement study's, :mod:`planner.report.placement`).
    ``progress``: a bar on stderr over the three files (seconds on a path of ``MIN_TOTAL`` samples
    or more, :mod:`planner._progress`), on a terminal only."""
    with bar(3, "report", progress and len(res.prep.path) >= MIN_TOTAL, unit="file",
             min_total=1) as pbar:
        return _write_report(res, Path(folder), sections, pbar)


def _write_report(res, out: Path, sections: tuple[str, ...], pbar) -> dict[str, Path]:
    pbar.set_postfix_str("plan_along_path.png")
    along = plot_along_path(res, out / "plan_along_path.png")
    pbar.update()
    pbar.set_postfix_str("plan_characteristics.png")
    chars = plot_characteristics(res, out / "plan_characteristics.png")
    pbar.update()
    pbar.set_postfix_str("report.html")
    prep, lim = res.prep, res.limits
    rows = res.section_rows
    summ = {"method": res.method, "cycle time [s]": f"{res.cycle_time:.2f}",
            "process time Σ L/f [s]": f"{res.process_time:.2f}",
            "cutting time [s]": (f"{res.cut_time:.2f}; no plan with sections ≥ "
                                 f"{lim.section_length_min * 1e3:g} mm can cut in less than "
                                 f"{quantity(res.cut_time_bound, '.2f')}"),
            **({"feed profile": f"a speed per sample; the cycle is "
                                f"{100 * (res.cycle_time / res.profile.bound_cycle_time - 1):.2f} % "
                                f"above the pointwise bound "
                                f"{res.profile.bound_cycle_time:.2f} s (no feed plan is faster)"}
               if getattr(res, "profile", None) is not None else {}),
            "sections (cut)": f"{len(rows)} ({sum(r['kind'] == 'cut' for r in rows)})",
            "robot-limited sections": sum(r["robot_limited"] for r in rows),
            "solver": res.solver.describe(),
            "model": f"{prep.job.model.process_model} process model, {prep.job.model.mass_model} "
                     f"mass, {prep.job.model.chatter_criterion} criterion, CCT "
                     f"{'on' if prep.job.model.cct else 'off'}"}
    ev = res.evaluation
    if ev.force.size:
        summ.update({"worst force [N]": f"{ev.force.max():.1f} (limit {lim.force_max:g})",
                     "worst |δ| [mm]": f"{ev.deflection_norm.max() * 1e3:.3f} (tolerance "
                                       f"{lim.deflection_tol * 1e3:g})",
                     "worst |δ·X_o| [mm]": f"{np.abs(ev.deflection_normal).max() * 1e3:.3f}",
                     "lowest margin [N/m]": f"{ev.margin.min():.3g}"})
        if lim.compensate_deflection:
            summ["worst held deflection [mm]"] = (
                f"{ev.deflection_held.max() * 1e3:.3f} (compensated export: "
                f"{lim.deflection_model_uncertainty:g}·|δ| + the change of δ along a LIN, against "
                f"the tolerance {lim.deflection_tol * 1e3:g})")
    counts: dict[str, int] = {}
    for r in rows:
        counts[r["binding"]] = counts.get(r["binding"], 0) + 1
    from planner.report.view3d import plotlyjs_script, view3d_html

    view = view3d_html(res, BINDING_COLOURS)
    doc = f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>cctmill plan: {html.escape(prep.job.job.name)}</title>
<style>{_CSS}</style></head><body>
<h1>cctmill plan — {html.escape(prep.job.job.name)}</h1>
<p class="note">The feed along the path is the fastest its samples allow under every limit (a
feed profile, in sections whose feed scales it, or one feed per section); the colour says what
stops each section going faster. Files: plan.json (sections), samples.npz (every sample).</p>
{_warnings_box(res)}
{_table(["", ""], [[k, v] for k, v in headline(res).items()], cls="head")}
{_table(["", ""], [[k, v] for k, v in summ.items()])}
<h2>What binds</h2>
{_table(["binding", "sections"], [[b, n] for b, n in sorted(counts.items())], colour_col=0)}
<h2>The toolpath in 3-D</h2>
<p class="note">The part frame ($BASE), mm. Drag to turn, scroll to zoom; the buttons colour the
cut by the planned feed, the binding constraint, the deflection or the chatter margin; hover a point
for its sample, line, feed, binding and a_e/a_p.</p>
{view}
{_posture_section(res)}
<h2>Along the path</h2>
{_img(along)}
<h2>Stability characteristic of the three tightest sections</h2>
{_img(chars)}
<h2>Limits</h2>
{_table(["limit", "value"], _limit_rows(lim, res.safety_factor))}
<h2>Sections</h2>
<p class="note">Sections are numbered from 1 in path order, as in plan.json (<code>index</code>),
the KRL program (<code>;FOLD section N</code>, <code>NAME_F00N</code>) and the supervisor's log.</p>
{_section_tables(res)}
{"".join(sections)}
{plotlyjs_script()}
</body></html>
"""
    report = write_text_atomic(out / "report.html", doc)
    pbar.update()
    return {"report": report, "plot_along_path": along, "plot_characteristics": chars}
