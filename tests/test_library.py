"""The shipped library (docs/library.md): every material, tool and robot loads with its sources; a
small job plans on every robot; a tool that is not the coefficients' tool warns; KRL is refused
for a robot that is not a KUKA; ``cctmill robots | tools | materials`` list what ships."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest

from models import robot as robot_module
from models import tooling
from models.errors import DataFileError
from models.robot import DEFAULT_VENDOR, available_robots, load_robot, robot_data
from models.tooling import (
    COEFFICIENT_STATUSES,
    available_materials,
    available_tools,
    kienzle_linear_fit,
    load_material,
    load_tool,
)

#: A placement of the small test job within reach of each shipped robot: ($BASE origin, $TOOL
#: origin) [mm]. A robot added to models/data/robots needs its line here (the test says so).
PLACEMENT_MM = {
    "kr210_r2700_extra": ([1500.0, -60.0, 400.0], [320.0, 0.0, 0.0]),
    "kr270_r2700_ultra": ([1500.0, -60.0, 400.0], [320.0, 0.0, 0.0]),
    "kr500_r2830": ([2200.0, -60.0, 800.0], [320.0, 0.0, 0.0]),
}

#: A 40 mm straight cut, 2 mm deep: enough to plan a section, short enough to plan in well under
#: a second.
LINE_NC = "G21 G90\nG0 X-10 Y0 Z5\nG1 Z-2 F600\nG1 X30 F1200\nG0 Z5\nM30\n"

#: Relative rounding of the derived coefficients (written with 4 significant figures).
FOUR_FIGURES = 5e-4


# --------------------------------------------------------------------------------- materials
def test_the_issue_materials_ship() -> None:
    assert {"al6061", "aluminium_7075_t6", "aluminium_2024_t3", "steel_aisi1045", "titanium_ti6al4v",
            "cast_iron_grey"} <= set(available_materials())


@pytest.mark.parametrize("name", available_materials())
def test_every_material_loads_with_its_source(name: str) -> None:
    m = load_material(name)
    assert m.status in COEFFICIENT_STATUSES
    assert m.description and m.source and m.conditions
    assert np.all(m.coefficients() > 0)
    # the cutting coefficients are N/m² (1e8..1e10), the edge ones N/m (1e2..1e6): a unit slip
    # (N/mm² written as is) would land outside
    assert np.all((1e8 < m.coefficients()[:3]) & (m.coefficients()[:3] < 1e10))
    assert np.all((1e2 < m.coefficients()[3:]) & (m.coefficients()[3:] < 1e6))
    if m.status == "identified":
        assert m.identified_with in available_tools()


def test_the_published_al7075_set_is_the_review_table() -> None:
    # doi:10.1186/s10033-021-00536-9, Table 5, row [190], in N/mm² and N/mm
    m = load_material("aluminium_7075_t6")
    np.testing.assert_allclose(m.coefficients(), np.array([767.01e6, 168.8e6, 222e6,
                                                           27.7e3, 26.6e3, 0.7e3]), rtol=1e-12)
    assert m.status == "published" and m.identified_with is None


@pytest.mark.parametrize("name", [n for n in available_materials()
                                  if load_material(n).status == "derived"])
def test_a_derived_set_is_its_stated_derivation(name: str) -> None:
    m = load_material(name)
    d = m.derivation
    assert d["method"] == "kienzle_linear_fit"
    k_c, k_e = kienzle_linear_fit(d["kc1_N_per_mm2"] * 1e6, d["mc"], d["h_min_mm"] * 1e-3,
                                  d["h_max_mm"] * 1e-3)
    ref = load_material(d["ratios_from"])
    expected = [k_c, k_c * ref.k_rc / ref.k_tc, k_c * ref.k_ac / ref.k_tc,
                k_e, k_e * ref.k_re / ref.k_te, k_e * ref.k_ae / ref.k_te]
    np.testing.assert_allclose(m.coefficients(), expected, rtol=FOUR_FIGURES)
    assert set(m.sources) == {"k_tc", "k_rc", "k_ac", "k_te", "k_re", "k_ae"}


def test_the_kienzle_fit_is_exact_for_a_straight_law() -> None:
    # m_c = 0: F/b = k_c1 h is already a line through the origin
    k_c, k_e = kienzle_linear_fit(1.5e9, 0.0, 2e-5, 2e-4)
    assert k_c == pytest.approx(1.5e9, rel=1e-12)
    assert abs(k_e) < 1e-9 * 1.5e9 * 2e-4
    # m_c > 0 bends the law down: a positive edge term, a smaller slope than k_c1 (h/1 mm)^-m_c
    # at the range's top
    k_c, k_e = kienzle_linear_fit(1.5e9, 0.22, 2e-5, 2e-4)
    assert k_e > 0 and 1.5e9 * 0.2 ** -0.22 * 0.78 < k_c < 1.5e9 * 0.02 ** -0.22


GOOD = "k_tc = 9e8\nk_rc = 3e8\nk_ac = 3e8\nk_te = 6e3\nk_re = 6e3\nk_ae = 1e3\n"
TOOL = "flutes = 2\ndiameter_mm = 10\nhelix_angle_deg = 30\n"


@pytest.mark.parametrize(
    ("kind", "text", "match"),
    [
        ("materials", GOOD + 'status = "guessed"\n', "status.*identified"),
        ("materials", GOOD + '[sources]\nk_xx = "a book"\n', r"sources.*\['k_xx'\]"),
        ("materials", GOOD + "[sources]\nk_tc = 3\n", "must be strings"),
        ("tools", TOOL + "corner_radius_mm = 6.0\n", "more than half the diameter"),
        ("tools", TOOL + "corner_radius_mm = -1.0\n", "corner_radius"),
        ("tools", TOOL + "stick_out_mm = 0\n", "stick_out"),
        ("tools", TOOL + 'stick_out_mm = "40"\n', "stick_out_mm must be a number"),
    ],
)
def test_malformed_library_files(tmp_path, monkeypatch, kind: str, text: str, match: str) -> None:
    (tmp_path / kind).mkdir()
    (tmp_path / kind / "bad.toml").write_text(text, encoding="utf-8")
    monkeypatch.setattr(tooling, "_data_dir", lambda k: tmp_path / k)
    loader = load_material if kind == "materials" else load_tool
    with pytest.raises(DataFileError, match=match):
        loader("bad")


# --------------------------------------------------------------------------------- tools
def test_the_tool_library_spans_the_issue_range() -> None:
    tools = [load_tool(n) for n in available_tools()]
    assert 6 <= len(tools) <= 10
    assert {t.flutes for t in tools} == {2, 3, 4}
    assert min(t.diameter for t in tools) == pytest.approx(6e-3)
    assert max(t.diameter for t in tools) <= 25.4e-3 * (1 + 1e-12)


@pytest.mark.parametrize("name", available_tools())
def test_every_tool_loads_with_its_limits_and_source(name: str) -> None:
    t = load_tool(name)
    assert t.description and t.source
    assert t.feed_per_tooth_min is not None and t.feed_per_tooth_max is not None
    assert 1e-5 < t.feed_per_tooth_min < t.feed_per_tooth_max < 1e-3      # m, not mm
    assert t.spindle_speed_max is not None and 100.0 < t.spindle_speed_max < 3000.0   # rad/s
    assert 0.0 <= t.corner_radius < t.radius
    assert t.stick_out is None or 2 * t.radius < t.stick_out < 0.2


def test_the_new_tool_fields_are_si() -> None:
    t = load_tool("em12_4f_r1")
    assert (t.flutes, t.radius, t.corner_radius, t.stick_out) == pytest.approx(
        (4, 6e-3, 1e-3, 36e-3), rel=1e-12)
    assert t.spindle_speed_max == pytest.approx(2400.0 * 2 * math.pi / 60, rel=1e-12)
    # the descriptive fields do not make two otherwise equal tools differ
    assert replace(t, description="x", source="y") == t
    assert load_tool("em25_2f").corner_radius == 0.0 and load_tool("em25_2f").stick_out is None


# --------------------------------------------------------------------------------- robots
@pytest.mark.parametrize("name", available_robots())
def test_every_robot_loads_with_its_sources(name: str) -> None:
    data = robot_data(name)
    assert data.vendor and data.description
    assert {"kinematics", "joint_stiffness"} <= set(data.sources)
    assert np.all(data.joint_stiffness > 1e4)
    robot = load_robot(name)
    assert robot.nq == len(data.joint_names) == 6


def test_a_robot_file_without_a_vendor_is_kuka() -> None:
    assert DEFAULT_VENDOR == "kuka"
    assert robot_data("kr210_r2700_extra").vendor == "kuka"


def _small_job(tmp_path, robot: str, tool: str = "em10_3f", material: str = "al6061"):
    from planner.job import parse_job

    assert robot in PLACEMENT_MM, f"add a placement of the small test job for {robot} here"
    base, tcp = PLACEMENT_MM[robot]
    (tmp_path / "line.nc").write_text(LINE_NC, encoding="utf-8")
    doc = {"job": {"name": "library_line", "toolpath": ["line.nc"]},
           "cell": {"robot": robot, "base_mm": base, "tcp_mm": tcp},
           "tool": {"name": tool}, "material": material, "spindle": {"rpm": 4000.0},
           "engagement": {"ae_mm": 3.0, "ap_mm": 2.0}, "limits": {"deflection_tol_mm": 0.5}}
    return parse_job(doc, "library_line.toml", tmp_path)


@pytest.mark.parametrize("name", available_robots())
def test_a_small_job_plans_on_every_robot(tmp_path, name: str) -> None:
    from planner.plan import plan_job

    res = plan_job(_small_job(tmp_path, name), "optimize")
    assert res.solver.success
    ev = res.evaluation
    assert ev.force.size > 0 and np.all(np.isfinite(ev.deflection_norm))
    assert 0.0 < ev.deflection_norm.max() < 0.5e-3          # within the job's tolerance
    # em10_3f is not em25_2f, the tool al6061 was identified with
    assert "coefficients" in {w.kind for w in res.warnings}


# --------------------------------------------------------------------------------- mismatch
def test_a_tool_coefficient_mismatch_warns() -> None:
    from planner.tool_limits import tool_warnings

    al6061 = load_material("al6061")
    assert tool_warnings(load_tool("em25_2f"), al6061) == []
    (w,) = tool_warnings(load_tool("em6_2f"), al6061)
    assert w.kind == "coefficients"
    assert "identified with em25_2f (25.4 mm, 2 flutes)" in w.message
    assert "6 mm, 2 flutes" in w.message and "extrapolated" in w.message
    # a set that names no identification tool warns with every tool
    for name in ("aluminium_7075_t6", "titanium_ti6al4v"):
        (w,) = tool_warnings(load_tool("em25_2f"), load_material(name))
        assert w.kind == "coefficients" and "do not say which tool" in w.message


# --------------------------------------------------------------------------------- KRL export
def test_krl_export_refuses_a_robot_that_is_not_a_kuka(tmp_path, monkeypatch) -> None:
    from planner.export import ExportError, plan_to_krl
    from planner.plan import plan_job, plan_of_result

    plan = plan_of_result(plan_job(_small_job(tmp_path, "kr210_r2700_extra"), "constant"))
    assert plan_to_krl(plan).moves                          # a KUKA plan exports
    real = robot_module.robot_data
    monkeypatch.setattr(robot_module, "robot_data", lambda n: replace(real(n), vendor="abb"))
    with pytest.raises(ExportError, match=r"for kr210_r2700_extra, whose controller is 'abb', "
                                          r"not KUKA: KRL runs on KUKA controllers only"):
        plan_to_krl(plan)


# --------------------------------------------------------------------------------- CLI
@pytest.mark.parametrize(("command", "lister"), [("robots", available_robots),
                                                 ("tools", available_tools),
                                                 ("materials", available_materials)])
def test_the_library_commands_list_what_ships(capsys, command: str, lister) -> None:
    from planner.cli import main

    assert main([command]) == 0
    table = capsys.readouterr().out
    assert all(name in table for name in lister())
    assert "source" in table
    assert main([command, "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert [r["name"] for r in rows] == lister()
    assert all(r.get("source") or r.get("sources") for r in rows)


# --------------------------------------------------------------------------------- docs
@pytest.mark.parametrize("kind", ["materials", "tools", "robots"])
def test_the_library_page_holds_the_current_tables(kind: str) -> None:
    from pathlib import Path

    from planner.cli import library

    page = (Path(__file__).resolve().parents[1] / "docs" / "library.md").read_text(
        encoding="utf-8")
    start, end = f"<!-- library-{kind}:start -->", f"<!-- library-{kind}:end -->"
    assert start in page and end in page
    block = page[page.index(start) + len(start):page.index(end)]
    entries = getattr(library, f"{kind[:-1]}_entries")()
    expected = getattr(library, f"{kind}_markdown")(entries)
    assert block.strip() == expected.strip(), f"paste `cctmill {kind} --markdown` into the page"
