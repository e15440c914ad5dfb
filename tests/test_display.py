"""What people read (issue 22): no Python ``None`` or ``nan`` and no float noise
(``2.4000000000000004``) in the report, the command line's summaries or error messages; a missing
value says what it means ("not limited", "no optimisation: …").

Named problem: the bundled demo job (``demo_prepared`` of conftest) planned by the optimiser and by
the thesis algorithm, its report rendered to HTML (its visible text read, no browser).
"""

from __future__ import annotations

import html
import math
import re

import numpy as np
import pytest

from models.errors import CctmillError
from planner.display import MISSING, quantity
from planner.engagement import fixed_engagement
from planner.optimize import NOT_SOLVED, SolveResult
from planner.plan import plan_prepared
from planner.report import write_report
from planner.supervisor.detector import select_level
from planner.supervisor.metrics import episode_timing_text
from robot_io.krl import KrlMove, KrlProgramSpec, KrlSection, render_krl

#: Significant digits a number a person reads may have; float noise has 16–17.
MAX_SIGNIFICANT = 8
#: A number in running text (a sign, digits, a decimal part, an exponent).
_NUMBER = re.compile(r"(?<![\w.])[-+]?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?(?![\w.])")

HOME = (0.0, -90.0, 90.0, 0.0, 45.0, 0.0)


def _significant(number: str) -> int:
    mantissa = re.split(r"[eE]", number.lstrip("+-"))[0]
    digits = mantissa.replace(".", "").lstrip("0")
    if "." in mantissa:        # trailing zeros after the point are digits someone chose to show
        return len(digits)
    return len(digits.rstrip("0")) or 1


def _visible_text(page: str) -> str:
    """What a browser shows of an HTML page: no styles, no scripts (the 3-D view's data and
    its packed plotly.js), no embedded images, no tags."""
    page = re.sub(r"<style>.*?</style>", " ", page, flags=re.S)
    page = re.sub(r"<script[^>]*>.*?</script>", " ", page, flags=re.S)
    page = re.sub(r"<img[^>]*>", " ", page)
    return html.unescape(re.sub(r"<[^>]+>", " ", page))


def _noise(text: str) -> list[str]:
    """What in ``text`` a person should never see: None, nan, n/a, over-long numbers."""
    bad = re.findall(r"\b(?:None|nan|NaN|inf|n/a)\b", text)
    bad += [m for m in _NUMBER.findall(text) if _significant(m) > MAX_SIGNIFICANT]
    return bad


@pytest.mark.parametrize("v, args, shown", [
    (None, (), MISSING),
    (math.nan, (), MISSING),
    (math.inf, ("g", "", "not limited"), "not limited"),
    (None, ("g", "ms", "no alarm"), "no alarm"),
    (2400 * 1e-3, ("g", "m/s"), "2.4 m/s"),
    (np.float64(0.1 + 0.2), (".4g",), "0.3"),
    (183.47, (".0f", "ms"), "183 ms"),
    (0, ("d",), "0"),
])
def test_quantity(v, args, shown):
    assert quantity(v, *args) == shown


def test_noise_finder_finds_noise():
    assert _noise("feed 2.4000000000000004 m/s, onset to alarm None ms, solver n/a, nan") == [
        "None", "n/a", "nan", "2.4000000000000004"]
    assert _noise("feed 2.4 m/s; margin 5.12e+05 N/m; 0.008252921 m/s; 892 samples") == []


@pytest.mark.parametrize("method, solver", [
    ("optimize", r"IPOPT Solve_Succeeded after \d+ iterations \(build [\d.]+ s, solve [\d.]+ s\)"),
    ("thesis", r"no optimisation: the thesis section algorithm sets the feeds"),
])
def test_the_report_shows_no_none_nan_or_float_noise(demo_prepared, tmp_path, method, solver):
    res = plan_prepared(demo_prepared, method)
    page = write_report(res, tmp_path)["report"].read_text(encoding="utf-8")
    text = _visible_text(page)
    assert _noise(text) == []
    assert re.search(r"solver\s+" + solver, text), text[:2000]
    # a limit the job does not set is said so (the demo sets no feed_change_max_mm_s)
    assert res.limits.feed_change_max is None
    assert re.search(r"feed_change_max_mm_s\s+not limited", text)


def test_a_plan_without_optimisation_says_what_set_its_feeds(demo_prepared):
    assert plan_prepared(demo_prepared, "constant").solver.describe() == (
        "no optimisation: one constant feed, the lowest ceiling of the cut")
    assert SolveResult(NOT_SOLVED, True, 0, 0.0, 0.0, 0.0).describe() == "no optimisation"
    assert SolveResult("Solve_Succeeded", True, 1, 0.0012, 0.25, 1.0).describe() == (
        "IPOPT Solve_Succeeded after 1 iteration (build 0.001 s, solve 0.250 s)")


def test_episode_timing_says_what_a_missing_time_means():
    assert episode_timing_text({"section": 3}) == ""          # no simulated truth: nothing to say
    none = episode_timing_text({"detection_delay_ms": None, "onset_to_alarm_ms": None,
                                "settling_ms": None, "quiet_ms": None})
    assert _noise(none) == [] and "ms" not in none
    assert none == ("alarm before the chatter reached the visible amplitude (a transient, not "
                    "chatter), the chatter not gone by the end of the record, the episode still "
                    "open at the end")
    some = episode_timing_text({"detection_delay_ms": 170.43, "onset_to_alarm_ms": 402.3,
                                "settling_ms": 341.6, "quiet_ms": 95.0})
    assert some == ("detected 170 ms after the chatter became visible, 402 ms from the onset to "
                    "the alarm, gone 342 ms after the alarm, declared quiet 95 ms after the alarm")


def test_the_supervise_summary_text_has_no_none():
    from planner.cli.supervise import _text

    summary = {
        "plan": "out/plan.json", "signal": "sim", "robot": "sim", "fs_hz": 10_000.0,
        "level_reason": "level 9", "L_c": 4.2, "sigma": None, "ucl": None, "steps": 0,
        "duration_s": 0.0, "status_counts": {},
        "step_latency_ms": {"p50": None, "p99": None, "max": None, "cycle": 4.0},
        "final_override": None, "overruns": 0, "link_writes": 0, "link_failures": 0,
        "link_downs": 0, "link_stats": {"writes": 0}, "source_stats": {"samples": 0},
        "episodes": [{"section": 41, "override_start": 100.0, "override_min": 62.5,
                      "direction": -1, "detection_delay_ms": None, "onset_to_alarm_ms": None,
                      "settling_ms": 341.6, "quiet_ms": None}],
    }
    text = _text(summary)
    assert _noise(text) == [], text
    assert "step latency  p50 —, p99 —, max — (cycle 4 ms" in text
    assert "final none commanded;" in text
    assert "section 41: override 100.0 -> 62.5 % (direction -1); alarm before the chatter" in text


@pytest.mark.parametrize("make, shown, noise", [
    # $VEL.CP of 2400 mm/s in m/s: 2.4000000000000004 as a float
    (lambda: render_krl(KrlProgramSpec("P", HOME), [KrlSection(2400 * 1e-3)],
                        [KrlMove("LIN", (0, 0, 0, 0, 90, 0), 0)]),
     "2.4 m/s is above KR C4's $VEL.CP maximum 2 m/s", "2.4000000000000004"),
    # a depth of cut typed in mm, in m
    (lambda: fixed_engagement(2, -0.3 * 1e-3, 5e-3, "up", np.tile([1.0, 0, 0], (2, 1)),
                              (0, 0, 1.0), np.ones(2, bool)),
     "a_e (-0.0003 m)", "0.00030000000000000003"),
    # a chatter frequency of sqrt(f1 f2) against half a sample rate
    (lambda: select_level(1000.0 * 1.1, math.sqrt(600.0 * 600.0 * 1.0000000001)),
     "must lie in (0, f_s/2 = 550 Hz)", "550.0000000000001"),
])
def test_messages_show_numbers_not_float_noise(make, shown, noise):
    with pytest.raises(CctmillError) as e:
        make()
    msg = str(e.value)
    assert shown in msg and noise not in msg, msg
    assert [m for m in _NUMBER.findall(msg) if _significant(m) > MAX_SIGNIFICANT] == [], msg
