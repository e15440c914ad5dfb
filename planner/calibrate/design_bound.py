"""How well a set of test passes can identify the cutting coefficients, before they are cut.

The mean forces of the passes are F̄ = A K (:func:`planner.calibrate.fit_coefficients.design_rows`)
with a measurement error σ = σ_abs + σ_rel |F̄| per component. Their Fisher information is
I = Σ Aᵀ A / σ², and no unbiased estimate from these passes can have a smaller covariance than
I⁻¹ (the Cramér–Rao bound). :func:`coefficient_bound` gives the bound's standard errors relative
to K; :func:`best_design` searches a candidate set for the n passes with the smallest worst
relative bound (a Fedorov-style exchange). A target below the best design's bound cannot be met by
any fit of those passes at that noise: the calibration benchmark quotes both
(docs/calibration.md, "Validation on a simulated truth").
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from models.tooling import Tool
from planner.calibrate.fit_coefficients import design_rows
from planner.calibrate.records import CutRecord

__all__ = ["FORCE_NOISE_N", "FORCE_NOISE_REL", "best_design", "coefficient_bound", "information"]

#: The default force measurement error, σ = FORCE_NOISE_N [N] + FORCE_NOISE_REL × |F̄| per
#: component: a dynamometer's floor, calibration and cross-talk over a pass (also the simulated
#: truth's default, :class:`planner.calibrate.truth.TruthCell`).
FORCE_NOISE_N, FORCE_NOISE_REL = 0.5, 0.01


def information(records: Sequence[CutRecord], tool: Tool, coefficients: np.ndarray,
                force_noise_n: float, force_noise_rel: float) -> np.ndarray:
    """Fisher information of the passes about K, (6, 6), at ``coefficients`` (SI) and the error
    σ = ``force_noise_n`` [N] + ``force_noise_rel`` × |F̄| per component."""
    return sum((_info(design_rows(r, tool), coefficients, force_noise_n, force_noise_rel)
                for r in records), np.zeros((6, 6)))


def coefficient_bound(records: Sequence[CutRecord], tool: Tool, coefficients: np.ndarray,
                      force_noise_n: float = FORCE_NOISE_N,
                      force_noise_rel: float = FORCE_NOISE_REL) -> np.ndarray:
    """The Cramér–Rao standard errors of K from ``records``, relative to ``coefficients``, (6,);
    ``inf`` where the passes cannot separate a coefficient (a singular information)."""
    return _relative(information(records, tool, coefficients, force_noise_n, force_noise_rel),
                     coefficients)


def best_design(candidates: Sequence[CutRecord], n: int, tool: Tool, coefficients: np.ndarray,
                force_noise_n: float = FORCE_NOISE_N, force_noise_rel: float = FORCE_NOISE_REL,
                starts: int = 12,
                seed: int = 0) -> tuple[list[int], np.ndarray]:
    """The ``n`` candidates (repeats allowed) whose worst relative Cramér–Rao error is smallest:
    (their indices, that bound (6,)). Exchange from ``starts`` random designs: replace one pass by
    the candidate that lowers the worst bound most, until no exchange does."""
    k = np.asarray(coefficients, float)
    infos = [_info(design_rows(r, tool), k, force_noise_n, force_noise_rel) for r in candidates]
    rng = np.random.default_rng(seed)

    def worst(design: list[int]) -> float:
        return float(np.max(_relative(sum((infos[i] for i in design), np.zeros((6, 6))), k)))

    best: tuple[float, list[int]] = (np.inf, [])
    for _ in range(starts):
        design = [int(i) for i in rng.integers(0, len(infos), n)]
        value = worst(design)
        improved = True
        while improved:
            improved = False
            for slot in range(n):
                for cand in range(len(infos)):
                    if cand == design[slot]:
                        continue
                    trial = design[:slot] + [cand] + design[slot + 1:]
                    v = worst(trial)
                    if v < value * (1.0 - 1e-9):
                        design, value, improved = trial, v, True
        if value < best[0]:
            best = (value, sorted(design))
    total = sum((infos[i] for i in best[1]), np.zeros((6, 6)))
    return best[1], _relative(total, k)


def _info(a: np.ndarray, k: np.ndarray, sigma_abs: float, sigma_rel: float) -> np.ndarray:
    sigma = sigma_abs + sigma_rel * float(np.linalg.norm(a @ k))
    return a.T @ a / sigma**2


def _relative(info: np.ndarray, k: np.ndarray) -> np.ndarray:
    scale = np.abs(k)
    scaled = info * np.outer(scale, scale)       # the information about K / |K|
    if np.linalg.matrix_rank(scaled) < 6:
        return np.full(6, np.inf)
    return np.sqrt(np.diag(np.linalg.inv(scaled)))
