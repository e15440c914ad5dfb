"""Floquet criterion vs the time-domain simulation and the averaged eigen model (docs/model.md §5, §6).

The agreement tables: cases found by a seeded random search with the physics core
(tests/_dynamics_cases.py), clear of the boundary on both sides; each row is checked for the
verdict and the vibration frequency.
"""

from __future__ import annotations

import _dynamics_cases as cases
import numpy as np
import pytest

from models import Cut, load_material, load_tool
from models.dynamics import Structure, modal_damping
from models.floquet import floquet, floquet_margin, path_floquet

MAT = load_material("al6061")
TOOL = load_tool("em25_2f")


@pytest.fixture(scope="module")
def low():
    return cases.candidates(40, [1000.0])


@pytest.fixture(scope="module")
def high():
    return cases.candidates(40, [4000.0, 6000.0, 8000.0], seed=cases.SEED + 1)


def _near_alias(f_sim, result, tol_hz):
    return np.min(np.abs(result.aliases_hz(f_sim + 50.0) - f_sim)) <= tol_hz


def test_averaging_caveat_at_1000_rpm(low):
    """docs/model.md §6: at 1000 rpm many averaged-stable cuts are Floquet-unstable; every averaged-unstable
    cut is Floquet-unstable too."""
    eig_stable = np.array([c.eigen_stable for c in low])
    fl_unstable = np.array([c.floquet_growth > 0 for c in low])
    assert np.all(fl_unstable[~eig_stable])
    assert fl_unstable[eig_stable].mean() > 0.3
    assert (~fl_unstable).sum() >= 3


def test_floquet_agrees_with_averaged_model_at_high_speed(high):
    agree = [(c.floquet_growth > 0) == (not c.eigen_stable) for c in high
             if abs(c.average_growth) > 1.0]
    assert len(agree) >= 20 and all(agree)


def test_simulation_agrees_with_floquet_at_1000_rpm(low):
    picked = cases.pick(low, "floquet", 4)
    grows = [c for c in picked if c.floquet_growth > 0]
    assert len(grows) >= 3 and len(picked) - len(grows) >= 3
    # among them, averaged-stable cuts that Floquet (rightly) calls unstable
    assert any(c.eigen_stable for c in grows)
    for case in picked:
        sim = cases.run(case)
        assert (sim.growth_rate > 0) == (case.floquet_growth > 0), case
        if case.floquet_growth < 0:
            robot, material, tool, params = cases._setup()
            st = cases.pose_structure(robot, params, case.q, case.cut, case.feed)
            res = floquet(st, case.cut, material, tool.helix_angle)
            assert _near_alias(sim.vibration_frequency_hz, res, 2.0), (sim.vibration_frequency_hz,
                                                                      res.frequency_hz)


def test_simulation_agrees_with_averaged_eigen_model_at_4000_rpm_and_above(high):
    picked = cases.pick(high, "eigen", 3)
    assert sum(not c.eigen_stable for c in picked) == 3 and sum(c.eigen_stable for c in picked) == 3
    for case in picked:
        assert case.rpm >= 4000
        sim = cases.run(case)
        assert (sim.growth_rate > 0) == (not case.eigen_stable), case
        if case.eigen_stable:  # the decay is the damped modes' (both modes mix in the fit)
            assert 0.5 * case.average_growth > sim.growth_rate > 2.0 * case.average_growth


def _structure():
    mass = np.array([[250.0, 6.0], [6.0, 160.0]])
    stiff = np.array([[5e5, -1.3e5], [-1.3e5, 1.4e6]])
    return Structure(mass, stiff, modal_damping(mass, stiff, 0.02), np.eye(3)[:, [0, 2]])


def _cut(rpm, a_p=2e-3):
    return Cut(np.array([0.0, 1.0, 0.0]), np.array([1.0, 0.0, 0.0]), 6e-3, a_p, "up",
               rpm * np.pi / 30, 2, TOOL.radius)


def test_monodromy_converges_with_steps():
    st = _structure()
    for rpm in (1000.0, 6000.0):
        coarse = floquet(st, _cut(rpm), MAT, TOOL.helix_angle, steps=128).spectral_radius
        fine = floquet(st, _cut(rpm), MAT, TOOL.helix_angle, steps=1024).spectral_radius
        default = floquet(st, _cut(rpm), MAT, TOOL.helix_angle).spectral_radius
        assert abs(default - fine) < 1e-4
        assert abs(coarse - fine) < 1e-3


def test_no_cut_gives_the_damped_structure():
    """With a vanishing depth of cut the multipliers are exp(λT) of the damped structure."""
    st = _structure()
    res = floquet(st, _cut(1000.0, a_p=1e-12), MAT, TOOL.helix_angle)
    lam = np.linalg.eigvals(st.state_matrix())
    expected = np.exp(lam * res.tooth_period)
    np.testing.assert_allclose(np.sort(np.abs(res.multipliers)), np.sort(np.abs(expected)),
                               rtol=1e-9)
    assert res.growth_rate == pytest.approx(lam.real.max(), rel=1e-6)


def test_floquet_margin_batch_matches_single():
    st = _structure()
    cuts = [_cut(1000.0), _cut(4000.0, 4e-3), _cut(8000.0, 1e-3)]
    rho, margin = floquet_margin([st] * 3, cuts, MAT, TOOL.helix_angle)
    singles = [floquet(st, c, MAT, TOOL.helix_angle).spectral_radius for c in cuts]
    np.testing.assert_allclose(rho, singles, rtol=1e-12)
    np.testing.assert_allclose(margin, 1 - rho)


def test_path_floquet_matches_the_per_point_structure():
    robot, material, tool, params = cases._setup()
    picked = cases.candidates(4, [1000.0, 4000.0], seed=11)
    q = np.array([c.q for c in picked])
    vecs = np.array([c.cut.vector() for c in picked])
    feeds = np.array([c.feed for c in picked])
    rho, margin = path_floquet(robot, params, q, vecs, feeds, tool.helix_angle)
    expected = [np.exp(c.floquet_growth * 2 * np.pi / (c.cut.flutes * c.cut.spindle_speed))
                for c in picked]
    np.testing.assert_allclose(rho, expected, rtol=1e-9)
    np.testing.assert_allclose(margin, 1 - rho)


def test_periodic_start_is_on_the_orbit_and_shows_the_floquet_rate(high):
    """``initial="periodic"``: a stable cut starts on its tooth-periodic motion (no entry
    transient, up to the integrator's own discretisation of it); a tiny perturbation then grows at
    the Floquet rate of an unstable cut."""
    from models.dynamics import pose_structure, simulate

    robot, material, tool, params = cases._setup()
    picked = cases.pick(high, "eigen", 3)
    stable = next(c for c in picked if c.eigen_stable)
    unstable = next(c for c in picked if not c.eigen_stable and c.rpm >= 8000)
    st = pose_structure(robot, params, stable.q, stable.cut, stable.feed)
    for regeneration in (False, True):
        runs = {init: simulate(st, stable.cut, stable.feed, material, tool.helix_angle,
                               duration=0.3, regeneration=regeneration, initial=init,
                               steps_per_tooth=256) for init in ("static", "periodic")}

        def drift(sim):
            step = int(round(sim.tooth_period * sim.fs))
            return np.abs(sim.displacement[step:] - sim.displacement[:-step]).max()

        assert drift(runs["periodic"]) < 0.1 * drift(runs["static"])
        assert runs["periodic"].dynamic_ratio < 5e-3
    st = pose_structure(robot, params, unstable.q, unstable.cut, unstable.feed)
    c = unstable.feed / (unstable.cut.flutes * unstable.rpm / 60)
    grow = simulate(st, unstable.cut, unstable.feed, material, tool.helix_angle, duration=1.0,
                    regeneration=False, initial="periodic", perturbation=1e-6 * c)
    assert grow.growth_rate == pytest.approx(unstable.floquet_growth, rel=0.15)
