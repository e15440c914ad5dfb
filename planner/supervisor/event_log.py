"""The supervisor's decision log: JSON lines, one object per decision.

Each line holds at least ``t_s`` (supervisor clock [s]), ``section`` (the running section's
number, from 1, as plan.json, the report and the KRL program number it), ``band`` (largest
|detail| of the step, or null), ``ucl`` (the control limit in force), ``override`` [percent],
``status`` and ``reason`` (in words). The file is opened line-buffered and appended to.

Writing is split in two so that a supervisor step never waits for a disk: :meth:`EventLog.write`
(called inside the step) only appends the record to a bounded in-memory list; :meth:`EventLog.drain`
serialises and writes what is pending, and the loop calls it after the step, in the rest of the
cycle. (A writer thread was tried first: waking it from the step hands the GIL over and stretched
deterministic steps to the 5 ms switch interval — see ``benchmarks/supervisor_latency.py``.) A full
list drops new records and counts them in ``dropped``.
"""

from __future__ import annotations

import json
import math
import os
from typing import Any

__all__ = ["EventLog"]

#: Records held between drains at most; later ones are dropped (and counted).
PENDING_RECORDS = 100_000


def _clean(v: Any) -> Any:
    if isinstance(v, float) and not math.isfinite(v):
        return None
    return v


class EventLog:
    """Append decision records to ``path`` as JSON lines (``path=None``: keep them in memory only).

    Attributes:
        records: the last records written (in-memory copy, bounded to ``keep``), newest last.
        dropped: records lost because too many were pending, or could not be written.
    """

    def __init__(self, path: str | os.PathLike | None = None, keep: int = 10_000) -> None:
        self.path = path
        self.records: list[dict[str, Any]] = []
        self.dropped = 0
        self._keep = keep
        self._pending: list[dict[str, Any]] = []
        self._fh = (open(path, "a", buffering=1, encoding="utf-8")  # noqa: SIM115
                    if path is not None else None)

    def write(self, record: dict[str, Any]) -> None:
        """Queue one record (O(1), no I/O); never raises."""
        if len(self._pending) >= PENDING_RECORDS:
            self.dropped += 1
            return
        self._pending.append(record)

    def drain(self) -> int:
        """Write the pending records; return how many. Never raises."""
        pending, self._pending = self._pending, []
        for rec in pending:
            if self._fh is not None:
                try:
                    self._fh.write(json.dumps({k: _clean(v) for k, v in rec.items()}) + "\n")
                except (OSError, TypeError, ValueError):
                    self.dropped += 1
        self.records.extend(pending)
        if len(self.records) > self._keep:
            del self.records[: len(self.records) - self._keep]
        return len(pending)

    def flush(self) -> None:
        """Write everything pending."""
        self.drain()

    def close(self) -> None:
        """Write what is pending and close the file; idempotent."""
        self.drain()
        if self._fh is not None:
            self._fh.close()
            self._fh = None
