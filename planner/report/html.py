"""The plan report: plots along the path and one self-contained HTML page (images embedded).

``report.html`` opens offline in any browser; the PNGs beside it are the same images:

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

from models.errors import CctmillError
from planner._atomic import atomic_path, write_text_atomic
from planner.display import quantity
from planner.report.plots import new_figure, save_figure

__all__ = [
    "BINDING_COLOURS",
    "BROWSERS",
    "ReportRenderError",
    "find_browser",
    "plot_along_path",
    "plot_characteristics",
    "render_screenshot",
    "tightest_sections",
    "write_report",
]

#: One colour per binding constraint (bands in the plots, cells in the table).
BINDING_COLOURS = {
    "chatter": "#d62728", "force": "#ff7f0e", "deflection": "#9467bd", "power": "#8c564b",
    "robot": "#1f77b4", "feed_max": "#2ca02c", "feed_change": "#7f7f7f",
    "cam_feed": "#17becf", "rapid": "#bcbd22", "tool": "#e377c2",
}


class ReportRenderError(CctmillError):
    """The report could not be rendered to a screenshot (no browser, or it failed)."""


def _bands(ax, rows: list[dict[str, Any]]) -> None:
    for r in rows:
        ax.axvspan(r["s_start_m"], r["s_end_m"], color=BINDING_COLOURS[r["binding"]], alpha=0.13,
                   lw=0)


def plot_along_path(res, path: str | os.PathLike) -> Path:
    """Feed, force, deflection, γ, margin and joint speeds along the path. Writes a PNG."""
    prep, lim = res.prep, res.limits
    s = prep.path.s
    idx = res.model.index
    ev = res.evaluation
    rows = res.section_rows
    plt, fig = new_figure(figsize=(11.0, 13.0), dpi=100)
    axes = fig.subplots(6, 1, sharex=True)
    ax = axes[0]
    _bands(ax, rows)
    ceiling = np.full(s.size, np.nan)
    ceiling[idx] = res.ceilings.feed
    cutting = res.kinds != 2
    ax.plot(s, np.where(cutting, ceiling, np.nan) * 1e3, color="0.55", lw=0.8,
            label="feed ceiling (every limit)")
    ax.plot(s, np.where(cutting, res.feed, np.nan) * 1e3, color="k", lw=1.4, drawstyle="steps-pre",
            label="planned section feed")
    ax.plot(s, np.where(cutting, res.timing.speed, np.nan) * 1e3, color="#1f77b4", lw=1.0,
            label="timed path speed (toppra)")
    ax.set_ylabel("feed [mm/s]")
    ax.set_ylim(0, min(lim.feed_max * 1e3 * 1.05, np.nanmax(res.feed[cutting]) * 1e3 * 1.3 + 1))
    handles, labels = ax.get_legend_handles_labels()
    from matplotlib.patches import Patch

    present = sorted({r["binding"] for r in rows if r["kind"] != "rapid"})
    handles += [Patch(color=BINDING_COLOURS[b], alpha=0.35) for b in present]
    labels += [f"binds: {b}" for b in present]
    ax.legend(handles, labels, fontsize=7, ncol=3, loc="upper right")

    def series(v: np.ndarray) -> np.ndarray:
        out = np.full(s.size, np.nan)
        out[idx] = v
        return out

    ax = axes[1]
    _bands(ax, rows)
    ax.plot(s, series(ev.force), color="#ff7f0e", lw=1.0, label="resultant force")
    ax.axhline(lim.force_max, color="#ff7f0e", ls="--", lw=1.0, label=f"limit {lim.force_max:g} N")
    ax.set_ylabel("force [N]")
    ax.legend(fontsize=7, loc="upper right")
    ax = axes[2]
    _bands(ax, rows)
    ax.plot(s, series(ev.deflection_norm) * 1e3, color="#9467bd", lw=1.0, label="|δ| at the TCP")
    ax.plot(s, series(np.abs(ev.deflection_normal)) * 1e3, color="#9467bd", lw=0.8, ls=":",
            label="|δ · X_o| (normal to the wall)")
    ax.axhline(lim.deflection_tol * 1e3, color="#9467bd", ls="--", lw=1.0,
               label=f"tolerance {lim.deflection_tol * 1e3:g} mm")
    ax.set_ylabel("deflection [mm]")
    ax.legend(fontsize=7, loc="upper right")
    ax = axes[3]
    _bands(ax, rows)
    ax.plot(s, np.degrees(series(ev.gamma)), color="k", lw=1.0)
    ax.set_ylabel("γ [deg]")
    ax = axes[4]
    _bands(ax, rows)
    m = series(ev.margin)
    ax.plot(s, m, color="#d62728", lw=1.0, label=f"margin ({prep.job.model.process_model} model)")
    ax.axhline(max(lim.margin_min, 0.0), color="#d62728", ls="--", lw=1.0, label="required")
    ax.set_yscale("symlog", linthresh=1e3)
    top = float(np.nanmax(m)) if np.any(np.isfinite(m)) else 1e3
    # 0 and the decades above the linear band only (the default puts 10² on top of 0)
    ax.set_yticks([0.0] + [10.0 ** k for k in range(3, max(4, int(np.ceil(np.log10(max(top, 1e3)))) + 1))])
    ax.set_ylabel("chatter margin [N/m]")
    ax.legend(fontsize=7, loc="upper right")
    ax = axes[5]
    vmax = prep.robot.data.velocity
    pct = 100.0 * res.timing.joint_speed / vmax
    for j in range(pct.shape[1]):
        ax.plot(s, pct[:, j], lw=0.9, label=prep.kinematics.joint_names[j])
    ax.axhline(100.0, color="k", ls="--", lw=1.0)
    ax.set_ylabel("joint speed [% of limit]")
    ax.set_xlabel("path length s [m]")
    ax.set_yscale("log")
    ax.set_ylim(1e-3, 150)
    ax.legend(fontsize=7, ncol=6, loc="lower right")
    return save_figure(plt, fig, f"{prep.job.job.name}: {res.method} plan, cycle {res.cycle_time:.1f} s "
                 "(colour bands: what binds each section)", path)


def tightest_sections(rows: list[dict[str, Any]], k: int = 3) -> list[dict[str, Any]]:
    """The ``k`` cut sections with the lowest feed ceiling."""
    cut = [r for r in rows if r["kind"] == "cut" and r.get("characteristic")]
    return sorted(cut, key=lambda r: r["ceiling_min_mm_s"])[:k]


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
                ax.axvspan(f[bad[0]], f[-1], color="#d62728", alpha=0.07, lw=0)
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


def _table(headers: list[str], rows: list[list[Any]], colour_col: int | None = None) -> str:
    out = ["<table>"]
    if any(headers):
        out.append("<tr>" + "".join(f"<th>{html.escape(h)}</th>" for h in headers) + "</tr>")
    for row in rows:
        cells = []
        for i, v in enumerate(row):
            style = ""
            if i == colour_col and v in BINDING_COLOURS:
                style = f' style="background:{BINDING_COLOURS[v]}33"'
            cells.append(f"<td{style}>{html.escape(str(v))}</td>")
        out.append("<tr>" + "".join(cells) + "</tr>")
    out.append("</table>")
    return "\n".join(out)


#: What a limit the plan does not hold (null in plan.json's ``constraints``) is shown as.
_NOT_LIMITED = "not limited"


def _limit_rows(lim, safety_factor: float) -> list[list[str]]:
    """The limits table: every value to 6 significant digits, a missing limit in words."""
    return [[k, quantity(v, "g", missing=_NOT_LIMITED) if k != "safety_factor"
             else quantity(v, "g")] for k, v in lim.as_json(safety_factor).items()]


def _section_row(r: dict[str, Any]) -> list[str]:
    """One row of the section table (``r`` a plan.json section: ``index`` numbers from 1)."""
    lines = (f"{r['line_start']}–{r['line_end']}" if r.get("line_start") is not None
             else quantity(None))
    return [str(r["index"]), r["kind"], quantity(r["s_start_m"], ".4f"),
            quantity(r["s_end_m"], ".4f"), quantity(r["feed_mm_s"], ".3f"), r["binding"],
            quantity(r["force_max_N"], ".1f"), quantity(r["deflection_max_mm"], ".3f"),
            quantity(r["margin_N_per_m"], ".3g"), quantity(r["gamma_deg"], ".2f"),
            quantity(r["time_s"], ".2f"), lines, r.get("note") or ""]


_CSS = """body{font-family:system-ui,sans-serif;margin:1.5em;max-width:1200px;color:#222}
h1{font-size:1.4em}h2{font-size:1.1em;margin-top:1.6em}table{border-collapse:collapse;font-size:.85em}
td,th{border:1px solid #ccc;padding:2px 6px;text-align:right}th{background:#f3f3f3}
img{max-width:100%;border:1px solid #ddd}.note{color:#555;font-size:.9em}
.warn{background:#fff4d6;border:1px solid #e0b040;padding:.4em .8em;margin:.8em 0}
.warn ul{margin:.3em 0;padding-left:1.2em}.warn li{font-size:.9em}"""


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


def write_report(res, folder: str | os.PathLike, sections: tuple[str, ...] = ()) -> dict[str, Path]:
    """Write the PNGs and ``report.html`` into ``folder``; return the paths by name. ``sections``:
    more HTML sections at the end (a placement study's, :mod:`planner.report.placement`)."""
    out = Path(folder)
    along = plot_along_path(res, out / "plan_along_path.png")
    chars = plot_characteristics(res, out / "plan_characteristics.png")
    prep, lim = res.prep, res.limits
    rows = res.section_rows
    summ = {"method": res.method, "cycle time [s]": f"{res.cycle_time:.2f}",
            "process time Σ L/f [s]": f"{res.process_time:.2f}",
            "cutting time [s]": (f"{res.cut_time:.2f}; no plan with sections ≥ "
                                 f"{lim.section_length_min * 1e3:g} mm can cut in less than "
                                 f"{quantity(res.cut_time_bound, '.2f')}"),
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
    counts: dict[str, int] = {}
    for r in rows:
        counts[r["binding"]] = counts.get(r["binding"], 0) + 1
    sec_rows = [_section_row(r) for r in rows]
    doc = f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>cctmill plan: {html.escape(prep.job.job.name)}</title>
<style>{_CSS}</style></head><body>
<h1>cctmill plan — {html.escape(prep.job.job.name)}</h1>
<p class="note">Every section's feed is the fastest its samples allow under every limit; the
colour says what stops it going faster. Files: plan.json (sections), samples.npz (every sample).</p>
{_warnings_box(res)}
{_table(["", ""], [[k, v] for k, v in summ.items()])}
<h2>What binds</h2>
{_table(["binding", "sections"], [[b, n] for b, n in sorted(counts.items())], colour_col=0)}
<h2>Along the path</h2>
{_img(along)}
<h2>Stability characteristic of the three tightest sections</h2>
{_img(chars)}
<h2>Limits</h2>
{_table(["limit", "value"], _limit_rows(lim, res.safety_factor))}
<h2>Sections</h2>
<p class="note">Sections are numbered from 1 in path order, as in plan.json (<code>index</code>),
the KRL program (<code>;FOLD section N</code>, <code>NAME_F00N</code>) and the supervisor's log.</p>
{_table(["#", "kind", "s start [m]", "s end [m]", "feed [mm/s]", "binds", "force max [N]",
         "|δ| max [mm]", "margin min [N/m]", "γ [deg]", "time [s]", "lines", "note"],
        sec_rows, colour_col=5)}
{"".join(sections)}
</body></html>
"""
    report = write_text_atomic(out / "report.html", doc)
    return {"report": report, "plot_along_path": along, "plot_characteristics": chars}


#: Browsers tried for the headless screenshot, in order (Debian's package is ``chromium``).
BROWSERS = ("chromium", "chromium-browser", "google-chrome")
#: Flags for a headless, offline, throw-away browser (no network, no profile, no GPU).
_BROWSER_FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update", "--disable-sync",
                  "--hide-scrollbars", "--force-device-scale-factor=1")
#: Longest a screenshot may take [s].
SCREENSHOT_TIMEOUT = 120.0


def find_browser() -> str | None:
    """Path of a headless-capable Chromium, or None."""
    import shutil

    for name in BROWSERS:
        exe = shutil.which(name)
        if exe:
            return exe
    return None


def render_screenshot(html_path: str | os.PathLike, png_path: str | os.PathLike,
                      width: int = 1240, height: int = 3600) -> Path:
    """Render ``html_path`` in headless Chromium and save a PNG of the page (atomically).

    Raises:
        ReportRenderError: no browser, or the browser failed or wrote nothing.
    """
    import subprocess
    import tempfile

    exe = find_browser()
    if exe is None:
        raise ReportRenderError("no Chromium found to render the report (apt-get install chromium)")
    page = Path(html_path).resolve().as_uri()
    with tempfile.TemporaryDirectory(prefix="cctmill-browser-") as profile, \
            atomic_path(png_path, suffix=".png") as tmp:
        cmd = [exe, *_BROWSER_FLAGS, f"--user-data-dir={profile}", f"--window-size={width},{height}",
               f"--screenshot={tmp}", page]
        try:
            proc = subprocess.run(cmd, capture_output=True, text=True, timeout=SCREENSHOT_TIMEOUT,
                                  check=False)
        except (OSError, subprocess.TimeoutExpired) as e:
            raise ReportRenderError(f"{exe} could not render {html_path}: {e}") from e
        if not tmp.exists() or tmp.stat().st_size == 0:
            raise ReportRenderError(f"{exe} wrote no screenshot (exit {proc.returncode}): "
                                    f"{proc.stderr.strip()[-300:]}")
    return Path(png_path)
