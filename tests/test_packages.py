"""The house's rules, checked: every package hands on what its ``__all__`` lists, importing a reader
loads no physics, and only ``planner/cli/`` speaks argparse."""

from __future__ import annotations

import importlib
import pkgutil
import subprocess
import sys
from pathlib import Path

import pytest

from models.errors import CctmillError

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("models", "planner", "robot_io")


def _isort(name: str) -> tuple[int, str]:
    """isort's order (ruff RUF022): CONSTANTS, then Classes, then functions."""
    return (0 if name.isupper() else 1 if name[:1].isupper() else 2, name)


def _modules() -> list[str]:
    out = []
    for top in PACKAGES:
        pkg = importlib.import_module(top)
        out.append(top)
        for info in pkgutil.walk_packages(pkg.__path__, prefix=f"{top}."):
            if ".data" not in info.name:
                out.append(info.name)
    return out


@pytest.mark.parametrize("name", _modules())
def test_every_module_has_a_sorted_all_that_resolves(name):
    mod = importlib.import_module(name)
    exported = getattr(mod, "__all__", None)
    assert isinstance(exported, list), f"{name} has no explicit __all__"
    if not name.rsplit(".", 1)[-1].startswith("_"):
        assert exported in (sorted(exported), sorted(exported, key=_isort)), \
            f"{name}.__all__ is not sorted"
    for attr in exported:
        assert getattr(mod, attr) is not None, f"{name}.{attr}"


@pytest.mark.parametrize("top", PACKAGES)
def test_every_error_is_in_the_tree_and_handed_on(top):
    """Each public exception class derives from CctmillError and its package's __all__ has it."""
    pkg = importlib.import_module(top)
    for name in _modules():
        if not name.startswith(top) or name.rsplit(".", 1)[-1].startswith("_"):
            continue
        mod = importlib.import_module(name)
        for attr in getattr(mod, "__all__", []):
            obj = getattr(mod, attr)
            if isinstance(obj, type) and issubclass(obj, BaseException):
                assert issubclass(obj, CctmillError), f"{name}.{attr} is outside the tree"
                assert attr in pkg.__all__, f"{top}.__all__ lacks {attr} (from {name})"


def test_importing_a_reader_loads_no_physics():
    code = "import sys, robot_io.gcode, robot_io.apt, robot_io.krl; " \
           "print(sorted(m for m in ('casadi', 'pinocchio') if m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         cwd=ROOT, timeout=120).stdout.strip()
    assert out == "[]"


def test_only_the_cli_imports_argparse():
    offenders = []
    for top in PACKAGES:
        for path in (ROOT / top).rglob("*.py"):
            rel = path.relative_to(ROOT).as_posix()
            if rel.startswith("planner/cli/"):
                continue
            text = path.read_text(encoding="utf-8")
            if ("import argparse" in text or "from planner.cli" in text
                    or "import planner.cli" in text):
                offenders.append(rel)
    assert offenders == []


def test_no_module_is_over_600_lines():
    long = [(p.relative_to(ROOT).as_posix(), n) for top in PACKAGES for p in (ROOT / top).rglob("*.py")
            if (n := len(p.read_text(encoding="utf-8").splitlines())) > 600]
    assert long == []
