"""Cutting coefficients from mean forces: the mechanistic identification (Altintas), as least squares.

For a given engagement (a_e, a_p, mode, tool) the tooth-period mean force of docs/model.md §4 is
linear in the six coefficients, F̄ = A(c, a_e, a_p) K, and affine in the feed per tooth c: each
component is a slope times c (the cutting coefficients) plus an intercept (the edge coefficients).
The classic identification — slot cuts at several feeds, a straight line of each mean force
component on c — is the special case of one engagement; here every record with a measured mean
force gives three rows of A, and K is the (weighted) least-squares solution with the covariance
s² (AᵀWA)⁻¹, s² = RSS/(n − 6) the residual variance. Confidence intervals use Student's t with
n − 6 degrees of freedom.

Only records judged ``stable`` (or ``unknown``) enter: a chattering cut's mean force is not the
static model's. A fit is refused, with the reason, when there are too few cuts or feeds, when the
cuts do not separate the coefficients (rank or conditioning), or when the records contradict the
model (residuals far above what a force measurement gives, or a non-physical result).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.optimize
import scipy.stats

from models import cutting
from models.errors import CctmillError
from models.tooling import Material, Tool
from planner.calibrate.records import CutRecord

__all__ = [
    "COEFFICIENT_NAMES",
    "CONDITION_MAX",
    "CONTRADICTION_RATIO",
    "CoefficientFit",
    "FitRefused",
    "MIN_CUTS",
    "MIN_DOF",
    "MIN_FEEDS",
    "design_rows",
    "fit_coefficients",
]

COEFFICIENT_NAMES = ("k_tc", "k_rc", "k_ac", "k_te", "k_re", "k_ae")
#: Fewest records with a usable mean force [-]: three cuts give nine equations for six unknowns.
MIN_CUTS = 3
#: Fewest distinct feeds per tooth [-]: a straight line needs two points (slope and intercept).
MIN_FEEDS = 2
#: Fewest residual degrees of freedom [-] for a variance estimate worth a confidence interval.
MIN_DOF = 3
#: Largest condition number of the column-scaled design matrix [-]: above it the cuts do not
#: separate the coefficients (a 1 % force error would move some coefficient by more than 1e4 %).
CONDITION_MAX = 1e4
#: Largest residual RMS as a fraction of the RMS mean force [-]: a force measurement is good to a
#: few per cent; residuals of a quarter of the force mean the records contradict the model (a wrong
#: frame, a unit slip, a mislabelled chatter) and no fit is made.
CONTRADICTION_RATIO = 0.25
#: A record the other records' fit misses by more than this many standard deviations [-]
#: (RMS over its three components) contradicts them: 3·5² = 75 is far beyond χ²₃'s 1e-6 tail (≈ 31).
OUTLIER_SIGMA = 5.0
#: ... and by more than this much [N] plus this share of its force [-]: far below a dynamometer's
#: accuracy (≈ 1 %), so only a misfit a sensor could see is called a contradiction.
MISFIT_FLOOR_N, MISFIT_FLOOR_REL = 0.1, 0.002
#: Fewest cuts for estimating how the measurement error grows with the force [-] (below: one σ).
MIN_CUTS_VARIANCE = 6
#: Reweighting passes of the feasible weighted least squares [-].
VARIANCE_ITERATIONS = 2
#: Confidence level of the intervals [-].
CONFIDENCE = 0.95
#: Relative feed-per-tooth difference [-] below which two feeds count as one.
_FEED_SAME = 1e-3


class FitRefused(CctmillError):
    """A fit was not made because the data cannot support it.

    Attributes:
        what: the fit (``"coefficients"``, ``"stiffness"``, ``"boundary"``).
        reason: why, and what data would allow it.
    """

    def __init__(self, what: str, reason: str) -> None:
        super().__init__(f"{what} fit refused: {reason}")
        self.what, self.reason = what, reason


def _engagement(record: CutRecord, tool: Tool) -> tuple[float, float, float, int, float]:
    """(c [m], a_e [m], a_p [m], mode code, radius [m]) of a record with the tool."""
    radius = tool.radius if record.diameter_mm is None else record.diameter_mm * 5e-4
    flutes = tool.flutes if record.flutes is None else record.flutes
    a_e = 2.0 * radius if record.milling == "slot" else record.ae_mm * 1e-3
    c = cutting.feed_per_tooth(record.feed(), flutes, record.rpm)
    return c, a_e, record.ap_mm * 1e-3, cutting.MILLING_MODES[record.milling], radius


def design_rows(record: CutRecord, tool: Tool) -> np.ndarray:
    """The rows of A for one record: F̄_cut = A K [N], shape (3, 6) (columns in
    :data:`COEFFICIENT_NAMES` order, N/(N/m²) then N/(N/m))."""
    c, a_e, a_p, mode, radius = _engagement(record, tool)
    flutes = tool.flutes if record.flutes is None else record.flutes
    return np.asarray(cutting.coefficient_design_function()(c, a_e, a_p, mode, flutes, radius), float)


@dataclass(frozen=True)
class CoefficientFit:
    """The identified cutting coefficients with their uncertainty and the fit's quality. SI.

    Attributes:
        values: K [N/m² ×3, N/m ×3], (6,), in :data:`COEFFICIENT_NAMES` order.
        std: their standard errors, (6,).
        ci_low, ci_high: the :data:`CONFIDENCE` intervals, (6,).
        covariance: (6, 6).
        nominal: the job's coefficients, (6,).
        sigma_n: residual standard deviation of a mean force component [N] (weighted: of the
            standardised residual times the weights' scale).
        residual_rms_n, force_rms_n: RMS of residuals and of the measured components [N].
        dof: residual degrees of freedom; n_cuts, n_feeds: usable records, distinct feeds.
        condition: condition number of the column-scaled design matrix.
        worst: (record name, its largest |residual| [N]).
        used: names of the records used; excluded: (name, reason) of those left out.
        feed_per_tooth_range: (lowest, highest) c of the data [m] — the fit's range.
    """

    values: np.ndarray
    std: np.ndarray
    ci_low: np.ndarray
    ci_high: np.ndarray
    covariance: np.ndarray
    nominal: np.ndarray
    sigma_n: float
    residual_rms_n: float
    force_rms_n: float
    dof: int
    n_cuts: int
    n_feeds: int
    condition: float
    worst: tuple[str, float]
    used: tuple[str, ...]
    excluded: tuple[tuple[str, str], ...]
    feed_per_tooth_range: tuple[float, float]

    def material(self, name: str, identified_with: str | None = None) -> Material:
        """The fitted coefficients as a :class:`Material`."""
        return Material(name, *(float(v) for v in self.values), identified_with=identified_with)

    def relative_half_width(self) -> np.ndarray:
        """CI half width over the value [-], (6,)."""
        return (self.ci_high - self.ci_low) / 2.0 / np.abs(self.values)

    def as_json(self) -> dict:
        """The fit for a report or an overlay (SI)."""
        return {
            "values": dict(zip(COEFFICIENT_NAMES, self.values.tolist(), strict=True)),
            "std": dict(zip(COEFFICIENT_NAMES, self.std.tolist(), strict=True)),
            "ci95_low": dict(zip(COEFFICIENT_NAMES, self.ci_low.tolist(), strict=True)),
            "ci95_high": dict(zip(COEFFICIENT_NAMES, self.ci_high.tolist(), strict=True)),
            "ratio_to_nominal": dict(zip(COEFFICIENT_NAMES,
                                         (self.values / self.nominal).tolist(), strict=True)),
            "sigma_n": self.sigma_n, "residual_rms_n": self.residual_rms_n,
            "force_rms_n": self.force_rms_n, "dof": self.dof, "n_cuts": self.n_cuts,
            "n_feeds": self.n_feeds, "condition": self.condition,
            "worst_record": self.worst[0], "worst_residual_n": self.worst[1],
            "used": list(self.used), "excluded": [list(e) for e in self.excluded],
            "feed_per_tooth_range_m": list(self.feed_per_tooth_range),
        }


def _usable(records: Sequence[CutRecord], tool: Tool, material: Material
            ) -> tuple[list[CutRecord], list[tuple[str, str]]]:
    used, excluded = [], []
    for r in records:
        if r.force_n is None:
            continue
        if r.verdict == "chatter":
            excluded.append((r.name, "chatter: the mean force of a vibrating cut is not the "
                                     "static model's"))
            continue
        if r.tool != tool.name:
            raise FitRefused("coefficients", f"record {r.name} was cut with tool {r.tool!r}, the "
                             f"job's is {tool.name!r}: coefficients belong to one tool and "
                             "material; calibrate each tool's records on their own")
        if r.material is not None and r.material != material.name:
            raise FitRefused("coefficients", f"record {r.name} cut {r.material!r}, the job cuts "
                             f"{material.name!r}; calibrate each material on its own")
        radius = tool.radius if r.diameter_mm is None else r.diameter_mm * 5e-4
        if r.ae_mm is not None and r.milling != "slot" and r.ae_mm * 1e-3 > 2.0 * radius * (1 + 1e-9):
            raise FitRefused("coefficients", f"record {r.name}: ae_mm {r.ae_mm:g} is beyond the "
                             f"tool's diameter {2e3 * radius:g} mm; fix the record")
        used.append(r)
    return used, excluded


def _weighted_solve(a: np.ndarray, f: np.ndarray, w: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, float]:
    """(K, residuals [N], covariance, s², condition) of the weighted least squares A K ≈ F."""
    aw = a * w[:, None]
    col = np.linalg.norm(aw, axis=0)
    if np.any(col == 0.0):
        missing = [COEFFICIENT_NAMES[i] for i in np.flatnonzero(col == 0.0)]
        raise FitRefused("coefficients", f"the cuts carry no information on {missing}")
    scaled = aw / col  # columns near 1: K_tc (1e9) and K_ae (1e3) side by side
    sv = np.linalg.svd(scaled, compute_uv=False)
    condition = float(sv[0] / sv[-1]) if sv[-1] > 0 else float("inf")
    if not condition <= CONDITION_MAX:
        raise FitRefused("coefficients", f"the cuts do not separate the six coefficients (scaled "
                         f"condition number {condition:.3g} > {CONDITION_MAX:g}); vary the feed "
                         "per tooth widely and add a second radial or axial depth")
    z, *_ = np.linalg.lstsq(scaled, f * w, rcond=None)
    k = z / col
    resid = f - a @ k
    s2 = float(np.sum((resid * w) ** 2)) / (a.shape[0] - 6)
    cov = s2 * np.linalg.inv(scaled.T @ scaled) / np.outer(col, col)
    return k, resid, cov, s2, condition


def _most_contradicting(a: np.ndarray, f: np.ndarray, w: np.ndarray) -> tuple[int, float]:
    """(record index, distance): the record whose mean force the fit of the *other* records
    predicts worst, in standard deviations of that prediction (√ of the Mahalanobis distance over
    its three components, measurement and fit uncertainty both counted). Leaving the record out
    keeps one bad record from hiding in the residual variance it inflates."""
    n = a.shape[0] // 3
    worst, where = 0.0, 0
    for i in range(n):
        keep = np.ones(a.shape[0], bool)
        keep[3 * i:3 * i + 3] = False
        if keep.sum() - 6 < 1:
            return 0, 0.0
        try:
            k, _, cov, s2, _ = _weighted_solve(a[keep], f[keep], w[keep])
        except FitRefused:
            continue  # without this record the rest cannot be fitted: it is not contradicted
        rows = slice(3 * i, 3 * i + 3)
        e = f[rows] - a[rows] @ k
        spread = np.diag(s2 / w[rows] ** 2) + a[rows] @ cov @ a[rows].T
        d = float(np.sqrt(e @ np.linalg.solve(spread, e) / 3.0))
        if d > worst:
            worst, where = d, i
    return where, worst


def fit_coefficients(records: Sequence[CutRecord], tool: Tool, material: Material
                     ) -> CoefficientFit:
    """Fit the six cutting coefficients to the records' mean forces.

    Args:
        records: cut records; those with ``force_n`` and a verdict other than ``chatter`` are
            used. A record's ``force_std_n`` weighs its rows (1/σ); without one a record has
            weight 1 and the common σ is estimated from the residuals.
        tool: the tool the records were cut with (radius, flutes).
        material: the nominal material (only its coefficients, for the report's ratios).

    Raises:
        FitRefused: too few cuts or feeds, coefficients not separable (rank, conditioning),
            residuals contradicting the model, or a non-physical result.
    """
    used, excluded = _usable(records, tool, material)
    if len(used) < MIN_CUTS:
        raise FitRefused("coefficients", f"{len(used)} record(s) with a mean force from a cut "
                         f"not judged chatter; need at least {MIN_CUTS} (better 8-12), at two or "
                         "more feeds per tooth")
    feeds = np.array([_engagement(r, tool)[0] for r in used])
    distinct = np.unique(np.round(np.log(feeds) / _FEED_SAME))
    if len(distinct) < MIN_FEEDS:
        raise FitRefused("coefficients", f"all {len(used)} cuts run at one feed per tooth "
                         f"({feeds[0] * 1e3:.4g} mm): slope (cutting) and intercept (edge) "
                         "coefficients cannot be told apart; add cuts at other feeds")
    a = np.vstack([design_rows(r, tool) for r in used])
    f = np.concatenate([r.force_cut() for r in used])
    w = np.repeat([1.0 / r.force_std_n if r.force_std_n else 1.0 for r in used], 3)
    dof = a.shape[0] - 6
    if dof < MIN_DOF:
        raise FitRefused("coefficients", f"{a.shape[0]} force components for 6 coefficients "
                         f"leave {dof} degrees of freedom; need {MIN_DOF}: add a cut")
    k, resid, cov, s2, condition = _weighted_solve(a, f, w)
    if all(r.force_std_n is None for r in used) and len(used) >= MIN_CUTS_VARIANCE:
        # Feasible weighted least squares: a force measurement errs by a floor plus a fraction
        # of the force (calibration, cross-talk), σ_r = α + β |F_r|. Fit α, β ≥ 0 to the absolute
        # residuals (E|e| = σ √(2/π)) and reweigh; twice is enough for 12 cuts.
        size = np.repeat([np.linalg.norm(r.force_n) for r in used], 3)
        for _ in range(VARIANCE_ITERATIONS):
            design = np.column_stack([np.ones_like(size), size])
            ab, _ = scipy.optimize.nnls(design, np.abs(resid) * np.sqrt(np.pi / 2.0))
            sigma = design @ ab
            if not np.all(sigma > 0):
                break
            w = 1.0 / sigma
            k, resid, cov, s2, condition = _weighted_solve(a, f, w)
    std = np.sqrt(np.diag(cov))
    t = float(scipy.stats.t.ppf(0.5 + CONFIDENCE / 2.0, dof))
    force_rms = float(np.sqrt(np.mean(f**2)))
    resid_rms = float(np.sqrt(np.mean(resid**2)))
    per_record = np.abs(resid).reshape(-1, 3).max(axis=1)
    worst = int(np.argmax(per_record))
    if resid_rms > CONTRADICTION_RATIO * force_rms:
        raise FitRefused("coefficients", f"the records contradict the mean force model: residual "
                         f"RMS {resid_rms:.3g} N against forces of {force_rms:.3g} N RMS (worst: "
                         f"record {used[worst].name}, {per_record[worst]:.3g} N); check its "
                         "frame, units and verdict")
    odd, distance = _most_contradicting(a, f, w)
    # Near-perfect records (a simulation) make σ a few mN: a misfit below any force sensor's
    # resolution contradicts nothing, however many of those σ it is.
    floor = MISFIT_FLOOR_N + MISFIT_FLOOR_REL * float(np.linalg.norm(used[odd].force_n))
    if distance > OUTLIER_SIGMA and per_record[odd] > floor:
        raise FitRefused("coefficients", f"record {used[odd].name} contradicts the others: its "
                         f"mean force misses the fit of the other cuts by {distance:.1f} standard "
                         f"deviations ({per_record[odd]:.3g} N); check its frame, units and "
                         "verdict, or leave it out")
    if not k[0] > 0 or not k[1] > 0:
        raise FitRefused("coefficients", f"the fit gives k_tc = {k[0]:.3g}, k_rc = {k[1]:.3g} "
                         "N/m²: the tangential and radial cutting coefficients are positive in "
                         "any metal; check the sign convention of force_n (force on the tool)")
    return CoefficientFit(
        values=k, std=std, ci_low=k - t * std, ci_high=k + t * std, covariance=cov,
        nominal=material.coefficients(),
        sigma_n=float(np.sqrt(s2) * np.sqrt(np.mean(1.0 / w**2))), residual_rms_n=resid_rms,
        force_rms_n=force_rms, dof=dof, n_cuts=len(used), n_feeds=len(distinct),
        condition=condition, worst=(used[worst].name, float(per_record[worst])),
        used=tuple(r.name for r in used), excluded=tuple(excluded),
        feed_per_tooth_range=(float(feeds.min()), float(feeds.max())))
