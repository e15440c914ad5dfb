"""Shared fixtures and named test problems of the physics tests.

Named problems:
    Case 1 (thesis): joints (−96.42, −29.26, 99.08, −9.95, 83.23, −160.5) deg, feed along base +Y,
    radial along base +X, up milling, a_e 15.24 mm, a_p 5.08 mm, the 25.4 mm two-flute end mill
    (N = 2, R = 12.7 mm), 1000 rpm, 1 mm/s, aluminium 6061.

Randomness is seeded: every test that asks for ``rng`` gets a fresh generator with the same seed, so
a failure reproduces exactly.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from models.analysis import Cut, ModelParameters
from models.cutting import Material, Tool, load_material, load_tool
from models.point import PointModel
from models.robot import Robot, load_robot

SEED = 20240611

CASE1_JOINTS_DEG = (-96.42, -29.26, 99.08, -9.95, 83.23, -160.5)
CASE1_FEED = 1e-3  # [m/s]
CASE1_SPINDLE_RPM = 1000.0

#: A TCP offset in the flange frame [m] with all three components non-zero (a spindle along +x plus
#: a deliberately off-axis part), so a Jacobian that ignores any component of the offset fails.
TCP_OFFSET = (0.32, 0.04, -0.05)


@pytest.fixture(scope="session")
def robot() -> Robot:
    return load_robot()


@pytest.fixture(scope="session")
def material() -> Material:
    return load_material("al6061")


@pytest.fixture(scope="session")
def tool() -> Tool:
    return load_tool("em25_2f")


@pytest.fixture(scope="session")
def tcp() -> np.ndarray:
    """Non-zero TCP offset in the flange frame [m], shape (3,)."""
    return np.array(TCP_OFFSET)


@pytest.fixture(scope="session")
def params(robot: Robot, material: Material) -> ModelParameters:
    """Model parameters as shipped: K_θ of the data file, al6061 coefficients, CCT on, TCP at the
    flange, default spindle."""
    return ModelParameters(joint_stiffness=robot.data.joint_stiffness,
                           coefficients=material.coefficients())


@pytest.fixture(scope="session")
def case1_q() -> np.ndarray:
    """Thesis Case 1 joint angles [rad], shape (6,)."""
    return np.deg2rad(np.array(CASE1_JOINTS_DEG))


@pytest.fixture(scope="session")
def case1_cut(tool: Tool) -> Cut:
    """Thesis Case 1 cut: feed +Y, radial +X (base axes), up milling, a_e 15.24 mm, a_p 5.08 mm."""
    return Cut(feed_dir=np.array([0.0, 1.0, 0.0]), radial_dir=np.array([1.0, 0.0, 0.0]),
               a_e=15.24e-3, a_p=5.08e-3, mode="up",
               spindle_speed=CASE1_SPINDLE_RPM * 2.0 * np.pi / 60.0,
               flutes=tool.flutes, radius=tool.radius)


@pytest.fixture(scope="session")
def case1_feed() -> float:
    """Thesis Case 1 feed speed [m/s]."""
    return CASE1_FEED


@pytest.fixture(scope="session")
def point_model(robot: Robot, params: ModelParameters) -> PointModel:
    """The default point model: thesis process stiffness, isotropic mass, eigen criterion."""
    return PointModel(robot, params)


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(SEED)


@pytest.fixture(scope="session")
def demo_prepared():
    """The bundled demo job (``planner/data/demo``: outside contour of an Al 6061 bracket on the
    KR 210, engagement from the stock), prepared. Shared by the session: do not modify it."""
    # planner is imported here, not at the top, so the physics tests do not load it
    from planner.demo import demo_job_file
    from planner.job import load_job
    from planner.prepare import prepare

    return prepare(load_job(demo_job_file()))


@pytest.fixture(scope="session")
def demo_optimized(demo_prepared):
    """The demo job planned by the section optimiser (``sections``: one feed per section, a
    :class:`planner.plan.PlanResult`). Shared by the session: do not modify it (copy the feeds
    and sections first)."""
    from planner.plan import plan_prepared

    return plan_prepared(demo_prepared, "sections")


@pytest.fixture(scope="session")
def demo_profiled(demo_prepared):
    """The demo job planned with a feed profile (``optimize``: the sections of ``sections`` and a
    speed per sample). Shared by the session: do not modify it."""
    from planner.plan import plan_prepared

    return plan_prepared(demo_prepared, "optimize")


def _well_conditioned(robot: Robot, q: np.ndarray, tcp: np.ndarray, min_sigma: float) -> bool:
    """σ_min of [J_v; 0.25 m · J_ω] [m/rad] above ``min_sigma``: far from any singularity."""
    jac = np.asarray(robot.jacobian_function(q, tcp), float)
    scaled = np.vstack([jac[0:3, :], 0.25 * jac[3:6, :]])
    return bool(np.linalg.svd(scaled, compute_uv=False)[-1] > min_sigma)


@pytest.fixture
def random_poses(robot: Robot, rng: np.random.Generator) -> Callable[..., np.ndarray]:
    """``draw(n, tcp=0, margin_deg=5, min_wrist_deg=10, min_sigma=0.02) -> q [rad], shape (n, 6)``.

    Uniform joint values inside the joint limits shrunk by ``margin_deg``, rejecting wrist
    singularities (|A5| < ``min_wrist_deg``) and poses whose scaled Jacobian has a smallest singular
    value below ``min_sigma`` [m/rad] (stretched or folded arm, wrist centre on the A1 axis).
    """

    def draw(n: int, tcp: np.ndarray | None = None, margin_deg: float = 5.0,
             min_wrist_deg: float = 10.0, min_sigma: float = 0.02) -> np.ndarray:
        tcp_ = np.zeros(3) if tcp is None else np.asarray(tcp, float)
        margin = np.deg2rad(margin_deg)
        lo, hi = robot.data.lower + margin, robot.data.upper - margin
        out: list[np.ndarray] = []
        for _ in range(1000 * n):
            q = rng.uniform(lo, hi)
            if abs(q[4]) < np.deg2rad(min_wrist_deg):
                continue
            if not _well_conditioned(robot, q, tcp_, min_sigma):
                continue
            out.append(q)
            if len(out) == n:
                return np.array(out)
        raise RuntimeError("could not draw enough well-conditioned poses")  # pragma: no cover

    return draw


def mutate(base: bytes, alphabet: bytes, rng: np.random.Generator, edits: int = 5) -> bytes:
    """``base`` with 1..``edits`` random single-byte replacements, insertions or deletions drawn from
    ``alphabet`` (the readers' fuzz tests)."""
    data = bytearray(base)
    for _ in range(int(rng.integers(1, edits + 1))):
        i = int(rng.integers(0, len(data)))
        op = int(rng.integers(0, 3))
        b = alphabet[int(rng.integers(0, len(alphabet)))]
        if op == 0:
            data[i] = b
        elif op == 1:
            data.insert(i, b)
        else:
            del data[i]
    return bytes(data)
