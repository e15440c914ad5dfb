"""Named synthetic plans for the supervisor tests (written with planner.plan_file.write_plan).

``make_plan(folder, sections)`` writes a plan whose cut sections carry a synthetic stability
characteristic: margin falls linearly with feed and crosses zero at ``boundary_mm_s`` (so lowering
the feed is stabilising), force rises linearly with feed; ``flat=True`` gives a margin that does not
depend on feed (no stabilising direction, as with the oriented process model).

Named plans:
    (``rising=True``: margin rises with feed, stable above the boundary.)
    ONE_SECTION: 0.5 m cut at 8 mm/s, stable up to 10 mm/s (so a boundary shift of 1.6 makes 8 mm/s
        chatter and 5 mm/s safe).
    FEED_STEP: 0.012 m at 8 mm/s (1.5 s) then 0.5 m at 4 mm/s (the thesis's feed-step false-alarm test).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from planner.plan_file import SAMPLE_ARRAYS, write_plan
from robot_io.links.base import LinkStats, LinkStatus

FEEDS_MM_S = np.linspace(1.0, 20.0, 39)
NATURAL_HZ = (9.0, 13.4)  # sqrt = 10.98 Hz
TOOTH_HZ = 1000.0 * 2 / 60.0
FORCE_MAX_N = 300.0


def characteristic(boundary_mm_s: float = 10.0, flat: bool = False, force_per_mm_s: float = 15.0,
                   force0_N: float = 20.0, rising: bool = False) -> dict:
    margin = (np.full_like(FEEDS_MM_S, 2e4) if flat
              else 1e5 * (boundary_mm_s - FEEDS_MM_S) / boundary_mm_s)
    if rising:
        margin = -margin
    force = force0_N + force_per_mm_s * FEEDS_MM_S
    return {"sample": 0, "feeds_mm_s": FEEDS_MM_S.tolist(), "margin_N_per_m": margin.tolist(),
            "gamma_deg": np.linspace(10, 40, FEEDS_MM_S.size).tolist(), "force_N": force.tolist(),
            "stable": (margin >= 0).tolist()}


def make_plan(folder: Path, sections: list[dict], step_m: float = 0.002,
              force_max_N: float = FORCE_MAX_N) -> Path:
    """sections: dicts with length_m, feed_mm_s and optionally boundary_mm_s, flat, rising, kind,
    force_per_mm_s."""
    secs = []
    s0 = 0.0
    starts = []
    for i, spec in enumerate(sections):
        n = max(2, int(round(spec["length_m"] / step_m)))
        starts.append((s0, n))
        kind = spec.get("kind", "cut")
        ch = (characteristic(spec.get("boundary_mm_s", 10.0), spec.get("flat", False),
                             spec.get("force_per_mm_s", 15.0), rising=spec.get("rising", False))
              if kind == "cut" else None)
        secs.append({
            "index": i + 1, "kind": kind, "s_start_m": s0, "s_end_m": s0 + spec["length_m"],
            "feed_mm_s": spec["feed_mm_s"], "binding": "chatter", "margin_N_per_m": 1e4,
            "force_max_N": 150.0, "gamma_deg": 20.0, "natural_frequency_hz": list(NATURAL_HZ),
            "tooth_frequency_hz": TOOTH_HZ, "characteristic": ch,
        })
        s0 += spec["length_m"]
    n_total = sum(n for _, n in starts)
    samples = {}
    for name, tail in SAMPLE_ARRAYS.items():
        samples[name] = np.zeros((n_total, *tail))
    s_all, sec_all, feed_all = [], [], []
    k = 0
    for i, ((s_start, n), spec) in enumerate(zip(starts, sections, strict=True)):
        s_all.append(np.linspace(s_start, s_start + spec["length_m"], n, endpoint=False))
        sec_all.append(np.full(n, i + 1))     # the file numbers sections from 1
        feed_all.append(np.full(n, spec["feed_mm_s"]))
        secs[i]["sample_start"], secs[i]["sample_stop"] = k, k + n
        k += n
    samples["s_m"] = np.concatenate(s_all)
    samples["section"] = np.concatenate(sec_all).astype(int)
    samples["feed_mm_s"] = np.concatenate(feed_all)
    samples["speed_mm_s"] = samples["feed_mm_s"].copy()
    ds = np.diff(samples["s_m"], prepend=0.0)
    samples["time_s"] = np.cumsum(ds / (samples["speed_mm_s"] * 1e-3))
    for name in ("kind", "move", "line", "file", "source_file", "mode"):
        if name in samples:
            samples[name] = samples[name].astype(int)
    samples["arc"] = samples["arc"].astype(bool)
    data = {
        "method": "constant", "job_name": "synthetic", "job_file": "none.toml",
        "robot": "kr210_r2700_extra",
        "base_frame": {"xyz_mm": [0, 0, 0], "abc_deg": [0, 0, 0]},
        "tool_frame": {"xyz_mm": [0, 0, 0], "abc_deg": [0, 0, 0]},
        "spindle_rpm": 1000.0, "flutes": 2, "tool_diameter_mm": 25.4, "material": "al6061",
        "model": {"process_model": "thesis", "mass_model": "robot", "criterion": "eigen", "cct": True},
        "constraints": {"force_max_N": force_max_N, "feed_min_mm_s": 0.5, "feed_max_mm_s": 20.0},
        "sections": secs, "cycle_time_s": float(samples["time_s"][-1]),
        "process_time_s": float(samples["time_s"][-1]),
        "solver": {"status": "synthetic", "success": True, "iterations": 0, "build_time_s": 0.0,
                   "solve_time_s": 0.0},
    }
    return write_plan(folder, data, samples)


ONE_SECTION = [{"length_m": 0.5, "feed_mm_s": 8.0}]
FEED_STEP = [{"length_m": 0.012, "feed_mm_s": 8.0}, {"length_m": 0.5, "feed_mm_s": 4.0}]


class ApplyingLink:
    """A robot link whose controller applies every override at once (the supervisor tests'
    in-process controller)."""

    stats = LinkStats()
    connected = True

    def __init__(self) -> None:
        self.v = 100.0

    def set_override(self, p: float) -> LinkStatus:
        self.v = float(p)
        return LinkStatus(True, "ok", int(p))

    def read_override(self) -> float:
        return self.v

    def close(self) -> None:
        pass
