"""Agreement cases for the dynamic simulation, found with the physics core (not by hand).

A seeded random search over reachable, non-singular KR 210 poses (tool axis along Y_o), radial and
axial depths, feed per tooth and spindle speed; each candidate is judged by the Floquet criterion
and by the averaged (``oriented``, ``robot`` mass) eigen model; cases clear of the boundary on both
sides are kept and simulated. Used by tests/test_floquet.py and, as a table, by
``.venv/bin/python tests/_dynamics_cases.py`` (the figures of docs/dynamics.md).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from models import Cut, ModelParameters, PointModel, load_material, load_robot, load_tool
from models.dynamics import (
    DEFAULT_DAMPING_RATIO,
    cutter_geometry,
    pose_structure,
    process_stiffness_series,
    simulate,
)
from models.errors import CctmillError
from models.floquet import floquet_batch

#: Growth rates [1/s] closer to zero than this are "near the boundary" and not used.
CLEARANCE = 3.0
SEED = 7


@dataclass(frozen=True)
class Case:
    q: np.ndarray
    cut: Cut
    feed: float
    rpm: float
    floquet_growth: float
    floquet_hz: float
    eigen_stable: bool
    average_growth: float


def _setup():
    robot = load_robot()
    material = load_material("al6061")
    tool = load_tool("em25_2f")
    params = ModelParameters(joint_stiffness=robot.data.joint_stiffness,
                             coefficients=material.coefficients(),
                             spindle_mass=robot.data.spindle_mass,
                             spindle_com=robot.data.spindle_com, tcp=np.array([0.32, 0.0, 0.0]))
    return robot, material, tool, params


def candidates(n: int, rpm_choices, seed: int = SEED) -> list[Case]:
    """``n`` random (pose, cut) candidates with their Floquet and averaged verdicts."""
    robot, material, tool, params = _setup()
    point = PointModel(robot, params, "oriented", "robot")
    rng = np.random.default_rng(seed)
    lo, hi = robot.data.lower, robot.data.upper
    out_q, out_cut, out_feed, out_rpm, structures = [], [], [], [], []
    while len(out_q) < n:
        q = np.radians([rng.uniform(-60, 60), rng.uniform(-100, -20), rng.uniform(20, 130),
                        rng.uniform(-90, 90), rng.uniform(30, 110), rng.uniform(-180, 180)])
        q = np.clip(q, lo, hi)
        try:
            point.check_pose(q)
        except CctmillError:
            continue
        pos, rot = robot.pose_function(q, params.tcp)
        axis = np.asarray(rot, float)[:, 0]
        feed_dir = np.cross(axis, rng.normal(size=3))
        feed_dir /= np.linalg.norm(feed_dir)
        radial = np.cross(axis, feed_dir)  # Y_o = Z_o x X_o = axis
        rpm = float(rng.choice(rpm_choices)) if len(rpm_choices) > 1 else float(rpm_choices[0])
        mode = str(rng.choice(["up", "down"]))
        cut = Cut(feed_dir, radial, a_e=rng.uniform(1.0, 20.0) * 1e-3,
                  a_p=rng.uniform(0.5, 6.0) * 1e-3, mode=mode, spindle_speed=rpm * np.pi / 30,
                  flutes=tool.flutes, radius=tool.radius)
        c = rng.uniform(0.05, 0.15) * 1e-3
        feed = c * tool.flutes * rpm / 60.0
        try:
            st = pose_structure(robot, params, q, cut, feed, DEFAULT_DAMPING_RATIO)
        except CctmillError:
            continue
        out_q.append(q)
        out_cut.append(cut)
        out_feed.append(feed)
        out_rpm.append(rpm)
        structures.append(st)
    fl = floquet_batch(structures, out_cut, material, tool.helix_angle)
    cases = []
    for q, cut, feed, rpm, st, f in zip(out_q, out_cut, out_feed, out_rpm, structures, fl,
                                        strict=True):
        geo = cutter_geometry(cut, tool.helix_angle, 256)
        kp = process_stiffness_series(geo, material).mean(axis=0)
        avg = float(np.linalg.eigvals(st.state_matrix(kp)).real.max())
        eig = point.analyze(q, cut, feed).stable_eigen
        cases.append(Case(q, cut, feed, rpm, f.growth_rate, f.frequency_hz, eig, avg))
    return cases


def pick(cases: list[Case], key: str, per_side: int) -> list[Case]:
    """``per_side`` cases clear of the boundary on each side of the verdict ``key``."""
    if key == "floquet":
        grows = [c for c in cases if c.floquet_growth > CLEARANCE]
        settles = [c for c in cases if c.floquet_growth < -1.0]
    else:
        grows = [c for c in cases if not c.eigen_stable and c.average_growth > CLEARANCE]
        settles = [c for c in cases if c.eigen_stable and c.average_growth < -0.3
                   and c.floquet_growth < -1.0]
    return grows[:per_side] + settles[:per_side]


def run(case: Case, regeneration: bool = False, duration: float | None = None,
        initial: str = "static"):
    """Simulate a case (2 s at 1000 rpm, 1.5 s above; the integrator takes at least 64 steps per
    tooth period, so the high speeds cost more per simulated second). ``initial="periodic"``
    starts on the tooth-periodic motion with a perturbation of 1e-6 feeds per tooth."""
    if duration is None:
        duration = 2.0 if case.rpm < 2000 else 1.5
    robot, material, tool, params = _setup()
    st = pose_structure(robot, params, case.q, case.cut, case.feed, DEFAULT_DAMPING_RATIO)
    c = case.feed / (case.cut.flutes * case.rpm / 60.0)
    return simulate(st, case.cut, case.feed, material, tool.helix_angle, duration=duration,
                    regeneration=regeneration, initial=initial,
                    perturbation=1e-6 * c if initial == "periodic" else 0.0)


def table(rows: list[tuple[str, Case]]) -> str:
    lines = ["| rpm | a_e mm | a_p mm | mode | c mm | eigen (avg) | avg growth 1/s | Floquet "
             "growth 1/s | Floquet f Hz | sim growth 1/s | sim f Hz | sim verdict | sim growth "
             "1/s, periodic start |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for _, case in rows:
        s = run(case)
        p = run(case, initial="periodic")
        lines.append(
            f"| {case.rpm:.0f} | {case.cut.a_e * 1e3:.2f} | {case.cut.a_p * 1e3:.2f} | "
            f"{case.cut.mode} | {s.feed_per_tooth * 1e3:.3f} | "
            f"{'stable' if case.eigen_stable else 'unstable'} | {case.average_growth:+.2f} | "
            f"{case.floquet_growth:+.2f} | {case.floquet_hz:.2f} | {s.growth_rate:+.2f} | "
            f"{s.vibration_frequency_hz:.2f} | {'grows' if s.growth_rate > 0 else 'settles'} | "
            f"{p.growth_rate:+.2f} |")
    return "\n".join(lines)


def caveat(cases: list[Case]) -> str:
    """How often the averaged eigen verdict and the Floquet verdict differ."""
    eig = np.array([c.eigen_stable for c in cases])
    grows = np.array([c.floquet_growth > 0 for c in cases])
    return (f"{len(cases)} candidates: averaged-stable {eig.sum()}, of which Floquet-unstable "
            f"{(grows & eig).sum()}; averaged-unstable {(~eig).sum()}, of which Floquet-stable "
            f"{(~grows & ~eig).sum()}")


if __name__ == "__main__":
    low = candidates(40, [1000.0])
    high = candidates(40, [4000.0, 6000.0, 8000.0], seed=SEED + 1)
    print("1000 rpm: " + caveat(low))
    print(">= 4000 rpm: " + caveat(high))
    print("1000 rpm, Floquet-selected:")
    print(table([("", c) for c in pick(low, "floquet", 4)]))
    print("\n>= 4000 rpm, eigen-selected:")
    print(table([("", c) for c in pick(high, "eigen", 3)]))
