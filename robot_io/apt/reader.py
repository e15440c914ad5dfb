"""Read APT/CL cutter-location data (SolidWorks CAM/CAMWorks and Siemens NX styles) into the plain
move model of ``robot_io.toolpath``.

Records and lines
-----------------
A record is ``MAJOR/arg,arg,…`` (or a bare ``MAJOR`` such as ``RAPID``, ``FINI``). ``$$`` starts a
comment; a single ``$`` continues the record on the next physical line (anything after it is
ignored, as in APT source). In the free-text records ``PPRINT``, ``INSERT``, ``PARTNO`` and
``REMARK`` a single ``$`` only continues when it is the last character of the line, otherwise it is
text. A UTF-8 BOM is dropped; files that are not UTF-8 are read as Latin-1 (``meta["encoding"]``).
Error and warning locations use the physical line where the record *starts*; the column is the
physical column of the offending field (1-based), and the message names the continuation line when
the field sits on one. ``Move.source`` is the ``GOTO`` (for arcs: the ``CIRCLE``, for splines:
the ``NURBS``) record.

Conventions (read this before trusting a number)
------------------------------------------------
* SI inside: positions [m], feeds [m/s]. ``UNITS/MM``, ``UNIT/MM``, ``UNITS/INCHES`` (also ``INCH``,
  ``IN``) set the length unit; before the first of them ``default_units`` applies, with a warning.
* Every number of a record is a plain decimal of at most :data:`MAX_NUMBER_CHARS` characters and
  at most :data:`MAX_NUMBER_VALUE` in size (as in the G-code and KRL readers); a larger one is an
  error (strict) or its record is skipped (lenient).
* ``GOTO/x,y,z`` or ``GOTO/x,y,z,i,j,k``: i,j,k is the tool axis, a unit vector from the tool tip
  towards the spindle (normalised; warned about when its norm is off by more than
  :data:`TOOL_AXIS_NORM_TOL`). The tool axis is modal: a ``GOTO`` without i,j,k keeps the last one
  given by a ``GOTO``, ``TLAXIS/i,j,k`` or a ``CSYS`` (below); ``Move.tool_axis`` is ``None`` only
  while none of these has appeared. ``FROM/x,y,z`` sets the position without a move. ``MULTAX``
  (``/ON``, ``/OFF``) is recorded in ``meta["multax"]`` only: the field count decides.
* ``RAPID`` makes the next ``GOTO`` (only that one) a rapid.
* ``FEDRAT/f,MMPM`` and ``FEDRAT/MMPM,f`` (either order), ``IPM``, ``MMPR``, ``IPR``; a bare
  ``FEDRAT/f`` is per minute in the units in force. Per-revolution feeds are modal and converted
  at each move with the spindle speed in force (``SPINDL``); a feed move under a per-revolution
  feed with no spindle speed (never set, or ``SPINDL/OFF``) is an error. A feed move (``GOTO``
  without ``RAPID``, or an arc) before any ``FEDRAT`` is an error (strict) or a warning with
  ``Move.feed = None`` (lenient).
* ``CIRCLE/xc,yc,zc,i,j,k`` (SolidWorks CAM, 6 fields) or
  ``CIRCLE/xc,yc,zc,i,j,k,r,t,f,d,e`` (NX, 11 fields: radius r, total tolerance t, in-tolerance
  ratio f, tool diameter d and corner radius e — NX's CLSF documentation), optionally followed by
  ``TIMES,n``, is an arc from the current position to the end point given by the **next** record,
  which must be a ``GOTO``. **Direction** (``circle_direction``, default ``"auto"``): a 6-field
  CIRCLE turns **counter-clockwise** about i,j,k (right-hand rule), an 11-field (NX) CIRCLE
  **clockwise** about i,j,k (i,j,k is the tool axis when the cut is clockwise, G2, seen from
  the spindle). Evidence, SolidWorks CAM: (1) in the shared files 630 arcs continue the move
  before them tangentially under the counter-clockwise rule and 2 reverse it (the other rule
  swaps the counts), and the hole contours come out as 355° sweeps between 92° lead-in/lead-out
  arcs; (2) aamorim1913/AptPostProcessor (a SolidWorks CAM APT post, clsplit.cpp) writes
  Heidenhain DR+ (counter-clockwise) for an axis along the tool. Evidence, NX — the arcs meet
  the moves around them where these rules say (joins: angle between an arc's end tangent and
  the straight move there; clockwise rule / counter-clockwise rule), under MSYS frames of both
  orientations, so the axis is **not** in another frame than the points (the rule "axis in the
  absolute frame, counter-clockwise" predicts the identity case wrongly): HumMan/CLSFProcessor
  ``samples/`` with MSYS z (x × y) = world −Z — ``cutcom.clsf`` 140 arcs, all 280 joins ≤ 10°
  (the leads) against all 280 ≥ 170°, sweeps 90° against 270°; ``_3_PAZ_125_N2.cls`` 300 arcs,
  500 of 600 joins < 1° and none > 90° against 200 and 400; ``_1_KONTUR_NAR_40_N2.cls`` 19
  arcs, 32 of 38 < 1° and none > 90° against 12 and 26; in ``_2``/``_6``/``_7``/``_10``/
  ``_11_KONTUR…`` the arcs that split one circle into 3–4 pieces sum to one turn (120°/90°
  pieces) against two or three; with an **identity** MSYS, an NX Wire-EDM CLSF
  (``TLDATA/WEDM``, ``TOOL PATH/EXTERNAL_TRIM``, quoted in a public C# test suite): 3 arcs, all
  5 joins 0° against 180°, sweeps 90° against 270°. HumMan/CLSFProcessor's own post
  (FiveAxisKinematics.h) writes G2 when the axis as written points along +x+y+z and G3
  otherwise, and linearises arcs clockwise about it, with no MSYS transform. ``"auto"``
  **refuses** the mixes no sample covers — a 6-field CIRCLE after an NX ``MSYS``, an 11-field
  one after a SolidWorks ``CSYS`` (strict: an error naming both fixes; lenient: the CIRCLE is
  skipped, its GOTO read as a line); ``circle_direction="ccw"`` or ``"cw"`` states the rule for
  every CIRCLE of the file. ``meta["circle_directions"]`` counts the CIRCLEs read by each rule.
  The move is stored with the
  normal turned towards the tool axis (+z when none), so an arc about -z is ``ARC_CW`` about +z,
  as G2 would be. The centre is projected into the start point's plane (``Move.center`` is in
  the start plane; a helix's travel is along the normal). Start and end must lie on the circle
  (and on radius r, when given) within ``max(arc_radius_tol, arc_radius_rtol·r)``. ``TIMES,n``
  (NX helices) is read as n−1 extra full turns; no public source pins n down further, so each one
  is also warned about (``helix_turns``).
* ``CSYS/a1,…,a12`` (SolidWorks CAM) and ``MSYS/…`` (9 numbers: origin, x axis, y axis; or 12) are
  setup frames. The 12 numbers are the APT standard matrix, row by row: ``[a1 a2 a3 a4; a5 a6 a7
  a8; a9 a10 a11 a12]`` = ``[R | t]`` (ICAM's definition of the APT <matrix>), so the **columns**
  of R are the frame's axes and t its origin, both in the coordinates the GOTOs are written in.
  Evidence from the data: in ``solidworkscam_tilted_axis.apt``,
  ``CSYS/0,-0.984808,-0.173648,0,1.,0,0,0,0,-0.173648,.984808,0`` has third column
  (-0.1736, 0, 0.9848) = the i,j,k of every GOTO in the file (its rows do not), R is a proper
  rotation, and the facing passes lie at a constant height along that column (R^T·p: z = −1 mm
  for all points of the first pass). In all 19 CSYS records of the shared files the GOTO i,j,k
  (or +z when a GOTO has none) is R's third column. So SolidWorks CAM writes GOTOs in the
  **world (program) frame** (``TRNTYP/WORLD``) and its CSYS is informational: by default the
  reader keeps every point as written, records each frame in ``meta["frames"]`` and takes the
  CSYS z axis as the modal tool axis (SolidWorks CAM omits i,j,k exactly when it is +z).
  ``apply_frames=True`` is for CL data written in the frame's local coordinates (e.g. NX output
  relative to an MSYS): then every GOTO/FROM/CIRCLE/TLAXIS is mapped into the program frame with
  ``p = R·p_local + t`` (directions with R), which puts several setups into one workpiece frame;
  an MSYS then also sets the modal tool axis to its z axis. Applying frames to a file that
  declares ``TRNTYP/WORLD`` is warned about (the points would be moved twice).
* ``CYCLE/DRILL|DEEP|DEEP2|BRKCHP|TAP|BORE|REAM|…,FEDTO,d,…,MMPM,f,RAPTO,c,RTRCTO,r`` drilling
  cycles are **expanded**: each ``GOTO`` until ``CYCLE/OFF`` is a hole top point p with axis a (its
  i,j,k, else the tool axis in force, else +z); the moves are a rapid to p + r·a (when the tool is
  not already within :data:`CYCLE_POSITION_TOL` of it), a rapid to p + c·a, a feed to p − |d|·a at
  the cycle's feed, and the retract to p + r·a (at the cycle feed for TAP/BORE/REAM, else rapid).
  FEDTO is a depth below the hole point: SolidWorks CAM writes it positive (``FEDTO,2.75344``),
  NX as a negative offset along the tool axis (``FEDTO,-33.0043``; public NX CLSF converters
  compute the bottom as z + FEDTO), so its sign is dropped. ``FEDTO,0`` (both HumMan NX drilling
  samples) is read, with a warning (``zero_depth_cycle``): the feed runs from the RAPTO point to
  the hole point and back — a well-defined move, not a malformed record. NX's forms
  ``CYCLE/DRILL,DEEP,…`` and ``CYCLE/DRILL,BRKCHP,…`` are the DEEP and BRKCHP cycles;
  ``RTRCTO,AUTO`` retracts to the RAPTO point, ``RTRCTO,r,MANUAL`` to r.
  RTRCTO is measured from the hole point along the axis (SolidWorks CAM places the approach GOTO
  exactly there: 27.5 mm above for ``RTRCTO,27.5``, 10 mm along the tilted axis for ``RTRCTO,10``);
  without RTRCTO the tool returns to p + c·a. Pecks (``1STPECK``, ``SUBPECK``, ``STEP``) and
  ``DWELL`` are not modelled (one straight feed in); each cycle is listed in ``meta["cycles"]``.
  ``CYCLE/INIT`` (CAMWorks) is a no-op, ``CYCLE/ON`` re-activates the last cycle. The expanded
  moves carry ``Move.extra = {"cycle": type}``.
* ``SPINDL/n,RPM,CLW`` (any order; ``CCLW``; ``OFF``; ``ON``) sets ``Move.spindle_rpm`` (0 while
  off). ``LOAD/TOOL,n`` (and ``TOOLNO/n``) sets ``Move.tool``. ``CUTTER/d,r,e,f,α,β,h`` (the APT
  cutter), CAMWorks' ``CSI_SET_FLUTE_LENGTH``/``CSI_SET_EXTENSION_LENGTH`` and NX's ``TLDATA`` go to
  ``meta["cutters"]`` (lengths in metres); ``SELECT/TOOL,n`` to ``meta["selected_tools"]``,
  ``PARTNO`` to ``meta["program"]``, ``TRNTYP`` to ``meta["trntyp"]``; ``LOADTL/n`` sets the tool.
* ``CUTCOM/LEFT|RIGHT`` is accepted with a warning (``cutter_compensation``): CL data are the
  tool-centre path and are read as written, without the controller's offset.
* ``GODLTA/d`` moves d along the tool axis in force (+z when none), ``GODLTA/dx,dy,dz`` by the
  delta (turned, not moved, by the frame with ``apply_frames``); ``RAPID`` applies to it.
* **Splines** (NX CLSF): ``NURBS/``, then ``KNOT/k1,…`` records, then ``CNTRL/x,y,z`` records
  are a clamped **cubic** B-spline whose **first control point is the tool position** (not
  written); the knots are the ends of its spans, the first starting at 0 (knot vector
  ``0,0,0,0,k1…kn,kn,kn,kn``), so n knots come with n + 2 CNTRL records. Evidence, from
  ``samples/nurbs.clsf`` of HumMan/CLSFProcessor (NX output, every spline bare ``NURBS/`` with
  CNTRL = KNOT + 2, knots ending at 1): read this way, splines that follow each other with no
  GOTO between join without a gap, tangents 2–6° apart (reading the CNTRLs alone leaves 0.3–0.8
  mm jumps there, up to 3 mm after a GOTO); three checked splines come out parametrised by arc length
  as a fit would be (|C'| constant within 0.3 % and equal to the lengths 21.72, 78.89, 23.53 mm);
  the symmetric lead-out (knots 1/26, 1/2, 25/26, 1) gets equal end legs. A spline ends at its
  last CNTRL. Also accepted: the start point written as the first CNTRL (n + 3 records), when it
  is within :data:`SPLINE_START_TOL` of the tool; ``CNTRL/x,y,z,w``, the rational form (weight
  w > 0, x,y,z the point itself, the tool position weight 1) — the samples carry no weights, so
  this layout is an assumption. The curve becomes LINEAR moves at the feed in force (``RAPID``
  applies), none farther than ``chord_tol`` from it (``_spline.flatten``), ending exactly at the
  last control point, with ``Move.extra = {"spline": n}`` (n counts NURBS records from 0) and the
  NURBS record as source; ``meta["splines"]`` lists them. A decreasing knot, one repeated more
  than 3 times, a first knot <= 0, a last knot not above the one before, other counts, weights
  <= 0 or an unknown start position are errors (lenient: the spline is dropped, the tool put at
  its last control point).
* **Strict mode never skips geometry.** A record that moves the tool or changes how later
  records are read is read or refused by name, saying what it does (``GOHOME``, ``GOCLER``,
  ``RETRCT``, ``ORIGIN``, ``TRANS``, ``ROTABL``, ``ROTATE``, ``PIVOTZ``, ``VTLAXS``, ``MODE``,
  ``PREFUN``, ``COPY``, ``INDEX``, ``THREAD``, non-drilling ``CYCLE`` types, APT source such as
  ``PSIS``, ``AUTOPS``, ``INDIRV``, ``GOFWD``, ``LOOPST`` or assignments: ``_words.REFUSED``), and
  so is an **unknown** record, which may be any of these. Only path-neutral words are passed over
  (``COOLNT``, ``PPRINT``, ``INSERT``, ``REMARK``, ``PAINT``, ``TOOL PATH``, ``END-OF-PATH``,
  ``MACHIN``, ``CLRSRF``, ``OPSTOP``, ``STOP``, ``DELAY``, ``DWELL``, ``SEQNO``, ``OPNAME``,
  ``AUXFUN``, the CAM tolerances ``INTOL``/``OUTTOL``/``TOLER``/``LINTOL``, …:
  ``_words.PATH_NEUTRAL``), counted by name in ``meta["ignored_records"]``. Lenient mode skips
  refused and unknown records, counts them in ``Toolpath.skipped`` by record name and warns once
  per name with what it may change; after a skipped motion the next move's start is unknown.
  Malformed known records raise in strict mode and are skipped, warned about and counted by
  category in lenient mode. ``FINI`` ends the program; later records are counted in
  ``skipped["after_fini"]`` with one warning. Messages naming an option speak the interface in
  use (``robot_io.options.fix``).
* An NX **information listing** header (``Information listing created by : …``, ``Date : …``,
  ``Current work part : …``, ``Node name : …``, up to a rule of ``=``; blank lines) at the top of
  the file, and only there, is passed over and kept in ``meta["listing_header"]``.

``Toolpath.meta``: ``program``, ``units_declared`` [(line, units)], ``frames`` [{record, line,
rotation (3×3, rows), origin_m}], ``trntyp``, ``cutters``, ``selected_tools``, ``cycles``,
``multax``, ``apply_frames``, ``splines``, ``listing_header``, ``circle_directions``,
``record_counts`` (every major word), ``ignored_records`` (the path-neutral ones), ``records``,
``warning_counts`` (all warnings by category, also those beyond
:data:`MAX_WARNINGS_PER_CATEGORY`) and, from :func:`read_apt`, ``encoding``.

Speed: a slice test (or one regex) per record head and one ``fullmatch`` + ``split`` for
all-numeric records; plain floats and tuples while reading, numpy only when the moves are built
(end points as rows of one read-only array). About 50 k records/s on a shared 2-core box (the
12 427-line boss file in 0.24 s CPU). Linear in the input size, also for a 10 MB single line
(field count and number length are capped before any conversion).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from typing import Any

from models.errors import InputError
from robot_io.apt._interp import run_program
from robot_io.apt._records import (
    ARC_MIN_RADIUS,
    CHORD_TOL,
    CYCLE_POSITION_TOL,
    FRAME_ORTHONORMAL_TOL,
    INCH,
    MAX_ARC_TURNS,
    MAX_NUMBER_CHARS,
    MAX_NUMBER_VALUE,
    MAX_RECORD_FIELDS,
    MAX_SPLINE_MOVES,
    MAX_WARNINGS_PER_CATEGORY,
    MM,
    SPLINE_START_TOL,
    TOOL_AXIS_NORM_TOL,
)
from robot_io.toolpath import (
    ARC_RADIUS_RTOL,
    ARC_RADIUS_TOL,
    Toolpath,
    check_option_names,
    read_source_text,
)

__all__ = [
    "ARC_MIN_RADIUS",
    "AptOptions",
    "AptReader",
    "CHORD_TOL",
    "CIRCLE_DIRECTIONS",
    "CYCLE_POSITION_TOL",
    "FRAME_ORTHONORMAL_TOL",
    "INCH",
    "MAX_ARC_TURNS",
    "MAX_NUMBER_CHARS",
    "MAX_NUMBER_VALUE",
    "MAX_RECORD_FIELDS",
    "MAX_SPLINE_MOVES",
    "MAX_WARNINGS_PER_CATEGORY",
    "MM",
    "SPLINE_START_TOL",
    "TOOL_AXIS_NORM_TOL",
    "read_apt",
    "read_apt_text",
]


#: The values of the ``circle_direction`` option.
CIRCLE_DIRECTIONS = ("auto", "ccw", "cw")


# --------------------------------------------------------------------------- options
@dataclass(frozen=True)
class AptOptions:
    """Options of the APT/CL reader (SI).

    Attributes:
        default_units: units before the first ``UNITS`` record, ``"mm"`` or ``"inch"``.
        apply_frames: map GOTO/CIRCLE/FROM/TLAXIS data through the last CSYS/MSYS frame (for CL
            data written in local setup coordinates); default keeps points as written.
        circle_direction: which way a CIRCLE turns about its i,j,k: ``"auto"`` (by layout: 11
            fields, NX, clockwise; 6 fields, SolidWorks CAM, counter-clockwise; refused when the
            file's frame record is the other system's), ``"ccw"`` or ``"cw"`` for every CIRCLE.
        arc_radius_tol: allowed start/end (and given-radius) mismatch of a CIRCLE [m].
        arc_radius_rtol: the same relative to the radius [-]; the larger of the two applies.
        chord_tol: largest distance of a spline's linear moves from the curve [m] (the planner
            passes the job's ``[path] chord_tol_mm``).
    """

    default_units: str = "mm"
    apply_frames: bool = False
    circle_direction: str = "auto"
    arc_radius_tol: float = ARC_RADIUS_TOL
    arc_radius_rtol: float = ARC_RADIUS_RTOL
    chord_tol: float = CHORD_TOL

    @classmethod
    def from_kwargs(cls, **options: Any) -> AptOptions:
        """Validate reader keyword options; unknown names raise :class:`InputError`."""
        check_option_names(cls, options, "APT")
        if options.get("default_units", "mm") not in ("mm", "inch"):
            raise InputError("default_units", "must be 'mm' or 'inch'")
        if options.get("apply_frames", False) not in (True, False):
            raise InputError("apply_frames", "must be True or False")
        if options.get("circle_direction", "auto") not in CIRCLE_DIRECTIONS:
            raise InputError("circle_direction", "must be one of "
                             + ", ".join(repr(d) for d in CIRCLE_DIRECTIONS))
        for k in ("arc_radius_tol", "arc_radius_rtol"):
            v = options.get(k, 0.0)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                raise InputError(k, "must be a finite number >= 0")
        v = options.get("chord_tol", CHORD_TOL)
        if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
            raise InputError("chord_tol", "must be a finite number > 0 (metres)")
        return cls(**options)


# --------------------------------------------------------------------------- public entry points
def read_apt_text(text: str, file: str = "<string>", strict: bool = True,
                  **options: Any) -> Toolpath:
    """Read APT/CL data from a string. See the module docstring for conventions.

    Args:
        text: the CL data.
        file: name used in messages and ``SourceRef``.
        strict: raise :class:`ToolpathError` on the first malformed, refused or unknown record
            (default); ``False`` warns, skips it and counts it in ``Toolpath.skipped``.
        **options: fields of :class:`AptOptions` (``default_units``, ``apply_frames``,
            ``circle_direction``, ``arc_radius_tol`` [m], ``arc_radius_rtol``, ``chord_tol`` [m]).
    """
    opts = AptOptions.from_kwargs(**options)
    return run_program(text, file, strict, opts)


def read_apt(path: str | os.PathLike[str], strict: bool = True, **options: Any) -> Toolpath:
    """Read an APT/CL file (UTF-8, falling back to Latin-1). Same arguments as
    :func:`read_apt_text`; ``meta["encoding"]`` records the decoding used."""
    file = os.fspath(path)
    opts = AptOptions.from_kwargs(**options)
    text, encoding = read_source_text(file)
    tp = run_program(text, file, strict, opts)
    tp.meta["encoding"] = encoding
    return tp


class AptReader:
    """The APT/CL member of the ``ToolpathReader`` family."""

    format = "apt"
    suffixes = (".apt", ".cl", ".cls", ".aptsource")

    @staticmethod
    def sniff(head: str) -> bool:
        """Whether the first KiB of a file (upper-cased) look like APT/CL."""
        return "GOTO/" in head or "FEDRAT/" in head or "PARTNO" in head

    def read(self, path: str, strict: bool = True, **options: Any) -> Toolpath:
        """Read ``path``; options as :func:`read_apt`."""
        return read_apt(path, strict=strict, **options)

