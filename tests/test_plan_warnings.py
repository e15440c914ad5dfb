"""A reader's warnings reach the user of ``cctmill plan``: its output, plan.json and the report
(issue 15)."""

from __future__ import annotations

import json
from importlib import resources
from pathlib import Path

from planner.cli import main
from planner.plan_file import load_plan

DEMO = Path(str(resources.files("planner").joinpath("data/demo/demo_job.toml")))


def test_reader_warnings_reach_the_cli_plan_json_and_report(tmp_path, capsys):
    program = (DEMO.parent / "bracket_contour.nc").read_text(encoding="utf-8")
    # cutter compensation on the first contour: the path is read as written, with a warning
    assert "N45 G3" in program
    program = program.replace("N45 G3", "N45 G41 G3", 1)
    (tmp_path / "bracket_g41.nc").write_text(program, encoding="utf-8")
    job = DEMO.read_text(encoding="utf-8").replace('toolpath = ["bracket_contour.nc"]',
                                                   'toolpath = ["bracket_g41.nc"]')
    (tmp_path / "job.toml").write_text(job, encoding="utf-8")
    out = tmp_path / "out"
    assert main(["plan", str(tmp_path / "job.toml"), "-o", str(out), "--method", "constant",
                 "--krl"]) == 0
    printed = capsys.readouterr().out
    assert "toolpath warnings: 1" in printed
    assert "cutter_compensation" in printed and "bracket_g41.nc:13:" in printed

    doc = json.loads((out / "plan.json").read_text(encoding="utf-8"))
    (w,) = doc["import_warnings"]
    assert w["kind"] == "cutter_compensation" and w["count"] == 1
    assert ":13:" in w["first"]
    assert load_plan(out).import_warnings[0].kind == "cutter_compensation"

    (src,) = [p for p in out.rglob("*.src") if "toolpath warning" in p.read_text("ascii")][:1]
    assert "; toolpath warning (cutter_compensation x1)" in src.read_text("ascii")

    report = (out / "report.html").read_text(encoding="utf-8")
    head = report[:report.index("<h2>")]
    assert 'class="warn"' in head and "cutter_compensation" in head and "bracket_g41.nc:13:" in head


def test_a_clean_program_plans_without_an_import_warning(demo_optimized):
    from planner.plan_file import Plan

    plan = Plan.from_result(demo_optimized)
    assert plan.import_warnings == ()
    assert plan.document()["import_warnings"] == []
