"""Run the fuzz targets of ``tests/fuzz_targets.py`` for minutes each, keep their corpus, and print
the table of the run (``make fuzz``; issue 22)::

    .venv/bin/python tests/fuzz_run.py [--minutes 10] [--target NAME ...] [--json] [--jobs 1]
                                       [--root fuzz] [--memory-cap-mb 4096]

Each target runs in a child process of its own, one after the other (``--jobs 2`` runs two at a
time), so that a crash, or a hang the in-process alarm cannot break (a loop inside C code), takes
down that target only; the parent kills a child that overruns its minutes by ``GRACE_S`` and saves
the input it was on. A child runs one hypothesis test of unbounded examples and stops it at the
first example after its minutes (another run if hypothesis ends one by itself). Every input is
judged by the target's rule (:func:`_fuzz_kit.run_calls`: a result that keeps its promises or a
documented error, each call within 2 s and 500 MB of peak resident memory growth, warnings
counted as errors as in the suite). A call over 2 s is run again and counts as slow when the
second run is over 2 s too (a shared machine's scheduler can stall one run; both times are in
its report). Each input reports its time to hypothesis (``target``, in half-octaves), which
steers generation towards slow inputs. The child caps its data segment at what it holds after
loading its seeds plus ``--memory-cap-mb``, so a runaway allocation is a ``MemoryError`` of one
call, not a machine that swaps.

What it keeps, under ``--root`` (default ``fuzz/`` at the repository root, git-ignored):

- ``corpus/<target>/hypothesis/``: hypothesis's example database (the pareto front of the slowest
  inputs), replayed by the next run;
- ``corpus/<target>/kept/<digest>/``: inputs whose outcome had a shape not seen before (another
  kind of error message, another set of skipped categories), seeds of the next run;
- ``findings/<target>/<kind>-<digest>/``: inputs that broke the rule (their files, ``case.json``,
  ``report.txt`` with the traceback), at most three per kind of failure; a child that died leaves
  the input it was on there too;
- ``last_run.md`` and ``last_run.json``: the table below and its numbers.

The table: target | minutes | inputs | undocumented exceptions | broken results | inputs > 2 s |
inputs > 500 MB | slowest input. The exit status is 1 when any input broke the rule or a child
died, else 0.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import resource
import shutil
import subprocess
import sys
import time
import warnings
from pathlib import Path
from typing import Any

from _fuzz_kit import HANG_S, LIMIT_MB, LIMIT_S, Case, Verdict
from fuzz_targets import REPO, TARGETS, check
from hypothesis import HealthCheck, Phase, Verbosity, given, settings
from hypothesis import target as hypothesis_target
from hypothesis.database import DirectoryBasedExampleDatabase

#: Inputs kept per kind of failure, and in the corpus per target.
MAX_FINDINGS_PER_KIND = 3
MAX_KEPT = 500
#: Largest input kept in the corpus [bytes].
MAX_KEPT_BYTES = 256 * 1024
#: Time a child gets beyond its minutes to load its seeds and finish its last input [s].
GRACE_S = 180.0


class _TimeUp(BaseException):
    """Raised by the test at its first example after the time is up: hypothesis lets a
    BaseException through at once (no shrinking, no replay)."""


class _Run:
    """One target's counts, findings and corpus during a child's run."""

    def __init__(self, name: str, root: Path) -> None:
        self.name = name
        self.findings = root / "findings" / name
        self.kept = root / "corpus" / name / "kept"
        self.inputs = 0
        self.calls = 0
        self.kinds = {"undocumented": 0, "bad": 0, "slow": 0, "memory": 0}
        self.unconfirmed_slow = 0
        self.failures: dict[str, dict[str, Any]] = {}
        self.slowest = (0.0, "")
        self.max_rss_mb = 0.0
        self.statuses: dict[str, int] = {}
        self.signatures = {(d / "signature.txt").read_text() for d in self._kept_dirs()}
        self.kept_new = 0

    def _kept_dirs(self) -> list[Path]:
        return sorted(d for d in self.kept.glob("*") if (d / "signature.txt").is_file()) \
            if self.kept.is_dir() else []

    def kept_cases(self) -> list[Case]:
        out = []
        for d in self._kept_dirs():
            try:
                out.append(Case.load(d))
            except (OSError, ValueError, KeyError):
                continue    # a damaged corpus entry is not a seed
        return out

    def add(self, case: Case, verdict: Verdict, again: Verdict | None) -> None:
        self.inputs += 1
        self.calls += len(verdict.calls)
        for c in verdict.calls:
            self.statuses[c.status] = self.statuses.get(c.status, 0) + 1
        kinds = verdict.kinds()
        seconds = verdict.seconds
        if again is not None:      # an input over the limit, run a second time
            seconds = min(seconds, again.seconds)
            if "slow" not in again.kinds():
                kinds.discard("slow")
                self.unconfirmed_slow += 1
        if seconds > self.slowest[0]:
            label = max(verdict.calls, key=lambda c: c.seconds).label
            self.slowest = (seconds, f"{label}, {case.size:,} B, {case.digest()}")
        self.max_rss_mb = max(self.max_rss_mb, verdict.rss_mb)
        for kind in kinds:
            self.kinds[kind] += 1
        if kinds:
            self._finding(case, verdict, again, kinds)
        elif verdict.signature not in self.signatures and case.size <= MAX_KEPT_BYTES \
                and len(self.signatures) < MAX_KEPT:
            self.signatures.add(verdict.signature)
            folder = self.kept / case.digest()
            case.save(folder)
            (folder / "signature.txt").write_text(verdict.signature)
            self.kept_new += 1

    def _finding(self, case: Case, verdict: Verdict, again: Verdict | None, kinds: set[str]) -> None:
        failing = [c for c in verdict.calls if c.status in ("undocumented", "bad", "slow", "memory")
                   or c.seconds > LIMIT_S or c.rss_mb > LIMIT_MB]
        key = f"{'+'.join(sorted(kinds))}: {failing[0].label}: {failing[0].signature}" if failing else \
            "+".join(sorted(kinds))
        entry = self.failures.setdefault(key, {"kinds": sorted(kinds), "inputs": 0, "saved": []})
        entry["inputs"] += 1
        folder = self.findings / f"{'+'.join(sorted(kinds))}-{case.digest()}"
        if len(entry["saved"]) < MAX_FINDINGS_PER_KIND and str(folder) not in entry["saved"]:
            case.save(folder)
            report = verdict.report() + ("" if again is None else "\n\nrun again:\n" + again.report())
            (folder / "report.txt").write_text(report + "\n")
            entry["saved"].append(str(folder))

    def row(self, minutes: float) -> dict[str, Any]:
        return {"target": self.name, "minutes": round(minutes, 2), "inputs": self.inputs,
                "calls": self.calls, "undocumented": self.kinds["undocumented"], "bad": self.kinds["bad"],
                "slow": self.kinds["slow"], "memory": self.kinds["memory"],
                "unconfirmed_slow": self.unconfirmed_slow, "slowest_s": round(self.slowest[0], 3),
                "slowest": self.slowest[1], "max_rss_growth_mb": round(self.max_rss_mb, 1),
                "statuses": self.statuses, "kept_new": self.kept_new, "corpus": len(self.signatures),
                "failures": self.failures, "died": None}


def _cap_memory(extra_mb: float) -> None:
    """Cap the data segment at what the process holds now plus ``extra_mb`` (Linux)."""
    try:
        with open("/proc/self/status", "rb") as f:
            data_mb = next(float(line.split()[1]) / 1024.0 for line in f if line.startswith(b"VmData"))
    except (OSError, StopIteration):
        return
    limit = int((data_mb + extra_mb) * 2**20)
    resource.setrlimit(resource.RLIMIT_DATA, (limit, resource.getrlimit(resource.RLIMIT_DATA)[1]))


def child(name: str, minutes: float, root: Path, result: Path, memory_cap_mb: float) -> int:
    """Fuzz one target for ``minutes``; write its row as JSON to ``result``."""
    target = TARGETS[name]
    run = _Run(name, root)
    started = time.monotonic()
    seeds = target.seeds() + [Case(c.files) for c in run.kept_cases()]
    strategy = target.strategy(seeds, True)
    work = root / "work" / name        # the input being run: left behind if the child dies
    database = DirectoryBasedExampleDatabase(str(root / "corpus" / name / "hypothesis"))
    if memory_cap_mb > 0:
        _cap_memory(memory_cap_mb)
    warnings.simplefilter("error")     # as in the suite (pyproject: filterwarnings = error)
    fuzz_start = time.monotonic()
    deadline = fuzz_start + minutes * 60.0

    def one(case: Case) -> None:
        if time.monotonic() >= deadline:
            raise _TimeUp
        verdict = check(target, case, work, HANG_S)
        again = check(target, case, work, HANG_S) if "slow" in verdict.kinds() else None
        run.add(case, verdict, again)
        # in half-octaves: noise-free ties keep hypothesis's pareto front (the database) small
        hypothesis_target(round(2.0 * math.log2(max(verdict.seconds, 1e-4))) / 2.0, label="log2 s")

    test = settings(max_examples=10**9, database=database, deadline=None, print_blob=False,
                    phases=[Phase.reuse, Phase.generate, Phase.target], report_multiple_bugs=False,
                    suppress_health_check=list(HealthCheck), verbosity=Verbosity.quiet)(
        given(case=strategy)(one))
    while time.monotonic() < deadline:   # hypothesis may end a run on its own: start another
        try:
            test()
        except _TimeUp:
            break
    shutil.rmtree(work, ignore_errors=True)
    row = run.row((time.monotonic() - fuzz_start) / 60.0)
    row["seed_s"] = round(fuzz_start - started, 1)
    result.write_text(json.dumps(row, indent=1) + "\n")
    return 0


def _died(name: str, root: Path, minutes: float, how: str) -> dict[str, Any]:
    """The row of a child that did not report: its last input saved as a finding."""
    work = root / "work" / name
    saved = []
    if work.is_dir():
        folder = root / "findings" / name / f"died-{time.strftime('%Y%m%d-%H%M%S')}"
        shutil.copytree(work, folder, dirs_exist_ok=True)
        (folder / "report.txt").write_text(f"the child {how} while running this input\n")
        saved.append(str(folder))
    return {"target": name, "minutes": round(minutes, 2), "inputs": 0, "calls": 0, "undocumented": 0,
            "bad": 0, "slow": 0, "memory": 0, "unconfirmed_slow": 0, "slowest_s": 0.0, "slowest": "",
            "max_rss_growth_mb": 0.0, "statuses": {}, "kept_new": 0, "corpus": 0,
            "failures": {f"died: {how}": {"kinds": ["died"], "inputs": 1, "saved": saved}}, "died": how}


def _spawn(name: str, args: argparse.Namespace, root: Path) -> tuple[subprocess.Popen, Path, float]:
    result = root / "work" / f"{name}.result.json"
    result.unlink(missing_ok=True)
    cmd = [sys.executable, os.path.abspath(__file__), "--child", name, "--minutes", str(args.minutes),
           "--root", str(root), "--memory-cap-mb", str(args.memory_cap_mb)]
    return subprocess.Popen(cmd, stdout=sys.stderr), result, time.monotonic()


def _collect(name: str, proc: subprocess.Popen, result: Path, t0: float, args: argparse.Namespace,
             root: Path) -> dict[str, Any]:
    try:
        rc = proc.wait(timeout=max(0.0, args.minutes * 60.0 + GRACE_S - (time.monotonic() - t0)))
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()
        return _died(name, root, args.minutes, f"hung: killed {GRACE_S:.0f} s after its minutes")
    if rc != 0 or not result.is_file():
        return _died(name, root, args.minutes, f"exited with status {rc}")
    return json.loads(result.read_text())


def table(rows: list[dict[str, Any]]) -> str:
    """The Markdown table of a run."""
    out = ["| target | minutes | inputs | undocumented exceptions | broken results | inputs > 2 s "
           "| inputs > 500 MB | slowest input |", "|---|---:|---:|---:|---:|---:|---:|---|"]
    for r in rows:
        slowest = f"{r['slowest_s']:.3f} s: {r['slowest']}" if r["slowest"] else "-"
        if r["died"]:
            slowest = f"child {r['died']}"
        out.append(f"| {r['target']} | {r['minutes']:.1f} | {r['inputs']:,} | {r['undocumented']} | "
                   f"{r['bad']} | {r['slow']} | {r['memory']} | {slowest} |")
    return "\n".join(out) + "\n"


def _failed(r: dict[str, Any]) -> bool:
    return bool(r["died"] or r["undocumented"] or r["bad"] or r["slow"] or r["memory"])


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--minutes", type=float, default=10.0, help="wall time per target (default 10)")
    p.add_argument("--target", action="append", choices=sorted(TARGETS),
                   help="a target to run (repeatable; default: all)")
    p.add_argument("--json", action="store_true", help="print the run as JSON instead of the table")
    p.add_argument("--jobs", type=int, default=1, help="targets run at the same time (default 1)")
    p.add_argument("--root", type=Path, default=REPO / "fuzz",
                   help="corpus, findings and last run (default fuzz/ in the repository)")
    p.add_argument("--memory-cap-mb", type=float, default=4096.0,
                   help="data segment a child may grow by (0: no cap; default 4096)")
    p.add_argument("--child", help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    root = args.root.resolve()
    if args.child:
        return child(args.child, args.minutes, root, root / "work" / f"{args.child}.result.json",
                     args.memory_cap_mb)
    (root / "work").mkdir(parents=True, exist_ok=True)
    names = args.target or list(TARGETS)
    rows: dict[str, dict[str, Any]] = {}
    pending = list(names)
    running: list[tuple[str, subprocess.Popen, Path, float]] = []
    while pending or running:
        while pending and len(running) < max(1, args.jobs):
            name = pending.pop(0)
            print(f"fuzzing {name} for {args.minutes:g} min: {TARGETS[name].rule}", file=sys.stderr)
            running.append((name, *_spawn(name, args, root)))
        name, proc, result, t0 = running.pop(0)
        rows[name] = _collect(name, proc, result, t0, args, root)
    ordered = [rows[n] for n in names]
    md = table(ordered)
    (root / "last_run.md").write_text(md)
    (root / "last_run.json").write_text(json.dumps({"targets": ordered}, indent=1) + "\n")
    if args.json:
        print(json.dumps({"targets": ordered}, indent=1))
    else:
        print(md, end="")
        for r in ordered:
            for key, f in r["failures"].items():
                print(f"- {r['target']}: {f['inputs']} input(s): {key}; saved: {', '.join(f['saved'])}")
    return 1 if any(_failed(r) for r in ordered) else 0


if __name__ == "__main__":
    sys.exit(main())
