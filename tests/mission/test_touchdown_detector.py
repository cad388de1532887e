"""The onboard land detector: what stops the motors, and what must not (the range finder's blind zone,
a vehicle still sinking, thrust still high)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from alight.mission.touchdown_detector import TouchdownConfig, TouchdownDetector, TouchdownState

CFG = TouchdownConfig(hover_thrust_N=9.81)
G = np.array([0.0, 0.0, 9.81])
DT = 0.01


def _run(det, t0, seconds, *, vz=0.0, range_m=None, thrust=None, spool=True):
    """Feed the detector at 100 Hz; the thrust follows its spool-down unless given. Returns the last
    state and the thrust commanded at the end."""
    t, state, cmd = t0, det.state, 0.0
    for _ in range(round(seconds / DT)):
        t += DT
        base = CFG.hover_thrust_N if thrust is None else thrust
        cmd = base * (det.thrust_scale(t) if spool else 1.0)
        state = det.update(t, vz, range_m, cmd)
    return state, cmd


def test_impact_then_stillness_spools_down_and_lands():
    det = TouchdownDetector(CFG)
    det.on_imu(1.0, G + np.array([0.0, 0.0, 15.0]))  # the feet hit the deck
    state, _ = _run(det, 1.0, CFG.ground_contact_s + 0.02, range_m=math.inf)
    assert state is TouchdownState.GROUND_CONTACT
    assert det.thrust_scale(1.0 + CFG.ground_contact_s + 0.02 + CFG.spool_down_s) == 0.0
    state, cmd = _run(det, 1.2, 1.0, range_m=math.inf)
    assert state is TouchdownState.LANDED and det.t_landed is not None and det.reason == "impact"
    # landed is final
    assert det.update(5.0, -2.0, None, 20.0) is TouchdownState.LANDED and det.thrust_scale(5.0) == 0.0


def test_a_reading_in_the_blind_zone_at_hover_thrust_never_stops_the_motors():
    # hovering still 0.2 m above the pad with a 0.2 m blind zone: the sensor says "too close" (-inf),
    # which is no evidence of the floor; without an impact there is no contact at all
    det = TouchdownDetector(CFG)
    for spool in (False, True):
        state, _ = _run(det, 0.0, 5.0, range_m=-math.inf, spool=spool)
        assert state is TouchdownState.AIRBORNE
    # even after a jolt in the air (an impact without a surface), the spool-down makes a vehicle in the
    # air sink, which clears the contact before it lands
    det = TouchdownDetector(CFG)
    det.on_imu(0.0, G * 2.0)
    t = 0.0
    vz = 0.0
    for _ in range(500):
        t += DT
        thrust = CFG.hover_thrust_N * det.thrust_scale(t)
        vz += (thrust / 1.0 - 9.81) * DT  # a free 1 kg body under that thrust
        if det.update(t, vz, -math.inf, thrust) is TouchdownState.LANDED:
            break
        if det.state is TouchdownState.AIRBORNE:
            vz = 0.0  # the position loop catches it again
    assert det.state is not TouchdownState.LANDED


def test_range_at_the_floor_counts_as_contact_evidence():
    det = TouchdownDetector(CFG)
    state, _ = _run(det, 0.0, 1.5, range_m=0.02)
    assert state is TouchdownState.LANDED and det.reason == "range at floor"


def test_vertical_motion_or_no_evidence_keeps_it_airborne():
    det = TouchdownDetector(CFG)
    assert _run(det, 0.0, 2.0, vz=-0.4, range_m=0.02)[0] is TouchdownState.AIRBORNE  # still sinking
    det = TouchdownDetector(CFG)
    assert _run(det, 0.0, 2.0, range_m=1.0)[0] is TouchdownState.AIRBORNE  # no impact, range high
    det = TouchdownDetector(CFG)
    det.on_imu(0.0, G * 1.2)  # 2 m/s^2 off 1 g: manoeuvring, not an impact
    assert _run(det, 0.0, 2.0, range_m=None)[0] is TouchdownState.AIRBORNE


def test_a_jolt_with_the_range_finder_reading_height_is_not_a_contact():
    # a gust's jolt during kim_kaist's 0.1 m/s descent, 1.5 m above the pad
    det = TouchdownDetector(CFG)
    det.on_imu(0.0, G * 1.6)
    assert _run(det, 0.0, 0.9, vz=-0.1, range_m=1.5)[0] is TouchdownState.AIRBORNE


def test_an_old_impact_is_forgotten():
    det = TouchdownDetector(CFG)
    det.on_imu(0.0, G * 3.0)
    assert _run(det, CFG.impact_memory_s + 0.1, 2.0, range_m=None)[0] is TouchdownState.AIRBORNE


def test_low_thrust_without_sinking_is_a_contact():
    # a touchdown too soft for the accelerometer: the position loop commands 0.7 hover and nothing sinks
    det = TouchdownDetector(CFG)
    state, _ = _run(det, 0.0, 1.5, range_m=-math.inf, thrust=0.7 * CFG.hover_thrust_N)
    assert state is TouchdownState.LANDED and det.reason == "held up"


def test_a_thrust_that_does_not_fly_is_no_evidence_until_ground_contact():
    # an autopilot's position controller flies (the bridge's position setpoints): the pipeline's low
    # thrust command says nothing of a surface, and the vehicle stays airborne; an impact still makes a
    # ground contact, and from then on (its spool-down flies) the thrust counts again
    det = TouchdownDetector(CFG)
    det.thrust_flown = False
    state, _ = _run(det, 0.0, 1.5, range_m=-math.inf, thrust=0.7 * CFG.hover_thrust_N)
    assert state is TouchdownState.AIRBORNE and det.evidence["held"] is False
    det.on_imu(1.5, G * 2.0)  # the feet meet the deck
    state, _ = _run(det, 1.5, 1.5, range_m=-math.inf, thrust=0.7 * CFG.hover_thrust_N)
    assert state is TouchdownState.LANDED and det.evidence["held"] is True


def test_high_thrust_after_contact_does_not_land():
    det = TouchdownDetector(CFG)
    det.on_imu(0.0, G * 3.0)
    state, _ = _run(det, 0.0, 0.9, thrust=CFG.hover_thrust_N, spool=False)
    assert state is TouchdownState.GROUND_CONTACT


def test_losing_contact_restores_full_thrust_and_reset_starts_over():
    det = TouchdownDetector(CFG)
    _run(det, 0.0, 0.3, range_m=0.01)
    assert det.state is TouchdownState.GROUND_CONTACT and det.thrust_scale(0.5) < 1.0
    det.update(0.5, -0.5, 0.01, 5.0)
    assert det.state is TouchdownState.AIRBORNE and det.thrust_scale(0.5) == 1.0
    det.on_imu(0.6, G * 3)
    det.reset()
    assert det.t_impact == -math.inf and det.state is TouchdownState.AIRBORNE


@pytest.mark.parametrize("name", ["hover_thrust_N", "impact_mps2", "spool_down_s", "landed_s"])
def test_bad_config_raises(name):
    with pytest.raises(ValueError, match=name):
        TouchdownConfig(**{name: 0.0})
    with pytest.raises(ValueError, match="low_thrust_fraction"):
        TouchdownConfig(low_thrust_fraction=1.0)
    with pytest.raises(ValueError, match="held_thrust_fraction"):
        TouchdownConfig(held_thrust_fraction=1.0)


def test_level_rates_turn_the_body_upright_without_yaw():
    from scipy.spatial.transform import Rotation

    det = TouchdownDetector(CFG)
    for euler in ((0.2, 0.0, 1.0), (0.0, -0.3, -2.0), (0.1, 0.15, 0.5)):
        q = Rotation.from_euler("xyz", euler).as_quat()
        w = det.level_rates(q)
        assert w[2] == 0.0
        # a small step along w reduces the tilt
        R = Rotation.from_quat(q)
        after = R * Rotation.from_rotvec(w * 1e-3)
        assert after.as_matrix()[2, 2] > R.as_matrix()[2, 2]
    np.testing.assert_allclose(det.level_rates(np.array([0.0, 0.0, 0.3, 0.95393920141])), 0.0, atol=1e-12)
