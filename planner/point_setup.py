"""The point model at one pose, from the values a person types (mm, degrees, rpm): what
``cctmill analyze`` / ``stability`` / ``simulate`` and the demo's Case 1 evaluate.

:class:`PointSetup` holds those values with their units in the names; :meth:`PointSetup.build`
is the one SI edge (mm → m, deg → rad, rpm → rad/s) and returns the model, the joints and the cut.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from models.analysis import Cut, ModelParameters
from models.cutting import load_material
from models.errors import InputError
from models.point import PointModel
from models.robot import DEFAULT_ROBOT, load_robot

__all__ = ["CASE1", "PointSetup"]

#: Fields of :class:`Cut` as :class:`PointSetup` names them (for messages).
_CUT_FIELDS = {"radial direction": "radial_dir", "feed direction": "feed_dir",
               "radial depth": "ae_mm", "axial depth": "ap_mm", "spindle speed": "rpm",
               "tool radius": "diameter_mm", "flutes": "flutes"}


@dataclass(frozen=True)
class PointSetup:
    """A pose, a cut and the model options, in the units their names carry.

    Attributes:
        joints_deg: KUKA axis values A1..A6 [deg], shape (6,).
        feed_dir: feed direction Z_o in base axes, (3,); radial_dir: X_o (the cutting edge at
            immersion 0), (3,).
        ap_mm: axial depth [mm]; ae_mm: radial depth [mm] (None: slot, the diameter).
        tcp_mm: TCP offset in the flange frame [mm], (3,).
        rpm, flutes, diameter_mm, milling (up, down, slot), material, robot: the cut and the cell.
        cct, mass_model, process_model, criterion, gamma_window_deg (lo, hi): the model.
        joint_stiffness_scale, process_gain, spindle_kg (None: the robot data's): calibration.
    """

    joints_deg: tuple[float, ...]
    feed_dir: tuple[float, ...]
    radial_dir: tuple[float, ...]
    ap_mm: float
    ae_mm: float | None = None
    tcp_mm: tuple[float, ...] = (0.0, 0.0, 0.0)
    rpm: float = 1000.0
    flutes: int = 2
    diameter_mm: float = 25.4
    milling: str = "up"
    material: str = "al6061"
    robot: str = DEFAULT_ROBOT
    cct: bool = True
    mass_model: str = "isotropic"
    process_model: str = "thesis"
    criterion: str = "eigen"
    gamma_window_deg: tuple[float, float] = (-90.0, 90.0)
    joint_stiffness_scale: float = 1.0
    process_gain: float = 1.0
    spindle_kg: float | None = None

    def build(self) -> tuple[PointModel, np.ndarray, Cut]:
        """``(model, q [rad], cut)``. Raises InputError naming the field to fix."""
        robot = load_robot(self.robot)
        material = load_material(self.material)
        joints = np.asarray(self.joints_deg, float)
        if joints.shape != (robot.nq,) or not np.all(np.isfinite(joints)):
            raise InputError("joints_deg", f"need {robot.nq} finite values, got {self.joints_deg!r}")
        q = np.radians(joints)
        tcp = np.asarray(self.tcp_mm, float) * 1e-3
        radius = self.diameter_mm * 1e-3 / 2.0
        if self.ae_mm is None:
            if self.milling != "slot":
                raise InputError("ae_mm", "required for up and down milling")
            a_e = 2.0 * radius
        else:
            a_e = self.ae_mm * 1e-3
        if not self.joint_stiffness_scale > 0:
            raise InputError("joint_stiffness_scale", "must be positive")
        lo, hi = np.radians(np.asarray(self.gamma_window_deg, float))
        if not lo < hi:
            raise InputError("gamma_window_deg", "LO must be below HI")
        try:
            cut = Cut(feed_dir=np.asarray(self.feed_dir, float),
                      radial_dir=np.asarray(self.radial_dir, float), a_e=a_e,
                      a_p=self.ap_mm * 1e-3, mode=self.milling,
                      spindle_speed=self.rpm * 2.0 * np.pi / 60.0, flutes=self.flutes,
                      radius=radius)
        except InputError as e:
            name = _CUT_FIELDS.get(e.field, e.field)
            raise InputError(name, str(e).split(": ", 1)[1]) from None
        params = ModelParameters(
            joint_stiffness=robot.data.joint_stiffness * self.joint_stiffness_scale,
            coefficients=material.coefficients(), cct=self.cct,
            process_gain=self.process_gain, tcp=tcp, gamma_window=(float(lo), float(hi)),
            spindle_mass=robot.data.spindle_mass if self.spindle_kg is None else self.spindle_kg,
            spindle_com=robot.data.spindle_com)
        model = PointModel(robot, params, self.process_model, self.mass_model, self.criterion)
        return model, q, cut


#: The thesis's Case 1: KR 210 pose, cutting frame and cut (a_e 15.24 mm, a_p 5.08 mm, 1000 rpm).
CASE1 = PointSetup(joints_deg=(-96.42, -29.26, 99.08, -9.95, 83.23, -160.5),
                   feed_dir=(0.0, 1.0, 0.0), radial_dir=(1.0, 0.0, 0.0), ae_mm=15.24, ap_mm=5.08)
