"""Which APT/CL records the interpreter may pass over (private): the path-neutral words, the
words it refuses by name with what each may change, and the handlers of refused and unknown
records; conventions in :mod:`robot_io.apt.reader`.

Strict mode never skips geometry: a record that moves the tool or changes how later records are
read is either read (``_interp.HANDLERS``) or refused here; only the words in
:data:`PATH_NEUTRAL` are passed over (counted in ``meta["ignored_records"]``). An unknown word may
be anything, so it is refused too. Lenient mode skips refused and unknown records, counts them in
``Toolpath.skipped`` by record name and warns once per name with what it may change.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from robot_io.apt import _records as rc
from robot_io.options import fix
from robot_io.toolpath import ToolpathError

if TYPE_CHECKING:
    from robot_io.apt._interp import Run

__all__ = ["MAY_CHANGE", "PATH_NEUTRAL", "REFUSED", "refuse", "unknown"]

#: Records without effect on the path: text and operator messages, coolant, display, sequence
#: numbers, tool-path headers/footers, stops and dwells (time only), tolerances the CAM used to
#: compute the points (INTOL, OUTTOL, TOLER; LINTOL asks the post to keep the tool tip on the
#: straight line between points, which is how the points are read anyway), M functions
#: (AUXFUN: coolant, clamps; a subprogram is CALSUB, refused) and the clearance plane (used only
#: by motions that are refused).
PATH_NEUTRAL = frozenset({
    "AUXFUN", "CLRSRF", "COOLNT", "DELAY", "DISPLY", "DWELL", "END", "END-OF-PATH", "INSERT",
    "INTOL", "ISTOP", "LEADER", "LINTOL", "MACHIN", "MCHFIN", "OPNAME", "OPSTOP", "OUTTOL",
    "PAINT", "PPLOT", "PPRINT", "REMARK", "REWIND", "SEQNO", "STOP", "TMARK", "TOLER",
    "TOOL PATH",
})

#: What a refused record may change, by kind (the lenient warning says it).
MAY_CHANGE = {
    "move": "may move the tool",
    "frame": "may move or turn the coordinates of later moves",
    "axis": "may change the tool axis of later moves",
    "mode": "may change how the controller runs later moves",
    "flow": "may repeat or skip moves",
    "source": "may move the tool or change how later moves are read",
}

_SOURCE = ("is an APT part-program statement: the file looks like APT source, which an APT "
           "processor turns into CL data (cutter locations) — give the CL file")

#: Records that change the path and are not read: word → (what it does, kind of MAY_CHANGE).
REFUSED: dict[str, tuple[str, str]] = {
    "GOHOME": ("sends the tool to its home position, which the file does not give", "move"),
    "GOCLER": ("sends the tool to the clearance plane", "move"),
    "RETRCT": ("retracts the tool by a distance the post decides", "move"),
    "MOVETO": ("moves the tool", "move"),
    "THREAD": ("cuts a thread (the moves are the controller's)", "move"),
    "PLUNGE": ("sets how the controller plunges", "move"),
    "ORIGIN": ("moves the origin of the coordinates after it", "frame"),
    "TRANS": ("shifts the coordinates after it", "frame"),
    "ROTABL": ("turns the rotary table, so the points after it may be in a turned frame",
               "frame"),
    "ROTATE": ("turns the coordinates or an axis", "frame"),
    "ROTHED": ("turns the head", "axis"),
    "PIVOTZ": ("changes the pivot distance the tool axis turns about", "axis"),
    "VTLAXS": ("makes the tool axis vary over later moves", "axis"),
    "COUPLE": ("couples a rotary axis to the moves after it", "axis"),
    "MODE": ("changes the machining mode the points after it are meant for", "mode"),
    "ARCSLP": ("changes how later arcs are interpolated", "mode"),
    "PREFUN": ("sends a G function (G91, G68, G51, …) that may change how the controller runs "
               "the moves after it", "mode"),
    "OPSKIP": ("makes the moves after it skippable at the controller", "flow"),
    "COPY": ("repeats earlier moves (an APT COPY loop)", "flow"),
    "INDEX": ("marks moves for a COPY loop or indexes a rotary table", "flow"),
    **{w: (_SOURCE, "source") for w in (
        "PSIS", "AUTOPS", "INDIRV", "INDIRP", "GO", "GOLFT", "GORGT", "GOFWD", "GOBACK", "GOUP",
        "GODOWN", "TLLFT", "TLRGT", "TLON", "TLOFPS", "TLONPS", "LOOPST", "LOOPND", "JUMPTO",
        "IF", "CALL", "CALSUB", "DEFSUB", "ENDSUB", "MACRO", "TERMAC")},
}


def refuse(run: Run, rec: rc.Record) -> None:
    """A record that changes the path and is not read: strict raises, lenient skips it."""
    what, kind = REFUSED[rec.word]
    may = MAY_CHANGE[kind]
    if run.strict:
        raise ToolpathError(run.file, rec.line, rec.col, f"{rec.word} {what}; this reader does "
                            f"not read it ({may}), so the path after it would be wrong — remove "
                            "it if it does not apply, or read leniently "
                            f"({fix('strict', False)}) to skip it")
    _skip(run, rec, rec.word, "unsupported_record", f"{rec.word} skipped: it {may}"
          + (" (the move after it starts from an unknown position)" if kind == "move" else ""))
    if kind == "move":
        run.pos = None


def unknown(run: Run, rec: rc.Record) -> None:
    """A record this reader does not know: it may be anything, so strict refuses it."""
    name = rc.short(rec.word)
    args = (rec.args or "").lstrip(" \t")
    source = args.startswith("=")
    if run.strict:
        if source:
            reason = f"{name}=…: an assignment, which {_SOURCE}"
        else:
            reason = (f"unknown record {name!r}: it may move the tool or change how later "
                      "records are read, so it is not skipped; remove it if it has no effect "
                      f"on the path, or read leniently ({fix('strict', False)}) to skip it")
        raise ToolpathError(run.file, rec.line, rec.col, reason)
    _skip(run, rec, name, "unknown_record", f"unknown record {name!r} skipped: it "
          f"{MAY_CHANGE['source']}")


def _skip(run: Run, rec: rc.Record, name: str, category: str, message: str) -> None:
    """Lenient: count ``name`` in ``Toolpath.skipped``; warn at its first occurrence."""
    run.skipped[name] += 1
    if run.skipped[name] == 1:
        run.warn(rec.col, category, message + f" (every {name} is skipped, counted in skipped)")
