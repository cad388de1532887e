"""The turn-rate tracker and the prediction along a turn (alight.estimation.turn_rate), and what they
change in the two constant-velocity estimators' predictions on a circle."""

from __future__ import annotations

import math

import numpy as np
import pytest

from alight.estimation.platform_velocity import PlatformVelocityConfig
from alight.estimation.sdu_kf import SduKalmanFilter, SduKfConfig
from alight.estimation.turn_rate import TurnRateConfig, TurnRateTracker, turn_predict
from alight.sim.platform import Platform, PlatformConfig
from alight.types import PlatformMeasurement


def _circle(speed: float = 2.0, radius: float = 10.0, left: bool = True) -> Platform:
    return Platform(
        PlatformConfig(
            path="circle", speed_mps=speed, circle_radius_m=radius, turn_left=left, start_heading=0.7
        )
    )


@pytest.mark.parametrize("left", [True, False])
def test_turn_predict_is_the_circle_exactly(left: bool) -> None:
    plat = _circle(left=left)
    st = plat.states(np.array([3.0]))
    omega = (1.0 if left else -1.0) * 2.0 / 10.0
    taus = np.linspace(-1.0, 3.0, 9)
    p, v, a, yaw = turn_predict(st.p_WP[0], st.v_WP[0], omega, taus)
    truth = plat.states(3.0 + taus)
    np.testing.assert_allclose(p, truth.p_WP, atol=1e-9)
    np.testing.assert_allclose(v, truth.v_WP, atol=1e-9)
    np.testing.assert_allclose(a, truth.a_WP, atol=1e-9)
    np.testing.assert_allclose(np.cos(yaw - truth.yaw), 1.0, atol=1e-12)
    # zero rate: constant velocity
    p0, v0, a0, _ = turn_predict(st.p_WP[0], st.v_WP[0], 0.0, taus)
    np.testing.assert_allclose(p0, st.p_WP[0] + taus[:, None] * st.v_WP[0], atol=1e-12)
    assert np.all(a0 == 0.0) and np.allclose(v0, st.v_WP[0])


def test_tracker_finds_the_rate_of_a_circle_and_stays_near_zero_on_a_line() -> None:
    rng = np.random.default_rng(3)
    ts = np.arange(0.0, 12.0, 0.05)
    circle = _circle().states(ts)
    tr = TurnRateTracker()
    for t, v in zip(ts, circle.v_WP, strict=True):
        n = rng.normal(0.0, 0.05, 2)
        tr.update(float(t), float(v[0] + n[0]), float(v[1] + n[1]))
    assert tr.rate == pytest.approx(0.2, abs=0.02)
    line = Platform(PlatformConfig(path="straight", speed_mps=2.0, start_heading=-2.0)).states(ts)
    tr.reset()
    rates = []
    for t, v in zip(ts, line.v_WP, strict=True):
        n = rng.normal(0.0, 0.05, 2)
        tr.update(float(t), float(v[0] + n[0]), float(v[1] + n[1]))
        rates.append(tr.rate)
    assert np.abs(rates).max() < 0.05
    # slow, stale, out-of-order and non-finite inputs change nothing
    r = tr.rate
    tr.update(20.0, 0.1, 0.0)
    tr.update(5.0, 2.0, 0.0)
    tr.update(21.0, math.nan, 1.0)
    assert tr.rate == r
    with pytest.raises(ValueError):
        TurnRateConfig(baseline_s=0.0)


def _sdu_on_circle(turn_model: bool, seed: int) -> tuple[SduKalmanFilter, Platform]:
    plat = _circle()
    velocity = PlatformVelocityConfig(measured_yaw_increments=True, yaw_fold=4)  # as the preset
    kf = SduKalmanFilter(SduKfConfig(turn_model=turn_model, velocity=velocity))
    rng = np.random.default_rng(seed)
    ts = np.arange(0.0, 10.0, 0.05)
    st = plat.states(ts)
    for k, t in enumerate(ts):
        p = st.p_WP[k] + np.append(rng.normal(0.0, 0.03, 2), 0.0)
        yaw = float(np.mod(st.yaw[k] + rng.normal(0.0, 0.03), 0.5 * math.pi))
        kf.update(PlatformMeasurement(t=float(t), p_WP=p, cov_p_WP=np.eye(3) * 0.03**2, yaw=yaw))
    return kf, plat


def test_on_a_circle_the_prediction_follows_the_turn_where_constant_velocity_drifts_outward() -> None:
    """2 m/s on a 10 m circle, 3 s ahead (the far end of the tracking planner's horizon), six seeds:
    constant velocity misses by about (v tau)^2 / (2 R) = 1.8 m, outward; along the turn the miss is what
    the turn rate's noise leaves (0.1-0.8 m: 0.05 rad/s of rate error is 0.45 m at 3 s)."""
    ahead = 9.95 + np.array([3.0])
    for seed in range(6):
        errs = {}
        for turn in (True, False):
            kf, plat = _sdu_on_circle(turn, seed)
            p, _, a, _ = kf.predict_ahead(ahead)
            errs[turn] = float(np.linalg.norm(p[0, :2] - plat.states(ahead).p_WP[0, :2]))
            if turn:
                assert np.linalg.norm(a[0, :2]) == pytest.approx(2.0**2 / 10.0, rel=0.25)  # centripetal
        assert errs[False] > 1.2, errs
        assert errs[True] < 0.85 and errs[True] < 0.5 * errs[False], errs
