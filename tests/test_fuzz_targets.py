"""Every fuzz target of ``tests/fuzz_targets.py`` for a few seconds (issue 22): each reader, the job
and plan loaders and each wire parser gets a few dozen to 150 mutated inputs, each of which must
give a result that keeps its promises or a documented error, within 2 s and 500 MB. Big files are
mutated in windows here; ``make fuzz`` (``tests/fuzz_run.py``) runs the same targets for minutes,
whole files included, and keeps a corpus. No example database in the suite.
"""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import _fuzz_kit
import pytest
from _fuzz_kit import LIMIT_S, BadResult, Call, Case, cases, run_calls
from fuzz_targets import REPO, SHARED, TARGETS, check
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st

#: Inputs per target in the suite: a few seconds each on a loaded 2-core machine (the readers and
#: the plan loader take milliseconds an input, the packet parsers microseconds).
EXAMPLES = {"gcode": 150, "apt": 150, "krl": 150, "job": 150, "plan": 100, "kvp": 150, "rsi": 150,
            "udp": 150, "signal": 150}
#: A call still running after this long is interrupted, so a hang fails the test instead of the run [s].
SUITE_HANG_S = 10.0
#: Reproducible (the same inputs every run: ``make test`` does not flake; ``make fuzz`` explores) and
#: without shrinking (a failing input is saved as it is; shrinking a 100 kB program takes minutes).
SUITE = settings(deadline=LIMIT_S * 1000, database=None, derandomize=True,
                 phases=[Phase.explicit, Phase.generate],
                 suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                        HealthCheck.large_base_example])


def test_every_target_has_its_examples():
    assert sorted(EXAMPLES) == sorted(TARGETS)


@pytest.mark.parametrize("name", sorted(TARGETS))
def test_fuzz_target(name, tmp_path_factory):
    target = TARGETS[name]
    strategy = target.strategy(target.seeds(), False)
    folder = tmp_path_factory.mktemp(f"fuzz_{name}") / "case"
    saved = folder.parent / "failing"

    @settings(SUITE, max_examples=EXAMPLES[name])
    @given(case=strategy)
    def run(case: Case) -> None:
        verdict = check(target, case, folder, hang_s=SUITE_HANG_S)
        if verdict.kinds():
            case.save(saved / case.digest())
            pytest.fail(f"{name}: {sorted(verdict.kinds())}; input saved in {saved / case.digest()}\n"
                        f"{verdict.report()}", pytrace=False)

    run()


@pytest.mark.parametrize("name", sorted(TARGETS))
def test_every_seed_gives_a_result(name, tmp_path):
    """The seeds are inputs the parser reads (stale seeds would fuzz only the error paths); the
    real files are left to the readers' own tests (they take a second or more each)."""
    target = TARGETS[name]
    for case in target.seeds():
        if case.size > 64 * 1024:
            continue
        verdict = check(target, case, tmp_path / "case")
        assert not verdict.kinds(), verdict.report()
        assert any(c.status == "result" for c in verdict.calls), verdict.report()


@pytest.mark.skipif(not SHARED.is_dir(), reason=f"shared toolpath data not found at {SHARED} (expected "
                    "the repo next to ../shared/data/toolpaths)")
@pytest.mark.parametrize("name, suffixes", [("gcode", (".nc", ".ngc")), ("apt", (".apt",))])
def test_the_real_files_seed_the_readers(name, suffixes):
    real = {p.read_bytes() for p in SHARED.iterdir() if p.suffix in suffixes}
    assert real and real <= {d for c in TARGETS[name].seeds() for d in c.files.values()}


# -- the rule itself --------------------------------------------------------------------------------

def _raise(e: BaseException):
    def fn(_):
        raise e
    return fn


@pytest.mark.parametrize("fn, documented, status", [
    (lambda _: ("ok", 1), (), "result"),
    (_raise(KeyError("x")), (KeyError,), "error"),
    (_raise(KeyError("x")), (OSError,), "undocumented"),
    (_raise(BadResult("inf")), (), "bad"),
    (_raise(MemoryError()), (), "memory"),
])
def test_the_rule_sorts_what_a_call_does(fn, documented, status):
    (outcome,) = run_calls([Call("c", fn, documented)]).calls
    assert outcome.status == status
    assert (status in ("result", "error")) == (not run_calls([Call("c", fn, documented)]).kinds())


def test_a_malformed_documented_error_breaks_the_rule():
    verdict = run_calls([Call("c", _raise(ValueError("x")), (ValueError,),
                              lambda e: "does not name the file")])
    assert verdict.kinds() == {"bad"} and "does not name the file" in verdict.calls[0].signature


def test_a_slow_or_hung_call_breaks_the_rule(monkeypatch):
    monkeypatch.setattr(_fuzz_kit, "LIMIT_S", 0.01)
    assert run_calls([Call("c", lambda _: (time.sleep(0.03), ("ok", None))[1])]).kinds() == {"slow"}

    def spin(_):
        while True:
            pass

    verdict = run_calls([Call("c", spin)], hang_s=0.05)
    assert verdict.calls[0].status == "slow" and verdict.kinds() == {"slow"}


def test_a_file_left_open_breaks_the_rule(tmp_path):
    """What pytest reports as an unraisable ResourceWarning is the call's finding."""
    path = tmp_path / "f"
    path.write_bytes(b"x")
    verdict = run_calls([Call("c", lambda _: (open(path, "rb"), ("ok", None))[1])])
    assert verdict.kinds() == {"undocumented"} and "ResourceWarning" in verdict.calls[0].signature


def test_a_call_after_a_failed_one_is_skipped():
    verdict = run_calls([Call("a", _raise(KeyError()), (KeyError,)),
                         Call("b", lambda v: ("ok", v), needs_previous=True)])
    assert [c.status for c in verdict.calls] == ["error", "skipped"]


def test_memory_growth_is_the_calls_own():
    verdict = run_calls([Call("c", lambda _: ("ok", bytearray(64 * 2**20)))])
    assert 60 < verdict.rss_mb < 200


@settings(max_examples=30, database=None)
@given(data=st.data())
def test_mutations_keep_the_files_of_a_case(data):
    seed = Case({"a.src": b"LIN {X 1}\nEND\n", "a.dat": b"DEFDAT a\nENDDAT\n"})
    case = data.draw(cases([seed], {}, files_edits="companions"))
    assert next(iter(case.files)) == "a.src" and len(case.files) in (1, 2)


def test_a_case_saves_and_loads(tmp_path):
    case = Case({"x.bin": b"\x00\xff", "y.txt": b"y"}, {"fs_hz": 1000.0, "column": None})
    case.save(tmp_path / "c")
    assert Case.load(tmp_path / "c") == case


def test_the_runner_runs_a_target_and_prints_its_table(tmp_path):
    """``make fuzz`` in miniature: one target for about a second, its corpus in a temporary folder."""
    out = subprocess.run([sys.executable, str(REPO / "tests" / "fuzz_run.py"), "--minutes", "0.02",
                          "--target", "kvp", "--json", "--root", str(tmp_path)],
                         capture_output=True, text=True, timeout=120, check=False)
    assert out.returncode == 0, out.stderr
    (row,) = json.loads(out.stdout)["targets"]
    assert row["target"] == "kvp" and row["inputs"] > 0 and row["undocumented"] == 0
    assert (tmp_path / "last_run.md").read_text().startswith("| target |")
    assert Path(tmp_path / "corpus" / "kvp").is_dir()
