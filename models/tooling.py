"""Tools and work materials: the flat end mill (:class:`Tool`), the cutting coefficients of a work
material with it (:class:`Material`), and the shipped data files they are loaded from
(``models/data/tools/*.toml``, ``models/data/materials/*.toml``, read from the installed package with
:mod:`importlib.resources`; formats and sources in docs/library.md). The force models that use them
are in :mod:`models.cutting`.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field
from importlib import resources
from typing import Any

import numpy as np

from .errors import DataFileError, InputError, UnknownDataError

__all__ = [
    "COEFFICIENT_STATUSES",
    "KIENZLE_FIT_SAMPLES",
    "KIENZLE_REFERENCE_THICKNESS",
    "Material",
    "Tool",
    "available_materials",
    "available_tools",
    "kienzle_linear_fit",
    "load_material",
    "load_tool",
]

_COEFFICIENT_NAMES = ("k_tc", "k_rc", "k_ac", "k_te", "k_re", "k_ae")

#: How a material's coefficients were obtained (``status`` in its data file): ``identified`` by
#: cutting tests with the named tool, ``published`` (copied from the cited publication) or
#: ``derived`` (computed from published data by the stated method; not an end-mill identification).
COEFFICIENT_STATUSES = ("identified", "published", "derived")

#: The reference chip thickness of Kienzle's specific cutting force k_c1 [m] (1 mm).
KIENZLE_REFERENCE_THICKNESS = 1e-3
#: Chip thicknesses the linear fit of :func:`kienzle_linear_fit` samples (uniformly) [-].
KIENZLE_FIT_SAMPLES = 181


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
        description: what the material is (e.g. ``"Aluminium 7075-T6"``).
        status: how the values were obtained, one of :data:`COEFFICIENT_STATUSES` (``None``: not
            recorded).
        source: the publication (or measurement) the set comes from, in one line.
        conditions: the tool and cutting conditions the set belongs to, as the source states them.
        sources: per-coefficient source where it differs from ``source`` (key: coefficient name).
        derivation: for a ``derived`` set, the inputs of the derivation as the data file states
            them (e.g. ``kc1_N_per_mm2``, ``mc``, ``h_min_mm``, ``h_max_mm``, ``ratios_from``).

    The descriptive fields (``description`` … ``derivation``) do not take part in comparisons: two
    materials with equal coefficients and reference tool are equal.
    """

    name: str
    k_tc: float
    k_rc: float
    k_ac: float
    k_te: float
    k_re: float
    k_ae: float
    identified_with: str | None = None
    description: str | None = field(default=None, compare=False)
    status: str | None = field(default=None, compare=False)
    source: str | None = field(default=None, compare=False)
    conditions: str | None = field(default=None, compare=False)
    sources: dict[str, str] = field(default_factory=dict, compare=False)
    derivation: dict[str, Any] = field(default_factory=dict, compare=False)

    def __post_init__(self) -> None:
        for key in _COEFFICIENT_NAMES:
            value = getattr(self, key)
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise InputError(key, f"must be a number, got {value!r}")
            if not math.isfinite(value):
                raise InputError(key, f"must be finite, got {value!r}")
        if self.k_tc <= 0.0:
            raise InputError(
                "k_tc", f"the tangential cutting coefficient must be > 0, got {self.k_tc}"
            )
        if self.status is not None and self.status not in COEFFICIENT_STATUSES:
            raise InputError("status", f"must be one of {list(COEFFICIENT_STATUSES)}, "
                             f"got {self.status!r}")
        unknown = sorted(set(self.sources) - set(_COEFFICIENT_NAMES))
        if unknown:
            raise InputError("sources", f"names no coefficient: {unknown}; the coefficients are "
                             f"{list(_COEFFICIENT_NAMES)}")

    def coefficients(self) -> np.ndarray:
        """The six coefficients [k_tc, k_rc, k_ac, k_te, k_re, k_ae], N/m² then N/m, shape (6,)."""
        return np.array([float(getattr(self, key)) for key in _COEFFICIENT_NAMES])


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
        stick_out: length of the tool out of its holder [m] (``None``: not given); data for the
            user and the tool's own compliance, which the robot models do not include.
        corner_radius: corner radius [m] (0: sharp corner). The force models treat every tool
            as a flat end mill; a corner radius is recorded, not modelled.
        description: what the tool is, in one line.
        source: where its values come from (catalogue, chart), in one line.

    ``description`` and ``source`` do not take part in comparisons.
    """

    name: str
    flutes: int
    radius: float
    helix_angle: float
    feed_per_tooth_min: float | None = None
    feed_per_tooth_max: float | None = None
    spindle_speed_max: float | None = None
    stick_out: float | None = None
    corner_radius: float = 0.0
    description: str | None = field(default=None, compare=False)
    source: str | None = field(default=None, compare=False)

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
        for key in ("feed_per_tooth_min", "feed_per_tooth_max", "spindle_speed_max", "stick_out"):
            v = getattr(self, key)
            if v is not None and not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise InputError(key, f"must be a positive finite number or None, got {v!r}")
        c = self.corner_radius
        if isinstance(c, bool) or not (isinstance(c, (int, float)) and math.isfinite(c) and c >= 0):
            raise InputError("corner_radius", f"must be a finite length >= 0 [m], got {c!r}")
        lo, hi = self.feed_per_tooth_min, self.feed_per_tooth_max
        if lo is not None and hi is not None and not lo < hi:
            raise InputError("feed_per_tooth", f"the range must rise, got {lo!r}..{hi!r} m")

    @property
    def diameter(self) -> float:
        """Tool diameter 2R [m]."""
        return 2.0 * self.radius


def kienzle_linear_fit(kc1: float, mc: float, h_min: float, h_max: float) -> tuple[float, float]:
    """The linear edge-force model closest to Kienzle's law over a chip-thickness range.

    Kienzle: the force per unit width F/b = k_c1 · h · (h / h_0)^(−m_c) with h_0 = 1 mm
    (:data:`KIENZLE_REFERENCE_THICKNESS`). The mechanistic model writes F/b = K_c · h + K_e; this
    is its unweighted least-squares fit at :data:`KIENZLE_FIT_SAMPLES` thicknesses spread evenly
    over [h_min, h_max] (how the ``derived`` materials were made, docs/library.md).

    Args:
        kc1: specific cutting force at h = 1 mm [N/m²].
        mc: Kienzle exponent [-], in [0, 1).
        h_min, h_max: the chip-thickness range [m], 0 < h_min < h_max.

    Returns:
        (K_c [N/m²], K_e [N/m]).
    """
    if not (0.0 <= mc < 1.0):
        raise InputError("mc", f"must lie in [0, 1), got {mc!r}")
    if not (0.0 < h_min < h_max):
        raise InputError("h_min, h_max", f"need 0 < h_min < h_max, got {h_min!r}, {h_max!r} m")
    h = np.linspace(h_min, h_max, KIENZLE_FIT_SAMPLES)
    force = kc1 * h * (h / KIENZLE_REFERENCE_THICKNESS) ** (-mc)
    (k_c, k_e), *_ = np.linalg.lstsq(np.column_stack([h, np.ones_like(h)]), force, rcond=None)
    return float(k_c), float(k_e)


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

    The file holds ``k_tc``, ``k_rc``, ``k_ac`` [N/m²] and ``k_te``, ``k_re``, ``k_ae`` [N/m] (SI),
    and may hold ``identified_with_tool`` (a tool data file name), ``description``, ``status``
    (:data:`COEFFICIENT_STATUSES`), ``source``, ``conditions`` (strings), a ``[sources]`` table
    of per-coefficient sources and a ``[derivation]`` table (docs/library.md).

    Raises:
        UnknownDataError: no such material (the message lists the available ones).
        DataFileError: the file is malformed.
    """
    path, table = _read_table(
        "materials", "material", name, dict.fromkeys(_COEFFICIENT_NAMES, float),
        {"identified_with_tool": str, "description": str, "status": str, "source": str,
         "conditions": str, "sources": dict, "derivation": dict},
    )
    sources = table.get("sources", {})
    bad = [k for k, v in sources.items() if not isinstance(v, str)]
    if bad:
        raise DataFileError(path, f"[sources] values must be strings, not for {sorted(bad)}")
    try:
        return Material(name, *(float(table[key]) for key in _COEFFICIENT_NAMES),
                        identified_with=table.get("identified_with_tool"),
                        description=table.get("description"), status=table.get("status"),
                        source=table.get("source"), conditions=table.get("conditions"),
                        sources=dict(sources), derivation=dict(table.get("derivation", {})))
    except InputError as e:
        raise DataFileError(path, str(e)) from e


def load_tool(name: str) -> Tool:
    """Load a shipped tool.

    The file holds ``flutes`` (int), ``diameter_mm`` [mm] and ``helix_angle_deg`` [deg], and may
    hold ``feed_per_tooth_mm = [min, max]`` [mm], ``rpm_max`` [rev/min], ``stick_out_mm`` [mm],
    ``corner_radius_mm`` [mm] (default 0), ``description`` and ``source``; they are converted to
    SI here.

    Raises:
        UnknownDataError: no such tool (the message lists the available ones).
        DataFileError: the file is malformed.
    """
    required = {"flutes": int, "diameter_mm": float, "helix_angle_deg": float}
    path, table = _read_table("tools", "tool", name, required,
                              {"feed_per_tooth_mm": list, "rpm_max": float, "stick_out_mm": float,
                               "corner_radius_mm": float, "description": str, "source": str})
    fz = table.get("feed_per_tooth_mm")
    if fz is not None and not (len(fz) == 2 and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) for v in fz)):
        raise DataFileError(path, f"feed_per_tooth_mm must be [min, max] in mm, got {fz!r}")
    corner_mm = float(table.get("corner_radius_mm", 0.0))
    if corner_mm > float(table["diameter_mm"]) / 2.0:
        raise DataFileError(path, f"corner_radius_mm = {corner_mm:g} is more than half the "
                            f"diameter ({table['diameter_mm']:g} mm)")
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
            stick_out=(None if "stick_out_mm" not in table
                       else float(table["stick_out_mm"]) * 1e-3),
            corner_radius=corner_mm * 1e-3,
            description=table.get("description"),
            source=table.get("source"),
        )
    except InputError as e:
        raise DataFileError(path, str(e)) from e
