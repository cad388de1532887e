"""Wind: paper 004 eq. (3), the gust model of Sec. IV-C as written, steady wind drag."""

from __future__ import annotations

import math

import numpy as np
import pytest

from alight.sim.wind import GustWind, NoWind, SteadyWind, force_from_wind_speed

HIGH = np.array([0.0, 0.0, 20.0])
Z3 = np.zeros(3)


def test_eq3_reproduces_the_papers_forces():
    # the paper prints 3.45 N and 7.76 N for 8 and 12 m/s (A = 0.09 m^2, rho = 1.2 kg/m^3)
    assert force_from_wind_speed(8.0) == pytest.approx(3.45, abs=0.02)
    assert force_from_wind_speed(12.0) == pytest.approx(7.76, abs=0.02)
    assert force_from_wind_speed(8.0) == pytest.approx(0.5 * 1.2 * 64 * 0.09, rel=1e-15)
    assert force_from_wind_speed(10.0, area_m2=0.2, rho=1.0) == pytest.approx(10.0)


def test_gust_constant_within_a_cycle_and_changing_across_cycles():
    g = GustWind(np.random.default_rng(5))
    per_cycle = []
    for k in range(20):
        ts = k * 5.5 + np.array([0.0, 1.0, 2.7, 5.499])
        forces = np.array([g.force_W(t, HIGH, Z3) for t in ts])
        np.testing.assert_array_equal(forces, np.tile(forces[0], (4, 1)))
        per_cycle.append(forces[0])
    per_cycle = np.array(per_cycle)
    assert len(np.unique(per_cycle[:, 0])) == 20
    assert not np.array_equal(g.force_W(5.499, HIGH, Z3), g.force_W(5.5, HIGH, Z3))


def test_gust_direction_magnitude_and_noise_bounds():
    g = GustWind(np.random.default_rng(1), power_init_N=7.0)
    f = np.array([g.force_W(5.5 * k + 0.1, HIGH, Z3) for k in range(3000)])
    # direction (0.8, 0.2) as written (not normalised), pushing towards -x, -y, horizontal
    np.testing.assert_allclose(f[:, 0], 4.0 * f[:, 1])
    assert np.all(f[:, 0] < 0) and np.all(f[:, 2] == 0.0)
    noise = -f[:, 0] / (0.8 * 7.0)
    assert noise.min() >= 0.9 and noise.max() < 1.2
    assert noise.min() < 0.905 and noise.max() > 1.195
    # uniform: mean 1.05, std 0.3 / sqrt(12)
    assert noise.mean() == pytest.approx(1.05, abs=4 * 0.0866 / math.sqrt(3000))
    assert noise.std() == pytest.approx(0.3 / math.sqrt(12), rel=0.05)


def test_gust_altitude_scaling_as_written():
    g = GustWind(np.random.default_rng(2), power_init_N=7.0)
    t = 12.0
    n = g.noise(2)

    def power(z):
        return -g.force_W(t, np.array([0.0, 0.0, z]), Z3)[0] / (0.8 * n)

    assert power(10.0) == pytest.approx(7.0)
    assert power(6.0) == pytest.approx(7.0)
    assert power(4.5) == pytest.approx(7.0 * 4.5 / 6.0)
    assert power(3.0 + 1e-9) == pytest.approx(3.5)
    assert power(3.0) == pytest.approx(0.5)  # the discontinuity at 3 m, as the paper states it
    assert power(0.5) == pytest.approx(0.5)
    np.testing.assert_array_equal(g.air_velocity_W(t), Z3)


def test_gust_is_deterministic_and_independent_of_query_order():
    times = [0.0, 30.0, 500.0, 6.0, 1000.0, 2.0]
    a = GustWind(np.random.default_rng(9))
    b = GustWind(np.random.default_rng(9))
    fa = [a.force_W(t, HIGH, Z3) for t in times]
    fb = [b.force_W(t, HIGH, Z3) for t in sorted(times)]
    order = np.argsort(times)
    np.testing.assert_array_equal(np.array(fa)[order], np.array(fb))
    c = GustWind(np.random.default_rng(10))
    assert not np.array_equal(c.force_W(0.0, HIGH, Z3), fa[0])


def test_gust_from_wind_speed():
    g = GustWind.from_wind_speed(np.random.default_rng(0), 12.0)
    assert g.power_init_N == pytest.approx(7.776)


def test_steady_wind_drag_follows_relative_air_velocity():
    w = SteadyWind(np.array([5.0, 0.0, 0.0]))
    f = w.force_W(0.0, HIGH, Z3)
    np.testing.assert_allclose(f, [0.5 * 1.2 * 25 * 0.09, 0.0, 0.0])
    np.testing.assert_allclose(w.force_W(3.0, HIGH, np.array([5.0, 0.0, 0.0])), 0.0)
    # flying at 3 m/s along +y into the 5 m/s wind along +x: |v_rel| = sqrt(34), along (5, -3)
    f = w.force_W(0.0, HIGH, np.array([0.0, 3.0, 0.0]))
    np.testing.assert_allclose(f, 0.5 * 1.2 * 0.09 * math.sqrt(34) * np.array([5.0, -3.0, 0.0]))
    np.testing.assert_array_equal(w.air_velocity_W(1.0), [5.0, 0.0, 0.0])
    np.testing.assert_array_equal(NoWind().force_W(0.0, HIGH, Z3), Z3)
    with pytest.raises(ValueError):
        SteadyWind(np.array([1.0, 2.0]))
