"""LinuxCNC parameters of the G-code reader (private): numbered ``#1``…, named ``#<name>`` and
global ``#<_name>`` parameters, their settings ``#… = value``, and the words whose value is an
expression (``X[#1*2]``); the expressions themselves are :mod:`robot_io.gcode._expr`.

As in LinuxCNC ("G-code overview: Parameters"):

* numbered parameters ``#1``…``#5000`` are the program's own: read and written, 0 until set
  (a counted warning ``unset_numbered_parameter`` the first time each is read unset, since a
  typo reads silently as 0);
* named parameters spring into existence when first set; reading one before that is an error
  (LinuxCNC refuses it too); names are case-insensitive and blanks in them are ignored;
  ``#1``–``#30`` and names without a leading ``_`` are local to a subroutine call (the call's
  arguments are ``#1``…; the caller's values come back on return), ``#31`` and up and
  ``#<_names>`` are global;
* the settings on a line take effect after every value on the line has been read, in the order
  written (``#3=6 G1 X#3`` moves to the old #3; ``#3=15 #3=6`` leaves 6);
* ``#5001`` and up hold machine state (offsets, G28 home, probe results, tool table). Those this
  reader knows offline are modelled read-only: the position ``#5420``–``#5425`` (program units,
  degrees) and the predefined names of :data:`PREDEFINED`. Any other is refused when read (its
  value depends on the machine) and every one is refused when set (it would change offsets or
  machine state the reader does not model).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from robot_io.gcode import _expr as E
from robot_io.gcode import _words as W
from robot_io.gcode._state import DEG

if TYPE_CHECKING:
    from robot_io.gcode._interp import _Run

__all__ = [
    "LOCAL_NUMBERED",
    "MAX_PARAMETER",
    "PREDEFINED",
    "USER_PARAMETERS",
    "Parameters",
    "read_setting",
    "read_word",
]

#: Numbered parameters are ``#1``…``#MAX_PARAMETER`` (LinuxCNC's ``RS274NGC_MAX_PARAMETERS``
#: - 1 of the 2.9 series; a larger number is an error there too).
MAX_PARAMETER = 5601
#: The program's own numbered parameters (LinuxCNC: 1–30 subroutine arguments, 31–5000 user).
USER_PARAMETERS = range(1, 5001)
#: Machine-state parameters by range, for messages (LinuxCNC "Numbered Parameters").
_SYSTEM = (
    (5021, 5029, "current machine position"), (5061, 5070, "G38 probe result"),
    (5081, 5089, "applied tool length offset"), (5161, 5169, "G28 home position"),
    (5181, 5189, "G30 home position"), (5210, 5219, "G52/G92 offset"),
    (5220, 5220, "active coordinate system"), (5221, 5390, "G54–G59.3 work offset"),
    (5399, 5399, "M66 input result"), (5400, 5400, "tool number"),
    (5401, 5413, "tool table entry"), (5420, 5428, "current position"),
    (5599, 5601, "debug/tool changer flag"))
#: Read-only predefined named parameters this reader models (LinuxCNC "Predefined Named
#: Parameters"); their values come from the modal state when the line is read.
PREDEFINED = ("_a", "_absolute", "_b", "_c", "_feed", "_ijk_absolute_mode", "_imperial",
              "_incremental", "_inverse_time", "_line", "_metric", "_motion_mode", "_plane",
              "_rpm", "_spindle_on", "_units_per_minute", "_value", "_value_returned", "_x",
              "_y", "_z")
#: LinuxCNC's other predefined names: machine or interpreter state not known offline.
_UNMODELLED = frozenset({
    "_vmajor", "_vminor", "_ccomp", "_units_per_rev", "_coord_system", "_tool_offset",
    "_retract_r_plane", "_retract_old_z", "_spindle_rpm_mode", "_spindle_css_mode",
    "_lathe_diameter_mode", "_lathe_radius_mode", "_spindle_cw", "_mist", "_flood",
    "_speed_override", "_feed_override", "_adaptive_feed", "_feed_hold", "_u", "_v", "_w",
    "_abs_x", "_abs_y", "_abs_z", "_abs_a", "_abs_b", "_abs_c", "_abs_u", "_abs_v", "_abs_w",
    "_current_tool", "_current_pocket", "_selected_tool", "_selected_pocket", "_task",
    "_call_level", "_remap_level"})
_TRUE_FALSE = (0.0, 1.0)


def _system_name(index: int) -> str:
    for lo, hi, what in _SYSTEM:
        if lo <= index <= hi:
            return what
    return "system parameter"


#: Numbered parameters local to a subroutine call (its arguments).
LOCAL_NUMBERED = 30


def _local(key: int | str) -> bool:
    return key <= LOCAL_NUMBERED if isinstance(key, int) else key[0] != "_"


class Parameters:
    """The parameter table of one reading: values set so far, the settings of the line being
    read (applied by :meth:`commit` once the whole line has been read), and the value of the
    last subroutine return (``#<_value>``, ``#<_value_returned>``)."""

    def __init__(self) -> None:
        self.values: dict[int | str, float] = {}
        self.pending: list[tuple[int | str, float]] = []
        self.warned: set[int] = set()   # unset numbered parameters already warned about
        self.returned: float | None = None   # value of the last return/endsub, if it gave one

    def commit(self) -> None:
        """Apply the line's settings in the order written (the last one of a name wins)."""
        for key, value in self.pending:
            self.values[key] = value
        self.pending.clear()

    def enter(self, args: list[float]) -> dict[int | str, float]:
        """A subroutine call: the caller's local parameters are put aside (returned, for
        :meth:`leave`) and ``#1``… hold ``args``."""
        saved = {k: v for k, v in self.values.items() if _local(k)}
        for k in saved:
            del self.values[k]
        for n, v in enumerate(args, start=1):
            self.values[n] = v
        self.returned = None
        return saved

    def leave(self, saved: dict[int | str, float], value: float | None) -> None:
        """Back from a call: the subroutine's locals vanish, the caller's come back."""
        for k in [k for k in self.values if _local(k)]:
            del self.values[k]
        self.values.update(saved)
        self.returned = value


def _shown(key: int | str) -> str:
    return f"#{key}" if isinstance(key, int) else f"#<{key}>"


def _lookup(run: _Run):
    """The ``lookup(key, col)`` of :func:`robot_io.gcode._expr.read_value` for ``run``."""
    values = run.params.values

    def lookup(key: int | str, col: int) -> float:
        v = values.get(key)
        if v is not None:
            return v
        if isinstance(key, int):
            if key in USER_PARAMETERS:
                if key not in run.params.warned:
                    run.params.warned.add(key)
                    run.warn(col, "unset_numbered_parameter", f"#{key} is read before it is "
                             "set: 0, as LinuxCNC reads an unset numbered parameter")
                return 0.0
            return _system_value(run, key, col)
        if key[0] == "_":
            return _predefined_value(run, key, col)
        raise _unset(key, col)

    return lookup


def _exists(run: _Run):
    def exists(name: str, col: int) -> bool:
        if name in run.params.values or name in PREDEFINED:
            return True
        if name in _UNMODELLED or name.startswith(("_ini[", "_hal[")):
            raise E.ExpressionError(col, f"EXISTS[#<{name}>] depends on the machine's "
                                    "configuration, which a file alone does not tell",
                                    "system_parameter")
        return False

    return exists


def _unknown_position(col: int, what: str) -> E.ExpressionError:
    return E.ExpressionError(col, f"{what} is not known yet at this line (program start, "
                             "G28/G30 or G53); program the axis absolutely first",
                             "system_parameter")


def _system_value(run: _Run, index: int, col: int) -> float:
    if not 1 <= index <= MAX_PARAMETER:
        raise E.ExpressionError(col, f"parameter number #{index} is out of range "
                                f"(#1…#{MAX_PARAMETER})", "bad_parameter")
    st = run.st
    if 5420 <= index <= 5422:
        v = st.pos[index - 5420]
        if v is None:
            raise _unknown_position(col, f"#{index} (current {'XYZ'[index - 5420]})")
        return v / st.scale
    if 5423 <= index <= 5425:
        a = st.rot["ABC"[index - 5423]]
        if a is None:
            raise _unknown_position(col, f"#{index} (current {'ABC'[index - 5423]})")
        return a / DEG
    raise E.ExpressionError(col, f"#{index} ({_system_name(index)}) is machine state that a "
                            "file alone does not tell; use a program parameter (#1…#5000 or "
                            "a named one)", "system_parameter")


def _predefined_value(run: _Run, name: str, col: int) -> float:
    st = run.st
    if name in ("_x", "_y", "_z"):
        v = st.pos["xyz".index(name[1])]
        if v is None:
            raise _unknown_position(col, f"#<{name}>")
        return v / st.scale
    if name in ("_a", "_b", "_c"):
        a = st.rot[name[1].upper()]
        if a is None:
            raise _unknown_position(col, f"#<{name}>")
        return a / DEG
    flags = {"_metric": st.scale == W.MM, "_imperial": st.scale == W.INCH,
             "_absolute": st.absolute, "_incremental": not st.absolute,
             "_inverse_time": st.inverse_time, "_units_per_minute": not st.inverse_time,
             "_ijk_absolute_mode": st.arc_absolute, "_spindle_on": st.spindle_on,
             "_value_returned": run.params.returned is not None}
    if name in flags:
        return _TRUE_FALSE[flags[name]]
    if name == "_value":
        return run.params.returned or 0.0
    if name == "_feed":
        return 0.0 if st.feed_raw is None else st.feed_raw
    if name == "_rpm":
        return 0.0 if st.spindle_s is None else st.spindle_s
    if name == "_line":
        return float(run.line)
    if name == "_motion_mode":   # G-code × 10, G80 when none (the reader's code keys)
        return 800.0 if st.motion is None else float(st.motion)
    if name == "_plane":
        return float(st.plane)
    if name in _UNMODELLED or name.startswith(("_ini[", "_hal[")):
        raise E.ExpressionError(col, f"#<{name}> is machine state that a file alone does not "
                                "tell; use a program parameter", "system_parameter")
    raise _unset(name, col)


def _unset(name: str, col: int) -> E.ExpressionError:
    return E.ExpressionError(col, f"#<{name}> is read before it is set (LinuxCNC refuses an "
                             f"unset named parameter); set it first, e.g. #<{name}> = 0",
                             "unset_parameter")


def read_word(run: _Run, u: str, i: int) -> tuple[float, int]:
    """The value of a word starting at ``u[i]`` (after the letter and blanks)."""
    return E.read_value(u, i, _lookup(run), _exists(run))


def read_setting(run: _Run, u: str, i: int) -> int:
    """Read the parameter setting ``#… = value`` at ``u[i] == "#"`` into the line's pending
    settings; returns the index after it. Raises :class:`~robot_io.gcode._expr.ExpressionError`."""
    lookup = _lookup(run)
    col = i + 1
    j = E.skip_blanks(u, i + 1)
    key: int | str
    if u[j:j + 1] == "<":
        key, j = E.read_name(u, j)
        if key in PREDEFINED or key in _UNMODELLED or key.startswith(("_ini[", "_hal[")):
            raise E.ExpressionError(col, f"#<{key}> is a read-only predefined parameter; "
                                    "set a parameter of your own", "system_parameter")
    else:
        v, j = E.read_value(u, j, lookup, _exists(run))
        key = E.as_integer(v, col, "a parameter number")
        if not 1 <= key <= MAX_PARAMETER:
            raise E.ExpressionError(col, f"parameter number #{key} is out of range "
                                    f"(#1…#{MAX_PARAMETER})", "bad_parameter")
        if key not in USER_PARAMETERS:
            raise E.ExpressionError(col, f"setting #{key} ({_system_name(key)}) would change "
                                    "machine state the reader does not model (offsets, "
                                    "homes, tool table); use #1…#5000 or a named parameter",
                                    "system_parameter")
    j = E.skip_blanks(u, j)
    if u[j:j + 1] != "=":
        raise E.ExpressionError(j + 1, f"{_shown(key)} outside a word: a parameter setting "
                                f"needs '=' and a value, e.g. {_shown(key)} = 2.5; a word "
                                f"takes it as its value, e.g. X{_shown(key)}")
    j = E.skip_blanks(u, j + 1)
    if j >= len(u) or u[j] in "(;":
        raise E.ExpressionError(j + 1, f"{_shown(key)} = needs a value")
    value, j = E.read_value(u, j, lookup, _exists(run))
    run.params.pending.append((key, value))
    return j
