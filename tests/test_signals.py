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


def test_simulated_signals_tune_and_trip_the_wavelet_detector():
    """docs/model.md §6 (b), (c): σ of the stable-cut band from a simulated stable strain signal; a second
    record of the same cut stays under the chart's limit, a chattering cut (a depth past the
    boundary) trips it within 1.5 s. (σ belongs to its cut: a deeper stable cut has a larger band.)"""
    from models import ModelParameters, load_robot
    from models.dynamics import pose_structure
    from planner.supervisor.detector import Detector, select_level

    robot = load_robot()
    params = ModelParameters(joint_stiffness=robot.data.joint_stiffness,
                             coefficients=MAT.coefficients(), spindle_mass=robot.data.spindle_mass,
                             spindle_com=robot.data.spindle_com, tcp=np.array([0.32, 0.0, 0.0]))
    q = np.radians([-96.42, -29.26, 99.08, -9.95, 83.23, -160.5])
    rpm, fs = 4000.0, 5000.0
    feed = 0.1e-3 * 2 * rpm / 60

    def record(a_p, seed):
        cut = Cut(np.array([0.0, 1.0, 0.0]), np.array([1.0, 0.0, 0.0]), 6e-3, a_p, "up",
                  rpm * np.pi / 30, 2, TOOL.radius)
        st = pose_structure(robot, params, q, cut, feed)
        sim = simulate(st, cut, feed, MAT, TOOL.helix_angle, duration=2.5, fs=fs)
        return sim, st, synthetic_signals(sim, np.random.default_rng(seed), force_noise=0.3)

    sim_a, st, stable_a = record(0.3e-3, 1)
    sim_b, _, stable_b = record(0.3e-3, 2)  # the same cut, another noise record
    sim_c, _, chatter = record(1.5e-3, 3)
    assert sim_a.growth_rate < 0 and sim_b.growth_rate < 0 and sim_c.growth_rate > 0
    choice = select_level(fs, float(st.natural_frequencies_hz[0]), 1.0 / sim_a.tooth_period)
    learner = Detector(fs, choice)
    sigma = learner.learn(stable_a.strain)
    assert sigma > 0

    def first_alarm(sig):
        det = Detector(fs, choice, sigma=sigma)
        chunk = int(0.012 * fs)  # the KR C2's 12 ms cycle
        for i in range(0, sig.time.size - chunk + 1, chunk):
            out = det.update(sig.time[i:i + chunk], sig.strain[i:i + chunk])
            if out.alarm:
                return out.t_s
        return None

    assert first_alarm(stable_b) is None
    t_alarm = first_alarm(chatter)
    assert t_alarm is not None and t_alarm < 1.5
