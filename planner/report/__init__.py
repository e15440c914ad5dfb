"""Reports of a plan: the self-contained HTML page and its figures (:mod:`~planner.report.html`),
the path and characteristic plots (:mod:`~planner.report.plots`) and the point model's tables
(:mod:`~planner.report.tables`)."""

from planner.report.html import (
    BINDING_COLOURS,
    BROWSERS,
    ReportRenderError,
    find_browser,
    plot_along_path,
    plot_characteristics,
    render_screenshot,
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
)

__all__ = [
    "BINDING_COLOURS",
    "BROWSERS",
    "ReportRenderError",
    "analysis_json",
    "analysis_table",
    "characteristic_table",
    "find_browser",
    "new_figure",
    "plot_along_path",
    "plot_characteristic",
    "plot_characteristics",
    "plot_path_kinematics",
    "render_screenshot",
    "save_figure",
    "tightest_sections",
    "write_report",
]
