"""Synthetic force and strain signals (models/signals.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from models import Cut, load_material, load_tool
from models.dynamics import Structure, modal_damping, simulate
from models.errors import InputError
from models.signals import CARBIDE_YOUNGS_MODULUS, bending_strain, synthetic_signals

MAT = load_material("al6061")
TOOL = load_tool("em25_2f")


@pytest.fixture(scope="module")
def sim():
    mass = np.array([[250.0, 6.0], [6.0, 160.0]])
    stiff = np.array([[5e5, -1.3e5], [-1.3e5, 1.4e6]])
    st = Structure(mass, stiff, modal_damping(mass, stiff, 0.02), np.eye(3)[:, [0, 2]])
    cut = Cut(np.array([0.0, 1.0, 0.0]), np.array([1.0, 0.0, 0.0]), 5e-3, 1e-3, "up",
              4000 * np.pi / 30, 2, TOOL.radius)
    return simulate(st, cut, 0.1e-3 * 2 * 4000 / 60, MAT, TOOL.helix_angle, duration=0.3)


def test_bending_strain_closed_form():
    f = np.array([[100.0, 50.0, 0.0], [0.0, 0.0, 100.0]])
    lever, d = 0.05, 0.02
    eps = bending_strain(f, lever, d, gauge_angle=0.0)
    expected = 100.0 * lever / (CARBIDE_YOUNGS_MODULUS * math.pi * d**3 / 32)
    np.testing.assert_allclose(eps, [expected, 0.0], atol=1e-18)
    eps90 = bending_strain(f, lever, d, gauge_angle=math.pi / 2)
    np.testing.assert_allclose(eps90, [0.0, expected], atol=1e-18)
    # the axial force does not bend the section
    assert bending_strain(np.array([[0.0, 1e3, 0.0]]), lever, d)[0] == 0.0


def test_signals_follow_the_simulation_and_the_noise_is_as_asked(sim):
    sig = synthetic_signals(sim, np.random.default_rng(3), force_noise=2.0)
    np.testing.assert_allclose(sig.force_clean, np.linalg.norm(sim.force, axis=1))
    assert sig.fs == sim.fs and sig.time.shape == sim.time.shape
    assert np.std(sig.force - sig.force_clean) == pytest.approx(2.0, rel=0.1)
    assert np.std(sig.strain - sig.strain_clean) == pytest.approx(sig.strain_noise, rel=0.1)
    # same signal-to-noise ratio by default: strain noise is the strain of 2 N
    assert sig.strain_noise == pytest.approx(
        bending_strain(np.array([[2.0, 0, 0]]), 0.05, 25.4e-3)[0], rel=1e-12)
    # strain is proportional to the radial force component
    ratio = sig.strain_clean / np.where(np.abs(sim.force[:, 0]) > 1.0, sim.force[:, 0], np.nan)
    ok = np.isfinite(ratio)
    assert ok.sum() > 100 and np.nanstd(ratio[ok]) < 1e-9 * np.nanmean(np.abs(ratio[ok]))


def test_signals_are_reproducible_with_the_seed(sim):
    a = synthetic_signals(sim, np.random.default_rng(5), force_noise=1.0)
    b = synthetic_signals(sim, np.random.default_rng(5), force_noise=1.0)
    np.testing.assert_array_equal(a.force, b.force)
    quiet = synthetic_signals(sim, np.random.default_rng(5), force_noise=0.0)
    np.testing.assert_array_equal(quiet.force, quiet.force_clean)


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"lever": 0.0}, "lever"), ({"diameter": -1.0}, "diameter"), ({"force_noise": -1.0}, "noise"),
])
def test_signals_reject_bad_parameters(sim, kwargs, match):
    with pytest.raises(InputError, match=match):
        synthetic_signals(sim, np.random.default_rng(0), **kwargs)
