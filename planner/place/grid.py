"""Where the part may sit: placements of ``$BASE`` and the grids a study walks.

A placement moves the workpiece frame in the robot base: its origin ``(x, y, z)`` [m] and its yaw
[rad], the KUKA ``A`` angle of ``$BASE`` (rotation about the base z axis); the job's ``B`` and
``C`` are kept. A grid is the product of one :class:`Axis` per coordinate, x outermost and yaw
innermost, and lists its placements in that order (the order of ``place.json``).

:func:`default_grid` is the range a study takes when none is given: the robot's reachable box
around the job's own placement (see its docstring).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from models.errors import InputError

__all__ = [
    "DEFAULT_COUNTS",
    "DEFAULT_HALF_SPAN",
    "KEY_DECIMALS",
    "REACH_SAMPLES",
    "REACH_SEED",
    "Axis",
    "Placement",
    "PlacementGrid",
    "default_grid",
    "own_placement",
    "part_extent",
    "reach_box",
]

#: Half-width of the default range about the job's own origin, x, y, z [m]: far enough to cross
#: the regions of the arm's workspace where its stiffness changes (the issue's 300 mm / 400 mm
#: grid spans 900 mm × 800 mm), near enough that most placements stay reachable.
DEFAULT_HALF_SPAN = (0.6, 0.6, 0.4)
#: Placements along x, y, z of the default range (75 in all, the job's own yaw).
DEFAULT_COUNTS = (5, 5, 3)
#: Random joint configurations whose TCP positions bound the reachable box (seeded, reproducible).
REACH_SAMPLES = 20_000
#: Seed of those configurations.
REACH_SEED = 20260818
#: Decimals of a coordinate in millimetres (degrees for yaw) kept in a placement's key and in the
#: job it makes: 1 nm (1 µdeg), far below any machining tolerance, so that the mm → m → mm round trip
#: gives the job file's own numbers back.
KEY_DECIMALS = 6


@dataclass(frozen=True, order=True)
class Placement:
    """One ``$BASE`` candidate: origin in the robot base [m] and yaw (``$BASE`` A) [rad]."""

    x: float
    y: float
    z: float
    yaw: float

    @property
    def base_mm(self) -> list[float]:
        """The origin as the job's ``[cell] base_mm`` [mm] (rounded to :data:`KEY_DECIMALS`)."""
        return [round(v * 1e3, KEY_DECIMALS) for v in (self.x, self.y, self.z)]

    @property
    def yaw_deg(self) -> float:
        """The yaw as ``base_abc_deg[0]`` [deg]."""
        return round(math.degrees(self.yaw), KEY_DECIMALS)

    @property
    def key(self) -> str:
        """A stable name of the placement (the engine's task key; equal placements, equal keys)."""
        x, y, z = self.base_mm
        d = KEY_DECIMALS
        return f"x{x:.{d}f}_y{y:.{d}f}_z{z:.{d}f}_a{self.yaw_deg:.{d}f}"

    def as_json(self) -> dict[str, float]:
        """The placement in the job file's units (``x_mm`` … ``yaw_deg``)."""
        x, y, z = self.base_mm
        return {"x_mm": x, "y_mm": y, "z_mm": z, "yaw_deg": self.yaw_deg}

    @classmethod
    def from_mm_deg(cls, x_mm: float, y_mm: float, z_mm: float, yaw_deg: float) -> Placement:
        """A placement from millimetres and degrees."""
        return cls(x_mm * 1e-3, y_mm * 1e-3, z_mm * 1e-3, math.radians(yaw_deg))

    def vector(self) -> np.ndarray:
        """``[x, y, z, yaw]`` [m, m, m, rad], shape (4,)."""
        return np.array([self.x, self.y, self.z, self.yaw])


@dataclass(frozen=True)
class Axis:
    """Evenly spaced values ``lo … hi`` (``n`` of them; ``n = 1`` is ``lo`` alone), SI."""

    lo: float
    hi: float
    n: int

    def __post_init__(self) -> None:
        if not (isinstance(self.n, int) and self.n >= 1):
            raise InputError("grid", f"an axis needs at least one value, got n = {self.n!r}")
        if not (math.isfinite(self.lo) and math.isfinite(self.hi)):
            raise InputError("grid", f"axis bounds must be finite, got {self.lo!r}:{self.hi!r}")
        if self.n > 1 and not self.hi > self.lo:
            raise InputError("grid", f"an axis of {self.n} values needs lo < hi, got "
                                     f"{self.lo!r}:{self.hi!r}")

    @classmethod
    def single(cls, value: float) -> Axis:
        return cls(value, value, 1)

    def values(self) -> np.ndarray:
        """The values, shape (n,)."""
        return np.array([self.lo]) if self.n == 1 else np.linspace(self.lo, self.hi, self.n)

    @property
    def step(self) -> float:
        """Spacing of neighbouring values (0 for a single value)."""
        return 0.0 if self.n == 1 else (self.hi - self.lo) / (self.n - 1)


@dataclass(frozen=True)
class PlacementGrid:
    """The product of four axes: origin x, y, z [m] and yaw [rad]."""

    x: Axis
    y: Axis
    z: Axis
    yaw: Axis

    @property
    def axes(self) -> tuple[Axis, Axis, Axis, Axis]:
        return (self.x, self.y, self.z, self.yaw)

    @property
    def shape(self) -> tuple[int, int, int, int]:
        return (self.x.n, self.y.n, self.z.n, self.yaw.n)

    def __len__(self) -> int:
        return math.prod(self.shape)

    def placements(self) -> list[Placement]:
        """Every placement, x outermost, yaw innermost."""
        xs, ys, zs, ws = (a.values() for a in self.axes)
        return [Placement(float(x), float(y), float(z), float(w))
                for x in xs for y in ys for z in zs for w in ws]

    def as_json(self) -> dict[str, list[float]]:
        """The axes' values in the job file's units."""
        x, y, z, w = (a.values() for a in self.axes)
        return {"x_mm": [float(round(v * 1e3, KEY_DECIMALS)) for v in x],
                "y_mm": [float(round(v * 1e3, KEY_DECIMALS)) for v in y],
                "z_mm": [float(round(v * 1e3, KEY_DECIMALS)) for v in z],
                "yaw_deg": [float(round(math.degrees(v), KEY_DECIMALS)) for v in w]}


def own_placement(job) -> Placement:
    """The job's own ``$BASE`` as a placement (``job``: a :class:`planner.job.Job`)."""
    x, y, z = job.cell.base_mm
    return Placement.from_mm_deg(x, y, z, job.cell.base_abc_deg[0])


def reach_box(job) -> tuple[np.ndarray, np.ndarray]:
    """The box the job's TCP can reach at all: the bounds of the TCP over
    :data:`REACH_SAMPLES` random joint configurations within the limits (seeded).

    Returns:
        lower and upper corners in the robot base [m], shape (3,) each.
    """
    from models.robot import load_robot

    robot = load_robot(job.cell.robot)
    lo, hi = robot.data.lower, robot.data.upper
    rng = np.random.default_rng(REACH_SEED)
    q = lo + (hi - lo) * rng.random((REACH_SAMPLES, lo.size))
    f = robot.pose_function.map(REACH_SAMPLES)
    p, _ = f(q.T, job.tool_frame()[:3, 3])
    p = np.asarray(p, float)
    return p.min(axis=1), p.max(axis=1)


def part_extent(job) -> tuple[np.ndarray, np.ndarray]:
    """The bounds of the toolpath in the workpiece frame [m], shape (3,) each (the stock box
    where one is given, if larger)."""
    from planner.path import sample_toolpath
    from planner.prepare import read_job_toolpaths

    si = job.to_si()
    path = sample_toolpath(list(read_job_toolpaths(job, si.chord_tol)), np.eye(4), si.chord_tol,
                           si.step_max)
    lo, hi = path.position_wp.min(axis=0), path.position_wp.max(axis=0)
    if si.stock_box is not None and si.stock_z is not None:
        x0, y0, x1, y1 = si.stock_box
        lo = np.minimum(lo, [x0, y0, si.stock_z[0]])
        hi = np.maximum(hi, [x1, y1, si.stock_z[1]])
    return lo, hi


def default_grid(job, counts: tuple[int, int, int] = DEFAULT_COUNTS,
                 half_span: tuple[float, float, float] = DEFAULT_HALF_SPAN) -> PlacementGrid:
    """The robot's reachable box around the job's own placement, as a grid.

    Each origin coordinate spans the job's own ± ``half_span`` [m], clipped so that the part (its
    toolpath's bounds, turned by the job's ``$BASE`` rotation) stays inside :func:`reach_box`; yaw
    is the job's own. Reachability of every sample is decided by the plan at each placement, not
    here: the box is only the range where a placement can be reachable at all.

    Raises:
        InputError: the part does not fit inside the reachable box at all along some axis.
    """
    own = own_placement(job)
    box_lo, box_hi = reach_box(job)
    p_lo, p_hi = part_extent(job)
    corners = np.array([[x, y, z] for x in (p_lo[0], p_hi[0]) for y in (p_lo[1], p_hi[1])
                        for z in (p_lo[2], p_hi[2])])
    rot = job.base_frame()[:3, :3]
    c = corners @ rot.T
    # origin o keeps every corner inside: box_lo - min(c) <= o <= box_hi - max(c)
    o_lo, o_hi = box_lo - c.min(axis=0), box_hi - c.max(axis=0)
    axes = []
    for i, name in enumerate("xyz"):
        centre = (own.x, own.y, own.z)[i]
        lo = max(centre - half_span[i], o_lo[i])
        hi = min(centre + half_span[i], o_hi[i])
        if not hi >= lo:
            raise InputError(f"--{name}-mm", "the part does not fit inside the robot's reachable "
                                             f"box along {name}; give the range explicitly")
        axes.append(Axis(lo, hi, counts[i]) if hi > lo else Axis.single(lo))
    return PlacementGrid(*axes, Axis.single(own.yaw))
