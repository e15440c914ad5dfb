"""The plan.json schema: one typed model of the document :meth:`planner.plan_file.Plan.save` writes
and :func:`planner.plan_file.load_plan` reads, so a hand-edited or damaged file is refused with the
JSON path of the bad value instead of failing somewhere in the exporter or the supervisor.

:func:`validate_document` checks, in order:

- nesting: at most :data:`MAX_DEPTH` levels of arrays and objects (:func:`json_depth` scans the
  text before it is parsed; a 1,000-deep array cannot reach a recursive parser);
- types (pydantic, strict: ``"3"`` is not a number, ``1`` is not ``true``), unknown keys (a typo is
  not silently ignored), numbers finite where physics needs them (JSON's ``NaN``/``Infinity``
  tokens are refused), times and lengths ≥ 0, speeds > 0 and feeds at most
  :data:`FEED_MAX_MM_S`; ``null`` only where the writer writes it (a missing value);
- consistency: ``sections[k].index == k + 1`` (sections are numbered from 1, as the KRL program
  and the report number them), the sections partition the samples
  (``0 = start_0 < stop_0 = start_1 < … < stop_last = n`` with n the rows of ``samples.npz``),
  ``s_start_m ≤ s_end_m``, a null feed only in a rapid section, a characteristic's arrays as long
  as its ``feeds_mm_s``, ``feed_min_mm_s ≤ feed_max_mm_s``.

The first problem is raised as a :class:`planner.plan_file.PlanFileError` of one line,
``plan.json: json.path: what it must be, got value; the fix``, its ``where`` the JSON path.
:mod:`planner.plan_file` imports this module when it first reads a plan (and this module imports
the error from it), so importing the plan file does not load pydantic.
"""

from __future__ import annotations

import difflib
import math
import re
import typing
from collections.abc import Callable
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, PlainValidator, ValidationError
from pydantic_core import PydanticCustomError

from planner.plan_file import PlanFileError

__all__ = [
    "FEED_MAX_MM_S",
    "MAX_DEPTH",
    "CharacteristicDoc",
    "ConstraintsDoc",
    "FrameDoc",
    "ImportWarningDoc",
    "PlanDocument",
    "PlanWarningDoc",
    "SectionDoc",
    "SolverDoc",
    "check_sample_count",
    "json_depth",
    "validate_document",
]

#: The largest feed or path speed a plan may hold [mm/s]: 10 m/s, five times the fastest $VEL.CP
#: a KUKA controller takes (2 m/s); anything above is a unit slip or a damaged file, not a plan.
FEED_MAX_MM_S = 10_000.0
#: Deepest nesting of arrays and objects in a plan.json: the writer's deepest value is 5 levels
#: down (``sections[k].characteristic.feeds_mm_s[j]``); 32 leaves room for ``summary``/``model``
#: and stops a nesting bomb before a recursive parser or writer meets it.
MAX_DEPTH = 32
#: How much of a bad value a message shows [characters].
_SHOW_CHARS = 40


class _Problem(Exception):
    """One broken rule: the JSON path of the value and what is wrong (``count``: how many
    problems there are in all). :func:`validate_document` raises it as a ``PlanFileError``."""

    def __init__(self, where: str, problem: str, count: int = 1) -> None:
        super().__init__(where, problem)
        self.where, self.problem, self.count = where, problem, count

    def error(self, file: str) -> PlanFileError:
        n = self.count - 1
        more = f" (and {n} more problem{'s' if n > 1 else ''})" if n else ""
        return PlanFileError(file, f"{self.where}: {self.problem}{more}; {PlanFileError.REPLAN}",
                             where=self.where)


# -- value types ------------------------------------------------------------------------------
def _number(what: str, lo: float | None = None, lo_open: bool = False,
            hi: float | None = None) -> Callable[[Any], float]:
    """The check of a JSON number (not a bool, not a string) that is finite and in range."""

    def check(v: Any) -> float:
        ok = isinstance(v, int | float) and not isinstance(v, bool)
        if ok:
            try:
                f = float(v)
            except OverflowError:         # an integer of 400 digits
                f = math.inf
            ok = (math.isfinite(f) and (lo is None or (f > lo if lo_open else f >= lo))
                  and (hi is None or f <= hi))
        if not ok:
            raise PydanticCustomError("plan_number", f"must be {what}")
        return f

    return check


def _integer(lo: int) -> Callable[[Any], int]:
    """The check of a JSON integer (not a bool, not 3.0) of at least ``lo``."""

    def check(v: Any) -> int:
        if not (isinstance(v, int) and not isinstance(v, bool) and v >= lo):
            raise PydanticCustomError("plan_integer", f"must be an integer ≥ {lo}")
        return v

    return check


_Finite = Annotated[float, PlainValidator(_number("a finite number"))]
_NonNeg = Annotated[float, PlainValidator(_number("a finite number ≥ 0", 0.0))]
_Positive = Annotated[float, PlainValidator(_number("a positive finite number", 0.0, True))]
_Feed = Annotated[float, PlainValidator(_number(
    f"a positive finite number up to {FEED_MAX_MM_S:g} mm/s", 0.0, True, FEED_MAX_MM_S))]
_FeedOrZero = Annotated[float, PlainValidator(_number(
    f"a finite number from 0 to {FEED_MAX_MM_S:g} mm/s", 0.0, False, FEED_MAX_MM_S))]
_Index = Annotated[int, PlainValidator(_integer(0))]
#: A section's number: 1 for the first section (sample indices count from 0).
_Number = Annotated[int, PlainValidator(_integer(1))]
_Flutes = Annotated[int, PlainValidator(_integer(1))]
_Str = Annotated[str, Field(strict=True)]
_Bool = Annotated[bool, Field(strict=True)]
#: A characteristic's value at one feed: null where it was not evaluated (NaN in the plan).
_Element = Annotated[float, Field(strict=True, allow_inf_nan=False)] | None


class _Doc(BaseModel):
    model_config = ConfigDict(strict=True, extra="forbid", frozen=True)


class FrameDoc(_Doc):
    """``base_frame`` / ``tool_frame``: origin [mm] and KUKA A, B, C [deg]."""

    xyz_mm: Annotated[list[_Finite], Field(min_length=3, max_length=3)]
    abc_deg: Annotated[list[_Finite], Field(min_length=3, max_length=3)]


class ConstraintsDoc(_Doc):
    """``constraints`` (:meth:`planner.limits.Limits.as_json`); null or missing: no such limit."""

    force_max_N: _Positive | None = None
    deflection_tol_mm: _Positive | None = None
    power_max_kW: _Positive | None = None
    feed_min_mm_s: _FeedOrZero | None = None
    feed_max_mm_s: _Feed | None = None
    feed_change_max_mm_s: _Feed | None = None
    margin_min_N_per_m: _Finite | None = None
    section_length_min_mm: _NonNeg | None = None
    path_acc_max_m_s2: _Positive | None = None
    path_jerk_max_m_s3: _Positive | None = None
    rapid_mm_s: _Feed | None = None
    cam_feed_scale_max: _Positive | None = None
    safety_factor: _Positive | None = None
    deflection_model_uncertainty: _NonNeg | None = None
    compensate_deflection: _Bool | None = None


class CharacteristicDoc(_Doc):
    """A cut section's ``characteristic`` (:class:`planner.plan_file.SectionCharacteristic`)."""

    sample: _Index | None = None
    feeds_mm_s: Annotated[list[_Feed], Field(min_length=1)]
    margin_N_per_m: list[_Element]
    gamma_deg: list[_Element] | None = None
    force_N: list[_Element]
    deflection_mm: list[_Element] | None = None
    stable: list[_Bool] | None = None
    ok: list[_Bool] | None = None


_Pair = Annotated[list[_Finite], Field(min_length=2, max_length=2)]
#: Lists of a fixed length, by key.
_EXACT_LENGTH = {"xyz_mm": 3, "abc_deg": 3, "gamma_range_deg": 2, "natural_frequency_hz": 2}
#: Lists that may not be empty, by key: what they hold.
_AT_LEAST_ONE = {"sections": "section", "feeds_mm_s": "feed"}


class SectionDoc(_Doc):
    """One of ``sections`` (:class:`planner.plan_file.PlanSection`, units in the key names)."""

    index: _Number               # the section's number, 1 for the first
    kind: Literal["cut", "air", "rapid"]
    sample_start: _Index
    sample_stop: _Index
    s_start_m: _NonNeg
    s_end_m: _NonNeg
    feed_mm_s: _Feed | None      # null: no planned feed (a rapid runs at the controller's speed)
    binding: _Str
    length_m: _NonNeg | None = None
    process_binding: _Str | None = None
    note: _Str | None = None
    line_start: _Index | None = None
    line_end: _Index | None = None
    file: _Str | None = None
    time_s: _NonNeg | None = None
    process_time_s: _NonNeg | None = None
    robot_limited: _Bool | None = None
    tooth_frequency_hz: _Positive | None = None
    margin_N_per_m: _Finite | None = None
    force_max_N: _NonNeg | None = None
    deflection_max_mm: _NonNeg | None = None
    deflection_normal_max_mm: _NonNeg | None = None
    power_max_kW: _Finite | None = None
    gamma_deg: _Finite | None = None
    gamma_range_deg: _Pair | None = None
    natural_frequency_hz: _Pair | None = None
    ceiling_min_mm_s: _NonNeg | None = None
    tightest_sample: _Index | None = None
    characteristic: CharacteristicDoc | None = None


class SolverDoc(_Doc):
    """``solver`` (:class:`planner.plan_file.SolverRecord`)."""

    status: _Str
    success: _Bool
    iterations: _Index | None = None
    build_time_s: _NonNeg | None = None
    solve_time_s: _NonNeg | None = None
    objective: _Finite | None = None


class ImportWarningDoc(_Doc):
    """One of ``import_warnings`` (:class:`robot_io.diagnostics.WarningGroup`)."""

    kind: _Str
    count: _Index
    first: _Str
    message: _Str


class PlanWarningDoc(_Doc):
    """One of ``warnings`` (:class:`planner.tool_limits.PlanWarning`)."""

    kind: _Str
    message: _Str


class PlanDocument(_Doc):
    """A whole plan.json (``docs/planner.md``, "The plan file")."""

    format: Literal["cctmill-plan"]
    version: Literal[2]
    method: _Str
    job_name: _Str | None = None
    job_folder: _Str | None = None
    job_file: _Str | None = None          # what older plans call job_folder
    robot: _Str | None = None
    files: list[_Str] = []
    base_frame: FrameDoc
    tool_frame: FrameDoc
    spindle_rpm: _Positive | None = None
    flutes: _Flutes | None = None
    tool_diameter_mm: _Positive | None = None
    material: _Str | None = None
    model: dict[_Str, Any] = {}
    constraints: ConstraintsDoc
    sections: Annotated[list[SectionDoc], Field(min_length=1)]
    cycle_time_s: _NonNeg
    process_time_s: _NonNeg | None = None
    solver: SolverDoc
    wall_times_s: dict[_Str, _NonNeg] = {}
    summary: dict[_Str, Any] = {}
    import_warnings: list[ImportWarningDoc] = []
    warnings: list[PlanWarningDoc] = []
    samples_file: Annotated[str, Field(strict=True, pattern=r"^[^/\\]+\.npz$")]


# -- checking ---------------------------------------------------------------------------------
_STRING = re.compile(r'"[^"\\]*(?:\\.[^"\\]*)*"')
_BRACKET = re.compile(r"[\[\]{}]")


def json_depth(text: str, limit: int = MAX_DEPTH) -> int:
    """How deep arrays and objects nest in a JSON text (brackets inside strings do not count),
    counting only up to ``limit + 1``: a text deeper than ``limit`` is refused before parsing."""
    depth = top = 0
    for m in _BRACKET.finditer(_STRING.sub('""', text)):
        if m.group() in "[{":
            depth += 1
            if depth > top:
                top = depth
                if top > limit:
                    break
        else:
            depth -= 1
    return top


def _path(loc: tuple[Any, ...]) -> str:
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        elif part == "[key]":
            continue
        elif re.fullmatch(r"[A-Za-z_]\w*", str(part)):
            out += f".{part}" if out else str(part)
        else:
            out += f"[{str(part)!r}]"
    return out


def _show(v: Any) -> str:
    s = repr(v)
    return s if len(s) <= _SHOW_CHARS else s[:_SHOW_CHARS - 3] + "..."


def _model_in(tp: Any) -> type[BaseModel] | None:
    """The schema model inside a field's type (``list[SectionDoc]``, ``FrameDoc | None``, …)."""
    if isinstance(tp, type) and issubclass(tp, BaseModel):
        return tp
    for arg in typing.get_args(tp):
        found = _model_in(arg)
        if found is not None:
            return found
    return None


def _known(loc: tuple[Any, ...]) -> list[str]:
    """The keys the object holding ``loc[-1]`` may have."""
    model: type[BaseModel] | None = PlanDocument
    for part in loc[:-1]:
        if isinstance(part, str):
            field = model.model_fields.get(part) if model is not None else None
            model = None if field is None else _model_in(field.annotation)
    return [] if model is None else list(model.model_fields)


def _problem(err: dict[str, Any]) -> str:
    kind, ctx, got = err["type"], err.get("ctx") or {}, _show(err.get("input"))
    loc = tuple(err["loc"])
    if kind == "missing":
        return "missing"
    if kind == "extra_forbidden":
        close = difflib.get_close_matches(str(loc[-1]), _known(loc), n=1, cutoff=0.6)
        return "unknown key" + (f"; did you mean {close[0]!r}?" if close else "")
    what = {
        "plan_number": err["msg"], "plan_integer": err["msg"], "string_type": "must be a string",
        "bool_type": "must be true or false", "list_type": "must be a list",
        "model_type": "must be an object", "dict_type": "must be an object",
        "float_type": "must be a number or null", "finite_number": "must be a finite number or null",
        "literal_error": f"must be {ctx.get('expected', 'one of the listed values')}",
        "string_pattern_mismatch": "must be a file name ending .npz beside plan.json",
    }.get(kind)
    if what is None and kind in ("too_short", "too_long"):
        what = _length_rule(err)
    if what is None:
        what = str(err["msg"]).lower()
    return f"{what}, got {got}"


def _length_rule(err: dict[str, Any]) -> str:
    ctx = err.get("ctx") or {}
    key = str(err["loc"][-1])
    if key in _EXACT_LENGTH:
        return f"must hold {_EXACT_LENGTH[key]} numbers"
    if key in _AT_LEAST_ONE and err["type"] == "too_short":
        return f"must hold at least one {_AT_LEAST_ONE[key]}"
    if err["type"] == "too_short":
        return f"must hold at least {ctx.get('min_length')} value(s)"
    return f"must hold at most {ctx.get('max_length')} value(s)"


def _consistency(doc: PlanDocument) -> None:
    """The rules across values: numbering, the partition of the samples, array lengths."""
    lo_f, hi_f = doc.constraints.feed_min_mm_s, doc.constraints.feed_max_mm_s
    if lo_f is not None and hi_f is not None and lo_f > hi_f:
        raise _Problem("constraints.feed_min_mm_s",
                       f"must not exceed feed_max_mm_s {hi_f:g}, got {lo_f:g}")
    expect = 0
    for k, sec in enumerate(doc.sections):
        at = f"sections[{k}]"
        if sec.index != k + 1:
            raise _Problem(f"{at}.index", f"must be {k + 1} (sections are numbered 1, 2, … in "
                           f"path order), got {sec.index}")
        if sec.sample_start != expect:
            where = "0, the first sample" if k == 0 else f"{expect}, where sections[{k - 1}] stops"
            raise _Problem(f"{at}.sample_start", f"must be {where} (the sections partition the "
                           f"samples), got {sec.sample_start}")
        if sec.sample_stop <= sec.sample_start:
            raise _Problem(f"{at}.sample_stop",
                           f"must be above sample_start {sec.sample_start}, got {sec.sample_stop}")
        expect = sec.sample_stop
        if sec.s_end_m < sec.s_start_m:
            raise _Problem(f"{at}.s_end_m",
                           f"must not be below s_start_m {sec.s_start_m:g}, got {sec.s_end_m:g}")
        if sec.feed_mm_s is None and sec.kind != "rapid":
            raise _Problem(f"{at}.feed_mm_s", f"must be a positive finite number up to "
                           f"{FEED_MAX_MM_S:g} mm/s (null only in a rapid section), got None")
        ch = sec.characteristic
        if ch is not None:
            m = len(ch.feeds_mm_s)
            for key in ("margin_N_per_m", "gamma_deg", "force_N", "deflection_mm", "stable", "ok"):
                v = getattr(ch, key)
                if v is not None and len(v) != m:
                    raise _Problem(f"{at}.characteristic.{key}",
                                   f"must hold {m} values, one per feeds_mm_s, got {len(v)}")


def check_sample_count(doc: PlanDocument, n_samples: int, file: str = "plan.json") -> None:
    """The rules that need the rows of ``samples.npz``: the sections end at the last sample, and
    the sample indices a section names are samples.

    Raises:
        PlanFileError: the first problem, naming ``file`` and the JSON path.
    """
    try:
        _sample_count(doc, n_samples)
    except _Problem as e:
        raise e.error(file) from None


def _sample_count(doc: PlanDocument, n_samples: int) -> None:
    last = len(doc.sections) - 1
    if doc.sections[last].sample_stop != n_samples:
        raise _Problem(f"sections[{last}].sample_stop",
                       f"must be {n_samples}, the samples in {doc.samples_file} (the sections "
                       f"partition the samples), got {doc.sections[last].sample_stop}")
    for k, sec in enumerate(doc.sections):
        ch = sec.characteristic
        for where, v in (("tightest_sample", sec.tightest_sample),
                         ("characteristic.sample", None if ch is None else ch.sample)):
            if v is not None and v >= n_samples:
                raise _Problem(f"sections[{k}].{where}", f"must be a sample below {n_samples}, got {v}")


def validate_document(data: Any, n_samples: int | None = None,
                      file: str = "plan.json") -> PlanDocument:
    """A parsed plan.json, checked against the schema and its consistency rules.

    Args:
        data: the parsed JSON document.
        n_samples: the rows of its ``samples.npz`` (None: the partition's end is not checked).
        file: how messages name the document.

    Raises:
        PlanFileError: the first problem, ``file: json.path: what it must be, got value; fix``
            (``where``: the JSON path).
    """
    try:
        try:
            doc = PlanDocument.model_validate(data)
        except ValidationError as e:
            errs = e.errors(include_url=False)
            first = errs[0]
            raise _Problem(_path(tuple(first["loc"])), _problem(first), len(errs)) from None
        _consistency(doc)
        if n_samples is not None:
            _sample_count(doc, n_samples)
    except _Problem as e:
        raise e.error(file) from None
    return doc
