"""Time-domain milling on the flexible arm: the 2-DOF equilibrium-chip-thickness model (docs/model.md §6).

The structure is the arm at the pose in the plane normal to the tool axis (:mod:`models.structure`:
M ẍ + C ẋ + K x = F(t), x = (x_Xo, x_Zo) [m]); the cutter is cut into thin axial slices
(:mod:`models.cutter_geometry`). Each engaged edge slice carries the force of
:func:`models.cutting.edge_forces` (the same magnitudes as the point model), projected with
F = −F_t t(φ) − F_r n(φ) + F_a Y_o.

**Chip thickness.** h = c sin φ + n(φ)·x(t) − n(φ)·x_prev, clipped at 0 (the edge leaves the cut,
and then carries no force at all, edge force included). x_prev is the position at which the previous
edge at the same angle and height actually removed material: with regeneration on, the surface is
kept per slice and angle and updated only where an edge cut (an edge that left the cut leaves the
older surface, one more feed per tooth deeper: multiple regeneration); with regeneration off the
surface is smooth and stays where it was at the start — SPEC's x_prev = 0 measured from the
static equilibrium (``initial="static"``, the default) or from the nominal path (``"rest"``) — and
the model is the time-periodic one whose average is the ``oriented`` process stiffness of docs/model.md §5.
(Why not the nominal path with ``"static"``: on the KR 210 the static deflection under the mean
force is several feeds per tooth — about K_tc a_p/K ≈ 4 c for the thesis's cut — and against a
surface at the nominal path the tool would simply leave the cut; the previous pass was cut at the
deflected position too.)

**Integrator.** The linear structure is discretised exactly for a force that varies linearly over a
step (first-order hold, matrix exponential). Each step: the force with the rigid chip (tool at its
nominal position on the current surface), the structure's response at the end of the step, the chip
with that position, the force again, … until the force changes by less than
:data:`FORCE_TOLERANCE` (the thesis's equilibrium chip thickness); then advance. The step is a whole
fraction of the tooth period so that the surface memory is a plain ring buffer.

``iterate=False`` is the thesis's *first iteration*: the structure is driven by the rigid-chip force
(no chip feedback) and the force reported is the one after one chip update with that response.

Everything is SI; angles in rad, frequencies in Hz only where the name says ``_hz``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from models import cutting
from models.analysis import Cut
from models.cutter_geometry import DEFAULT_SLICES, CutterGeometry, cutter_geometry
from models.errors import InputError
from models.structure import (
    DEFAULT_DAMPING_RATIO,
    Structure,
    modal_damping,
    pose_structure,
    tcp_mass,
)

__all__ = [
    "DEFAULT_DAMPING_RATIO",
    "DEFAULT_SLICES",
    "FORCE_TOLERANCE",
    "MIN_STEPS_PER_TOOTH",
    "CutterGeometry",
    "SimulationResult",
    "Structure",
    "cutter_geometry",
    "discretise",
    "modal_damping",
    "pose_structure",
    "process_stiffness_series",
    "simulate",
    "tcp_mass",
]

#: Per-step equilibrium: stop when the force changes by less than this fraction [-] (docs/model.md §6: 1 %).
FORCE_TOLERANCE = 0.01
#: Absolute floor of the force scale in the convergence test [N]: below it (edge out of the cut)
#: a change of a micro-newton counts as converged.
FORCE_FLOOR = 1e-6
#: Per-step iteration cap; the fixed point contracts by ~(K_p dt²/m) ≪ 1 per iteration, so hitting
#: it means the step is far too long.
MAX_ITERATIONS = 50
#: Fewest integrator steps per tooth period [-] (angular resolution 360°/N/64 at most).
MIN_STEPS_PER_TOOTH = 64
#: Vibration amplitude [m], as a fraction of the feed per tooth, above which the edge leaves the
#: cut part of the time: growth rates are fitted only below it (the linear regime).
SATURATION_FRACTION = 0.25


# --------------------------------------------------------------------------------------------------
# Exact discretisation
# --------------------------------------------------------------------------------------------------


def discretise(structure: Structure, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """First-order-hold discretisation: z⁺ = Φ z + Γ₀ F₀ + Γ₁ F₁ for F linear over the step.

    z = (x, ẋ) [m, m/s], F = (F_Xo, F_Zo) [N] at the step's start (F₀) and end (F₁).
    Returns (Φ (4, 4), Γ₀ (4, 2), Γ₁ (4, 2)).
    """
    a = structure.state_matrix()
    b = np.vstack([np.zeros((2, 2)), np.linalg.inv(structure.mass)])
    aug = np.zeros((8, 8))
    aug[0:4, 0:4] = a * dt
    aug[0:4, 4:6] = b * dt
    aug[4:6, 6:8] = np.eye(2)
    e = scipy.linalg.expm(aug)
    phi, g_sum, g_ramp = e[0:4, 0:4], e[0:4, 4:6], e[0:4, 6:8]
    # ∫ e^{Aσ} B (u0 + (u1 − u0)(h − σ)/h) dσ: g_sum multiplies u0, g_ramp multiplies (u1 − u0).
    return phi, g_sum - g_ramp, g_ramp


# --------------------------------------------------------------------------------------------------
# Simulation
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class SimulationResult:
    """Output of :func:`simulate`, sampled at ``fs``. SI.

    Attributes:
        time: [s], shape (k,).
        force: force on the tool in (X_o, Y_o, Z_o) [N], shape (k, 3).
        displacement: tool displacement (x_Xo, x_Zo) [m], shape (k, 2).
        fs: output sample rate [Hz].
        tooth_period: [s].
        feed_per_tooth: c [m].
        f_peak: largest resultant force in the analysis window [N].
        f_pv: largest minus smallest per-tooth-period peak of the resultant in the window [N].
        tooth_peaks: per-tooth-period peaks of the resultant in the window [N].
        iterations_mean: mean chip/force iterations per step (1 with ``iterate=False``).
        unconverged_steps: steps that hit :data:`MAX_ITERATIONS`.
        dominant_frequency_hz: largest peak of the resultant force's spectrum (DC excluded) [Hz].
        vibration_frequency_hz: largest peak of the spectrum of x(t) − x(t − T), the part of the
            motion that is not periodic with the tooth period (chatter, transients) [Hz].
        growth_rate: exponential rate [1/s] fitted to the per-period RMS of x(t) − x(t − T) while it
            is below :data:`SATURATION_FRACTION` of the chip (> 0: the vibration grows).
        spectrum_hz, spectrum: one-sided amplitude spectrum of the resultant in the window [N].
        window_start: start of the analysis window [s].
        iterate, regeneration: the switches used.
    """

    time: np.ndarray
    force: np.ndarray
    displacement: np.ndarray
    fs: float
    tooth_period: float
    feed_per_tooth: float
    f_peak: float
    f_pv: float
    tooth_peaks: np.ndarray
    iterations_mean: float
    unconverged_steps: int
    dominant_frequency_hz: float
    vibration_frequency_hz: float
    growth_rate: float
    spectrum_hz: np.ndarray
    spectrum: np.ndarray
    window_start: float
    iterate: bool
    regeneration: bool

    @property
    def resultant(self) -> np.ndarray:
        """|F| [N], shape (k,)."""
        return np.linalg.norm(self.force, axis=1)

    @property
    def dynamic_ratio(self) -> float:
        """F_PV / F_peak [-] (docs/model.md §6: the static force model holds below 0.1)."""
        return self.f_pv / self.f_peak if self.f_peak > 0 else 0.0


def _coefficient_list(coefficients) -> list[float]:
    if isinstance(coefficients, cutting.Material):
        return [float(v) for v in coefficients.coefficients()]
    values = np.asarray(coefficients, float).reshape(-1)
    if values.shape != (6,) or not np.all(np.isfinite(values)):
        raise InputError("coefficients", "need 6 finite cutting coefficients")
    return [float(v) for v in values]


def _steps_per_tooth(cut: Cut, fs: float) -> int:
    period = 2.0 * np.pi / (int(cut.flutes) * cut.spindle_speed)
    return max(MIN_STEPS_PER_TOOTH, int(math.ceil(period * fs)))


@dataclass(frozen=True)
class _Row:
    """The engaged edge slices of one instant, with their force laws (engaged only: the others
    carry no force and keep no surface)."""

    normal: np.ndarray  # (E, 2): n(φ) in (X_o, Z_o)
    chip: np.ndarray  # (E,): rigid chip c sin φ [m]
    slope: np.ndarray  # (3, E): force per metre of chip while cutting [N/m]
    offset: np.ndarray  # (3, E): edge force while cutting [N]

    def force(self, h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(F_Xo, F_Yo, F_Zo) [N] for chips ``h`` [m], and which edges cut (h > 0)."""
        cuts = h > 0.0
        return self.slope @ np.where(cuts, h, 0.0) + self.offset @ cuts, cuts


def _rows(geo: CutterGeometry, c: float, k: list[float]) -> list[_Row]:
    """Per instant, the edge force F = −F_t t − F_r n + F_a Y_o of :func:`cutting.edge_forces`
    (linear in h: its magnitudes at h = 0 and h = 1 m give offset and slope)."""
    rows = []
    for p in range(geo.steps):
        idx = np.flatnonzero(geo.engaged[p])
        cos, sin, b = geo.cos[p, idx], geo.sin[p, idx], geo.width[p, idx]
        mags0 = cutting.edge_forces(None, np.zeros_like(b), b, k)
        mags1 = cutting.edge_forces(None, np.ones_like(b), b, k)

        def project(f_t, f_r, f_a, cos=cos, sin=sin):
            return np.vstack([f_t * sin - f_r * cos, f_a, -f_t * cos - f_r * sin])

        offset = project(*mags0)
        slope = project(*(m1 - m0 for m1, m0 in zip(mags1, mags0, strict=True)))
        rows.append(_Row(np.column_stack([cos, sin]), c * sin, slope, offset))
    return rows


def simulate(structure: Structure, cut: Cut, feed: float, coefficients, helix_angle: float,
             duration: float = 2.0, fs: float = 5000.0, iterate: bool = True,
             regeneration: bool = True, slices: int = DEFAULT_SLICES, initial: str = "static",
             steps_per_tooth: int | None = None, window: float = 0.5,
             perturbation: float = 0.0) -> SimulationResult:
    """Simulate the cut on the 2-DOF structure (docs/model.md §6).

    Args:
        structure: M, C, K in (X_o, Z_o).
        cut: the cut (its ``radial_dir``/``feed_dir`` must be the structure's plane).
        feed: feed speed v_f [m/s].
        coefficients: [K_tc, K_rc, K_ac (N/m²), K_te, K_re, K_ae (N/m)] or a Material.
        helix_angle: [rad].
        duration: simulated time [s].
        fs: output sample rate [Hz]; the integrator runs at least this fast.
        iterate: equilibrium chip per step (True) or the first iteration only (False).
        regeneration: the previous edge's surface (True) or the nominal surface (False).
        slices: axial slices.
        initial: ``"static"`` (start at the static equilibrium under the mean rigid-chip force,
            with the surface cut there: the entry transient of the periodic forces follows),
            ``"rest"`` (x = 0, the nominal surface) or ``"periodic"`` (start on the tooth-periodic
            motion of the linearised cut, with the surface it leaves: no entry transient, so a
            small ``perturbation`` shows the Floquet growth or decay from the first period on).
        steps_per_tooth: integrator steps per tooth period (default from ``fs``).
        window: fraction of the run, at its end, over which F_peak, F_PV and the spectrum are taken.
        perturbation: initial displacement [m] added along (X_o + Z_o)/√2.
    """
    if not (math.isfinite(feed) and feed > 0):
        raise InputError("feed", f"must be positive and finite, got {feed!r}")
    if not (math.isfinite(duration) and duration > 0 and math.isfinite(fs) and fs > 0):
        raise InputError("duration/fs", "duration and sample rate must be positive")
    if initial not in ("static", "rest", "periodic"):
        raise InputError("initial", f"{initial!r} is not 'static', 'rest' or 'periodic'")
    if not math.isfinite(perturbation):
        raise InputError("perturbation", f"must be finite, got {perturbation!r}")
    if not 0.0 < window <= 1.0:
        raise InputError("window", f"must lie in (0, 1], got {window!r}")
    k = _coefficient_list(coefficients)
    n_fl = int(cut.flutes)
    c = cutting.feed_per_tooth(feed, n_fl, cut.spindle_speed * 60.0 / (2.0 * np.pi))
    m = steps_per_tooth or _steps_per_tooth(cut, fs)
    geo = cutter_geometry(cut, helix_angle, m, slices)
    dt = geo.dt
    n_steps = int(math.ceil(duration / dt))
    if n_steps < 2 * m:
        raise InputError("duration", f"simulate at least two tooth periods ({2 * geo.tooth_period:g} s)")
    phi_d, g0, g1 = discretise(structure, dt)
    # Forces enter as (F_Xo, F_Yo, F_Zo); the axial component does not load the 2-DOF plane.
    g0_3 = np.column_stack([g0[:, 0], np.zeros(4), g0[:, 1]])
    g1_3 = np.column_stack([g1[:, 0], np.zeros(4), g1[:, 1]])
    g1x_3 = g1_3[0:2]
    rows = _rows(geo, c, k)

    # Surface memory: extra material beyond the nominal chip, per engaged edge slice of each
    # instant: h = w + c sin φ + n·x. After a cut w = −n·x (the surface is where the edge was);
    # where the edge left the cut, w grows by one more c sin φ (the older surface stays).
    w = [np.zeros(row.chip.shape) for row in rows]
    z = np.zeros(4)
    if initial in ("static", "periodic"):
        mean = sum(row.force(row.chip)[0] for row in rows) / m
        # The surface was cut at the static position: the chip there is the rigid one, so the
        # equilibrium is K x = F̄(rigid chip).
        z[0:2] = np.linalg.solve(structure.stiffness, mean[[0, 2]])
        w = [-(row.normal @ z[0:2]) for row in rows]
    if initial == "periodic":
        orbit = _periodic_orbit(structure, cut, c, k, helix_angle, m, slices, z[0:2].copy(),
                                regeneration)
        if regeneration:  # the previous edge left the orbit's own surface
            w = [-(row.normal @ orbit[p, 0:2]) for p, row in enumerate(rows)]
        z = orbit[0].copy()
    z[0:2] += perturbation * np.array([1.0, 1.0]) / math.sqrt(2.0)
    force = np.zeros((n_steps + 1, 3))
    disp = np.zeros((n_steps + 1, 2))
    disp[0] = z[0:2]
    f_prev = rows[0].force(w[0] + rows[0].chip + rows[0].normal @ z[0:2])[0]
    force[0] = f_prev
    iterations = 0
    unconverged = 0
    for n in range(1, n_steps + 1):
        p = n % m
        row = rows[p]
        h_rigid = w[p] + row.chip
        base = phi_d @ z + g0_3 @ f_prev
        f, cuts = row.force(h_rigid)
        if iterate:
            it = 0
            while True:
                it += 1
                x = base[0:2] + g1x_3 @ f
                f_new, cuts = row.force(h_rigid + row.normal @ x)
                d = f_new - f
                f = f_new
                if math.sqrt(d @ d) <= FORCE_TOLERANCE * max(math.sqrt(f @ f), FORCE_FLOOR):
                    break
                if it == MAX_ITERATIONS:
                    unconverged += 1
                    break
            iterations += it
            drive = f
            z = base + g1_3 @ drive
            x = z[0:2]
            reported = f
        else:
            drive = f  # the structure answers the rigid-chip force
            z = base + g1_3 @ drive
            x = z[0:2]
            reported, cuts = row.force(h_rigid + row.normal @ x)
            iterations += 1
        if regeneration:
            w[p] = np.where(cuts, -(row.normal @ x), h_rigid)
        force[n] = reported
        disp[n] = x
        f_prev = drive
    t_int = np.arange(n_steps + 1) * dt
    return _summarise(t_int, force, disp, geo.tooth_period, m, c, fs, duration,
                      iterations / n_steps, unconverged, iterate, regeneration, window)


def _periodic_orbit(structure: Structure, cut: Cut, c: float, k: list[float], helix_angle: float,
                    steps: int, slices: int, x_static: np.ndarray,
                    regeneration: bool) -> np.ndarray:
    """States (x, ẋ) at the instants p·T/steps of the tooth-periodic motion, shape (steps, 4).

    The linearised cut (every engaged edge in the cut) with the rigid-chip force F₀(t) at the
    sub-step midpoints: M ÿ + C ẏ + (K − K_p(t)) y = F₀(t) − K x_s, y = x − x_s. Without
    regeneration K_p(t) is the instantaneous process stiffness; with regeneration a T-periodic
    motion leaves a surface that repeats it, the chip is the rigid one and K_p drops out. The
    periodic solution is y(0) = (I − Φ)⁻¹ β, Φ and β the one-period map (exponential midpoint rule).
    """
    geo = cutter_geometry(cut, helix_angle, steps, slices, offset=0.5)
    forcing = np.array([row.force(row.chip)[0][[0, 2]] for row in _rows(geo, c, k)])
    forcing -= structure.stiffness @ x_static
    kp = process_stiffness_series(geo, k) if not regeneration else np.zeros((steps, 2, 2))
    m_inv = np.linalg.inv(structure.mass)
    maps = []
    for p in range(steps):
        aug = np.zeros((6, 6))
        aug[0:2, 2:4] = np.eye(2)
        aug[2:4, 0:2] = -m_inv @ (structure.stiffness - kp[p])
        aug[2:4, 2:4] = -m_inv @ structure.damping
        aug[2:4, 4:6] = m_inv
        e = scipy.linalg.expm(aug * geo.dt)
        maps.append((e[0:4, 0:4], e[0:4, 4:6] @ forcing[p]))
    phi, beta = np.eye(4), np.zeros(4)
    for e, g in maps:
        phi, beta = e @ phi, e @ beta + g
    y = np.linalg.solve(np.eye(4) - phi, beta)
    orbit = np.zeros((steps, 4))
    for p, (e, g) in enumerate(maps):
        orbit[p] = y
        y = e @ y + g
    orbit[:, 0:2] += x_static
    return orbit


def process_stiffness_series(geo: CutterGeometry, coefficients) -> np.ndarray:
    """Instantaneous ∂F/∂x [N/m] at each instant of ``geo`` on the geometric arc, (steps, 2, 2).

    Rows are force components, columns displacement components, in (X_o, Z_o): the sum over the
    engaged edge slices of −b (K_tc t + K_rc n) nᵀ, the x-derivative of the edge force of
    :func:`models.cutting.instantaneous_force` with h = c sin φ + n·x (linear in h, so it holds no
    feed). Its mean over the period is the ``oriented`` K_p of docs/model.md §5 (a test).
    """
    k = _coefficient_list(coefficients)
    k_tc, k_rc = k[0], k[1]
    b = np.where(geo.engaged, geo.width, 0.0)
    t = np.stack([-geo.sin, geo.cos])  # t(φ) in (X_o, Z_o)
    nn = np.stack([geo.cos, geo.sin])
    return -np.einsum("ips,jps,ps->pij", k_tc * t + k_rc * nn, nn, b)


def _summarise(t_int, force, disp, period, m, c, fs, duration, iterations_mean, unconverged,
               iterate, regeneration, window) -> SimulationResult:
    t_out = np.arange(int(math.floor(duration * fs)) + 1) / fs
    t_out = t_out[t_out <= t_int[-1]]
    f_out = np.column_stack([np.interp(t_out, t_int, force[:, i]) for i in range(3)])
    x_out = np.column_stack([np.interp(t_out, t_int, disp[:, i]) for i in range(2)])
    res = np.linalg.norm(force, axis=1)
    # Per-tooth-period peaks on the integrator grid (exact per period), over the window.
    n_periods = (len(res) - 1) // m
    first = max(0, int(math.floor((1.0 - window) * n_periods)))
    peaks = res[1:1 + n_periods * m].reshape(n_periods, m).max(axis=1)[first:]
    f_peak = float(peaks.max()) if peaks.size else float(res.max())
    f_pv = float(peaks.max() - peaks.min()) if peaks.size else 0.0
    w0 = first * m
    seg = res[w0:]
    spec_hz, spec = _spectrum(seg - seg.mean(), m / period)
    dominant = float(spec_hz[1 + np.argmax(spec[1:])]) if spec.size > 1 else 0.0
    diff = disp[m:] - disp[:-m]
    growth, (lo, hi) = _growth_rate(diff, m, period, c)
    seg_d = diff[lo * m:hi * m] if hi - lo >= 4 else diff
    vib_hz, vib = _spectrum(seg_d[:, 0] - seg_d[:, 0].mean(), m / period)
    amp = vib + _spectrum(seg_d[:, 1] - seg_d[:, 1].mean(), m / period)[1]
    vibration = float(vib_hz[1 + np.argmax(amp[1:])]) if amp.size > 1 else 0.0
    return SimulationResult(
        time=t_out, force=f_out, displacement=x_out, fs=float(fs), tooth_period=period,
        feed_per_tooth=float(c), f_peak=f_peak, f_pv=f_pv, tooth_peaks=peaks,
        iterations_mean=float(iterations_mean), unconverged_steps=int(unconverged),
        dominant_frequency_hz=dominant, vibration_frequency_hz=vibration, growth_rate=growth,
        spectrum_hz=spec_hz, spectrum=spec, window_start=float(first * period),
        iterate=iterate, regeneration=regeneration)


def _spectrum(signal: np.ndarray, rate: float) -> tuple[np.ndarray, np.ndarray]:
    """One-sided amplitude spectrum with a Hann window: (frequencies [Hz], amplitudes)."""
    n = len(signal)
    if n < 4:
        return np.zeros(1), np.zeros(1)
    win = np.hanning(n)
    amp = np.abs(np.fft.rfft(signal * win)) * 2.0 / win.sum()
    return np.fft.rfftfreq(n, 1.0 / rate), amp


def _growth_rate(diff: np.ndarray, m: int, period: float,
                 c: float) -> tuple[float, tuple[int, int]]:
    """Rate [1/s] of the per-period RMS of x(t) − x(t − T), fitted in the linear regime, and the
    range of periods (of ``diff``) it was fitted over."""
    n_periods = len(diff) // m
    if n_periods < 4:
        return 0.0, (0, n_periods)
    rms = np.sqrt((diff[:n_periods * m] ** 2).sum(axis=1).reshape(n_periods, m).mean(axis=1))
    rms = rms[1:]  # the first period still holds the start
    limit = SATURATION_FRACTION * c
    over = np.flatnonzero(rms > limit)
    stop = int(over[0]) if over.size else len(rms)
    stop = max(stop, min(4, len(rms)))
    # The later half of the linear regime: by then the least damped (or fastest growing) motion
    # dominates, which is what the Floquet multiplier describes.
    start = stop // 2 if stop >= 8 else 0
    y = np.log(np.maximum(rms[start:stop], 1e-300))
    t = (np.arange(start, stop) + 1.5) * period
    if stop - start < 2:
        return 0.0, (start + 1, stop + 1)
    return float(np.polyfit(t, y, 1)[0]), (start + 1, stop + 1)
