"""The typed plan and its files (planner.plan_file): SI in memory, mm/deg/kW only in plan.json and
samples.npz, and a save → load round trip that gives the same plan back."""

from __future__ import annotations

import json
import math
from dataclasses import fields, replace

import numpy as np
import pytest
from _plans import ONE_SECTION, make_plan

from planner.limits import Limits
from planner.plan_file import (
    SAMPLE_ARRAYS,
    Plan,
    PlanFileError,
    PlanSamples,
    PlanSection,
    SectionCharacteristic,
    SolverRecord,
    load_plan,
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


@pytest.mark.parametrize("mutate,match", [
    (lambda d: d.update(format="other"), "not a cctmill plan"),
    (lambda d: d.update(version=99), "plan version 99"),
    (lambda d: d.pop("sections"), "missing keys"),
    (lambda d: d.update(sections=[]), "no sections"),
    (lambda d: d["sections"][0].pop("feed_mm_s"), "lacks"),
    (lambda d: d["sections"][0].update(sample_start="x"), "malformed"),
    (lambda d: d.update(base_frame={"xyz_mm": [1, 2]}), "base_frame"),
])
def test_malformed_plans_are_refused_with_the_reason(tmp_path, mutate, match):
    path = _plan().save(tmp_path).path
    doc = json.loads(path.read_text(encoding="utf-8"))
    mutate(doc)
    path.write_text(json.dumps(doc), encoding="utf-8")
    with pytest.raises(PlanFileError, match=match):
        load_plan(tmp_path)


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
