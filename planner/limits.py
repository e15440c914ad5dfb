"""The limits a plan holds, in SI: what the job's ``[limits]`` and ``[spindle]`` tables ask for.

One SI edge: :meth:`Limits.from_job` converts the job's units (mm, mm/s, kW) once;
:meth:`Limits.as_json` / :meth:`Limits.from_json` are plan.json's ``constraints`` object.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from planner.job import Job

__all__ = ["DEFLECTION_MODEL_UNCERTAINTY", "Limits"]

#: Default share of the predicted deflection δ the model gets wrong [-] (``[limits]
#: deflection_model_uncertainty``): a compensated path is off by about u·|δ| where the model is off
#: by u. 0.3 is a stated default, not a measurement: set it from the cell's calibration
#: (docs/posture.md).
DEFLECTION_MODEL_UNCERTAINTY = 0.3


@dataclass(frozen=True)
class Limits:
    """What no sample may exceed, SI (from the job's ``[limits]`` and ``[spindle]``).

    Attributes:
        force_max: resultant average cutting force [N].
        deflection_tol: ‖δ‖ at the TCP [m].
        power_max: spindle power [W].
        feed_min, feed_max: feed bounds [m/s].
        feed_change_max: largest feed change between neighbouring cut sections [m/s] (None: free).
        margin_min: required chatter stability margin [N/m] (eigen criterion).
        section_length_min: shortest section [m].
        path_acc_max: path acceleration of feed transitions [m/s²].
        path_jerk_max: path jerk of feed transitions [m/s³].
        rapid_speed: path-speed bound on rapid moves [m/s].
        cam_feed_scale_max: no cut sample runs faster than its programmed feed × this [-]
            (``inf``: the programmed feed is no limit; plans of older versions).
        deflection_model_uncertainty: the share u of δ the model may get wrong [-].
        compensate_deflection: the KRL export moves the path by −δ (``[export]
            compensate_deflection``); the deflection limit then holds what compensation leaves,
            :meth:`deflection_held`.
    """

    force_max: float
    deflection_tol: float
    power_max: float
    feed_min: float
    feed_max: float
    feed_change_max: float | None
    margin_min: float
    section_length_min: float
    path_acc_max: float
    path_jerk_max: float
    rapid_speed: float
    cam_feed_scale_max: float = 1.0
    deflection_model_uncertainty: float = DEFLECTION_MODEL_UNCERTAINTY
    compensate_deflection: bool = False

    def deflection_held(self, norm, change):
        """What the deflection tolerance applies to [m], same shape as ``norm``.

        Uncompensated, the wall is off by δ: ``norm`` = |δ|. Compensated (the export moves every
        LIN end point by −δ), what remains is the model's error u·|δ| plus what a shift of the end
        points cannot follow: ``change`` = |δ_i − δ_(i−1)|, the change of δ along the LIN that ends
        at the sample (at the same feed). The tooth-frequency ripple of δ is not modelled (the
        point model is static).

        Args:
            norm: |δ| [m].
            change: |δ_i − δ_(i−1)| [m] (ignored uncompensated).
        """
        if not self.compensate_deflection:
            return norm
        return self.deflection_model_uncertainty * norm + change

    @classmethod
    def from_job(cls, job: Job) -> Limits:
        lim = job.limits
        export = getattr(job, "export", None)
        return cls(force_max=lim.force_max_n, deflection_tol=lim.deflection_tol_mm * 1e-3,
                   power_max=job.spindle.power_max_kw * 1e3, feed_min=lim.feed_min_mm_s * 1e-3,
                   feed_max=lim.feed_max_mm_s * 1e-3,
                   feed_change_max=(None if lim.feed_change_max_mm_s is None
                                    else lim.feed_change_max_mm_s * 1e-3),
                   margin_min=lim.margin_min_n_per_m,
                   section_length_min=lim.section_length_min_mm * 1e-3,
                   path_acc_max=lim.path_acc_max_m_s2, path_jerk_max=lim.path_jerk_max_m_s3,
                   rapid_speed=lim.rapid_mm_s * 1e-3,
                   cam_feed_scale_max=lim.cam_feed_scale_max,
                   deflection_model_uncertainty=getattr(lim, "deflection_model_uncertainty",
                                                        DEFLECTION_MODEL_UNCERTAINTY),
                   compensate_deflection=bool(getattr(export, "compensate_deflection", False)))

    @classmethod
    def from_json(cls, doc: dict[str, Any]) -> Limits:
        """Limits from plan.json's ``constraints`` (units in the names); a key that is missing or
        ``null`` means no such limit (synthetic and older plans carry only some)."""

        def get(key: str, scale: float, none: float | None) -> float | None:
            v = doc.get(key)
            return none if v is None else float(v) * scale

        return cls(force_max=get("force_max_N", 1.0, math.inf),
                   deflection_tol=get("deflection_tol_mm", 1e-3, math.inf),
                   power_max=get("power_max_kW", 1e3, math.inf),
                   feed_min=get("feed_min_mm_s", 1e-3, 0.0),
                   feed_max=get("feed_max_mm_s", 1e-3, math.inf),
                   feed_change_max=get("feed_change_max_mm_s", 1e-3, None),
                   margin_min=get("margin_min_N_per_m", 1.0, 0.0),
                   section_length_min=get("section_length_min_mm", 1e-3, 0.0),
                   path_acc_max=get("path_acc_max_m_s2", 1.0, math.inf),
                   path_jerk_max=get("path_jerk_max_m_s3", 1.0, math.inf),
                   rapid_speed=get("rapid_mm_s", 1e-3, math.inf),  # type: ignore[arg-type]
                   cam_feed_scale_max=get("cam_feed_scale_max", 1.0, math.inf),  # type: ignore[arg-type]
                   deflection_model_uncertainty=get(  # type: ignore[arg-type]
                       "deflection_model_uncertainty", 1.0, DEFLECTION_MODEL_UNCERTAINTY),
                   compensate_deflection=bool(doc.get("compensate_deflection") or False))

    def as_json(self, safety_factor: float) -> dict:
        """The ``constraints`` object of plan.json (units in the names)."""
        return {
            "force_max_N": self.force_max, "deflection_tol_mm": self.deflection_tol * 1e3,
            "power_max_kW": self.power_max * 1e-3, "feed_min_mm_s": self.feed_min * 1e3,
            "feed_max_mm_s": self.feed_max * 1e3,
            "feed_change_max_mm_s": (None if self.feed_change_max is None
                                     else self.feed_change_max * 1e3),
            "margin_min_N_per_m": self.margin_min,
            "section_length_min_mm": self.section_length_min * 1e3,
            "path_acc_max_m_s2": self.path_acc_max, "path_jerk_max_m_s3": self.path_jerk_max,
            "rapid_mm_s": self.rapid_speed * 1e3,
            "cam_feed_scale_max": None if math.isinf(self.cam_feed_scale_max)
            else self.cam_feed_scale_max,
            "safety_factor": safety_factor,
            "deflection_model_uncertainty": self.deflection_model_uncertainty,
            "compensate_deflection": self.compensate_deflection,
        }
