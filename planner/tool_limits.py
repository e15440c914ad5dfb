"""What the cutter allows, and what the model knows about it: the tool maker's chip-load range and
speed rating, and the tool the cutting coefficients were identified with (docs/model.md §8).

* The spindle speed may not exceed the tool's ``rpm_max`` (the plan is refused).
* No cut runs above the tool's largest feed per tooth: the feed cap f = f_z,max · N · n / 60 is
  applied to every ceiling (binding ``tool``).
* Cut sections planned below the smallest feed per tooth (the edge rubs instead of cutting) are
  warned about; the process model says nothing about rubbing.
* Cutting coefficients belong to the tool–material pair they were identified with: a job whose
  tool differs from that one in name, diameter or flutes is warned about (the forces are an
  extrapolation). A job that overrides a tool file's diameter or flutes makes another tool: the
  file's chip-load range and speed rating do not apply to it and are dropped, with a warning.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from models.errors import DataFileError, InputError, UnknownDataError
from models.tooling import Material, Tool, load_tool

__all__ = [
    "TOOL_BINDING",
    "PlanWarning",
    "check_spindle_speed",
    "job_tool",
    "rubbing_warnings",
    "tool_feed_cap",
    "tool_warnings",
]

#: The binding label of a feed held at the tool's largest feed per tooth.
TOOL_BINDING = "tool"


@dataclass(frozen=True)
class PlanWarning:
    """Something a plan's user must know that does not stop the plan.

    Attributes:
        kind: short key (``"coefficients"``, ``"tool_data"``, ``"rubbing"``, ``"engagement"``).
        message: what, and what to do.
    """

    kind: str
    message: str

    def as_json(self) -> dict[str, str]:
        """``{"kind", "message"}`` as plan.json keeps it."""
        return {"kind": self.kind, "message": self.message}

    @classmethod
    def from_json(cls, d: dict) -> PlanWarning:
        """The inverse of :meth:`as_json`."""
        return cls(kind=str(d["kind"]), message=str(d["message"]))

    def __str__(self) -> str:
        return f"{self.kind}: {self.message}"


def job_tool(name: str, radius: float | None, flutes: int | None) -> tuple[Tool, list[PlanWarning]]:
    """The tool data file ``name`` with a job's diameter/flutes overrides (``radius`` [m]).

    Returns:
        the tool, and a warning when an override drops the file's chip-load range and rating.
    """
    base = load_tool(name)
    r = base.radius if radius is None else radius
    z = base.flutes if flutes is None else flutes
    if math.isclose(r, base.radius, rel_tol=1e-9) and z == base.flutes:
        return base, []
    tool = replace(base, radius=r, flutes=z, feed_per_tooth_min=None, feed_per_tooth_max=None,
                   spindle_speed_max=None)
    out = []
    if base.feed_per_tooth_max is not None or base.spindle_speed_max is not None:
        out.append(PlanWarning("tool_data", (
            f"the job makes {name} a {2e3 * r:g} mm, {z}-flute tool: the file's chip-load range "
            f"and speed rating (for {base.diameter * 1e3:g} mm, {base.flutes} flutes) do not "
            "apply and no tool-side feed limit is enforced; add a data file for this tool")))
    return tool, out


def check_spindle_speed(tool: Tool, spindle_speed: float) -> None:
    """Raise :class:`InputError` when ``spindle_speed`` [rad/s] exceeds the tool's rating."""
    if tool.spindle_speed_max is not None and spindle_speed > tool.spindle_speed_max * (1 + 1e-12):
        rpm, top = spindle_speed * 60 / (2 * math.pi), tool.spindle_speed_max * 60 / (2 * math.pi)
        raise InputError("spindle.rpm", f"{rpm:g} rpm is above the rating of tool {tool.name} "
                         f"({top:g} rpm): lower [spindle] rpm or use another tool")


def tool_feed_cap(tool: Tool, spindle_speed: float) -> float:
    """The largest feed [m/s] the tool's chip load allows at ``spindle_speed`` [rad/s]
    (``inf`` without a rating): f_z,max · N · ω / 2π."""
    if tool.feed_per_tooth_max is None:
        return math.inf
    return tool.feed_per_tooth_max * tool.flutes * spindle_speed / (2.0 * math.pi)


def tool_warnings(tool: Tool, material: Material) -> list[PlanWarning]:
    """A warning when the material's coefficients were identified with another tool."""
    if material.identified_with is None:
        return [PlanWarning("coefficients", (
            f"the cutting coefficients of {material.name} do not say which tool they were "
            "identified with: the forces may be an extrapolation"))]
    try:
        ref = load_tool(material.identified_with)
    except (UnknownDataError, DataFileError):  # a missing reference tool is itself the warning
        return [PlanWarning("coefficients", (
            f"the cutting coefficients of {material.name} were identified with tool "
            f"{material.identified_with!r}, which has no data file: the forces may be an "
            "extrapolation"))]
    same = (ref.name == tool.name and math.isclose(ref.radius, tool.radius, rel_tol=1e-9)
            and ref.flutes == tool.flutes)
    if same:
        return []
    return [PlanWarning("coefficients", (
        f"the cutting coefficients of {material.name} were identified with {ref.name} "
        f"({ref.diameter * 1e3:g} mm, {ref.flutes} flutes); this job cuts with "
        f"{tool.diameter * 1e3:g} mm, {tool.flutes} flutes: forces, deflection and the chatter "
        "margin are extrapolated — identify the coefficients with this tool "
        "(docs/model.md §4)"))]


def rubbing_warnings(tool: Tool, spindle_speed: float, feeds: np.ndarray,
                     lines: list[tuple[int, int]]) -> list[PlanWarning]:
    """A warning for cut sections planned below the tool's smallest feed per tooth.

    Args:
        tool: the cutter.
        spindle_speed: [rad/s].
        feeds: the cut sections' feeds [m/s], (k,).
        lines: (first, last) program line of each of those sections.
    """
    if tool.feed_per_tooth_min is None or spindle_speed <= 0 or len(feeds) == 0:
        return []
    fz = np.asarray(feeds, float) * 2.0 * math.pi / (tool.flutes * spindle_speed)
    low = np.flatnonzero(fz < tool.feed_per_tooth_min * (1 - 1e-9))
    if low.size == 0:
        return []
    k = int(low[np.argmin(fz[low])])
    return [PlanWarning("rubbing", (
        f"{low.size} cut section{'s' if low.size > 1 else ''} run below the smallest feed per "
        f"tooth of {tool.name} ({tool.feed_per_tooth_min * 1e3:g} mm), the lowest "
        f"{fz[k] * 1e3:.3f} mm at lines {lines[k][0]}-{lines[k][1]}: the edge rubs rather than "
        "cuts there; lower [spindle] rpm (the feed per tooth grows as the spindle slows) or "
        "cut shallower so the process allows a higher feed"))]
