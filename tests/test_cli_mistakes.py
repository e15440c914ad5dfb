"""Issue 22, user mistakes: every one a new user made, run through the real ``cctmill`` entry
point, is exit status 2 and one line on stderr naming the path or key — never a traceback.

One table, one row a mistake: (id, argv, files to prepare, what the line must name). Placeholders in
argv and the expectation: ``{tmp}`` the row's folder, ``{job}`` a copy of the demo job there,
``{plan}`` the demo's planned output (made once per session by ``cctmill plan --demo``),
``{badplan}`` that plan with a string where plan.json has a number. A file value ``RO`` makes a
read-only folder (as root, where the system lets every write through, the check's view of it is
simulated: ``os.access`` is answered from the mode bits).
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import shutil
import stat
import subprocess
import sys
from pathlib import Path

import pytest

from planner.cli import main
from planner.demo import demo_job_file

#: A folder made read-only for a row.
RO = object()

CASE1 = ["--joints-deg", "-96.42,-29.26,99.08,-9.95,83.23,-160.5", "--feed-dir", "0,1,0",
         "--radial-dir", "1,0,0", "--ae-mm", "15.24", "--ap-mm", "5.08"]
STABILITY = ["stability", *CASE1, "--feed-range-mm-s", "1:10:3"]
SIMULATE = ["simulate", *CASE1, "--feed-mm-s", "1", "--duration-s", "0.1"]
SUPERVISE = ["supervise", "--plan", "{plan}", "--signal", "sim", "--robot", "sim"]
DEMO_TEXT = demo_job_file().read_text(encoding="utf-8")
DEMO_NC = json.dumps(str(demo_job_file().parent / "bracket_contour.nc"))


def job(old: str = "", new: str = "") -> str:
    """The demo job (its toolpath by absolute path) with one line replaced."""
    text = DEMO_TEXT.replace('toolpath = ["bracket_contour.nc"]', f"toolpath = [{DEMO_NC}]")
    if old:
        assert old in text, old
        text = text.replace(old, new, 1)
    return text


FILE = {"file.nc": ""}          # a file where a folder should be
MISTAKES = [
    # ---- output paths that cannot be written: caught before the work starts
    ("plan -o is the job file", ["plan", "{job}", "-o", "{job}"], {},
     "-o/--output {job}: cannot write: it is a file, not a folder"),
    ("plan -o under a file", ["plan", "{job}", "-o", "{tmp}/file.nc/sub"], FILE,
     "-o/--output {tmp}/file.nc/sub: cannot write: {tmp}/file.nc is a file"),
    ("plan -o in a read-only folder", ["plan", "{job}", "-o", "{tmp}/ro/out"], {"ro": RO},
     "-o/--output {tmp}/ro/out: cannot write: folder {tmp}/ro, where out would be made, is "
     "not writable (permission denied)"),
    ("plan --krl -o under a file", ["plan", "{job}", "--krl", "-o", "{tmp}/file.nc/k"], FILE,
     "-o/--output {tmp}/file.nc/k"),
    ("demo -o is a file", ["demo", "-o", "{tmp}/file.nc"], FILE, "-o/--output {tmp}/file.nc:"),
    ("export -o under a file", ["export", "{plan}", "-o", "{tmp}/file.nc/krl"], FILE,
     "-o/--output {tmp}/file.nc/krl: cannot write: {tmp}/file.nc is a file"),
    ("export -o is a file", ["export", "{plan}", "-o", "{tmp}/file.nc"], FILE,
     "-o/--output {tmp}/file.nc: cannot write: it is a file, not a folder"),
    ("export -o in a read-only folder", ["export", "{plan}", "-o", "{tmp}/ro/krl"], {"ro": RO},
     "folder {tmp}/ro, where krl would be made, is not writable"),
    ("stability --plot under a file", [*STABILITY, "--plot", "{tmp}/file.nc/x.png"], FILE,
     "--plot {tmp}/file.nc/x.png: cannot write: {tmp}/file.nc is a file"),
    ("stability --plot is a folder", [*STABILITY, "--plot", "{tmp}"], {},
     "--plot {tmp}: cannot write: it is a folder"),
    ("stability --plot in a read-only folder", [*STABILITY, "--plot", "{tmp}/ro/x.png"],
     {"ro": RO}, "--plot {tmp}/ro/x.png: cannot write: folder {tmp}/ro is not writable"),
    ("simulate --out under a file", [*SIMULATE, "--out", "{tmp}/file.nc/s.csv"], FILE,
     "--out {tmp}/file.nc/s.csv"),
    ("simulate --plot under a file", [*SIMULATE, "--plot", "{tmp}/file.nc/s.png"], FILE,
     "--plot {tmp}/file.nc/s.png"),
    ("inspect --plot under a file", ["inspect", "{job}", "--plot", "{tmp}/file.nc/k.png"], FILE,
     "--plot {tmp}/file.nc/k.png"),
    ("supervise --log under a file", [*SUPERVISE, "--log", "{tmp}/file.nc/ev.jsonl"], FILE,
     "--log {tmp}/file.nc/ev.jsonl: cannot write: {tmp}/file.nc is a file"),
    ("supervise --log in a missing folder", [*SUPERVISE, "--log", "{tmp}/nodir/ev.jsonl"], {},
     "--log {tmp}/nodir/ev.jsonl: cannot write: folder {tmp}/nodir does not exist"),
    ("supervise --log in a read-only folder", [*SUPERVISE, "--log", "{tmp}/ro/ev.jsonl"],
     {"ro": RO}, "--log {tmp}/ro/ev.jsonl: cannot write: folder {tmp}/ro is not writable"),
    ("supervise --plot under a file", [*SUPERVISE, "--plot", "{tmp}/file.nc/s.png"], FILE,
     "--plot {tmp}/file.nc/s.png"),
    # ---- job values the loader used to accept without a word
    ("seed joint outside its limits", ["plan", "{tmp}/j.toml", "-o", "{tmp}/out"],
     {"j.toml": job("choose_for_stiffness = true",
                    "choose_for_stiffness = true\nseed_joints_deg = [0, -200, 90, 0, 45, 0]")},
     "[kinematics] seed_joints_deg: A2 = -200 deg is outside its limits -140 .. -5 deg"),
    ("deflection tolerance of 200 mm", ["plan", "{tmp}/j.toml", "-o", "{tmp}/out"],
     {"j.toml": job("deflection_tol_mm = 0.2", "deflection_tol_mm = 200")},
     "[limits] deflection_tol_mm: 200 mm is above 5 mm"),
    ("rpm as a string", ["plan", "{tmp}/j.toml", "-o", "{tmp}/out"],
     {"j.toml": job("rpm = 4000.0", 'rpm = "4000"')},
     '[spindle] rpm: must be a number, got the string "4000"; write it without quotes'),
    ("a boolean as a string", ["inspect", "{tmp}/j.toml"],
     {"j.toml": job("strict = true", 'strict = "true"')}, "[job] strict: must be true or false"),
    ("rapid speed in mm/min", ["inspect", "{tmp}/j.toml"],
     {"j.toml": job("cam_feed_scale_max = 2.0", "cam_feed_scale_max = 2.0\nrapid_mm_s = 15000")},
     "[limits] rapid_mm_s: 15000 mm/s is above 10000 mm/s"),
    ("unknown robot", ["inspect", "{tmp}/j.toml"],
     {"j.toml": job('robot = "kr210_r2700_extra"', 'robot = "kr6"')},
     "[cell] robot: unknown robot 'kr6'"),
    # ---- a job that cannot be cut
    ("unreachable job, inspect", ["inspect", "{tmp}/j.toml"],
     {"j.toml": job("base_mm = [1500.0, -60.0, 400.0]", "base_mm = [1500.0, -60.0, 2500.0]")},
     "samples of job bracket_contour cannot be reached"),
    ("unreachable job, plan", ["plan", "{tmp}/j.toml", "-o", "{tmp}/out"],
     {"j.toml": job("base_mm = [1500.0, -60.0, 400.0]", "base_mm = [1500.0, -60.0, 2500.0]")},
     "out of the arm's reach"),
    ("infeasible job, plan", ["plan", "{tmp}/j.toml", "-o", "{tmp}/out"],
     {"j.toml": job("force_max_n = 300.0", "force_max_n = 5.0")},
     "force limit cannot be met even at feed_min_mm_s"),
    ("infeasible job, inspect", ["inspect", "{tmp}/j.toml"],
     {"j.toml": job("force_max_n = 300.0", "force_max_n = 5.0")}, "force limit"),
    # ---- the earlier findings that a user meets
    ("job file not UTF-8", ["plan", "{tmp}/j.toml", "-o", "{tmp}/out"],
     {"j.toml": job('name = "bracket_contour"', 'name = "caf\xe9"').encode("latin-1")},
     "{tmp}/j.toml: not UTF-8 text (byte 0xe9 on line"),
    ("TOML nested 1000 deep", ["plan", "{tmp}/j.toml", "-o", "{tmp}/out"],
     {"j.toml": "a = " + "[" * 1000 + "]" * 1000},
     "{tmp}/j.toml: not valid TOML: arrays or inline tables nest too deep"),
    ("plan.json with a wrong type, export", ["export", "{badplan}", "-o", "{tmp}/krl"], {},
     "{badplan}/plan.json: cycle_time_s: must be a finite number"),
    ("plan.json with a wrong type, supervise",
     ["supervise", "--plan", "{badplan}", "--signal", "sim", "--robot", "sim"], {},
     "{badplan}/plan.json: cycle_time_s: must be a finite number"),
    ("missing toolpath file", ["inspect", "{tmp}/missing.nc"], {},
     "{tmp}/missing.nc: not found"),
    ("job naming a missing toolpath", ["plan", "{tmp}/j.toml", "-o", "{tmp}/out"],
     {"j.toml": job(f"toolpath = [{DEMO_NC}]", 'toolpath = ["gone.nc"]')}, "gone.nc: not found"),
    ("unknown --format", ["inspect", str(demo_job_file().parent / "bracket_contour.nc"),
                          "--format", "xyz"], {}, "argument --format: invalid choice: 'xyz'"),
    ("unknown --method", ["plan", "--demo", "--method", "fast"], {},
     "argument --method: invalid choice: 'fast'"),
]


#: Rows that show what is not done yet, and why.
NOT_YET: dict[str, str] = {}
ROWS = [pytest.param(*row[1:], id=row[0], marks=[pytest.mark.xfail(strict=True,
                                                                   reason=NOT_YET[row[0]])]
                     if row[0] in NOT_YET else []) for row in MISTAKES]


@pytest.fixture(scope="session")
def planned(tmp_path_factory) -> dict[str, Path]:
    """``cctmill plan --demo`` once, and a copy of its plan with a string for a number."""
    root = tmp_path_factory.mktemp("planned")
    plan = root / "plan"
    with contextlib.redirect_stdout(io.StringIO()):
        assert main(["plan", "--demo", "-o", str(plan), "--json"]) == 0
    bad = root / "badplan"
    bad.mkdir()
    shutil.copy(plan / "samples.npz", bad / "samples.npz")
    doc = json.loads((plan / "plan.json").read_text(encoding="utf-8"))
    doc["cycle_time_s"] = "fast"
    (bad / "plan.json").write_text(json.dumps(doc), encoding="utf-8")
    return {"plan": plan, "badplan": bad}


@pytest.fixture
def read_only_as_seen_by_a_user(monkeypatch):
    """As root every folder is writable: let the output check see the mode bits a user would."""
    if os.geteuid() != 0:
        return
    import planner._atomic as atomic

    real = atomic.os.access

    def access(path, mode, **kw):
        if mode & os.W_OK and os.path.isdir(path) and not os.stat(path).st_mode & stat.S_IWUSR:
            return False
        return real(path, mode, **kw)

    monkeypatch.setattr(atomic.os, "access", access)


def _prepare(tmp: Path, files: dict) -> None:
    (tmp / "job.toml").write_text(job(), encoding="utf-8")
    for name, content in files.items():
        p = tmp / name
        if content is RO:
            p.mkdir()
            p.chmod(0o555)
        elif isinstance(content, bytes):
            p.write_bytes(content)
        else:
            p.write_text(content, encoding="utf-8")


def _run(argv: list[str]) -> int:
    try:
        return main(argv)
    except SystemExit as e:      # argparse's own errors
        return int(e.code or 0)


@pytest.mark.parametrize(("argv", "files", "names"), ROWS)
def test_a_user_mistake_is_status_2_and_one_line(request, tmp_path, capsys, planned, argv, files,
                                                 names, read_only_as_seen_by_a_user):
    where = {"tmp": str(tmp_path), "job": str(tmp_path / "job.toml"),
             **{k: str(v) for k, v in planned.items()}}
    _prepare(tmp_path, files)
    request.addfinalizer(lambda: [p.chmod(0o755) for p in tmp_path.iterdir() if p.is_dir()])
    capsys.readouterr()
    rc = _run([a.format(**where) for a in argv])
    err = capsys.readouterr().err
    lines = err.splitlines()
    assert rc == 2, err
    assert "Traceback" not in err
    assert len(lines) == 1 and lines[0].strip(), err
    assert names.format(**where) in lines[0], lines[0]


def test_an_output_mistake_fails_before_the_planning(tmp_path, capsys, monkeypatch):
    """The output folder is checked before the work: a long plan is not lost to a typo in -o."""
    import planner.plan

    def no_planning(*args, **kwargs):
        raise AssertionError("planned before the output folder was checked")

    monkeypatch.setattr(planner.plan, "plan_job", no_planning)
    (tmp_path / "file.nc").write_text("", encoding="utf-8")
    assert main(["plan", "--demo", "-o", str(tmp_path / "file.nc")]) == 2
    assert "it is a file, not a folder" in capsys.readouterr().err


def test_a_write_that_fails_anyway_is_one_output_error(tmp_path):
    """The writers themselves say a failed write as OutputError naming the target (here the
    system's own refusal, a file where the folder should be, met past the check)."""
    from planner._atomic import OutputError, output_errors, write_text_atomic

    (tmp_path / "f").write_text("", encoding="utf-8")
    with pytest.raises(OutputError, match=r"f/x\.json: cannot write"):
        write_text_atomic(tmp_path / "f" / "x.json", "{}")
    with pytest.raises(OutputError, match=r"f/k: cannot write"):
        with output_errors(tmp_path / "f" / "k"):
            (tmp_path / "f" / "k").mkdir(parents=True)
    with pytest.raises(ConnectionRefusedError):   # not about the output: left as it is
        with output_errors(tmp_path / "log", unnamed=False):
            raise ConnectionRefusedError("no controller")


def test_the_console_script_prints_the_line_without_a_traceback(tmp_path):
    """The installed entry point, as the issue ran it: ``cctmill plan demo_job.toml -o
    demo_job.toml``."""
    exe = Path(sys.executable).parent / "cctmill"
    if not exe.exists():
        pytest.skip("console script not installed")
    (tmp_path / "demo_job.toml").write_text(job(), encoding="utf-8")
    proc = subprocess.run([str(exe), "plan", "demo_job.toml", "-o", "demo_job.toml"],
                          cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    assert proc.stderr == ("cctmill plan: error: -o/--output demo_job.toml: cannot write: it is "
                           "a file, not a folder; give a folder name (it is made if missing)\n")


def test_every_option_that_names_an_output_is_checked_before_the_work():
    """Every output option goes through ``add_output`` (so ``check_outputs`` sees it): found by
    its name or its metavar, in every command."""
    import argparse
    import re

    from planner.cli import build_parser

    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    looks_like_output = re.compile(r"OUTDIR|\.(png|jsonl|csv|html|src)$", re.IGNORECASE)
    missed, seen = [], 0
    for command, parser in sub.choices.items():
        checked = {dest for dest, _, _ in parser.get_default("output_paths") or ()}
        for action in parser._actions:
            if action.dest in {"output", "out", "plot", "log"} or looks_like_output.search(
                    str(action.metavar or "")):
                seen += 1
                if action.dest not in checked:
                    missed.append(f"{command} {'/'.join(action.option_strings)}")
    assert seen >= 9 and missed == []
