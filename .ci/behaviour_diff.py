#!/usr/bin/env python3
"""Behaviour check across a refactoring: run the same commands at two commits and diff what they write.

    .venv/bin/python .ci/behaviour_diff.py BASE [NEW]      # NEW defaults to the working tree

Each side runs from a clean ``git worktree`` of its commit (the working tree itself for NEW when it
is not given), with that tree first on ``PYTHONPATH`` and this checkout's ``.venv`` interpreter. It
compares:

- ``cctmill analyze --json`` on the thesis's Case 1 for both process models and both mass models;
- ``cctmill inspect --json`` of the demo job;
- the demo's ``plan.json`` (``cctmill demo``) and every file of its KRL program.

Numbers are compared exactly, after removing the fields that measure the machine rather than the plan
(``wall_times_s``, the solver's build and solve times) and the paths of the trees. A KRL line that
differs only in how a number prints (the same value to 1e-12, e.g. the float noise
``0.039645373000000005`` of a feed) is reported separately, as allowed. Exit status 0 when nothing
but allowed differences remain.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PY = ROOT / ".venv" / "bin" / "python"
CASE1 = ["--joints-deg=-96.42,-29.26,99.08,-9.95,83.23,-160.5", "--feed-dir", "0,1,0",
         "--radial-dir", "1,0,0", "--feed-mm-s", "1", "--ae-mm", "15.24", "--ap-mm", "5.08"]
#: keys whose values time the machine, not the plan (dropped before comparing)
VOLATILE = re.compile(r"^wall_times_s$|^(build|solve)_time_s$")
CLI = "import sys; from planner.cli import main; sys.exit(main())"


def _run(tree: Path, args: list[str], env: dict[str, str]) -> str:
    r = subprocess.run([str(PY), "-c", CLI, *args], cwd=tree, env=env, capture_output=True,
                       text=True, timeout=900)
    if r.returncode != 0:
        raise SystemExit(f"{tree}: cctmill {' '.join(args)} failed ({r.returncode}):\n{r.stderr}")
    return r.stdout


def _strip(obj):
    if isinstance(obj, dict):
        return {k: _strip(v) for k, v in obj.items() if not VOLATILE.search(k)}
    if isinstance(obj, list):
        return [_strip(v) for v in obj]
    return obj


def collect(tree: Path, out: Path) -> dict[str, object]:
    """Everything compared, keyed by a name."""
    env = dict(os.environ, PYTHONPATH=str(tree), MPLBACKEND="Agg")
    got: dict[str, object] = {}
    for process in ("thesis", "oriented"):
        for mass in ("isotropic", "robot"):
            text = _run(tree, ["analyze", *CASE1, "--process-model", process, "--mass", mass,
                               "--json"], env)
            got[f"analyze {process} {mass}"] = json.loads(text)
    job = tree / "planner" / "data" / "demo" / "demo_job.toml"
    got["inspect demo job"] = _strip(json.loads(_run(tree, ["inspect", str(job), "--json"], env)))
    _run(tree, ["demo", "-o", str(out)], env)
    plan = json.loads((out / "plan.json").read_text())
    plan.pop("job_folder", None)  # where the tree is, not what it planned
    got["demo plan.json"] = _strip(plan)
    for f in sorted((out / "krl").iterdir()):
        got[f"krl/{f.name}"] = f.read_text()
    # where the tree and the outputs are is not what was planned
    text = json.dumps(got).replace(str(tree), "<tree>").replace(str(out), "<out>")
    return json.loads(text)


_NUMBER = re.compile(r"[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?")


def _float_noise_only(a: str, b: str) -> bool:
    """True when two KRL texts differ only in how a number prints (the same value to 1e-12
    relative, e.g. ``0.039645373000000005`` and ``0.039645373``)."""
    la, lb = a.splitlines(), b.splitlines()
    if len(la) != len(lb):
        return False
    for x, y in zip(la, lb, strict=True):
        if x == y:
            continue
        if _NUMBER.sub("#", x) != _NUMBER.sub("#", y):
            return False
        for u, v in zip(_NUMBER.findall(x), _NUMBER.findall(y), strict=True):
            fu, fv = float(u), float(v)
            if abs(fu - fv) > 1e-12 * max(1.0, abs(fu)):
                return False
    return True


def _diff(name: str, a: object, b: object) -> str:
    import difflib

    if not isinstance(a, str):
        a, b = (json.dumps(v, indent=1, sort_keys=True) + "\n" for v in (a, b))
    lines = difflib.unified_diff(a.splitlines(True), b.splitlines(True),  # type: ignore[union-attr]
                                 f"base/{name}", f"new/{name}", n=0)
    return "".join(list(lines)[:60])


def main() -> int:
    if len(sys.argv) not in (2, 3):
        print(__doc__)
        return 2
    base, new = sys.argv[1], (sys.argv[2] if len(sys.argv) == 3 else None)
    tmp = Path(tempfile.mkdtemp(prefix="cctmill-bdiff-"))
    trees = []
    try:
        sides = {}
        for label, rev in (("base", base), ("new", new)):
            if rev is None:
                tree = ROOT
            else:
                tree = tmp / label
                subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", "-q",
                                str(tree), rev], check=True)
                trees.append(tree)
            print(f"{label}: {rev or 'working tree'} ({tree})", flush=True)
            sides[label] = collect(tree, tmp / f"out-{label}")
        a, b = sides["base"], sides["new"]
        bad = 0
        for name in sorted(set(a) | set(b)):
            if name not in a or name not in b:
                print(f"MISSING  {name}: only in {'base' if name in a else 'new'}")
                bad += 1
            elif a[name] == b[name]:
                print(f"same     {name}")
            elif name.startswith("krl/") and _float_noise_only(a[name], b[name]):  # type: ignore[arg-type]
                pairs = zip(a[name].splitlines(), b[name].splitlines(), strict=True)  # type: ignore[union-attr]
                n = sum(x != y for x, y in pairs)
                print(f"noise    {name}: {n} lines differ only in float noise of a number (allowed)")
                print(_diff(name, a[name], b[name])[:1200])
            else:
                print(f"DIFFERS  {name}")
                print(_diff(name, a[name], b[name]))
                bad += 1
        print(f"{len(set(a) | set(b))} outputs compared, {bad} differ")
        return 1 if bad else 0
    finally:
        for tree in trees:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(tree)],
                           check=False)
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    raise SystemExit(main())
