"""Reader options as the user spells them: a fix in a message names the flag, job key or keyword
of the interface in use.

A reader's message that tells the user to change an option (read leniently, set the units, choose a
rotary kinematics) calls :func:`fix` instead of writing ``strict=False``: from Python that is the
keyword, from the command line the flag (``--lenient``), from a job file the key
(``[job] strict = false``). The caller says which interface it serves with :func:`speaking`
(the CLI's ``inspect`` says ``"cli"``, ``planner.prepare`` says ``"job"``); Python is the default.

:data:`OPTION_FORMATS` says which formats each option applies to, so that an option given for a
file of another format is refused with the formats it does apply to (not "unknown option").
"""

from __future__ import annotations

import contextlib
import contextvars
import re
from collections.abc import Iterator
from typing import Any

__all__ = [
    "INTERFACES",
    "OPTION_FORMATS",
    "current_interface",
    "fix",
    "option_name",
    "speaking",
    "without_lenient_hint",
]

#: The interfaces a message can speak.
INTERFACES = ("python", "cli", "job")

#: The formats each reader option applies to ("*" = all, passed by ``read_toolpath`` itself).
OPTION_FORMATS: dict[str, tuple[str, ...]] = {
    "strict": ("*",),
    "format": ("*",),
    "chord_tol": ("apt",),
    "default_units": ("gcode", "apt"),
    "apply_frames": ("apt",),
    "circle_direction": ("apt",),
    "rotary": ("gcode",),
    "tcp": ("gcode",),
    "pivot": ("gcode",),
    "c_offset": ("gcode",),
    "initial_position": ("gcode",),
    "home_position": ("gcode",),
    "arc_radius_tol": ("gcode", "apt"),
    "arc_radius_rtol": ("gcode", "apt"),
    "ignore_calls": ("krl",),
    "global_dat": ("krl",),
}

_INTERFACE: contextvars.ContextVar[str] = contextvars.ContextVar("cctmill_interface",
                                                                 default="python")

#: How each option is named on the command line and in a job file; ``{}`` is the value.
_CLI: dict[str, str] = {
    "strict": "--lenient",
    "format": "--format {}",
    "default_units": "--units {}",
    "apply_frames": "--apply-frames",
    "circle_direction": "--circle-direction {}",
    "rotary": "--rotary {}",
    "initial_position": "--initial-position-mm X,Y,Z",
    "home_position": "--home-position-mm X,Y,Z",
    "chord_tol": "--chord-tol-mm {}",
    "arc_radius_tol": "--arc-radius-tol-mm {}",
}
_JOB: dict[str, str] = {
    "strict": "[job] strict = false",
    "format": "[job] format = \"{}\"",
    "default_units": "[job] units = \"{}\"",
    "apply_frames": "[job] apply_frames = true",
    "circle_direction": "[job] circle_direction = \"{}\"",
    "rotary": "[job] rotary = \"{}\"",
    "initial_position": "[job] initial_position_mm = [x, y, z]",
    "home_position": "[job] home_position_mm = [x, y, z]",
    "chord_tol": "[path] chord_tol_mm = {}",
    "arc_radius_tol": "[job] arc_radius_tol_mm = {}",
}


#: Options in metres, shown in mm by the CLI and job forms.
_METRES = ("chord_tol", "arc_radius_tol")


def current_interface() -> str:
    """``"python"``, ``"cli"`` or ``"job"``: whom messages made now are written for."""
    return _INTERFACE.get()


@contextlib.contextmanager
def speaking(interface: str) -> Iterator[None]:
    """Make messages created inside the block name options as ``interface`` spells them."""
    if interface not in INTERFACES:
        raise ValueError(f"interface must be one of {INTERFACES}, not {interface!r}")
    token = _INTERFACE.set(interface)
    try:
        yield
    finally:
        _INTERFACE.reset(token)


def _python_form(name: str, value: Any) -> str:
    if name == "initial_position" or name == "home_position":
        return f"{name}=(x, y, z) in metres"
    if name in _METRES and value is not None:
        return f"{name}={value!r} (metres)"
    return f"{name}={value!r}"


def fix(name: str, value: Any = None) -> str:
    """The option ``name`` set to ``value`` as the user of the current interface writes it.

    ``fix("strict", False)`` is ``strict=False`` from Python, ``--lenient`` from the CLI and
    ``[job] strict = false`` from a job. A value of ``None`` leaves a placeholder where the form
    has one. Options that only Python offers keep the keyword form everywhere, with
    "(Python API)" added outside Python.
    """
    where = _INTERFACE.get()
    if where == "python":
        return _python_form(name, value)
    table = _CLI if where == "cli" else _JOB
    form = table.get(name)
    if form is None:
        return f"{_python_form(name, value)} (Python API)"
    shown = "…" if value is None else (value if isinstance(value, str) else repr(value))
    if isinstance(value, float) and name in _METRES:
        shown = f"{value * 1e3:g}"
    return form.format(shown)


def option_name(name: str) -> str:
    """The bare name of option ``name`` in the current interface (``--rotary``,
    ``[job] rotary``, ``rotary``), for "this option applies to …" messages."""
    where = _INTERFACE.get()
    if where == "python":
        return name
    table = _CLI if where == "cli" else _JOB
    form = table.get(name)
    if form is None:
        return f"{name} (Python API)"
    return form.split(" = ")[0] if where == "job" else form.split(" ")[0]


def without_lenient_hint(message: str) -> str:
    """``message`` without its advice to read leniently: a reader's warning (made in lenient
    mode, where the same problem raises in strict) already says what was done, so
    "or read with --lenient to skip it" is dropped from it, in any interface's words."""
    lenient = re.escape(fix("strict", False))
    hint = (rf"(?:[;,] *| +)(?:or +)?read(?: +it)?(?: +leniently)?(?: +with)? *\(?{lenient}\)?"
            r"(?: +to +[^;():]*)?")
    out = re.sub(hint, "", message)
    out = re.sub(r"^ *(?:or +)?remove it *(?:;|$)", "", out)
    out = re.sub(r"[;,] *, *or remove it\b", "; or remove it", out)
    out = re.sub(r"[;,] *(?:or +)?remove it$", "", out)
    return out.rstrip(" ;,") if out != message else message
