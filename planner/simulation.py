"""The time-domain cut at one pose (docs/model.md §6): simulation, its Floquet and eigen verdicts and
the signals a sensor would record — what ``cctmill simulate`` runs, as one library call::

    model, q, cut = PointSetup(..., mass_model="robot", criterion="floquet").build()
    report = simulate_point(model, q, cut, feed=1e-3, options=SimulationOptions(duration=2.0))
    report.as_json()["growth_rate_per_s"]; write_signal_csv(report, "signal.csv")
"""

from __future__ import annotations

import io
import math
import os
from dataclasses import dataclass
from typing import Any

import numpy as np

from models.cutter_geometry import DEFAULT_SLICES
from models.dynamics import SimulationResult, simulate
from models.errors import InputError
from models.floquet import FloquetResult, floquet
from models.point import PointAnalysis, PointModel
from models.signals import synthetic_signals
from models.structure import DEFAULT_DAMPING_RATIO, Structure, pose_structure
from models.tooling import load_tool
from planner._atomic import write_text_atomic

__all__ = ["SimulationOptions", "SimulationReport", "simulate_point", "write_signal_csv"]


@dataclass(frozen=True)
class SimulationOptions:
    """How to simulate (SI).

    Attributes:
        tool: tool data name (its helix angle).
        damping_ratio: modal damping of both arm modes [-], in [0, 1).
        duration: simulated time [s]; fs_hz: output sample rate [Hz].
        iterate: equilibrium chip thickness per step (False: the thesis's first iteration).
        regeneration: the previous flute's waviness in the chip.
        slices: axial slices of the cutter.
        initial: ``static``, ``rest`` or ``periodic`` start; perturbation: initial displacement [m].
        noise: force noise of the recorded signals [N] (standard deviation); seed: its seed.
    """

    tool: str = "em25_2f"
    damping_ratio: float = DEFAULT_DAMPING_RATIO
    duration: float = 2.0
    fs_hz: float = 5000.0
    iterate: bool = True
    regeneration: bool = True
    slices: int = DEFAULT_SLICES
    initial: str = "static"
    perturbation: float = 0.0
    noise: float = 0.0
    seed: int = 0

    def check(self) -> None:
        """Raises InputError naming the field that is out of range."""
        for name in ("duration", "fs_hz"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise InputError(name, f"must be positive, got {value:g}")
        if not 0.0 <= self.damping_ratio < 1.0:
            raise InputError("damping_ratio", f"must lie in [0, 1), got {self.damping_ratio:g}")
        if self.slices < 1:
            raise InputError("slices", f"need at least 1, got {self.slices}")
        if not math.isfinite(self.perturbation):
            raise InputError("perturbation", f"must be finite, got {self.perturbation:g}")
        if not (math.isfinite(self.noise) and self.noise >= 0):
            raise InputError("noise", f"must be >= 0, got {self.noise:g}")


@dataclass(frozen=True)
class SimulationReport:
    """A simulated cut and its verdicts: the run, the arm's structure at the pose, Floquet, and the
    point model at the same feed (its criterion decides ``stable_predicted``)."""

    sim: SimulationResult
    structure: Structure
    floquet: FloquetResult
    point: PointAnalysis
    criterion: str
    options: SimulationOptions

    def as_json(self) -> dict[str, Any]:
        """The figures ``cctmill simulate --json`` prints (units in the names)."""
        sim, fl, o = self.sim, self.floquet, self.options
        return {
            "f_peak_N": sim.f_peak, "f_pv_N": sim.f_pv, "f_pv_over_f_peak": sim.dynamic_ratio,
            "static_model_valid": bool(sim.dynamic_ratio < 0.1),
            "iterations_mean": sim.iterations_mean, "unconverged_steps": sim.unconverged_steps,
            "dominant_frequency_hz": sim.dominant_frequency_hz,
            "vibration_frequency_hz": sim.vibration_frequency_hz,
            "growth_rate_per_s": sim.growth_rate, "stable_predicted": bool(self.point.stable),
            "criterion": self.criterion, "stable_eigen": bool(self.point.stable_eigen),
            "floquet_spectral_radius": fl.spectral_radius,
            "floquet_growth_rate_per_s": fl.growth_rate, "floquet_frequency_hz": fl.frequency_hz,
            "natural_frequencies_hz": self.structure.natural_frequencies_hz.tolist(),
            "tooth_frequency_hz": 1.0 / sim.tooth_period, "feed_per_tooth_m": sim.feed_per_tooth,
            "iterate": sim.iterate, "regeneration": sim.regeneration,
            "damping_ratio": o.damping_ratio, "duration_s": o.duration, "fs_hz": o.fs_hz,
            "initial": o.initial, "perturbation_um": o.perturbation * 1e6,
            "window_start_s": sim.window_start, "warnings": list(self.point.warnings),
        }


def simulate_point(model: PointModel, q: np.ndarray, cut: Any, feed: float,
                   options: SimulationOptions) -> SimulationReport:
    """Simulate ``cut`` at joints ``q`` [rad] and ``feed`` [m/s] on the arm of ``model``.

    Raises:
        InputError: an option is out of range (the field is named).
    """
    options.check()
    tool = load_tool(options.tool)
    model.helix_angle = tool.helix_angle
    model.damping_ratio = options.damping_ratio
    point = model.analyze(q, cut, feed)
    structure = pose_structure(model.robot, model.params, q, cut, feed, options.damping_ratio)
    sim = simulate(structure, cut, feed, model.params.coefficients, tool.helix_angle,
                   duration=options.duration, fs=options.fs_hz, iterate=options.iterate,
                   regeneration=options.regeneration, slices=options.slices,
                   initial=options.initial, perturbation=options.perturbation)
    fl = floquet(structure, cut, model.params.coefficients, tool.helix_angle, slices=options.slices)
    return SimulationReport(sim, structure, fl, point, model.criterion, options)


def write_signal_csv(report: SimulationReport, path: str | os.PathLike) -> None:
    """Time, force (X_o, Y_o, Z_o), resultant, strain and displacement as CSV (atomically), with
    the options' force noise: a record ``cctmill supervise --signal FILE`` can replay."""
    sim, o = report.sim, report.options
    sig = synthetic_signals(sim, np.random.default_rng(o.seed), force_noise=o.noise)
    buf = io.StringIO()
    buf.write("time_s,fx_o_N,fy_o_N,fz_o_N,resultant_N,strain,x_o_mm,z_o_mm\n")
    data = np.column_stack([sim.time, sim.force, sig.force, sig.strain, sim.displacement * 1e3])
    np.savetxt(buf, data, delimiter=",", fmt="%.9g")
    write_text_atomic(path, buf.getvalue())
