"""Figures of the dynamic model for the manual's docs/dynamics.md (docs/model.md §6, §7): iteration,
engagement estimate, how regeneration moves the stability boundary, and the workspace map of the
dynamic effect.

1. Case 1 (pose and cut of the thesis, 1000 rpm, 1 mm/s, regeneration on): F_peak and F_PV of
   the equilibrium chip against the thesis's first iteration (the structure answers the
   rigid-chip force, the chip is updated once).
2. Engagement estimate: a_e from the mean force of simulated stable cuts (4000 rpm, a_p 1 mm,
   c 0.1 mm, Case 1's pose), up and down milling, a_e 1…20 mm.
3. Critical axial depth at Case 1's pose (bisection, 2 %): Floquet (no regeneration), the
   simulation without regeneration, the simulation with regeneration (the real surface).
4. Workspace map: F_PV/F_peak over an A2 × A3 grid around Case 1's pose, the cut following the tool
   (Y_o = tool axis), at 4000 rpm and at 1000 rpm; `ok` where the static force model holds
   (F_PV < 10 % F_peak); the PNGs go to out/.

Run from the repository root: ``python benchmarks/dynamics_validation.py``.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from models import Cut, ModelParameters, load_material, load_robot, load_tool  # noqa: E402
from models.deflection import estimate_radial_depth  # noqa: E402
from models.dynamic_map import STATIC_VALIDITY, critical_depth, dynamic_map  # noqa: E402
from models.dynamics import pose_structure, simulate  # noqa: E402
from models.floquet import floquet  # noqa: E402

CASE1_Q = np.radians([-96.42, -29.26, 99.08, -9.95, 83.23, -160.5])
MAT = load_material("al6061")
TOOL = load_tool("em25_2f")
OUT = REPO / "out"


def _model(tcp=(0.32, 0.0, 0.0)):
    robot = load_robot()
    return robot, ModelParameters(joint_stiffness=robot.data.joint_stiffness,
                                  coefficients=MAT.coefficients(),
                                  spindle_mass=robot.data.spindle_mass,
                                  spindle_com=robot.data.spindle_com, tcp=np.array(tcp))


def _cut(a_e, a_p, mode, rpm, feed_dir=(0, 1, 0), radial=(1, 0, 0)):
    return Cut(np.array(feed_dir, float), np.array(radial, float), a_e, a_p, mode,
               rpm * np.pi / 30, TOOL.flutes, TOOL.radius)


def iteration_table() -> str:
    robot, params = _model((0.0, 0.0, 0.0))
    rows = ["| Case 1 pose, up milling, 1000 rpm, 1 mm/s | Floquet ρ | F_peak N (equilibrium / first "
            "iteration) | F_PV N (equilibrium / first iteration) | iterations per step |",
            "|---|---|---|---|---|"]
    for a_e, a_p in ((15.24e-3, 5.08e-3), (15.24e-3, 1.0e-3), (5e-3, 1.0e-3)):
        cut = _cut(a_e, a_p, "up", 1000.0)
        st = pose_structure(robot, params, CASE1_Q, cut, 1e-3)
        rho = floquet(st, cut, MAT, TOOL.helix_angle).spectral_radius
        conv = simulate(st, cut, 1e-3, MAT, TOOL.helix_angle)
        first = simulate(st, cut, 1e-3, MAT, TOOL.helix_angle, iterate=False)
        rows.append(f"| a_e {a_e * 1e3:.2f} mm, a_p {a_p * 1e3:.2f} mm | {rho:.3f} | "
                    f"{conv.f_peak:.1f} / {first.f_peak:.1f} | {conv.f_pv:.1f} / {first.f_pv:.1f} | "
                    f"{conv.iterations_mean:.2f} |")
    return "\n".join(rows)


def estimate_table() -> str:
    robot, params = _model()
    rpm, c = 4000.0, 0.1e-3
    feed = c * 2 * rpm / 60
    errs = {}
    for mode in ("up", "down"):
        out = []
        for a_e_mm in (1.0, 3.0, 6.0, 10.0, 15.0, 20.0):
            cut = _cut(a_e_mm * 1e-3, 1e-3, mode, rpm)
            st = pose_structure(robot, params, CASE1_Q, cut, feed)
            sim = simulate(st, cut, feed, MAT, TOOL.helix_angle, duration=0.6)
            mean = sim.force[len(sim.time) // 2:].mean(axis=0)
            est = estimate_radial_depth(mean, c, mode, 2, TOOL.radius, MAT, prior=a_e_mm * 1e-3)
            out.append(100 * (est * 1e3 - a_e_mm) / a_e_mm)
        errs[mode] = out
    rows = ["| a_e mm | 1 | 3 | 6 | 10 | 15 | 20 |", "|---|---|---|---|---|---|---|"]
    for mode, out in errs.items():
        rows.append(f"| {mode}: error % | " + " | ".join(f"{e:+.2f}" for e in out) + " |")
    return "\n".join(rows)


def boundary_table() -> str:
    robot, params = _model()
    rows = ["| cut at Case 1's pose (c 0.1 mm) | Floquet, no regeneration | simulation, no "
            "regeneration | simulation, regeneration |", "|---|---|---|---|"]
    for rpm, a_e, mode in ((1000.0, 6e-3, "up"), (4000.0, 6e-3, "up"), (4000.0, 6e-3, "down")):
        cut = _cut(a_e, 1e-3, mode, rpm)
        feed = 0.1e-3 * 2 * rpm / 60
        depths = [critical_depth(robot, params, CASE1_Q, cut, feed, TOOL.helix_angle, j,
                                 a_p_range=(1e-4, 8e-3), tol=0.02)
                  for j in ("floquet", "simulation", "regeneration")]
        cells = [(f"{d * 1e3:.3f} mm" if d < 8e-3 else "> 8 mm") for d in depths]
        rows.append(f"| {rpm:.0f} rpm, {mode}, a_e {a_e * 1e3:.0f} mm | " + " | ".join(cells)
                    + " |")
    return "\n".join(rows)


def workspace(rpm: float, a_e: float, a_p: float, mode: str, n: int = 5) -> tuple[str, Path]:
    robot, params = _model()
    # In the TCP frame the tool axis is +x: feed Z_o = +y, radial X_o = +z, so Y_o = Z_o × X_o
    # = y × z = +x, the tool axis.
    cut_tcp = _cut(a_e, a_p, mode, rpm, feed_dir=(0, 1, 0), radial=(0, 0, 1))
    a2 = np.linspace(-50.0, -10.0, n)
    a3 = np.linspace(60.0, 120.0, n)
    qs = []
    for x in a2:
        for y in a3:
            q = np.degrees(CASE1_Q).copy()
            q[1], q[2] = x, y
            qs.append(np.radians(q))
    feed = 0.1e-3 * 2 * rpm / 60
    m = dynamic_map(robot, params, np.array(qs), cut_tcp, feed, TOOL.helix_angle, duration=1.0)
    ratio = m.ratio.reshape(n, n)
    rows = ["| A2 \\ A3 deg | " + " | ".join(f"{y:.0f}" for y in a3) + " |",
            "|---|" + "---|" * n]
    for i, x in enumerate(a2):
        cells = []
        for j in range(n):
            r = ratio[i, j]
            cells.append("—" if not np.isfinite(r) else
                         f"{100 * r:.0f} % {'ok' if r < STATIC_VALIDITY else ''}".strip())
        rows.append(f"| {x:.0f} | " + " | ".join(cells) + " |")
    OUT.mkdir(exist_ok=True)
    path = OUT / f"dynamic_map_{rpm:.0f}rpm.png"
    from planner.report.plots import new_figure, save_figure

    plt, fig = new_figure(figsize=(6, 5))
    ax = fig.add_subplot(1, 1, 1)
    im = ax.pcolormesh(a3, a2, 100 * ratio, shading="nearest", cmap="viridis")
    fig.colorbar(im, ax=ax, label="F_PV / F_peak [%]")
    for i, x in enumerate(a2):
        for j, y in enumerate(a3):
            if np.isfinite(ratio[i, j]) and ratio[i, j] < STATIC_VALIDITY:
                ax.plot(y, x, "w+", ms=10)
    ax.set_xlabel("A3 [deg]")
    ax.set_ylabel("A2 [deg]")
    save_figure(plt, fig, f"{mode} a_e {a_e * 1e3:.0f} mm a_p {a_p * 1e3:.1f} mm, {rpm:.0f} rpm: "
          "+ = static force model valid", path)
    valid = int(np.sum(m.valid))
    total = int(np.sum(np.isfinite(m.ratio)))
    return "\n".join(rows) + f"\n\nstatic force model valid at {valid} of {total} poses", path


def main() -> None:
    t0 = time.perf_counter()
    print("## Iteration (Case 1, regeneration on)\n")
    print(iteration_table())
    print("\n## Engagement estimate from simulated mean forces\n")
    print(estimate_table())
    print("\n## Critical axial depth: how regeneration moves the boundary\n")
    print(boundary_table())
    for rpm in (4000.0, 1000.0):
        table, path = workspace(rpm, 6e-3, 1.0e-3, "down")
        print(f"\n## Workspace map, down milling a_e 6 mm a_p 1 mm, {rpm:.0f} rpm ({path})\n")
        print(table)
    print(f"\n_{time.perf_counter() - t0:.0f} s_")


if __name__ == "__main__":
    main()
