"""Reports of a plan: the self-contained HTML page and its figures (:mod:`~planner.report.html`),
the toolpath in 3-D (:mod:`~planner.report.view3d`, plotly offline), the path and characteristic
plots (:mod:`~planner.report.plots`), the tables (:mod:`~planner.report.tables`) and the headless
browser that looks at the page (:mod:`~planner.report.browser`)."""

from planner.report.browser import BROWSERS, ReportRenderError, find_browser, render_screenshot
from planner.report.html import (
    BINDING_COLOURS,
    headline,
    plot_along_path,
    plot_characteristics,
    tightest_sections,
    write_report,
)
from planner.report.plots import (
    new_figure,
    plot_characteristic,
    plot_path_kinematics,
    save_figure,
)
from planner.report.tables import (
    analysis_json,
    analysis_table,
    characteristic_table,
    limiting_joints,
    section_engagement,
)
from planner.report.view3d import VIEW_MAX_POINTS, plotlyjs_script, toolpath_figure, view3d_html

__all__ = [
    "BINDING_COLOURS",
    "BROWSERS",
    "ReportRenderError",
    "VIEW_MAX_POINTS",
    "analysis_json",
    "analysis_table",
    "characteristic_table",
    "find_browser",
    "headline",
    "limiting_joints",
    "new_figure",
    "plot_along_path",
    "plot_characteristic",
    "plot_characteristics",
    "plot_path_kinematics",
    "plotlyjs_script",
    "render_screenshot",
    "save_figure",
    "section_engagement",
    "tightest_sections",
    "toolpath_figure",
    "view3d_html",
    "write_report",
]
