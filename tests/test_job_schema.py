"""The job schema over every key at once: strict types, the unit-slip bounds, the robot's limits.

Walks :data:`planner.job_schema.TABLES` so a key added later is covered without a new row.
"""

from __future__ import annotations

import types
import typing

import numpy as np
import pytest

from models.robot import load_robot
from planner.job import JobError, parse_job
from planner.job_schema import SANE_MAX, TABLES

MINIMAL = {"job": {"toolpath": "a.nc"}, "engagement": {"ae_mm": 3.0, "ap_mm": 5.0}}
STOCK = {"box_mm": [0.0, 0.0, 10.0, 10.0], "z_bottom_mm": -5.0, "z_top_mm": 0.0}


def _doc(table: str, key: str, value) -> dict:
    doc = {k: dict(v) for k, v in MINIMAL.items()}
    if table == "stock":
        doc["engagement"]["stock"] = {**STOCK, key: value}
    else:
        doc.setdefault(table, {})[key] = value
    return doc


def _number_kind(annotation) -> str | None:
    """``scalar`` or ``list`` when the key holds numbers (bool excluded), else None."""
    if annotation in (float, int):
        return "scalar"
    origin = typing.get_origin(annotation)
    args = typing.get_args(annotation)
    if origin is typing.Annotated:
        return _number_kind(args[0])
    if origin is list:
        return "list" if _number_kind(args[0]) else None
    if origin in (typing.Union, types.UnionType):
        kinds = {_number_kind(a) for a in args} - {None}
        return kinds.pop() if kinds else None
    return None


NUMERIC = [(table, key, kind) for table, model in TABLES.items()
           for key, info in model.model_fields.items()
           if (kind := _number_kind(info.annotation)) is not None]


def test_the_walk_finds_the_keys_of_the_issue():
    assert {("spindle", "rpm", "scalar"), ("limits", "deflection_tol_mm", "scalar"),
            ("kinematics", "seed_joints_deg", "list")} <= set(NUMERIC)
    assert len(NUMERIC) > 30


@pytest.mark.parametrize(("table", "key", "kind"), NUMERIC,
                         ids=[f"{t}.{k}" for t, k, _ in NUMERIC])
def test_a_number_in_quotes_is_refused_naming_the_key(table, key, kind):
    n = {"gamma_window_deg": 2, "box_mm": 4, "seed_joints_deg": 6}.get(key, 3)   # its length
    value = "1" if kind == "scalar" else [str(i) for i in range(1, n + 1)]
    with pytest.raises(JobError) as e:
        parse_job(_doc(table, key, value), "job.toml")
    where = "[engagement.stock]" if table == "stock" else f"[{table}]"
    hit = [p for p in e.value.problems if p.startswith(f"{where} {key}")]
    assert hit and all("must be " in p and 'got the string "' in p for p in hit), e.value.problems
    if kind == "scalar":
        assert hit[0].endswith(f"write it without quotes: {key} = 1"), hit[0]
    elif key != "outline_mm":                  # an array of [x, y] pairs: each is no pair
        assert hit[0].endswith("write the number without quotes"), hit[0]


@pytest.mark.parametrize("name", sorted(SANE_MAX))
def test_a_unit_slip_beyond_the_bound_is_refused_with_what_to_type(name):
    table, key = name.split(".")
    sane = SANE_MAX[name]
    parse_job(_doc(table, key, sane.bound), "job.toml")         # the bound itself is accepted
    with pytest.raises(JobError) as e:
        parse_job(_doc(table, key, sane.bound * 40), "job.toml")
    (line,) = e.value.problems
    assert line.startswith(f"[{table}] {key}: {sane.bound * 40:g} {sane.unit} is above "
                           f"{sane.bound:g} {sane.unit}: {sane.why}; "), line


def test_seed_joints_outside_their_limits_name_each_joint():
    data = load_robot().data
    lo, hi = np.degrees(data.lower), np.degrees(data.upper)
    mid = ((lo + hi) / 2).tolist()
    assert parse_job(_doc("kinematics", "seed_joints_deg", mid)).kinematics.seed_joints_deg == mid
    outside = [float(v) for v in hi + 1.0]
    with pytest.raises(JobError) as e:
        parse_job(_doc("kinematics", "seed_joints_deg", outside), "job.toml")
    assert len(e.value.problems) == 6
    for name, line, a, b in zip(data.joint_names, e.value.problems, lo, hi, strict=True):
        assert line.startswith(f"[kinematics] seed_joints_deg: {name} = ") and \
            f"outside its limits {a:g} .. {b:g} deg" in line, line


def test_an_unknown_robot_is_named_at_its_key():
    with pytest.raises(JobError, match=r"job.toml: \[cell\] robot: unknown robot 'kr6'; available"):
        parse_job(_doc("cell", "robot", "kr6"), "job.toml")


@pytest.mark.parametrize(("table", "key", "value", "said"), [
    ("job", "strict", "false", 'must be true or false, got the string "false"; write it without '
                               "quotes: strict = false"),
    ("job", "strict", 0, "must be true or false, got 0"),
    ("spindle", "rpm", True, "must be a number, got true"),
    ("tool", "flutes", 2.5, "must be a whole number, got 2.5"),
    ("tool", "name", 3, "must be a string in quotes, got 3"),
    ("cell", "base_mm", [0.0, "x", 0.0], '[cell] base_mm[1]: must be a number, got the string "x"'),
])
def test_other_type_mistakes_are_said_in_toml_words(table, key, value, said):
    with pytest.raises(JobError) as e:
        parse_job(_doc(table, key, value), "job.toml")
    assert any(said in p for p in e.value.problems), e.value.problems
