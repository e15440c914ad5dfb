"""The process gain: the factor on the process stiffness K_p at which the job's eigen criterion
best separates the cuts' verdicts.

With the thesis's parameters the eigen criterion calls nearly every cut stable (K_p ≈ 1e4 N/m
against a stiffness anisotropy of 1e5-1e6 N/m, docs/model.md §5); ``[model] process_gain``
multiplies K_p. Here it is learned from the cell's verdicts: for a gain g the records' margins
m_i(g) (N/m, > 0 stable) give P(chatter_i) = σ(−m_i(g) / s), a logistic link of width s [N/m]
for what the criterion does not model (noise, the cut's dynamics); s is fitted for each g by
maximum likelihood, and the profile log-likelihood ℓ(g) over a logarithmic grid gives the
estimate ĝ = argmax ℓ and its 95 % interval {g : 2 (ℓ(ĝ) − ℓ(g)) ≤ 3.84} (likelihood ratio),
rounded outward to the grid (19 gains per decade).

Refused, with the reason: too few labelled records or too few of either verdict; a criterion
other than eigen (the Floquet and γ-window criteria do not use K_p); a best gain at the edge of
the range searched (the criterion cannot place these verdicts with any gain); and a fit whose
verdicts are no better than the job's gain already gives.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
import scipy.optimize

from models.errors import CctmillError
from planner.calibrate.context import CalibrationContext
from planner.calibrate.fit_boundary import criterion_margin, labelled_verdicts
from planner.calibrate.fit_coefficients import FitRefused
from planner.calibrate.records import CutRecord

__all__ = ["GAIN_RANGE", "ProcessGainFit", "fit_process_gain"]

#: The gains searched, relative to the job's [-]: four and a half decades, 19 points per decade.
GAIN_RANGE = (0.05, 2000.0)
_POINTS_PER_DECADE = 19
#: Half the 95 % quantile of χ²(1): the likelihood-ratio interval's depth [-].
_LR_95 = 0.5 * 3.841


@dataclass(frozen=True)
class ProcessGainFit:
    """The fitted process gain.

    Attributes:
        gain: ĝ, relative to the job's process gain [-]; gain_ci: its 95 % interval [-] (an end
            at the searched range's edge means the data do not bound it there).
        width_n_per_m: the logistic width s at ĝ [N/m].
        n, n_chatter: labelled records, of them chatter.
        accuracy: share of records whose verdict the criterion gets right at ĝ (margin ≤ 0 is
            chatter) [-]; nominal_accuracy: the same at the job's gain.
        grid, profile: the gains searched [-] and the profile log-likelihood there.
    """

    gain: float
    gain_ci: tuple[float, float]
    width_n_per_m: float
    n: int
    n_chatter: int
    accuracy: float
    nominal_accuracy: float
    grid: np.ndarray
    profile: np.ndarray

    def as_json(self) -> dict:
        return {"gain": self.gain, "gain_ci": list(self.gain_ci),
                "width_n_per_m": self.width_n_per_m, "n": self.n, "n_chatter": self.n_chatter,
                "accuracy": self.accuracy, "nominal_accuracy": self.nominal_accuracy,
                "gain_range": list(GAIN_RANGE)}


def _profile_at(m: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """(max log-likelihood over s, the best s) of P(chatter) = σ(−m / s) for verdicts y."""
    ref = float(np.median(np.abs(m))) + 1.0

    def nll(log_s: float) -> float:
        z = -m / math.exp(log_s)
        # −log σ(z) for chatter, −log σ(−z) for stable, both stable for large |z|
        return float(np.sum(np.logaddexp(0.0, -z) * y + np.logaddexp(0.0, z) * (1 - y)))

    lo, hi = math.log(ref * 1e-4), math.log(ref * 1e3)
    res = scipy.optimize.minimize_scalar(nll, bounds=(lo, hi), method="bounded",
                                         options={"xatol": 1e-3})
    return -float(res.fun), math.exp(float(res.x))


def fit_process_gain(ctx: CalibrationContext, records: Sequence[CutRecord], params=None,
                     progress: bool = False) -> ProcessGainFit:
    """Fit the process gain to the records' verdicts (module docstring).

    Args:
        ctx: the cell; its criterion must be eigen.
        records: records with a verdict of stable or chatter are used.
        params: model parameters (default: the job's; the calibrated stiffness and coefficients
            when those fits succeeded); their process gain is the job's.
        progress: a bar on a terminal.

    Raises:
        FitRefused: see the module docstring.
    """
    from planner._progress import bar

    if ctx.criterion != "eigen":
        raise FitRefused("process", f"the job's criterion is {ctx.criterion}; the process gain "
                         "enters the eigen criterion only (set [model] chatter_criterion = "
                         "\"eigen\" to fit it)")
    labelled, labels = labelled_verdicts(records, "process", "the gain is where the criterion "
                                         "puts the boundary, so cuts on both sides of it are "
                                         "needed")
    y = labels.astype(float)
    n_chatter = int(y.sum())
    base = params or ctx.params()
    g0 = float(base.process_gain)
    decades = math.log10(GAIN_RANGE[1] / GAIN_RANGE[0])
    grid = np.geomspace(*GAIN_RANGE, int(round(decades * _POINTS_PER_DECADE)) + 1)
    grid = np.unique(np.append(grid, 1.0))
    margins = np.empty((grid.size, len(labelled)))
    with bar(int(grid.size * len(labelled)), "process gain", progress, unit="margin",
             min_total=200) as pbar:
        for i, g in enumerate(grid):
            p = replace(base, process_gain=g0 * float(g))
            for j, r in enumerate(labelled):
                try:
                    margins[i, j] = criterion_margin(ctx, r, p)
                except CctmillError as e:
                    raise FitRefused("process", f"record {r.name}: {e}; fix or leave out the "
                                     "record") from e
            pbar.update(len(labelled))
    prof = np.array([_profile_at(m, y) for m in margins])
    ll, widths = prof[:, 0], prof[:, 1]
    best = int(np.argmax(ll))
    # The interval to the grid's resolution, rounded outward: its ends are the first gains
    # searched outside it (the profile between two grid points is not known).
    keep = np.flatnonzero(ll >= ll[best] - _LR_95)
    inside = grid[max(0, keep.min() - 1):min(grid.size, keep.max() + 2)]
    nominal = int(np.flatnonzero(grid == 1.0)[0])
    accuracy = float(np.mean((margins[best] <= 0.0) == (y > 0.5)))
    nominal_accuracy = float(np.mean((margins[nominal] <= 0.0) == (y > 0.5)))
    if best in (0, grid.size - 1):
        raise FitRefused("process", f"the verdicts favour a gain at the edge of the range "
                         f"searched (x{grid[best]:g} of the job's, range x{GAIN_RANGE[0]:g} .. "
                         f"x{GAIN_RANGE[1]:g}): the eigen criterion cannot place these verdicts "
                         "with any gain; use the probabilistic boundary (--fit boundary)")
    if accuracy <= nominal_accuracy and ll[best] - ll[nominal] < _LR_95:
        raise FitRefused("process", f"no gain separates the verdicts better than the job's "
                         f"(accuracy {accuracy:.0%} against {nominal_accuracy:.0%}, likelihood "
                         "ratio not significant): keep the job's process gain")
    return ProcessGainFit(gain=float(grid[best]), gain_ci=(float(inside.min()), float(inside.max())),
                          width_n_per_m=float(widths[best]), n=len(labelled), n_chatter=n_chatter,
                          accuracy=accuracy, nominal_accuracy=nominal_accuracy, grid=grid,
                          profile=ll)
