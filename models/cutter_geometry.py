"""The helical cutter over one tooth period (docs/model.md §4, §6): a flat end mill cut into thin axial
slices, slice j of flute k at the immersion angle φ = Ω t + 2πk/N − j·Δz·tan(helix)/R (the helix
makes the upper slices lag), and which edge slices are in the engaged arc at each instant. The
simulation (:mod:`models.dynamics`) and the Floquet criterion (:mod:`models.floquet`) step through it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from models import cutting
from models.analysis import Cut
from models.errors import InputError

__all__ = ["CutterGeometry", "DEFAULT_SLICES", "cutter_geometry"]

#: Axial slices of the helical cutter [-].
DEFAULT_SLICES = 16


@dataclass(frozen=True)
class CutterGeometry:
    """Edge-slice angles at the ``steps`` instants of one tooth period. Arrays (steps, N·S).

    Row p holds every (flute, slice) at time p·dt; with identical flutes the set of angles repeats
    every tooth period, so row p also indexes the surface memory (the previous edge at the same
    angle and height passed exactly one tooth period, ``steps`` rows, earlier).

    Attributes:
        cos, sin: cos φ, sin φ of each edge slice.
        engaged: φ (mod 2π) inside the engaged arc [φ_st, φ_ex].
        width: axial width b of each slice [m].
        tooth_period: T = 2π/(NΩ) [s].
        steps: steps per tooth period.
    """

    cos: np.ndarray
    sin: np.ndarray
    engaged: np.ndarray
    width: np.ndarray
    tooth_period: float
    steps: int

    @property
    def dt(self) -> float:
        """Step [s]."""
        return self.tooth_period / self.steps


def cutter_geometry(cut: Cut, helix_angle: float, steps: int, slices: int = DEFAULT_SLICES,
                    offset: float = 0.0) -> CutterGeometry:
    """Angles of every edge slice over one tooth period (``steps`` instants), docs/model.md §4 conventions.

    Args:
        cut: the cut (a_e, a_p, mode, spindle speed, flutes, radius).
        helix_angle: [rad]; slice j (height (j + ½)·a_p/S) lags by height·tan(helix)/R.
        steps: instants per tooth period.
        slices: axial slices S.
        offset: instants at (p + offset)·dt (0.5: the midpoints the Floquet integrator uses).
    """
    if steps < 4 or slices < 1:
        raise InputError("discretisation", f"need >= 4 steps per tooth and >= 1 slice, got "
                         f"{steps}, {slices}")
    n_fl = int(cut.flutes)
    phi_st, phi_ex = (float(a) for a in cutting.immersion_angles(cut.a_e, cut.radius, cut.mode))
    period = 2.0 * np.pi / (n_fl * cut.spindle_speed)
    height = (np.arange(slices) + 0.5) * cut.a_p / slices
    lag = height * math.tan(helix_angle) / cut.radius
    t = (np.arange(steps) + offset) * (2.0 * np.pi / n_fl / steps)
    flute = np.arange(n_fl) * (2.0 * np.pi / n_fl)
    phi = t[:, None, None] + flute[None, :, None] - lag[None, None, :]
    phi = np.mod(phi, 2.0 * np.pi).reshape(steps, n_fl * slices)
    engaged = (phi >= phi_st) & (phi <= phi_ex)
    width = np.full(phi.shape, cut.a_p / slices)
    return CutterGeometry(np.cos(phi), np.sin(phi), engaged, width, period, steps)
