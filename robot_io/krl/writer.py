"""Write KUKA KRL programs (``NAME.src`` + ``NAME.dat``, paged into sub-modules when long).

The writer takes its own plain types, not the planner's (:mod:`robot_io.krl.spec`):
:class:`KrlProgramSpec` (name, controller, frames, motion parameters, override hook),
:class:`KrlSection` (a feed and why) and :class:`KrlMove` (a pose in ``$BASE`` or axis values,
the motion kind and its section). It follows KUKA_IO.md §1 (authoritative on KRL rules):
KUKA_IO.md §1 (authoritative on KRL rules):

* **Layout** of the main module: ``&`` header, ``DEF NAME( )``, declarations, the INI fold with
  ``BAS (#INITMOV,0 )``, ``$BASE``/``$TOOL`` (``{FRAME: …}`` literals or ``BASE_DATA[n]``/
  ``TOOL_DATA[n]``), ``$IPO_MODE = #BASE`` (robot-held spindle), ``$ORI_TYPE = #VAR``,
  ``$ADVANCE``, ``$APO.CDIS``, ``BAS (#VEL_PTP, …)``, the BCO run (``PTP $AXIS_ACT`` then a
  joint-space PTP to :attr:`KrlProgramSpec.bco_axes_deg`), the sections, ``END``.
* **Sections**: each opens a fold whose title names the section, its kind, feed and binding
  constraint; ``$VEL.CP = NAME_Fnnn`` (m/s) comes before the section's first motion. The feed
  values themselves are ``DECL GLOBAL REAL NAME_Fnnn=…`` lines in ``NAME.dat`` (under ``DEFDAT
  NAME PUBLIC``), written with at least :data:`FEED_DECIMALS` decimals and exactly (the literal
  reads back as the same double), so an engineer retunes a section there without touching the
  geometry. The names carry the program name, so two programs on one controller never share a
  global. A move with a ``feed_scale`` (a feed profile) gets ``$VEL.CP = NAME_Fnnn * 0.873100``
  before it: the speed changes inside the section and the ``.dat`` value still retunes all of it.
* **Motions**: ``LIN {X …,Y …,Z …,A …,B …,C …} C_DIS`` and ``CIRC {aux},{end} C_DIS`` with
  positions in mm and angles in degrees to :data:`POSITION_DECIMALS` / :data:`ANGLE_DECIMALS`
  decimals; ``PTP {A1 …,…,A6 …}`` (joint space, never approximated).
* **KRL rules**: identifiers ≤ 24 characters (letters, digits, ``_``, ``$``; no leading digit;
  no keyword), ASCII only (comments transliterated, see ``robot_io.krl._text``), CRLF line
  endings, feeds in (0, ``$VEL_MA.CP``].
* **Paging**: a program longer than the controller's page (:data:`CONTROLLERS`: 2000 lines on KR
  C2, 1400 on KR C4, KUKA_IO.md §1.5) becomes a main module ``NAME`` that does the INI, frames and
  BCO run and then calls ``NAME_001( )``, ``NAME_002( )`` … in order; each page is a ``.src`` with
  a small ``.dat``. Pages break at section boundaries. **Exception**: a section longer than a page
  is split before a LIN (never before a CIRC, so a CIRC and the second half of a split arc stay
  with their predecessor); the continuation page re-opens the section's fold with a comment
  saying so and re-issues its ``$VEL.CP``.
* **Override hook** (:data:`OVERRIDE_HOOKS`, for the online supervisor, KUKA_IO.md §2.4/§3):
  ``none``; ``kvp`` — ``DECL GLOBAL INT NAME_SEC`` in the ``.dat``, set to the running section's
  number at each section start, so the supervisor reads over KukaVarProxy which section (and so
  which stability characteristic) is running while it writes ``$OV_PRO``; ``rsi`` (KR C4 only) —
  the same marker plus an RSI context around the sections: ``RSI_CREATE`` of
  :attr:`KrlProgramSpec.rsi_config` (ETHERNET → MAP2OV_PRO, configured on the controller) and
  ``RSI_ON (#RELATIVE, #IPO)`` before the first section, ``RSI_OFF ( )`` after the last; no
  ``RSI_MOVECORR`` (the programmed path runs unchanged). Whether an RSI context stays active
  across page calls is UNVERIFIED (KUKA_IO.md §5).

:func:`write_krl` validates and renders everything before it touches the disk, writes every file
to a temporary beside its target and only then moves them all into place: after an error no target
file is created or changed. After a successful write, pages ``NAME_nnn`` that an earlier, longer
export of the same program left in the folder (recognised by their cctmill header) are deleted.
Validation errors are :class:`KrlError` with a message naming the field and the fix.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from robot_io.krl._files import remove_stale_pages, write_all
from robot_io.krl._pages import NoPageBreakError, PageSection, paginate, section_lines
from robot_io.krl._text import (
    MAX_IDENTIFIER,
    ascii_comment,
    fixed,
    identifier_problem,
    real_literal,
    sanitize_identifier,
)
from robot_io.krl.spec import (
    CONTROLLERS,
    MAX_COORDINATE,
    MOVE_KINDS,
    OVERRIDE_HOOKS,
    ControllerLimits,
    KrlError,
    KrlFrame,
    KrlMove,
    KrlProgramSpec,
    KrlSection,
    check_program,
)

__all__ = [
    "ANGLE_DECIMALS",
    "CONTROLLERS",
    "ControllerLimits",
    "FEED_DECIMALS",
    "KrlError",
    "KrlFrame",
    "KrlMove",
    "KrlOutput",
    "KrlProgramSpec",
    "KrlSection",
    "MAX_COORDINATE",
    "MOVE_KINDS",
    "OVERRIDE_HOOKS",
    "POSITION_DECIMALS",
    "SCALE_DECIMALS",
    "ascii_comment",
    "render_krl",
    "sanitize_identifier",
    "write_krl",
]

#: Decimals of positions [mm] (0.1 µm: a round trip stays well inside 0.001 mm).
POSITION_DECIMALS = 4
#: Decimals of angles [deg].
ANGLE_DECIMALS = 4
#: Fewest decimals of a ``$VEL.CP`` value [m/s] (milling feeds are 0.0005–0.002 m/s).
FEED_DECIMALS = 6
#: Fewest decimals of a move's feed scale in ``$VEL.CP = NAME_Fnnn * scale`` [-].
SCALE_DECIMALS = 6

_CRLF = "\r\n"
_RSI_CHECK = ("IF (CCT_RET <> RSIOK) THEN", "  HALT", "ENDIF")



@dataclass(frozen=True)
class KrlOutput:
    """The rendered program.

    Attributes:
        files: file name → text (CRLF line endings, ASCII), main ``.src`` and ``.dat`` first.
        pages: page module names in call order; empty when the program is one module.
        feed_names: the ``.dat`` variable holding each section's feed, in section order.
    """

    files: dict[str, str]
    pages: tuple[str, ...]
    feed_names: tuple[str, ...]


# --------------------------------------------------------------------------- rendering
def _pos(v: Sequence[float]) -> str:
    return (f"X {fixed(v[0], POSITION_DECIMALS)},Y {fixed(v[1], POSITION_DECIMALS)},"
            f"Z {fixed(v[2], POSITION_DECIMALS)},A {fixed(v[3], ANGLE_DECIMALS)},"
            f"B {fixed(v[4], ANGLE_DECIMALS)},C {fixed(v[5], ANGLE_DECIMALS)}")


def _axes(v: Sequence[float]) -> str:
    return ",".join(f"A{i} {fixed(x, ANGLE_DECIMALS)}" for i, x in enumerate(v, 1))


def _frame(which: str, frame: KrlFrame | int) -> str:
    if isinstance(frame, KrlFrame):
        return f"${which} = {{FRAME: {_pos((*frame.xyz_mm, *frame.abc_deg))}}}"
    return f"${which} = {which}_DATA[{frame}]"


def _motion(m: KrlMove) -> str:
    if m.kind == "PTP":
        return f"PTP {{{_axes(m.target)}}}"
    cdis = " C_DIS" if m.approx else ""
    if m.kind == "LIN":
        return f"LIN {{{_pos(m.target)}}}{cdis}"
    assert m.aux is not None   # checked in check_program
    return f"CIRC {{{_pos(m.aux)}}},{{{_pos(m.target)}}}{cdis}"


def _comment(text: str) -> str:
    return ("; " + ascii_comment(text)).rstrip()


def _section_title(k: int, sec: KrlSection) -> str:
    mm_s = sec.feed_m_s * 1e3
    title = f"section {k}: {ascii_comment(sec.kind)}, {mm_s:.6f} mm/s"
    if sec.binding:
        title += f", bound by {ascii_comment(sec.binding)}"
    return title


def _render_sections(spec: KrlProgramSpec, sections: Sequence[KrlSection],
                     moves: Sequence[KrlMove], feed_names: list[str]) -> list[PageSection]:
    out: list[PageSection] = []
    lim_vel = CONTROLLERS[spec.controller].vel_cp_max
    marker = f"{spec.name}_SEC" if spec.override_hook != "none" else None
    by_section: list[list[KrlMove]] = [[] for _ in sections]
    for m in moves:
        by_section[m.section].append(m)
    for k, (sec, mv) in enumerate(zip(sections, by_section, strict=True), 1):
        head = [f"{marker} = {k}"] if marker else []
        head.append(f"$VEL.CP = {feed_names[k - 1]} ; "
                    f"{real_literal(float(sec.feed_m_s), FEED_DECIMALS)} m/s, see {spec.name}.dat")
        body: list[str] = []
        breakable: list[bool] = []
        for m in mv:
            if m.feed_scale is not None:
                if sec.feed_m_s * m.feed_scale > lim_vel:
                    raise KrlError(f"section {k} feed", f"{sec.feed_m_s:.10g} m/s x scale "
                                   f"{m.feed_scale:g} is above the $VEL.CP maximum {lim_vel:g} m/s")
                body.append(f"$VEL.CP = {feed_names[k - 1]} * "
                            f"{real_literal(float(m.feed_scale), SCALE_DECIMALS)}")
                breakable.append(m.kind != "CIRC")     # a page starts here, not between the two
            body.append(_motion(m))
            breakable.append(m.kind != "CIRC" and m.feed_scale is None)
        out.append(PageSection(k, _section_title(k, sec), _comment(sec.comment) if sec.comment else "",
                            head, body, breakable))
    return out


def _header(comment: str, src: bool = True) -> list[str]:
    lines = ["&ACCESS RVP", "&REL 1", f"&COMMENT {ascii_comment(comment)[:60]}"]
    if src:
        lines += [r"&PARAM TEMPLATE = C:\KRC\Roboter\Template\vorgabe", "&PARAM EDITMASK = *"]
    return lines


def _preamble(spec: KrlProgramSpec, notes: list[str]) -> list[str]:
    lines = [_comment(c) for c in spec.comments] + notes
    lines += [
        ";FOLD INI",
        "  ;FOLD BASISTECH INI",
        "    GLOBAL INTERRUPT DECL 3 WHEN $STOPMESS==TRUE DO IR_STOPM ( )",
        "    INTERRUPT ON 3",
        "    BAS (#INITMOV,0 )",
        "  ;ENDFOLD (BASISTECH INI)",
        "  ;FOLD USER INI",
        "  ;ENDFOLD (USER INI)",
        ";ENDFOLD (INI)",
        _frame("BASE", spec.base),
        _frame("TOOL", spec.tool),
        "$IPO_MODE = #BASE",
        "$ORI_TYPE = #VAR",
        f"$ADVANCE = {spec.advance}",
        f"$APO.CDIS = {fixed(spec.apo_cdis_mm, 3)} ; mm",
        f"BAS (#VEL_PTP,{fixed(spec.ptp_velocity_pct, 1)} )",
        "PTP $AXIS_ACT ; BCO run",
        f"PTP {{{_axes(spec.bco_axes_deg)}}}",
    ]
    if spec.override_hook != "none":
        lines.append(f"{spec.name}_SEC = 0")
    if spec.override_hook == "rsi":
        lines += ["; RSI context for the supervisor's override (ETHERNET -> MAP2OV_PRO), "
                  "path unchanged",
                  f"CCT_RET = RSI_CREATE(\"{spec.rsi_config}\",CCT_CONT,TRUE)",
                  *_RSI_CHECK,
                  "CCT_RET = RSI_ON(#RELATIVE,#IPO)",
                  *_RSI_CHECK]
    return lines


def _postamble(spec: KrlProgramSpec) -> list[str]:
    lines = []
    if spec.override_hook == "rsi":
        lines += ["CCT_RET = RSI_OFF()", *_RSI_CHECK]
    if spec.override_hook != "none":
        lines.append(f"{spec.name}_SEC = 0")
    if spec.end_axes_deg is not None:
        lines.append(f"PTP {{{_axes(spec.end_axes_deg)}}}")
    return lines


def _decls(spec: KrlProgramSpec, lim: ControllerLimits, pages: Sequence[str]) -> list[str]:
    lines = [f"EXT {p}( )" for p in pages]
    if lim.ext_bas:
        lines.append("EXT BAS (BAS_COMMAND :IN,REAL :IN )")
    if spec.override_hook == "rsi":
        lines += ["DECL INT CCT_RET", "DECL INT CCT_CONT"]
    return lines


def _dat_main(spec: KrlProgramSpec, sections: Sequence[KrlSection], secs: list[PageSection],
              feed_names: list[str], pages: Sequence[str]) -> list[str]:
    lines = _header(f"cctmill feeds of {spec.name}", src=False) + [
        f"DEFDAT {spec.name} PUBLIC",
        f"; cctmill: section feeds $VEL.CP [m/s] of {spec.name}. Retune a section here; the "
        "geometry is in the .src" + (" pages" if pages else "") + ".",
        f"; Keep every value in (0, {CONTROLLERS[spec.controller].vel_cp_max:g}] m/s. The "
        "program override $OV_PRO scales them.",
    ]
    for name, sec, s in zip(feed_names, sections, secs, strict=True):
        lines.append(f"DECL GLOBAL REAL {name}={real_literal(float(sec.feed_m_s), FEED_DECIMALS)}"
                     f" ; {s.title}")
    if spec.override_hook != "none":
        lines.append(f"DECL GLOBAL INT {spec.name}_SEC=0 ; number of the running section "
                     "(0: none), for the supervisor")
    lines.append("ENDDAT")
    return lines


def _crlf(lines: list[str]) -> str:
    return _CRLF.join(lines) + _CRLF


def render_krl(spec: KrlProgramSpec, sections: Sequence[KrlSection],
               moves: Sequence[KrlMove], notes: Sequence[str] = ()) -> KrlOutput:
    """Validate and render a program (no I/O). See the module docstring for the layout.

    Args:
        spec: name, controller, frames, parameters.
        sections: the feed sections, in path order.
        moves: the motions, in order; each names its section.
        notes: extra comment lines written into every ``.src`` after the header comments
            (e.g. that the path is deflection-compensated).

    Raises:
        KrlError: anything KRL cannot hold (names, feeds, numbers, hook on the wrong controller).
    """
    lim = check_program(spec, sections, moves)
    digits = max(3, len(str(len(sections))))
    feed_names = [f"{spec.name}_F{k:0{digits}d}" for k in range(1, len(sections) + 1)]
    for n in feed_names:
        p = identifier_problem(n)
        if p is not None:     # the length was checked in check_program; this guards the rest
            raise KrlError("name", f"feed variable {n} {p}")
    secs = _render_sections(spec, sections, moves, feed_names)
    note_lines = [_comment(n) for n in notes]
    limit = spec.page_lines or lim.page_lines
    body = [line for s in secs for line in section_lines(s, 0, len(s.body), False)]
    name = spec.name
    head = _header(f"cctmill {name}")
    single = (head + [f"DEF {name}( )"] + _decls(spec, lim, ()) + _preamble(spec, note_lines)
              + body + _postamble(spec) + ["END"])
    files: dict[str, str] = {}
    page_names: tuple[str, ...] = ()
    if len(single) <= limit:
        files[f"{name}.src"] = _crlf(single)
        files[f"{name}.dat"] = _crlf(_dat_main(spec, sections, secs, feed_names, ()))
        return KrlOutput(files, page_names, tuple(feed_names))
    if len(name) + 4 > MAX_IDENTIFIER:
        raise KrlError("name", f"the program needs pages {name}_001…, which must stay within "
                       f"{MAX_IDENTIFIER} characters: pass a --name of at most "
                       f"{MAX_IDENTIFIER - 4} characters")
    page_head = len(_header("")) + 3 + len(note_lines)   # header, DEF, 2 comments, notes
    try:
        pages = paginate(secs, limit - page_head - 1)
    except NoPageBreakError as e:
        raise KrlError("moves", f"section {e.section} has a page's worth ({limit} lines) of "
                       "CIRCs without a LIN between them, and a page may not begin with a CIRC; "
                       "split the section or write part of the arcs as LINs") from None
    width = max(3, len(str(len(pages))))
    if len(name) + 1 + width > MAX_IDENTIFIER:
        raise KrlError("name", f"{len(pages)} pages need names {name}_{'0' * width}: pass a "
                       "shorter --name")
    page_names = tuple(f"{name}_{p:0{width}d}" for p in range(1, len(pages) + 1))
    main = (head + [f"DEF {name}( )"] + _decls(spec, lim, page_names)
            + _preamble(spec, note_lines)
            + [f"{p}( ) ; page {i} of {len(pages)}" for i, p in enumerate(page_names, 1)]
            + _postamble(spec) + ["END"])
    if len(main) > limit:
        raise KrlError("moves", f"the main module would need {len(main)} lines for "
                       f"{len(pages)} page calls (limit {limit}); split the job")
    files[f"{name}.src"] = _crlf(main)
    files[f"{name}.dat"] = _crlf(_dat_main(spec, sections, secs, feed_names, page_names))
    for i, (pname, lines) in enumerate(zip(page_names, pages, strict=True), 1):
        nums = [int(x.split()[2].rstrip(")")) for x in lines if x.startswith(";ENDFOLD (section")]
        span = f"sections {nums[0]}-{nums[-1]}" if nums[0] != nums[-1] else f"section {nums[0]}"
        src = (_header(f"cctmill {name} page {i}") + [f"DEF {pname}( )",
               f"; page {i} of {len(pages)} of {name} ({span}); called by {name}.src",
               f"; feeds: {name}.dat"] + note_lines + lines + ["END"])
        files[f"{pname}.src"] = _crlf(src)
        files[f"{pname}.dat"] = _crlf(_header(f"cctmill {name} page {i}", src=False) + [
            f"DEFDAT {pname}", f"; page {i} of {len(pages)} of {name} ({span}); the section "
            f"feeds are in {name}.dat", "ENDDAT"])
    return KrlOutput(files, page_names, tuple(feed_names))


# --------------------------------------------------------------------------- writing
def write_krl(spec: KrlProgramSpec, sections: Sequence[KrlSection], moves: Sequence[KrlMove],
              folder: str | os.PathLike, notes: Sequence[str] = ()) -> list[Path]:
    """Render the program (:func:`render_krl`) and write its files into ``folder``.

    Everything is validated and rendered first; then every file goes to a temporary file beside
    its target and only when all are written are they moved into place, so an error leaves no
    new or changed target file behind.

    Returns:
        the paths written, main ``.src`` and ``.dat`` first, then the pages in call order.

    Raises:
        KrlError: see :func:`render_krl`; ``OSError`` from the file system.
    """
    out = render_krl(spec, sections, moves, notes)
    try:
        data = {k: v.encode("ascii") for k, v in out.files.items()}
    except UnicodeEncodeError as e:   # a bug if it happens: every line is built from ASCII
        raise KrlError("text", f"non-ASCII character in the rendered program ({e})") from e
    target_dir = Path(folder)
    for fname in data:
        target = target_dir / fname
        if target.exists() and not target.is_file():
            raise KrlError("output", f"{target} is in the way and not a file; remove it or "
                           "choose another output folder")
    paths = write_all(target_dir, data)
    remove_stale_pages(target_dir, spec.name, set(out.files))
    return paths
