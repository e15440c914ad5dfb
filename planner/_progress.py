"""Progress bars on stderr for the long steps (tqdm), off unless asked for.

Library functions take ``progress: bool``; only the CLI turns it on. A bar appears only for work
that is long enough to watch (:data:`MIN_TOTAL` items) and only on a terminal: piped or captured
stderr stays clean for the one-line error messages scripts read, and a CI runner (``CI`` set in
the environment, as GitHub Actions, GitLab and most runners do) or a dumb terminal shows none.
"""

from __future__ import annotations

import os
import sys
from typing import Any

from tqdm import tqdm

__all__ = ["MIN_TOTAL", "bar", "close_all", "on_terminal"]

#: Fewer items than this finish in well under a second: no bar.
MIN_TOTAL = 2000


def on_terminal() -> bool:
    """stderr is an interactive terminal, not a CI runner's or a dumb one."""
    return (sys.stderr.isatty() and not os.environ.get("CI")
            and os.environ.get("TERM", "") != "dumb")


def bar(total: int, desc: str, enabled: bool, unit: str = "sample",
        min_total: int = MIN_TOTAL) -> Any:
    """A tqdm bar (a no-op one when ``enabled`` is false or ``total`` is below ``min_total``: a
    placement study, whose items take seconds each, passes 1)."""
    return tqdm(total=total, desc=desc, unit=unit, file=sys.stderr, leave=False,
                disable=not (enabled and total >= min_total and on_terminal()),
                dynamic_ncols=True, mininterval=0.2)


def close_all() -> None:
    """Close (and clear) every bar still open: the CLI calls it before an error message, which a
    bar left open by the exception would otherwise run into on the same line."""
    for pbar in list(getattr(tqdm, "_instances", ())):
        pbar.close()
