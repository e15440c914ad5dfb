"""One section numbering everywhere (issue 22): a section is numbered from 1 wherever a file or a
person sees it — the KRL folds, comments and ``.dat``, plan.json's ``index``, samples.npz's
``section``, the report's section table, ``cctmill plan``'s table and the supervisor's log and
summary — and every one of them names the same section for the same samples and source lines.

Named problem: the bundled demo job planned by the optimiser (``demo_optimized`` of conftest),
written with the report and a KRL program with the KukaVarProxy section marker; a short supervised
run of its plan on a virtual clock against the simulated cut (no sockets, no waiting).
"""

from __future__ import annotations

import html
import json
import re

import numpy as np
import pytest
from _plans import ApplyingLink

from planner.cli.plan import section_table
from planner.outputs import KrlOptions, write_plan_outputs
from planner.plan_file import Plan, load_plan
from planner.supervisor.loop import VirtualClock
from planner.supervisor.policy import SupervisorConfig
from planner.supervisor.session import SessionConfig, run_session, simulated_sigma
from planner.supervisor.sim_cut import CutScenario, SimulatedCut

#: The simulated cut's sample rate [Hz] and how long before the chosen section it starts [s].
FS_HZ = 10_000.0
LEAD_S = 0.2
#: The model error's onset [s] and the fraction of the planned feed that stays stable under it.
ONSET_S = 0.5
STABLE_FRACTION = 0.7

_FOLD = re.compile(r";FOLD section (\d+): (\w+), ([\d.]+) mm/s")
_COMMENT = re.compile(r"; plan section (\d+); source lines (\d+)-(\d+)")
_DECL = re.compile(r"DECL GLOBAL REAL (\w+)_F(\d+)=([\d.]+) ; section (\d+): (\w+),")


@pytest.fixture(scope="module")
def demo_out(demo_optimized, tmp_path_factory):
    """The demo plan's files: plan.json + samples.npz, report.html, the KRL with a marker."""
    out = tmp_path_factory.mktemp("demo_numbering")
    outputs = write_plan_outputs(demo_optimized, out, krl=KrlOptions(override_hook="kvp"))
    return out, outputs


def _folds(src: str) -> dict[int, dict]:
    """Each KRL section fold by the number in its title: kind, feed, the comment's number and
    source lines, the marker and the feed variable it sets."""
    folds: dict[int, dict] = {}
    lines = src.splitlines()
    for i, line in enumerate(lines):
        m = _FOLD.match(line)
        if not m:
            continue
        n = int(m.group(1))
        c = _COMMENT.match(lines[i + 1])
        assert c is not None, lines[i + 1]
        marker = re.match(r"\w+_SEC = (\d+)$", lines[i + 2])
        vel = re.match(r"\$VEL\.CP = \w+_F(\d+) ", lines[i + 3])
        assert marker and vel, lines[i + 2:i + 4]
        end = next(x for x in lines[i:] if x.startswith(";ENDFOLD"))
        folds[n] = {"kind": m.group(2), "feed_mm_s": float(m.group(3)),
                    "comment": int(c.group(1)), "lines": (int(c.group(2)), int(c.group(3))),
                    "marker": int(marker.group(1)), "feed_var": int(vel.group(1)), "end": end}
    return folds


def _report_rows(page: str) -> dict[int, list[str]]:
    """The report's section table, by the number in its first column."""
    table = page.split("<h2>Sections</h2>", 1)[1]
    rows = {}
    for tr in re.findall(r"<tr>(.*?)</tr>", table, flags=re.S)[1:]:      # [0]: the header
        cells = [html.unescape(c) for c in re.findall(r"<td[^>]*>(.*?)</td>", tr, flags=re.S)]
        rows[int(cells[0])] = cells
    return rows


def test_every_output_names_a_section_by_the_same_number(demo_out, demo_optimized):
    out, outputs = demo_out
    doc = json.loads((out / "plan.json").read_text(encoding="utf-8"))
    secs = doc["sections"]
    n = len(secs)
    assert [s["index"] for s in secs] == list(range(1, n + 1))
    with np.load(out / "samples.npz") as z:
        sample_section = z["section"]
    for s in secs:            # samples.npz numbers each sample's section as plan.json does
        assert set(sample_section[s["sample_start"]:s["sample_stop"]]) == {s["index"]}

    src = (out / "bracket_contour.src").read_text(encoding="ascii")
    dat = (out / "bracket_contour.dat").read_text(encoding="ascii")
    folds = _folds(src)
    decls = {int(m.group(2)): m for m in map(_DECL.match, dat.splitlines()) if m}
    rows = _report_rows((out / "report.html").read_text(encoding="utf-8"))
    table = {int(line.split()[0]): line.split() for line in section_table(demo_optimized, limit=n)
             .splitlines()[2:]}
    assert sorted(folds) == sorted(decls) == sorted(rows) == sorted(table) == list(range(1, n + 1))
    plan = outputs.plan
    for s in secs:
        k = s["index"]
        fold, decl, row = folds[k], decls[k], rows[k]
        # the KRL fold: its title, comment, marker, feed variable and end all say k
        assert (fold["comment"], fold["marker"], fold["feed_var"]) == (k, k, k)
        assert fold["end"] == f";ENDFOLD (section {k})"
        assert fold["kind"] == s["kind"] and fold["lines"] == (s["line_start"], s["line_end"])
        # the .dat: NAME_F00k holds section k's feed
        assert int(decl.group(4)) == k and decl.group(5) == s["kind"]
        assert float(decl.group(3)) * 1e3 == pytest.approx(s["feed_mm_s"], abs=1e-5)
        assert fold["feed_mm_s"] == pytest.approx(s["feed_mm_s"], abs=1e-5)
        # the report's row k and the CLI's: the same samples' arc length and source lines
        assert row[1] == s["kind"] and row[2] == f"{s['s_start_m']:.4f}"
        assert row[11] == f"{s['line_start']}–{s['line_end']}"
        assert table[k][1] == s["kind"] and table[k][-1] == f"{s['line_start']}-{s['line_end']}"
        # in memory: position k - 1, number k
        assert plan.sections[k - 1].index == k - 1 and plan.sections[k - 1].number == k


def _chatter_section(plan: Plan):
    """The longest-running cut section whose margin falls with feed, and the margin offset that
    makes its planned feed chatter and :data:`STABLE_FRACTION` of it stable."""
    best = None
    for sec in plan.sections:
        ch = sec.characteristic
        if sec.kind != "cut" or ch is None:
            continue
        at = float(np.interp(sec.feed, ch.feeds, ch.margin))
        below = float(np.interp(STABLE_FRACTION * sec.feed, ch.feeds, ch.margin))
        if below > at and (best is None or (sec.time or 0.0) > (best[0].time or 0.0)):
            best = (sec, below)
    assert best is not None
    return best


def test_the_supervisor_log_and_summary_number_sections_as_the_plan(demo_out, tmp_path):
    out, _ = demo_out
    plan = load_plan(out)
    sec, offset = _chatter_section(plan)
    prev = plan.sections[sec.index - 1]
    # start in the section before, LEAD_S before the chosen one, so the run crosses a boundary
    start = max(prev.s_start, sec.s_start - LEAD_S * prev.feed)
    scenario = CutScenario(onset_s=ONSET_S, boundary_shift=1.0, margin_offset_N_per_m=offset)
    clock, link = VirtualClock(), ApplyingLink()
    cut = SimulatedCut(plan, link.read_override, FS_HZ, scenario, clock=clock, start_s=start)
    log = tmp_path / "events.jsonl"
    config = SessionConfig(duration=2.0, start=start, log=str(log),
                           sigma=simulated_sigma(plan, FS_HZ, scenario, SupervisorConfig()))
    summary = run_session(plan, cut, link, config, FS_HZ, cut=cut, scenario=scenario,
                          clock=clock, sleep=clock.sleep)
    records = [json.loads(line) for line in log.read_text(encoding="utf-8").splitlines()]
    seen = [r["section"] for r in records]
    assert seen[0] == prev.number and sec.number in seen
    krl = _folds((out / "bracket_contour.src").read_text(encoding="ascii"))
    for r in records:
        s = plan.sections[r["section"] - 1]         # the log's number k is plan.json's index k
        if "s_m" in r:
            assert s.s_start - 1e-9 <= r["s_m"] <= s.s_end + 1e-9, r
        m = re.match(r"section (\d+) \(planned ([\d.]+) mm/s", r["reason"])
        if m:                                        # entering a section names it in words too
            assert int(m.group(1)) == r["section"]
            assert float(m.group(2)) == pytest.approx(krl[r["section"]]["feed_mm_s"], rel=5e-3)
    episodes = summary.as_json()["episodes"]
    assert episodes and episodes[0]["section"] == sec.number      # where the chatter was
