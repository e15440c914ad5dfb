"""Sections: contiguous stretches of path samples that run at one feed.

A sample belongs to the step that *arrives* at it: sample k is cut at its section's feed over the
step of length ``ds[k] = s[k] − s[k−1]`` (``ds[0] = 0``), so a section's length and time are sums
over its samples. Kinds (codes of :data:`planner.plan_file.KINDS`):

* ``cut`` — an engaged sample the point model describes (side milling);
* ``air`` — a feed move the model does not describe: in air or cleared space, or a plunge;
* ``rapid`` — a rapid (G0) move.

Sections never mix kinds. The optimiser and the thesis baseline split the ``cut`` runs; ``air`` and
``rapid`` runs are one section each.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

__all__ = [
    "AIR",
    "CUT",
    "RAPID",
    "Section",
    "kind_runs",
    "merge_empty_sections",
    "sample_kinds",
    "section_of_samples",
    "split_by_length",
    "step_lengths",
]

CUT, AIR, RAPID = 0, 1, 2


@dataclass
class Section:
    """One stretch of samples ``[start, stop)`` at one feed.

    Attributes:
        start, stop: sample range.
        kind: :data:`CUT`, :data:`AIR` or :data:`RAPID`.
        feed: path speed bound [m/s].
        binding: what limits the feed (see :data:`planner.plan_file.BINDINGS`).
        note: a short human reason beyond ``binding`` (may be empty).
    """

    start: int
    stop: int
    kind: int
    feed: float = math.nan
    binding: str = ""
    note: str = ""


def step_lengths(s: np.ndarray) -> np.ndarray:
    """ds[k] = s[k] − s[k−1], ds[0] = 0 [m], shape (n,)."""
    return np.concatenate([[0.0], np.diff(s)])


def merge_empty_sections(sections: list[Section], ds: np.ndarray) -> list[Section]:
    """``sections`` (in path order) with every section that adds no path (its samples' steps
    sum to 0 m: a zero-length move, a repeated point) joined to the section before it (the
    first one to the section after it). Such a section takes no time and cuts nothing; on its
    own it would be a 0 m section in the plan and the KRL program."""
    out: list[Section] = []
    pending: Section | None = None     # empty sections before the first non-empty one
    for sec in sections:
        empty = sec.stop <= sec.start or float(ds[sec.start:sec.stop].sum()) <= 0.0
        if not empty:
            if pending is not None:
                sec = replace(sec, start=pending.start)
                pending = None
            out.append(sec)
        elif out:
            out[-1] = replace(out[-1], stop=sec.stop)
        elif pending is None:
            pending = sec
        else:
            pending = replace(pending, stop=sec.stop)
    if pending is not None:         # nothing but empty sections: keep them as one
        out.append(pending)
    return out


def sample_kinds(n: int, engaged: np.ndarray, cutting: np.ndarray) -> np.ndarray:
    """Kind code per sample, shape (n,).

    Args:
        n: number of samples.
        engaged: indices of the engaged samples.
        cutting: (n,) bool, True where the sample ends a feed move (not a rapid).
    """
    kinds = np.where(np.asarray(cutting, bool), AIR, RAPID).astype(int)
    kinds[np.asarray(engaged, int)] = CUT
    if n:
        kinds[0] = kinds[1] if n > 1 else kinds[0]  # sample 0 has no step: take its successor's
    return kinds


def kind_runs(kinds: np.ndarray) -> list[tuple[int, int, int]]:
    """Maximal runs of equal kind, ``(start, stop, kind)`` in order."""
    if kinds.size == 0:
        return []
    cuts = np.flatnonzero(np.diff(kinds)) + 1
    starts = np.concatenate([[0], cuts])
    stops = np.concatenate([cuts, [kinds.size]])
    return [(int(a), int(b), int(kinds[a])) for a, b in zip(starts, stops, strict=True)]


def split_by_length(ds: np.ndarray, start: int, stop: int, length: float) -> list[tuple[int, int]]:
    """Cut ``[start, stop)`` into pieces at least ``length`` long [m], in order.

    Pieces close as soon as they reach ``length``; a shorter remainder joins the last piece. A run
    shorter than ``length`` is one piece.
    """
    pieces: list[tuple[int, int]] = []
    a, acc = start, 0.0
    for k in range(start, stop):
        acc += ds[k]
        if acc >= length and k + 1 < stop:
            pieces.append((a, k + 1))
            a, acc = k + 1, 0.0
    if a < stop:
        if pieces and acc < length:
            pieces[-1] = (pieces[-1][0], stop)
        else:
            pieces.append((a, stop))
    return pieces


def section_of_samples(sections: list[Section], n: int) -> np.ndarray:
    """Section index of every sample, shape (n,)."""
    out = np.full(n, -1, dtype=int)
    for i, sec in enumerate(sections):
        out[sec.start:sec.stop] = i
    return out
