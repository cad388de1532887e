"""Dryden turbulence and the wind's direction and drag area (``alight.sim.wind``).

The generated sequences are checked against the MIL-F-8785C shaping filters themselves: the Welch PSD
of a long sequence against ``|H(j omega)|^2`` from ``dryden_transfer_function`` (scipy.signal.freqs),
the sample variance against sigma^2 with its standard error, and the exact stationary variance of the
discrete recursion (discrete Lyapunov equation) against 1. Numbers from
``/work/shared/references/dryden_turbulence.md``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import linalg, signal

from alight.airframes import load_airframe
from alight.scenario import scenario_from_dict
from alight.sim.wind import (
    TURBULENCE_W20_MPS,
    DrydenTurbulence,
    DrydenWind,
    SteadyWind,
    WindDirection,
    _zoh_step,
    dryden_low_altitude,
    dryden_transfer_function,
)
from alight.sim.world import make_wind

DT = 0.01


def test_low_altitude_law_matches_the_reference_table() -> None:
    su, sv, sw, lu, lv, lw = dryden_low_altitude(10.0, TURBULENCE_W20_MPS["moderate"])
    assert (su, lu) == (sv, lv) and lw == 10.0
    assert lu == pytest.approx(67.37, abs=0.01)
    assert sw == pytest.approx(1.543, abs=1e-3) and su == pytest.approx(2.915, abs=1e-3)
    assert dryden_low_altitude(50.0, 1.0)[3] == pytest.approx(202.29, abs=0.01)
    # clamped at 10 ft below, isotropic at 1000 ft
    assert dryden_low_altitude(0.0, 1.0) == dryden_low_altitude(3.05, 1.0)
    s = dryden_low_altitude(304.8, 1.0)
    assert s[0] == pytest.approx(s[2], rel=1e-3) and s[3] == pytest.approx(s[5], rel=1e-3)


@pytest.mark.parametrize("tc", [0.15, 1.15, 6.7])
def test_discrete_recursion_has_unit_stationary_variance(tc: float) -> None:
    # The (a, b) recursion is linear: read its matrices off _zoh_step, then solve P = F P F^T + G G^T.
    col_a = _zoh_step(1.0, 0.0, DT, tc, 0.0)
    col_b = _zoh_step(0.0, 1.0, DT, tc, 0.0)
    g = _zoh_step(0.0, 0.0, DT, tc, math.sqrt(math.pi / DT))  # one unit-normal draw scaled as in step()
    F = np.array([col_a, col_b]).T
    G = np.array(g).reshape(2, 1)
    P = linalg.solve_discrete_lyapunov(F, G @ G.T)
    c = np.array([math.sqrt(3.0), 1.0 - math.sqrt(3.0)])
    # the zero-order hold of the noise loses O((dt/T)^2) of the variance: 2e-5 at T = 1 s, dt = 10 ms
    assert float(c @ P @ c) == pytest.approx(1.0, abs=0.5 * (DT / tc) ** 2)
    # ... and the covariance the filters start from is that of the continuous filter, for every T
    np.testing.assert_allclose(P, [[0.5, 0.25], [0.25, 0.25]], atol=2.0 * DT / tc)


def _sequence(seed: int, n: int, height_m: float, airspeed_mps: float, w20: float) -> np.ndarray:
    """Turbulence (u, v, w) in m/s from DrydenWind hovering in a mean wind of ``airspeed_mps`` along x."""
    wind = DrydenWind(np.random.default_rng(seed), [airspeed_mps, 0.0, 0.0], w20, dt=DT)
    p = np.array([0.0, 0.0, height_m])
    v = np.zeros(3)
    out = np.empty((n, 3))
    for k in range(n):
        wind.force_W((k + 1) * DT, p, v)
        out[k] = wind.air_velocity_W((k + 1) * DT)
    out[:, 0] -= airspeed_mps
    return out


@pytest.fixture(scope="module")
def long_run() -> tuple[np.ndarray, tuple[float, ...]]:
    # Low and fast, so that the correlation times (L/V: 1.15 s for u and v, 0.15 s for w) are short
    # against the 2000 s run and one run pins the statistics.
    h, airspeed, w20 = 3.05, 20.0, TURBULENCE_W20_MPS["moderate"]
    return _sequence(8785, 200_000, h, airspeed, w20), (h, airspeed, w20)


def test_variance_is_sigma_squared(long_run) -> None:  # type: ignore[no-untyped-def]
    x, (h, airspeed, w20) = long_run
    su, sv, sw, lu, lv, lw = dryden_low_altitude(h, w20)
    t_run = x.shape[0] * DT
    for k, (sigma, length, c) in enumerate([(su, lu, 1.0), (sv, lv, 0.625), (sw, lw, 0.625)]):
        se = math.sqrt(2.0 * c * length / (airspeed * t_run))  # relative SE of the sample variance
        assert np.var(x[:, k]) / sigma**2 == pytest.approx(1.0, abs=4.0 * se), k
    assert abs(float(np.mean(x[:, 0]))) < 4.0 * su * math.sqrt(2.0 * lu / (airspeed * t_run))


def test_psd_follows_the_dryden_transfer_functions(long_run) -> None:  # type: ignore[no-untyped-def]
    x, (h, airspeed, w20) = long_run
    su, sv, sw, lu, lv, lw = dryden_low_altitude(h, w20)
    f, pxx = signal.welch(x, fs=1.0 / DT, nperseg=2**12, axis=0)
    edges = np.geomspace(0.1, 2.0, 7)  # below 0.02/dt: aliasing stays under 1 %
    for k, (comp, sigma, length) in enumerate([("u", su, lu), ("v", sv, lv), ("w", sw, lw)]):
        num, den = dryden_transfer_function(comp, sigma, length, airspeed)
        _, resp = signal.freqs(num, den, worN=2.0 * math.pi * f)
        analytic = 2.0 * math.pi * np.abs(resp) ** 2  # per rad/s -> per Hz
        band = (f >= edges[0]) & (f < edges[-1])
        assert np.mean(pxx[band, k] / analytic[band]) == pytest.approx(1.0, abs=0.05), comp
        for lo, hi in zip(edges[:-1], edges[1:], strict=True):
            sel = (f >= lo) & (f < hi)
            assert np.mean(pxx[sel, k] / analytic[sel]) == pytest.approx(1.0, abs=0.25), (comp, lo)


def test_transfer_functions_integrate_to_sigma_squared() -> None:
    omega = np.geomspace(1e-5, 1e4, 400_001)
    for comp in "uvw":
        num, den = dryden_transfer_function(comp, 2.0, 30.0, 7.0)
        _, resp = signal.freqs(num, den, worN=omega)
        assert np.trapezoid(np.abs(resp) ** 2, omega) == pytest.approx(4.0, rel=1e-3), comp


def test_same_seed_same_turbulence_and_seeds_differ() -> None:
    a = _sequence(3, 500, 10.0, 12.0, TURBULENCE_W20_MPS["light"])
    b = _sequence(3, 500, 10.0, 12.0, TURBULENCE_W20_MPS["light"])
    c = _sequence(4, 500, 10.0, 12.0, TURBULENCE_W20_MPS["light"])
    np.testing.assert_array_equal(a, b)
    assert not np.allclose(a, c)


def test_grid_makes_the_sequence_independent_of_how_often_it_is_asked() -> None:
    # Queried every 10 ms or twice per grid point, the turbulence at the grid points is the same.
    w1 = DrydenWind(np.random.default_rng(5), [8.0, 0.0, 0.0], 10.0, dt=DT)
    w2 = DrydenWind(np.random.default_rng(5), [8.0, 0.0, 0.0], 10.0, dt=DT)
    p, v = np.array([0.0, 0.0, 6.0]), np.zeros(3)
    for k in range(1, 200):
        w2.force_W((k - 0.5) * DT, p, v)
        f1 = w1.force_W(k * DT, p, v)
        f2 = w2.force_W(k * DT, p, v)
        np.testing.assert_array_equal(f1, f2)


def test_stationary_start_for_any_airspeed() -> None:
    # The initial filter states are drawn from the stationary covariance, so the very first samples of
    # many seeds already have variance sigma^2 (no warm-up transient).
    first = np.array([DrydenTurbulence(np.random.default_rng(s)).output() for s in range(4000)])
    np.testing.assert_allclose(first.var(axis=0), 1.0, atol=0.1)


def test_direction_steps_and_drifts() -> None:
    d = WindDirection(0.0, [(10.0, math.pi / 2)])
    wind = SteadyWind(np.array([8.0, 0.0, 0.5]), direction=d)
    np.testing.assert_array_equal(wind.air_velocity_W(9.99), [8.0, 0.0, 0.5])
    np.testing.assert_allclose(wind.air_velocity_W(10.0), [0.0, 8.0, 0.5], atol=1e-12)
    drift = SteadyWind(np.array([5.0, 0.0, 0.0]), direction=WindDirection(0.01))
    np.testing.assert_allclose(drift.air_velocity_W(100.0), [5.0 * math.cos(1.0), 5.0 * math.sin(1.0), 0.0])
    # Dryden without turbulence is its mean wind, turned alike; with it, u lies along the turned wind
    calm = DrydenWind(np.random.default_rng(0), [8.0, 0.0, 0.0], 0.0, direction=d)
    calm.force_W(12.0, np.array([0.0, 0.0, 10.0]), np.zeros(3))
    np.testing.assert_allclose(calm.air_velocity_W(12.0), [0.0, 8.0, 0.0], atol=1e-12)
    # constant direction: the very array the steady model always had (bit-identical missions)
    assert SteadyWind(np.array([8.0, 0.0, 0.0]), direction=WindDirection()).direction is None


def test_turbulence_axes_follow_the_mean_wind() -> None:
    # Mean wind along +y: the along-wind (u) gusts are then in y and the cross-wind (v) ones in x.
    # At h = 3.05 m sigma_u = sigma_v, so compare the spectra instead: u is first order (less power
    # at high frequency than v, whose filter has a zero).
    w = DrydenWind(np.random.default_rng(2), [0.0, 15.0, 0.0], 15.0, dt=DT)
    p, v = np.array([0.0, 0.0, 3.05]), np.zeros(3)
    xs = np.empty((40_000, 3))
    for k in range(xs.shape[0]):
        w.force_W((k + 1) * DT, p, v)
        xs[k] = w.air_velocity_W((k + 1) * DT)
    f, pxx = signal.welch(xs, fs=1.0 / DT, nperseg=2**11, axis=0)
    high = (f > 1.0) & (f < 2.0)
    # far above the corners |H_v|^2 / |H_u|^2 -> 3/2 (swapped axes would give 2/3)
    assert np.mean(pxx[high, 0]) > 1.25 * np.mean(pxx[high, 1])  # x (cross, v) above y (along, u)


def test_drag_area_comes_from_the_airframe() -> None:
    heavy = load_airframe("matrice100")
    f450 = load_airframe("f450")
    rng = np.random.default_rng(0)
    p, v = np.array([0.0, 0.0, 5.0]), np.zeros(3)
    steady = scenario_from_dict({"wind": {"model": "steady", "velocity_mps": [12.0, 0.0, 0.0]}})
    f_heavy = make_wind(steady, rng, heavy).force_W(0.0, p, v)
    assert f_heavy[0] == pytest.approx(0.5 * 1.2 * heavy.body_drag_area_m2 * 144.0)
    # the F450's area is paper 004's 0.09 m^2: the same force as the steady model always gave
    np.testing.assert_array_equal(
        make_wind(steady, rng, f450).force_W(0.0, p, v),
        SteadyWind(np.array([12.0, 0.0, 0.0])).force_W(0.0, p, v),
    )
    dryden = scenario_from_dict(
        {"wind": {"model": "dryden", "velocity_mps": [12.0, 0.0, 0.0], "turbulence": "light"}}
    )
    wind = make_wind(dryden, rng, heavy)
    f = wind.force_W(0.0, p, v)
    rel = wind.air_velocity_W(0.0) - v
    np.testing.assert_allclose(f, 0.5 * 1.2 * heavy.body_drag_area_m2 * np.linalg.norm(rel) * rel)


@pytest.mark.parametrize(
    ("wind", "message"),
    [
        ({"model": "gust", "velocity_mps": [8.0, 0.0, 0.0]}, "wind model 'gust' does not use velocity_mps"),
        ({"model": "steady", "turbulence": "light"}, "wind model 'steady' does not use turbulence"),
        ({"model": "steady", "gust_power_N": 3.0}, "does not use gust_power_N"),
        ({"model": "dryden"}, "wind model 'dryden' needs turbulence"),
        ({"model": "dryden", "turbulence": "strong"}, "turbulence: Input should be"),
        ({"model": "steady", "direction_changes": [[-1.0, 0.5]]}, "greater than or equal to 0"),
    ],
)
def test_wind_keys_act_or_are_refused(wind: dict[str, object], message: str) -> None:
    from alight.errors import ConfigError

    with pytest.raises(ConfigError, match=message):
        scenario_from_dict({"wind": wind}, "s.yaml")


def test_wind_spec_survives_a_dump_and_reload() -> None:
    for wind in (
        {"model": "dryden", "turbulence": "severe", "direction_rate_rad_s": 0.01},
        {"model": "gust", "gust_power_N": 3.45},
        {"model": "none", "gust_power_N": 7.76},  # kept unused: campaigns sweep the model over it
    ):
        s = scenario_from_dict({"wind": wind})
        assert scenario_from_dict(s.model_dump(mode="json")) == s


def test_dryden_mission_is_deterministic_with_the_seed() -> None:
    from alight.evaluation.runner import run_mission

    def fly(seed: int) -> np.ndarray:
        s = scenario_from_dict(
            {
                "seed": seed,
                "duration_s": 6.0,
                "airframe": "matrice100",
                "wind": {
                    "model": "dryden",
                    "velocity_mps": [10.0, 0.0, 0.0],
                    "turbulence": "moderate",
                    "direction_changes": [[3.0, 0.5]],
                },
            }
        )
        log = run_mission(s).log
        assert log is not None
        return np.hstack([log["p_WB"], log["f_wind_W"]])

    a, b, c = fly(1), fly(1), fly(2)
    np.testing.assert_array_equal(a, b)
    assert not np.allclose(a, c)
    # the wind pushes: a 10 m/s mean on the matrice100's 0.04 m^2 is ~2.4 N, turbulence around it
    assert 0.5 < float(np.median(np.linalg.norm(a[:, 3:6], axis=1))) < 10.0
