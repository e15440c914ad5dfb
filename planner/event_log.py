"""The supervisor's decision log: JSON lines, one object per decision.

Each line holds at least ``t_s`` (supervisor clock [s]), ``section``, ``band`` (largest |detail| of
the step, or null), ``ucl`` (the control limit in force), ``override`` [percent], ``status`` and
``reason`` (in words). Writing happens on a background thread, so a slow disk never stretches a
supervisor step: :meth:`EventLog.write` only queues the record (a full queue drops it and counts it
in ``dropped``). The file is opened line-buffered and appended to.
"""

from __future__ import annotations

import json
import math
import os
import queue
import threading
from typing import Any

__all__ = ["EventLog"]

#: Records queued at most before new ones are dropped (and counted).
QUEUE_RECORDS = 100_000


def _clean(v: Any) -> Any:
    if isinstance(v, float) and not math.isfinite(v):
        return None
    return v


class EventLog:
    """Append decision records to ``path`` as JSON lines (``path=None``: keep them in memory only).

    Attributes:
        records: the last records written (in-memory copy, bounded to ``keep``), newest last.
        dropped: records lost because the queue was full.
    """

    def __init__(self, path: str | os.PathLike | None = None, keep: int = 10_000) -> None:
        self.path = path
        self.records: list[dict[str, Any]] = []
        self.dropped = 0
        self._keep = keep
        self._q: queue.Queue[dict[str, Any] | None] = queue.Queue(QUEUE_RECORDS)
        self._fh = (open(path, "a", buffering=1, encoding="utf-8")  # noqa: SIM115
                    if path is not None else None)
        self._thread = threading.Thread(target=self._run, name="cctmill-event-log", daemon=True)
        self._thread.start()

    def write(self, record: dict[str, Any]) -> None:
        """Queue one record; never blocks, never raises."""
        try:
            self._q.put_nowait(record)
        except queue.Full:
            self.dropped += 1

    def _run(self) -> None:
        while True:
            rec = self._q.get()
            if rec is None:
                return
            if "__flush__" in rec:
                rec["__flush__"].set()
                continue
            self.records.append(rec)
            if len(self.records) > self._keep:
                del self.records[: len(self.records) - self._keep]
            if self._fh is not None:
                try:
                    self._fh.write(json.dumps({k: _clean(v) for k, v in rec.items()}) + "\n")
                except (OSError, TypeError, ValueError):
                    self.dropped += 1

    def flush(self) -> None:
        """Wait until every queued record is written."""
        done = threading.Event()
        self._q.put({"__flush__": done})
        done.wait(5.0)

    def close(self) -> None:
        """Write what is queued and close the file; idempotent."""
        if self._thread.is_alive():
            self._q.put(None)
            self._thread.join(10.0)
        if self._fh is not None:
            self._fh.close()
            self._fh = None
