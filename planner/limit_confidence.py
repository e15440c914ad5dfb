"""Force and deflection limits that hold with a stated probability under a calibration's
parameter uncertainty (docs/calibration.md, "Planning with the fit's uncertainty").

A calibrated model predicts the mean force F̄ = A(c) K from fitted coefficients K with covariance
Σ_K, and the deflection δ ≈ C F̄ / s from a fitted stiffness scale s with relative standard error
σ_s. A plan that holds ``|F̄| ≤ F_max`` and ``|δ| ≤ tol`` at the fitted values holds them in the
real cell only about half of the time at the binding samples. To first order the standard errors
of the predictions, relative to the predictions, are

    u_F = √(ĝᵀ A Σ_K Aᵀ ĝ) / |F̄|          (ĝ = F̄/|F̄|: the error of the force's magnitude)
    u_δ = √(λ_max(A Σ_K Aᵀ) / |F̄|² + σ_s²)  (the force error in its worst direction, as C may turn
                                             it into δ, plus the stiffness scale's)

and the limits are checked on |F̄|·(1 + z u_F) and |δ|·(1 + z u_δ), z the one-sided normal quantile
of ``[model] limit_confidence`` (0.95: z = 1.645). A is affine in the feed per tooth c, so the
bound grows with the feed and the feed ceilings stay monotone. The parameter errors are common to
every sample, so the probability holds for the whole plan, not per sample only. What the overlay
does not carry (a coefficient fit without a stiffness fit: σ_s unknown) counts as zero: the
bound is then only as complete as the calibration.
"""

from __future__ import annotations

from dataclasses import dataclass
from statistics import NormalDist

import numpy as np

from models.cutting import coefficient_design_function

__all__ = ["LimitConfidence", "limit_confidence"]


@dataclass(frozen=True)
class LimitConfidence:
    """The calibration's uncertainty bound on the force and deflection of the engaged samples.

    Attributes:
        probability: ``[model] limit_confidence`` [-]; z: its one-sided normal quantile [-].
        covariance: Σ_K of the fitted coefficients, SI, (6, 6).
        stiffness_rel_std: σ_s, the relative standard error of the fitted stiffness scale [-].
        design0, design1: A(c) = design0 + c · design1 per engaged sample, (m, 3, 6).
        tooth_frequency: N · rpm / 60 [1/s] (c = feed / this).
    """

    probability: float
    z: float
    covariance: np.ndarray
    stiffness_rel_std: float
    design0: np.ndarray
    design1: np.ndarray
    tooth_frequency: float

    def relative_std(self, feeds: np.ndarray, force_o: np.ndarray,
                     sel: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(u_F, u_δ) [-], (k,) each, at ``feeds`` [m/s] of the engaged samples ``sel`` whose
        predicted mean force in the cutting frame is ``force_o`` [N], (k, 3)."""
        c = np.asarray(feeds, float) / self.tooth_frequency
        a = self.design0[sel] + c[:, None, None] * self.design1[sel]
        cov_f = np.einsum("kij,jl,kml->kim", a, self.covariance, a)      # A Σ Aᵀ, (k, 3, 3)
        norm = np.linalg.norm(force_o, axis=1)
        safe = np.where(norm > 0.0, norm, 1.0)
        g = force_o / safe[:, None]
        u_force = np.sqrt(np.maximum(np.einsum("ki,kij,kj->k", g, cov_f, g), 0.0)) / safe
        worst = np.maximum(np.linalg.eigvalsh(cov_f)[:, -1], 0.0)
        u_defl = np.sqrt(worst / safe**2 + self.stiffness_rel_std**2)
        zero = norm <= 0.0
        return np.where(zero, 0.0, u_force), np.where(zero, 0.0, u_defl)

    def factors(self, feeds: np.ndarray, force_o: np.ndarray,
                sel: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(1 + z u_F, 1 + z u_δ) [-], (k,) each: what the force and the deflection are multiplied
        by before they are compared with their limits."""
        u_force, u_defl = self.relative_std(feeds, force_o, sel)
        return 1.0 + self.z * u_force, 1.0 + self.z * u_defl


def limit_confidence(job, a_e: np.ndarray, a_p: np.ndarray, mode: np.ndarray, flutes: int,
                     radius: float, tooth_frequency: float) -> LimitConfidence | None:
    """The bound for a job whose ``[calibration]`` carries a coefficient covariance or a stiffness
    scale's standard error, at ``[model] limit_confidence``; None without either (a nominal model
    states no uncertainty to bound) or at a confidence of 0.5.

    Args:
        job: the job.
        a_e, a_p: radial and axial depth of cut of the engaged samples [m], (m,) each.
        mode: their milling mode codes (:data:`models.cutting.MILLING_MODES`), (m,).
        flutes, radius: the tool's [-] and [m].
        tooth_frequency: N · rpm / 60 [1/s].
    """
    cal = job.calibration
    if cal.coefficient_covariance is None and not cal.joint_stiffness_scale_std:
        return None
    p = float(job.model.limit_confidence)
    z = NormalDist().inv_cdf(p)
    if z <= 0.0:
        return None
    cov = (np.zeros((6, 6)) if cal.coefficient_covariance is None
           else np.asarray(cal.coefficient_covariance, float).reshape(6, 6))
    cov = 0.5 * (cov + cov.T)
    m = int(np.size(a_e))
    if m:
        f = coefficient_design_function().map(m)
        args = (np.asarray(a_e, float), np.asarray(a_p, float), np.asarray(mode, float),
                np.full(m, float(flutes)), np.full(m, float(radius)))
        d0 = np.asarray(f(np.zeros(m), *args), float)
        d1 = np.asarray(f(np.ones(m), *args), float) - d0
        # (3, 6 m), column blocks per sample -> (m, 3, 6)
        d0 = d0.reshape(3, m, 6).transpose(1, 0, 2)
        d1 = d1.reshape(3, m, 6).transpose(1, 0, 2)
    else:
        d0 = d1 = np.zeros((0, 3, 6))
    return LimitConfidence(probability=p, z=z, covariance=cov,
                           stiffness_rel_std=float(cal.joint_stiffness_scale_std or 0.0),
                           design0=d0, design1=d1, tooth_frequency=float(tooth_frequency))
