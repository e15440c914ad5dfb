"""The point model along the path: every quantity of every engaged sample, as a function of feed.

:class:`PathModel` binds the prepared job (joints, cutting frame and engagement per sample) to the
mapped CasADi point Function of the physics core (:func:`models.analysis.point_function`) and
evaluates it for any per-sample feeds in one call: force, static deflection (and its component
normal to the machined wall), γ, the chatter margin, the spindle power.

:meth:`PathModel.ceilings` turns the constraints of docs/model.md §8 into one number per sample: the
**feed ceiling**, the largest feed at which the sample meets every limit — chatter margin ≥ the
required margin, resultant force ≤ the force limit, ‖δ‖ ≤ the deflection tolerance, spindle power ≤
its limit — *and every feed below it does too* (the feed limit of the stability characteristic,
docs/model.md §5 step 7). It is found on a log-spaced feed grid and refined by regula falsi (Illinois) on
the largest normalised constraint slack in log-feed, every evaluation with the full CCT model.
Force, deflection and power grow with feed; the margin of the ``thesis`` process model falls with
it (mostly) and that of the ``oriented`` model hardly changes, so the constraints
are monotone in feed and a ceiling represents them exactly; the grid catches a constraint that
fails and recovers between two grid feeds only if it fails at a grid feed. The independent checker
(:mod:`planner.check`) re-evaluates every planned sample, so the plan never relies on this
assumption unseen.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from models.analysis import Cut, ModelParameters, point_function
from models.cutting import MILLING_MODES
from models.errors import InputError
from planner._progress import bar
from planner.job import Job
from planner.limit_confidence import limit_confidence
from planner.limits import Limits
from planner.prepare import Prepared

__all__ = [
    "CEILING_RTOL",
    "CONSTRAINTS",
    "FEED_GRID",
    "HALVING_AFTER",
    "MAX_REFINE_STEPS",
    "Ceilings",
    "Evaluation",
    "Limits",
    "PathModel",
    "engaged_samples",
    "job_parameters",
    "model_parameters",
]

#: The process constraints checked at every engaged sample, in reporting order.
CONSTRAINTS = ("chatter", "force", "deflection", "power")
#: Feeds of the coarse grid, log-spaced over [feed_min, feed_max] [-] (3× apart for the default
#: 0.5…40 mm/s range); the refinement below works inside the first failing interval.
FEED_GRID = 5
#: Relative width of the final bracket [-]: the ceiling is its feasible end, at most 0.1 % below
#: the true edge.
CEILING_RTOL = 1e-3
#: Refinement steps at most (slacks are smooth in log-feed: 3–5 regula-falsi steps close a
#: bracket; this bound only guards a pathological sample).
MAX_REFINE_STEPS = 40
#: Regula-falsi steps before every other step halves the bracket instead: a steep slack makes
#: regula falsi crawl along the feasible end, halving closes the grid's 3× bracket to
#: CEILING_RTOL in 2 × 11 more steps, inside MAX_REFINE_STEPS.
HALVING_AFTER = 6
#: Scale of the chatter margin's slack [N/m] (only its sign matters for the ceiling; the scale
#: makes the interpolation well conditioned next to the force/deflection/power ratios).
MARGIN_SCALE = 1e5
#: Outputs of the point Function the planner needs (a smaller graph is faster).
_OUTPUTS = ("force_o", "force_base", "deflection", "margin", "stable", "gamma", "gamma_margin",
            "power", "omega2")


def engaged_samples(s: np.ndarray, engaged: np.ndarray) -> np.ndarray:
    """``engaged`` (n,) bool without the samples that add no path: a sample whose step is of zero
    length (a zero-length move, a repeated point) removes no material of its own, so it is
    engaged only when the sample before it is (it then belongs to that cut); an engaged
    zero-length sample after an unengaged one would otherwise make a cut section of 0 m."""
    out = np.asarray(engaged, bool).copy()
    if out.size == 0:
        return out
    ds = np.diff(s, prepend=s[0])
    out[0] = out[0] and out.size > 1 and bool(out[1])
    for i in np.flatnonzero(ds <= 0.0):
        if i > 0 and out[i] and not out[i - 1]:
            out[i] = False
    return out


def _previous_engaged(index: np.ndarray) -> np.ndarray:
    """Per engaged sample (path indices ``index``, sorted), the position of the path sample just
    before it among the engaged ones, or −1 when that sample does not cut."""
    out = np.full(index.size, -1)
    if index.size > 1:
        follows = np.flatnonzero(np.diff(index) == 1) + 1
        out[follows] = follows - 1
    return out


def model_parameters(job: Job, prep: Prepared) -> ModelParameters:
    """The point-model parameters a job asks for (robot data, material, calibration knobs)."""
    return job_parameters(job, prep.robot)


def job_parameters(job: Job, robot) -> ModelParameters:
    """:func:`model_parameters` from the job and its loaded robot (no prepared path needed): the
    robot data's joint stiffness × ``[cell] joint_stiffness_scale``, the job's cutting
    coefficients (a calibration overlay's where it has one), ``[model] cct`` and
    ``process_gain``, ``$TOOL``'s origin and the spindle (the robot data's where the job gives
    none)."""
    spindle = job.spindle
    si = job.to_si()
    return ModelParameters(
        joint_stiffness=robot.data.joint_stiffness * job.cell.joint_stiffness_scale,
        coefficients=job.material_coefficients(), cct=job.model.cct,
        process_gain=job.model.process_gain, tcp=si.tcp, gamma_window=si.gamma_window,
        spindle_mass=robot.data.spindle_mass if spindle.mass_kg is None else spindle.mass_kg,
        spindle_com=robot.data.spindle_com if si.spindle_com is None else si.spindle_com)


@dataclass(frozen=True)
class Evaluation:
    """The point model at one feed per engaged sample. SI; ``m`` engaged samples.

    Attributes:
        feed: [m/s], (m,).
        force: resultant average force [N], (m,).
        force_base: average force in base axes [N], (m, 3).
        deflection: static TCP deflection δ = C_tt F̄ in base axes [m], (m, 3).
        deflection_norm: ‖δ‖ [m], (m,).
        deflection_normal: δ · X_o, the part normal to the machined wall [m], (m,) (signed:
            positive along +X_o).
        gamma: [rad], (m,).
        margin: eigen stability margin [N/m], (m,).
        gamma_margin: distance of γ inside the calibrated window [rad], (m,).
        stable: verdict of the job's criterion, (m,) bool.
        power: spindle power [W], (m,).
        natural_frequencies: 2-DOF natural frequencies [Hz], (m, 2); NaN for isotropic mass.
        ok: per constraint of :data:`CONSTRAINTS`, (m, 4) bool.
        slack: per constraint, a continuous measure that is ≤ 0 exactly where ``ok`` holds
            (value / limit − 1 for force, deflection and power; the margin's shortfall for
            chatter), (m, 4).
        deflection_change: |δ_i − δ_(i−1)| at the same feed, the change of δ along the LIN
            that ends at the sample [m], (m,) (zero where the sample before does not cut; filled
            only when the limits compensate the deflection, else empty).
        deflection_held: what the deflection tolerance held [m], (m,):
            :meth:`planner.limits.Limits.deflection_held` — ‖δ‖ uncompensated, u·‖δ‖ + the
            change compensated (empty from evaluations made without it).
        confidence_factors: (1 + z u_F, 1 + z u_δ) per sample, what the force and the held
            deflection were multiplied by before the limits (:mod:`planner.limit_confidence`),
            (m, 2); empty when the job states no calibration uncertainty.
    """

    feed: np.ndarray
    force: np.ndarray
    force_base: np.ndarray
    deflection: np.ndarray
    deflection_norm: np.ndarray
    deflection_normal: np.ndarray
    gamma: np.ndarray
    margin: np.ndarray
    gamma_margin: np.ndarray
    stable: np.ndarray
    power: np.ndarray
    natural_frequencies: np.ndarray
    ok: np.ndarray
    slack: np.ndarray
    deflection_change: np.ndarray = field(default_factory=lambda: np.zeros(0))
    deflection_held: np.ndarray = field(default_factory=lambda: np.zeros(0))
    confidence_factors: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))

    @property
    def all_ok(self) -> np.ndarray:
        """(m,) bool: every constraint holds."""
        return np.all(self.ok, axis=1)


@dataclass(frozen=True)
class Ceilings:
    """Per engaged sample, the feed ceiling and what sets it.

    Attributes:
        feed: the ceiling [m/s], (m,); ``feed_max`` where nothing binds inside the range, and
            ``feed_min`` (with ``floor_violation`` set) where even the lowest feed fails.
        binding: what stops the feed from rising, (m,) str: a constraint name or ``"feed_max"``.
        floor_violation: (m,) str, ``""`` or the constraint that fails at ``feed_min``.
        evaluations: number of mapped evaluations spent.
    """

    feed: np.ndarray
    binding: np.ndarray
    floor_violation: np.ndarray
    evaluations: int


class PathModel:
    """The physics core mapped over the engaged samples of a prepared job.

    Args:
        prep: the prepared job (joints, engagement).
        params: model parameters (default: :func:`model_parameters` of the job).
        limits: the limits (default: from the job).
        threads: worker threads of the mapped Function.
    """

    def __init__(self, prep: Prepared, params: ModelParameters | None = None,
                 limits: Limits | None = None, threads: int = 2, progress: bool = False) -> None:
        job = prep.job
        self.prep = prep
        self.params = params or model_parameters(job, prep)
        self.limits = limits or Limits.from_job(job)
        self.criterion = job.model.chatter_criterion
        if self.criterion not in ("eigen", "floquet", "gamma_window"):
            raise InputError("model.chatter_criterion",
                             f"{self.criterion!r} is not eigen, floquet or gamma_window")
        self._floquet_rho: np.ndarray | None = None
        self._bar = None
        self.process_model = job.model.process_model
        self.mass_model = job.model.mass_model
        self.threads = threads
        self.progress = progress
        e = prep.engagement
        cutting = engaged_samples(prep.path.s, prep.path.cutting & (e.mode >= 0)
                                  & prep.kinematics.reachable)
        #: indices of the engaged samples into the path, (m,).
        self.index = np.flatnonzero(cutting)
        feed_dir = e.feed_dir if e.feed_dir is not None else prep.path.feed_dir
        tool = prep.tool
        self.spindle_speed = job.to_si().spindle_speed
        self.tooth_frequency = tool.flutes * job.spindle.rpm / 60.0
        i = self.index
        m = i.size
        self.radial_dir = e.radial_dir[i]
        self.cut = np.vstack([feed_dir[i].T, e.radial_dir[i].T, e.a_e[i], e.a_p[i],
                              e.mode[i].astype(float), np.full(m, self.spindle_speed),
                              np.full(m, float(tool.flutes)), np.full(m, tool.radius)])
        #: per engaged sample, the margin ``[model] chatter_probability_max`` needs by the job's
        #: calibrated boundary (criterion's unit; None: no probability asked for), (m,).
        self.margin_floor: np.ndarray | None = None
        if job.model.chatter_probability_max is not None:   # scipy.stats only when asked for
            from planner.calibrate.fit_boundary import margin_floors

            self.margin_floor = margin_floors(job, e.a_p[i], self.spindle_speed)
        #: the calibration's uncertainty bound on force and deflection (None: plan on the
        #: model's values), :mod:`planner.limit_confidence`.
        self.confidence = limit_confidence(job, e.a_e[i], e.a_p[i], e.mode[i], tool.flutes,
                                           tool.radius, self.tooth_frequency)
        self.q = prep.kinematics.q[i].T
        #: per engaged sample, the engaged sample just before it on the path (−1: none), whose δ
        #: a compensated path cannot follow inside the LIN between them.
        self.previous = _previous_engaged(i)
        self.function = point_function(prep.robot, self.process_model, self.mass_model, _OUTPUTS)
        self._param_vec = self.params.vector()
        self._maps: dict[int, ca.Function] = {}
        self.evaluations = 0

    def __len__(self) -> int:
        return int(self.index.size)

    def _mapped(self, n: int) -> ca.Function:
        if n not in self._maps:
            self._maps[n] = self.function.map(n, "thread", self.threads) if n > 1 else self.function
        return self._maps[n]

    def evaluate(self, feeds: np.ndarray, subset: np.ndarray | None = None) -> Evaluation:
        """The model at ``feeds`` [m/s], one per engaged sample (or per ``subset`` entry).

        Args:
            feeds: (m,) or (k,) with ``subset``.
            subset: indices into the engaged samples (default all).
        """
        sel = np.arange(len(self)) if subset is None else np.asarray(subset, int)
        feeds = np.asarray(feeds, float).reshape(-1)
        if feeds.size != sel.size:
            raise InputError("feeds", f"need {sel.size} feeds, got {feeds.size}")
        if sel.size and not (np.all(np.isfinite(feeds)) and np.all(feeds > 0)):
            raise InputError("feeds", "every feed must be positive and finite")
        n = sel.size
        if n == 0:
            z = np.zeros(0)
            return Evaluation(z, z, np.zeros((0, 3)), np.zeros((0, 3)), z, z, z, z, z,
                              np.zeros(0, bool), z, np.zeros((0, 2)), np.zeros((0, 4), bool),
                              np.zeros((0, 4)))
        res = self._mapped(n)(q=self.q[:, sel], cut=self.cut[:, sel], feed=feeds.reshape(1, -1),
                              params=self._param_vec)
        self.evaluations += 1
        if self._bar is not None:
            self._bar.update(n)
        r = {k: np.asarray(v, float) for k, v in res.items()}
        force_o = r["force_o"].reshape(3, n)
        force = np.linalg.norm(force_o, axis=0)
        defl = r["deflection"].reshape(3, n).T
        margin = r["margin"].reshape(n)
        gamma_margin = r["gamma_margin"].reshape(n)
        if self.criterion == "floquet":
            rho = self.floquet_radius()[sel]
            need = 0.0 if self.margin_floor is None else np.maximum(self.margin_floor[sel], 0.0)
            stable = rho < 1.0 - need
            chatter_ok = stable
            chatter_slack = np.where(stable, rho - 1.0 + need, np.maximum(rho - 1.0 + need, 1e-12))
        elif self.criterion == "gamma_window":
            stable = gamma_margin > 0.0
            chatter_ok = stable
            chatter_slack = np.where(stable, -gamma_margin, np.maximum(-gamma_margin, 1e-12))
        else:
            stable = r["stable"].reshape(n) > 0.5
            floor = (self.limits.margin_min if self.margin_floor is None
                     else np.maximum(self.limits.margin_min, self.margin_floor[sel]))
            chatter_ok = stable & (margin >= floor)
            short = (floor - margin) / MARGIN_SCALE
            chatter_slack = np.where(chatter_ok, np.minimum(short, 0.0), np.maximum(short, 1e-12))
        power = r["power"].reshape(n)
        dnorm = np.linalg.norm(defl, axis=1)
        lim = self.limits
        change = (self._deflection_change(defl, feeds, sel) if lim.compensate_deflection
                  else np.zeros(0))
        held = lim.deflection_held(dnorm, change)
        force_bound, held_bound = force, held
        factors = np.zeros((0, 2))
        if self.confidence is not None:
            k_force, k_defl = self.confidence.factors(feeds, force_o.T, sel)
            force_bound, held_bound = force * k_force, held * k_defl
            factors = np.column_stack([k_force, k_defl])
        ok = np.column_stack([chatter_ok, force_bound <= lim.force_max,
                              held_bound <= lim.deflection_tol, power <= lim.power_max])
        slack = np.column_stack([chatter_slack, force_bound / lim.force_max - 1.0,
                                 held_bound / lim.deflection_tol - 1.0, power / lim.power_max - 1.0])
        if self.mass_model == "robot":
            freqs = np.sqrt(np.maximum(r["omega2"].reshape(2, n).T, 0.0)) / (2.0 * np.pi)
        else:
            freqs = np.full((n, 2), np.nan)
        return Evaluation(
            feed=feeds, force=force, force_base=r["force_base"].reshape(3, n).T, deflection=defl,
            deflection_norm=dnorm, deflection_normal=np.einsum("ij,ij->i", defl, self.radial_dir[sel]),
            gamma=r["gamma"].reshape(n), margin=margin, gamma_margin=gamma_margin, stable=stable,
            power=power, natural_frequencies=freqs, ok=ok, slack=slack,
            deflection_change=change, deflection_held=held, confidence_factors=factors)

    def _deflection_change(self, defl: np.ndarray, feeds: np.ndarray,
                           sel: np.ndarray) -> np.ndarray:
        """|δ_i − δ_(i−1)| [m], (k,): δ of the engaged sample before each of ``sel`` at the same
        feed (one more mapped evaluation of those samples); zero where there is none."""
        prev = self.previous[sel]
        has = np.flatnonzero(prev >= 0)
        out = np.zeros(sel.size)
        if has.size == 0:
            return out
        j = prev[has]
        res = self._mapped(has.size)(q=self.q[:, j], cut=self.cut[:, j],
                                     feed=feeds[has].reshape(1, -1), params=self._param_vec)
        d_prev = np.asarray(res["deflection"], float).reshape(3, has.size).T
        out[has] = np.linalg.norm(defl[has] - d_prev, axis=1)
        return out

    def ceilings(self, rtol: float = CEILING_RTOL) -> Ceilings:
        """The feed ceiling of every engaged sample (module docstring).

        Args:
            rtol: relative width of the final bracket (default :data:`CEILING_RTOL`; the posture
                search, :mod:`planner.posture`, compares poses with a coarser one).
        """
        lim = self.limits
        m = len(self)
        start = self.evaluations
        # about FEED_GRID + 5 evaluations of every sample (the grid, then the refinement)
        self._bar = bar((FEED_GRID + 5) * m, "feed ceilings", self.progress, unit="point")
        grid = np.geomspace(lim.feed_min, lim.feed_max, FEED_GRID)
        first_bad = np.full(m, FEED_GRID)
        floor = np.full(m, "", dtype=object)
        g_grid = np.full((m, FEED_GRID), np.nan)
        why_grid = np.zeros((m, FEED_GRID), int)
        for j, f in enumerate(grid):
            open_ = np.flatnonzero(first_bad == FEED_GRID)
            if open_.size == 0:
                break
            ev = self.evaluate(np.full(open_.size, f), open_)
            bad = ~ev.all_ok
            first_bad[open_[bad]] = j
            g_grid[open_, j] = np.max(ev.slack, axis=1)
            why_grid[open_, j] = np.argmax(ev.slack, axis=1)
            if j == 0:
                for k in np.flatnonzero(bad):
                    floor[open_[k]] = CONSTRAINTS[int(np.argmin(ev.ok[k]))]
        feed = np.where(first_bad == FEED_GRID, lim.feed_max, lim.feed_min)
        binding = np.where(first_bad == FEED_GRID, "feed_max", "").astype(object)
        for k in np.flatnonzero(first_bad == 0):
            binding[k] = floor[k]
        refine = np.flatnonzero((first_bad > 0) & (first_bad < FEED_GRID))
        if refine.size:
            j = first_bad[refine]
            feed[refine], why = self._refine(refine, grid[j - 1], grid[j],
                                             g_grid[refine, j - 1], g_grid[refine, j],
                                             why_grid[refine, j], rtol)
            for k, w in zip(refine, why, strict=True):
                binding[k] = CONSTRAINTS[int(w)]
        self._bar.close()
        self._bar = None
        return Ceilings(feed=feed, binding=binding.astype(str), floor_violation=floor.astype(str),
                        evaluations=self.evaluations - start)

    def floquet_radius(self) -> np.ndarray:
        """Spectral radius of the monodromy matrix per engaged sample, (m,) (``floquet``).

        Without regeneration the time-periodic system does not depend on the feed except through
        the CCT stiffness, which the mean force barely moves (docs/model.md §5: far below a degree of γ);
        it is evaluated once, at ``feed_min``, and the checker re-evaluates it at the planned
        feed of every sample.
        """
        if self._floquet_rho is None:
            from models.dynamics import pose_structure
            from models.floquet import floquet_margin

            cuts = [self.cut_at(k) for k in range(len(self))]
            structures = [pose_structure(self.prep.robot, self.params, self.q[:, k], cuts[k],
                                         self.limits.feed_min) for k in range(len(self))]
            self._floquet_rho, _ = floquet_margin(structures, cuts, self.params.coefficients,
                                                  self.prep.tool.helix_angle)
        return self._floquet_rho

    def cut_at(self, k: int) -> Cut:
        """The :class:`~models.analysis.Cut` of engaged sample ``k``."""
        v = self.cut[:, k]
        return Cut(feed_dir=v[0:3], radial_dir=v[3:6], a_e=float(v[6]), a_p=float(v[7]),
                   mode=self.mode_name(k), spindle_speed=float(v[9]), flutes=int(v[10]),
                   radius=float(v[11]))

    def _refine(self, idx: np.ndarray, f_lo: np.ndarray, f_hi: np.ndarray, g_lo: np.ndarray,
                g_hi: np.ndarray, why: np.ndarray,
                rtol: float = CEILING_RTOL) -> tuple[np.ndarray, np.ndarray]:
        """Close the brackets [f_lo (all ok), f_hi (a limit broken)] of samples ``idx``, given
        the largest slack at both ends and the constraint broken at ``f_hi``.

        Illinois regula falsi on g(x) = max slack, x = log f (g ≤ 0 ⇔ every limit holds); a side
        kept twice has its value halved, and no step lands within half the tolerance of an end,
        so the bracket closes from both sides; after :data:`HALVING_AFTER` steps every other step
        halves it (a steep slack would have regula falsi crawl). Returns the feasible ends
        and, per sample, the constraint broken at the infeasible end.
        """
        lo, hi = np.log(f_lo), np.log(f_hi)
        g_lo, g_hi, why = g_lo.copy(), g_hi.copy(), why.copy()
        side = np.zeros(idx.size, int)
        todo = np.flatnonzero(hi - lo > np.log1p(rtol))
        for it in range(MAX_REFINE_STEPS):
            if todo.size == 0:
                break
            a, b, ga, gb = lo[todo], hi[todo], g_lo[todo], g_hi[todo]
            t = ga / np.minimum(ga - gb, -1e-300)
            t = np.where(np.isfinite(t), np.clip(t, 0.0, 1.0), 0.5)
            if it >= HALVING_AFTER and it % 2 == 1:
                t = np.full_like(t, 0.5)
            # never closer than half the tolerance to an end, so the bracket keeps closing
            step = 0.5 * np.log1p(rtol)
            x = np.clip(a + t * (b - a), a + step, b - step)
            e = self.evaluate(np.exp(x), idx[todo])
            g = np.max(e.slack, axis=1)
            good = g <= 0.0
            j_good, j_bad = todo[good], todo[~good]
            lo[j_good], g_lo[j_good] = x[good], g[good]
            g_hi[j_good] *= np.where(side[j_good] == 1, 0.5, 1.0)
            side[j_good] = 1
            hi[j_bad], g_hi[j_bad] = x[~good], g[~good]
            why[j_bad] = np.argmax(e.slack[~good], axis=1)
            g_lo[j_bad] *= np.where(side[j_bad] == -1, 0.5, 1.0)
            side[j_bad] = -1
            todo = todo[hi[todo] - lo[todo] > np.log1p(rtol)]
        return np.exp(lo), why

    def mode_name(self, k: int) -> str:
        """Milling mode of engaged sample ``k``."""
        codes = {v: n for n, v in MILLING_MODES.items()}
        return codes[int(self.cut[8, k])]
