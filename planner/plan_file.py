"""The plan: one typed object in SI from the optimiser to the exporter and the supervisor, and its
files ``plan.json`` + ``samples.npz`` (the only place its units are mm, degrees and kW).

:class:`Plan` is made in memory by :meth:`Plan.from_result` (no disk round trip), written by
:meth:`Plan.save` and read back by :func:`load_plan`. Every consumer — the KRL exporter, the
supervisor, the simulated cut, the demo — takes a :class:`Plan`. The file contract is in
``docs/planner.md`` ("plan.json"); in short, ``plan.json`` (``format`` ``"cctmill-plan"``,
``version`` 2) holds the job's identity, ``base_frame``/``tool_frame`` (``xyz_mm``, ``abc_deg``),
``constraints`` (:class:`planner.limits.Limits`), the ``sections`` (one object per
:class:`PlanSection`, units in the key names), ``cycle_time_s``, ``process_time_s``, ``solver``,
``wall_times_s``, ``summary``, ``import_warnings``, ``warnings`` and ``samples_file``;
``samples.npz`` one array per :data:`SAMPLE_ARRAYS` entry (and the optional ones of
:data:`SAMPLE_EXTRA`). :func:`load_plan` checks the document against :mod:`planner.plan_schema`
(types, ranges, the partition of the samples) before it converts anything.

Sections are numbered from 1 wherever a file or a person sees them — plan.json's ``index``,
samples.npz's ``section``, the KRL folds and ``.dat``, the report, the supervisor's log — and
held from 0 in memory (:attr:`PlanSection.index`, a position in :attr:`Plan.sections`;
:attr:`PlanSection.number` is the one people see). Version 1 files numbered them from 0 and are
refused (:data:`SECTIONS_FROM_ZERO_VERSION`).
"""

from __future__ import annotations

import json
import math
import os
import zipfile
import zlib
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from models.errors import DataFileError
from planner._atomic import atomic_path, write_text_atomic
from planner.limits import Limits
from planner.plan_samples import SAMPLE_ARRAYS, SAMPLE_EXTRA, PlanSamples, from_file_unit, to_file_unit
from planner.tool_limits import PlanWarning
from robot_io.diagnostics import WarningGroup

__all__ = [
    "BINDINGS",
    "FORMAT",
    "FRAME_DECIMALS",
    "KINDS",
    "SAMPLE_ARRAYS",
    "SAMPLE_EXTRA",
    "SECTIONS_FROM_ZERO_VERSION",
    "VERSION",
    "Plan",
    "PlanFileError",
    "PlanSamples",
    "PlanSection",
    "SectionCharacteristic",
    "SolverRecord",
    "load_plan",
    "write_plan",
]

FORMAT = "cctmill-plan"
#: Version 2: sections numbered from 1 in plan.json and samples.npz.
VERSION = 2
#: The last plan.json version that numbered sections from 0 (refused, with the fix).
SECTIONS_FROM_ZERO_VERSION = 1
#: What can bind a section's feed.
BINDINGS = ("chatter", "force", "deflection", "power", "robot", "feed_max", "feed_change",
            "cam_feed", "rapid", "tool")
#: Section / sample kinds, in the order of their integer codes in ``samples.npz``.
KINDS = ("cut", "air", "rapid")
#: Decimals of a frame's mm and degree values in plan.json: the frame is the job's, typed in mm
#: and degrees; 1e-9 mm / 1e-9° keeps what the user wrote and drops the float noise of mm → m → mm.
FRAME_DECIMALS = 9

#: numpy dtype kinds a samples array may have: bool, integers, floats.
_NUMERIC = "biuf"


class PlanFileError(DataFileError):
    """A plan file is missing, malformed, or not a cctmill plan.

    Attributes:
        path: the file.
        where: the JSON path of the bad value (``sections[3].feed_mm_s``), or None.
    """

    #: The fix for a plan file that is not as cctmill wrote it.
    REPLAN = "fix it or plan the job again (cctmill plan JOB.toml -o DIR)"

    def __init__(self, path: str, message: str, where: str | None = None) -> None:
        super().__init__(path, message)
        self.where = where


def _opt(v: Any) -> float | None:
    return None if v is None else float(v)


@dataclass(frozen=True)
class SectionCharacteristic:
    """A cut section's stability characteristic at its tightest sample.

    Attributes:
        sample: the path sample it was evaluated at.
        feeds: feeds [m/s], shape (k,), increasing.
        margin: chatter margin [N/m], (k,).
        gamma: γ [rad], (k,).
        force: resultant average force [N], (k,).
        stable: the criterion's verdict, (k,) bool.
        deflection: ‖δ‖ [m], (k,) (None in synthetic plans).
        ok: every limit met, (k,) bool (None in synthetic plans).
    """

    sample: int
    feeds: np.ndarray
    margin: np.ndarray
    gamma: np.ndarray
    force: np.ndarray
    stable: np.ndarray
    deflection: np.ndarray | None = None
    ok: np.ndarray | None = None

    def as_json(self) -> dict[str, Any]:
        out = {"sample": self.sample, "feeds_mm_s": (self.feeds * 1e3).tolist(),
               "margin_N_per_m": self.margin.tolist(), "gamma_deg": np.degrees(self.gamma).tolist(),
               "force_N": self.force.tolist(), "deflection_mm": to_file_unit(self.deflection, 1e3),
               "stable": self.stable.tolist(), "ok": self.ok}
        return {k: v.tolist() if isinstance(v, np.ndarray) else v for k, v in out.items()
                if v is not None}

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> SectionCharacteristic:
        """Raises ``KeyError``/``TypeError``/``ValueError`` for a malformed object."""
        feeds = np.asarray(d["feeds_mm_s"], float) * 1e-3
        k = feeds.size

        def arr(key: str, scale: float = 1.0, dtype: type = float) -> np.ndarray:
            a = np.asarray(d[key], dtype) * scale if dtype is float else np.asarray(d[key], dtype)
            if a.shape != (k,):
                raise ValueError(f"characteristic {key} has shape {a.shape}, expected ({k},)")
            return a

        def has(key: str) -> bool:
            return d.get(key) is not None

        sample = d.get("sample")
        return cls(sample=-1 if sample is None else int(sample), feeds=feeds,
                   margin=arr("margin_N_per_m"),
                   gamma=np.radians(arr("gamma_deg")) if has("gamma_deg") else np.full(k, np.nan),
                   force=arr("force_N"),
                   stable=arr("stable", dtype=bool) if has("stable") else np.ones(k, bool),
                   deflection=arr("deflection_mm", 1e-3) if has("deflection_mm") else None,
                   ok=arr("ok", dtype=bool) if has("ok") else None)


@dataclass(frozen=True)
class PlanSection:
    """One section of the plan, SI (None: not evaluated, e.g. air and rapid sections).

    Attributes:
        index: position in :attr:`Plan.sections`, from 0 (files and people see :attr:`number`).
        kind: ``"cut"``, ``"air"`` or ``"rapid"``.
        sample_start, sample_stop: the samples it covers, ``[start, stop)``.
        s_start, s_end: arc length at its ends [m]; length: its length [m].
        feed: planned feed [m/s] (the ``$VEL.CP`` of the section; in a feed profile the base the
            samples' ``feed`` is a multiple of).
        binding: what holds it back (:data:`BINDINGS`), ``robot`` when the timed speed stays under
            90 % of the feed; process_binding: what binds the feed itself.
        note: why the feed is what it is, for people.
        line_start, line_end, file: where in the CAM program it comes from.
        time: toppra-timed duration [s]; process_time: length / feed [s].
        robot_limited: the robot's joint limits hold the timed speed under the feed.
        tooth_frequency: tooth-passing frequency [Hz].
        margin: least chatter margin over the section [N/m]; force_max [N]; deflection_max,
            deflection_normal_max [m]; power_max [W].
        gamma: γ at the tightest sample [rad]; gamma_range: (lo, hi) over the section [rad].
        natural_frequencies: (f1, f2) at the tightest sample [Hz] (None for the isotropic mass).
        ceiling_min: the tightest sample's feed ceiling [m/s]; tightest_sample: its index.
        characteristic: the stability characteristic at the tightest sample.
    """

    index: int
    kind: str
    sample_start: int
    sample_stop: int
    s_start: float
    s_end: float
    feed: float
    binding: str
    length: float | None = None
    process_binding: str | None = None
    note: str | None = None
    line_start: int | None = None
    line_end: int | None = None
    file: str | None = None
    time: float | None = None
    process_time: float | None = None
    robot_limited: bool | None = None
    tooth_frequency: float | None = None
    margin: float | None = None
    force_max: float | None = None
    deflection_max: float | None = None
    deflection_normal_max: float | None = None
    power_max: float | None = None
    gamma: float | None = None
    gamma_range: tuple[float, float] | None = None
    natural_frequencies: tuple[float, float] | None = None
    ceiling_min: float | None = None
    tightest_sample: int | None = None
    characteristic: SectionCharacteristic | None = None

    @property
    def number(self) -> int:
        """The section's number as files and people see it: 1 for the first section (the KRL
        fold ``section 1``, ``NAME_F001``, plan.json ``index`` 1, the report's row 1)."""
        return self.index + 1

    def as_json(self) -> dict[str, Any]:
        """The section's plan.json object (units in the key names; ``index`` is its
        :attr:`number`, from 1)."""
        out: dict[str, Any] = {
            "index": self.number, "kind": self.kind, "sample_start": self.sample_start,
            "sample_stop": self.sample_stop, "s_start_m": self.s_start, "s_end_m": self.s_end,
            "length_m": self.length, "feed_mm_s": self.feed * 1e3, "binding": self.binding,
            "process_binding": self.process_binding, "note": self.note,
            "line_start": self.line_start, "line_end": self.line_end, "file": self.file,
            "time_s": self.time, "process_time_s": self.process_time,
            "robot_limited": self.robot_limited, "tooth_frequency_hz": self.tooth_frequency,
            "margin_N_per_m": self.margin, "force_max_N": self.force_max,
            "deflection_max_mm": to_file_unit(self.deflection_max, 1e3),
            "deflection_normal_max_mm": to_file_unit(self.deflection_normal_max, 1e3),
            "power_max_kW": to_file_unit(self.power_max, 1e-3),
            "gamma_deg": None if self.gamma is None else float(np.degrees(self.gamma)),
            "gamma_range_deg": (None if self.gamma_range is None
                                else [float(np.degrees(g)) for g in self.gamma_range]),
            "natural_frequency_hz": (None if self.natural_frequencies is None
                                     else list(self.natural_frequencies)),
            "characteristic": None if self.characteristic is None else self.characteristic.as_json(),
        }
        if self.ceiling_min is not None:
            out["ceiling_min_mm_s"] = self.ceiling_min * 1e3
            out["tightest_sample"] = self.tightest_sample
        return out

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> PlanSection:
        """The section of a plan.json object (its ``index`` a number from 1). Raises
        ``KeyError``/``TypeError``/``ValueError`` for a malformed object."""
        ch = d.get("characteristic")
        try:
            char = SectionCharacteristic.from_json(ch) if isinstance(ch, dict) else None
        except (KeyError, TypeError, ValueError):
            char = None          # a broken characteristic: the section has none
        gr, nf = d.get("gamma_range_deg"), d.get("natural_frequency_hz")
        feed = d["feed_mm_s"]
        return cls(
            index=int(d["index"]) - 1, kind=str(d["kind"]), sample_start=int(d["sample_start"]),
            sample_stop=int(d["sample_stop"]), s_start=float(d["s_start_m"]),
            s_end=float(d["s_end_m"]), feed=math.nan if feed is None else float(feed) * 1e-3,
            binding=str(d["binding"]), length=_opt(d.get("length_m")),
            process_binding=d.get("process_binding"), note=d.get("note"),
            line_start=d.get("line_start"), line_end=d.get("line_end"), file=d.get("file"),
            time=_opt(d.get("time_s")), process_time=_opt(d.get("process_time_s")),
            robot_limited=d.get("robot_limited"), tooth_frequency=_opt(d.get("tooth_frequency_hz")),
            margin=_opt(d.get("margin_N_per_m")), force_max=_opt(d.get("force_max_N")),
            deflection_max=from_file_unit(_opt(d.get("deflection_max_mm")), 1e3),
            deflection_normal_max=from_file_unit(_opt(d.get("deflection_normal_max_mm")), 1e3),
            power_max=from_file_unit(_opt(d.get("power_max_kW")), 1e-3),
            gamma=None if d.get("gamma_deg") is None else math.radians(float(d["gamma_deg"])),
            gamma_range=None if gr is None else (math.radians(gr[0]), math.radians(gr[1])),
            natural_frequencies=None if nf is None else (float(nf[0]), float(nf[1])),
            ceiling_min=from_file_unit(_opt(d.get("ceiling_min_mm_s")), 1e3),
            tightest_sample=d.get("tightest_sample"), characteristic=char)


@dataclass(frozen=True)
class SolverRecord:
    """How the plan's feeds were found: solver status and success, iterations, the time to build
    the NLP and to solve it [s], the objective (None for the thesis and constant methods)."""

    status: str
    success: bool
    iterations: int = 0
    build_time: float = 0.0
    solve_time: float = 0.0
    objective: float | None = None

    def as_json(self) -> dict[str, Any]:
        return {"status": self.status, "success": self.success, "iterations": self.iterations,
                "build_time_s": self.build_time, "solve_time_s": self.solve_time,
                "objective": self.objective}

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> SolverRecord:
        return cls(status=str(d.get("status")), success=bool(d.get("success", True)),
                   iterations=int(d.get("iterations") or 0),
                   build_time=float(d.get("build_time_s") or 0.0),
                   solve_time=float(d.get("solve_time_s") or 0.0), objective=d.get("objective"))


def _frame_json(xyz: tuple[float, ...], abc: tuple[float, ...]) -> dict[str, list[float]]:
    return {"xyz_mm": [round(v * 1e3, FRAME_DECIMALS) for v in xyz],
            "abc_deg": [round(math.degrees(v), FRAME_DECIMALS) for v in abc]}


def _frame_si(d: Any, which: str, where: str) -> tuple[tuple[float, ...], tuple[float, ...]]:
    try:
        xyz = tuple(float(v) * 1e-3 for v in d["xyz_mm"])
        abc = tuple(math.radians(float(v)) for v in d["abc_deg"])
        if len(xyz) != 3 or len(abc) != 3:
            raise ValueError("3 values in each")
    except (KeyError, TypeError, ValueError) as e:
        raise PlanFileError(where, f"{which}_frame needs xyz_mm and abc_deg ({e})") from e
    return xyz, abc


@dataclass(frozen=True)
class Plan:
    """A plan, SI. Made by :meth:`from_result` or :func:`load_plan`; written by :meth:`save`.

    Attributes:
        method: ``optimize`` (a feed profile), ``sections``, ``thesis`` or ``constant``.
        job_name, job_folder: the job it plans.
        robot: robot data name.
        files: the toolpath files (``PlanSection.file`` and ``PlanSamples.source_file`` refer to it).
        base_xyz, base_abc: ``$BASE`` (workpiece frame in the robot base): origin [m] (3,) and
            KUKA A, B, C [rad] (3,); tool_xyz, tool_abc: ``$TOOL`` (TCP in the flange frame).
        spindle_rpm: spindle speed [rpm] (an edge value the job and KRL carry as typed).
        flutes, tool_diameter [m], material.
        model: ``process_model``, ``mass_model``, ``criterion``, ``cct`` the plan was made with.
        limits: the limits it holds; safety_factor: the thesis safety factor.
        sections: in path order, partitioning the samples.
        samples: every sample.
        cycle_time: toppra-timed cycle [s]; process_time: Σ L/f over feed moves [s].
        solver: how the feeds were found.
        wall_times: wall time of each planning stage [s] (names with ``_s``, as in the file).
        summary: headline numbers (units in the names: a report, as in the file).
        import_warnings: what reading the toolpaths warned about, one group per kind and file
            (plan.json ``import_warnings``: kind, count, first file:line:col, message).
        warnings: what else the plan's user must know (plan.json ``warnings``: kind, message):
            tool data that do not apply, coefficients of another tool, rubbing, engagement.
        path: the ``plan.json`` it was read from or saved to (None for a plan only in memory).
    """

    method: str
    job_name: str
    robot: str
    base_xyz: tuple[float, ...]
    base_abc: tuple[float, ...]
    tool_xyz: tuple[float, ...]
    tool_abc: tuple[float, ...]
    limits: Limits
    sections: tuple[PlanSection, ...]
    samples: PlanSamples
    cycle_time: float
    solver: SolverRecord
    safety_factor: float | None = None
    job_folder: str | None = None
    files: tuple[str, ...] = ()
    spindle_rpm: float | None = None
    flutes: int | None = None
    tool_diameter: float | None = None
    material: str | None = None
    model: dict[str, Any] = field(default_factory=dict)
    process_time: float | None = None
    wall_times: dict[str, float] = field(default_factory=dict)
    summary: dict[str, Any] = field(default_factory=dict)
    import_warnings: tuple[WarningGroup, ...] = ()
    warnings: tuple[PlanWarning, ...] = ()
    path: Path | None = None

    @property
    def label(self) -> str:
        """How messages name the plan: its file, or the job it plans."""
        return str(self.path) if self.path is not None else f"the plan of job {self.job_name}"

    def frame_mm_deg(self, which: str) -> tuple[tuple[float, ...], tuple[float, ...]]:
        """``$BASE`` (``which="base"``) or ``$TOOL`` (``"tool"``) as plan.json and KRL write it:
        X, Y, Z [mm] and A, B, C [deg]."""
        xyz, abc = (self.base_xyz, self.base_abc) if which == "base" else (self.tool_xyz, self.tool_abc)
        d = _frame_json(xyz, abc)
        return tuple(d["xyz_mm"]), tuple(d["abc_deg"])

    def section_at(self, s: float) -> PlanSection:
        """The section containing arc length ``s`` [m] (the last one past the end)."""
        for sec in self.sections:
            if s < sec.s_end:
                return sec
        return self.sections[-1]

    @classmethod
    def from_result(cls, result: Any) -> Plan:
        """The plan of a :class:`planner.plan.PlanResult`, in memory."""
        from planner.plan import plan_of_result

        return plan_of_result(result)

    def model_coefficients(self) -> np.ndarray:
        """The cutting coefficients k_tc … k_ae [N/m², N/m] the plan was made with: its job's
        calibration (``model.coefficients``) where the plan records one, else the material
        file's.

        Raises:
            DataFileError: a recorded ``model.coefficients`` that is not six finite numbers.
        """
        rec = (self.model or {}).get("coefficients")
        if rec is None:
            from models import load_material

            return np.asarray(load_material(self.material).coefficients(), float)
        try:
            k = np.asarray(rec, float).reshape(-1)
        except (TypeError, ValueError) as e:
            raise DataFileError("plan.json", f"model.coefficients: {e}") from e
        if k.shape != (6,) or not np.all(np.isfinite(k)):
            raise DataFileError("plan.json", "model.coefficients must be six numbers k_tc .. k_ae")
        return k

    # -- the file edge ------------------------------------------------------------------------
    def document(self) -> dict[str, Any]:
        """The plan.json document (without ``format``, ``version``, ``samples_file``)."""
        return {
            "method": self.method, "job_name": self.job_name, "job_folder": self.job_folder,
            "robot": self.robot, "files": list(self.files),
            "base_frame": _frame_json(self.base_xyz, self.base_abc),
            "tool_frame": _frame_json(self.tool_xyz, self.tool_abc),
            "spindle_rpm": self.spindle_rpm, "flutes": self.flutes,
            "tool_diameter_mm": to_file_unit(self.tool_diameter, 1e3), "material": self.material,
            "model": dict(self.model),
            "constraints": self.limits.as_json(self.safety_factor),
            "sections": [s.as_json() for s in self.sections],
            "cycle_time_s": self.cycle_time, "process_time_s": self.process_time,
            "solver": self.solver.as_json(), "wall_times_s": dict(self.wall_times),
            "summary": self.summary,
            "import_warnings": [w.as_json() for w in self.import_warnings],
            "warnings": [w.as_json() for w in self.warnings],
        }

    def save(self, folder: str | os.PathLike) -> Plan:
        """Write ``plan.json`` and ``samples.npz`` into ``folder`` atomically; return the plan with
        :attr:`path` set to the written ``plan.json``."""
        p = write_plan(folder, self.document(), self.samples.as_arrays())
        return replace(self, path=p)

    @classmethod
    def from_document(cls, doc: dict[str, Any], arrays: dict[str, np.ndarray],
                      path: Path | None = None) -> Plan:
        """A plan from its plan.json document and samples arrays (units in the names); the
        document as :func:`planner.plan_schema.validate_document` passed it (:func:`load_plan`
        checks it first).

        Raises:
            PlanFileError: a section or frame is malformed.
        """
        where = str(path) if path is not None else "<plan>"
        secs = []
        for k, d in enumerate(doc["sections"]):
            try:
                secs.append(PlanSection.from_json(d))
            except (KeyError, TypeError, ValueError) as e:
                raise PlanFileError(where, f"section {d.get('index', k + 1)} is malformed ({e})") from e
        base = _frame_si(doc.get("base_frame"), "base", where)
        tool = _frame_si(doc.get("tool_frame"), "tool", where)
        sf = (doc.get("constraints") or {}).get("safety_factor")
        return cls(method=str(doc["method"]), job_name=str(doc.get("job_name") or "job"),
                   robot=str(doc.get("robot") or ""), base_xyz=base[0], base_abc=base[1],
                   tool_xyz=tool[0], tool_abc=tool[1],
                   limits=Limits.from_json(doc.get("constraints") or {}), sections=tuple(secs),
                   samples=PlanSamples.from_arrays(arrays), cycle_time=float(doc["cycle_time_s"]),
                   solver=SolverRecord.from_json(doc.get("solver") or {}),
                   safety_factor=_opt(sf), path=path,
                   job_folder=doc.get("job_folder", doc.get("job_file")),
                   files=tuple(doc.get("files") or ()), spindle_rpm=doc.get("spindle_rpm"),
                   flutes=doc.get("flutes"), material=doc.get("material"),
                   tool_diameter=from_file_unit(_opt(doc.get("tool_diameter_mm")), 1e3),
                   model=dict(doc.get("model") or {}), process_time=_opt(doc.get("process_time_s")),
                   wall_times=dict(doc.get("wall_times_s") or {}),
                   summary=dict(doc.get("summary") or {}),
                   import_warnings=tuple(WarningGroup.from_json(w)
                                         for w in doc.get("import_warnings") or ()),
                   warnings=tuple(PlanWarning.from_json(w) for w in doc.get("warnings") or ()))


def _resolve(path: str | os.PathLike) -> Path:
    p = Path(path)
    return p / "plan.json" if p.is_dir() else p


def load_plan(path: str | os.PathLike) -> Plan:
    """Read ``plan.json`` (or a folder holding one) and its samples table into a :class:`Plan`.

    The document is checked against :mod:`planner.plan_schema` (types, ranges, the partition of
    the samples) before anything is converted.

    Raises:
        PlanFileError: missing file, bad JSON, wrong format or version, a value of the wrong type
            or out of range (the message names its JSON path), missing or malformed arrays.
    """
    from planner.plan_schema import MAX_DEPTH, check_sample_count, json_depth, validate_document

    p = _resolve(path)
    if not p.is_file():
        raise PlanFileError(str(p), "no such plan; run `cctmill plan JOB.toml -o DIR` first")
    try:
        text = p.read_text(encoding="utf-8")
    except UnicodeDecodeError as e:
        raise PlanFileError(str(p), f"not UTF-8 text (byte {e.start}); {PlanFileError.REPLAN}") from e
    except OSError as e:
        raise PlanFileError(str(p), f"cannot read ({e.strerror or e})") from e
    if json_depth(text) > MAX_DEPTH:
        raise PlanFileError(str(p), f"arrays and objects nest more than {MAX_DEPTH} deep; "
                            f"{PlanFileError.REPLAN}")
    try:
        data = json.loads(text)
    except RecursionError as e:
        raise PlanFileError(str(p), f"nested too deep to read; {PlanFileError.REPLAN}") from e
    except ValueError as e:       # JSONDecodeError, and integers of more than 4300 digits
        raise PlanFileError(str(p), f"not readable JSON ({e}); {PlanFileError.REPLAN}") from e
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise PlanFileError(str(p), f"not a cctmill plan (format must be {FORMAT!r})")
    version = data.get("version")
    if version == SECTIONS_FROM_ZERO_VERSION and not isinstance(version, bool):
        raise PlanFileError(str(p), f"plan.json from an older cctmill (version {version}) numbers "
                            "sections from 0; plan it again (cctmill plan JOB.toml -o DIR) to "
                            "number them from 1, as the KRL program and the report do")
    if version != VERSION or isinstance(version, bool):
        raise PlanFileError(str(p), f"plan version {_short(data.get('version'))}; this cctmill "
                            f"reads version {VERSION}: plan the job again")
    doc = validate_document(data, file=str(p))
    samples = _load_samples(p.parent / doc.samples_file)
    check_sample_count(doc, samples["s_m"].shape[0], file=str(p))
    return Plan.from_document(doc.model_dump(exclude_unset=True), samples, path=p)


def _short(v: Any) -> str:
    s = repr(v)
    return s if len(s) <= 40 else s[:37] + "..."


def _load_samples(sp: Path) -> dict[str, np.ndarray]:
    """The arrays of ``samples.npz``, checked: every required array, numeric, of its shape."""
    try:
        with open(sp, "rb") as f:        # ours to close, whatever np.load makes of the bytes
            z = np.load(f, allow_pickle=False)
            if not isinstance(z, np.lib.npyio.NpzFile):     # a plain .npy: one array, not a table
                raise ValueError("one array, not a table of arrays")
            with z:
                samples = {k: z[k] for k in z.files}
    except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile, zlib.error) as e:
        raise PlanFileError(str(sp), f"samples table not readable ({e}); {PlanFileError.REPLAN}") from e
    s = samples.get("s_m")
    n = s.shape[0] if s is not None and s.ndim >= 1 else 0
    for name, tail in SAMPLE_ARRAYS.items():
        a = samples.get(name)
        if a is None or a.shape != (n, *tail):
            raise PlanFileError(str(sp), f"array {name!r} missing or not of shape {(n, *tail)}")
        if a.dtype.kind not in _NUMERIC:
            raise PlanFileError(str(sp), f"array {name!r} holds {a.dtype} values, not numbers")
    for name, tail in SAMPLE_EXTRA.items():
        a = samples.get(name)
        if a is not None and (a.shape != (n, *tail) or a.dtype.kind not in _NUMERIC):
            samples.pop(name)        # an optional array of the wrong shape is not used
    return samples


def _jsonable(v: Any) -> Any:
    if isinstance(v, dict):
        return {k: _jsonable(x) for k, x in v.items()}
    if isinstance(v, list | tuple):
        return [_jsonable(x) for x in v]
    if isinstance(v, np.ndarray):
        return _jsonable(v.tolist())
    if isinstance(v, np.bool_):
        return bool(v)
    if isinstance(v, np.integer):
        return int(v)
    if isinstance(v, float | np.floating):
        f = float(v)
        return f if np.isfinite(f) else None
    return v


def write_plan(folder: str | os.PathLike, data: dict[str, Any],
               samples: dict[str, np.ndarray]) -> Path:
    """Write a plan.json document and its ``samples.npz`` arrays (units in the names) into
    ``folder`` atomically; return the JSON path. :meth:`Plan.save` calls it; tests use it to
    write synthetic plans. Non-finite floats become ``null`` (JSON has no NaN).
    """
    out = Path(folder)
    n = samples["s_m"].shape[0]
    for name, tail in SAMPLE_ARRAYS.items():
        if name not in samples or samples[name].shape != (n, *tail):
            raise ValueError(f"samples[{name!r}] missing or not of shape {(n, *tail)}")
    doc = {"format": FORMAT, "version": VERSION, **data, "samples_file": "samples.npz"}
    with atomic_path(out / "samples.npz", suffix=".npz") as tmp:
        np.savez_compressed(tmp, **samples)
    return write_text_atomic(out / "plan.json", json.dumps(_jsonable(doc), indent=2) + "\n")
