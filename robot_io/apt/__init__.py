"""APT/CL cutter-location data (SolidWorks CAM/CAMWorks, Siemens NX): the reader and its options;
conventions and limits in :mod:`robot_io.apt.reader`. The underscored modules (``_records``, the
interpreter ``_interp`` and its record handlers ``_motion``, ``_spline``, ``_cycles``, ``_frames``,
``_modal``, ``_words``) are private to this package."""

from robot_io.apt.reader import AptOptions, AptReader, read_apt, read_apt_text

__all__ = ["AptOptions", "AptReader", "read_apt", "read_apt_text"]
