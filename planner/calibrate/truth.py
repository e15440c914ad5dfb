"""A simulated "true" cell: hidden parameters that differ from the nominal ones, and the records its
cuts would give (docs/calibration.md, "Validation on a simulated truth").

Each cut runs in the time-domain model of docs/model.md §6 (helical cutter in axial slices,
equilibrium chip thickness, regeneration on) on the true arm at the record's pose. What a real cell
would record comes out of it:

- ``force_n``: the mean of the simulated force over whole tooth periods of the run's second half,
  plus a measurement error per component drawn from N(0, σ²), σ = ``force_noise_n`` +
  ``force_noise_rel`` × |F̄| (a dynamometer's calibration, cross-talk and drift over a pass:
  0.5 N + 1 % by default).
- ``deflection_mm``: the true static deflection under that mean force (CCT compliance with the
  true joint stiffness), plus N(0, ``deflection_noise_mm``²) per component (a laser tracker:
  15 µm by default).
- ``verdict``: ``chatter`` when the non-tooth-periodic vibration grows (growth rate above
  :data:`GROWTH_CHATTER`) and the force is dynamic (F_PV/F_peak above :data:`DYNAMIC_CHATTER`),
  else ``stable``; ``chatter_hz``: the vibration's frequency.

The truth's ``process_gain`` factor is recorded with it but the time-domain model has no such knob:
its process is the coefficients' own (docs/limitations: a calibrated gain describes the model, not
the cut).
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from models.dynamics import simulate
from models.errors import InputError
from models.structure import DEFAULT_DAMPING_RATIO, pose_structure
from planner.calibrate.context import CalibrationContext
from planner.calibrate.design_bound import FORCE_NOISE_N, FORCE_NOISE_REL
from planner.calibrate.fit_stiffness import joint_terms, record_cut
from planner.calibrate.records import CutRecord

__all__ = ["DYNAMIC_CHATTER", "GROWTH_CHATTER", "TruthCell", "load_truth", "run_cut", "run_cuts"]

#: Growth rate of the non-periodic vibration [1/s] above which a simulated cut chatters.
GROWTH_CHATTER = 0.5
#: F_PV/F_peak [-] above which the force is dynamic (docs/model.md §6: static model valid below 0.1).
DYNAMIC_CHATTER = 0.1


@dataclass(frozen=True)
class TruthCell:
    """The hidden parameters of a true cell, relative to a nominal :class:`CalibrationContext`.

    Attributes:
        nominal: the nominal cell.
        joint_scale: true joint stiffness / nominal [-], common or (6,).
        coefficient_factor: true cutting coefficients / nominal [-], common or (6,).
        process_gain: true process gain / nominal [-] (recorded; see the module doc).
        regeneration: simulate with the previous flute's surface.
        force_noise_n, force_noise_rel: mean force error σ = abs [N] + rel × |F̄|.
        deflection_noise_mm: σ of a deflection measurement component [mm].
        duration_s: simulated time per cut [s]; fs_hz: the simulation's rate [Hz].
        damping_ratio: modal damping of the arm [-]; slices: axial slices of the cutter.
    """

    nominal: CalibrationContext
    joint_scale: float | tuple[float, ...] = 0.7
    coefficient_factor: float | tuple[float, ...] = 1.15
    process_gain: float = 1.3
    regeneration: bool = True
    force_noise_n: float = FORCE_NOISE_N
    force_noise_rel: float = FORCE_NOISE_REL
    deflection_noise_mm: float = 0.015
    duration_s: float = 0.6
    fs_hz: float = 5000.0
    damping_ratio: float = DEFAULT_DAMPING_RATIO
    slices: int = 8

    def coefficients(self) -> np.ndarray:
        """The true coefficients [N/m², N/m], (6,)."""
        return self.nominal.material.coefficients() * np.broadcast_to(
            np.asarray(self.coefficient_factor, float), (6,))

    def context(self) -> CalibrationContext:
        """The true cell as a context (its joint stiffness scale folded in)."""
        scale = np.broadcast_to(np.asarray(self.joint_scale, float), (6,))
        if not np.allclose(scale, scale[0]):
            raise InputError("joint_scale", "a per-joint truth has no single context scale")
        return replace(self.nominal,
                       joint_stiffness_scale=self.nominal.joint_stiffness_scale * float(scale[0]))


def load_truth(path: str | Path, nominal: CalibrationContext) -> TruthCell:
    """Read a truth file (TOML, one ``[truth]`` table with :class:`TruthCell`'s keys)."""
    p = Path(path)
    try:
        doc = tomllib.loads(p.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as e:
        raise InputError(str(p), f"cannot read the truth file: {e}") from e
    table = doc.get("truth")
    if not isinstance(table, dict):
        raise InputError(str(p), "needs a [truth] table (joint_scale, coefficient_factor, ...)")
    known = {f for f in TruthCell.__dataclass_fields__ if f != "nominal"}
    unknown = sorted(set(table) - known)
    if unknown:
        raise InputError(str(p), f"unknown keys {unknown} in [truth]; known: {sorted(known)}")
    values = {k: tuple(v) if isinstance(v, list) else v for k, v in table.items()}
    return TruthCell(nominal=nominal, **values)


def _whole_periods_mean(time: np.ndarray, force: np.ndarray, start: float, period: float
                        ) -> np.ndarray:
    """Mean of ``force`` over the whole tooth periods after ``start``."""
    t_end = time[-1]
    n = math.floor((t_end - start) / period)
    if n < 1:
        return force[time >= start].mean(axis=0)
    keep = (time > t_end - n * period) & (time <= t_end)
    return force[keep].mean(axis=0)


def run_cut(truth: TruthCell, planned: CutRecord, rng: np.random.Generator) -> CutRecord:
    """Run one planned cut in the true cell; return the record the cell would write."""
    ctx = truth.nominal
    scale = np.broadcast_to(np.asarray(truth.joint_scale, float), (6,))
    coefficients = truth.coefficients()
    params = ctx.params(joint_scale=scale, coefficients=coefficients)
    robot = ctx.load_robot()
    cut = record_cut(ctx, planned)
    feed, q = planned.feed(), planned.q()
    structure = pose_structure(robot, params, q, cut, feed, truth.damping_ratio)
    sim = simulate(structure, cut, feed, coefficients, ctx.tool.helix_angle,
                   duration=truth.duration_s, fs=truth.fs_hz, regeneration=truth.regeneration,
                   slices=truth.slices)
    mean = _whole_periods_mean(sim.time, sim.force, sim.window_start, sim.tooth_period)
    chatter = sim.growth_rate > GROWTH_CHATTER and sim.dynamic_ratio > DYNAMIC_CHATTER
    sigma = truth.force_noise_n + truth.force_noise_rel * float(np.linalg.norm(mean))
    measured = mean + rng.normal(0.0, sigma, 3)
    axes = planned.cut_axes()
    # The true static deflection under the true mean force (base axes), measured with noise.
    probe = replace(planned, force_n=tuple(float(v) for v in mean), frame="cut")
    jv, k_c = joint_terms(ctx, probe)
    k_theta = np.asarray(params.joint_stiffness, float)
    delta = jv @ np.linalg.solve(np.diag(k_theta) - k_c, jv.T @ (axes @ mean))
    delta_mm = (axes.T @ delta) * 1e3 + rng.normal(0.0, truth.deflection_noise_mm, 3)
    source = {**planned.source, "kind": "simulated",
              "growth_rate_per_s": round(float(sim.growth_rate), 4),
              "dynamic_ratio": round(float(sim.dynamic_ratio), 4)}
    return replace(
        planned, verdict="chatter" if chatter else "stable", frame="cut",
        force_n=tuple(round(float(v), 3) for v in measured),
        deflection_mm=tuple(round(float(v), 5) for v in delta_mm),
        chatter_hz=round(float(sim.vibration_frequency_hz), 3) if chatter else None,
        duration_s=truth.duration_s, source=source)


def run_cuts(truth: TruthCell, planned: list[CutRecord], seed: int = 0,
             progress: bool = False) -> list[CutRecord]:
    """:func:`run_cut` for each planned record, with one seeded generator (``progress``: a bar on
    a terminal, a pass being a fraction of a second to a few seconds)."""
    from planner._progress import bar

    rng = np.random.default_rng(seed)
    out = []
    with bar(len(planned), "simulated test cuts", progress, unit="cut", min_total=4) as pbar:
        for r in planned:
            out.append(run_cut(truth, r, rng))
            pbar.update(1)
    return out
