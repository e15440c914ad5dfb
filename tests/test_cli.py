"""The ``cctmill`` command line: the contract later issues rely on, and one-line errors."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys

import numpy as np
import pytest

from planner.cli import main

CASE1 = ["--joints-deg", "-96.42,-29.26,99.08,-9.95,83.23,-160.5", "--feed-dir", "0,1,0",
         "--radial-dir", "1,0,0", "--ae-mm", "15.24", "--ap-mm", "5.08"]
ANALYZE_KEYS = {
    "force_N", "force_base_N", "alpha_deg", "beta_deg", "gamma_deg", "k_px_N_per_m",
    "k_py_N_per_m", "k_max_N_per_m", "k_min_N_per_m", "k_p_N_per_m", "eig_A", "stable",
    "margin_N_per_m", "stiffness_N_per_m", "warnings",
}


def _json(capsys, argv):
    assert main(argv) == 0
    return json.loads(capsys.readouterr().out)


def test_analyze_case1_contract(capsys):
    """Issue item 3: the thesis's Case 1 prints |F| ≈ 71.5 N and k_py ≈ −1.41e4 N/m."""
    out = _json(capsys, ["analyze", *CASE1, "--feed-mm-s", "1", "--json"])
    assert ANALYZE_KEYS <= out.keys()
    assert np.linalg.norm(out["force_N"]) == pytest.approx(71.5, rel=2e-3)
    assert out["k_py_N_per_m"] == pytest.approx(-1.41e4, rel=3e-3)
    assert np.array(out["k_p_N_per_m"]).shape == (2, 2)
    assert np.array(out["stiffness_N_per_m"]).shape == (3, 3)
    assert len(out["eig_A"]) == 2 and all(len(e) == 2 for e in out["eig_A"])
    assert out["stable"] == (out["margin_N_per_m"] > 0)
    # Force in base = [X_o Y_o Z_o] F_o with X_o = x, Z_o = y, Y_o = Z_o × X_o = −z.
    f = np.array(out["force_N"])
    assert np.allclose(out["force_base_N"], [f[0], f[2], -f[1]])
    assert any("63." in w for w in out["warnings"])  # docs/model.md §4: Case 1's tool axis is 63° off Y_o


def test_analyze_robot_mass_gives_frequencies_and_flags_change_model(capsys):
    iso = _json(capsys, ["analyze", *CASE1, "--feed-mm-s", "1", "--json"])
    assert "natural_frequencies_hz" not in iso
    rob = _json(capsys, ["analyze", *CASE1, "--feed-mm-s", "1", "--json", "--mass", "robot"])
    f = rob["natural_frequencies_hz"]
    assert len(f) == 2 and all(3.0 < v < 50.0 for v in f)
    ori = _json(capsys, ["analyze", *CASE1, "--feed-mm-s", "1", "--json", "--process-model",
                         "oriented"])
    # docs/model.md §5: the two process models differ by about two orders of magnitude.
    ratio = np.abs(ori["k_p_N_per_m"]).max() / np.abs(iso["k_p_N_per_m"]).max()
    assert ratio > 30
    conv = _json(capsys, ["analyze", *CASE1, "--feed-mm-s", "1", "--json", "--no-cct"])
    assert conv["cct"] is False
    assert not np.allclose(conv["stiffness_N_per_m"], iso["stiffness_N_per_m"], rtol=1e-9)
    tcp = _json(capsys, ["analyze", *CASE1, "--feed-mm-s", "1", "--json", "--tcp-mm", "200,0,0"])
    assert np.linalg.norm(np.subtract(tcp["tcp_position_m"], iso["tcp_position_m"])) == \
        pytest.approx(0.2, abs=1e-9)


def test_analyze_table_is_readable(capsys):
    assert main(["analyze", *CASE1, "--feed-mm-s", "1"]) == 0
    text = capsys.readouterr().out
    for word in ("gamma", "K_px", "margin", "STABLE", "deflection", "warning"):
        assert word in text


def test_stability_json_and_plot(capsys, tmp_path):
    png = tmp_path / "st.png"
    rows = _json(capsys, ["stability", *CASE1, "--feed-range-mm-s", "1:10:4", "--json",
                          "--plot", str(png)])
    assert [r["feed_mm_s"] for r in rows] == pytest.approx([1, 4, 7, 10])
    assert ANALYZE_KEYS <= rows[0].keys()
    forces = [np.linalg.norm(r["force_N"]) for r in rows]
    assert np.all(np.diff(forces) > 0)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 10_000


def test_stability_table_names_the_binding_limit(capsys):
    assert main(["stability", *CASE1, "--feed-range-mm-s", "1:10:10"]) == 0
    last = capsys.readouterr().out.strip().splitlines()[-1]
    # 300 N is reached between 5 and 6 mm/s for this cut (about 5.4); the thesis model is stable.
    assert last.startswith("feed limit 5.000 mm/s, bound by force")


@pytest.mark.parametrize(("change", "message"), [
    (["--ae-mm", "30"], r"--ae-mm: .*tool diameter"),
    (["--radial-dir", "1,1,0"], r"--radial-dir: must be orthogonal"),
    (["--feed-dir", "0,0,0"], r"--feed-dir: direction is the zero vector"),
    (["--material", "steel"], r"unknown material 'steel'; available: al6061"),
    (["--joints-deg", "0,-90,90,0,0,0"], r"singular pose"),
    (["--joints-deg", "0,-190,90,0,0,0"], r"A2 = -190.00 deg is outside its limits"),
    (["--joints-deg", "1,2,3"], r"--joints-deg: need 6"),
    (["--feed-mm-s", "0"], r"--feed-mm-s: must be positive"),
    (["--ap-mm", "-1"], r"--ap-mm: must be positive"),
    (["--milling", "side"], r"invalid choice: 'side'"),
    (["--robot", "kr6"], r"unknown robot 'kr6'"),
])
def test_bad_input_is_one_clear_line(capsys, change, message):
    argv = ["analyze", *CASE1, "--feed-mm-s", "1"]
    for i in range(0, len(change), 2):
        if change[i] in argv:
            argv[argv.index(change[i]) + 1] = change[i + 1]
        else:
            argv += change[i:i + 2]
    try:
        rc = main(argv)
    except SystemExit as e:  # argparse's own errors
        rc = e.code
    assert rc == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1
    assert "Traceback" not in err
    import re

    assert re.search(message, err), err


def test_demo_writes_outputs(tmp_path, capsys):
    assert main(["demo", "-o", str(tmp_path)]) == 0
    files = sorted(p.name for p in tmp_path.iterdir())
    assert "case1_thesis_isotropic_analysis.json" in files
    assert "case1_oriented_robot_stability.png" in files
    assert not any(name.startswith(".") for name in files)  # no temporary files left behind
    data = json.loads((tmp_path / "case1_thesis_robot_analysis.json").read_text())
    assert np.linalg.norm(data["force_N"]) == pytest.approx(71.5, rel=2e-3)
    # the whole product: plan, report, KRL, supervised run with its log and plot
    for name in ("plan.json", "samples.npz", "report.html", "plan_along_path.png",
                 "supervise_events.jsonl", "supervise.png"):
        assert (tmp_path / name).stat().st_size > 1000, name
    assert (tmp_path / "krl" / "bracket_contour.src").is_file()
    events = [json.loads(line) for line in
              (tmp_path / "supervise_events.jsonl").read_text().splitlines()]
    assert events and all({"t_s", "section", "override", "reason"} <= set(e) for e in events[:50])
    out = capsys.readouterr().out
    headline = [line for line in out.splitlines() if line.startswith("headline:")]
    assert len(headline) == 1
    assert "thesis baseline" in headline[0] and "deflection" in headline[0]
    caught = int(headline[0].rsplit("chatter episodes caught", 1)[1])
    assert caught >= 1
    # what was caught is the simulated chatter, not a transient: the first alarm follows it
    supervised = next(line for line in out.splitlines() if line.startswith("== Supervised run"))
    assert "ms after the chatter became visible" in supervised.split("; section ", 2)[1], supervised


@pytest.mark.skipif(shutil.which("cctmill") is None and not (
    __import__("pathlib").Path(sys.executable).parent / "cctmill").exists(),
    reason="console script not installed")
def test_console_script_error_has_no_traceback():
    exe = __import__("pathlib").Path(sys.executable).parent / "cctmill"
    proc = subprocess.run([str(exe), "analyze", *CASE1, "--feed-mm-s", "1", "--ae-mm", "40"],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr


def test_an_output_folder_that_cannot_be_written_is_one_line(tmp_path, capsys):
    from planner._atomic import OutputError, write_text_atomic

    blocker = tmp_path / "file"
    blocker.write_text("x", encoding="utf-8")           # a file where a folder should be
    with pytest.raises(OutputError, match="cannot write.*choose another output folder"):
        write_text_atomic(blocker / "plan.json", "{}")
    assert main(["demo", "-o", str(blocker / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("cctmill demo: error:") and "out" in err[0]
