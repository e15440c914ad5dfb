"""What the KRL writer (:mod:`robot_io.krl.writer`) takes, and the checks it makes before rendering:
the program spec (:class:`KrlProgramSpec`), its feed sections (:class:`KrlSection`) and motions
(:class:`KrlMove`), the controller generations (:data:`CONTROLLERS`) and :class:`KrlError`, raised
with a message naming the field and the fix for anything KRL cannot hold as given (KUKA_IO.md §1).
These are the writer's own plain types, not the planner's.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

from models.errors import InputError
from robot_io.krl._text import MAX_IDENTIFIER, module_name_problem

__all__ = [
    "CONTROLLERS",
    "ControllerLimits",
    "KrlError",
    "KrlFrame",
    "KrlMove",
    "KrlProgramSpec",
    "KrlSection",
    "MAX_COORDINATE",
    "MOVE_KINDS",
    "OVERRIDE_HOOKS",
    "check_program",
]

#: Largest |coordinate| the writer accepts [mm or deg]: anything larger is a unit mistake.
MAX_COORDINATE = 1e6
#: Motion kinds of :class:`KrlMove`.
MOVE_KINDS = ("PTP", "LIN", "CIRC")
#: Program-override hooks for the supervisor (see :mod:`robot_io.krl.writer`).
OVERRIDE_HOOKS = ("none", "kvp", "rsi")


@dataclass(frozen=True)
class ControllerLimits:
    """What a controller generation allows.

    Attributes:
        label: human name.
        page_lines: most lines of one ``.src`` page (KUKA_IO.md §1.5, our rule).
        vel_cp_max: largest ``$VEL.CP`` [m/s] (``$VEL_MA.CP``; 2 m/s is the usual machine datum —
            INFERRED, check the robot's machine data).
        rsi: whether the ``rsi`` override hook is offered (RSI ≥ 3 with MAP2OV_PRO).
        ext_bas: whether ``EXT BAS (…)`` is declared in the program (KR C2 posts do).
    """

    label: str
    page_lines: int
    vel_cp_max: float
    rsi: bool
    ext_bas: bool


#: Controller generations by ``--controller`` name.
CONTROLLERS: dict[str, ControllerLimits] = {
    "krc2": ControllerLimits("KR C2", 2000, 2.0, rsi=False, ext_bas=True),
    "krc4": ControllerLimits("KR C4", 1400, 2.0, rsi=True, ext_bas=False),
}



class KrlError(InputError):
    """A program the writer refuses: KRL cannot hold it as given (the message says how to fix it)."""


@dataclass(frozen=True)
class KrlFrame:
    """A literal ``{FRAME: X …,Y …,Z …,A …,B …,C …}``.

    Attributes:
        xyz_mm: origin [mm], 3 values.
        abc_deg: orientation, KUKA A, B, C [deg] (R = Rz(A)·Ry(B)·Rx(C)).
    """

    xyz_mm: tuple[float, float, float] = (0.0, 0.0, 0.0)
    abc_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class KrlSection:
    """One feed section.

    Attributes:
        feed_m_s: path speed ``$VEL.CP`` [m/s]; in (0, the controller's maximum].
        kind: ``"cut"``, ``"air"`` or ``"rapid"`` (for the comments).
        binding: what limits the feed (``"chatter"``, ``"force"`` …), for the comments.
        comment: free text for the section's comment line (transliterated to ASCII).
    """

    feed_m_s: float
    kind: str = "cut"
    binding: str = ""
    comment: str = ""


@dataclass(frozen=True)
class KrlMove:
    """One motion statement.

    Attributes:
        kind: ``"LIN"``, ``"CIRC"`` or ``"PTP"``.
        target: LIN/CIRC: the TCP end pose in ``$BASE`` (X, Y, Z [mm], A, B, C [deg]); PTP: the
            axis values A1..A6 [deg].
        section: index of the move's section in the ``sections`` list, from 0 (moves of a
            section are contiguous and sections come in list order); the program numbers it from
            1 (the fold ``section 1``, ``NAME_F001``). The move's velocity is its section's
            feed, or a fraction of it (``feed_scale``).
        aux: CIRC only: the auxiliary (via) pose, 6 values like ``target``.
        approx: ``C_DIS`` approximation (LIN/CIRC; PTPs are never approximated).
        feed_scale: LIN/CIRC only: ``$VEL.CP = NAME_Fnnn * feed_scale`` is written before the
            move (a feed profile: the section's ``.dat`` feed still retunes all of it); the
            following moves of the section keep that speed until the next scaled move. ``None``:
            no statement (the speed in force stays). A finite number > 0, written as the
            shortest decimal with at least ``robot_io.krl.writer.SCALE_DECIMALS`` decimals that
            reads back as the same double.
    """

    kind: str
    target: tuple[float, ...]
    section: int
    aux: tuple[float, ...] | None = None
    approx: bool = True
    feed_scale: float | None = None


@dataclass(frozen=True)
class KrlProgramSpec:
    """Everything about a program except its sections and moves.

    Attributes:
        name: module name (``NAME.src``): a KRL identifier without ``$``; short enough for its
            derived names (``NAME_Fnnn``, ``NAME_SEC``, pages ``NAME_001``).
        bco_axes_deg: axis values A1..A6 [deg] of the joint PTP after ``PTP $AXIS_ACT`` (the BCO
            run); the first section starts from there.
        controller: ``"krc2"`` or ``"krc4"`` (:data:`CONTROLLERS`).
        base: ``$BASE``: a literal frame or a ``BASE_DATA`` index (1–32).
        tool: ``$TOOL``: a literal frame or a ``TOOL_DATA`` index (1–16).
        advance: ``$ADVANCE`` (1–5; approximation needs look-ahead).
        apo_cdis_mm: ``$APO.CDIS`` [mm], > 0.
        ptp_velocity_pct: ``BAS (#VEL_PTP, …)`` [% of the axes' maximum], in (0, 100].
        override_hook: one of :data:`OVERRIDE_HOOKS`.
        rsi_config: RSI context file created by ``RSI_CREATE`` (hook ``rsi``).
        comments: lines for the program's comment header (job, plan, compensation …).
        end_axes_deg: axis values [deg] of a final joint PTP, or ``None`` (stay at the end).
        page_lines: lines per page, at most the controller's (``None``: the controller's).
    """

    name: str
    bco_axes_deg: tuple[float, ...]
    controller: str = "krc4"
    base: KrlFrame | int = field(default_factory=KrlFrame)
    tool: KrlFrame | int = field(default_factory=KrlFrame)
    advance: int = 3
    apo_cdis_mm: float = 0.1
    ptp_velocity_pct: float = 20.0
    override_hook: str = "none"
    rsi_config: str = "cct_override"
    comments: tuple[str, ...] = ()
    end_axes_deg: tuple[float, ...] | None = None
    page_lines: int | None = None


# --------------------------------------------------------------------------- checks
def _finite(values: Sequence[float], n: int, what: str, field_: str) -> tuple[float, ...]:
    try:
        v = tuple(float(x) for x in values)
    except (TypeError, ValueError):
        raise KrlError(field_, f"{what} must be {n} numbers") from None
    if len(v) != n:
        raise KrlError(field_, f"{what} must be {n} numbers, got {len(v)}")
    bad = [x for x in v if not math.isfinite(x) or abs(x) > MAX_COORDINATE]
    if bad:
        raise KrlError(field_, f"{what} holds {bad[0]:.10g}: KRL needs finite numbers below "
                       f"{MAX_COORDINATE:g} (mm, deg); fix the value upstream")
    return v


def _check_spec(spec: KrlProgramSpec, n_sections: int) -> ControllerLimits:
    lim = CONTROLLERS.get(spec.controller)
    if lim is None:
        raise KrlError("controller", f"unknown controller {spec.controller!r}; use one of "
                       f"{', '.join(CONTROLLERS)}")
    p = module_name_problem(spec.name)
    if p is not None:
        raise KrlError("name", f"program name {spec.name!r} {p}; pass a valid KRL name "
                       "(e.g. --name MILL_PART1)")
    digits = max(3, len(str(n_sections)))
    longest = max(len("_F") + digits, len("_SEC") if spec.override_hook != "none" else 0)
    if len(spec.name) + longest > MAX_IDENTIFIER:
        keep = MAX_IDENTIFIER - longest
        raise KrlError("name", f"program name {spec.name!r} has {len(spec.name)} characters; "
                       f"the feed variables {spec.name}_F{1:0{digits}d} need it at most {keep} "
                       f"long (KRL names ≤ {MAX_IDENTIFIER}); pass a shorter --name")
    _finite(spec.bco_axes_deg, 6, "bco_axes_deg", "bco_axes_deg")
    if spec.end_axes_deg is not None:
        _finite(spec.end_axes_deg, 6, "end_axes_deg", "end_axes_deg")
    for which, frame, top in (("base", spec.base, 32), ("tool", spec.tool, 16)):
        if isinstance(frame, KrlFrame):
            _finite(frame.xyz_mm, 3, f"{which} xyz_mm", which)
            _finite(frame.abc_deg, 3, f"{which} abc_deg", which)
        elif isinstance(frame, bool) or not isinstance(frame, int) or not 1 <= frame <= top:
            raise KrlError(which, f"{which.upper()}_DATA index {frame!r} must be a whole number "
                           f"1..{top} (or give the frame as a literal)")
    if isinstance(spec.advance, bool) or spec.advance not in (1, 2, 3, 4, 5):
        raise KrlError("advance", f"$ADVANCE {spec.advance!r} must be 1..5 (approximation "
                       "needs look-ahead; 0 is not allowed for milling)")
    if not (math.isfinite(spec.apo_cdis_mm) and spec.apo_cdis_mm > 0):
        raise KrlError("apo_cdis_mm", f"$APO.CDIS {spec.apo_cdis_mm:g} mm must be > 0")
    if not (math.isfinite(spec.ptp_velocity_pct) and 0 < spec.ptp_velocity_pct <= 100):
        raise KrlError("ptp_velocity_pct", f"{spec.ptp_velocity_pct:g} % must be in (0, 100] %")
    if spec.override_hook not in OVERRIDE_HOOKS:
        raise KrlError("override_hook", f"unknown override hook {spec.override_hook!r}; use one "
                       f"of {', '.join(OVERRIDE_HOOKS)}")
    if spec.override_hook == "rsi" and not lim.rsi:
        raise KrlError("override_hook", f"the rsi hook needs RSI >= 3 (KR C4); on {lim.label} use "
                       "--override-hook kvp (KukaVarProxy writes $OV_PRO), KUKA_IO.md §2.4")
    if spec.override_hook == "rsi":
        cfg = spec.rsi_config
        if not cfg or not cfg.isascii() or any(c in cfg for c in '"\r\n;') or len(cfg) > 64:
            raise KrlError("rsi_config", f"RSI context file {cfg!r} must be a short ASCII file "
                           "name without quotes")
    if spec.page_lines is not None and not (
            isinstance(spec.page_lines, int) and 100 <= spec.page_lines <= lim.page_lines):
        raise KrlError("page_lines", f"{spec.page_lines!r} must be a whole number in "
                       f"100..{lim.page_lines} ({lim.label})")
    return lim


def _check_sections(sections: Sequence[KrlSection], lim: ControllerLimits) -> None:
    if not sections:
        raise KrlError("sections", "a program needs at least one section with moves")
    for k, sec in enumerate(sections, 1):
        f = sec.feed_m_s
        if isinstance(f, bool) or not isinstance(f, (int, float)) or not math.isfinite(f):
            raise KrlError(f"section {k} feed", f"{f!r} is not a number: $VEL.CP needs a "
                           "finite path speed in m/s; re-plan the job")
        if f <= 0:
            raise KrlError(f"section {k} feed", f"{f:.10g} m/s: $VEL.CP must be > 0 (a zero feed "
                           "never reaches the target); re-plan or drop the section")
        if f > lim.vel_cp_max:    # 10 digits: 1 nm/s at a few m/s, without a float's noise
            raise KrlError(f"section {k} feed", f"{f:.10g} m/s is above {lim.label}'s $VEL.CP "
                           f"maximum {lim.vel_cp_max:g} m/s; $VEL.CP is in m/s (was mm/s "
                           "given?)")


def _check_moves(moves: Sequence[KrlMove], n_sections: int) -> None:
    if not moves:
        raise KrlError("moves", "a program needs at least one move")
    last = 0
    used = set()
    for i, m in enumerate(moves):
        where = f"move {i}"
        if m.kind not in MOVE_KINDS:
            raise KrlError(where, f"kind {m.kind!r} must be one of {', '.join(MOVE_KINDS)}")
        _finite(m.target, 6, "the target", where)
        if m.kind == "CIRC":
            if m.aux is None:
                raise KrlError(where, "a CIRC needs its auxiliary point (aux)")
            _finite(m.aux, 6, "the auxiliary point", where)
        elif m.aux is not None:
            raise KrlError(where, f"only CIRC takes an auxiliary point, not {m.kind}")
        fs = m.feed_scale
        if fs is not None and (m.kind == "PTP" or isinstance(fs, bool)
                               or not isinstance(fs, (int, float)) or not math.isfinite(fs)
                               or fs <= 0):
            raise KrlError(where, f"feed_scale {fs!r} must be a finite number > 0 on a LIN or "
                           "CIRC (it multiplies the section's $VEL.CP)")
        s = m.section
        if isinstance(s, bool) or not isinstance(s, int) or not 0 <= s < n_sections:
            raise KrlError(where, f"its section {s!r} is not an index into the {n_sections} "
                           f"sections (0..{n_sections - 1})")
        if s < last:     # the messages number sections from 1, as the folds do
            raise KrlError(where, f"section {s + 1} comes after section {last + 1}: the moves of "
                           "a section must be contiguous and sections in list order")
        last = s
        used.add(s)
    empty = sorted(set(range(n_sections)) - used)
    if empty:
        raise KrlError("sections", f"section {empty[0] + 1} has no moves; drop empty sections")
    for i, m in enumerate(moves):
        if m.kind == "CIRC" and (i == 0 or moves[i - 1].kind == "PTP"):
            raise KrlError(f"move {i}", "a CIRC cannot follow a joint PTP (or the BCO PTP): its "
                           "start point would be a joint position; put a LIN before it")



def check_program(spec: KrlProgramSpec, sections: Sequence[KrlSection],
                  moves: Sequence[KrlMove]) -> ControllerLimits:
    """Check a program before it is rendered: the spec, then the sections, then the moves.

    Returns:
        the limits of ``spec.controller``.

    Raises:
        KrlError: the first thing KRL cannot hold as given (the message names the field and the
            fix).
    """
    lim = _check_spec(spec, len(sections))
    _check_sections(sections, lim)
    _check_moves(moves, len(sections))
    return lim
