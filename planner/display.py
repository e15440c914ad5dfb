"""How values are shown to people (the report, the command line, the supervisor's summaries).

A missing value never reaches a reader as Python's ``None`` or ``nan``, and a number never as the
float noise of a unit conversion (``2.4000000000000004``): :func:`quantity` writes a value with a
format and its unit, or — when there is no value — a dash or the sentence that says what no value
means there ("not limited", "not settled within the record"). plan.json and the JSON outputs keep
``null``: that is for programs, this is for people.
"""

from __future__ import annotations

import math
from typing import Any

__all__ = ["MISSING", "quantity"]

#: What a missing value is shown as when nothing more specific can be said.
MISSING = "—"


def quantity(v: Any, spec: str = ".4g", unit: str = "", missing: str = MISSING) -> str:
    """``v`` formatted with ``spec`` (``format(v, spec)``) and followed by ``unit``, or
    ``missing`` when ``v`` is None or a non-finite float (NaN, ±inf).

    Args:
        v: the value (a number, or None).
        spec: its format (``".4g"``: four significant digits; ``".1f"``: one decimal).
        unit: appended after a space when given ("ms", "mm/s").
        missing: what to show without a value: a dash, or what no value means ("no limit").
    """
    if v is None:
        return missing
    if isinstance(v, bool) or not hasattr(v, "__float__"):
        return str(v)
    if not math.isfinite(float(v)):
        return missing
    text = format(v, spec)
    return f"{text} {unit}" if unit else text
