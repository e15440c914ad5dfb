"""Page layout of long KRL programs (private helper of ``robot_io.krl``, whose docstring states the
rules): section folds as lines, packed into pages that break at section boundaries, a section
longer than a page split before a LIN with its fold reopened and its ``$VEL.CP`` re-issued (the
section's, then the last scaled one before the split, so a feed profile goes on at its speed).
"""

from __future__ import annotations

from dataclasses import dataclass

from models.errors import CctmillError

__all__ = ["NoPageBreakError", "PageSection", "paginate", "section_lines"]


class NoPageBreakError(CctmillError):
    """A page's worth of a section holds no place to break (only CIRCs)."""

    def __init__(self, section: int) -> None:
        super().__init__(f"section {section}: no LIN to break a page at")
        self.section = section


@dataclass
class PageSection:
    """A section rendered: fold title, motion lines, where a page may break."""

    number: int
    title: str
    comment: str
    head_tail: list[str]          # marker and $VEL.CP lines
    body: list[str]
    breakable: list[bool]         # a page may start at body[i]


def section_lines(s: PageSection, lo: int, hi: int, continued: bool) -> list[str]:
    title = s.title + (" (continued)" if continued else "")
    lines = [f";FOLD {title}"]
    if continued:
        lines.append(f"; section {s.number} is longer than a page: split before a LIN, "
                     "$VEL.CP re-issued")
    elif s.comment:
        lines.append(s.comment)
    lines += s.head_tail
    if continued:
        last = next((x for x in reversed(s.body[:lo]) if x.startswith("$VEL.CP")), None)
        if last is not None:
            lines.append(last)
    lines += s.body[lo:hi] + [f";ENDFOLD (section {s.number})"]
    return lines


def paginate(secs: list[PageSection], budget: int) -> list[list[str]]:
    """Pack section folds into pages of at most ``budget`` lines (see the module docstring)."""
    pages: list[list[str]] = []
    cur: list[str] = []
    for s in secs:
        whole = section_lines(s, 0, len(s.body), False)
        if len(cur) + len(whole) <= budget:
            cur += whole
            continue
        if len(whole) <= budget:
            pages.append(cur)
            cur = list(whole)
            continue
        i = 0
        while i < len(s.body):
            overhead = len(section_lines(s, i, i, i > 0))
            room = budget - len(cur) - overhead
            j = min(len(s.body), i + max(room, 0))
            if j < len(s.body):
                while j > i and not s.breakable[j]:
                    j -= 1
            if j <= i:
                if not cur:     # a page's worth of CIRCs in a row: no place to break
                    raise NoPageBreakError(s.number)
                pages.append(cur)
                cur = []
                continue
            cur += section_lines(s, i, j, i > 0)
            i = j
            if i < len(s.body):
                pages.append(cur)
                cur = []
    if cur:
        pages.append(cur)
    return [p for p in pages if p]
