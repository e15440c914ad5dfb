"""Where the static force model holds, and where the stability boundary lies (docs/model.md §6 (a)).

- :func:`dynamic_map`: F_PV / F_peak of the time-domain simulation over a set of poses for one cut;
  the static (averaged) force model is valid where F_PV < :data:`STATIC_VALIDITY` · F_peak.
- :func:`critical_depth`: the axial depth at which a cut turns unstable, by bisection, judged by
  the Floquet criterion (no regeneration) or by the simulation (with or without regeneration), so
  the effect of regeneration on the boundary can be read off.

The cut is given once, with its feed and radial directions in the **TCP frame** (so that it
follows the tool from pose to pose), see :func:`cut_at_pose`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from models.analysis import Cut, ModelParameters
from models.dynamics import DEFAULT_DAMPING_RATIO, pose_structure, simulate
from models.errors import CctmillError, InputError
from models.floquet import floquet
from models.robot import Robot

__all__ = [
    "STATIC_VALIDITY",
    "DynamicMap",
    "critical_depth",
    "cut_at_pose",
    "dynamic_map",
]

#: F_PV / F_peak below which the static force model is taken as valid [-] (docs/model.md §6).
STATIC_VALIDITY = 0.1


def cut_at_pose(robot: Robot, params: ModelParameters, q: np.ndarray, cut_tcp: Cut) -> Cut:
    """``cut_tcp`` with its directions (given in the TCP frame) rotated into base axes at ``q``."""
    rot = np.asarray(robot.pose_function(np.asarray(q, float), params.tcp)[1], float)
    return replace(cut_tcp, feed_dir=rot @ cut_tcp.feed_dir, radial_dir=rot @ cut_tcp.radial_dir)


@dataclass(frozen=True)
class DynamicMap:
    """F_PV / F_peak over poses. NaN where the pose is singular or outside the limits.

    Attributes:
        q: joints [rad], shape (P, nq).
        tcp_position: [m], shape (P, 3).
        f_peak, f_pv: [N], shape (P,).
        ratio: F_PV / F_peak [-], shape (P,).
        valid: the static force model holds (ratio < :data:`STATIC_VALIDITY`), shape (P,).
        floquet_radius: spectral radius of the Floquet criterion [-], shape (P,).
        natural_frequencies_hz: shape (P, 2).
    """

    q: np.ndarray
    tcp_position: np.ndarray
    f_peak: np.ndarray
    f_pv: np.ndarray
    ratio: np.ndarray
    valid: np.ndarray
    floquet_radius: np.ndarray
    natural_frequencies_hz: np.ndarray


def dynamic_map(robot: Robot, params: ModelParameters, q: np.ndarray, cut_tcp: Cut, feed: float,
                helix_angle: float, damping_ratio: float = DEFAULT_DAMPING_RATIO,
                duration: float = 1.0, fs: float = 5000.0,
                regeneration: bool = True) -> DynamicMap:
    """Simulate ``cut_tcp`` at ``feed`` [m/s] at every pose of ``q`` [rad], shape (P, nq)."""
    q = np.atleast_2d(np.asarray(q, float))
    n = q.shape[0]
    out = {k: np.full(n, np.nan) for k in ("f_peak", "f_pv", "ratio", "rho")}
    pos = np.full((n, 3), np.nan)
    freqs = np.full((n, 2), np.nan)
    from models.point import PointModel

    checker = PointModel(robot, params)
    for i, qi in enumerate(q):
        try:
            checker.check_pose(qi)
            cut = cut_at_pose(robot, params, qi, cut_tcp)
            st = pose_structure(robot, params, qi, cut, feed, damping_ratio)
        except CctmillError:
            continue
        pos[i] = np.asarray(robot.pose_function(qi, params.tcp)[0], float).reshape(3)
        sim = simulate(st, cut, feed, params.coefficients, helix_angle, duration=duration, fs=fs,
                       regeneration=regeneration)
        out["f_peak"][i], out["f_pv"][i], out["ratio"][i] = sim.f_peak, sim.f_pv, sim.dynamic_ratio
        out["rho"][i] = floquet(st, cut, params.coefficients, helix_angle).spectral_radius
        freqs[i] = st.natural_frequencies_hz
    with np.errstate(invalid="ignore"):
        valid = out["ratio"] < STATIC_VALIDITY
    return DynamicMap(q=q, tcp_position=pos, f_peak=out["f_peak"], f_pv=out["f_pv"],
                      ratio=out["ratio"], valid=valid, floquet_radius=out["rho"],
                      natural_frequencies_hz=freqs)


def critical_depth(robot: Robot, params: ModelParameters, q: np.ndarray, cut: Cut, feed: float,
                   helix_angle: float, judge: str = "floquet", a_p_range: tuple[float, float] =
                   (1e-4, 8e-3), tol: float = 0.02, damping_ratio: float = DEFAULT_DAMPING_RATIO,
                   duration: float = 2.0) -> float:
    """Largest stable axial depth [m] in ``a_p_range`` by bisection (relative tolerance ``tol``).

    Args:
        judge: ``"floquet"`` (ρ < 1, no regeneration), ``"simulation"`` (growth < 0, no
            regeneration) or ``"regeneration"`` (growth < 0, with regeneration).

    Returns the upper end of the range if it is stable, NaN if even the lower end is not. The
    stiffness is evaluated once, under the mean force of the depth being tried.
    """
    if judge not in ("floquet", "simulation", "regeneration"):
        raise InputError("judge", f"{judge!r} is not floquet, simulation or regeneration")
    lo, hi = a_p_range
    if not 0 < lo < hi:
        raise InputError("a_p_range", f"need 0 < lo < hi, got {a_p_range}")

    def stable(a_p: float) -> bool:
        c = replace(cut, a_p=a_p)
        st = pose_structure(robot, params, q, c, feed, damping_ratio)
        if judge == "floquet":
            return floquet(st, c, params.coefficients, helix_angle).spectral_radius < 1.0
        sim = simulate(st, c, feed, params.coefficients, helix_angle, duration=duration,
                       regeneration=judge == "regeneration")
        return sim.growth_rate < 0.0

    if stable(hi):
        return hi
    if not stable(lo):
        return math.nan
    while hi / lo > 1.0 + tol:
        mid = math.sqrt(lo * hi)
        lo, hi = (mid, hi) if stable(mid) else (lo, mid)
    return lo
