"""``cctmill robots``, ``cctmill tools``, ``cctmill materials``: what ships in ``models/data``, with
the source of every value (docs/library.md).

Each command reads the shipped data files (:func:`models.robot.robot_data`,
:func:`models.tooling.load_tool`, :func:`models.tooling.load_material`) and prints a table, with
``--json`` one JSON list whose keys carry their units as the data files do, or with ``--markdown``
the Markdown table that docs/library.md holds between its ``<!-- library-KIND:start -->`` and
``<!-- library-KIND:end -->`` markers (a test checks the page against it).
"""

from __future__ import annotations

import argparse
import json
import math
from typing import Any

__all__ = [
    "material_entries",
    "materials_markdown",
    "materials_table",
    "register",
    "robot_entries",
    "robots_markdown",
    "robots_table",
    "tool_entries",
    "tools_markdown",
    "tools_table",
]

#: Display scales: N/m² → N/mm², N/m → N/mm, N·m/rad → MN·m/rad.
_PER_MM2 = 1e-6
_PER_MM = 1e-3
_MEGA = 1e-6
#: Significant digits of the numbers ``--json`` prints (unit conversions leave 1e-16 dust).
_JSON_DIGITS = 12


def _round(v: Any) -> Any:
    if isinstance(v, float):
        return float(f"{v:.{_JSON_DIGITS}g}")
    if isinstance(v, list):
        return [_round(x) for x in v]
    if isinstance(v, dict):
        return {k: _round(x) for k, x in v.items()}
    return v


def material_entries() -> list[dict[str, Any]]:
    """Every shipped material: coefficients (SI, unit in the key) and where they come from."""
    from models.tooling import available_materials, load_material

    out = []
    for name in available_materials():
        m = load_material(name)
        out.append({
            "name": name, "description": m.description, "status": m.status,
            "identified_with_tool": m.identified_with,
            "k_tc_N_per_m2": m.k_tc, "k_rc_N_per_m2": m.k_rc, "k_ac_N_per_m2": m.k_ac,
            "k_te_N_per_m": m.k_te, "k_re_N_per_m": m.k_re, "k_ae_N_per_m": m.k_ae,
            "source": m.source, "conditions": m.conditions, "sources": m.sources,
            "derivation": m.derivation})
    return out


def tool_entries() -> list[dict[str, Any]]:
    """Every shipped tool, in the data files' units (mm, deg, rpm)."""
    from models.tooling import available_tools, load_tool

    out = []
    for name in available_tools():
        t = load_tool(name)
        fz = (None if t.feed_per_tooth_min is None or t.feed_per_tooth_max is None
              else [t.feed_per_tooth_min * 1e3, t.feed_per_tooth_max * 1e3])
        out.append({
            "name": name, "description": t.description, "diameter_mm": t.diameter * 1e3,
            "flutes": t.flutes, "helix_angle_deg": math.degrees(t.helix_angle),
            "corner_radius_mm": t.corner_radius * 1e3,
            "stick_out_mm": None if t.stick_out is None else t.stick_out * 1e3,
            "feed_per_tooth_mm": fz,
            "rpm_max": (None if t.spindle_speed_max is None
                        else t.spindle_speed_max * 60.0 / (2.0 * math.pi)),
            "source": t.source})
    return out


def robot_entries() -> list[dict[str, Any]]:
    """Every shipped robot's data file (no URDF parsed): vendor, stiffness, limits, sources."""
    import numpy as np

    from models.robot import available_robots, robot_data

    out = []
    for name in available_robots():
        d = robot_data(name)
        out.append({
            "name": name, "vendor": d.vendor, "description": d.description,
            "joint_names": list(d.joint_names),
            "joint_stiffness_Nm_per_rad": d.joint_stiffness.tolist(),
            "lower_deg": np.rad2deg(d.lower).tolist(), "upper_deg": np.rad2deg(d.upper).tolist(),
            "spindle_mass_kg": d.spindle_mass, "urdf": d.urdf_path.name,
            "krl_export": d.vendor == "kuka", "sources": d.sources})
    return out


def _opt(v: float | None, fmt: str) -> str:
    return "-" if v is None else format(v, fmt)


def materials_table(entries: list[dict[str, Any]]) -> str:
    """The ``cctmill materials`` table (N/mm² and N/mm)."""
    w = max([len("material"), *(len(e["name"]) for e in entries)])
    lines = [f"{'material':<{w}} {'status':<10} {'K_tc':>7} {'K_rc':>7} {'K_ac':>7} "
             f"{'K_te':>6} {'K_re':>6} {'K_ae':>6}  identified with",
             f"{'':<{w}} {'':<10} {'[N/mm²]':>23} {'[N/mm]':>20}"]
    for e in entries:
        lines.append(
            f"{e['name']:<{w}} {e['status'] or '-':<10} "
            f"{e['k_tc_N_per_m2'] * _PER_MM2:>7.1f} {e['k_rc_N_per_m2'] * _PER_MM2:>7.1f} "
            f"{e['k_ac_N_per_m2'] * _PER_MM2:>7.1f} {e['k_te_N_per_m'] * _PER_MM:>6.2f} "
            f"{e['k_re_N_per_m'] * _PER_MM:>6.2f} {e['k_ae_N_per_m'] * _PER_MM:>6.2f}  "
            f"{e['identified_with_tool'] or 'not recorded'}")
        if e["description"]:
            lines.append(f"    {e['description']}")
        lines.append(f"    source: {e['source'] or 'not recorded'}")
        if e["conditions"]:
            lines.append(f"    conditions: {e['conditions']}")
    lines.append("derived = computed from published data, not identified with an end mill; a plan "
                 "whose tool is not the one named warns (docs/library.md)")
    return "\n".join(lines)


def tools_table(entries: list[dict[str, Any]]) -> str:
    """The ``cctmill tools`` table."""
    w = max([len("tool"), *(len(e["name"]) for e in entries)])
    lines = [f"{'tool':<{w}} {'D mm':>5} {'z':>2} {'helix':>5} {'r_c mm':>6} {'out mm':>6} "
             f"{'f_z mm':>11} {'rpm max':>7}  description"]
    for e in entries:
        fz = e["feed_per_tooth_mm"]
        fz_text = "-" if fz is None else f"{fz[0]:.3f}-{fz[1]:.3f}"
        lines.append(
            f"{e['name']:<{w}} {e['diameter_mm']:>5.1f} {e['flutes']:>2} "
            f"{e['helix_angle_deg']:>5.1f} {e['corner_radius_mm']:>6.1f} "
            f"{_opt(e['stick_out_mm'], '6.1f'):>6} {fz_text:>11} {_opt(e['rpm_max'], '7.0f'):>7}  "
            f"{e['description'] or ''}")
        lines.append(f"    source: {e['source'] or 'not recorded'}")
    return "\n".join(lines)


def robots_table(entries: list[dict[str, Any]]) -> str:
    """The ``cctmill robots`` table (joint stiffness in MN·m/rad)."""
    lines = []
    for e in entries:
        k = ", ".join(f"{v * _MEGA:.3g}" for v in e["joint_stiffness_Nm_per_rad"])
        lines.append(f"{e['name']}  ({e['vendor']}{'' if e['krl_export'] else ', no KRL export'})"
                     f"  {e['description']}")
        lines.append(f"    joint stiffness [MN·m/rad]: {k}")
        for key, text in sorted(e["sources"].items()):
            lines.append(f"    {key}: {text}")
    return "\n".join(lines)


def _md_row(cells: list[Any]) -> str:
    return "| " + " | ".join(str(c) for c in cells) + " |"


def materials_markdown(entries: list[dict[str, Any]]) -> str:
    """docs/library.md's table of every material's coefficients and sources, then the per-value
    sources where a file gives them."""
    lines = [_md_row(["material", "status", "K_tc [N/mm²]", "K_rc [N/mm²]", "K_ac [N/mm²]",
                      "K_te [N/mm]", "K_re [N/mm]", "K_ae [N/mm]", "identified with", "source"]),
             "|---|---|--:|--:|--:|--:|--:|--:|---|---|"]
    per_value = []
    for e in entries:
        lines.append(_md_row([
            f"`{e['name']}` {e['description'] or ''}", e["status"] or "—",
            f"{e['k_tc_N_per_m2'] * _PER_MM2:.1f}", f"{e['k_rc_N_per_m2'] * _PER_MM2:.1f}",
            f"{e['k_ac_N_per_m2'] * _PER_MM2:.1f}", f"{e['k_te_N_per_m'] * _PER_MM:.2f}",
            f"{e['k_re_N_per_m'] * _PER_MM:.2f}", f"{e['k_ae_N_per_m'] * _PER_MM:.2f}",
            f"`{e['identified_with_tool']}`" if e["identified_with_tool"] else
            f"not recorded ({e['conditions']})" if e["conditions"] else "not recorded",
            e["source"] or "not recorded"]))
        per_value += [_md_row([f"`{e['name']}`", f"`{k}`", v]) for k, v in e["sources"].items()]
    out = "\n".join(lines)
    if per_value:
        out += ("\n\nPer-value sources, where a file gives them:\n\n"
                + _md_row(["material", "coefficient", "source"]) + "\n|---|---|---|\n"
                + "\n".join(per_value))
    return out


def tools_markdown(entries: list[dict[str, Any]]) -> str:
    """docs/library.md's table of the tool library."""
    lines = [_md_row(["tool", "D [mm]", "flutes", "helix [deg]", "corner r [mm]",
                      "stick-out [mm]", "f_z [mm]", "rpm max", "source"]),
             "|---|--:|--:|--:|--:|--:|--:|--:|---|"]
    for e in entries:
        fz = e["feed_per_tooth_mm"]
        lines.append(_md_row([
            f"`{e['name']}`", f"{e['diameter_mm']:g}", e["flutes"], f"{e['helix_angle_deg']:g}",
            f"{e['corner_radius_mm']:g}", _opt(e["stick_out_mm"], "g").replace("-", "—"),
            "—" if fz is None else f"{fz[0]:.3f}–{fz[1]:.3f}",
            _opt(e["rpm_max"], ".0f").replace("-", "—"), e["source"] or "not recorded"]))
    return "\n".join(lines)


def robots_markdown(entries: list[dict[str, Any]]) -> str:
    """docs/library.md's table of the shipped robots."""
    lines = [_md_row(["robot", "vendor", "KRL export", "K_θ [MN·m/rad]", "sources"]),
             "|---|---|---|---|---|"]
    for e in entries:
        lines.append(_md_row([
            f"`{e['name']}` {e['description']}", e["vendor"], "yes" if e["krl_export"] else "no",
            ", ".join(f"{v * _MEGA:.3g}" for v in e["joint_stiffness_Nm_per_rad"]),
            "; ".join(f"{k}: {v}" for k, v in sorted(e["sources"].items()))]))
    return "\n".join(lines)


def _runner(entries, table, markdown):
    def run(args: argparse.Namespace) -> int:
        rows = entries()
        if args.json:
            print(json.dumps(_round(rows), indent=2, ensure_ascii=False))
        else:
            print(markdown(rows) if args.markdown else table(rows))
        return 0
    return run


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``robots``, ``tools`` and ``materials``."""
    for name, what, entries, table, markdown in (
            ("robots", "the shipped robots (kinematics, joint stiffness, vendor) and their sources",
             robot_entries, robots_table, robots_markdown),
            ("tools", "the shipped tool library (diameter, flutes, helix, limits) and its sources",
             tool_entries, tools_table, tools_markdown),
            ("materials", "the shipped materials' cutting coefficients and their sources",
             material_entries, materials_table, materials_markdown)):
        p = sub.add_parser(name, help=f"list {what}", description=f"List {what}.")
        form = p.add_mutually_exclusive_group()
        form.add_argument("--json", action="store_true",
                          help="print JSON (units in the key names) instead of a table")
        form.add_argument("--markdown", action="store_true",
                          help="print the Markdown table of docs/library.md")
        p.set_defaults(run=_runner(entries, table, markdown))
