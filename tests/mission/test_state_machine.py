"""The mission state machine: every transition of TRANSITIONS is taken by a test, and nothing else moves."""

from __future__ import annotations

import numpy as np
import pytest

from alight.mission.state_machine import TRANSITIONS, Mission, MissionConfig
from alight.types import EgoState, Mode, PlatformEstimate

CFG = MissionConfig(takeoff_altitude_m=4.0, track_height_m=2.5, time_budget_s=100.0, max_go_arounds=1)
PAD_Z = 0.5


def ego(p=(0.0, 0.0, 0.1), v=(0.0, 0.0, 0.0), t=0.0) -> EgoState:
    return EgoState(
        t=t, p_WB=np.array(p), v_WB=np.array(v), q_WB=np.array([0, 0, 0, 1.0]), w_WB_B=np.zeros(3)
    )


def target(t: float, p=(5.0, 0.0, PAD_Z), v=(1.0, 0.0, 0.0), age=0.0) -> PlatformEstimate:
    return PlatformEstimate(
        t=t,
        p_WP=np.array(p),
        v_WP=np.array(v),
        a_WP=np.zeros(3),
        yaw=0.0,
        cov_p_WP=np.eye(3) * 0.01,
        t_last_measurement=t - age,
    )


def started(t: float = 0.0) -> Mission:
    m = Mission(CFG)
    m.step(t, ego(), None, None)
    assert m.mode is Mode.TAKEOFF
    return m


def at_mode(mode: Mode) -> Mission:
    """A mission brought into ``mode`` through legal transitions."""
    m = started()
    hover = ego(p=(0, 0, 4.0))
    if mode is Mode.TAKEOFF:
        return m
    if mode is Mode.EXPLORE:
        m.step(1.0, hover, None, None)
        return m
    m.step(1.0, hover, target(1.0), None)
    assert m.mode is Mode.TRACK
    if mode is Mode.TRACK:
        return m
    above = ego(p=(5.0, 0.0, 3.0), v=(1.0, 0, 0))
    m.step(2.0, above, target(2.0), None)
    m.step(2.0 + CFG.land_dwell_s + 0.01, above, target(2.0 + CFG.land_dwell_s + 0.01), None)
    assert m.mode is Mode.LAND
    if mode is Mode.LAND:
        return m
    if mode is Mode.GO_AROUND:
        m.step(3.0, above, target(3.0, age=CFG.land_lost_timeout_s + 0.1), None)
        assert m.mode is Mode.GO_AROUND
        return m
    raise ValueError(mode)


def test_idle_to_takeoff_records_the_takeoff_point() -> None:
    m = Mission(CFG)
    assert m.mode is Mode.IDLE
    status = m.step(0.0, ego(p=(1.0, 2.0, 0.1)), None, None)
    assert status.mode is Mode.TAKEOFF and status.changed
    np.testing.assert_allclose(m.hover_point_W(), [1.0, 2.0, 4.1])


def test_takeoff_waits_for_the_hover_point() -> None:
    m = started()
    assert m.step(0.5, ego(p=(0, 0, 2.0)), None, None).mode is Mode.TAKEOFF  # not there yet
    assert m.step(0.6, ego(p=(0, 0, 4.1), v=(0, 0, 1.0)), None, None).mode is Mode.TAKEOFF  # too fast
    assert m.step(0.7, ego(p=(0, 0, 4.1)), None, None).mode is Mode.EXPLORE


def test_takeoff_goes_straight_to_track_when_target_seen() -> None:
    m = started()
    assert m.step(1.0, ego(p=(0, 0, 4.1)), target(1.0), None).mode is Mode.TRACK


def test_takeoff_tracks_a_target_seen_during_the_climb_once_above_the_tracking_height() -> None:
    m = started()
    below = ego(p=(0, 0, 0.1 + CFG.track_height_m - 0.1), v=(0, 0, 1.5))
    assert m.step(0.5, below, target(0.5), None).mode is Mode.TAKEOFF
    climbing = ego(p=(0, 0, 0.1 + CFG.track_height_m + 0.1), v=(0, 0, 1.5))
    assert m.step(0.6, climbing, target(0.6, age=CFG.lost_timeout_s + 0.1), None).mode is Mode.TAKEOFF
    status = m.step(0.7, climbing, target(0.7), None)
    assert status.mode is Mode.TRACK and status.reason == "target seen above the tracking height"


def test_explore_to_track_on_detection_only_when_fresh() -> None:
    m = at_mode(Mode.EXPLORE)
    assert m.step(2.0, ego(p=(0, 0, 8)), target(2.0, age=CFG.lost_timeout_s + 1), None).mode is Mode.EXPLORE
    assert m.step(2.1, ego(p=(0, 0, 8)), target(2.1), None).mode is Mode.TRACK


def test_track_to_land_needs_position_velocity_and_dwell() -> None:
    m = at_mode(Mode.TRACK)
    off = ego(p=(5.5, 0.0, 3.0), v=(1.0, 0, 0))
    slow = ego(p=(5.0, 0.0, 3.0), v=(0.0, 0, 0))
    good = ego(p=(5.0, 0.1, 3.0), v=(1.1, 0, 0))
    assert m.step(2.0, off, target(2.0), None).mode is Mode.TRACK
    assert m.step(2.1, slow, target(2.1), None).mode is Mode.TRACK
    assert m.step(2.2, good, target(2.2), None).mode is Mode.TRACK  # dwell starts
    assert m.step(2.2 + CFG.land_dwell_s / 2, good, target(2.3), None).mode is Mode.TRACK
    # a stale estimate interrupts the dwell
    assert m.step(2.4, good, target(2.4, age=CFG.max_estimate_age_s + 0.1), None).mode is Mode.TRACK
    assert m.step(2.5, good, target(2.5), None).mode is Mode.TRACK
    status = m.step(2.51 + CFG.land_dwell_s, good, target(2.51 + CFG.land_dwell_s), None)
    assert status.mode is Mode.LAND and status.reason == "above the platform with matched velocity"


def test_track_to_explore_when_lost() -> None:
    m = at_mode(Mode.TRACK)
    assert m.step(5.0, ego(p=(0, 0, 4)), target(5.0, age=CFG.lost_timeout_s + 0.1), None).mode is Mode.EXPLORE


def test_land_to_landed_on_range_cutoff() -> None:
    m = at_mode(Mode.LAND)
    low = ego(p=(5.0, 0.0, 0.7), v=(1.0, 0, -0.4))
    assert m.step(3.0, low, target(3.0), CFG.motor_cutoff_range_m + 0.05).mode is Mode.LAND
    assert m.step(3.1, low, target(3.1), None).mode is Mode.LAND  # no reading: keep descending
    assert m.step(3.2, low, target(3.2), CFG.motor_cutoff_range_m / 2).mode is Mode.LANDED
    # LANDED is final
    assert m.step(9.0, ego(p=(0, 0, 5)), None, None).mode is Mode.LANDED


def test_land_to_go_around_when_target_lost_or_off_pad() -> None:
    m = at_mode(Mode.LAND)
    high = ego(p=(5.0, 0, PAD_Z + CFG.land_commit_height_m + 0.5))
    assert m.step(3.0, high, target(3.0, age=CFG.land_lost_timeout_s + 0.1), None).mode is Mode.GO_AROUND
    # below the commit height a lost target does not stop the descent (the camera cannot see the pad)
    m = at_mode(Mode.LAND)
    low = ego(p=(5.0, 0, PAD_Z + CFG.land_commit_height_m - 0.2))
    assert m.step(3.0, low, target(3.0, age=CFG.land_lost_timeout_s + 0.1), None).mode is Mode.LAND
    m = at_mode(Mode.LAND)
    far = ego(p=(5.0 + CFG.land_abort_offset_m + 0.1, 0, PAD_Z + CFG.land_abort_min_height_m + 0.5))
    assert m.step(3.0, far, target(3.0), None).mode is Mode.GO_AROUND
    # close to the pad the descent commits even when off-centre
    m = at_mode(Mode.LAND)
    low_far = ego(p=(5.0 + CFG.land_abort_offset_m + 0.1, 0, PAD_Z + CFG.land_abort_min_height_m / 2))
    assert m.step(3.0, low_far, target(3.0), None).mode is Mode.LAND


def test_go_around_returns_to_track_at_height_and_aborts_after_too_many() -> None:
    m = at_mode(Mode.GO_AROUND)
    assert m.go_arounds == 1
    assert m.step(4.0, ego(p=(5, 0, PAD_Z + 1.0)), target(4.0), None).mode is Mode.GO_AROUND
    assert m.step(5.0, ego(p=(5, 0, PAD_Z + CFG.track_height_m)), target(5.0), None).mode is Mode.TRACK
    # a second go-around exceeds max_go_arounds = 1
    above = ego(p=(5.0, 0.0, 3.0), v=(1.0, 0, 0))
    m.step(6.0, above, target(6.0), None)
    m.step(6.0 + CFG.land_dwell_s + 0.01, above, target(6.0 + CFG.land_dwell_s + 0.01), None)
    assert m.mode is Mode.LAND
    m.step(7.0, above, target(7.0, age=5.0), None)
    assert m.mode is Mode.GO_AROUND and m.go_arounds == 2
    assert m.step(7.1, above, target(7.1), None).mode is Mode.ABORT
    assert m.step(50.0, above, target(50.0), None).mode is Mode.ABORT  # final


@pytest.mark.parametrize("mode", [Mode.EXPLORE, Mode.TRACK, Mode.LAND])
def test_time_budget_aborts(mode: Mode) -> None:
    m = at_mode(mode)
    late = CFG.time_budget_s + 1.0
    assert m.step(late, ego(p=(5.0, 0.0, 3.0), v=(1.0, 0, 0)), target(late), None).mode is Mode.ABORT


def test_every_listed_transition_is_reachable_and_only_those_happen() -> None:
    """Replays the scenarios above and checks that the transitions they took are exactly the table."""
    seen: set[tuple[Mode, Mode]] = set()
    for fn in (
        test_idle_to_takeoff_records_the_takeoff_point,
        test_takeoff_waits_for_the_hover_point,
        test_takeoff_goes_straight_to_track_when_target_seen,
        test_takeoff_tracks_a_target_seen_during_the_climb_once_above_the_tracking_height,
        test_explore_to_track_on_detection_only_when_fresh,
        test_track_to_land_needs_position_velocity_and_dwell,
        test_track_to_explore_when_lost,
        test_land_to_landed_on_range_cutoff,
        test_land_to_go_around_when_target_lost_or_off_pad,
        test_go_around_returns_to_track_at_height_and_aborts_after_too_many,
    ):
        original = Mission._go
        record: list[tuple[Mode, Mode]] = []

        def spy(self: Mission, t: float, mode: Mode, reason: str, _orig=original, _rec=record) -> None:
            _rec.append((self.mode, mode))
            _orig(self, t, mode, reason)

        Mission._go = spy  # type: ignore[method-assign]
        try:
            fn()
        finally:
            Mission._go = original  # type: ignore[method-assign]
        seen.update(record)
    for mode in (Mode.EXPLORE, Mode.TRACK, Mode.LAND):
        seen.add((mode, Mode.ABORT))  # covered by test_time_budget_aborts
    table = {(a, b) for a, b, _ in TRANSITIONS}
    assert seen == table


def test_bad_config_raises() -> None:
    with pytest.raises(ValueError, match="land_speed_mps"):
        MissionConfig(land_speed_mps=0.0)
    with pytest.raises(ValueError, match="max_go_arounds"):
        MissionConfig(max_go_arounds=-1)
