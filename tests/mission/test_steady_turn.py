"""The commit rule of a sustained turn (MissionConfig.land_steady_turn_s): the turn rate read from an
estimate against its closed form, and the rule against a circle that lasts, a U-turn that ends, a turn
whose rate wanders and a turn too hard to lean into."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from alight.mission.state_machine import Mission, MissionConfig, SteadyTurn, signed_turn_rate
from alight.types import EgoState, Mode, PlatformEstimate

PAD_Z = 0.5
STEP_S = 0.02  # the mission's 50 Hz
CFG = MissionConfig(
    takeoff_altitude_m=4.0,
    track_height_m=2.5,
    time_budget_s=1000.0,
    land_commit_max_platform_accel_mps2=1.5,
    land_steady_turn_s=5.0,
)


def turning(t: float, speed: float, rate: float, heading: float = 0.3) -> PlatformEstimate:
    """A unicycle at ``speed`` turning at ``rate``: v = speed (cos h, sin h), a = speed rate (-sin h,
    cos h)."""
    c, s = math.cos(heading), math.sin(heading)
    return PlatformEstimate(
        t=t,
        p_WP=np.array([5.0, 0.0, PAD_Z]),
        v_WP=np.array([speed * c, speed * s, 0.0]),
        a_WP=np.array([-speed * rate * s, speed * rate * c, 0.0]),
        yaw=heading,
        cov_p_WP=np.eye(3) * 0.01,
        t_last_measurement=t,
    )


def ego_over(t: float, target: PlatformEstimate, height: float) -> EgoState:
    p = target.p_WP + np.array([0.0, 0.0, height])
    return EgoState(t=t, p_WB=p, v_WB=target.v_WP.copy(), q_WB=np.array([0, 0, 0, 1.0]), w_WB_B=np.zeros(3))


@pytest.mark.parametrize("speed, rate", [(8.5, 8.5 / 30.0), (3.0, -0.75), (10.0, 0.0)])
def test_signed_turn_rate_is_the_unicycle_rate(speed: float, rate: float) -> None:
    for heading in (-2.0, 0.0, 1.0, 3.0):
        assert signed_turn_rate(turning(0.0, speed, rate, heading)) == pytest.approx(rate, abs=1e-12)
    assert signed_turn_rate(turning(0.0, 0.1, 0.5)) == 0.0  # at rest the heading says nothing


def _descend_on(
    rates: list[float], speed: float, cfg: MissionConfig = CFG, before: float | None = None
) -> Mission:
    """A mission in LAND held at the commit height while the estimate turns at ``rates`` (one per 50 Hz
    step, from t = 3 s), at ``before`` (default: the first of ``rates``) until then."""
    m = Mission(cfg)
    m.step(0.0, ego_over(0.0, turning(0.0, 0.0, 0.0), -0.4), None)
    t = 1.0
    w0 = rates[0] if before is None else before
    first = turning(t, speed, w0)
    m.step(t, ego_over(t, first, 3.5), first)  # seen above the tracking height: TRACK
    for k in range(50):  # matched for the dwell: LAND, and on at 50 Hz to t = 3 s
        t = 2.0 + k * STEP_S
        m.step(t, ego_over(t, turning(t, speed, w0), 2.0), turning(t, speed, w0))
    assert m.mode is Mode.LAND
    low = cfg.land_commit_height_m - 0.05
    for k, w in enumerate(rates):
        t = 3.0 + k * STEP_S
        est = turning(t, speed, w)
        m.step(t, ego_over(t, est, low), est)
        if m.committed or m.mode is not Mode.LAND:
            break
    return m


def test_a_circle_commits_once_it_has_turned_steadily_for_the_duration() -> None:
    # a 30 m circle at 8.5 m/s: 2.41 m/s^2, over the 1.5 limit; the estimate's rate jitters by +-0.03 rad/s
    w = 8.5 / 30.0
    rates = [w + 0.03 * (-1.0) ** (k // 7) for k in range(int(8.0 / STEP_S))]
    m = _descend_on(rates, 8.5)
    assert m.committed
    t_commit = m._committed_since
    assert t_commit is not None
    # steady since the estimate's stream began without a gap (t = 2 s, the same rate): 5 s later, and
    # committed at the step after the hold is released
    assert 2.0 + CFG.land_steady_turn_s <= t_commit <= 2.0 + CFG.land_steady_turn_s + 0.1
    # without the rule the same circle never commits, and goes around after land_tilt_wait_s
    off = dataclasses.replace(CFG, land_steady_turn_s=None)
    m = _descend_on(rates, 8.5, off)
    assert not m.committed and m.descent_hold


def test_a_u_turn_that_ends_waits_for_the_row() -> None:
    # a tractor's 4 m U-turn at 3 m/s: 0.75 rad/s for pi r / v = 4.19 s, then straight: never steady for
    # 5 s while hard; it commits on the straight after the turn
    n_turn = int(math.pi * 4.0 / 3.0 / STEP_S)
    rates = [0.75] * n_turn + [0.0] * 50
    m = _descend_on(rates, 3.0, before=0.0)
    assert m.committed
    assert m._committed_since is not None and m._committed_since > 3.0 + n_turn * STEP_S


def test_a_wandering_turn_rate_is_not_steady() -> None:
    # at 7 m/s the rate swings by +-0.13 rad/s around 0.35 with a 3 s period (1.5-3.4 m/s^2, always a hard
    # turn): the 1.7 s running mean lags, and the rate leaves its 0.08 band every half period
    rates = [0.35 + 0.13 * math.sin(2.0 * math.pi * k * STEP_S / 3.0) for k in range(int(12.0 / STEP_S))]
    m = _descend_on(rates, 7.0)
    assert not m.committed


def test_a_steady_turn_too_hard_to_lean_into_still_waits() -> None:
    # 10 m/s on a 25 m circle: 4 m/s^2, above land_steady_turn_max_accel_mps2 (3.5)
    m = _descend_on([0.4] * int(10.0 / STEP_S), 10.0)
    assert not m.committed and m.descent_hold


def test_steady_turn_tracker_restarts() -> None:
    tr = SteadyTurn()
    assert tr.steady_for(1.0) == 0.0
    for k in range(101):
        t = k * STEP_S
        tr.update(t, turning(t, 8.0, 0.25), 5.0, 0.08)
    assert tr.steady_for(2.0) == pytest.approx(2.0)
    assert tr.mean_rad_s == pytest.approx(0.25)
    tr.update(2.0 + STEP_S, turning(2.0, 8.0, -0.25), 5.0, 0.08)  # a figure-8's crossing
    assert tr.steady_for(2.0 + STEP_S) == 0.0
    tr.update(3.0, turning(3.0, 8.0, -0.25), 5.0, 0.08)  # a gap of 1 s: restart
    assert tr.steady_for(3.0) == 0.0
    tr.update(3.02, None, 5.0, 0.08)
    assert tr.steady_for(3.5) == 0.0
    with pytest.raises(ValueError, match="land_steady_turn_s"):
        MissionConfig(land_steady_turn_s=0.0)
