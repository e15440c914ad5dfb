"""The report in a headless browser: find Chromium and take a screenshot of a page (the demo's
``report.png``, the tests that look at the 3-D view)."""

from __future__ import annotations

import os
from pathlib import Path

from models.errors import CctmillError
from planner._atomic import atomic_path

__all__ = ["BROWSERS", "SCREENSHOT_SETTLE_MS", "SCREENSHOT_TIMEOUT", "ReportRenderError",
           "find_browser", "render_screenshot"]


class ReportRenderError(CctmillError):
    """The report could not be rendered to a screenshot (no browser, or it failed)."""


#: Browsers tried for the headless screenshot, in order (Debian's package is ``chromium``).
BROWSERS = ("chromium", "chromium-browser", "google-chrome")
#: Flags for a headless, offline, throw-away browser (no network, no profile, no GPU).
_BROWSER_FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update", "--disable-sync",
                  "--hide-scrollbars", "--force-device-scale-factor=1")
#: Longest a screenshot may take [s].
SCREENSHOT_TIMEOUT = 120.0
#: Virtual time the page may take to settle before the screenshot [ms]: the 3-D view is drawn
#: after plotly.js is unpacked, asynchronously (Chromium's ``--virtual-time-budget``).
SCREENSHOT_SETTLE_MS = 20000


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
               f"--virtual-time-budget={SCREENSHOT_SETTLE_MS}", f"--screenshot={tmp}", page]
        try:
            proc = subprocess.run(cmd, capture_output=True, text=True, timeout=SCREENSHOT_TIMEOUT,
                                  check=False)
        except (OSError, subprocess.TimeoutExpired) as e:
            raise ReportRenderError(f"{exe} could not render {html_path}: {e}") from e
        if not tmp.exists() or tmp.stat().st_size == 0:
            raise ReportRenderError(f"{exe} wrote no screenshot (exit {proc.returncode}): "
                                    f"{proc.stderr.strip()[-300:]}")
    return Path(png_path)
