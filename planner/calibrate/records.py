"""Cut records: the JSON Lines file of cuts a cell ran, the raw material of calibration (docs/calibration.md).

One JSON object per line; blank lines and lines starting with ``#`` are skipped. Units are in the
key names (the edge of the program); :class:`CutRecord` keeps them as written and converts to SI
only in its ``*_si`` accessors. The frames:

- ``joints_deg``: KUKA axis values A1..A6 [deg] while the section ran (its middle, or where the
  mean force was taken).
- ``feed_dir``, ``radial_dir``: the cutting frame Δ_o of docs/model.md §4 in robot base axes:
  Z_o along the feed, X_o radial (the edge at immersion 0); Y_o = Z_o × X_o.
- ``force_n``: the mean force **on the tool** over whole tooth periods [N], in the frame named by
  ``frame`` — ``"cut"`` (X_o, Y_o, Z_o, the default) or ``"base"`` (robot base axes).
- ``deflection_mm``: the measured static TCP deflection under that force [mm], same ``frame``.

Reading reports every problem with the file and line number; a record that cannot be a cut
(a radial depth beyond the diameter, a negative feed, an unknown verdict) is refused at read time,
never passed on to a fit.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from models.errors import CctmillError
from planner._atomic import write_text_atomic

__all__ = [
    "FORMAT",
    "FRAMES",
    "SOURCE_KINDS",
    "VERDICTS",
    "CutRecord",
    "RecordError",
    "dump_records",
    "dumps_record",
    "load_records",
    "parse_record",
    "write_records",
]

#: The format tag every record carries (a reader refuses other versions).
FORMAT = "cctmill-cut/1"
#: The verdicts a record may carry.
VERDICTS = ("stable", "chatter", "unknown")
#: The frames ``force_n`` and ``deflection_mm`` may be given in.
FRAMES = ("cut", "base")
#: Where a record came from (``source.kind``).
SOURCE_KINDS = ("supervisor", "hand", "simulated", "planned")
#: Milling modes (docs/model.md §4).
_MILLING = ("up", "down", "slot")
#: Directions must be orthogonal to this tolerance [-] (cosine of their angle); a hand-typed frame
#: with three decimals passes.
ORTHOGONALITY_TOL = 5e-3
#: Largest value of each key a cut may have, in the key's unit: anything above is a unit slip.
_SANE = {"ae_mm": 200.0, "ap_mm": 200.0, "rpm": 100_000.0, "feed_mm_s": 10_000.0,
         "diameter_mm": 200.0, "chatter_hz": 100_000.0}
_REQUIRED = ("joints_deg", "feed_dir", "radial_dir", "ap_mm", "rpm", "feed_mm_s", "milling",
             "tool", "verdict")
_OPTIONAL = ("format", "id", "ae_mm", "diameter_mm", "flutes", "material", "frame", "force_n",
             "force_std_n", "chatter_hz", "deflection_mm", "duration_s", "source")


class RecordError(CctmillError, ValueError):
    """A cut record file or record is not valid.

    Attributes:
        file: the records file (``"<records>"`` for records not read from a file).
        line: the 1-based line number (0: the file as a whole).
        problems: one line per problem, ``key: what is wrong; how to fix``.
    """

    def __init__(self, file: str, line: int, problems: list[str]) -> None:
        self.file, self.line, self.problems = file, line, problems
        where = f"{file}:{line}" if line else file
        super().__init__(f"{where}: " + "; ".join(problems))


@dataclass(frozen=True)
class CutRecord:
    """One cut a cell ran (or will run), as the records file holds it (units in the names).

    Attributes:
        joints_deg: A1..A6 [deg], (6,).
        feed_dir, radial_dir: Z_o and X_o in base axes, (3,) each, unit and orthogonal.
        ap_mm: axial depth [mm]; ae_mm: radial depth [mm] (None: a slot, the diameter).
        rpm: spindle speed [rev/min]; feed_mm_s: feed speed [mm/s].
        milling: ``"up"``, ``"down"`` or ``"slot"`` (docs/model.md §4).
        tool: the tool data name; diameter_mm, flutes: the tool's, when overridden (None: the
            tool data's).
        verdict: ``"stable"``, ``"chatter"`` or ``"unknown"``.
        material: the work material data name (None: the job's).
        frame: the frame of ``force_n`` and ``deflection_mm`` (``"cut"`` or ``"base"``).
        force_n: mean force on the tool [N], (3,), or None.
        force_std_n: the standard deviation of the mean force's measurement [N] (None: unknown;
            the fit estimates it from the residuals).
        chatter_hz: the chatter frequency the detector saw [Hz], or None.
        deflection_mm: measured static TCP deflection [mm], (3,), or None.
        duration_s: how long the cut ran [s], or None.
        id: a name for the record (messages use it), or None.
        source: where the record came from: ``{"kind": one of SOURCE_KINDS, ...}`` (file,
            section, time, detector: free keys of strings and numbers).
    """

    joints_deg: tuple[float, ...]
    feed_dir: tuple[float, ...]
    radial_dir: tuple[float, ...]
    ap_mm: float
    rpm: float
    feed_mm_s: float
    milling: str
    tool: str
    verdict: str
    ae_mm: float | None = None
    diameter_mm: float | None = None
    flutes: int | None = None
    material: str | None = None
    frame: str = "cut"
    force_n: tuple[float, ...] | None = None
    force_std_n: float | None = None
    chatter_hz: float | None = None
    deflection_mm: tuple[float, ...] | None = None
    duration_s: float | None = None
    id: str | None = None
    source: dict[str, Any] = field(default_factory=lambda: {"kind": "hand"})

    def __post_init__(self) -> None:
        problems = _problems(self)
        if problems:
            raise RecordError("<records>", 0, problems)

    # -- SI accessors ------------------------------------------------------------------------------

    @property
    def name(self) -> str:
        """The record's id, or a description of it for messages."""
        return self.id or f"{self.milling} ap {self.ap_mm:g} mm at {self.feed_mm_s:g} mm/s"

    def q(self) -> np.ndarray:
        """Joint angles [rad], (6,)."""
        return np.radians(np.asarray(self.joints_deg, float))

    def cut_axes(self) -> np.ndarray:
        """(X_o, Y_o, Z_o) as the columns of a 3×3 rotation, base axes."""
        z = np.asarray(self.feed_dir, float)
        x = np.asarray(self.radial_dir, float)
        z = z / np.linalg.norm(z)
        x = x - (x @ z) * z
        x = x / np.linalg.norm(x)
        return np.column_stack([x, np.cross(z, x), z])

    def force_cut(self) -> np.ndarray | None:
        """Mean force on the tool in (X_o, Y_o, Z_o) [N], (3,), or None."""
        if self.force_n is None:
            return None
        f = np.asarray(self.force_n, float)
        return f if self.frame == "cut" else self.cut_axes().T @ f

    def force_base(self) -> np.ndarray | None:
        """Mean force on the tool in base axes [N], (3,), or None."""
        if self.force_n is None:
            return None
        f = np.asarray(self.force_n, float)
        return f if self.frame == "base" else self.cut_axes() @ f

    def deflection_base(self) -> np.ndarray | None:
        """Measured static deflection in base axes [m], (3,), or None."""
        if self.deflection_mm is None:
            return None
        d = np.asarray(self.deflection_mm, float) * 1e-3
        return d if self.frame == "base" else self.cut_axes() @ d

    def feed(self) -> float:
        """Feed speed [m/s]."""
        return self.feed_mm_s * 1e-3

    def spindle_speed(self) -> float:
        """Spindle speed [rad/s]."""
        return self.rpm * 2.0 * math.pi / 60.0

    def as_json(self) -> dict[str, Any]:
        """The record as one JSON object (the file's form; None values left out)."""
        out: dict[str, Any] = {"format": FORMAT}
        for key in ("id", *_REQUIRED, *_OPTIONAL[2:]):
            value = getattr(self, key)
            if value is None or (key == "frame" and value == "cut"):
                continue
            out[key] = list(value) if isinstance(value, tuple) else value
        return out


def _number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _vector(v: Any, n: int) -> bool:
    return isinstance(v, (list, tuple)) and len(v) == n and all(_number(x) for x in v)


def _problems(r: CutRecord) -> list[str]:
    """Every problem of a record, in its file's terms."""
    out = []
    if not _vector(r.joints_deg, 6):
        out.append(f"joints_deg: need six numbers A1..A6 [deg], got {r.joints_deg!r}")
    for key in ("feed_dir", "radial_dir"):
        v = getattr(r, key)
        if not _vector(v, 3) or not np.linalg.norm(v) > 0:
            out.append(f"{key}: need three numbers (a direction in base axes), got {v!r}")
    if not out:
        z, x = np.asarray(r.feed_dir, float), np.asarray(r.radial_dir, float)
        cos = abs(z @ x) / (np.linalg.norm(z) * np.linalg.norm(x))
        if cos > ORTHOGONALITY_TOL:
            out.append(f"radial_dir: must be orthogonal to feed_dir (they are "
                       f"{np.degrees(np.arccos(min(cos, 1.0))):.2f} deg apart)")
    for key in ("ap_mm", "rpm", "feed_mm_s", "ae_mm", "diameter_mm", "chatter_hz", "duration_s",
                "force_std_n"):
        v = getattr(r, key)
        if v is None and key not in _REQUIRED:
            continue
        if not _number(v) or not v > 0:
            out.append(f"{key}: must be a positive number, got {v!r}")
        elif key in _SANE and v > _SANE[key]:
            out.append(f"{key}: {v:g} is beyond any milling value (at most {_SANE[key]:g}); "
                       "check the unit in the key's name")
    if r.milling not in _MILLING:
        out.append(f"milling: must be one of {', '.join(_MILLING)}, got {r.milling!r}")
    elif r.milling != "slot" and r.ae_mm is None:
        out.append("ae_mm: required for up and down milling (a slot needs none)")
    if r.verdict not in VERDICTS:
        out.append(f"verdict: must be one of {', '.join(VERDICTS)}, got {r.verdict!r}")
    if r.frame not in FRAMES:
        out.append(f"frame: must be one of {', '.join(FRAMES)}, got {r.frame!r}")
    for key in ("tool", "material", "id"):
        v = getattr(r, key)
        if v is not None and not (isinstance(v, str) and v):
            out.append(f"{key}: must be a non-empty string, got {v!r}")
    if r.flutes is not None and (isinstance(r.flutes, bool) or not isinstance(r.flutes, int)
                                 or not 1 <= r.flutes <= 12):
        out.append(f"flutes: must be a whole number 1..12, got {r.flutes!r}")
    for key in ("force_n", "deflection_mm"):
        v = getattr(r, key)
        if v is not None and not _vector(v, 3):
            out.append(f"{key}: need three numbers [x, y, z] in the record's frame, got {v!r}")
    if r.force_n is not None and not np.linalg.norm(r.force_n) > 0:
        out.append("force_n: a cut's mean force is not zero; leave the key out if not measured")
    src = r.source
    if not isinstance(src, dict) or src.get("kind") not in SOURCE_KINDS:
        out.append(f"source: must be a table with kind one of {', '.join(SOURCE_KINDS)}, "
                   f"got {src!r}")
    elif not all(isinstance(v, (str, int, float)) and not isinstance(v, bool)
                 for v in src.values()):
        out.append("source: values must be strings or numbers")
    return out


def _tupled(v: Any) -> Any:
    return tuple(v) if isinstance(v, list) else v


def parse_record(obj: Any, file: str = "<records>", line: int = 0) -> CutRecord:
    """A record from one parsed JSON object; :class:`RecordError` names every problem."""
    if not isinstance(obj, dict):
        raise RecordError(file, line, [f"a record is a JSON object {{...}}, got "
                                       f"{type(obj).__name__}"])
    problems = []
    fmt = obj.get("format", FORMAT)
    if fmt != FORMAT:
        problems.append(f"format: {fmt!r} is not {FORMAT!r} (this cctmill reads {FORMAT})")
    missing = [k for k in _REQUIRED if k not in obj]
    if missing:
        problems.append(f"missing {', '.join(missing)}; add them (docs/calibration.md)")
    unknown = sorted(set(obj) - set(_REQUIRED) - set(_OPTIONAL))
    if unknown:
        problems.append(f"unknown keys {', '.join(unknown)} (units are part of key names: "
                        "ae_mm, feed_mm_s, force_n, ...)")
    if problems:
        raise RecordError(file, line, problems)
    kwargs = {k: _tupled(v) for k, v in obj.items() if k != "format"}
    try:
        return CutRecord(**kwargs)
    except RecordError as e:
        raise RecordError(file, line, e.problems) from None
    except TypeError as e:  # a value of a type the checks did not foresee
        raise RecordError(file, line, [str(e)]) from None


def load_records(*paths: str | Path) -> list[CutRecord]:
    """Read records from JSON Lines files, in order.

    Raises:
        RecordError: a file cannot be read, a line is not JSON, or a record is not valid (the
            message names the file and line; every problem of that record).
    """
    out: list[CutRecord] = []
    for path in paths:
        p = Path(path)
        try:
            text = p.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as e:
            raise RecordError(str(p), 0, [f"cannot read: {getattr(e, 'strerror', None) or e}"]) from e
        for number, raw in enumerate(text.splitlines(), 1):
            line = raw.strip()
            if not line or line.startswith("#"):
                continue
            try:
                obj = json.loads(line)
            except json.JSONDecodeError as e:
                raise RecordError(str(p), number, [f"not JSON: {e.msg} at column {e.colno}"]) from None
            out.append(parse_record(obj, str(p), number))
    return out


def dumps_record(record: CutRecord) -> str:
    """One record as its line (no newline)."""
    return json.dumps(record.as_json(), separators=(", ", ": "), allow_nan=False)


def dump_records(records: Iterable[CutRecord]) -> str:
    """Records as JSON Lines text."""
    return "".join(dumps_record(r) + "\n" for r in records)


def write_records(path: str | Path, records: Sequence[CutRecord]) -> Path:
    """Write records as a JSON Lines file, atomically; return the path."""
    return write_text_atomic(path, dump_records(records))
