"""The typed plan and its files (planner.plan_file): SI in memory, mm/deg/kW only in plan.json and
samples.npz, and a save → load round trip that gives the same plan back."""

from __future__ import annotations

import json
import math
import re
from dataclasses import fields, replace

import numpy as np
import pytest
from _plans import ONE_SECTION, make_plan

from planner.cli import main
from planner.limits import Limits
from planner.plan_file import (
    FORMAT,
    SAMPLE_ARRAYS,
    VERSION,
    Plan,
    PlanFileError,
    PlanSamples,
    PlanSection,
    SectionCharacteristic,
    SolverRecord,
    load_plan,
)
from planner.plan_schema import (
    CharacteristicDoc,
    ConstraintsDoc,
    PlanDocument,
    SectionDoc,
    json_depth,
    validate_document,
)

#: A unit conversion on the way in and out may move a float by an ulp or two (mm → m → mm).
ROUND_TRIP_RTOL = 1e-15


def _section(**kw) -> PlanSection:
    base = dict(index=0, kind="cut", sample_start=0, sample_stop=3, s_start=0.0, s_end=0.02,
                feed=0.0123456789, binding="deflection", length=0.02, process_binding="deflection",
                note="n", line_start=4, line_end=7, file="a.nc", time=1.7, process_time=1.62,
                robot_limited=False, tooth_frequency=133.3, margin=2.5e4, force_max=120.0,
                deflection_max=1.9e-4, deflection_normal_max=1.1e-4, power_max=850.0,
                gamma=math.radians(33.0), gamma_range=(math.radians(20.0), math.radians(40.0)),
                natural_frequencies=(9.5, 12.5), ceiling_min=0.0124, tightest_sample=1,
                characteristic=SectionCharacteristic(
                    sample=1, feeds=np.geomspace(5e-4, 4e-2, 5), margin=np.linspace(3e4, -1e4, 5),
                    gamma=np.radians(np.linspace(30, 36, 5)), force=np.linspace(20, 300, 5),
                    stable=np.array([True, True, True, False, False]),
                    deflection=np.linspace(1e-5, 3e-4, 5), ok=np.array([True, True, False, False, False])))
    base.update(kw)
    return PlanSection(**base)


def _samples(n: int = 3) -> PlanSamples:
    rng = np.random.default_rng(7)
    vec = rng.normal(size=(n, 3))
    return PlanSamples(
        s=np.linspace(0, 0.02, n), q=rng.normal(size=(n, 6)), position_wp=vec * 0.1,
        abc_wp=np.radians(rng.uniform(-170, 170, (n, 3))), tool_axis_wp=np.tile([0, 0, 1.0], (n, 1)),
        section=np.zeros(n, int), kind=np.zeros(n, int), arc=np.zeros(n, bool),
        move=np.arange(n), line=np.arange(n) + 4, source_file=np.zeros(n, int),
        feed=np.full(n, 0.0123456789), speed=np.full(n, 0.012), time=np.linspace(0, 1.7, n),
        force=rng.uniform(10, 200, n), deflection=rng.uniform(0, 2e-4, n),
        deflection_wp=vec * 1e-4, deflection_normal=rng.uniform(0, 1e-4, n),
        gamma=rng.uniform(-1, 1, n), margin=rng.uniform(0, 3e4, n), power=rng.uniform(0, 900, n),
        a_e=np.full(n, 5e-3), a_p=np.full(n, 1e-2), mode=np.zeros(n, int),
        ceiling=np.full(n, 0.0124), robot_limited=np.zeros(n, bool), bound=np.full(n, 0.0123),
        joint_speed=rng.normal(size=(n, 6)))


def _plan() -> Plan:
    limits = Limits(force_max=300.0, deflection_tol=2e-4, power_max=1e4, feed_min=5e-4,
                    feed_max=4e-2, feed_change_max=None, margin_min=0.0, section_length_min=1e-2,
                    path_acc_max=1.0, path_jerk_max=10.0, rapid_speed=0.25)
    return Plan(method="optimize", job_name="part", robot="kr210_r2700_extra",
                base_xyz=(1.5, -0.06, 0.4), base_abc=(0.0, 0.0, math.radians(90.0)),
                tool_xyz=(0.25, 0.0, 0.2), tool_abc=(0.0, math.radians(90.0), 0.0), limits=limits,
                sections=(_section(),), samples=_samples(), cycle_time=2.5,
                solver=SolverRecord("Solve_Succeeded", True, 20, 0.01, 0.02, 1.5),
                safety_factor=1.1, job_folder="/jobs", files=("a.nc",), spindle_rpm=4000.0,
                flutes=2, tool_diameter=0.0254, material="al6061",
                model={"process_model": "thesis", "mass_model": "robot", "criterion": "eigen",
                       "cct": True}, process_time=2.2, wall_times={"plan_s": 0.3},
                summary={"sections": 1})


def _close(a, b) -> bool:
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        a, b = np.asarray(a), np.asarray(b)
        if a.dtype == bool or b.dtype == bool or a.dtype.kind in "iu":
            return np.array_equal(a, b)
        return np.allclose(a, b, rtol=ROUND_TRIP_RTOL, atol=0.0, equal_nan=True)
    if isinstance(a, float) and isinstance(b, float):
        return math.isclose(a, b, rel_tol=ROUND_TRIP_RTOL, abs_tol=0.0)
    if isinstance(a, tuple) and isinstance(b, tuple):
        return len(a) == len(b) and all(_close(x, y) for x, y in zip(a, b, strict=True))
    return a == b


def _assert_same(a, b, where: str = "plan") -> None:
    for f in fields(a):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if hasattr(x, "__dataclass_fields__") and not isinstance(x, Limits):
            _assert_same(x, y, f"{where}.{f.name}")
        elif isinstance(x, tuple) and x and hasattr(x[0], "__dataclass_fields__"):
            for k, (u, v) in enumerate(zip(x, y, strict=True)):
                _assert_same(u, v, f"{where}.{f.name}[{k}]")
        else:
            assert _close(x, y), (where, f.name, x, y)


def test_save_then_load_gives_the_same_plan(tmp_path):
    plan = _plan()
    saved = plan.save(tmp_path)
    assert saved.path == tmp_path / "plan.json" and plan.path is None
    back = load_plan(tmp_path)
    _assert_same(replace(plan, path=back.path), back)
    assert back.limits == plan.limits or all(
        math.isclose(getattr(back.limits, f.name) or 0.0, getattr(plan.limits, f.name) or 0.0,
                     rel_tol=ROUND_TRIP_RTOL) for f in fields(Limits))


def test_the_file_is_in_file_units(tmp_path):
    """SI inside, the unit in every key name at the edge: mm, mm/s, deg, kW."""
    _plan().save(tmp_path)
    doc = json.loads((tmp_path / "plan.json").read_text(encoding="utf-8"))
    sec = doc["sections"][0]
    assert sec["feed_mm_s"] == pytest.approx(12.3456789)
    assert sec["deflection_max_mm"] == pytest.approx(0.19)
    assert sec["power_max_kW"] == pytest.approx(0.85)
    assert sec["gamma_deg"] == pytest.approx(33.0)
    assert sec["gamma_range_deg"] == pytest.approx([20.0, 40.0])
    assert sec["characteristic"]["feeds_mm_s"][0] == pytest.approx(0.5)
    assert doc["base_frame"] == {"xyz_mm": [1500.0, -60.0, 400.0], "abc_deg": [0.0, 0.0, 90.0]}
    assert doc["tool_frame"] == {"xyz_mm": [250.0, 0.0, 200.0], "abc_deg": [0.0, 90.0, 0.0]}
    assert doc["tool_diameter_mm"] == pytest.approx(25.4)
    assert doc["constraints"]["feed_max_mm_s"] == pytest.approx(40.0)
    with np.load(tmp_path / "samples.npz") as z:
        assert set(SAMPLE_ARRAYS) <= set(z.files)
        assert z["feed_mm_s"][0] == pytest.approx(12.3456789)
        assert z["power_kW"].max() < 1.0 and np.abs(z["abc_wp_deg"]).max() > 10.0


def test_the_frame_is_written_as_the_user_typed_it():
    """mm → m → mm float noise is not written: 1e-9 mm resolution keeps the typed values."""
    plan = replace(_plan(), base_xyz=tuple(v * 1e-3 for v in (1500.3, -60.1, 400.7)),
                   base_abc=tuple(math.radians(v) for v in (0.1, -0.3, 179.9)))
    assert plan.frame_mm_deg("base") == ((1500.3, -60.1, 400.7), (0.1, -0.3, 179.9))


def test_a_synthetic_plan_with_few_keys_loads(tmp_path):
    plan = load_plan(make_plan(tmp_path, ONE_SECTION))
    sec = plan.sections[0]
    assert sec.feed == pytest.approx(8e-3) and sec.time is None and sec.power_max is None
    assert sec.characteristic is not None and sec.characteristic.deflection is None
    assert plan.limits.force_max == 300.0 and math.isinf(plan.limits.power_max)
    assert plan.samples.ceiling is None and len(plan.samples) == 250
    assert plan.section_at(0.49).index == 0 and plan.section_at(9.0).index == 0


@pytest.fixture(scope="module")
def demo_plan_dir(demo_prepared, tmp_path_factory):
    """The demo job planned with constant feeds, saved: a real plan.json with every key."""
    from planner.plan import plan_prepared

    folder = tmp_path_factory.mktemp("demo_plan")
    Plan.from_result(plan_prepared(demo_prepared, "constant")).save(folder)
    return folder


def _raw(key: str, text: str):
    """A mutation that puts raw JSON text (not expressible as a Python value) at ``key``."""
    def mutate(d: dict) -> None:
        d[key] = _RAW
    mutate.raw = text
    return mutate


_RAW = "@@raw@@"


def _whole(change):
    """A mutation of the whole JSON text."""
    def mutate(d: dict) -> None:
        pass
    mutate.text = change
    return mutate


def _set(*path_value):
    """``_set("sections", 3, "feed_mm_s", "fast")``: a mutation setting one value."""
    *path, value = path_value

    def mutate(d: dict) -> None:
        for key in path[:-1]:
            d = d[key]
        d[path[-1]] = value
    return mutate


def _shift_start(d: dict) -> None:
    d["sections"][3]["sample_start"] += 1


def _stop_at_start(d: dict) -> None:
    d["sections"][3]["sample_stop"] = d["sections"][3]["sample_start"]


def _first_cut(d: dict) -> dict:
    return next(s for s in d["sections"] if s.get("characteristic"))


def _short_margin(d: dict) -> None:
    _first_cut(d)["characteristic"]["margin_N_per_m"].pop()


def _s_end_below_start(d: dict) -> None:
    d["sections"][3]["s_end_m"] = d["sections"][3]["s_start_m"] - 0.01


#: One corruption a line: id, mutation of the demo plan.json, what the message says (after the
#: file name). Issue 22 finding 6: each of these was a traceback or was accepted.
CORRUPTIONS = [
    ("section_int", _set("sections", 3, 5), r"sections\[3\]: must be an object, got 5"),
    ("section_str", _set("sections", 3, "cut"), r"sections\[3\]: must be an object, got 'cut'"),
    ("feed_str", _set("sections", 3, "feed_mm_s", "fast"),
     r"sections\[3\]\.feed_mm_s: must be a positive finite number up to 10000 mm/s, got 'fast'"),
    ("feed_1e308", _set("sections", 3, "feed_mm_s", 1e308),
     r"sections\[3\]\.feed_mm_s: must be a positive finite number .*got 1e\+308"),
    ("feed_negative", _set("sections", 3, "feed_mm_s", -5.0), r"feed_mm_s: .*got -5\.0"),
    ("feed_true", _set("sections", 3, "feed_mm_s", True), r"feed_mm_s: .*got True"),
    ("feed_nan_token", _set("sections", 3, "feed_mm_s", math.nan), r"feed_mm_s: .*got nan"),
    ("feed_null_in_cut", _set("sections", 3, "feed_mm_s", None),
     r"sections\[3\]\.feed_mm_s: .*null only in a rapid section"),
    ("solver_number", _set("solver", 3.5), r"solver: must be an object, got 3\.5"),
    ("solver_success_str", _set("solver", "success", "no"),
     r"solver\.success: must be true or false, got 'no'"),
    ("sample_stop_null", _set("sections", 3, "sample_stop", None),
     r"sections\[3\]\.sample_stop: must be an integer ≥ 0, got None"),
    ("sample_start_float", _set("sections", 3, "sample_start", 43.0),
     r"sections\[3\]\.sample_start: must be an integer ≥ 0, got 43\.0"),
    ("cycle_time_list", _set("cycle_time_s", [1]), r"cycle_time_s: must be a finite number ≥ 0, got \[1\]"),
    ("constraints_number", _set("constraints", -1), r"constraints: must be an object, got -1"),
    ("constraint_str", _set("constraints", "force_max_N", "300"),
     r"constraints\.force_max_N: must be a positive finite number, got '300'"),
    ("feed_min_above_max", _set("constraints", "feed_min_mm_s", 50.0),
     r"constraints\.feed_min_mm_s: must not exceed feed_max_mm_s 40, got 50"),
    ("nested_1100", _raw("summary", "[" * 1100 + "]" * 1100), r"nest more than 32 deep"),
    ("sections_object", _set("sections", {"a": 1}), r"sections: must be a list"),
    ("sections_empty", _set("sections", []), r"sections: must hold at least one section"),
    ("sections_missing", lambda d: d.pop("sections"), r"sections: missing"),
    ("section_key_missing", lambda d: d["sections"][3].pop("feed_mm_s"),
     r"sections\[3\]\.feed_mm_s: missing"),
    ("section_key_typo", lambda d: d["sections"][3].update(feed_mms=5.0),
     r"sections\[3\]\.feed_mms: unknown key; did you mean 'feed_mm_s'\?"),
    ("index_str", _set("sections", 3, "index", "3"), r"sections\[3\]\.index: must be an integer"),
    ("index_out_of_order", _set("sections", 3, "index", 3),
     r"sections\[3\]\.index: must be 4 \(sections are numbered 1, 2, … in path order\), got 3"),
    ("index_from_zero", _set("sections", 0, "index", 0),
     r"sections\[0\]\.index: must be an integer ≥ 1, got 0"),
    ("kind_unknown", _set("sections", 3, "kind", "milling"),
     r"sections\[3\]\.kind: must be 'cut', 'air' or 'rapid', got 'milling'"),
    ("samples_gap", _shift_start,
     r"sections\[3\]\.sample_start: must be 43, where sections\[2\] stops .*got 44"),
    ("section_empty_range", _stop_at_start, r"sections\[3\]\.sample_stop: must be above sample_start"),
    ("samples_beyond_end", _set("sections", 9, "sample_stop", 10**6),
     r"sections\[9\]\.sample_stop: must be 892, the samples in samples\.npz"),
    ("s_end_below_start", _s_end_below_start, r"sections\[3\]\.s_end_m: must not be below s_start_m"),
    ("frame_str", _set("base_frame", "xyz_mm", ["a", 0, 0]),
     r"base_frame\.xyz_mm\[0\]: must be a finite number, got 'a'"),
    ("frame_short", _set("tool_frame", "abc_deg", [0, 0]), r"tool_frame\.abc_deg: must hold 3 numbers"),
    ("characteristic_str", lambda d: _first_cut(d)["characteristic"].update(feeds_mm_s="x"),
     r"sections\[3\]\.characteristic\.feeds_mm_s: must be a list, got 'x'"),
    ("characteristic_length", _short_margin,
     r"sections\[3\]\.characteristic\.margin_N_per_m: must hold 25 values, one per feeds_mm_s, got 24"),
    ("natural_frequency_short", lambda d: _first_cut(d).update(natural_frequency_hz=[1.0]),
     r"sections\[3\]\.natural_frequency_hz: must hold 2 numbers, got \[1\.0\]"),
    ("gamma_range_number", lambda d: _first_cut(d).update(gamma_range_deg=3),
     r"sections\[3\]\.gamma_range_deg: must be a list, got 3"),
    ("line_start_str", _set("sections", 3, "line_start", "x"),
     r"sections\[3\]\.line_start: must be an integer"),
    ("import_warnings_object", _set("import_warnings", {"a": 1}), r"import_warnings: must be a list"),
    ("import_warning_incomplete", _set("import_warnings", [{"count": 1, "first": "a:1:1", "message": "m"}]),
     r"import_warnings\[0\]\.kind: missing"),
    ("warnings_str", _set("warnings", "x"), r"warnings: must be a list, got 'x'"),
    ("files_str", _set("files", "a.nc"), r"files: must be a list, got 'a\.nc'"),
    ("wall_times_list", _set("wall_times_s", [1]), r"wall_times_s: must be an object, got \[1\]"),
    ("model_list", _set("model", [1]), r"model: must be an object, got \[1\]"),
    ("job_name_object", _set("job_name", {}), r"job_name: must be a string, got \{\}"),
    ("samples_file_path", _set("samples_file", "../other/samples.npz"),
     r"samples_file: must be a file name ending \.npz beside plan\.json"),
    ("version_str", _set("version", "2"), r"plan version '2'; this cctmill reads version 2"),
    ("version_1", _set("version", 1), r"older cctmill \(version 1\) numbers sections from 0; plan it again"),
    ("top_level_list", _whole(lambda text: f"[{text}]"), r"not a cctmill plan"),
    ("integer_5000_digits", _raw("cycle_time_s", "9" * 5000), r"not readable JSON"),
]


def _corrupt(folder, mutate) -> None:
    path = folder / "plan.json"
    doc = json.loads(path.read_text(encoding="utf-8"))
    mutate(doc)
    text = json.dumps(doc)
    if hasattr(mutate, "raw"):
        text = text.replace(json.dumps(_RAW), mutate.raw)
    if hasattr(mutate, "text"):
        text = mutate.text(text)
    path.write_text(text, encoding="utf-8")


@pytest.fixture
def corrupted(demo_plan_dir, tmp_path, request):
    """A copy of the demo plan with one corruption of :data:`CORRUPTIONS`."""
    import shutil

    folder = tmp_path / "plan"
    shutil.copytree(demo_plan_dir, folder)
    _corrupt(folder, request.param)
    return folder


@pytest.mark.parametrize("corrupted,match", [(m, r) for _, m, r in CORRUPTIONS],
                         ids=[c[0] for c in CORRUPTIONS], indirect=["corrupted"])
def test_a_corrupted_plan_is_refused_with_the_json_path(corrupted, match):
    with pytest.raises(PlanFileError) as e:
        load_plan(corrupted)
    msg = str(e.value)
    assert msg.startswith(f"{corrupted / 'plan.json'}: ") and "\n" not in msg
    assert re.search(match, msg), msg
    assert e.value.path == str(corrupted / "plan.json")
    if e.value.where is not None:                 # a value of the document: its JSON path leads
        assert msg.startswith(f"{corrupted / 'plan.json'}: {e.value.where}: ")


@pytest.mark.parametrize("corrupted", [m for _, m, _ in CORRUPTIONS],
                         ids=[c[0] for c in CORRUPTIONS], indirect=True)
def test_the_cli_refuses_a_corrupted_plan_in_one_line(corrupted, capsys):
    """``cctmill export`` and ``cctmill supervise --plan``: exit 2, one line, no traceback."""
    for argv in (["export", str(corrupted), "-o", str(corrupted / "krl")],
                 ["supervise", "--plan", str(corrupted), "--signal", "sim", "--robot", "sim",
                  "--duration-s", "0.1"]):
        assert main(argv) == 2, argv
        out = capsys.readouterr()
        lines = out.err.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith(f"cctmill {argv[0]}: error: "), out.err
        assert "Traceback" not in out.err and "plan.json" in lines[0]
    assert not (corrupted / "krl").exists()


def test_a_valid_plan_passes_untouched(demo_plan_dir):
    plan = load_plan(demo_plan_dir)
    assert len(plan.sections) == 10 and len(plan.samples) == 892


def test_a_null_feed_is_allowed_in_a_rapid_section(demo_plan_dir, tmp_path):
    """A rapid section without a planned feed runs at the controller's rapid speed (the exporter's
    RAPID_FEED_M_S): null is a legal value there, and only there."""
    import shutil

    shutil.copytree(demo_plan_dir, tmp_path / "plan")
    _corrupt(tmp_path / "plan", _set("sections", 0, "feed_mm_s", None))
    assert math.isnan(load_plan(tmp_path / "plan").sections[0].feed)


@pytest.mark.parametrize("name,content,match", [
    ("not_utf8", b'{"format": "cctmill-plan", "job_name": "caf\xe9"}', r"not UTF-8 text \(byte 43\)"),
    ("not_json", b'{"format": "cctmill-plan",', r"not readable JSON"),
])
def test_unreadable_plan_text_is_refused(tmp_path, name, content, match):
    (tmp_path / "plan.json").write_bytes(content)
    with pytest.raises(PlanFileError, match=match):
        load_plan(tmp_path)


def _rewrite_samples(folder, change) -> None:
    with np.load(folder / "samples.npz") as z:
        arrays = {k: z[k] for k in z.files}
    change(arrays)
    np.savez(folder / "samples.npz", **arrays)


@pytest.mark.parametrize("change,match", [
    (lambda a: a.pop("q_rad"), r"array 'q_rad' missing"),
    (lambda a: a.update(kind=a["kind"].astype(str)), r"array 'kind' holds <U\d+ values, not numbers"),
    (lambda a: a.update(s_m=a["s_m"][:-1]), r"array 'q_rad' missing or not of shape \(891, 6\)"),
])
def test_a_bad_samples_table_is_refused(demo_plan_dir, tmp_path, change, match):
    import shutil

    folder = tmp_path / "plan"
    shutil.copytree(demo_plan_dir, folder)
    _rewrite_samples(folder, change)
    with pytest.raises(PlanFileError, match=match):
        load_plan(folder)


def test_a_samples_file_that_is_no_table_is_refused(demo_plan_dir, tmp_path):
    import shutil

    folder = tmp_path / "plan"
    shutil.copytree(demo_plan_dir, folder)
    (folder / "samples.npz").write_bytes(b"PK\x03\x04 not a zip at all")
    with pytest.raises(PlanFileError, match=r"samples\.npz: samples table not readable"):
        load_plan(folder)
    np.save(folder / "one.npy", np.zeros(3))
    (folder / "one.npy").rename(folder / "samples.npz")
    with pytest.raises(PlanFileError, match=r"one array, not a table"):
        load_plan(folder)


def test_writer_and_reader_share_one_schema(demo_plan_dir, demo_optimized, tmp_path):
    """Every key the writer writes is one the schema knows (it forbids others) and every key the
    schema knows is one the writer writes: ``Plan.document()`` of the demo validates."""
    for folder in (demo_plan_dir, Plan.from_result(demo_optimized).save(tmp_path).path.parent):
        doc = json.loads((folder / "plan.json").read_text(encoding="utf-8"))
        with np.load(folder / "samples.npz") as z:
            n = z["s_m"].shape[0]
        checked = validate_document(doc, n)
        assert len(checked.sections) == len(doc["sections"])
        assert set(doc) == set(PlanDocument.model_fields) - {"job_file"}
        assert set(doc["constraints"]) == set(ConstraintsDoc.model_fields)
        written = set().union(*(s.keys() for s in doc["sections"]))
        assert written == set(SectionDoc.model_fields)
        chars = [s["characteristic"] for s in doc["sections"] if s["characteristic"]]
        assert set().union(*(c.keys() for c in chars)) == set(CharacteristicDoc.model_fields)
    plan = load_plan(demo_plan_dir)
    in_memory = {"format": FORMAT, "version": VERSION, **plan.document(), "samples_file": "samples.npz"}
    as_written = json.loads(json.dumps(in_memory, default=lambda v: v.item()),  # numpy scalars
                            parse_constant=lambda _: None)      # NaN → null, as the writer does
    validate_document(as_written, len(plan.samples))


def test_a_schema_problem_names_the_first_and_counts_the_rest():
    with pytest.raises(PlanFileError) as e:
        validate_document({"format": "cctmill-plan", "version": VERSION}, file="x/plan.json")
    assert e.value.where == "method" and e.value.path == "x/plan.json"
    assert str(e.value).startswith("x/plan.json: method: missing (and ")


def test_json_depth_skips_brackets_in_strings():
    assert json_depth('{"a": "[[[[[[", "b": [[1]]}') == 3
    assert json_depth('["\\"[[["]') == 1
    assert json_depth("[" * 100 + "]" * 100, limit=5) == 6


def test_a_missing_plan_says_how_to_make_one(tmp_path):
    with pytest.raises(PlanFileError, match="cctmill plan"):
        load_plan(tmp_path / "nowhere")


def test_from_result_needs_no_disk(demo_optimized, tmp_path):
    """The plan of a result, in memory, equals the same plan saved and read back."""
    plan = Plan.from_result(demo_optimized)
    assert plan.path is None and plan.sections[0].index == 0
    cut = [s for s in plan.sections if s.kind == "cut"]
    # the optimiser's feed sits on the ceiling to an ulp (IPOPT's bound, scaled by feed_max)
    assert all(s.characteristic is not None and s.feed <= s.ceiling_min * (1 + 1e-12) for s in cut)
    back = load_plan(plan.save(tmp_path).path)
    _assert_same(replace(plan, path=back.path), back)
