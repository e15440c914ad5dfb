"""Floquet stability of the time-periodic 2-DOF cut without regeneration (docs/model.md §5 `floquet`, §6).

Linearised about any trajectory that keeps every engaged edge in the cut, the structure of
:mod:`models.dynamics` with the nominal surface obeys

    M ẍ + C ẋ + (K − K_p(t)) x = F₀(t),     K_p(t + T) = K_p(t),

K_p(t) the instantaneous ∂F/∂x of the engaged edge slices (its mean is the ``oriented`` process
stiffness of docs/model.md §5; :func:`models.dynamics.process_stiffness_series`), T the tooth period. The
forcing F₀ does not decide stability: the homogeneous system z' = A(t) z, z = (x, ẋ), does. Its
monodromy matrix Φ(T) maps the state over one tooth period; the cut is stable iff the spectral
radius ρ of Φ(T) is below 1. The averaged (eigen) criterion replaces K_p(t) by its mean, which is
right only when the tooth-passing frequency is well above the arm's modes (docs/model.md §6's caveat).

Φ(T) is the ordered product of exp(A(t_p + ½dt)·dt) over ``steps`` sub-steps (exponential midpoint
rule, second order in dt). The exponentials are evaluated in one batch for many points (Taylor
series with scaling and squaring) so the planner can map the criterion along a path.

Derived numbers:
- ``spectral_radius`` ρ [-] and ``margin`` = 1 − ρ [-] (> 0 stable).
- ``growth_rate`` = ln ρ / T [1/s]: the envelope of a small vibration grows as e^{growth·t}.
- ``frequency_hz``: the multiplier's angle θ gives vibration frequencies θ/(2πT) + k/T; the one
  reported is folded into [0, f_tooth/2] (f_tooth/2 is period doubling, θ = π).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from models import cutting
from models.analysis import Cut, ModelParameters, path_inputs, point_function
from models.cutter_geometry import DEFAULT_SLICES, cutter_geometry
from models.dynamics import process_stiffness_series
from models.errors import InputError
from models.robot import Robot
from models.structure import DEFAULT_DAMPING_RATIO, Structure, modal_damping, tcp_mass_function

__all__ = [
    "DEFAULT_FLOQUET_STEPS",
    "FloquetResult",
    "floquet",
    "floquet_batch",
    "floquet_margin",
    "monodromy",
    "path_floquet",
]

#: Sub-steps per tooth period of the monodromy integration [-]; the spectral radius changes by
#: < 1e-4 when doubled for the KR 210 cuts of the tests (a test checks the convergence).
DEFAULT_FLOQUET_STEPS = 256
#: Largest ‖A dt‖ (∞-norm) fed to the Taylor series; larger steps are halved (scaling and squaring).
_TAYLOR_NORM = 0.25
#: Taylor order: error ~ 0.25¹³/13! ≈ 1e-18 per sub-step at the largest allowed norm.
_TAYLOR_ORDER = 12


@dataclass(frozen=True)
class FloquetResult:
    """Floquet verdict of one cut at one pose.

    Attributes:
        spectral_radius: ρ of the monodromy matrix [-].
        margin: 1 − ρ [-] (> 0 stable).
        multipliers: eigenvalues of the monodromy matrix, largest modulus first, shape (4,).
        growth_rate: ln ρ / T [1/s].
        frequency_hz: vibration frequency of the leading multiplier folded into [0, f_tooth/2] [Hz].
        tooth_period: T [s].
        steps: sub-steps used.
    """

    spectral_radius: float
    margin: float
    multipliers: np.ndarray
    growth_rate: float
    frequency_hz: float
    tooth_period: float
    steps: int

    @property
    def stable(self) -> bool:
        """ρ < 1."""
        return self.spectral_radius < 1.0

    def aliases_hz(self, up_to_hz: float) -> np.ndarray:
        """Every frequency θ/(2πT) ± k/T in [0, up_to_hz] the leading multiplier stands for [Hz]."""
        f_t = 1.0 / self.tooth_period
        base = abs(float(np.angle(self.multipliers[0]))) / (2.0 * np.pi * self.tooth_period)
        ks = np.arange(0, int(up_to_hz / f_t) + 2)
        out = np.concatenate([base + ks * f_t, ks * f_t - base])
        return np.sort(out[(out >= 0) & (out <= up_to_hz)])


def _expm_batch(a: np.ndarray) -> np.ndarray:
    """exp of a batch of small square matrices, shape (..., n, n): Taylor + scaling and squaring."""
    norm = np.abs(a).sum(axis=-1).max()
    squarings = max(0, int(math.ceil(math.log2(norm / _TAYLOR_NORM)))) if norm > 0 else 0
    a = a / (2.0**squarings)
    n = a.shape[-1]
    result = np.broadcast_to(np.eye(n), a.shape).copy()
    term = result.copy()
    for order in range(1, _TAYLOR_ORDER + 1):
        term = term @ a / order
        result = result + term
    for _ in range(squarings):
        result = result @ result
    return result


def monodromy(mass: np.ndarray, damping: np.ndarray, stiffness: np.ndarray,
              process_stiffness: np.ndarray, period: np.ndarray | float) -> np.ndarray:
    """Monodromy matrices of z' = A(t) z for a batch of points.

    Args:
        mass, damping, stiffness: [kg], [N·s/m], [N/m], shape (P, 2, 2).
        process_stiffness: K_p(t) at the sub-step midpoints [N/m], shape (P, steps, 2, 2).
        period: tooth period T [s], scalar or shape (P,).

    Returns:
        Φ(T), shape (P, 4, 4), for the state z = (x, ẋ).
    """
    mass, damping, stiffness = (np.asarray(v, float) for v in (mass, damping, stiffness))
    kp = np.asarray(process_stiffness, float)
    n_pts, steps = kp.shape[0], kp.shape[1]
    period = np.broadcast_to(np.asarray(period, float), (n_pts,))
    m_inv = np.linalg.inv(mass)
    a = np.zeros((n_pts, steps, 4, 4))
    a[:, :, 0:2, 2:4] = np.eye(2)
    a[:, :, 2:4, 0:2] = -np.einsum("pij,psjk->psik", m_inv, stiffness[:, None] - kp)
    a[:, :, 2:4, 2:4] = -(m_inv @ damping)[:, None]
    e = _expm_batch(a * (period / steps)[:, None, None, None])
    phi = np.broadcast_to(np.eye(4), (n_pts, 4, 4)).copy()
    for s in range(steps):
        phi = e[:, s] @ phi
    return phi


def _result(phi: np.ndarray, period: float, steps: int) -> FloquetResult:
    mult = np.linalg.eigvals(phi)
    mult = mult[np.argsort(-np.abs(mult), kind="stable")]
    rho = float(np.abs(mult[0]))
    theta = abs(float(np.angle(mult[0])))
    return FloquetResult(spectral_radius=rho, margin=1.0 - rho, multipliers=mult,
                         growth_rate=math.log(rho) / period if rho > 0 else -math.inf,
                         frequency_hz=theta / (2.0 * np.pi * period), tooth_period=period,
                         steps=steps)


def floquet_batch(structures: list[Structure], cuts: list[Cut], coefficients, helix_angle: float,
                  steps: int = DEFAULT_FLOQUET_STEPS,
                  slices: int = DEFAULT_SLICES) -> list[FloquetResult]:
    """Floquet verdicts for many (structure, cut) pairs in one batch (the planner's entry point).

    Args:
        structures: one per point (M, C, K in the cut's (X_o, Z_o) plane).
        cuts: one per point (engagement, spindle speed, flutes, radius).
        coefficients: cutting coefficients (6,) [N/m², N/m] or a Material, shared by all points.
        helix_angle: [rad].
        steps: sub-steps per tooth period.
        slices: axial slices of the cutter.
    """
    if len(structures) != len(cuts) or not structures:
        raise InputError("floquet", "need as many structures as cuts, at least one")
    if steps < 8:
        raise InputError("steps", f"need at least 8 sub-steps per tooth period, got {steps}")
    geos = [cutter_geometry(cut, helix_angle, steps, slices, offset=0.5) for cut in cuts]
    kp = np.stack([process_stiffness_series(g, coefficients) for g in geos])
    mass = np.stack([s.mass for s in structures])
    damping = np.stack([s.damping for s in structures])
    stiffness = np.stack([s.stiffness for s in structures])
    periods = np.array([g.tooth_period for g in geos])
    phis = monodromy(mass, damping, stiffness, kp, periods)
    return [_result(phi, float(period), steps) for phi, period in zip(phis, periods, strict=True)]


def floquet(structure: Structure, cut: Cut, coefficients, helix_angle: float,
            steps: int = DEFAULT_FLOQUET_STEPS, slices: int = DEFAULT_SLICES) -> FloquetResult:
    """Floquet verdict of one cut on one structure (see :func:`floquet_batch`)."""
    return floquet_batch([structure], [cut], coefficients, helix_angle, steps, slices)[0]


def floquet_margin(structures: list[Structure], cuts: list[Cut], coefficients, helix_angle: float,
                   steps: int = DEFAULT_FLOQUET_STEPS,
                   slices: int = DEFAULT_SLICES) -> tuple[np.ndarray, np.ndarray]:
    """(spectral radius ρ, margin 1 − ρ) per point, shape (P,) each; margin > 0 is stable."""
    res = floquet_batch(structures, cuts, coefficients, helix_angle, steps, slices)
    rho = np.array([r.spectral_radius for r in res])
    return rho, 1.0 - rho


def _cut_from_vector(v: np.ndarray) -> Cut:
    modes = {code: name for name, code in cutting.MILLING_MODES.items()}
    mode = modes[int(round(float(v[8])))]
    return Cut(v[0:3], v[3:6], float(v[6]), float(v[7]), mode, float(v[9]), int(round(v[10])),
               float(v[11]))


def path_floquet(robot: Robot, params: ModelParameters, q: np.ndarray, cuts: np.ndarray,
                 feeds: np.ndarray, helix_angle: float,
                 damping_ratio: float = DEFAULT_DAMPING_RATIO,
                 steps: int = DEFAULT_FLOQUET_STEPS,
                 slices: int = DEFAULT_SLICES) -> tuple[np.ndarray, np.ndarray]:
    """Floquet (ρ, margin 1 − ρ) at every path sample, shape (n,) each — the planner's form.

    The stiffness (CCT under each sample's mean force) and the Cartesian mass are evaluated with
    mapped CasADi Functions, the monodromy matrices in one batch.

    Args:
        q: joints [rad], shape (n, nq).
        cuts: ``Cut.vector()`` rows, shape (n, 12) (directions in base axes).
        feeds: [m/s], shape (n,).
        helix_angle: [rad]; damping_ratio: ζ of both modes.
    """
    q, cuts, feeds, n = path_inputs(q, cuts, feeds)
    k_fun = point_function(robot, "oriented", "isotropic", outputs=("stiffness",)).map(n)
    k_t = np.asarray(k_fun(q.T, cuts.T, feeds.reshape(1, -1), params.vector()), float)
    m_fun = tcp_mass_function(robot).map(n)
    lam = np.asarray(m_fun(q.T, np.asarray(params.tcp, float), params.spindle_mass,
                           np.asarray(params.spindle_com, float)), float)
    structures, cut_list = [], []
    for i in range(n):
        cut = _cut_from_vector(cuts[i])
        plane = np.column_stack([cut.radial_dir, cut.feed_dir])
        k2 = plane.T @ k_t[:, 3 * i:3 * i + 3] @ plane
        m2 = plane.T @ lam[:, 3 * i:3 * i + 3] @ plane
        k2, m2 = 0.5 * (k2 + k2.T), 0.5 * (m2 + m2.T)
        structures.append(Structure(m2, k2, modal_damping(m2, k2, damping_ratio), plane,
                                    damping_ratio))
        cut_list.append(cut)
    return floquet_margin(structures, cut_list, params.coefficients, helix_angle, steps, slices)
