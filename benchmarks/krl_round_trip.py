"""KRL export round trip: write → lint → read back, for the demo job and a long paged job.

For each case: the program is written by ``robot_io.krl`` (through ``planner.export`` for the demo
job), checked by ``robot_io.krl.lint`` and read back with ``robot_io.krl.reader``. Printed: moves,
CIRCs, pages, the largest position and orientation error of a move target, the largest distance
of a plan sample absorbed inside a CIRC from the read-back arc, whether every feed read back is
exactly its ``.dat`` value, lint problems, and write/read time (this machine, one run).
Targets (issue 5): 0.001 mm, 0.001°, feeds exact, no lint problem.

Run from the repository root: ``python benchmarks/krl_round_trip.py``.
"""

from __future__ import annotations

import math
import re
import sys
import tempfile
import time
from importlib import resources
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from planner.export import plan_to_krl  # noqa: E402
from robot_io.krl import KrlMove, KrlProgramSpec, KrlSection, write_krl  # noqa: E402
from robot_io.krl.lint import lint_krl  # noqa: E402
from robot_io.krl.reader import abc_to_matrix, read_krl  # noqa: E402
from robot_io.toolpath import MoveKind  # noqa: E402

SEED = 20240611
POS_TARGET_MM = 1e-3
ANG_TARGET_DEG = 1e-3


def _angle_deg(abc1, abc2) -> float:
    r = abc_to_matrix(*abc1).T @ abc_to_matrix(*abc2)
    return math.degrees(math.acos(max(-1.0, min(1.0, (np.trace(r) - 1) / 2))))


def _dist_to_move(p_mm: np.ndarray, m) -> float:
    if m.kind in (MoveKind.ARC_CW, MoveKind.ARC_CCW):
        c = m.center * 1e3
        d = p_mm - c
        off = float(d @ m.normal)
        return math.hypot(off, float(np.linalg.norm(d - off * m.normal))
                          - float(np.linalg.norm(m.end * 1e3 - c)))
    a, b = m.start * 1e3, m.end * 1e3
    t = float(np.clip((p_mm - a) @ (b - a) / max(float((b - a) @ (b - a)), 1e-30), 0, 1))
    return float(np.linalg.norm(a + t * (b - a) - p_mm))


def measure(name: str, spec, sections, moves, notes=(), samples_mm=None, sample_of=None) -> dict:
    with tempfile.TemporaryDirectory() as d:
        t0 = time.perf_counter()
        paths = write_krl(spec, sections, moves, d, notes)
        t1 = time.perf_counter()
        problems = lint_krl({p.name: p.read_bytes() for p in paths}, controller=spec.controller)
        t2 = time.perf_counter()
        tp = read_krl(paths[0])
        t3 = time.perf_counter()
        dat = "".join(p.read_text(encoding="ascii") for p in paths if p.suffix == ".dat")
    decl = dict(re.findall(r"DECL GLOBAL REAL (\w+_F\d+)=([0-9.]+)", dat))
    names = sorted(decl)
    cart = [m for m in moves if m.kind != "PTP"]
    assert len(tp.moves) == len(cart), "read-back move count differs"
    pos_err = max(float(np.abs(g.end * 1e3 - np.array(w.target[:3])).max())
                  for g, w in zip(tp.moves, cart, strict=True))
    ang_err = max(_angle_deg(g.extra["abc_deg"], w.target[3:])
                  for g, w in zip(tp.moves, cart, strict=True))
    # each move at its section's .dat value, times the last scale written in the section (a
    # feed profile: $VEL.CP = NAME_Fnnn * scale), as the controller computes it
    expect, scale, sec = [], 1.0, -1
    for w in cart:
        if w.section != sec:
            sec, scale = w.section, 1.0
        if w.feed_scale is not None:
            scale = w.feed_scale
        base = float(decl[names[w.section]])
        expect.append(base * scale if scale != 1.0 else base)
    feeds_exact = (all(g.feed == e for g, e in zip(tp.moves, expect, strict=True))
                   and all(float(decl[names[k]]) == s.feed_m_s for k, s in enumerate(sections)))
    absorbed = 0.0
    if samples_mm is not None:
        prev = -1
        for g, i in zip(tp.moves, sample_of, strict=True):
            for j in range(prev + 1, i):
                absorbed = max(absorbed, _dist_to_move(samples_mm[j], g))
            prev = i
    pages = sum(1 for p in paths if p.suffix == ".src")
    return {"case": name, "controller": spec.controller, "moves": len(moves),
            "circ": sum(m.kind == "CIRC" for m in moves), "src_files": pages,
            "pos_err_mm": pos_err, "ang_err_deg": ang_err, "absorbed_mm": absorbed,
            "feeds_exact": feeds_exact, "lint": len(problems), "write_ms": (t1 - t0) * 1e3,
            "lint_ms": (t2 - t1) * 1e3, "read_ms": (t3 - t2) * 1e3}


def long_job(n_moves: int = 12_000) -> tuple[list[KrlSection], list[KrlMove]]:
    """A zig-zag of 2 mm LIN steps with half-circle CIRC pairs at the turns, 30 sections."""
    rng = np.random.default_rng(SEED)
    secs = [KrlSection(float(f), "cut", "chatter") for f in rng.uniform(5e-4, 2e-3, 30)]
    per = n_moves // 30
    mv: list[KrlMove] = []
    x = y = 0.0
    direction = 1.0
    for k in range(30):
        for j in range(per):
            if j % 100 == 99:
                c = (x, y + 5)
                s = math.sqrt(0.5)
                mv.append(KrlMove("CIRC", (x + 5 * direction, y + 5, -1, 0, 90, 0), k,
                                  aux=(c[0] + 5 * s * direction, c[1] - 5 * s, -1, 0, 90, 0)))
                mv.append(KrlMove("CIRC", (x, y + 10, -1, 0, 90, 0), k,
                                  aux=(c[0] + 5 * s * direction, c[1] + 5 * s, -1, 0, 90, 0)))
                y += 10
                direction = -direction
                continue
            x += 2.0 * direction
            mv.append(KrlMove("LIN", (x, y, -1, float(rng.uniform(-20, 20)), 90, 0), k))
    return secs, mv


def main() -> list[dict]:
    from planner.job import load_job
    from planner.outputs import write_plan_outputs
    from planner.plan import plan_job

    rows = []
    job = load_job(str(resources.files("planner").joinpath("data/demo/demo_job.toml")))
    res = plan_job(job)
    with tempfile.TemporaryDirectory() as d:
        plan = write_plan_outputs(res, d, report=False).plan
        for controller, hook, comp in (("krc4", "rsi", False), ("krc2", "kvp", False),
                                       ("krc4", "none", True)):
            prog = plan_to_krl(plan, controller=controller, override_hook=hook, compensate=comp)
            smp = plan.samples
            p = smp.position_wp - (np.nan_to_num(smp.deflection_wp) if comp else 0.0)
            label = "demo job" + (" (compensated)" if comp else "") + f", hook {hook}"
            rows.append(measure(label, prog.spec, prog.sections, prog.moves, prog.notes,
                                p * 1e3, prog.sample_of_move))
    secs, mv = long_job()
    for controller in ("krc2", "krc4"):
        spec = KrlProgramSpec("LONG_JOB", (0, -90, 90, 0, 45, 0), controller=controller)
        rows.append(measure("long zig-zag, 30 sections", spec, secs, mv))
    head = ("| case | ctrl | moves | CIRC | .src files | max pos err mm | max ori err deg | "
            "max absorbed-sample dist mm | feeds exact | lint problems | write / lint / read ms |")
    print(head)
    print("|---" * (head.count("|") - 1) + "|")
    for r in rows:
        print(f"| {r['case']} | {r['controller']} | {r['moves']:,} | {r['circ']} | "
              f"{r['src_files']} | {r['pos_err_mm']:.2e} | {r['ang_err_deg']:.2e} | "
              f"{r['absorbed_mm']:.2e} | {'yes' if r['feeds_exact'] else 'NO'} | {r['lint']} | "
              f"{r['write_ms']:.0f} / {r['lint_ms']:.0f} / {r['read_ms']:.0f} |")
    ok = all(r["pos_err_mm"] <= POS_TARGET_MM and r["ang_err_deg"] <= ANG_TARGET_DEG
             and r["absorbed_mm"] <= POS_TARGET_MM and r["feeds_exact"] and r["lint"] == 0
             for r in rows)
    print(f"\ntargets (0.001 mm, 0.001 deg, feeds exact, lint clean): {'met' if ok else 'NOT met'}")
    return rows


if __name__ == "__main__":
    main()
