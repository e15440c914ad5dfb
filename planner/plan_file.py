"""The plan on disk: ``plan.json`` plus a per-sample table ``samples.npz``.

This is the contract between the planner (``cctmill plan``), the KRL exporter (``cctmill export``)
and the online supervisor (``cctmill supervise``). Units are in the key names (the file is an edge);
:func:`load_plan` hands back SI arrays and plain dicts.

``plan.json`` (``format`` = ``"cctmill-plan"``, ``version`` = 1)::

    method            "optimize" | "thesis" | "constant"
    job_name, job_file
    robot             robot data name
    base_frame        {"xyz_mm": [3], "abc_deg": [3]}     $BASE (workpiece frame in the robot base)
    tool_frame        {"xyz_mm": [3], "abc_deg": [3]}     $TOOL (TCP in the flange frame)
    spindle_rpm, flutes, tool_diameter_mm, material
    model             {"process_model", "mass_model", "criterion", "cct"}
    constraints       {"force_max_N", "deflection_tol_mm", "power_max_kW", "feed_min_mm_s",
                       "feed_max_mm_s", "feed_change_max_mm_s", "margin_min_N_per_m",
                       "section_length_min_mm", "safety_factor"}
    sections          list, in path order, partitioning the samples:
        index, kind ("cut" | "air" | "rapid"), sample_start, sample_stop (exclusive),
        s_start_m, s_end_m, feed_mm_s, binding (chatter | force | deflection | power | robot |
        feed_max | feed_change), margin_N_per_m (min over the section), force_max_N,
        deflection_max_mm, deflection_normal_max_mm, power_max_kW, gamma_deg (at the tightest
        sample), gamma_range_deg [lo, hi], natural_frequency_hz ([f1, f2] at the tightest sample,
        null for the isotropic mass model), tooth_frequency_hz, line_start, line_end, file,
        time_s (timed duration), robot_limited (bool),
        characteristic {sample, feeds_mm_s, margin_N_per_m, gamma_deg, force_N, stable}
            the stability characteristic at the section's tightest sample (cut sections only)
    cycle_time_s      toppra-timed cycle (rapids included)
    process_time_s    Σ L_i / f_i over the cut and air sections (no robot limits)
    solver            {"status", "success", "iterations", "build_time_s", "solve_time_s"}
    samples_file      "samples.npz" (relative to plan.json)

``samples.npz`` (n samples)::

    s_m (n,)  q_rad (n, 6)  position_wp_m (n, 3)  abc_wp_deg (n, 3)  tool_axis_wp (n, 3)
    section (n,) int  kind (n,) int (0 cut, 1 air, 2 rapid)  arc (n,) bool  move (n,) int
    line (n,) int  source_file (n,) int (index into plan.json's ``files``)
    feed_mm_s (n,) planned  speed_mm_s (n,) timed  time_s (n,)
    force_N (n,)  deflection_mm (n,)  deflection_wp_m (n, 3)  deflection_normal_mm (n,)
    gamma_deg (n,)  margin_N_per_m (n,)  power_kW (n,)  a_e_m (n,)  a_p_m (n,)  mode (n,) int

``abc_wp_deg`` is the TCP orientation in ``$BASE`` as KUKA A, B, C; ``deflection_wp_m`` the
predicted static deflection of the TCP in ``$BASE`` axes (the KRL exporter's mirror compensation
subtracts it). Samples of one arc move (``arc`` true, same ``move``) lie on that arc.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from models.errors import DataFileError
from planner._atomic import atomic_path, write_text_atomic

__all__ = [
    "BINDINGS",
    "FORMAT",
    "KINDS",
    "Plan",
    "PlanFileError",
    "SAMPLE_ARRAYS",
    "VERSION",
    "load_plan",
    "write_plan",
]

FORMAT = "cctmill-plan"
VERSION = 1
#: What can bind a section's feed.
BINDINGS = ("chatter", "force", "deflection", "power", "robot", "feed_max", "feed_change")
#: Section / sample kinds, in the order of their integer codes in ``samples.npz``.
KINDS = ("cut", "air", "rapid")
#: Arrays every ``samples.npz`` holds, with their trailing shape.
SAMPLE_ARRAYS: dict[str, tuple[int, ...]] = {
    "s_m": (), "q_rad": (6,), "position_wp_m": (3,), "abc_wp_deg": (3,), "tool_axis_wp": (3,),
    "section": (), "kind": (), "arc": (), "move": (), "line": (), "source_file": (), "feed_mm_s": (),
    "speed_mm_s": (), "time_s": (), "force_N": (), "deflection_mm": (), "deflection_wp_m": (3,),
    "deflection_normal_mm": (), "gamma_deg": (), "margin_N_per_m": (), "power_kW": (),
    "a_e_m": (), "a_p_m": (), "mode": (),
}
_REQUIRED = ("format", "version", "method", "sections", "cycle_time_s", "constraints", "solver",
             "samples_file", "base_frame", "tool_frame")
_SECTION_REQUIRED = ("index", "kind", "sample_start", "sample_stop", "s_start_m", "s_end_m",
                     "feed_mm_s", "binding")


class PlanFileError(DataFileError):
    """A plan file is missing, malformed, or not a cctmill plan (``path``: the file)."""


@dataclass(frozen=True)
class Plan:
    """A plan read back from disk.

    Attributes:
        path: the ``plan.json`` file.
        data: the JSON document (units in key names).
        samples: the per-sample arrays of ``samples.npz`` (units in names), see module docstring.
    """

    path: Path
    data: dict[str, Any]
    samples: dict[str, np.ndarray]

    @property
    def sections(self) -> list[dict[str, Any]]:
        """The sections, in path order."""
        return self.data["sections"]

    @property
    def method(self) -> str:
        return str(self.data["method"])

    def section_at(self, s: float) -> dict[str, Any]:
        """The section containing arc length ``s`` [m] (the last one past the end)."""
        for sec in self.sections:
            if s < sec["s_end_m"]:
                return sec
        return self.sections[-1]


def _resolve(path: str | os.PathLike) -> Path:
    p = Path(path)
    return p / "plan.json" if p.is_dir() else p


def load_plan(path: str | os.PathLike) -> Plan:
    """Read ``plan.json`` (or a folder holding one) and its samples table.

    Raises:
        PlanFileError: missing file, bad JSON, wrong format, missing keys or arrays.
    """
    p = _resolve(path)
    if not p.is_file():
        raise PlanFileError(str(p), "no such plan; run `cctmill plan JOB.toml -o DIR` first")
    try:
        data = json.loads(p.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise PlanFileError(str(p), f"not readable JSON ({e})") from e
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise PlanFileError(str(p), f"not a cctmill plan (format must be {FORMAT!r})")
    if data.get("version") != VERSION:
        raise PlanFileError(str(p), f"plan version {data.get('version')!r}; this cctmill reads "
                            f"version {VERSION}: plan the job again")
    missing = [k for k in _REQUIRED if k not in data]
    if missing:
        raise PlanFileError(str(p), f"missing keys {missing}")
    for sec in data["sections"]:
        gone = [k for k in _SECTION_REQUIRED if k not in sec]
        if gone:
            raise PlanFileError(str(p), f"section {sec.get('index', '?')} lacks {gone}")
    sp = p.parent / data["samples_file"]
    try:
        with np.load(sp, allow_pickle=False) as z:
            samples = {k: z[k] for k in z.files}
    except (OSError, ValueError) as e:
        raise PlanFileError(str(sp), f"samples table not readable ({e})") from e
    n = samples.get("s_m", np.zeros(0)).shape[0]
    for name, tail in SAMPLE_ARRAYS.items():
        a = samples.get(name)
        if a is None or a.shape != (n, *tail):
            raise PlanFileError(str(sp), f"array {name!r} missing or not of shape {(n, *tail)}")
    return Plan(path=p, data=data, samples=samples)


def _jsonable(v: Any) -> Any:
    if isinstance(v, dict):
        return {k: _jsonable(x) for k, x in v.items()}
    if isinstance(v, list | tuple):
        return [_jsonable(x) for x in v]
    if isinstance(v, np.ndarray):
        return _jsonable(v.tolist())
    if isinstance(v, np.bool_):
        return bool(v)
    if isinstance(v, np.integer):
        return int(v)
    if isinstance(v, float | np.floating):
        f = float(v)
        return f if np.isfinite(f) else None
    return v


def write_plan(folder: str | os.PathLike, data: dict[str, Any],
               samples: dict[str, np.ndarray]) -> Path:
    """Write ``plan.json`` and ``samples.npz`` into ``folder`` atomically; return the JSON path.

    Non-finite floats become ``null`` (JSON has no NaN).
    """
    out = Path(folder)
    n = samples["s_m"].shape[0]
    for name, tail in SAMPLE_ARRAYS.items():
        if name not in samples or samples[name].shape != (n, *tail):
            raise ValueError(f"samples[{name!r}] missing or not of shape {(n, *tail)}")
    doc = {"format": FORMAT, "version": VERSION, **data, "samples_file": "samples.npz"}
    with atomic_path(out / "samples.npz", suffix=".npz") as tmp:
        np.savez_compressed(tmp, **samples)
    return write_text_atomic(out / "plan.json", json.dumps(_jsonable(doc), indent=2) + "\n")
