"""Progress bars of the long steps (issue 21): the calibration's fits and the files written after a
plan take ``progress``, stay silent when stderr is not a terminal (scripts, CI, captured output),
and show a bar on one (a pseudo-terminal: ``cctmill calibrate`` in a child process)."""

from __future__ import annotations

import dataclasses
import io
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from planner.calibrate.context import CalibrationContext
from planner.calibrate.fit_boundary import PROGRESS_MIN_RECORDS
from planner.calibrate.records import CutRecord, write_records
from planner.job import load_job

ROOT = Path(__file__).resolve().parents[1]
DEMO = ROOT / "planner" / "data" / "demo"
#: Poses over the demo's stock top [deg] (as tests/test_calibrate.py).
POSES = [(0.0, -70.7843, 112.2894, 0.0, 48.495, 0.0), (1.6236, -74.0789, 116.9107, 0.0, 47.1682, 0.0)]
#: The child's wall-clock limit [s]: imports and a boundary fit of a few hundred records.
CHILD_TIMEOUT_S = 60.0


class _Tty(io.StringIO):
    """A captured stderr that says it is a terminal."""

    def isatty(self) -> bool:
        return True


@pytest.fixture(scope="module")
def ctx() -> CalibrationContext:
    return CalibrationContext.from_job(load_job(DEMO / "demo_job.toml"))


@pytest.fixture(scope="module")
def labelled(ctx) -> list[CutRecord]:
    """Enough labelled records for the boundary's bars: chatter iff a_p > 2 mm + 0.4 mm per 1000 rpm
    above 4000 rpm, with 10 % of the verdicts flipped (seeded)."""
    from planner.calibrate.testcuts import boundary_cuts

    rng = np.random.default_rng(21)
    out = []
    for r in boundary_cuts(ctx, POSES, PROGRESS_MIN_RECORDS + 10, rpm=(3000.0, 6000.0),
                           ap_mm=(0.5, 4.0), ae_mm=6.0, seed=21):
        chatter = (r.ap_mm > 2.0 + 0.4e-3 * (r.rpm - 4000.0)) ^ bool(rng.random() < 0.1)
        out.append(dataclasses.replace(r, verdict="chatter" if chatter else "stable"))
    return out


@pytest.fixture()
def job_dir(tmp_path, labelled) -> Path:
    shutil.copy(DEMO / "demo_job.toml", tmp_path / "job.toml")
    shutil.copy(DEMO / "bracket_contour.nc", tmp_path)
    write_records(tmp_path / "cuts.jsonl", labelled)
    return tmp_path


@pytest.fixture(scope="module")
def demo_plan():
    """The demo job planned with every bar asked for on a terminal, and what it drew (the feed
    ceilings' bar counts points, ~8000 here; the planning steps' bar counts samples, and the
    demo's 892 are below :data:`planner._progress.MIN_TOTAL`)."""
    from planner.plan import plan_job

    saved, sys.stderr = sys.stderr, _Tty()
    env = {k: os.environ.pop(k) for k in ("CI", "TERM") if k in os.environ}
    os.environ["TERM"] = "xterm"
    try:
        res = plan_job(load_job(DEMO / "demo_job.toml"), progress=True)
        err = sys.stderr.getvalue()
    finally:
        sys.stderr = saved
        os.environ.pop("TERM")
        os.environ.update(env)
    return res, err


def test_calibrate_with_progress_is_silent_without_a_terminal(job_dir, monkeypatch):
    from planner.calibrate.run import calibrate

    err = io.StringIO()
    monkeypatch.setattr(sys, "stderr", err)
    result = calibrate([job_dir / "cuts.jsonl"], job_dir / "job.toml", ["boundary"], progress=True)
    assert result.boundary is not None and result.boundary.n == PROGRESS_MIN_RECORDS + 10
    assert err.getvalue() == ""


def test_the_boundary_bars_show_on_a_terminal_and_not_when_not_asked(ctx, labelled, monkeypatch):
    from planner.calibrate.fit_boundary import fit_boundary

    monkeypatch.delenv("CI", raising=False)
    monkeypatch.setenv("TERM", "xterm")
    for progress, shown in ((True, True), (False, False)):
        tty = _Tty()
        monkeypatch.setattr(sys, "stderr", tty)
        fit_boundary(ctx, labelled, progress=progress)
        text = tty.getvalue()
        assert ("boundary: eigen margins" in text and "boundary: leave-one-out" in text) is shown
        assert (text != "") is shown


def test_plan_and_report_writing_with_progress_are_silent_without_a_terminal(demo_plan, tmp_path,
                                                                            monkeypatch):
    from planner import outputs
    from planner.report import html

    res, _ = demo_plan
    monkeypatch.setattr(html, "MIN_TOTAL", 1)        # as long a path as a bar needs
    err = io.StringIO()
    monkeypatch.setattr(sys, "stderr", err)
    written = outputs.write_plan_outputs(res, tmp_path, progress=True).files
    assert Path(written["report"]).is_file() and Path(written["plot_along_path"]).is_file()
    assert err.getvalue() == ""


def test_the_report_bar_names_the_files_on_a_terminal(demo_plan, tmp_path, monkeypatch):
    from planner.report import html

    res, plan_drew = demo_plan
    assert len(res.prep.path) < html.MIN_TOTAL and "planning" not in plan_drew   # a short job
    monkeypatch.delenv("CI", raising=False)
    monkeypatch.setenv("TERM", "xterm")
    tty = _Tty()
    monkeypatch.setattr(sys, "stderr", tty)
    monkeypatch.setattr(html, "MIN_TOTAL", 1)        # as long a path as a bar needs
    html.write_report(res, tmp_path, progress=True)
    text = tty.getvalue()
    assert "report" in text and "plan_along_path.png" in text and "report.html" in text


def _on_a_pty(argv: list[str], cwd: Path) -> str:
    """Run ``argv`` with stdin, stdout and stderr on a pseudo-terminal of 120 columns (a terminal
    of 0 columns, as ``script`` gives without one, draws no bar); return what it printed."""
    import fcntl
    import pty
    import select
    import struct
    import termios

    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 40, 120, 0, 0))
    env = {k: v for k, v in os.environ.items() if k != "CI"}
    env.update(TERM="xterm", PYTHONPATH=str(ROOT))
    proc = subprocess.Popen(argv, stdin=slave, stdout=slave, stderr=slave, cwd=cwd, env=env,
                            close_fds=True)
    os.close(slave)
    chunks, deadline = [], time.monotonic() + CHILD_TIMEOUT_S
    try:
        while time.monotonic() < deadline:
            ready, _, _ = select.select([master], [], [], 0.5)
            if ready:
                try:
                    data = os.read(master, 65536)
                except OSError:          # the child closed the terminal (Linux: EIO)
                    break
                if not data:
                    break
                chunks.append(data)
            elif proc.poll() is not None:
                break
    finally:
        os.close(master)
        if proc.poll() is None:
            proc.kill()
        proc.wait()
    assert proc.returncode == 0, b"".join(chunks).decode(errors="replace")
    return b"".join(chunks).decode(errors="replace")


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="a Linux pseudo-terminal")
def test_cctmill_calibrate_draws_a_bar_on_a_terminal(job_dir):
    cctmill = "import sys; from planner.cli import main; sys.exit(main(sys.argv[1:]))"
    out = _on_a_pty([sys.executable, "-c", cctmill, "calibrate", "cuts.jsonl", "--job", "job.toml",
                     "-o", "cell.overlay.toml", "--fit", "boundary"], job_dir)
    assert "boundary: eigen margins" in out and "boundary: leave-one-out" in out
    assert f"/{PROGRESS_MIN_RECORDS + 10}" in out                    # a bar counts the records
    assert "stability boundary on the eigen margin" in out and (job_dir / "cell.overlay.toml").is_file()
