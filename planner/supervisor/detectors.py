"""The chatter detectors by name: ``dwt`` (the thesis's wavelet band, the default) and ``iir`` (a
band-pass with tooth notches, faster; docs/supervisor.md, "Detectors")."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from models.errors import InputError
from planner.supervisor.characteristic import chatter_frequency
from planner.supervisor.detector import Detector, LevelChoice, select_level
from planner.supervisor.detector_iir import IirDetector

if TYPE_CHECKING:
    from planner.plan_file import Plan
    from planner.supervisor.step import SupervisorConfig

__all__ = ["DEFAULT_DETECTOR", "DETECTORS", "detector_for_plan", "make_detector"]

#: Name → detector class; every class takes (fs_hz, choice, alpha_f, sigma, wavelet).
DETECTORS: dict[str, type[Detector]] = {"dwt": Detector, "iir": IirDetector}
#: The thesis's detector.
DEFAULT_DETECTOR = "dwt"


def make_detector(name: str, fs_hz: float, choice: LevelChoice, alpha_f: float,
                  sigma: float | None, wavelet: str) -> Detector:
    """The detector called ``name`` (a key of :data:`DETECTORS`).

    Raises:
        InputError: an unknown name.
    """
    cls = DETECTORS.get(name)
    if cls is None:
        raise InputError("detector", f"{name!r} is not a detector; use one of "
                         f"{', '.join(sorted(DETECTORS))}")
    return cls(fs_hz, choice, alpha_f, sigma, wavelet)


def detector_for_plan(plan: Plan, cfg: SupervisorConfig, fs_hz: float,
                      sigma: float | None) -> Detector:
    """The configured detector for a plan: f_c the median expected chatter frequency of its cut
    sections (``cfg.chatter_hz`` where a section has no natural frequencies), f_t the median tooth
    frequency, the DWT level from :func:`~planner.supervisor.detector.select_level`."""
    cuts = [s for s in plan.sections if s.kind == "cut"] or list(plan.sections)
    f_c = float(np.median([chatter_frequency(s, cfg.chatter_hz) for s in cuts]))
    teeth = [s.tooth_frequency for s in cuts if s.tooth_frequency]
    f_t = float(np.median(teeth)) if teeth else None
    choice = select_level(fs_hz, f_c, f_t)
    return make_detector(cfg.detector, fs_hz, choice, cfg.alpha_f, sigma, cfg.wavelet)
