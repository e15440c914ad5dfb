"""What the readers' messages say to whom: from the CLI a fix names a flag, from a job a job key,
from Python the keyword — never a Python keyword form outside Python (issue 15)."""

from __future__ import annotations

from pathlib import Path

import pytest

from planner.cli import main
from planner.job import parse_job
from planner.prepare import read_job_toolpaths
from robot_io.options import fix, option_name, speaking
from robot_io.readers import read_toolpath
from robot_io.toolpath import ToolpathError

#: Python keyword forms no CLI or job message may contain.
KEYWORD_FORMS = ("=False", "=True", "='", "=(", "=None", "strict=", "(Python API)")

#: (file name, content, what the message must name from the CLI, from a job).
CASES = [
    ("unknown_g.nc", "G21 G90\nG0 X0 Y0 Z5\nG1 Z0 F100\nG5.2 X1\n",
     "--lenient", "[job] strict = false"),
    ("vendor_word.nc", "G21 G90\nG0 X0 Y0 Z5\nG1 X1 E5 F100\n",
     "--lenient", "[job] strict = false"),
    ("rotary.nc", "G21\nG0 X0 Y0 Z0\nG1 X1 A10 F100\n",
     "--rotary xyzac-trunnion", '[job] rotary = "xyzac-trunnion"'),
    ("no_units.nc", "G0 X0 Y0 Z5\nG1 X1 F100\n",
     "--units inch", '[job] units = "inch"'),
    ("unknown_start.nc", "G21\nG1 X1 F100\n",
     "--initial-position-mm", "[job] initial_position_mm"),
    ("bad_fedrat.apt", "UNITS/MM\nFEDRAT/abc,MMPM\n",
     "--lenient", "[job] strict = false"),
    ("no_units.apt", "FEDRAT/100,MMPM\nGOTO/1,2,3\n",
     "--units inch", '[job] units = "inch"'),
    ("spline.src", "DEF t()\nPTP {A1 0}\nSPLINE\nSPL {X 1}\nENDSPLINE\nEND\n",
     "--lenient", "[job] strict = false"),
    ("unknown.xyz", "hello world\n", "--format gcode", '[job] format = "gcode"'),
]


def _message(path: Path, argv: list[str], capsys) -> str:
    code = main(["inspect", str(path), *argv])
    out = capsys.readouterr()
    return (out.err if code else out.out).strip()


@pytest.mark.parametrize(("name", "text", "cli", "job"), CASES, ids=[c[0] for c in CASES])
def test_cli_messages_name_flags_not_keywords(tmp_path, capsys, name, text, cli, job):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    msg = _message(path, [], capsys)
    assert cli in msg, msg
    for form in KEYWORD_FORMS:
        assert form not in msg, f"{form!r} in: {msg}"


@pytest.mark.parametrize(("name", "text", "cli", "job"), CASES, ids=[c[0] for c in CASES])
def test_job_messages_name_job_keys(tmp_path, name, text, cli, job):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    doc = {"job": {"toolpath": [name]}, "engagement": {"source": "fixed", "ae_mm": 1.0,
                                                       "ap_mm": 1.0}}
    try:
        tps = read_job_toolpaths(parse_job(doc, "job.toml", tmp_path))
        msg = "\n".join(str(w) for tp in tps for w in tp.warnings)
    except ToolpathError as e:
        msg = str(e)
    assert job in msg, msg
    for form in KEYWORD_FORMS:
        assert form not in msg, f"{form!r} in: {msg}"


@pytest.mark.parametrize(("name", "text", "cli", "job"), CASES, ids=[c[0] for c in CASES])
def test_python_messages_name_keywords(tmp_path, name, text, cli, job):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    try:
        msg = "\n".join(str(w) for w in read_toolpath(path).warnings)
    except ToolpathError as e:
        msg = str(e)
    assert "=" in msg and "--" not in msg and "[job]" not in msg, msg


def test_fix_forms():
    assert fix("strict", False) == "strict=False"
    with speaking("cli"):
        assert fix("strict", False) == "--lenient"
        assert fix("rotary", "xyzbc-trunnion") == "--rotary xyzbc-trunnion"
        assert option_name("rotary") == "--rotary"
        assert fix("tcp", True) == "tcp=True (Python API)"
    with speaking("job"):
        assert fix("default_units", "inch") == '[job] units = "inch"'
        assert option_name("apply_frames") == "[job] apply_frames"
    assert fix("strict", False) == "strict=False"
    with pytest.raises(ValueError, match="interface"), speaking("web"):
        pass


def test_missing_file_says_not_found(tmp_path, capsys):
    msg = _message(tmp_path / "nofile.nc", [], capsys)
    assert "not found" in msg and ":0:0" not in msg, msg


def test_an_option_of_another_format_names_the_formats_it_applies_to(tmp_path, capsys):
    path = tmp_path / "f.apt"
    path.write_text("UNITS/MM\nFEDRAT/100,MMPM\nGOTO/1,2,3\n", encoding="utf-8")
    msg = _message(path, ["--rotary", "xyzbc-trunnion"], capsys)
    assert "--rotary applies to G-code programs only" in msg and "APT/CL" in msg, msg
    with pytest.raises(ToolpathError, match="rotary applies to G-code programs only"):
        read_toolpath(path, rotary="xyzac-trunnion")


def test_a_job_option_for_no_file_of_the_job_is_refused(tmp_path):
    (tmp_path / "f.apt").write_text("UNITS/MM\nFEDRAT/100,MMPM\nGOTO/1,2,3\n", encoding="utf-8")
    doc = {"job": {"toolpath": ["f.apt"], "rotary": "xyzbc-trunnion"},
           "engagement": {"source": "fixed", "ae_mm": 1.0, "ap_mm": 1.0}}
    from planner.job import JobError

    with pytest.raises(JobError, match=r"\[job\] rotary applies to gcode toolpaths"):
        read_job_toolpaths(parse_job(doc, "job.toml", tmp_path))


def test_bc_trunnion_from_the_cli(tmp_path, capsys):
    path = tmp_path / "bc.ngc"
    path.write_text("G21 G90\nG0 X0 Y0 Z10 B0 C0\nG1 X10 B30 C45 F500\n", encoding="utf-8")
    assert main(["inspect", str(path), "--rotary", "xyzbc-trunnion", "--json"]) == 0
    import json

    doc = json.loads(capsys.readouterr().out)
    assert doc["has_tool_axis"] and doc["tool_axes"] == 2


@pytest.mark.parametrize(("name", "text", "cli", "job"), CASES, ids=[c[0] for c in CASES])
def test_lenient_warnings_do_not_advise_reading_leniently(tmp_path, capsys, name, text, cli, job):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    msg = _message(path, ["--lenient"], capsys)
    assert "--lenient" not in msg, msg
    for form in KEYWORD_FORMS:
        assert form not in msg, f"{form!r} in: {msg}"
