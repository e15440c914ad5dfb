"""The robot: a URDF loaded with pinocchio, plus the data a URDF cannot hold, plus CasADi kinematics.

One source of truth: :class:`Robot` reads the shipped URDF into a :class:`pinocchio.Model` and builds
every symbolic expression (TCP pose, geometric Jacobian, joint-space mass matrix) by walking *that*
model's joint placements, joint axes and body inertias. Nothing geometric is typed twice.

Conventions (docs/model.md §1–§2): joint values are KUKA axis values A1..A6 [rad]; the base frame is
``$ROBROOT``; the flange frame has x along the A6 axis pointing away from the robot; the TCP frame is
the flange frame shifted by ``tcp`` [m] (flange axes) — its +x is the tool axis. The Jacobian is the
6×n geometric Jacobian of the TCP, rows [linear; angular], base axes at the TCP origin (pinocchio's
``LOCAL_WORLD_ALIGNED``).
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from functools import cached_property
from importlib import resources
from pathlib import Path

import casadi as ca
import numpy as np
import pinocchio as pin

from models.errors import DataFileError, InputError, UnknownDataError, UnreachablePoseError

__all__ = [
    "DEFAULT_ROBOT",
    "DEFAULT_VENDOR",
    "Robot",
    "RobotData",
    "SymbolicKinematics",
    "available_robots",
    "load_robot",
    "robot_data",
]

DEFAULT_ROBOT = "kr210_r2700_extra"

#: Joint limits in the URDF and the TOML must agree to this [rad] (the TOML holds degrees with
#: one decimal, the URDF radians with 7 decimals).
LIMIT_AGREEMENT_TOL = 1e-6

_DATA = "data/robots"

#: The controller maker of a robot data file that does not name one.
DEFAULT_VENDOR = "kuka"


@dataclass(frozen=True)
class RobotData:
    """What a URDF cannot hold about a robot, in SI.

    Attributes:
        name: robot name (file stem).
        urdf_path: path of the URDF file.
        joint_names: controller axis names, e.g. ``("A1", ..., "A6")``.
        joint_stiffness: K_θ diagonal [N·m/rad], shape (n,).
        lower, upper: joint position limits [rad], shape (n,).
        velocity: joint speed limits [rad/s], shape (n,).
        acceleration: joint acceleration limits [rad/s²], shape (n,).
        spindle_mass: default spindle point mass [kg].
        spindle_com: default spindle centre of mass in the flange frame [m], shape (3,).
        vendor: the controller's maker, lower case (``"kuka"``, ``"abb"``, …); the KRL export
            writes programs for ``"kuka"`` only. A data file without ``vendor`` is KUKA's.
        description: what the robot is, in one line.
        sources: where each group of values comes from (keys such as ``kinematics``,
            ``joint_stiffness``, ``limits``, ``inertia``; values one line each).
    """

    name: str
    urdf_path: Path
    joint_names: tuple[str, ...]
    joint_stiffness: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    spindle_mass: float
    spindle_com: np.ndarray = field(default_factory=lambda: np.zeros(3))
    vendor: str = DEFAULT_VENDOR
    description: str = ""
    sources: dict[str, str] = field(default_factory=dict)


def available_robots() -> list[str]:
    """Names of the robots shipped as data files."""
    folder = resources.files("models").joinpath(_DATA)
    return sorted(p.name[: -len(".toml")] for p in folder.iterdir() if p.name.endswith(".toml"))


def _vector(doc: dict, key: str, n: int, path: str) -> np.ndarray:
    try:
        v = np.asarray(doc[key], dtype=float)
    except KeyError as e:
        raise DataFileError(path, f"missing key {key!r}") from e
    except (TypeError, ValueError) as e:
        raise DataFileError(path, f"{key!r} must be a list of numbers") from e
    if v.shape != (n,):
        raise DataFileError(path, f"{key!r} must have {n} entries, has {v.size}")
    return v


def _text_table(doc: dict, key: str, path: str) -> dict[str, str]:
    table = doc.get(key, {})
    if not isinstance(table, dict) or not all(isinstance(v, str) for v in table.values()):
        raise DataFileError(path, f"[{key}] must be a table of strings")
    return dict(table)


def robot_data(name: str) -> RobotData:
    """The data file of a shipped robot, read without building its model (no URDF parse).

    Raises:
        UnknownDataError: no such robot (the message lists the available ones).
        DataFileError: the file is malformed.
    """
    return _read_robot_data(name)


def _read_robot_data(name: str) -> RobotData:
    if name not in available_robots():
        raise UnknownDataError("robot", name, available_robots())
    folder = resources.files("models").joinpath(_DATA)
    toml_path = folder.joinpath(f"{name}.toml")
    path = str(toml_path)
    try:
        doc = tomllib.loads(toml_path.read_text(encoding="utf-8"))
        names = tuple(str(s) for s in doc["joint_names"])
        n = len(names)
        limits = doc["limits"]
        spindle = doc.get("spindle", {})
        urdf = Path(str(folder.joinpath(doc["urdf"])))
        vendor = doc.get("vendor", DEFAULT_VENDOR)
        description = doc.get("description", "")
    except tomllib.TOMLDecodeError as e:
        raise DataFileError(path, f"not valid TOML: {e}") from e
    except KeyError as e:
        raise DataFileError(path, f"missing key {e}") from e
    if not isinstance(vendor, str) or not vendor or vendor != vendor.lower():
        raise DataFileError(path, f"vendor must be a lower-case name such as 'kuka', got {vendor!r}")
    if not isinstance(description, str):
        raise DataFileError(path, f"description must be a string, got {description!r}")
    return RobotData(
        name=name,
        urdf_path=urdf,
        joint_names=names,
        joint_stiffness=_vector(doc, "joint_stiffness_Nm_per_rad", n, path),
        lower=np.deg2rad(_vector(limits, "lower_deg", n, path)),
        upper=np.deg2rad(_vector(limits, "upper_deg", n, path)),
        velocity=np.deg2rad(_vector(limits, "velocity_deg_s", n, path)),
        acceleration=_vector(limits, "acceleration_rad_s2", n, path),
        spindle_mass=float(spindle.get("mass_kg", 0.0)),
        spindle_com=np.array([float(spindle.get("com_x_m", 0.0)), 0.0, 0.0]),
        vendor=vendor,
        description=description,
        sources=_text_table(doc, "sources", path),
    )


def _axis_of(joint: pin.JointModel) -> np.ndarray:
    """Unit rotation axis of a revolute pinocchio joint, in its own frame."""
    kind = joint.shortname()
    fixed = {"JointModelRX": (1.0, 0.0, 0.0), "JointModelRY": (0.0, 1.0, 0.0),
             "JointModelRZ": (0.0, 0.0, 1.0)}
    if kind in fixed:
        return np.array(fixed[kind])
    if kind in ("JointModelRevoluteUnaligned",):
        a = np.asarray(joint.extract().axis, dtype=float)
        return a / np.linalg.norm(a)
    raise DataFileError("URDF", f"joint type {kind} is not supported (revolute joints only)")


def _rotation(axis: np.ndarray, angle: ca.SX) -> ca.SX:
    """Rotation matrix exp([axis]× angle) (Rodrigues), axis numeric unit (3,), angle symbolic."""
    k = ca.DM(np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]],
                        [-axis[1], axis[0], 0.0]]))
    s, c = ca.sin(angle), ca.cos(angle)
    return ca.SX.eye(3) + s * k + (1.0 - c) * (k @ k)


@dataclass(frozen=True)
class SymbolicKinematics:
    """CasADi expressions of one robot configuration (all in base axes, SI).

    Attributes:
        q: the joint symbols [rad], shape (n,).
        tcp: the TCP offset symbols in the flange frame [m], shape (3,).
        origins: joint origins [m], n entries of shape (3,).
        axes: joint axes (unit), n entries of shape (3,).
        rotations: joint-frame rotations, n entries of shape (3, 3) (the last is the flange's).
        position: TCP position [m], shape (3,).
        rotation: TCP (= flange) rotation, shape (3, 3); column 0 is the tool axis.
        jacobian: geometric TCP Jacobian, shape (6, n), rows [linear; angular].
    """

    q: ca.SX
    tcp: ca.SX
    origins: list
    axes: list
    rotations: list
    position: ca.SX
    rotation: ca.SX
    jacobian: ca.SX


class Robot:
    """A serial robot: pinocchio model, limits, joint stiffness and symbolic kinematics.

    Build with :func:`load_robot`. Attributes:
        data: the :class:`RobotData`.
        model: the pinocchio model read from the URDF (no spindle).
        nq: number of joints.
        flange_frame: pinocchio frame id of the flange.
    """

    def __init__(self, data: RobotData) -> None:
        self.data = data
        try:
            self.model = pin.buildModelFromUrdf(str(data.urdf_path))
        except (RuntimeError, ValueError) as e:
            raise DataFileError(str(data.urdf_path), f"pinocchio could not read the URDF: {e}") from e
        self.nq = self.model.nq
        if self.nq != len(data.joint_names):
            raise DataFileError(str(data.urdf_path),
                                f"{self.nq} joints in the URDF, {len(data.joint_names)} in the data file")
        for lim, key in ((self.model.lowerPositionLimit, "lower"),
                         (self.model.upperPositionLimit, "upper")):
            if np.max(np.abs(lim - getattr(data, key))) > LIMIT_AGREEMENT_TOL:
                raise DataFileError(str(data.urdf_path),
                                    f"{key} joint limits differ from {data.name}.toml; make them equal")
        if not self.model.existFrame("flange"):
            raise DataFileError(str(data.urdf_path), "no link named 'flange'")
        self.flange_frame = self.model.getFrameId("flange")
        self._axes = [_axis_of(self.model.joints[i]) for i in range(1, self.model.njoints)]

    # ------------------------------------------------------------------ pinocchio (numeric)
    def pin_model(self, tcp: np.ndarray | None = None, spindle_mass: float | None = None,
                  spindle_com: np.ndarray | None = None,
                  tcp_rotation: np.ndarray | None = None) -> tuple[pin.Model, int]:
        """A copy of the pinocchio model with the spindle mass on the last body and a ``tcp`` frame.

        Args:
            tcp: TCP offset in the flange frame [m], shape (3,); default zero.
            tcp_rotation: TCP orientation in the flange frame, shape (3, 3); default identity
                (tool axis = flange x).
            spindle_mass: spindle point mass [kg]; default from the data file.
            spindle_com: spindle centre of mass in the flange frame [m], shape (3,).

        Returns:
            (model, tcp frame id).
        """
        model = self.model.copy()
        m = self.data.spindle_mass if spindle_mass is None else float(spindle_mass)
        com = self.data.spindle_com if spindle_com is None else np.asarray(spindle_com, float)
        flange = model.frames[self.flange_frame]
        joint = flange.parentJoint
        if m > 0.0:
            com_joint = flange.placement.act(com)
            model.inertias[joint] = model.inertias[joint] + pin.Inertia(
                m, com_joint, np.zeros((3, 3)))
        offset = pin.SE3(np.eye(3) if tcp_rotation is None else np.asarray(tcp_rotation, float),
                         np.zeros(3) if tcp is None else np.asarray(tcp, float))
        fid = model.addFrame(pin.Frame("tcp", joint, flange.placement * offset,
                                       pin.FrameType.OP_FRAME))
        return model, fid

    def check_limits(self, q: np.ndarray, sample: int | None = None) -> None:
        """Raise :class:`UnreachablePoseError` naming the first joint outside its limits.

        Args:
            q: joint values [rad], shape (n,).
            sample: path sample index, for the message.
        """
        q = np.asarray(q, dtype=float)
        if q.shape != (self.nq,):
            raise InputError("joints", f"need {self.nq} joint values, got {q.size}")
        for i, name in enumerate(self.data.joint_names):
            lo, hi = self.data.lower[i], self.data.upper[i]
            if not lo <= q[i] <= hi:
                where = f"sample {sample}: " if sample is not None else ""
                raise UnreachablePoseError(
                    f"{where}{name} = {np.rad2deg(q[i]):.2f} deg is outside its limits "
                    f"[{np.rad2deg(lo):.1f}, {np.rad2deg(hi):.1f}] deg",
                    joint=name, value_deg=float(np.rad2deg(q[i])), sample=sample)

    # ------------------------------------------------------------------ CasADi (symbolic)
    @cached_property
    def symbolic(self) -> SymbolicKinematics:
        """TCP pose and Jacobian as CasADi SX expressions of (q, tcp), walked from the pinocchio model."""
        model = self.model
        q = ca.SX.sym("q", self.nq)
        tcp = ca.SX.sym("tcp", 3)
        rot: dict[int, ca.SX] = {0: ca.SX.eye(3)}
        pos: dict[int, ca.SX] = {0: ca.SX.zeros(3)}
        origins, axes, rotations = [], [], []
        for i in range(1, model.njoints):
            parent = model.parents[i]
            placement = model.jointPlacements[i]
            r_parent, p_parent = rot[parent], pos[parent]
            p_i = p_parent + r_parent @ ca.DM(placement.translation)
            r_fixed = r_parent @ ca.DM(placement.rotation)
            axis = self._axes[i - 1]
            r_i = r_fixed @ _rotation(axis, q[model.joints[i].idx_q])
            rot[i], pos[i] = r_i, p_i
            origins.append(p_i)
            axes.append(r_fixed @ ca.DM(axis))
            rotations.append(r_i)
        flange = model.frames[self.flange_frame]
        j = flange.parentJoint
        r_flange = rot[j] @ ca.DM(flange.placement.rotation)
        p_flange = pos[j] + rot[j] @ ca.DM(flange.placement.translation)
        p_tcp = p_flange + r_flange @ tcp
        cols_v, cols_w = [], []
        for p_i, z_i in zip(origins, axes, strict=True):
            cols_v.append(ca.cross(z_i, p_tcp - p_i))
            cols_w.append(z_i)
        jac = ca.vertcat(ca.horzcat(*cols_v), ca.horzcat(*cols_w))
        return SymbolicKinematics(q=q, tcp=tcp, origins=origins, axes=axes, rotations=rotations,
                                  position=p_tcp, rotation=r_flange, jacobian=jac)

    def mass_matrix_expr(self, spindle_mass: ca.SX, spindle_com: ca.SX) -> ca.SX:
        """Joint-space mass matrix M(q) [kg·m², mixed], shape (n, n), as a CasADi expression.

        Built from the pinocchio model's body inertias (the URDF's, an approximation: docs/model.md §2) plus
        the spindle as a point mass ``spindle_mass`` [kg] at ``spindle_com`` [m] (flange frame).
        Uses the symbols of :attr:`symbolic`.
        """
        sym = self.symbolic
        model = self.model
        n = self.nq
        mass = ca.SX.zeros(n, n)

        def support(i: int) -> list[int]:
            chain = []
            while i > 0:
                chain.append(i)
                i = model.parents[i]
            return chain

        def add_point_body(body: int, m, com_local, inertia_local) -> ca.SX:
            r_b = sym.rotations[body - 1]
            c = sym.origins[body - 1] + r_b @ com_local
            jv = ca.SX.zeros(3, n)
            jw = ca.SX.zeros(3, n)
            for k in support(body):
                idx = model.joints[k].idx_v
                jv[:, idx] = ca.cross(sym.axes[k - 1], c - sym.origins[k - 1])
                jw[:, idx] = sym.axes[k - 1]
            out = m * (jv.T @ jv)
            if inertia_local is not None:
                out += jw.T @ (r_b @ ca.DM(inertia_local) @ r_b.T) @ jw
            return out

        for i in range(1, model.njoints):
            inertia = model.inertias[i]
            mass += add_point_body(i, inertia.mass, ca.DM(inertia.lever), inertia.inertia)
        flange = model.frames[self.flange_frame]
        com_joint = ca.DM(flange.placement.rotation) @ spindle_com + ca.DM(flange.placement.translation)
        mass += add_point_body(flange.parentJoint, spindle_mass, com_joint, None)
        return mass

    @cached_property
    def pose_function(self) -> ca.Function:
        """``pose(q[n], tcp[3]) -> (p[3], R[3x3])``: TCP position [m] and rotation in base axes."""
        s = self.symbolic
        return ca.Function("tcp_pose", [s.q, s.tcp], [s.position, s.rotation],
                           ["q", "tcp"], ["p", "R"])

    @cached_property
    def jacobian_function(self) -> ca.Function:
        """``jacobian(q[n], tcp[3]) -> J[6xn]``: geometric TCP Jacobian, base axes."""
        s = self.symbolic
        return ca.Function("tcp_jacobian", [s.q, s.tcp], [s.jacobian], ["q", "tcp"], ["J"])


_CACHE: dict[str, Robot] = {}


def load_robot(name: str = DEFAULT_ROBOT) -> Robot:
    """Load a shipped robot by name (cached: symbolic expressions are built once per process)."""
    if name not in _CACHE:
        _CACHE[name] = Robot(_read_robot_data(name))
    return _CACHE[name]
