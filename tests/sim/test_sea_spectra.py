"""Sea states and spectra (alight.sim.sea.spectra): the table, the spectra's m0 = Hs^2/16, their peaks."""

from __future__ import annotations

import math

import numpy as np
import pytest

from alight.errors import ConfigError
from alight.sim.sea.spectra import (
    SEA_STATES,
    jonswap,
    pierson_moskowitz,
    sea_state_hs_tp,
    spectral_moment,
    spectrum,
)

W = np.linspace(0.005, 25.0, 400_001)


@pytest.mark.parametrize(("hs", "tp"), [(0.3, 2.0), (1.88, 8.8), (5.0, 12.4)])
def test_pierson_moskowitz_integrates_to_hs_squared_over_16(hs, tp):
    # over [0.05, 100] wp the tail left out is 1 - exp(-1.25e-8), nothing
    w = np.linspace(0.05, 100.0, 400_001) * 2 * math.pi / tp
    m0 = spectral_moment(w, pierson_moskowitz(w, hs, tp), 0)
    assert m0 == pytest.approx(hs**2 / 16.0, rel=1e-6)


@pytest.mark.parametrize("gamma", [1.0, 2.0, 3.3, 5.0])
def test_jonswap_keeps_m0_within_a_quarter_percent_over_the_usual_gammas(gamma):
    # the DNV normalisation 1 - 0.287 ln(gamma) is approximate: exact at gamma 1, within 0.25 % in m0
    # (0.12 % in Hs) for gamma 1-5, as the sheet's 4 sqrt(m0) = 1.882 for Hs 1.88 at gamma 3.3
    m0 = spectral_moment(W, jonswap(W, 2.0, 8.0, gamma), 0)
    assert m0 == pytest.approx(2.0**2 / 16.0, rel=2.5e-3)


def test_jonswap_with_gamma_one_is_pierson_moskowitz_and_peaks_at_wp():
    np.testing.assert_allclose(jonswap(W, 2.0, 8.0, 1.0), pierson_moskowitz(W, 2.0, 8.0), rtol=1e-14)
    wp = 2 * math.pi / 8.0
    for g in (1.0, 3.3, 7.0):
        s = jonswap(W, 2.0, 8.0, g)
        assert W[np.argmax(s)] == pytest.approx(wp, abs=2e-4)
    # the enhancement at the peak is gamma times the normalisation
    assert jonswap(np.array([wp]), 2.0, 8.0, 3.3)[0] / pierson_moskowitz(np.array([wp]), 2.0, 8.0)[0] == (
        pytest.approx(3.3 * (1 - 0.287 * math.log(3.3)), rel=1e-12)
    )


def test_spectra_are_zero_at_and_below_zero_frequency():
    assert np.all(pierson_moskowitz(np.array([0.0, -1.0]), 2.0, 8.0) == 0.0)
    assert np.all(np.isfinite(jonswap(np.array([0.0, 1e-3]), 2.0, 8.0)))


def test_sea_state_table_is_the_sheets_where_they_overlap():
    # reference sheet sec. 1: mean Hs and most probable Tp of the Bales table, SS 2-6
    sheet = {2: (0.3, 7.5), 3: (0.88, 7.5), 4: (1.88, 8.8), 5: (3.25, 9.7), 6: (5.0, 12.4)}
    for code, hs_tp in sheet.items():
        assert sea_state_hs_tp(code) == hs_tp
    assert set(SEA_STATES) == set(range(10))
    assert sea_state_hs_tp(0)[0] == 0.0
    assert sea_state_hs_tp(3, tp_s=3.0) == (0.88, 3.0)  # a lake's short period replaces the ocean's
    assert [SEA_STATES[c][0] for c in range(10)] == sorted(SEA_STATES[c][0] for c in range(10))


@pytest.mark.parametrize("code", [-1, 10, 2.5, True, "3"])
def test_unknown_sea_state_is_one_line(code):
    with pytest.raises(ConfigError, match="WMO code") as info:
        sea_state_hs_tp(code)
    assert "\n" not in str(info.value)


def test_sea_state_one_needs_a_period_and_unknown_spectrum_is_refused():
    with pytest.raises(ConfigError, match="give tp_s"):
        sea_state_hs_tp(1)
    assert sea_state_hs_tp(1, tp_s=1.0) == (0.05, 1.0)
    with pytest.raises(ConfigError, match="'pm' or 'jonswap'"):
        spectrum(W, 1.0, 5.0, "bretschneider", None)
