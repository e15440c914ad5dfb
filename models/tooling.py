"""Tools and work materials: the flat end mill (:class:`Tool`), the cutting coefficients of a work
material with it (:class:`Material`), and the shipped data files they are loaded from
(``models/data/tools/*.toml``, ``models/data/materials/*.toml``, read from the installed package with
:mod:`importlib.resources`). The force models that use them are in :mod:`models.cutting`.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass
from importlib import resources
from typing import Any

import numpy as np

from .errors import DataFileError, InputError, UnknownDataError

__all__ = [
    "Material",
    "Tool",
    "available_materials",
    "available_tools",
    "load_material",
    "load_tool",
]

_COEFFICIENT_NAMES = ("k_tc", "k_rc", "k_ac", "k_te", "k_re", "k_ae")


@dataclass(frozen=True)
class Material:
    """Mechanistic cutting coefficients of a work material with a given tool (docs/model.md §4).

    The coefficients belong to the tool–material pair they were identified with.

    Attributes:
        name: identifier (the data file's stem, e.g. ``"al6061"``).
        k_tc, k_rc, k_ac: tangential, radial, axial cutting (shear) coefficients [N/m²].
        k_te, k_re, k_ae: tangential, radial, axial edge coefficients [N/m].
        identified_with: name of the tool data file the coefficients were identified with
            (``None``: not recorded); a plan with another tool says it extrapolates them.
    """

    name: str
    k_tc: float
    k_rc: float
    k_ac: float
    k_te: float
    k_re: float
    k_ae: float
    identified_with: str | None = None

    def __post_init__(self) -> None:
        for field in _COEFFICIENT_NAMES:
            value = getattr(self, field)
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise InputError(field, f"must be a number, got {value!r}")
            if not math.isfinite(value):
                raise InputError(field, f"must be finite, got {value!r}")
        if self.k_tc <= 0.0:
            raise InputError(
                "k_tc", f"the tangential cutting coefficient must be > 0, got {self.k_tc}"
            )

    def coefficients(self) -> np.ndarray:
        """The six coefficients [k_tc, k_rc, k_ac, k_te, k_re, k_ae], N/m² then N/m, shape (6,)."""
        return np.array([float(getattr(self, field)) for field in _COEFFICIENT_NAMES])


@dataclass(frozen=True)
class Tool:
    """A flat end mill.

    Attributes:
        name: identifier (the data file's stem, e.g. ``"em25_2f"``).
        flutes: number of flutes N [-].
        radius: tool radius R [m].
        helix_angle: helix angle [rad]; used only by the time-domain model (docs/model.md §6).
        feed_per_tooth_min, feed_per_tooth_max: the tool maker's chip-load range [m] (``None``:
            not given); below the minimum the edge rubs, above the maximum it breaks.
        spindle_speed_max: highest spindle speed the tool is rated for [rad/s] (``None``: not
            given).
    """

    name: str
    flutes: int
    radius: float
    helix_angle: float
    feed_per_tooth_min: float | None = None
    feed_per_tooth_max: float | None = None
    spindle_speed_max: float | None = None

    def __post_init__(self) -> None:
        if isinstance(self.flutes, bool) or not isinstance(self.flutes, int) or self.flutes < 1:
            raise InputError("flutes", f"must be a whole number >= 1, got {self.flutes!r}")
        if (
            not (isinstance(self.radius, (int, float)) and math.isfinite(self.radius))
            or self.radius <= 0
        ):
            raise InputError("radius", f"must be a finite length > 0 [m], got {self.radius!r}")
        angle = self.helix_angle
        if not (isinstance(angle, (int, float)) and 0.0 <= angle < math.pi / 2):
            raise InputError("helix_angle", f"must lie in [0, pi/2) rad, got {angle!r}")
        for key in ("feed_per_tooth_min", "feed_per_tooth_max", "spindle_speed_max"):
            v = getattr(self, key)
            if v is not None and not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise InputError(key, f"must be a positive finite number or None, got {v!r}")
        lo, hi = self.feed_per_tooth_min, self.feed_per_tooth_max
        if lo is not None and hi is not None and not lo < hi:
            raise InputError("feed_per_tooth", f"the range must rise, got {lo!r}..{hi!r} m")

    @property
    def diameter(self) -> float:
        """Tool diameter 2R [m]."""
        return 2.0 * self.radius


def _data_dir(kind: str) -> Any:
    return resources.files(__package__ or "models").joinpath("data", kind)


def _available(kind: str) -> list[str]:
    folder = _data_dir(kind)
    if not folder.is_dir():
        return []
    return sorted(
        entry.name[: -len(".toml")] for entry in folder.iterdir() if entry.name.endswith(".toml")
    )


def _read_table(kind: str, singular: str, name: str, required: dict[str, type],
                optional: dict[str, type] | None = None) -> tuple[str, dict]:
    """Read ``data/<kind>/<name>.toml``; check it holds the ``required`` keys, maybe some of the
    ``optional`` ones, nothing else, each of its type."""
    available = _available(kind)
    if name not in available:
        raise UnknownDataError(singular, name, available)
    entry = _data_dir(kind).joinpath(f"{name}.toml")
    path = str(entry)
    try:
        table = tomllib.loads(entry.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
        raise DataFileError(path, f"not valid TOML: {e}") from e
    optional = optional or {}
    missing = sorted(set(required) - set(table))
    unknown = sorted(set(table) - set(required) - set(optional))
    if missing or unknown:
        problems = []
        if missing:
            problems.append(f"missing keys {missing}")
        if unknown:
            problems.append(f"unknown keys {unknown}")
        raise DataFileError(path, "; ".join(problems) + f"; expected {sorted(required)}"
                            + (f" and maybe {sorted(optional)}" if optional else ""))
    for key, kind_type in {**required, **optional}.items():
        if key not in table:
            continue
        value = table[key]
        accepted = (int, float) if kind_type is float else kind_type  # TOML writes 30.0 as 30
        if isinstance(value, bool) or not isinstance(value, accepted):
            wanted = "a number" if kind_type is float else f"of type {kind_type.__name__}"
            raise DataFileError(path, f"{key} must be {wanted}, got {value!r}")
    return path, table


def available_materials() -> list[str]:
    """Names of the shipped materials (``models/data/materials/*.toml``), sorted."""
    return _available("materials")


def available_tools() -> list[str]:
    """Names of the shipped tools (``models/data/tools/*.toml``), sorted."""
    return _available("tools")


def load_material(name: str) -> Material:
    """Load a shipped material's cutting coefficients.

    The file holds ``k_tc``, ``k_rc``, ``k_ac`` [N/m²] and ``k_te``, ``k_re``, ``k_ae`` [N/m] (SI).

    Raises:
        UnknownDataError: no such material (the message lists the available ones).
        DataFileError: the file is malformed.
    """
    path, table = _read_table(
        "materials", "material", name, dict.fromkeys(_COEFFICIENT_NAMES, float),
        {"identified_with_tool": str},
    )
    try:
        return Material(name, *(float(table[key]) for key in _COEFFICIENT_NAMES),
                        identified_with=table.get("identified_with_tool"))
    except InputError as e:
        raise DataFileError(path, str(e)) from e


def load_tool(name: str) -> Tool:
    """Load a shipped tool.

    The file holds ``flutes`` (int), ``diameter_mm`` [mm] and ``helix_angle_deg`` [deg], and may
    hold ``feed_per_tooth_mm = [min, max]`` [mm] and ``rpm_max`` [rev/min]; they are converted to
    SI here.

    Raises:
        UnknownDataError: no such tool (the message lists the available ones).
        DataFileError: the file is malformed.
    """
    required = {"flutes": int, "diameter_mm": float, "helix_angle_deg": float}
    path, table = _read_table("tools", "tool", name, required,
                              {"feed_per_tooth_mm": list, "rpm_max": float})
    fz = table.get("feed_per_tooth_mm")
    if fz is not None and not (len(fz) == 2 and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) for v in fz)):
        raise DataFileError(path, f"feed_per_tooth_mm must be [min, max] in mm, got {fz!r}")
    try:
        return Tool(
            name=name,
            flutes=table["flutes"],
            radius=float(table["diameter_mm"]) * 1e-3 / 2.0,
            helix_angle=math.radians(float(table["helix_angle_deg"])),
            feed_per_tooth_min=None if fz is None else float(fz[0]) * 1e-3,
            feed_per_tooth_max=None if fz is None else float(fz[1]) * 1e-3,
            spindle_speed_max=(None if "rpm_max" not in table
                               else float(table["rpm_max"]) * 2.0 * math.pi / 60.0),
        )
    except InputError as e:
        raise DataFileError(path, str(e)) from e

