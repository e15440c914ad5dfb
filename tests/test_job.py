"""Job file validation: every problem named in the user's terms, all at once."""

from __future__ import annotations

import numpy as np
import pytest

from planner.job import JobError, load_job, parse_job
from robot_io.krl.frames import frame_from_mm_deg as frame_matrix

MINIMAL = {"job": {"toolpath": "a.nc"}, "engagement": {"ae_mm": 3.0, "ap_mm": 5.0}}


def _with(table: str, **keys) -> dict:
    doc = {k: dict(v) if isinstance(v, dict) else v for k, v in MINIMAL.items()}
    doc.setdefault(table, {}).update(keys)
    return doc


def test_minimal_job_has_sane_defaults():
    job = parse_job(MINIMAL)
    assert job.limits.force_max_n == 300.0
    assert job.cell.robot == "kr210_r2700_extra"
    assert job.job.toolpath == ["a.nc"]
    assert job.model.process_model == "thesis"


@pytest.mark.parametrize(("doc", "message"), [
    (_with("limits", feed_max_mm_min=100.0),
     r"\[limits\] feed_max_mm_min: unknown key; did you mean 'feed_max_mm_s'\? \(units are part"),
    (_with("limits", force_max_n=-3.0), r"\[limits\] force_max_n: input should be greater than 0"),
    (_with("limits", feed_min_mm_s=50.0, feed_max_mm_s=10.0),
     r"feed_min_mm_s must be below feed_max_mm_s"),
    (_with("cell", base_mm=[1.0, 2.0]), r"\[cell\] base_mm: List should have at least 3 items"),
    (_with("cell", tcp_in=[1.0, 2.0, 3.0]), r"\[cell\] tcp_in: unknown key; did you mean 'tcp_mm'"),
    (_with("spindel", rpm=100.0), r"spindel: unknown key; did you mean 'spindle'"),
    (_with("engagement", source="stock"), r"source = 'stock' needs an \[engagement.stock\]"),
    (_with("engagement", source="stock",
           stock={"box_mm": [0, 0, 1, 1], "z_bottom_mm": 5.0, "z_top_mm": 1.0}),
     r"z_top_mm must be above z_bottom_mm"),
    (_with("model", process_model="tlusty"), r"\[model\] process_model: Input should be 'thesis'"),
    (_with("spindle", rpm=float("nan")), r"\[spindle\] rpm: "),
    ({"engagement": {"ae_mm": 3.0, "ap_mm": 5.0}}, r"job: missing; add it"),
])
def test_bad_job_is_named(doc, message):
    with pytest.raises(JobError, match=message):
        parse_job(doc, "job.toml")


def test_all_problems_at_once():
    doc = _with("limits", force_max_n=-1.0, feed_max_mm_min=3.0)
    with pytest.raises(JobError, match=r"2 problems") as info:
        parse_job(doc, "job.toml")
    assert len(info.value.problems) == 2


def test_toml_syntax_error_has_line(tmp_path):
    p = tmp_path / "bad.toml"
    p.write_text("[job]\ntoolpath = \"a.nc\" x\n")
    with pytest.raises(JobError, match=r"bad.toml: not valid TOML: .*line"):
        load_job(p)


def test_relative_toolpath_resolves_next_to_job(tmp_path):
    p = tmp_path / "j.toml"
    p.write_text('[job]\ntoolpath = "sub/a.nc"\n[engagement]\nae_mm = 2.0\nap_mm = 4.0\n')
    assert load_job(p).toolpath_files() == [(tmp_path / "sub" / "a.nc").resolve()]


def test_frame_matrix_is_kuka_abc():
    """R = Rz(A) Ry(B) Rx(C); A = 90 deg maps x to y; translation in mm → m."""
    t = frame_matrix([1000.0, 0.0, -50.0], [90.0, 0.0, 0.0])
    assert np.allclose(t[:3, :3] @ [1, 0, 0], [0, 1, 0])
    assert np.allclose(t[:3, 3], [1.0, 0.0, -0.05])
    t = frame_matrix([0, 0, 0], [0.0, 90.0, 0.0])
    assert np.allclose(t[:3, :3] @ [1, 0, 0], [0, 0, -1])
    t = frame_matrix([0, 0, 0], [10.0, 20.0, 30.0])
    r = t[:3, :3]
    assert np.allclose(r @ r.T, np.eye(3)) and np.isclose(np.linalg.det(r), 1.0)


def test_demo_job_is_valid():
    from importlib import resources

    path = resources.files("planner").joinpath("data/demo/demo_job.toml")
    job = load_job(str(path))
    assert all(p.exists() for p in job.toolpath_files())


def test_every_key_is_documented_and_the_reference_is_in_the_manual():
    """The manual's job file reference (docs/job.md) is generated from the schema; keep them equal."""
    from pathlib import Path

    from planner.job import reference_markdown

    page = (Path(__file__).resolve().parents[1] / "docs" / "job.md").read_text(encoding="utf-8")
    start, end = "<!-- job-reference:start -->", "<!-- job-reference:end -->"
    assert start in page and end in page
    block = page.split(start, 1)[1].split(end, 1)[0]
    assert block.strip() == reference_markdown().strip(), "regenerate: make docs"
