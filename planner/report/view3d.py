"""The toolpath in 3-D for the report: plotly, offline, in the page itself.

The path is drawn in the part frame (``$BASE``, mm) with the stock and the part frame's axes; the
cut samples are coloured by the planned feed and, switched by the buttons above the view, by the
section's binding constraint, the deflection and the chatter margin; air moves and rapids are a thin
grey line. Hovering a point shows its sample, source line, feed, binding and a_e/a_p.

The page stays one file that opens offline: plotly.js (≈ 4.8 MB) is inlined *once*, gzip-compressed
and base64-encoded (≈ 2 MB), and unpacked by the browser's own ``DecompressionStream`` (Chromium
80, Firefox 113, Safari 16.4) before the view is drawn. A long path is decimated to
:data:`VIEW_MAX_POINTS` points, every section's first and last sample kept.
"""

from __future__ import annotations

import base64
import functools
import gzip
import html
import json
from typing import Any

import numpy as np

from planner.sections import CUT, RAPID

__all__ = ["COLOUR_MODES", "VIEW_MAX_POINTS", "plotlyjs_script", "toolpath_figure", "view3d_html",
           "view_samples"]

#: Most path points drawn (a 10,000-sample job is decimated to about this; each section's ends
#: are kept beyond it). Keeps the page small and the WebGL view fluid.
VIEW_MAX_POINTS = 4000
#: Decimals of a coordinate in mm in the page (0.001 mm: below any chord tolerance).
_MM_DECIMALS = 3
#: The colour modes, in the order of the buttons.
COLOUR_MODES = ("feed", "binding", "deflection", "margin")
#: Colour scales given as stops (plotly.js knows only a few by name): deflection from blue (none)
#: to red (at the tolerance); margin from red (the least) to green (the most).
_DEFLECTION_SCALE = [[0.0, "#2c7bb6"], [0.5, "#fdae61"], [1.0, "#d7191c"]]
_MARGIN_SCALE = [[0.0, "#d62728"], [0.5, "#f2c744"], [1.0, "#2ca02c"]]
#: Delay from the page's load to unpacking plotly.js [ms]: time for the first paint to happen.
_PAINT_FIRST_MS = 50
#: id of the <script> holding the packed plotly.js.
_PACKED_ID = "cctmill-plotlyjs-gz"


def view_samples(n: int, sections: list[dict[str, Any]], max_points: int = VIEW_MAX_POINTS) -> np.ndarray:
    """Indices of the samples drawn: every ``k``-th so that about ``max_points`` remain, plus the
    first and last sample of every section (so that every section boundary is where it is)."""
    if n <= max_points:
        return np.arange(n)
    step = int(np.ceil(n / max_points))
    keep = np.zeros(n, bool)
    keep[::step] = True
    keep[-1] = True
    for r in sections:
        keep[int(r["sample_start"])] = True
        keep[max(int(r["sample_stop"]) - 1, 0)] = True
    return np.flatnonzero(keep)


def _binding_colourscale(names: list[str], colours: dict[str, str]) -> list[list[Any]]:
    """A stepped colourscale: code ``i`` of ``names`` takes the colour of ``names[i]``."""
    k = max(len(names), 1)
    scale: list[list[Any]] = []
    for i, name in enumerate(names):
        c = colours.get(name, "#444444")
        scale += [[i / k, c], [(i + 1) / k, c]]
    return scale or [[0.0, "#444444"], [1.0, "#444444"]]


def _box_edges(x0: float, y0: float, x1: float, y1: float, z0: float, z1: float):
    """The 12 edges of a box as one polyline with gaps (None)."""
    return _outline_edges([(x0, y0), (x1, y0), (x1, y1), (x0, y1)], z0, z1)


def _outline_edges(outline: list[tuple[float, float]], z0: float, z1: float):
    """A prism over a closed outline, from z0 to z1: both outlines and the vertical edges, as one
    polyline with gaps (None)."""
    xs: list[float | None] = []
    ys: list[float | None] = []
    zs: list[float | None] = []
    loop = [*outline, outline[0]]
    for z in (z0, z1):
        for x, y in loop:
            xs.append(x)
            ys.append(y)
            zs.append(z)
        xs.append(None)
        ys.append(None)
        zs.append(None)
    for x, y in outline:
        xs += [x, x, None]
        ys += [y, y, None]
        zs += [z0, z1, None]
    return xs, ys, zs


def _round(a: np.ndarray, decimals: int) -> list[float | None]:
    """A list for JSON with NaN as None (plotly's gap)."""
    a = np.round(np.asarray(a, float), decimals)
    return [None if not np.isfinite(v) else float(v) for v in a]


def _num(v: float, digits: int, significant: bool = False) -> float | None:
    """A JSON number (None for NaN): ``digits`` decimals or significant digits."""
    if not np.isfinite(v):
        return None
    return float(f"{v:.{digits}g}") if significant else round(float(v), digits)


def toolpath_figure(res, binding_colours: dict[str, str], max_points: int = VIEW_MAX_POINTS) -> dict:
    """The 3-D view as a plotly figure (a plain dict: ``data``, ``layout``).

    Args:
        res: the plan (:class:`planner.plan.PlanResult`).
        binding_colours: a colour per binding constraint (the report's).
        max_points: most path points drawn (:func:`view_samples`).
    """
    prep = res.prep
    path, eng = prep.path, prep.engagement
    n = len(path)
    rows = res.section_rows
    keep = view_samples(n, rows, max_points)
    p_mm = path.position_wp * 1e3
    kinds = np.asarray(res.kinds)

    # per sample: the section's binding and number, the evaluation on the cut samples
    binding = np.full(n, "", dtype=object)
    number = np.zeros(n, int)
    for r in rows:
        binding[r["sample_start"]:r["sample_stop"]] = r["binding"]
        number[r["sample_start"]:r["sample_stop"]] = r["index"]
    ev = res.evaluation
    defl_mm = np.full(n, np.nan)
    margin = np.full(n, np.nan)
    ceiling_binds = np.full(n, "", dtype=object)
    idx = np.asarray(res.model.index, int)
    if idx.size:
        defl_mm[idx] = ev.deflection_norm * 1e3
        margin[idx] = ev.margin
        ceiling_binds[idx] = np.asarray(res.ceilings.binding, dtype=object)
    feed_mm_s = np.asarray(res.feed, float) * 1e3
    timed_mm_s = np.asarray(res.timing.speed, float) * 1e3

    cut = kinds == CUT
    k_cut = keep[cut[keep]]
    # the cut line: gaps (None) where the path leaves the cut, so that one trace holds every cut
    gap = np.zeros(k_cut.size, bool)
    if k_cut.size > 1:
        prev_kept = keep[np.searchsorted(keep, k_cut[1:]) - 1]
        gap[1:] = prev_kept != k_cut[:-1]   # a non-cut sample lies between two kept cut samples
    order = []
    for j, i in enumerate(k_cut):
        if gap[j]:
            order.append(-1)
        order.append(int(i))
    order_a = np.asarray(order, int)
    real = order_a >= 0

    def col(v: np.ndarray, decimals: int) -> list[float | None]:
        out = np.full(order_a.size, np.nan)
        out[real] = np.asarray(v, float)[order_a[real]]
        return _round(out, decimals)

    present = sorted({str(b) for b in binding[k_cut]} - {""})
    code_of = {b: i for i, b in enumerate(present)}
    codes = np.array([code_of.get(str(b), 0) for b in binding], float)
    files = [p.rsplit("/", 1)[-1] for p in path.files]
    many_files = len(files) > 1

    def where(i: int) -> str:
        line = int(path.line[i])
        return f"{files[int(path.file[i])]}:{line}" if many_files else str(line)

    custom: list[list[Any] | None] = []
    for i in order_a:
        if i < 0:
            custom.append(None)
            continue
        custom.append([int(i), where(i), round(float(feed_mm_s[i]), 3), round(float(timed_mm_s[i]), 3),
                       f"{binding[i]} (section {number[i]})", str(ceiling_binds[i] or "—"),
                       round(float(eng.a_e[i]) * 1e3, 3), round(float(eng.a_p[i]) * 1e3, 3),
                       _num(defl_mm[i], 4), _num(margin[i], 4, significant=True)])
    hover = ("sample %{customdata[0]}, line %{customdata[1]}<br>"
             "feed %{customdata[2]:.2f} mm/s (timed %{customdata[3]:.2f})<br>"
             "binds: %{customdata[4]}; ceiling here: %{customdata[5]}<br>"
             "a_e %{customdata[6]:.3f} mm, a_p %{customdata[7]:.3f} mm<br>"
             "|δ| %{customdata[8]:.3f} mm, margin %{customdata[9]:.3g} N/m<extra></extra>")

    finite_margin = margin[cut & np.isfinite(margin)]
    m_lo, m_hi = (np.percentile(finite_margin, [2, 98]) if finite_margin.size else (0.0, 1.0))
    tol_mm = res.limits.deflection_tol * 1e3
    feed_hi = float(np.nanmax(feed_mm_s[cut])) if cut.any() else 1.0
    modes: dict[str, dict[str, Any]] = {
        "feed": {"color": col(feed_mm_s, 3), "colorscale": "Viridis", "cmin": 0.0, "cmax": feed_hi,
                 "colorbar": {"title": {"text": "planned feed [mm/s]"}}},
        "binding": {"color": col(codes, 0), "colorscale": _binding_colourscale(present, binding_colours),
                    "cmin": -0.5, "cmax": max(len(present), 1) - 0.5,
                    "colorbar": {"title": {"text": "binding constraint"},
                                 "tickvals": list(range(len(present))), "ticktext": present}},
        "deflection": {"color": col(defl_mm, 4), "colorscale": _DEFLECTION_SCALE, "cmin": 0.0,
                       "cmax": float(tol_mm) if np.isfinite(tol_mm) else float(np.nanmax(defl_mm)),
                       "colorbar": {"title": {"text": "|δ| at the TCP [mm]<br>(top: tolerance)"}}},
        "margin": {"color": col(margin, 4), "colorscale": _MARGIN_SCALE, "cmin": float(m_lo),
                   "cmax": float(max(m_hi, m_lo + 1.0)),
                   "colorbar": {"title": {"text": "chatter margin [N/m]"},
                                "exponentformat": "e"}},
    }
    for m in modes.values():
        m["colorbar"].update({"x": 1.0, "len": 0.75, "thickness": 14})
    xyz = [col(p_mm[:, a], _MM_DECIMALS) for a in range(3)]
    data: list[dict[str, Any]] = []

    # air moves and rapids: thin grey, the samples next to them included so the line joins the cut
    other = ~cut
    near = other.copy()
    near[1:] |= other[:-1]
    near[:-1] |= other[1:]
    k_other = keep[near[keep]]
    if k_other.size:
        ox: list[list[float | None]] = [[], [], []]
        otext: list[str | None] = []
        last = None
        for i in k_other:
            if last is not None and i != last + 1 and np.any(~near[last + 1:i]):
                for a in range(3):
                    ox[a].append(None)
                otext.append(None)
            for a in range(3):
                ox[a].append(round(float(p_mm[i, a]), _MM_DECIMALS))
            kind = "rapid" if kinds[i] == RAPID else ("air" if kinds[i] != CUT else "cut")
            otext.append(f"sample {int(i)}, line {where(int(i))}: {kind}")
            last = int(i)
        data.append({"type": "scatter3d", "mode": "lines", "name": "air moves and rapids",
                     "x": ox[0], "y": ox[1], "z": ox[2], "text": otext, "hoverinfo": "text",
                     "line": {"color": "rgba(90,90,90,0.55)", "width": 2}})
    first = modes["feed"]
    data.append({"type": "scatter3d", "mode": "lines", "name": "cut", "showlegend": False,
                 "x": xyz[0], "y": xyz[1], "z": xyz[2], "customdata": custom, "hovertemplate": hover,
                 "line": {"width": 6, "showscale": True, **first}})
    cut_trace = len(data) - 1

    # the stock and the part frame
    job = prep.job
    st = job.engagement.stock
    extent = np.ptp(p_mm[keep], axis=0) if keep.size else np.ones(3)
    if st is not None:
        z0, z1 = st.z_bottom_mm, st.z_top_mm
        if st.box_mm is not None:
            sx, sy, sz = _box_edges(*st.box_mm, z0, z1)
        else:
            sx, sy, sz = _outline_edges([tuple(p) for p in st.outline_mm], z0, z1)
        data.append({"type": "scatter3d", "mode": "lines", "name": "stock", "x": sx, "y": sy,
                     "z": sz, "hoverinfo": "name", "line": {"color": "#8c6d31", "width": 3}})
        lo = np.array([min(v for v in sx if v is not None), min(v for v in sy if v is not None), z0])
        hi = np.array([max(v for v in sx if v is not None), max(v for v in sy if v is not None), z1])
        extent = np.maximum(extent, hi - lo)
    axis_len = 0.15 * float(max(np.max(extent), 1.0))
    for a, (name, colour) in enumerate((("X", "#d62728"), ("Y", "#2ca02c"), ("Z", "#1f77b4"))):
        end = [0.0, 0.0, 0.0]
        end[a] = axis_len
        data.append({"type": "scatter3d", "mode": "lines+text", "name": f"part frame {name}",
                     "x": [0.0, end[0]], "y": [0.0, end[1]], "z": [0.0, end[2]],
                     "text": ["", f"{name}<sub>part</sub>"], "textfont": {"color": colour, "size": 13},
                     "hoverinfo": "name", "showlegend": a == 0, "legendgroup": "frame",
                     "line": {"color": colour, "width": 7}})
    data[-3]["name"] = "part frame ($BASE): X red, Y green, Z blue"

    buttons = []
    for name in COLOUR_MODES:
        m = modes[name]
        buttons.append({"label": {"feed": "planned feed", "binding": "binding constraint",
                                  "deflection": "deflection", "margin": "chatter margin"}[name],
                        "method": "restyle",
                        "args": [{"line.color": [m["color"]], "line.colorscale": [m["colorscale"]],
                                  "line.cmin": m["cmin"], "line.cmax": m["cmax"],
                                  "line.colorbar": [m["colorbar"]]}, [cut_trace]]})
    decimated = keep.size < n
    layout = {
        "height": 640, "margin": {"l": 0, "r": 0, "t": 40, "b": 0},
        "scene": {"aspectmode": "data",
                  "xaxis": {"title": {"text": "X [mm]"}}, "yaxis": {"title": {"text": "Y [mm]"}},
                  "zaxis": {"title": {"text": "Z [mm]"}},
                  "camera": {"eye": {"x": -1.25, "y": -1.65, "z": 1.1}}},
        "legend": {"orientation": "h", "x": 0.0, "y": 0.99, "yanchor": "top",
                   "bgcolor": "rgba(255,255,255,0.7)"},
        "updatemenus": [{"type": "buttons", "direction": "right", "x": 0.0, "y": 1.0,
                         "xanchor": "left", "yanchor": "bottom", "pad": {"t": 4, "b": 4},
                         "showactive": True, "buttons": buttons}],
        "annotations": [{"text": (f"{keep.size:,} of {n:,} samples drawn (every section's ends kept)"
                                  if decimated else f"all {n:,} samples"),
                         "showarrow": False, "xref": "paper", "yref": "paper", "x": 1.0, "y": 1.0,
                         "xanchor": "right", "yanchor": "bottom", "font": {"size": 11, "color": "#555"}}],
    }
    return {"data": data, "layout": layout}


@functools.lru_cache(maxsize=1)
def _packed_plotlyjs() -> str:
    """plotly.js, gzip-compressed and base64-encoded (computed once per process)."""
    from plotly.offline import get_plotlyjs

    raw = get_plotlyjs().encode("utf-8")
    return base64.b64encode(gzip.compress(raw, compresslevel=6, mtime=0)).decode("ascii")


#: Unpacks plotly.js in the browser and then draws every ``cctmillViews`` entry.
_LOADER = """<script>
(function () {
  var draw = function () {
    (window.cctmillViews || []).forEach(function (v) {
      Plotly.newPlot(v.id, v.figure.data, v.figure.layout,
                     {responsive: true, displaylogo: false}).then(function () {
        // when the view was drawn [ms since navigation]: for tests and timing
        document.getElementById(v.id).dataset.drawnMs = Math.round(performance.now());
      });
    });
  };
  var fail = function (why) {
    (window.cctmillViews || []).forEach(function (v) {
      document.getElementById(v.id).textContent = "The 3-D view needs a browser that unpacks gzip " +
        "(Chromium 80, Firefox 113, Safari 16.4 or newer): " + why;
    });
  };
  var start = function () {
    try {
      var b = atob(document.getElementById("@PACKED_ID@").textContent.trim());
      var u = new Uint8Array(b.length);
      for (var i = 0; i < b.length; i++) u[i] = b.charCodeAt(i);
      var s = new Blob([u]).stream().pipeThrough(new DecompressionStream("gzip"));
      new Response(s).text().then(function (js) {
        var el = document.createElement("script");
        el.textContent = js;
        document.head.appendChild(el);
        draw();
      }).catch(function (e) { fail(String(e)); });
    } catch (e) { fail(String(e)); }
  };
  // the page first (its text, tables and plots), then the 3-D view: unpacking and compiling
  // plotly.js takes a moment and must not hold back the first paint (a frame is due within
  // PAINT_FIRST_MS of the load; requestAnimationFrame would stall a headless, virtual-time render)
  var later = function () { setTimeout(start, @PAINT_FIRST_MS@); };
  if (document.readyState === "complete") later(); else window.addEventListener("load", later);
})();
</script>""".replace("@PACKED_ID@", _PACKED_ID).replace("@PAINT_FIRST_MS@", str(_PAINT_FIRST_MS))


def plotlyjs_script() -> str:
    """The packed plotly.js and its loader: put once in a page, after the views' ``<div>``s."""
    return (f'<script id="{_PACKED_ID}" type="application/gzip;base64">{_packed_plotlyjs()}</script>\n'
            + _LOADER)


def view3d_html(res, binding_colours: dict[str, str], div_id: str = "cctmill-view3d",
                max_points: int = VIEW_MAX_POINTS) -> str:
    """The 3-D view's ``<div>`` and its figure (a script that registers it for the loader of
    :func:`plotlyjs_script`, which the page must hold once)."""
    fig = toolpath_figure(res, binding_colours, max_points)
    payload = json.dumps(fig, separators=(",", ":"), allow_nan=False).replace("</", "<\\/")
    return (f'<div id="{html.escape(div_id)}" class="view3d" style="width:100%;height:640px"></div>\n'
            f"<script>(window.cctmillViews = window.cctmillViews || []).push("
            f'{{id: "{html.escape(div_id)}", figure: {payload}}});</script>')
