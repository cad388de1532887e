"""The per-axis response (alight.sim.sea.response): a single wave's gain and phase, the sheet's figures,
time-domain statistics against the frequency domain, following seas, the long-wave limits."""

from __future__ import annotations

import math

import numpy as np
import pytest

from alight.sim.sea import DeckMotion, SeaConfig, load_vessel
from alight.sim.sea.response import AXES, resonance, response_coefficients, sinc, slope_factor
from alight.sim.sea.vessel import Vessel
from alight.sim.sea.waves import WaveComponents
from alight.types import GRAVITY_MPS2


def _sheet_vessel(name: str) -> Vessel:
    # the reference sheet's placeholder rows (sec. 3.2), to compare with its printed figures
    rows = {
        "patrol_boat": (20.0, 5.5, 1.2, 3.0, 4.5, 3.0, 0.25, 0.12, 0.25),
        "frigate": (130.0, 15.0, 4.5, 5.5, 10.0, 5.5, 0.30, 0.08, 0.30),
    }
    L, B, d, th, tr, tp, zh, zr, zp = rows[name]
    return Vessel(
        name=name, length_m=L, beam_m=B, draft_m=d, heave_period_s=th, roll_period_s=tr, pitch_period_s=tp,
        heave_damping=zh, roll_damping=zr, pitch_damping=zp, yaw_fraction=0.0, pad_offset_m=(0.0, 0.0, 0.0),
    )  # fmt: skip


def _fit(t: np.ndarray, x: np.ndarray, w: float) -> complex:
    # least-squares complex amplitude c of x = Re{c e^{j w t}}
    basis = np.stack([np.cos(w * t), -np.sin(w * t)], axis=1)
    re, im = np.linalg.lstsq(basis, x, rcond=None)[0]
    return complex(re, im)


@pytest.mark.parametrize(
    ("vessel", "period", "mu_deg", "speed", "axis", "gain_sheet"),
    [
        ("patrol_boat", 4.5, 90, 0.0, "heave", 1.1564),
        ("patrol_boat", 4.5, 90, 0.0, "roll", 36.2728),
        ("frigate", 10.0, 90, 0.0, "heave", 1.0650),
        ("frigate", 10.0, 90, 0.0, "roll", 11.9147),
        ("frigate", 8.0, 180, 0.0, "heave", 0.2233),
        ("frigate", 8.0, 180, 0.0, "pitch", 0.2817),
        ("frigate", 8.0, 180, 10.0, "heave", 0.1636),
        ("frigate", 8.0, 180, 10.0, "pitch", 0.2064),
    ],
)
def test_single_wave_reproduces_gain_and_phase_and_the_sheets_figures(
    vessel, period, mu_deg, speed, axis, gain_sheet
):
    w0, eps = 2 * math.pi / period, 0.3
    waves = WaveComponents(np.array([w0]), np.array([1.0]), np.array([eps]))
    v = _sheet_vessel(vessel)
    mu = math.radians(mu_deg)
    deck = DeckMotion(waves, v, speed, mu, (0.0, 0.0, 0.0))
    w_e = deck.w_e[0]
    assert w_e == pytest.approx(w0 - w0**2 / GRAVITY_MPS2 * speed * math.cos(mu), rel=1e-14)
    t = np.arange(0.0, 600.0, 0.05)
    c = _fit(t, deck.axis(axis, t), w_e)
    # the transfer function written out independently of response_coefficients
    k = w0**2 / GRAVITY_MPS2
    kx, ky = k * math.cos(mu), k * math.sin(mu)
    f_l, f_b = np.sinc(kx * v.length_m / 2 / math.pi), np.sinc(ky * v.beam_m / 2 / math.pi)
    wn = 2 * math.pi / getattr(v, f"{axis}_period_s")
    z = getattr(v, f"{axis}_damping")
    h = wn**2 / (wn**2 - w_e**2 + 2j * z * wn * w_e) * math.exp(-k * v.draft_m)
    if axis == "heave":
        x = f_l * f_b
    elif axis == "roll":
        u = ky * v.beam_m / 2
        x = -1j * ky * 3 * (math.sin(u) - u * math.cos(u)) / u**3 * f_l
    else:
        u = kx * v.length_m / 2
        x = 1j * kx * 3 * (math.sin(u) - u * math.cos(u)) / u**3 * f_b
    expected = x * h * math.e ** (1j * eps)
    assert abs(c) == pytest.approx(abs(expected), rel=1e-9)
    assert np.angle(c / expected) == pytest.approx(0.0, abs=1e-9)
    scale = 1.0 if axis == "heave" else math.degrees(1.0)
    assert abs(c) * scale == pytest.approx(gain_sheet, abs=1e-4)  # the sheet's printed gain (m/m, deg/m)


def test_time_domain_amplitudes_match_the_frequency_domain():
    # the sheet's check 2: 2 std of each axis over 3 h equals 2 sqrt(sum |C|^2 / 2)
    cfg = SeaConfig(sea_state=5, vessel="patrol_boat", wave_direction_deg=135.0)
    deck = DeckMotion.from_config(cfg, np.random.default_rng(7), 5.0)
    q, qd, _ = deck.axes(np.arange(0.0, 3 * 3600.0, 0.25))
    for j, name in enumerate(AXES):
        pred = 2 * math.sqrt(np.sum(np.abs(deck.coefficients[j]) ** 2) / 2)
        assert 2 * q[:, j].std() == pytest.approx(pred, rel=0.03), name
        pred_rate = 2 * math.sqrt(np.sum(np.abs(deck.coefficients[j] * deck.w_e) ** 2) / 2)
        assert 2 * qd[:, j].std() == pytest.approx(pred_rate, rel=0.03), name


def test_following_seas_keep_the_sign_of_the_encounter_frequency():
    # a wave the vessel overtakes (w_e < 0) is the same motion as |w_e| with the phase reversed, which
    # is what conj-symmetric transfer functions give: x(t) = Re{C e^{j w_e t}} = Re{conj(C) e^{j |w_e| t}}
    v = load_vessel("patrol_boat")
    u = 8.0
    w0 = 1.6 * GRAVITY_MPS2 / u  # shorter than the wave the vessel rides
    waves = WaveComponents(np.array([w0]), np.array([0.2]), np.array([1.1]))
    c, w_e = response_coefficients(waves, v, u, 0.0)
    assert w_e[0] < 0.0
    k = w0**2 / GRAVITY_MPS2
    excitation = waves.a[0] * np.exp(1j * waves.eps[0]) * sinc(np.array([k * v.length_m / 2]))[0]
    excitation *= math.exp(-k * v.draft_m)
    h_positive = resonance(np.array([abs(w_e[0])]), v.heave_period_s, v.heave_damping)[0]
    assert np.conj(c[2, 0]) == pytest.approx(np.conj(excitation) * h_positive, rel=1e-12)
    deck = DeckMotion(waves, v, u, 0.0)
    t = np.linspace(0.0, 30.0, 301)
    heave = deck.axis("heave", t)
    np.testing.assert_allclose(heave, np.real(np.conj(c[2, 0]) * np.exp(1j * abs(w_e[0]) * t)), atol=1e-15)
    # a wave met at w_e = 0 (the vessel rides it) gives a frozen, finite displacement
    ride = WaveComponents(np.array([GRAVITY_MPS2 / u]), np.array([0.2]), np.array([0.4]))
    deck = DeckMotion(ride, v, u, 0.0)
    x = deck.axis("heave", t)
    assert np.all(np.isfinite(x)) and np.ptp(x) < 1e-12 and np.all(deck.axis("heave", t, 1) == 0.0)


def test_long_waves_are_followed_and_short_ones_averaged_out():
    v = load_vessel("frigate")
    k = np.array([1e-5, 2 * math.pi / 5.0])  # a very long swell, a 5 m chop
    w = np.sqrt(GRAVITY_MPS2 * k)
    waves = WaveComponents(w, np.ones(2), np.zeros(2))
    beam, _ = response_coefficients(waves, v, 0.0, math.pi / 2)
    head, _ = response_coefficients(waves, v, 0.0, math.pi)
    assert abs(beam[2, 0]) == pytest.approx(1.0, rel=1e-4)  # heave follows the surface
    assert abs(beam[3, 0]) == pytest.approx(k[0], rel=1e-3)  # roll follows the slope
    assert abs(head[4, 0]) == pytest.approx(k[0], rel=1e-3)  # pitch follows the slope
    assert abs(beam[1, 0]) == pytest.approx(1.0, rel=1e-6) and abs(head[0, 0]) == pytest.approx(1.0, rel=1e-6)
    assert abs(head[2, 1]) < 0.01 and abs(head[4, 1]) < 1e-3  # a 142 m hull ignores 5 m waves
    # beam and head seas make no yaw; quartering seas do
    assert abs(beam[5, 0]) < 1e-12 and abs(head[5, 0]) < 1e-12
    quartering, _ = response_coefficients(waves, v, 0.0, math.radians(45))
    assert abs(quartering[5, 0]) == pytest.approx(v.yaw_fraction * k[0] / 2, rel=1e-3)


def test_helper_functions_at_zero_and_against_series():
    u = np.array([0.0, 1e-6, 1e-3, 0.5, 3.0])
    s3 = slope_factor(u)
    assert s3[0] == 1.0 and s3[1] == pytest.approx(1.0, abs=1e-12)
    np.testing.assert_allclose(s3[2:], 3 * (np.sin(u[2:]) - u[2:] * np.cos(u[2:])) / u[2:] ** 3, rtol=1e-6)
    assert sinc(np.array([0.0]))[0] == 1.0
    assert resonance(np.array([0.0]), 5.0, 0.2)[0] == pytest.approx(1.0, abs=1e-15)
    wn = 2 * math.pi / 5.0
    assert abs(resonance(np.array([wn]), 5.0, 0.2)[0]) == pytest.approx(1 / (2 * 0.2), rel=1e-12)
