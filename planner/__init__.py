"""cctmill planning: point analyses and their reports, the command line; later path kinematics,
sections, optimisation, timing and the online supervisor's policy. Uses ``models`` and ``robot_io``."""

__all__: list[str] = []
