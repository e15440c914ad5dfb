"""A probabilistic stability boundary: P(chatter) over the criterion's margin, a_p and rpm.

Each record with a verdict of ``stable`` or ``chatter`` is one labelled point; its features are the
margin the job's criterion gives at the record's pose, cut and feed (under the model the planner
will use: the calibrated one when the other fits succeeded), its axial depth and its spindle speed.
A logistic regression (scikit-learn, L2-regularised on standardised features) gives
logit P(chatter) = b₀ + b·x̃; its uncertainty is the Laplace approximation of the posterior
(the inverse Hessian of the penalised log-likelihood), so that a prediction carries a variance of
its logit — the quantity the test-cut proposal maximises (value of information, after Karandikar
et al. 2014).

The planner uses the boundary through :func:`required_margin`: for a section's a_p and rpm, the
smallest margin at which P(chatter) ≤ ``[model] chatter_probability_max``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from models.errors import CctmillError
from planner._progress import bar
from planner.calibrate.context import CalibrationContext
from planner.calibrate.fit_coefficients import FitRefused
from planner.calibrate.fit_stiffness import record_cut
from planner.calibrate.records import CutRecord

__all__ = [
    "FEATURES",
    "MIN_LABELLED",
    "MIN_PER_CLASS",
    "PROGRESS_MIN_RECORDS",
    "Boundary",
    "allowed_depth_and_speed",
    "boundary_from_job",
    "criterion_margin",
    "fit_boundary",
    "job_margin_floor",
    "labelled_verdicts",
    "margin_floors",
    "required_margin",
]

#: The features, in order, in the units the overlay stores them.
FEATURES = ("margin", "ap_mm", "rpm")
#: Fewest records with a verdict of stable or chatter [-].
MIN_LABELLED = 8
#: Fewest records of each verdict [-]: a boundary needs cuts on both sides of it.
MIN_PER_CLASS = 2
#: Inverse L2 regularisation strength on the standardised features [-] (scikit-learn's C): the
#: prior keeps a separable handful of cuts from a boundary of infinite slope.
REGULARISATION_C = 1.0
#: Fewest labelled records for a progress bar [-]: a margin takes 1-3 ms, a leave-one-out refit
#: some 3 ms at a thousand records, so fewer than this finish in well under a second.
PROGRESS_MIN_RECORDS = 200


def criterion_margin(ctx: CalibrationContext, record: CutRecord, params=None) -> float:
    """The margin of the job's criterion at a record (> 0 stable): eigen [N/m], floquet 1 − ρ [-],
    gamma_window [rad]."""
    model = ctx.point_model(params)
    a = model.analyze(record.q(), record_cut(ctx, record), record.feed())
    if ctx.criterion == "floquet":
        return float(a.floquet_margin)
    if ctx.criterion == "gamma_window":
        return float(a.gamma_margin)
    return float(a.margin)


@dataclass(frozen=True)
class Boundary:
    """logit P(chatter) = intercept + coef · (x − mean) / scale, x = (margin, ap_mm, rpm).

    Attributes:
        criterion: the criterion whose margin is the first feature.
        mean, scale, coef: (3,) each; intercept: [-].
        covariance: (4, 4) Laplace covariance of (intercept, coef).
        n, n_chatter: labelled records, of them chatter.
        loo_accuracy: leave-one-out accuracy [-]; log_loss, brier: on the data [-].
        margin_orders: the fitted P(chatter) falls as the margin grows (the criterion and the
            cuts agree on the direction).
    """

    criterion: str
    mean: np.ndarray
    scale: np.ndarray
    coef: np.ndarray
    intercept: float
    covariance: np.ndarray
    n: int
    n_chatter: int
    loo_accuracy: float
    log_loss: float
    brier: float
    margin_orders: bool

    def _design(self, x: np.ndarray) -> np.ndarray:
        z = (np.atleast_2d(np.asarray(x, float)) - self.mean) / self.scale
        return np.column_stack([np.ones(len(z)), z])

    def logit(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(mean, variance) of logit P(chatter) at features x, shape (k, 3) → (k,), (k,)."""
        d = self._design(x)
        beta = np.concatenate([[self.intercept], self.coef])
        return d @ beta, np.einsum("ij,jk,ik->i", d, self.covariance, d)

    def probability(self, x: np.ndarray) -> np.ndarray:
        """P(chatter) [-] at features x (k, 3), averaged over the coefficients' uncertainty
        (the probit approximation σ(μ / √(1 + π v / 8)))."""
        mu, var = self.logit(x)
        return 1.0 / (1.0 + np.exp(-mu / np.sqrt(1.0 + math.pi * var / 8.0)))

    def as_overlay(self) -> dict:
        """The keys ``[calibration]`` stores."""
        return {"boundary_criterion": self.criterion,
                "boundary_features": list(FEATURES),
                "boundary_mean": [float(f"{v:.8g}") for v in self.mean],
                "boundary_scale": [float(f"{v:.8g}") for v in self.scale],
                "boundary_coef": [float(f"{v:.8g}") for v in self.coef],
                "boundary_intercept": float(f"{self.intercept:.8g}")}

    def as_json(self) -> dict:
        return {**self.as_overlay(), "covariance": self.covariance.tolist(), "n": self.n,
                "n_chatter": self.n_chatter, "loo_accuracy": self.loo_accuracy,
                "log_loss": self.log_loss, "brier": self.brier,
                "margin_orders": self.margin_orders}


def _fit(z: np.ndarray, y: np.ndarray):
    from sklearn.linear_model import LogisticRegression

    return LogisticRegression(C=REGULARISATION_C).fit(z, y)


def labelled_verdicts(records: Sequence[CutRecord], fit: str, why: str
                      ) -> tuple[list[CutRecord], np.ndarray]:
    """The records with a verdict of stable or chatter and their labels (1: chatter).

    Raises:
        FitRefused: (for ``fit``, with ``why``) fewer than :data:`MIN_LABELLED` of them, or fewer
            than :data:`MIN_PER_CLASS` of either verdict.
    """
    labelled = [r for r in records if r.verdict in ("stable", "chatter")]
    y = np.array([r.verdict == "chatter" for r in labelled], int)
    n_chatter = int(y.sum())
    if len(labelled) < MIN_LABELLED or min(n_chatter, len(y) - n_chatter) < MIN_PER_CLASS:
        raise FitRefused(fit, f"{len(labelled)} records with a verdict ({n_chatter} chatter); "
                         f"need {MIN_LABELLED}, at least {MIN_PER_CLASS} of each: {why} "
                         "(cctmill testcuts proposes them)")
    return labelled, y


def fit_boundary(ctx: CalibrationContext, records: Sequence[CutRecord], params=None,
                 progress: bool = False) -> Boundary:
    """Fit P(chatter | margin, a_p, rpm) to the records' verdicts.

    Args:
        ctx: the cell (its criterion gives the margin).
        records: records with a verdict of stable or chatter are used.
        params: model parameters for the margins (default: the job's).
        progress: progress bars on stderr (the margins, the leave-one-out refits), on a
            terminal only and from :data:`PROGRESS_MIN_RECORDS` records.

    Raises:
        FitRefused: fewer than :data:`MIN_LABELLED` labelled records, or fewer than
            :data:`MIN_PER_CLASS` of either verdict.
    """
    labelled, y = labelled_verdicts(records, "boundary", "a boundary needs cuts on both sides "
                                    "of it")
    n_chatter = int(y.sum())
    rows = []
    with bar(len(labelled), f"boundary: {ctx.criterion} margins", progress, unit="record",
             min_total=PROGRESS_MIN_RECORDS) as pbar:
        for r in labelled:
            try:
                rows.append([criterion_margin(ctx, r, params), r.ap_mm, r.rpm])
            except CctmillError as e:   # outside the joint limits, singular, a refused cut
                raise FitRefused("boundary", f"record {r.name}: {e}; fix or leave out the "
                                 "record") from e
            pbar.update()
    x = np.array(rows)
    mean = x.mean(axis=0)
    scale = x.std(axis=0)
    scale[scale == 0.0] = 1.0  # a feature that does not vary carries no weight
    z = (x - mean) / scale
    model = _fit(z, y)
    coef, intercept = model.coef_[0].astype(float), float(model.intercept_[0])
    d = np.column_stack([np.ones(len(z)), z])
    p = 1.0 / (1.0 + np.exp(-(d @ np.concatenate([[intercept], coef]))))
    hessian = d.T @ (d * (p * (1.0 - p))[:, None])
    hessian[1:, 1:] += np.eye(3) / REGULARISATION_C  # the intercept is not penalised
    covariance = np.linalg.inv(hessian + 1e-12 * np.eye(4))
    from threadpoolctl import threadpool_limits  # scikit-learn's own dependency

    hits = 0
    # one BLAS thread: the refits are a few thousand tiny products each, which threads only slow
    # (ten times and more on a busy machine, where the threads wait for each other)
    with bar(len(y), "boundary: leave-one-out", progress, unit="fit",
             min_total=PROGRESS_MIN_RECORDS) as pbar, threadpool_limits(limits=1, user_api="blas"):
        for i in range(len(y)):
            pbar.update()
            keep = np.arange(len(y)) != i
            if len(set(y[keep])) < 2:
                continue
            hits += int(_fit(z[keep], y[keep]).predict(z[i:i + 1])[0] == y[i])
    eps = 1e-12
    log_loss = float(-np.mean(y * np.log(p + eps) + (1 - y) * np.log(1 - p + eps)))
    return Boundary(criterion=ctx.criterion, mean=mean, scale=scale, coef=coef,
                    intercept=intercept, covariance=covariance, n=len(y), n_chatter=n_chatter,
                    loo_accuracy=hits / len(y), log_loss=log_loss,
                    brier=float(np.mean((p - y) ** 2)), margin_orders=bool(coef[0] < 0.0))


def required_margin(boundary: Boundary, p_max: float, ap_mm: float, rpm: float) -> float:
    """The smallest criterion margin at which the boundary's point estimate P(chatter) ≤ p_max for
    a cut of axial depth ``ap_mm`` [mm] at ``rpm`` [rev/min] (the margin's unit: the criterion's).
    ``inf`` when no margin assures it (the fitted P(chatter) does not fall with the margin: the
    criterion and the cuts disagree), ``-inf`` when every margin will do."""
    if not 0.0 < p_max < 1.0:
        raise ValueError(f"p_max must lie in (0, 1), got {p_max!r}")
    target = math.log(p_max / (1.0 - p_max))
    rest = boundary.intercept + sum(
        c * (v - m) / s for c, v, m, s in zip(boundary.coef[1:], (ap_mm, rpm),
                                              boundary.mean[1:], boundary.scale[1:], strict=True))
    b = boundary.coef[0] / boundary.scale[0]
    if b == 0.0:
        return -math.inf if rest <= target else math.inf
    if b > 0.0:
        return math.inf          # the cuts chatter more where the criterion sees more margin
    return float(boundary.mean[0] + (target - rest) / b)


def allowed_depth_and_speed(boundary: Boundary, p_max: float, margin: float, ap_mm: float,
                            rpm: float) -> tuple[float | None, float | None]:
    """For a cut of criterion margin ``margin`` at ``ap_mm`` [mm] and ``rpm``: the largest a_p
    [mm] at this speed, and the lowest speed [rev/min] at this a_p, at which the boundary's point
    estimate P(chatter) ≤ ``p_max`` (the logit is linear in both). None where the boundary does
    not fall that way (P(chatter) does not rise with a_p, or does not fall with the speed)."""
    target = math.log(p_max / (1.0 - p_max))
    mu = float(boundary.logit(np.array([[margin, ap_mm, rpm]], float))[0][0])
    b_ap = boundary.coef[1] / boundary.scale[1]
    b_rpm = boundary.coef[2] / boundary.scale[2]
    depth = float(ap_mm + (target - mu) / b_ap) if b_ap > 0 else None
    speed = float(rpm + (target - mu) / b_rpm) if b_rpm < 0 else None
    return depth, speed


def boundary_from_job(job) -> Boundary | None:
    """The boundary a job's ``[calibration]`` holds (from its overlay), or None."""
    cal = job.calibration
    if cal.boundary_coef is None:
        return None
    return Boundary(criterion=cal.boundary_criterion or job.model.chatter_criterion,
                    mean=np.asarray(cal.boundary_mean, float),
                    scale=np.asarray(cal.boundary_scale, float),
                    coef=np.asarray(cal.boundary_coef, float),
                    intercept=float(cal.boundary_intercept or 0.0),
                    covariance=np.zeros((4, 4)), n=0, n_chatter=0, loo_accuracy=float("nan"),
                    log_loss=float("nan"), brier=float("nan"),
                    margin_orders=bool(cal.boundary_coef[0] < 0.0))


def job_margin_floor(job, a_p: float, spindle_speed: float) -> float | None:
    """The margin a section of axial depth ``a_p`` [m] at ``spindle_speed`` [rad/s] needs so that
    P(chatter) ≤ ``[model] chatter_probability_max`` by the job's calibrated boundary, in the
    criterion's unit; None when the job requires no probability or has no boundary.

    Raises:
        InputError: the job asks for a probability but has no boundary, or its boundary was fitted
            for another criterion.
    """
    from models.errors import InputError

    p_max = job.model.chatter_probability_max
    if p_max is None:
        return None
    boundary = boundary_from_job(job)
    if boundary is None:
        raise InputError("[model] chatter_probability_max", "needs a calibrated boundary: run "
                         "cctmill calibrate --fit boundary and add [calibration] overlay")
    if boundary.criterion != job.model.chatter_criterion:
        raise InputError("[model] chatter_probability_max", f"the boundary was fitted on the "
                         f"{boundary.criterion} margin, the job uses {job.model.chatter_criterion}; "
                         "recalibrate with this criterion")
    return required_margin(boundary, p_max, a_p * 1e3, spindle_speed * 60.0 / (2.0 * math.pi))


def margin_floors(job, a_p: np.ndarray, spindle_speed: float) -> np.ndarray | None:
    """:func:`job_margin_floor` for many samples: per axial depth ``a_p`` [m], shape (m,), the
    margin P(chatter) ≤ ``chatter_probability_max`` needs (criterion's unit), shape (m,); None
    when the job requires no probability. What the planner's ceilings add to their margin floor."""
    if job.model.chatter_probability_max is None:
        return None
    depths = np.asarray(a_p, float).reshape(-1)
    return np.array([job_margin_floor(job, float(d), spindle_speed) for d in depths])
