"""What a reading noticed, for people: plausibility checks on a read program and its warnings
grouped by kind (what ``cctmill plan`` prints, ``plan.json`` keeps as ``import_warnings`` and
the report shows in its headline box).

The checks catch the mistakes no reader can see line by line: a program in mm read as inches
(or the other way), feeds no milling robot runs, a part far larger than any cell. Each is a
:class:`~robot_io.toolpath.ToolpathWarning` of category ``plausibility`` with the fix.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

from robot_io.options import fix
from robot_io.toolpath import MoveKind, SourceRef, Toolpath, ToolpathWarning, summarize

__all__ = [
    "FEED_PLAUSIBLE_MAX",
    "INCH_EXTENT_SUSPECT",
    "MM_EXTENT_SUSPECT",
    "MM_FEED_SUSPECT",
    "REACH_DEFAULT",
    "WarningGroup",
    "group_warnings",
    "plausibility_warnings",
]

#: Feeds above this [m/s] (30 m/min) are beyond what a milling robot runs (spindle and arm); a
#: program asking for more is most likely in the wrong units.
FEED_PLAUSIBLE_MAX = 0.5
#: Reach [m] of the largest arms used for milling (≈ 3.9 m); a program wider than twice the reach
#: of the cell cannot be one setup of a robot cell.
REACH_DEFAULT = 4.0
#: An inch program whose bounding box is wider than this [m] is suspected of being written in mm.
INCH_EXTENT_SUSPECT = 3.0
#: A mm program narrower than this [m] whose feeds all stay below :data:`MM_FEED_SUSPECT` is
#: suspected of being written in inches (an inch program read as mm shrinks 25.4 times).
MM_EXTENT_SUSPECT = 2e-3
#: See :data:`MM_EXTENT_SUSPECT` [m/s] (25 mm/min: 1 in/min read as mm).
MM_FEED_SUSPECT = 25.4e-3 / 60.0


@dataclass(frozen=True)
class WarningGroup:
    """All warnings of one kind from one file.

    Attributes:
        kind: the warning category (``"cutter_compensation"``, ``"unknown_record"``, …).
        count: how many there were (also those beyond a reader's per-kind cap).
        first: where the first one is.
        message: the first one's message.
    """

    kind: str
    count: int
    first: SourceRef
    message: str

    def as_json(self) -> dict[str, Any]:
        """``{"kind", "count", "first", "message"}`` as plan.json keeps it."""
        return {"kind": self.kind, "count": self.count, "first": str(self.first),
                "message": self.message}

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> WarningGroup:
        """The inverse of :meth:`as_json`."""
        file, _, rest = str(d["first"]).rpartition(":")
        file, _, line = file.rpartition(":")
        try:
            src = SourceRef(file, int(line), int(rest))
        except ValueError:
            src = SourceRef(str(d["first"]), 0, 0)
        return cls(kind=str(d["kind"]), count=int(d["count"]), first=src,
                   message=str(d["message"]))

    def __str__(self) -> str:
        more = f" ({self.count} in all)" if self.count > 1 else ""
        return f"{self.first}: {self.message}{more}"


def group_warnings(toolpaths: Iterable[Toolpath]) -> tuple[WarningGroup, ...]:
    """The warnings of each toolpath grouped by kind, in order of first appearance."""
    out: list[WarningGroup] = []
    for tp in toolpaths:
        totals = dict(tp.meta.get("warning_counts") or {})
        seen: dict[str, list[ToolpathWarning]] = {}
        for w in tp.warnings:
            seen.setdefault(w.category, []).append(w)
        for kind, ws in seen.items():
            out.append(WarningGroup(kind=kind, count=max(int(totals.get(kind, 0)), len(ws)),
                                    first=ws[0].source, message=ws[0].message))
    return tuple(out)


def _width(bbox: list[list[float]] | None) -> float:
    if not bbox:
        return 0.0
    return max(hi - lo for lo, hi in zip(*bbox, strict=True))


def plausibility_warnings(tp: Toolpath, reach: float = REACH_DEFAULT,
                          summary: dict[str, Any] | None = None) -> list[ToolpathWarning]:
    """Warnings for a program that is implausible as a robot-milling job (each with its fix).

    Args:
        tp: the program read.
        reach: the cell's reach [m] (default :data:`REACH_DEFAULT`, the largest milling arms).
        summary: :func:`~robot_io.toolpath.summarize` of ``tp`` when already made.
    """
    s = summary if summary is not None else summarize(tp)
    where = SourceRef(tp.file, 1, 0)
    fastest = None
    fmax = 0.0
    for m in tp.moves:
        if m.kind != MoveKind.RAPID and m.feed is not None and m.feed > fmax:
            fastest, fmax = m, m.feed
    out: list[ToolpathWarning] = []
    width = _width(s["bbox_m"])
    units = tp.units
    declare = tp.format != "krl"
    if units == "inch" and (width > INCH_EXTENT_SUSPECT or fmax > FEED_PLAUSIBLE_MAX):
        out.append(ToolpathWarning(where, (
            f"the program is in inches but {width:.1f} m wide with feeds up to "
            f"{fmax * 60:.1f} m/min: its numbers look like millimetres; make it G21 / UNITS/MM "
            "in the program"
            + (f", or read it with {fix('default_units', 'mm')} if it declares no units"
               if declare else "")), "plausibility"))
    elif width > 2.0 * reach:
        out.append(ToolpathWarning(where, (
            f"the program is {width:.1f} m wide, more than twice the reach of a robot cell "
            f"({reach:.1f} m): check its units ({units}) and that it is one setup"),
            "plausibility"))
    elif units == "mm" and 0.0 < width < MM_EXTENT_SUSPECT and 0.0 < fmax < MM_FEED_SUSPECT:
        out.append(ToolpathWarning(where, (
            f"the program is in mm but only {width * 1e3:.3f} mm wide with feeds up to "
            f"{fmax * 6e4:.2f} mm/min: its numbers look like inches; make it G20 / UNITS/INCHES "
            "in the program"
            + (f", or read it with {fix('default_units', 'inch')} if it declares no units"
               if declare else "")), "plausibility"))
    if fastest is not None and fmax > FEED_PLAUSIBLE_MAX and units != "inch":
        out.append(ToolpathWarning(fastest.source, (
            f"feed {fmax * 60:.1f} m/min is above {FEED_PLAUSIBLE_MAX * 60:.0f} m/min, more than "
            "a milling robot runs: check the program's units and its F words"), "plausibility"))
    return out
