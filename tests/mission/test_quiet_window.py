"""The quiet-window choice: synthetic deck trajectories with known answers, and a simulated sea."""

from __future__ import annotations

import math

import numpy as np
import pytest

from alight.errors import ConfigError, EstimationError
from alight.estimation.deck_estimator import DeckEstimator
from alight.mission.quiet_window import (
    QuietWindowConfig,
    check_commitment,
    feasible_contacts,
    find_quiet_window,
)
from alight.sim.sea import DeckMotion, SeaConfig
from alight.sim.sea.deck_sensors import deck_truth, simulate_deck_readings

DT = 0.001
PERIOD = 6.0
W = 2.0 * math.pi / PERIOD
AMP = math.radians(6.0)
# roll = 6 deg sin(w t) against a 3 deg limit: inside while |sin| <= 1/2, i.e. within (pi/6)/w = 0.5 s of
# every half period k * 3 s
CONFIG = QuietWindowConfig(max_tilt_rad=math.radians(3.0), settle_s=0.3, timing_tolerance_s=0.1)


def _sinusoid(phase: float = 0.0, t_end: float = 12.0):  # type: ignore[no-untyped-def]
    t = np.arange(0.0, t_end, DT)
    roll = AMP * np.sin(W * t + phase)
    return t, np.zeros_like(t), roll, np.zeros_like(t), np.zeros((t.shape[0], 6, 6))


def test_a_pure_sinusoid_gives_its_windows_at_the_known_phases() -> None:
    t, vz, roll, pitch, cov = _sinusoid()
    ok = feasible_contacts(t, vz, roll, pitch, cov, CONFIG)
    # contact at t needs [t - 0.1, t + 0.3] inside [3k - 0.5, 3k + 0.5]: t in [3k - 0.4, 3k + 0.2]
    for k in (1, 2, 3):
        inside = (t > 3 * k - 0.4 + 2 * DT) & (t < 3 * k + 0.2 - 2 * DT)
        assert ok[inside].all()
        near = (t > 3 * k - 1.0) & (t < 3 * k + 1.0)
        outside = near & ((t < 3 * k - 0.4 - 2 * DT) | (t > 3 * k + 0.2 + 2 * DT))
        assert not ok[outside].any()
    # descent of 2 s from t = 0: the first reachable window is k = 1, contact in its middle (2.9 s)
    win = find_quiet_window(t, vz, roll, pitch, cov, descent_s=2.0, t_now=0.0, config=CONFIG)
    assert win is not None
    assert win.t_open == pytest.approx(2.6, abs=2 * DT) and win.t_close == pytest.approx(3.2, abs=2 * DT)
    assert win.t_contact == pytest.approx(2.9, abs=2 * DT)
    assert win.t_start_descent == pytest.approx(0.9, abs=2 * DT)
    # a descent of 3 s misses the start of that window: its feasible part starts at 3 s
    win3 = find_quiet_window(t, vz, roll, pitch, cov, descent_s=3.0, t_now=0.0, config=CONFIG)
    assert win3 is not None and win3.t_open == pytest.approx(3.0, abs=2 * DT)


def test_the_deck_speed_limit_is_applied_to_the_closing_speed() -> None:
    # heave rate 0.8 cos(w t) with a 0.5 m/s sink: closing 0.5 + 0.8 cos <= 1.0 where cos <= 0.625
    t, _, _, pitch, cov = _sinusoid()
    vz = 0.8 * np.cos(W * t)
    ok = feasible_contacts(
        t, vz, np.zeros_like(t), pitch, cov, QuietWindowConfig(settle_s=0.0, timing_tolerance_s=0.0)
    )
    closing = 0.5 + vz
    expect = (closing <= 1.0) & (closing >= 0.1)
    interior = (t > 0.01) & (t < t[-1] - 0.01)
    assert (ok[interior] == expect[interior]).all()


def test_limits_never_met_give_no_window() -> None:
    t, vz, roll, pitch, cov = _sinusoid()
    assert find_quiet_window(t, vz, roll * 0.0 + math.radians(4.0), pitch, cov, 1.0, 0.0, CONFIG) is None
    assert find_quiet_window(t, vz + 0.7, roll * 0.0, pitch, cov, 1.0, 0.0, CONFIG) is None


def test_a_window_too_short_for_contact_is_refused() -> None:
    t, vz, roll, pitch, cov = _sinusoid()
    # the deck is inside the limits for 1.0 s at a time: a 1.2 s settle cannot fit
    long_settle = QuietWindowConfig(settle_s=1.2, timing_tolerance_s=0.0)
    assert find_quiet_window(t, vz, roll, pitch, cov, 1.0, 0.0, long_settle) is None
    # the feasible contacts span 0.6 s: a 0.7 s minimum window refuses them
    strict = QuietWindowConfig(settle_s=0.3, timing_tolerance_s=0.1, min_window_s=0.7)
    assert find_quiet_window(t, vz, roll, pitch, cov, 1.0, 0.0, strict) is None


def test_the_prediction_uncertainty_narrows_the_window() -> None:
    t, vz, roll, pitch, cov = _sinusoid()
    cov = cov.copy()
    cov[:, 2, 2] = math.radians(1.5) ** 2  # 1 sigma of 1.5 deg leaves 1.5 deg of the 3 deg limit
    win = find_quiet_window(t, vz, roll, pitch, cov, 2.0, 0.0, CONFIG)
    assert win is not None
    # |sin| <= 1/4 within asin(1/4)/w = 0.2413 s of 3 s: contacts in [3 - 0.1413, 3 - 0.0587]
    half = math.asin(0.25) / W
    assert win.t_open == pytest.approx(3.0 - half + 0.1, abs=2 * DT)
    assert win.t_close == pytest.approx(3.0 + half - 0.3, abs=2 * DT)


def test_a_window_that_closes_before_contact_sends_the_vehicle_around() -> None:
    t, vz, roll, pitch, cov = _sinusoid()
    win = find_quiet_window(t, vz, roll, pitch, cov, 2.0, 0.0, CONFIG)
    assert win is not None
    assert check_commitment(t, vz, roll, pitch, cov, win.t_contact, CONFIG)
    # a fresh prediction with the deck 0.4 s later in its cycle: the window has closed at contact
    t2, vz2, roll2, pitch2, cov2 = _sinusoid(phase=0.4 * W)
    assert not check_commitment(t2, vz2, roll2, pitch2, cov2, win.t_contact, CONFIG)
    # and a contact past the prediction's end is not held
    assert not check_commitment(t, vz, roll, pitch, cov, 100.0, CONFIG)


def test_bad_predictions_and_settings_are_refused_in_one_line() -> None:
    t, vz, roll, pitch, cov = _sinusoid(t_end=1.0)
    with pytest.raises(EstimationError):
        feasible_contacts(t, vz[:-1], roll, pitch, cov, CONFIG)
    with pytest.raises(EstimationError):
        feasible_contacts(t[::-1].copy(), vz, roll, pitch, cov, CONFIG)
    bad = roll.copy()
    bad[3] = math.nan
    with pytest.raises(EstimationError):
        feasible_contacts(t, vz, bad, pitch, cov, CONFIG)
    with pytest.raises(EstimationError):
        find_quiet_window(t, vz, roll, pitch, cov, math.nan, 0.0, CONFIG)
    with pytest.raises(ConfigError):
        QuietWindowConfig(max_tilt_rad=-1.0)
    with pytest.raises(ConfigError):
        QuietWindowConfig(min_closing_mps=2.0)


def test_windows_chosen_on_a_simulated_sea_hold_at_contact_against_the_truth() -> None:
    # patrol boat, sea state 3, bow-quartering seas, with the MRU: every 8 s after the first fit, the
    # window for a 3 s final descent is chosen from the estimator's 12 s prediction; the truth at the
    # planned contact is checked against the limits. Measured: 44 windows in 51 decisions, the truth
    # inside the limits at contact in 36 (82 %); the test asks for 75 %.
    speed = 5.0
    deck = DeckMotion.from_config(
        SeaConfig(sea_state=3, vessel="patrol_boat", wave_direction_deg=150.0),
        np.random.default_rng(21),
        speed_mps=speed,
    )
    readings = simulate_deck_readings(deck, 360.0, np.random.default_rng(22), speed_mps=speed)
    est = DeckEstimator()
    config = QuietWindowConfig()
    t_next, held, chosen = 60.0, 0, 0
    for r in readings:
        est.set_clock(r.t_arrival)
        if r.kind == "pose":
            est.update_pose(r.t_stamp, r.p_WP, r.cov_p_WP, r.attitude, r.cov_attitude)
        else:
            c = np.diag([r.cov_attitude[0, 0], r.cov_attitude[1, 1], r.heave_rate_var])
            est.update_mru(r.t_stamp, r.attitude, r.heave_rate, c)
        if r.t_arrival < t_next:
            continue
        t_next += 6.0
        pred = est.predict(r.t_arrival + np.arange(0.0, 12.0, 0.05))
        win = find_quiet_window(
            pred.t, pred.heave_rate, pred.roll, pred.pitch, pred.cov, 3.0, r.t_arrival, config
        )
        if win is None:
            continue
        chosen += 1
        s = deck_truth(deck, np.array([win.t_contact]), speed).state[0]
        tilt = math.acos(math.cos(s[2]) * math.cos(s[4]))
        closing = config.touchdown_sink_mps + s[1]
        held += tilt <= config.max_tilt_rad and config.min_closing_mps <= closing <= config.max_closing_mps
    assert chosen >= 30, chosen
    assert held >= 0.75 * chosen, (held, chosen)
