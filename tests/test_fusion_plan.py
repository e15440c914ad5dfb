"""The shared Fusion 360 program (pocket, contours, 0.5 mm-pitch helical bores; 2.8 mm flat end
mill) plans end to end with the Z-map stock model and the KRL export, and the independent checker
finds nothing (issue 16). The deflection tolerance is 0.5 mm: with 0.1 mm the finishing contour,
cut 10 mm deep in one pass, is infeasible at any feed (the edge forces alone bend the arm more),
which the planner says with its line."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from planner.check import check_result
from planner.job import parse_job
from planner.outputs import KrlOptions, run_plan_job
from planner.plan import PlanInfeasibleError
from planner.sections import CUT
from robot_io.krl.reader import read_krl

FUSION = Path(__file__).resolve().parents[2] / "shared" / "data" / "toolpaths" / \
    "fusion360_1117_wall_28bit.nc"

pytestmark = pytest.mark.skipif(not FUSION.is_file(),
                                reason=f"the shared Fusion 360 program is not at {FUSION}")


def _job(deflection_tol_mm: float = 0.5):
    doc = {"job": {"name": "fusion_wall", "toolpath": [FUSION.as_posix()]},
           "cell": {"base_mm": [1500.0, -60.0, 400.0], "tcp_mm": [320.0, 0.0, 0.0]},
           "tool": {"diameter_mm": 2.8}, "spindle": {"rpm": 5000.0},
           "limits": {"deflection_tol_mm": deflection_tol_mm},
           "engagement": {"stock": {"box_mm": [0.0, 0.0, 228.0, 70.0],
                                    "z_bottom_mm": -14.0, "z_top_mm": 0.0}}}
    return parse_job(doc, "fusion_wall.toml", FUSION.parent)


def test_the_fusion_program_plans_with_the_zmap_and_krl(tmp_path):
    job = _job()
    assert job.engagement.source == "zmap"          # the default for a job with a stock
    out = run_plan_job(job, tmp_path, "optimize", krl=KrlOptions())
    res = out.result
    assert res.solver.success
    report = check_result(res)
    assert report.ok, report.violations[:5]
    # the bores: a_p is the pitch, not the bore depth
    e, path = res.prep.engagement, res.prep.path
    assert e.a_p[e.mode >= 0].min() > 0 and e.a_e.max() <= 2.8e-3 * (1 + 1e-9)
    # nothing cuts faster than programmed (the default factor 1)
    cut = res.kinds == CUT
    assert np.all(res.feed[cut] <= path.feed[cut] * (1 + 1e-12))
    bindings = {s.binding for s in out.plan.sections}
    assert "cam_feed" in bindings
    kinds = {w.kind for w in out.plan.warnings}
    assert {"tool_data", "coefficients"} <= kinds
    # the KRL program reads back with the plan's feeds
    src = sorted(p for p in out.files["krl"] if p.suffix == ".src")[0]
    tp = read_krl(src)
    assert len(tp.moves) > 0


def test_the_finishing_contour_is_infeasible_at_a_tenth_of_a_millimetre():
    from planner.plan import plan_job

    with pytest.raises(PlanInfeasibleError, match=r"fusion360_1117_wall_28bit.nc:\d+\): "
                                                  r"deflection limit cannot be met"):
        plan_job(_job(0.1), "constant")
