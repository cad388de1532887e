"""Random-sea synthesis and encounter frequency (alight.sim.sea.waves): Hs recovered, no repetition,
determinism by seed, the encounter-frequency cases of the reference sheet."""

from __future__ import annotations

import math

import numpy as np
import pytest

from alight.errors import ConfigError
from alight.sim.sea import DeckMotion, SeaConfig
from alight.sim.sea.spectra import jonswap
from alight.sim.sea.waves import WaveComponents, encounter_frequency, synthesise
from alight.types import GRAVITY_MPS2


@pytest.mark.parametrize(("hs", "tp", "gamma"), [(1.88, 8.8, 3.3), (3.25, 9.7, 3.3), (5.0, 12.4, 1.0)])
def test_four_sqrt_m0_of_a_long_record_recovers_hs_within_two_percent(hs, tp, gamma):
    t = np.arange(0.0, 3 * 3600.0, 0.25)  # 3 h at 4 Hz, as the sheet's check
    for seed in range(3):
        waves = synthesise(hs, tp, np.random.default_rng(seed), "jonswap", gamma)
        eta = waves.elevation(t)
        assert 4.0 * eta.std() == pytest.approx(hs, rel=0.02)
        assert 4.0 * math.sqrt(waves.m0) == pytest.approx(hs, rel=0.02)  # the band keeps >= 99.7 % of m0


def test_same_seed_same_sea_other_seed_other_sea():
    a = synthesise(2.0, 8.0, np.random.default_rng(42))
    b = synthesise(2.0, 8.0, np.random.default_rng(42))
    c = synthesise(2.0, 8.0, np.random.default_rng(43))
    for x, y in ((a.w, b.w), (a.a, b.a), (a.eps, b.eps)):
        np.testing.assert_array_equal(x, y)
    assert not np.array_equal(a.eps, c.eps) and not np.array_equal(a.w, c.w)


def _autocorrelation(x: np.ndarray, lags: np.ndarray) -> np.ndarray:
    x = x - x.mean()
    return np.array([np.dot(x[: x.size - k], x[k:]) / np.dot(x, x) * x.size / (x.size - k) for k in lags])


def test_no_periodic_repetition_within_ten_minutes():
    # heave-like record (the elevation at the centre of motion) over 40 min: at lags from 1 to 10 min
    # the autocorrelation stays far from 1; for a sea that repeated at T it would be ~1 at lag T
    dt = 0.25
    t = np.arange(0.0, 2400.0, dt)
    for hs, tp in ((0.88, 7.5), (3.25, 9.7)):
        waves = synthesise(hs, tp, np.random.default_rng(5))
        eta = waves.elevation(t)
        lags = np.arange(int(60 / dt), int(600 / dt) + 1)
        rho = _autocorrelation(eta, lags)
        assert np.max(rho) < 0.3, (hs, tp, np.max(rho), lags[np.argmax(rho)] * dt)
    # equal bins (the sheet's) with jittered frequencies: the envelope at the repeat lag 2 pi / dw of
    # the bin centres does not come back
    n = 100
    wp = 2 * math.pi / 8.0
    dw = 3.6 * wp / n
    t_rep = 2 * math.pi / dw
    t = np.arange(0.0, 600.0, 0.1)
    waves = synthesise(2.0, 8.0, np.random.default_rng(1), n=n, spacing="linear")
    assert np.diff(waves.w).min() > 0.0 and np.abs(np.diff(waves.w) - dw).max() > 0.5 * dw

    def envelope(tt: np.ndarray) -> np.ndarray:
        return np.abs(np.exp(1j * np.outer(tt, waves.w)) @ (waves.a * np.exp(1j * waves.eps)))

    assert abs(np.corrcoef(envelope(t), envelope(t + t_rep))[0, 1]) < 0.3


def test_deck_heave_does_not_repeat_within_ten_minutes():
    # the acceptance's check on the deck itself: the heave of each vessel class at sea states 3-5 in
    # head, bow-quartering and beam seas has no autocorrelation peak above 0.4 at lags of 1 to 10 min.
    # Measured on these seeds: 0.34 at most (frigate, SS3, head seas); with the sheet's equal bins 0.47
    # (frigate, SS3, bow-quartering: the few components in a long hull's pass band make the record
    # quasi-periodic), which this test refuses. Following seas near the waves' group speed are left out:
    # there the vessel rides a wave group and stays correlated for minutes, as at sea (docs/sea.md).
    dt = 0.5
    t = np.arange(0.0, 2400.0, dt)
    lags = np.arange(int(60 / dt), int(600 / dt) + 1)
    worst = 0.0
    for vessel, speed in (("small_usv", 2.0), ("patrol_boat", 5.0), ("frigate", 8.0)):
        for ss in (3, 4, 5):
            for mu in (180.0, 135.0, 90.0):
                cfg = SeaConfig(sea_state=ss, vessel=vessel, wave_direction_deg=mu)
                deck = DeckMotion.from_config(cfg, np.random.default_rng(ss * 1000 + int(mu)), speed)
                heave = deck.axis("heave", t)
                worst = max(worst, float(np.max(np.abs(_autocorrelation(heave, lags)))))
    assert worst < 0.4


def test_the_repetition_check_catches_equally_spaced_frequencies():
    # the failure the jitter prevents (sheet sec. 2.2): bin centres make the envelope repeat every
    # 2 pi / dw, harmonic frequencies the signal itself; the test above would see either
    n, tp = 100, 8.0
    wp = 2 * math.pi / tp
    edges = np.linspace(0.4 * wp, 4.0 * wp, n + 1)
    dw = edges[1] - edges[0]
    t_rep = 2 * math.pi / dw
    w = dw * np.arange(1, 4 * n)
    w = w[(w > 0.4 * wp) & (w < 4.0 * wp)]
    eps = np.random.default_rng(2).uniform(0, 2 * math.pi, w.size)
    harmonic = WaveComponents(w, np.sqrt(2 * jonswap(w, 2.0, tp) * dw), eps)
    t = np.arange(0.0, 300.0, 0.1)
    assert np.corrcoef(harmonic.elevation(t), harmonic.elevation(t + t_rep))[0, 1] > 0.999


def test_still_sea_has_no_components_and_bad_inputs_are_one_line():
    waves = synthesise(0.0, 8.0, np.random.default_rng(0))
    assert waves.w.size == 0 and np.all(waves.elevation(np.arange(5.0)) == 0.0)
    for hs, tp in ((-1.0, 8.0), (math.nan, 8.0), (1.0, 0.0), (1.0, math.inf)):
        with pytest.raises(ConfigError) as info:
            synthesise(hs, tp, np.random.default_rng(0))
        assert "\n" not in str(info.value)
    with pytest.raises(ConfigError, match="spacing"):
        synthesise(1.0, 8.0, np.random.default_rng(0), spacing="log")


def test_geometric_bins_have_equal_ratios_and_one_frequency_each():
    waves = synthesise(2.0, 8.0, np.random.default_rng(4), n=50)
    wp = 2 * math.pi / 8.0
    edges = np.geomspace(0.4 * wp, 4.0 * wp, 51)
    assert np.all((waves.w >= edges[:-1]) & (waves.w < edges[1:]))
    np.testing.assert_allclose(edges[1:] / edges[:-1], 10 ** (1 / 50), rtol=1e-12)


def test_encounter_frequency_cases():
    # the sheet's own check: w = 0.785 rad/s at U = 10 m/s in head seas -> 1.414 rad/s
    assert encounter_frequency(np.array([0.785]), 10.0, math.pi)[0] == pytest.approx(1.413, abs=1e-3)
    # boatdesign.net worked example: a 16 s swell at 10 kn in head seas -> 0.474 rad/s
    w16 = 2 * math.pi / 16.0
    assert encounter_frequency(np.array([w16]), 10 * 0.514444, math.pi)[0] == pytest.approx(0.474, abs=1e-3)
    w = np.array([0.3, 0.8, 1.5])
    np.testing.assert_allclose(encounter_frequency(w, 7.0, math.pi / 2), w, atol=1e-15)  # beam seas
    np.testing.assert_array_equal(encounter_frequency(w, 0.0, 1.0), w)  # at rest
    # following seas: the vessel rides the wave at w = g / U (w_e = 0) and overtakes shorter ones (< 0)
    u = 5.0
    w_ride = GRAVITY_MPS2 / u
    assert encounter_frequency(np.array([w_ride]), u, 0.0)[0] == pytest.approx(0.0, abs=1e-12)
    assert encounter_frequency(np.array([1.5 * w_ride]), u, 0.0)[0] < 0.0
    assert 0.0 < encounter_frequency(np.array([0.5 * w_ride]), u, 0.0)[0] < 0.5 * w_ride
    # the largest encounter frequency in following seas is g / (4 U) at w = g / (2 U)
    ws = np.linspace(0.01, 2 * w_ride, 10_001)
    assert encounter_frequency(ws, u, 0.0).max() == pytest.approx(GRAVITY_MPS2 / (4 * u), rel=1e-6)
