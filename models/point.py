"""Numeric face of the point model: evaluate one pose, or a feed range, into dataclasses.

:class:`PointModel` binds a robot, the build-time choices (process model, mass model) and the
:class:`~models.analysis.ModelParameters`; :meth:`PointModel.analyze` evaluates the CasADi point
Function once and checks the pose (joint limits, singularity); :meth:`PointModel.characteristic`
maps it over feeds (docs/model.md §5 step 7: the stability characteristic and the feed limit of the point,
saying whether chatter or force binds).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from models.analysis import OUTPUTS, Cut, ModelParameters, point_function
from models.errors import InputError, SingularPoseError
from models.robot import Robot

#: Helix angle [rad] the ``floquet`` criterion uses when none is given (the shipped tool's 30°).
DEFAULT_HELIX_ANGLE = float(np.radians(30.0))

__all__ = [
    "CRITERIA",
    "JACOBIAN_LENGTH",
    "JACOBIAN_SIGMA_MIN",
    "PointAnalysis",
    "PointModel",
    "StabilityCharacteristic",
]

CRITERIA = ("eigen", "floquet", "gamma_window")

#: Smallest singular value of the TCP Jacobian's *linear* rows [m/rad] below which a pose counts
#: as singular. The KR 210's arm is 2.7 m long: 5 mm of TCP motion per radian is a near-singular
#: wrist or a stretched arm, where K_t grows without bound.
JACOBIAN_SIGMA_MIN = 5e-3
#: Length [m] that scales the Jacobian's angular rows for the rank test (about the wrist-to-TCP
#: distance; makes the 6×6 singular values comparable in m/rad).
JACOBIAN_LENGTH = 0.25
#: Angle between Y_o and the tool axis [rad] above which a warning is issued (docs/model.md §4).
TOOL_AXIS_WARN = np.radians(5.0)


@dataclass(frozen=True)
class PointAnalysis:
    """Everything the point model says about one pose, cut and feed (SI; angles in rad).

    Matrices in the 2-DOF plane have rows = force components and columns = displacement components,
    in the plane's axes (``plane`` columns, base axes).
    """

    process_model: str
    mass_model: str
    criterion: str
    feed: float
    feed_per_tooth: float
    force_o: np.ndarray
    force_base: np.ndarray
    alpha: float
    beta: float
    gamma: float
    k_pxo: float
    k_px: float
    k_py: float
    k_max: float
    k_min: float
    k_p: np.ndarray
    a: np.ndarray
    eig: np.ndarray
    margin: float
    stable_eigen: bool
    gamma_margin: float
    stiffness: np.ndarray
    compliance: np.ndarray
    deflection: np.ndarray
    natural_frequencies: np.ndarray | None
    tool_axis_angle: float
    plane: np.ndarray
    tcp_position: np.ndarray
    tool_axis: np.ndarray
    principal_values: np.ndarray
    principal_directions: np.ndarray
    jacobian_sigma_min: float
    warnings: tuple[str, ...]
    floquet_radius: float | None = None
    """Spectral radius of the monodromy matrix (``floquet`` criterion only; docs/model.md §5, §6)."""

    @property
    def floquet_margin(self) -> float:
        """1 − ρ [-] of the ``floquet`` criterion (> 0 stable); NaN for the other criteria."""
        return 1.0 - self.floquet_radius if self.floquet_radius is not None else float("nan")

    @property
    def force(self) -> float:
        """Resultant average cutting force [N]."""
        return float(np.linalg.norm(self.force_o))

    @property
    def stable(self) -> bool:
        """Verdict of the chosen criterion."""
        if self.criterion == "gamma_window":
            return self.gamma_margin > 0.0
        if self.criterion == "floquet":
            return self.floquet_radius is not None and self.floquet_radius < 1.0
        return self.stable_eigen


@dataclass(frozen=True)
class StabilityCharacteristic:
    """γ(f) and margin(f) of one point over a feed range (docs/model.md §5 step 7).

    Attributes:
        feeds: [m/s], shape (k,).
        gamma: [rad], shape (k,).
        margin: [N/m] (eigen), [rad] (gamma_window) or 1 − ρ [-] (floquet), shape (k,).
        stable: shape (k,), bool.
        force: resultant average force [N], shape (k,).
        force_limit: [N].
        feed_limit: the largest feed of the range that is stable and under the force limit, and
            every feed below it too [m/s]; 0 when even the smallest is not.
        binding: what stops the feed from going higher: ``"chatter"``, ``"force"``, ``"both"``
            (same grid step) or ``"feed_max"`` (the whole range passes).
        points: the full analyses, one per feed.
    """

    feeds: np.ndarray
    gamma: np.ndarray
    margin: np.ndarray
    stable: np.ndarray
    force: np.ndarray
    force_limit: float
    feed_limit: float
    binding: str
    points: tuple[PointAnalysis, ...]


class PointModel:
    """A robot plus model choices, ready to evaluate points.

    Args:
        robot: the robot.
        params: the model parameters.
        process_model: ``"thesis"`` or ``"oriented"``.
        mass_model: ``"isotropic"`` or ``"robot"``.
        criterion: ``"eigen"``, ``"floquet"`` or ``"gamma_window"``.
        helix_angle: cutter helix angle [rad] (``floquet`` only).
        damping_ratio: ζ of both arm modes (``floquet`` only; docs/model.md §6).

    The ``floquet`` criterion (models.floquet) uses the robot's Cartesian mass and the oriented
    instantaneous process stiffness whatever ``process_model`` and ``mass_model`` say; the eigen
    outputs of the analysis stay those of the chosen models.
    """

    def __init__(self, robot: Robot, params: ModelParameters, process_model: str = "thesis",
                 mass_model: str = "isotropic", criterion: str = "eigen",
                 helix_angle: float = DEFAULT_HELIX_ANGLE, damping_ratio: float | None = None) -> None:
        if criterion not in CRITERIA:
            raise InputError("criterion", f"{criterion!r} is not one of {', '.join(CRITERIA)}")
        self.helix_angle = helix_angle
        self.damping_ratio = damping_ratio
        self.robot = robot
        self.params = params
        self.process_model = process_model
        self.mass_model = mass_model
        self.criterion = criterion
        self.function = point_function(robot, process_model, mass_model)

    def check_pose(self, q: np.ndarray) -> float:
        """Raise if ``q`` [rad] is outside the joint limits or singular; return σ_min(J_v) [m/rad].

        Two named conditions: the linear rows J_v lose rank (K_t = C_tt⁻¹ blows up), or the whole
        Jacobian, rotations scaled by :data:`JACOBIAN_LENGTH`, loses rank (wrist singularity).
        """
        self.robot.check_limits(q)
        jac = np.asarray(self.robot.jacobian_function(q, self.params.tcp), float)
        sigma_lin = float(np.linalg.svd(jac[0:3, :], compute_uv=False)[-1])
        if sigma_lin < JACOBIAN_SIGMA_MIN:
            raise SingularPoseError("smallest singular value of the linear TCP Jacobian [m/rad]",
                                    sigma_lin, JACOBIAN_SIGMA_MIN,
                                    "the arm is stretched or folded: K_t is unbounded here")
        scaled = np.vstack([jac[0:3, :], JACOBIAN_LENGTH * jac[3:6, :]])
        sigma_all = float(np.linalg.svd(scaled, compute_uv=False)[-1])
        if sigma_all < JACOBIAN_SIGMA_MIN:
            raise SingularPoseError("smallest singular value of the TCP Jacobian [m/rad]",
                                    sigma_all, JACOBIAN_SIGMA_MIN)
        return sigma_lin

    def _evaluate(self, q, cut: Cut, feeds: np.ndarray) -> list[dict[str, np.ndarray]]:
        f = self.function
        n = feeds.size
        fm = f if n == 1 else f.map(n)
        res = fm(q=np.asarray(q, float), cut=cut.vector(), feed=feeds.reshape(1, -1),
                 params=self.params.vector())
        out = []
        for k in range(n):
            row = {}
            for name in OUTPUTS:
                m = np.asarray(res[name], float)
                rows = f.size1_out(name)
                cols = f.size2_out(name)
                row[name] = m[:, k * cols:(k + 1) * cols].reshape(rows, cols) if n > 1 else m
            out.append(row)
        return out

    def _to_analysis(self, v: dict[str, np.ndarray], feed: float, sigma: float) -> PointAnalysis:
        def s(name):
            return float(v[name].reshape(-1)[0])

        warnings = []
        axis_angle = s("tool_axis_angle")
        if axis_angle > TOOL_AXIS_WARN:
            warnings.append(f"the tool axis is {np.degrees(axis_angle):.1f} deg off the axial "
                            "direction Y_o = feed x radial: check --feed-dir/--radial-dir against "
                            "the pose")
        omega2 = v["omega2"].reshape(-1)
        freqs = np.sqrt(np.maximum(omega2, 0.0)) / (2 * np.pi) if self.mass_model == "robot" else None
        if not np.all(np.isfinite(v["stiffness"])):
            raise SingularPoseError("translational compliance determinant", 0.0, 0.0,
                                    "K_t is not finite at this pose")
        eig = np.column_stack([v["eig_re"].reshape(-1), v["eig_im"].reshape(-1)])
        return PointAnalysis(
            process_model=self.process_model, mass_model=self.mass_model,
            criterion=self.criterion, feed=float(feed), feed_per_tooth=s("feed_per_tooth"),
            force_o=v["force_o"].reshape(3), force_base=v["force_base"].reshape(3),
            alpha=s("alpha"), beta=s("beta"), gamma=s("gamma"), k_pxo=s("k_pxo"),
            k_px=s("k_px"), k_py=s("k_py"), k_max=s("k_max"), k_min=s("k_min"),
            k_p=v["k_p"].reshape(2, 2), a=v["a"].reshape(2, 2), eig=eig, margin=s("margin"),
            stable_eigen=bool(s("stable") > 0.5), gamma_margin=s("gamma_margin"),
            stiffness=v["stiffness"].reshape(3, 3), compliance=v["compliance"].reshape(3, 3),
            deflection=v["deflection"].reshape(3), natural_frequencies=freqs,
            tool_axis_angle=axis_angle, plane=v["plane"].reshape(3, 2),
            tcp_position=v["tcp_position"].reshape(3), tool_axis=v["tool_axis"].reshape(3),
            principal_values=v["principal_values"].reshape(3),
            principal_directions=v["principal_directions"].reshape(3, 3),
            jacobian_sigma_min=sigma, warnings=tuple(warnings))

    def analyze(self, q: np.ndarray, cut: Cut, feed: float) -> PointAnalysis:
        """Evaluate the point model at joints ``q`` [rad], cut ``cut`` and feed ``feed`` [m/s]."""
        if not feed > 0.0 or not np.isfinite(feed):
            raise InputError("feed", f"must be positive and finite, got {feed}")
        sigma = self.check_pose(np.asarray(q, float))
        point = self._to_analysis(self._evaluate(q, cut, np.array([feed]))[0], feed, sigma)
        return self._with_floquet(q, cut, (point,))[0]

    def _with_floquet(self, q, cut: Cut, points: tuple[PointAnalysis, ...]) -> tuple:
        """Add the Floquet spectral radius to each point (``floquet`` criterion only)."""
        if self.criterion != "floquet":
            return points
        from dataclasses import replace

        from models.dynamics import DEFAULT_DAMPING_RATIO, pose_structure
        from models.floquet import floquet_margin

        zeta = DEFAULT_DAMPING_RATIO if self.damping_ratio is None else self.damping_ratio
        structures = [pose_structure(self.robot, self.params, np.asarray(q, float), cut, p.feed,
                                     zeta) for p in points]
        rho, _ = floquet_margin(structures, [cut] * len(points), self.params.coefficients,
                                self.helix_angle)
        return tuple(replace(p, floquet_radius=float(r)) for p, r in zip(points, rho, strict=True))

    def characteristic(self, q: np.ndarray, cut: Cut, feeds: np.ndarray,
                       force_limit: float = 300.0) -> StabilityCharacteristic:
        """The stability characteristic over ``feeds`` [m/s] and the point's feed limit.

        Args:
            q: joints [rad], shape (n,).
            cut: the cut.
            feeds: increasing feeds [m/s], shape (k,), all > 0.
            force_limit: resultant force limit [N] (thesis: 300 N for the KR210 with spindle).
        """
        feeds = np.asarray(feeds, float).reshape(-1)
        if (feeds.size == 0 or not np.all(np.isfinite(feeds)) or np.any(feeds <= 0)
                or np.any(np.diff(feeds) <= 0)):
            raise InputError("feed range", "need increasing positive finite feeds")
        sigma = self.check_pose(np.asarray(q, float))
        points = tuple(self._to_analysis(v, f, sigma)
                       for v, f in zip(self._evaluate(q, cut, feeds), feeds, strict=True))
        points = self._with_floquet(q, cut, points)
        stable = np.array([p.stable for p in points])
        force = np.array([p.force for p in points])
        under = force <= force_limit
        ok = stable & under
        bad = np.flatnonzero(~ok)
        if bad.size == 0:
            feed_limit, binding = float(feeds[-1]), "feed_max"
        else:
            first = bad[0]
            feed_limit = float(feeds[first - 1]) if first > 0 else 0.0
            chat, over = not stable[first], not under[first]
            binding = "both" if chat and over else ("chatter" if chat else "force")
        margin_name = {"gamma_window": "gamma_margin", "floquet": "floquet_margin"}.get(
            self.criterion, "margin")
        return StabilityCharacteristic(
            feeds=feeds, gamma=np.array([p.gamma for p in points]),
            margin=np.array([getattr(p, margin_name) for p in points]), stable=stable,
            force=force, force_limit=float(force_limit), feed_limit=feed_limit, binding=binding,
            points=points)
