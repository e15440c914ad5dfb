"""Fuzzing the job loader (planner.job.load_job / parse_job): any bytes, a damaged demo job, any
value anywhere in it give a JobError naming the file, or a Job; never another exception (issue 22
finding 4: a latin-1 byte and a 2 kB nesting bomb were tracebacks). Property-based, bounded."""

from __future__ import annotations

import json
import math
import time
import tomllib
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from planner.demo import demo_job_file
from planner.job import MAX_DEPTH, Job, JobError, load_job, parse_job

#: Most one load may take [s].
LOAD_S = 2.0
FUZZ = settings(max_examples=150, deadline=LOAD_S * 1000, database=None,
                suppress_health_check=[HealthCheck.too_slow])
DEMO = demo_job_file().read_bytes()


@pytest.mark.parametrize("name,content,match", [
    ("latin1", DEMO.replace(b'name = "', b'name = "caf\xe9 ', 1),
     r"not UTF-8 text \(byte 0xe9 on line \d+\); save the job file as UTF-8"),
    ("nested_arrays_1000", b"a = " + b"[" * 1000 + b"]" * 1000,
     r"not valid TOML: arrays or inline tables nest too deep to read"),
    ("nested_tables_1000", b"a = " + b"{b = " * 1000 + b"1" + b"}" * 1000,
     r"not valid TOML: arrays or inline tables nest too deep to read"),
    ("dotted_2000", b"[" + b".".join([b"a"] * 2000) + b"]\n",
     rf"tables and arrays nest more than {MAX_DEPTH} deep"),
    ("integer_5000_digits", b"x = " + b"9" * 5000, r"not valid TOML: Exceeds the limit"),
    ("bad_date", b"x = 2023-02-30", r"not valid TOML"),
])
def test_an_unreadable_job_is_one_job_error(tmp_path, name, content, match):
    path = tmp_path / f"{name}.toml"
    path.write_bytes(content)
    with pytest.raises(JobError, match=match) as e:
        load_job(path)
    assert str(e.value).startswith(f"{path}: ") and "\n" not in str(e.value)


def test_a_document_that_is_no_table_is_refused():
    with pytest.raises(JobError, match="not a job document"):
        parse_job([1, 2], "x.toml")      # type: ignore[arg-type]


def _load(path) -> None:
    t0 = time.perf_counter()
    try:
        assert isinstance(load_job(path), Job)
    except JobError as e:
        assert str(e).startswith(f"{path}: "), str(e)
    assert time.perf_counter() - t0 < LOAD_S


@FUZZ
@given(raw=st.binary(max_size=300))
def test_random_bytes_give_a_job_error(tmp_path_factory, raw) -> None:
    path = tmp_path_factory.mktemp("job") / "job.toml"
    path.write_bytes(raw)
    _load(path)


@FUZZ
@given(edits=st.lists(st.tuples(st.floats(0, 1), st.sampled_from(b'[]{}"=.,#\n\xe9\xff0-9aeEnf '),
                                st.integers(0, 2)), min_size=1, max_size=6))
def test_a_damaged_demo_job_gives_a_job_error_or_a_job(tmp_path_factory, edits) -> None:
    data = bytearray(DEMO)
    for where, b, op in edits:
        i = min(int(where * len(data)), len(data) - 1)
        if op == 0:
            data[i] = b
        elif op == 1:
            data.insert(i, b)
        else:
            del data[i]
    path = tmp_path_factory.mktemp("job") / "job.toml"
    path.write_bytes(bytes(data))
    _load(path)


def _paths(v: Any, at: tuple = ()) -> list[tuple]:
    out = []
    items = v.items() if isinstance(v, dict) else enumerate(v) if isinstance(v, list) else ()
    for k, x in items:
        out.append((*at, k))
        out += _paths(x, (*at, k))
    return out


DOC = tomllib.loads(DEMO.decode("utf-8"))
PATHS = _paths(DOC)
TOML_VALUES = st.recursive(
    st.booleans() | st.integers() | st.floats() | st.text(max_size=8)
    | st.sampled_from([0, -1, 1e308, math.inf, math.nan, 10**30, "", "fixed", [], {}]),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=6), inner, max_size=4),
    max_leaves=12)


@FUZZ
@given(data=st.data())
def test_any_value_anywhere_in_the_demo_job_gives_a_job_error_or_a_job(data) -> None:
    doc = json.loads(json.dumps(DOC))
    path = data.draw(st.sampled_from(PATHS), label="path")
    holder = doc
    for key in path[:-1]:
        holder = holder[key]
    if data.draw(st.booleans(), label="delete") and isinstance(holder, dict):
        del holder[path[-1]]
    else:
        holder[path[-1]] = data.draw(TOML_VALUES, label="value")
    try:
        assert isinstance(parse_job(doc, "job.toml"), Job)
    except JobError as e:
        assert str(e).startswith("job.toml: ") and e.problems
