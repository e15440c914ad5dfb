"""The one exception tree of cctmill.

Every error a user can cause derives from :class:`CctmillError` and carries a message that says how
to fix it. Leaves carry structured fields so scripts can react without parsing text. Backend
exceptions (CasADi, pinocchio) are wrapped with ``raise ... from e``.

The tree lives in ``models`` because every other package (``planner``, ``robot_io``) may import
``models`` but not each other.
"""

from __future__ import annotations

__all__ = [
    "CctmillError",
    "DataFileError",
    "InputError",
    "SingularPoseError",
    "UnknownDataError",
    "UnreachablePoseError",
]


class CctmillError(Exception):
    """Root of every error cctmill raises on purpose."""


class InputError(CctmillError, ValueError):
    """A value given by the user is out of range or inconsistent.

    Attributes:
        field: name of the offending input, in the user's terms (e.g. ``"--ae-mm"``).
    """

    def __init__(self, field: str, message: str) -> None:
        super().__init__(f"{field}: {message}")
        self.field = field


class UnknownDataError(CctmillError, KeyError):
    """A named material, tool or robot has no data file.

    Attributes:
        kind: ``"material"``, ``"tool"`` or ``"robot"``.
        name: the name asked for.
        available: the names that do exist.
    """

    def __init__(self, kind: str, name: str, available: list[str]) -> None:
        self.kind = kind
        self.name = name
        self.available = sorted(available)
        super().__init__(
            f"unknown {kind} {name!r}; available: {', '.join(self.available) or '(none)'}"
            f" (add a data file to ship another {kind})"
        )

    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0])


class DataFileError(CctmillError):
    """A shipped or user data file (URDF, robot/material/tool TOML) is malformed.

    Attributes:
        path: the file.
    """

    def __init__(self, path: str, message: str) -> None:
        super().__init__(f"{path}: {message}")
        self.path = path


class SingularPoseError(CctmillError):
    """The pose is at (or too near) a kinematic singularity: the Jacobian loses rank.

    Attributes:
        measure: the singularity measure that fell below its threshold.
        value: its value.
        threshold: the threshold.
    """

    def __init__(self, measure: str, value: float, threshold: float, hint: str = "") -> None:
        self.measure = measure
        self.value = value
        self.threshold = threshold
        super().__init__(
            f"singular pose: {measure} = {value:.3g} below {threshold:.3g}"
            + (f"; {hint}" if hint else "; move the wrist (A5) away from 0 deg or the arm from full stretch")
        )


class UnreachablePoseError(CctmillError):
    """A joint configuration violates a joint limit (or a Cartesian pose has no IK solution).

    Attributes:
        joint: joint name (``"A1"``..``"A6"``), or ``None`` when no single joint is to blame.
        value_deg: the offending joint value [deg], when known.
        sample: index of the path sample, when known.
    """

    def __init__(
        self,
        message: str,
        joint: str | None = None,
        value_deg: float | None = None,
        sample: int | None = None,
    ) -> None:
        super().__init__(message)
        self.joint = joint
        self.value_deg = value_deg
        self.sample = sample
