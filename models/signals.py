"""Synthetic sensor signals from the milling simulation, for the supervisor (docs/model.md §6 (b), §9).

Two signals at the simulation's output rate f_s:

- **resultant force** |F(t)| [N] plus white Gaussian noise (a dynamometer or the spindle's
  force estimate);
- **strain-like** signal ε(t) [-] of the thesis's PVDF rosette: a bending strain of the tool's
  section, ε = M_b / (E · S), with M_b the bending moment of the in-plane cutting force about the
  sensor section (force × lever, the lever being the distance from the sensor section to the
  middle of the axial depth of cut), S = π d³/32 the section modulus of a solid round section of
  diameter d and E the Young's modulus. A gauge measures the strain of one fibre: the moment
  component about the axis normal to the gauge direction u (in the X_o–Z_o plane), i.e.
  ε = (F · u) · lever / (E S). The PVDF film's charge is proportional to strain; its gain is
  calibrated away, so the signal is kept in strain units. Plus white Gaussian noise.

The noise is drawn from the ``rng`` passed in (seeded by the caller).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from models.dynamics import SimulationResult
from models.errors import InputError

__all__ = [
    "CARBIDE_YOUNGS_MODULUS",
    "SyntheticSignals",
    "bending_strain",
    "synthetic_signals",
]

#: Young's modulus of cemented carbide [Pa] (the thesis's tool material; WC-Co ≈ 600 GPa).
CARBIDE_YOUNGS_MODULUS = 6.0e11


@dataclass(frozen=True)
class SyntheticSignals:
    """Sensor signals sampled at ``fs``.

    Attributes:
        time: [s], shape (k,).
        force: resultant force with noise [N], shape (k,).
        strain: bending strain with noise [-], shape (k,).
        force_clean, strain_clean: the same without noise.
        fs: sample rate [Hz].
        force_noise, strain_noise: noise standard deviations [N], [-].
    """

    time: np.ndarray
    force: np.ndarray
    strain: np.ndarray
    force_clean: np.ndarray
    strain_clean: np.ndarray
    fs: float
    force_noise: float
    strain_noise: float


def bending_strain(force_o: np.ndarray, lever: float, diameter: float,
                   youngs_modulus: float = CARBIDE_YOUNGS_MODULUS,
                   gauge_angle: float = 0.0) -> np.ndarray:
    """ε = (F · u) · lever / (E · π d³/32) [-] for forces in (X_o, Y_o, Z_o) [N], shape (k, 3).

    Args:
        lever: sensor section to the middle of the cut [m].
        diameter: section diameter d [m].
        youngs_modulus: E [Pa].
        gauge_angle: direction u of the gauge in the X_o–Z_o plane, from X_o towards Z_o [rad].
    """
    for name, value in (("lever", lever), ("diameter", diameter), ("Young's modulus", youngs_modulus)):
        if not (math.isfinite(value) and value > 0):
            raise InputError(name, f"must be positive and finite, got {value!r}")
    f = np.atleast_2d(np.asarray(force_o, float))
    along = f[:, 0] * math.cos(gauge_angle) + f[:, 2] * math.sin(gauge_angle)
    section_modulus = math.pi * diameter**3 / 32.0
    return along * lever / (youngs_modulus * section_modulus)


def synthetic_signals(sim: SimulationResult, rng: np.random.Generator, lever: float = 0.05,
                      diameter: float = 25.4e-3, youngs_modulus: float = CARBIDE_YOUNGS_MODULUS,
                      gauge_angle: float = 0.0, force_noise: float = 1.0,
                      strain_noise: float | None = None) -> SyntheticSignals:
    """Force and strain signals of a simulated cut with noise.

    Args:
        sim: the simulation (its output rate is the signals' rate).
        rng: random generator (seed it).
        lever, diameter, youngs_modulus, gauge_angle: see :func:`bending_strain`.
        force_noise: standard deviation of the force noise [N].
        strain_noise: standard deviation of the strain noise [-]; default: the strain of
            ``force_noise`` newtons, so both signals have the same signal-to-noise ratio.
    """
    if not (math.isfinite(force_noise) and force_noise >= 0):
        raise InputError("force noise", f"must be >= 0, got {force_noise!r}")
    force_clean = np.linalg.norm(sim.force, axis=1)
    strain_clean = bending_strain(sim.force, lever, diameter, youngs_modulus, gauge_angle)
    if strain_noise is None:
        strain_noise = force_noise * lever / (youngs_modulus * math.pi * diameter**3 / 32.0)
    if not (math.isfinite(strain_noise) and strain_noise >= 0):
        raise InputError("strain noise", f"must be >= 0, got {strain_noise!r}")
    k = force_clean.size
    return SyntheticSignals(
        time=sim.time.copy(), force=force_clean + rng.normal(0.0, force_noise, k),
        strain=strain_clean + rng.normal(0.0, strain_noise, k), force_clean=force_clean,
        strain_clean=strain_clean, fs=sim.fs, force_noise=float(force_noise),
        strain_noise=float(strain_noise))
