"""Fuzzing plan.json: any value anywhere in a valid plan (or a key removed) gives a PlanFileError
naming the file, or a plan that loads and that the KRL exporter takes or refuses with a cctmill
error; never another exception, never more than 2 s. Property-based (hypothesis), bounded to a few
seconds, no example database."""

from __future__ import annotations

import json
import math
import time
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from models.errors import CctmillError
from planner.export import plan_to_krl
from planner.plan_file import Plan, PlanFileError, load_plan

#: Most a load (and an export of what loads) may take [s].
LOAD_S = 2.0
#: JSON values with the edges that once crashed the reader: huge and non-finite numbers, numbers
#: as strings, bools for numbers, deep and empty containers.
EDGES = [None, True, False, 0, -1, 1.5, 1e308, -1e308, math.inf, math.nan, 10**400, 2**63, "", "3",
         "fast", [], {}, [1, 2, 3], {"a": 1}, [[[[[[]]]]]]]
JSON = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=8)
    | st.sampled_from(EDGES),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=6), inner, max_size=4),
    max_leaves=12)
FUZZ = settings(max_examples=150, deadline=LOAD_S * 1000, database=None,
                suppress_health_check=[HealthCheck.too_slow])


def _paths(v: Any, at: tuple = ()) -> list[tuple]:
    """Every location in a JSON document (the document itself excluded)."""
    out = []
    items = v.items() if isinstance(v, dict) else enumerate(v) if isinstance(v, list) else ()
    for k, x in items:
        out.append((*at, k))
        out += _paths(x, (*at, k))
    return out


@pytest.fixture(scope="module")
def plan_dir(demo_prepared, tmp_path_factory):
    """The demo job planned with constant feeds (every key of plan.json, characteristics, import
    and plan warnings), saved; each example overwrites its plan.json, samples.npz stays."""
    from planner.plan import plan_prepared

    folder = tmp_path_factory.mktemp("fuzz_plan")
    Plan.from_result(plan_prepared(demo_prepared, "constant")).save(folder)
    doc = json.loads((folder / "plan.json").read_text(encoding="utf-8"))
    doc["import_warnings"] = [{"kind": "k", "count": 2, "first": "a.nc:3:1", "message": "m"}]
    return folder, doc, _paths(doc)


def _load_and_use(folder) -> None:
    """Load; what loads must also be usable: the exporter takes it or refuses it in its terms."""
    t0 = time.perf_counter()
    try:
        plan = load_plan(folder)
    except PlanFileError as e:
        assert str(e).startswith(str(folder / "plan.json")) and "\n" not in str(e), str(e)
        return
    finally:
        assert time.perf_counter() - t0 < LOAD_S
    assert isinstance(plan, Plan) and plan.sections
    try:
        plan_to_krl(plan)
    except CctmillError:
        pass


@FUZZ
@given(data=st.data())
def test_any_value_anywhere_is_refused_or_loads(plan_dir, data) -> None:
    folder, doc, paths = plan_dir
    doc = json.loads(json.dumps(doc))
    path = data.draw(st.sampled_from(paths), label="path")
    holder = doc
    for key in path[:-1]:
        holder = holder[key]
    if data.draw(st.booleans(), label="delete") and isinstance(holder, dict):
        del holder[path[-1]]
    else:
        holder[path[-1]] = data.draw(JSON, label="value")
    (folder / "plan.json").write_text(json.dumps(doc), encoding="utf-8")
    _load_and_use(folder)


@FUZZ
@given(edits=st.lists(st.tuples(st.floats(0, 1), st.sampled_from("[]{}\",:0123456789.-eE nul"),
                                st.integers(0, 2)), min_size=1, max_size=6))
def test_mutated_plan_text_is_refused_or_loads(plan_dir, edits) -> None:
    """Byte-level damage: a truncated, bracket-shuffled or digit-mangled plan.json."""
    folder, doc, _ = plan_dir
    text = list(json.dumps(doc))
    for where, ch, op in edits:
        i = min(int(where * len(text)), len(text) - 1)
        if op == 0:
            text[i] = ch
        elif op == 1:
            text.insert(i, ch)
        else:
            del text[i]
    (folder / "plan.json").write_text("".join(text), encoding="utf-8")
    _load_and_use(folder)


@settings(max_examples=60, deadline=LOAD_S * 1000, database=None)
@given(raw=st.binary(max_size=200))
def test_random_bytes_are_refused(plan_dir, raw) -> None:
    folder, _, _ = plan_dir
    (folder / "plan.json").write_bytes(raw)
    with pytest.raises(PlanFileError):
        load_plan(folder)
