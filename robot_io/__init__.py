"""cctmill I/O across the boundary: toolpath readers, KRL writer, KUKA protocols, signal sources.
Own plain data types; never imports ``planner``."""

__all__: list[str] = []
