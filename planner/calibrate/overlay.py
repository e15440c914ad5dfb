"""The calibration overlay: a job fragment (TOML) with the fitted values and the data they came from.

An overlay holds only ``[cell]``, ``[model]`` and ``[calibration]`` keys. A job uses it with
``[calibration] overlay = "cell.overlay.toml"`` (relative to the job file): the overlay's keys
replace the job's, table by table (:func:`merge_overlay`, called by the job loader). The fitted
cutting coefficients are ``[calibration] k_tc … k_ae`` (SI, N/m² and N/m); the planner takes them
instead of the material file's (:meth:`planner.job.Job.material_coefficients`).
"""

from __future__ import annotations

import datetime as dt
import json
import tomllib
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from planner._atomic import write_text_atomic

__all__ = ["OVERLAY_TABLES", "merge_overlay", "overlay_text", "write_overlay"]

#: The tables an overlay may hold.
OVERLAY_TABLES = ("cell", "model", "calibration")


def merge_overlay(doc: dict, folder: str | Path) -> tuple[dict, list[str]]:
    """``doc`` with the overlay its ``[calibration] overlay`` names merged in, and the problems
    (one line each, in the job file's terms; the doc is returned unchanged when there are any)."""
    cal = doc.get("calibration")
    if not isinstance(cal, dict) or not isinstance(cal.get("overlay"), str):
        return doc, []
    name = cal["overlay"]
    path = Path(folder) / name
    try:
        over = tomllib.loads(path.read_text(encoding="utf-8"))
    except OSError as e:
        return doc, [f"[calibration] overlay: cannot read {path}: {e.strerror or e}; give the "
                     "overlay's path relative to the job file (cctmill calibrate -o writes it)"]
    except (UnicodeDecodeError, tomllib.TOMLDecodeError, ValueError) as e:
        return doc, [f"[calibration] overlay: {path} is not valid TOML: {e}"]
    extra = sorted(set(over) - set(OVERLAY_TABLES))
    if extra:
        return doc, [f"[calibration] overlay: {path} holds {extra}; an overlay holds only "
                     f"{', '.join(f'[{t}]' for t in OVERLAY_TABLES)}"]
    nested = [t for t in OVERLAY_TABLES if t in over and not isinstance(over[t], dict)]
    if nested:
        return doc, [f"[calibration] overlay: {path}: {nested[0]} must be a table"]
    if "overlay" in over.get("calibration", {}):
        return doc, [f"[calibration] overlay: {path} names another overlay; overlays do not chain"]
    out = dict(doc)
    for table in OVERLAY_TABLES:
        if table in over:
            base = out.get(table, {})
            out[table] = {**(base if isinstance(base, dict) else {}), **over[table]}
    out["calibration"] = {**out.get("calibration", {}), "overlay": name}
    return out, []


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(float(v)) if isinstance(v, float) else str(v)
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise TypeError(f"no TOML form for {v!r}")


def overlay_text(cell: dict[str, Any], model: dict[str, Any], calibration: dict[str, Any],
                 comments: Sequence[str] = ()) -> str:
    """The overlay's TOML text: three tables of plain values, with a comment header."""
    lines = [f"# {c}" if c else "#" for c in comments]
    for title, table in (("cell", cell), ("model", model), ("calibration", calibration)):
        if not table:
            continue
        lines += ["", f"[{title}]"]
        lines += [f"{k} = {_toml_value(v)}" for k, v in table.items() if v is not None]
    return "\n".join(lines).lstrip("\n") + "\n"


def write_overlay(path: str | Path, cell: dict[str, Any], model: dict[str, Any],
                  calibration: dict[str, Any], comments: Sequence[str] = ()) -> Path:
    """Write an overlay atomically (see :func:`overlay_text`); ``calibration`` gets the time it
    was written (``fitted_utc``) unless it has one."""
    calibration = {**calibration}
    calibration.setdefault("fitted_utc", dt.datetime.now(dt.UTC).strftime("%Y-%m-%dT%H:%M:%SZ"))
    return write_text_atomic(path, overlay_text(cell, model, calibration, comments))
