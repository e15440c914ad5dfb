"""Calibration from cuts (docs/calibration.md): cut records, the fits, test cuts, a simulated truth.

Lazy (PEP 562): importing the records format does not load the physics.
"""

from __future__ import annotations

import importlib
from typing import Any

__all__ = [
    "Boundary",
    "CalibrationContext",
    "CalibrationResult",
    "CoefficientFit",
    "CutRecord",
    "CutSuggestion",
    "FitRefused",
    "ProcessGainFit",
    "RecordError",
    "SectionRecorder",
    "StiffnessFit",
    "TestCutsResult",
    "TruthCell",
    "along_job_cuts",
    "best_design",
    "calibrate",
    "coefficient_bound",
    "fit_boundary",
    "fit_coefficients",
    "fit_process_gain",
    "fit_stiffness",
    "identification_cuts",
    "load_records",
    "load_truth",
    "margin_floors",
    "propose_along_job",
    "propose_cuts",
    "run_cuts",
    "section_record",
    "section_templates",
    "suggest_levels_and_speed",
    "testcuts",
    "write_calibration",
    "write_records",
]

_WHERE = {
    "Boundary": "fit_boundary", "CalibrationContext": "context", "CalibrationResult": "run",
    "CoefficientFit": "fit_coefficients", "CutRecord": "records",
    "FitRefused": "fit_coefficients", "RecordError": "records",
    "SectionRecorder": "supervisor_records", "StiffnessFit": "fit_stiffness",
    "TestCutsResult": "run", "TruthCell": "truth", "calibrate": "run",
    "fit_boundary": "fit_boundary", "fit_coefficients": "fit_coefficients",
    "fit_stiffness": "fit_stiffness", "identification_cuts": "testcuts",
    "load_records": "records", "load_truth": "truth", "margin_floors": "fit_boundary",
    "propose_cuts": "testcuts", "run_cuts": "truth", "section_record": "supervisor_records",
    "testcuts": "run", "write_calibration": "run", "write_records": "records",
    "CutSuggestion": "suggest", "ProcessGainFit": "fit_process", "along_job_cuts": "testcuts",
    "fit_process_gain": "fit_process", "propose_along_job": "testcuts",
    "section_templates": "testcuts", "suggest_levels_and_speed": "suggest",
    "best_design": "design_bound", "coefficient_bound": "design_bound",
}


def __getattr__(name: str) -> Any:
    if name in _WHERE:
        return getattr(importlib.import_module(f"{__name__}.{_WHERE[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
