"""The mission state machine: every transition of TRANSITIONS (from, to and event) is taken by a test,
nothing else moves, and every failsafe records its event."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import test_quiet_gate as quiet_gate  # the quiet-window gate's transitions (mission/quiet_window.py)

from alight.mission.state_machine import TRANSITIONS, Mission, MissionConfig
from alight.types import EgoState, Mode, PlatformEstimate

CFG = MissionConfig(
    takeoff_altitude_m=4.0, track_height_m=2.5, time_budget_s=100.0, max_go_arounds=1, max_target_losses=1
)
PAD_Z = 0.5


def ego(p=(0.0, 0.0, 0.1), v=(0.0, 0.0, 0.0), t=0.0) -> EgoState:
    return EgoState(
        t=t, p_WB=np.array(p), v_WB=np.array(v), q_WB=np.array([0, 0, 0, 1.0]), w_WB_B=np.zeros(3)
    )


def target(
    t: float, p=(5.0, 0.0, PAD_Z), v=(1.0, 0.0, 0.0), age=0.0, std=0.1, a=(0.0, 0.0, 0.0)
) -> PlatformEstimate:
    return PlatformEstimate(
        t=t,
        p_WP=np.array(p),
        v_WP=np.array(v),
        a_WP=np.array(a, dtype=float),
        yaw=0.0,
        cov_p_WP=np.eye(3) * std**2,
        t_last_measurement=t - age,
    )


def kinds(m: Mission) -> list[str]:
    return [e.kind for e in m.events]


def started(t: float = 0.0, cfg: MissionConfig = CFG) -> Mission:
    m = Mission(cfg)
    m.step(t, ego(), None, None)
    assert m.mode is Mode.TAKEOFF
    return m


def at_mode(mode: Mode, cfg: MissionConfig = CFG) -> Mission:
    """A mission brought into ``mode`` through legal transitions."""
    m = started(cfg=cfg)
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


def at_search() -> Mission:
    m = at_mode(Mode.TRACK)
    m.step(5.0, ego(p=(5, 0, 4)), target(5.0, age=CFG.lost_timeout_s + 0.1), None)
    assert m.mode is Mode.SEARCH
    return m


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
    # a hover point below the tracking height: tracking starts once the take-off is done
    m = started(cfg=MissionConfig(takeoff_altitude_m=2.0, track_height_m=2.5))
    assert m.step(1.0, ego(p=(0, 0, 1.5)), target(1.0), None).mode is Mode.TAKEOFF
    status = m.step(2.0, ego(p=(0, 0, 2.1)), target(2.0), None)
    assert status.mode is Mode.TRACK and status.reason == "hover reached, target already seen"


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


def test_track_coasts_on_the_prediction_then_searches_and_reacquires() -> None:
    m = at_mode(Mode.TRACK)
    e = ego(p=(5, 0, 4))
    # unseen, but within the coast time: still tracking (on the prediction), and the coast is recorded
    assert m.step(3.0, e, target(3.0, age=CFG.max_estimate_age_s + 0.1), None).mode is Mode.TRACK
    assert m.step(3.5, e, target(3.5, age=CFG.lost_timeout_s - 0.1), None).mode is Mode.TRACK
    assert kinds(m) == ["coast"]
    status = m.step(5.0, e, target(5.0, age=CFG.lost_timeout_s + 0.1), None)
    assert status.mode is Mode.SEARCH and status.reason == "target lost, coast ended"
    assert kinds(m) == ["coast", "search"] and m.target_losses == 1
    # an old measurement does not end the search; a new one does
    assert m.step(6.0, e, target(6.0, age=CFG.lost_timeout_s + 1.1), None).mode is Mode.SEARCH
    status = m.step(7.0, e, target(7.0, age=0.05), None)
    assert status.mode is Mode.TRACK and status.reason == "target reacquired"
    assert kinds(m)[-1] == "reacquired"


def test_coast_then_sighting_records_reacquisition_without_a_search() -> None:
    m = at_mode(Mode.TRACK)
    e = ego(p=(5, 0, 4))
    m.step(3.0, e, target(3.0, age=CFG.max_estimate_age_s + 0.1), None)
    m.step(3.1, e, target(3.1), None)
    assert m.mode is Mode.TRACK and kinds(m) == ["coast", "reacquired"]


def test_search_times_out_into_exploration() -> None:
    m = at_search()
    e = ego(p=(5, 0, 8))
    assert m.step(5.0 + CFG.search_timeout_s - 0.1, e, target(6.0, age=9.0), None).mode is Mode.SEARCH
    status = m.step(5.0 + CFG.search_timeout_s + 0.1, e, target(26.0, age=25.0), None)
    assert status.mode is Mode.EXPLORE and status.reason == "search around the prediction timed out"
    assert kinds(m)[-1] == "explore"


def test_too_many_target_losses_abort() -> None:
    m = at_search()  # loss 1 of max_target_losses = 1
    m.step(7.0, ego(p=(5, 0, 4)), target(7.0), None)
    assert m.mode is Mode.TRACK
    status = m.step(12.0, ego(p=(5, 0, 4)), target(12.0, age=CFG.lost_timeout_s + 0.1), None)
    assert status.mode is Mode.ABORT and status.reason == "too many target losses"
    assert m.abort_reason == "too many target losses" and "retry_limit" in kinds(m)


def test_takeoff_timeout_aborts_with_the_final_action() -> None:
    m = started()
    assert m.step(CFG.takeoff_timeout_s - 1.0, ego(p=(0, 0, 1.0)), None, None).mode is Mode.TAKEOFF
    status = m.step(CFG.takeoff_timeout_s + 0.1, ego(p=(0, 0, 1.0)), None, None)
    assert status.mode is Mode.ABORT and status.reason == "take-off timeout"
    assert kinds(m) == ["takeoff_timeout", "abort", "final_action"] and m.abort_reason == "take-off timeout"


def test_track_to_land_needs_every_descent_gate() -> None:
    good = ego(p=(5.0, 0.1, 3.0), v=(1.1, 0, 0))
    for bad_target, bad_ego in (
        (target(2.0), ego(p=(5.0 + CFG.land_position_tolerance_m + 0.05, 0, 3.0), v=(1.0, 0, 0))),
        (target(2.0), ego(p=(5.0, 0, 3.0), v=(1.0 + CFG.land_velocity_tolerance_mps + 0.05, 0, 0))),
        (target(2.0, age=CFG.max_estimate_age_s + 0.05), good),
        (target(2.0, std=CFG.land_max_position_std_m + 0.05), good),
    ):
        m = at_mode(Mode.TRACK)
        for k in range(10):
            t = 2.0 + 0.1 * k
            tg = bad_target
            tg = target(t, age=t - tg.t_last_measurement, std=float(np.sqrt(tg.cov_p_WP[0, 0])))
            assert m.step(t, bad_ego, tg, None).mode is Mode.TRACK


def test_land_to_landed_on_the_onboard_touchdown() -> None:
    m = at_mode(Mode.LAND)
    low = ego(p=(5.0, 0.0, 0.65), v=(1.0, 0, -0.4))
    # the range finder's reading is no longer what stops the motors
    assert m.step(3.0, low, target(3.0), 0.0).mode is Mode.LAND
    status = m.step(3.2, low, target(3.2), None, touchdown=True)
    assert status.mode is Mode.LANDED and status.reason == "touchdown detected on board"
    # LANDED is final
    assert m.step(9.0, ego(p=(0, 0, 5)), None, None).mode is Mode.LANDED


@pytest.mark.parametrize(
    ("kw_ego", "kw_target", "reason"),
    [
        ({}, {"age": CFG.land_lost_timeout_s + 0.1}, "target lost during the descent"),
        ({"p": (5.0 + CFG.land_abort_offset_m + 0.1, 0, 3.0)}, {}, "off the pad during the descent"),
        (
            {"v": (1.0 + CFG.land_abort_rel_speed_mps + 0.1, 0, 0)},
            {},
            "relative velocity too large during the descent",
        ),
        ({}, {"std": CFG.land_abort_position_std_m + 0.1}, "estimate too uncertain during the descent"),
    ],
)
def test_land_gates_go_around_above_the_commit_height_only(kw_ego, kw_target, reason) -> None:
    high = dict(p=(5.0, 0, PAD_Z + CFG.land_commit_height_m + 0.5), v=(1.0, 0, 0))
    m = at_mode(Mode.LAND)
    status = m.step(3.0, ego(**{**high, **kw_ego}), target(3.0, **kw_target), None)
    assert status.mode is Mode.GO_AROUND and status.reason == reason
    assert m.events[-1].kind == "go_around" and m.events[-1].reason == reason
    # below the commit height the descent continues on the prediction, whatever the gates say
    m = at_mode(Mode.LAND)
    p = high["p"]
    low = dict(
        p=(kw_ego.get("p", p)[0], 0, PAD_Z + CFG.land_commit_height_m - 0.2), v=kw_ego.get("v", high["v"])
    )
    assert m.step(3.0, ego(**low), target(3.0, **kw_target), None).mode is Mode.LAND
    assert not m.descent_hold


def test_land_without_estimate_goes_around() -> None:
    m = at_mode(Mode.LAND)
    status = m.step(3.0, ego(p=(5, 0, 1.0)), None, None)
    assert status.mode is Mode.GO_AROUND and status.reason == "target lost during the descent"


def test_a_marginal_gate_holds_the_descent_then_goes_around() -> None:
    m = at_mode(Mode.LAND)
    high = PAD_Z + CFG.land_commit_height_m + 1.0
    marginal = ego(p=(5.0 + CFG.land_hold_offset_m + 0.05, 0, high), v=(1.0, 0, 0))
    good = ego(p=(5.0, 0, high), v=(1.0, 0, 0))
    assert m.step(3.0, marginal, target(3.0), None).mode is Mode.LAND and m.descent_hold
    assert m.events[-1].kind == "descent_hold"
    assert m.step(3.5, good, target(3.5), None).mode is Mode.LAND and not m.descent_hold  # resumes
    m.step(4.0, marginal, target(4.0), None)
    assert m.step(4.0 + CFG.land_hold_timeout_s - 0.1, marginal, target(6.8), None).mode is Mode.LAND
    status = m.step(4.0 + CFG.land_hold_timeout_s + 0.1, marginal, target(7.2), None)
    assert status.mode is Mode.GO_AROUND and status.reason == "descent held too long"


def tilted(p, v, tilt_rad: float) -> EgoState:  # type: ignore[no-untyped-def]
    """At ``p`` moving at ``v``, the body rolled by ``tilt_rad`` about x."""
    q = np.array([np.sin(0.5 * tilt_rad), 0.0, 0.0, np.cos(0.5 * tilt_rad)])
    return EgoState(t=0.0, p_WB=np.array(p), v_WB=np.array(v), q_WB=q, w_WB_B=np.zeros(3))


def test_the_lull_gate_holds_the_commit_until_the_tilt_drops_then_goes_around() -> None:
    cfg = dataclasses.replace(CFG, land_commit_max_tilt_rad=0.3, land_tilt_time_constant_s=0.3)
    m = at_mode(Mode.LAND, cfg)
    low = (5.0, 0, PAD_Z + cfg.land_commit_height_m - 0.05)
    high = (5.0, 0, PAD_Z + cfg.land_commit_height_m + 0.5)
    # above the commit height a lean does not hold the descent
    assert m.step(3.0, tilted(high, (1.0, 0, 0), 0.4), target(3.0), None).mode is Mode.LAND
    assert not m.descent_hold and m.tilt_lp_rad == pytest.approx(0.4)  # the first sample starts the filter
    # at the commit height, leaning 0.4 rad > 0.3: held, not committed, one event
    assert m.step(3.1, tilted(low, (1.0, 0, 0), 0.4), target(3.1), None).mode is Mode.LAND
    assert m.descent_hold and not m.committed
    assert m.events[-1].kind == "descent_hold" and "waiting for a lull" in m.events[-1].reason
    # the tilt drops to 0.2 rad: the 0.3 s low-pass (steps of 0.1 s, gain 0.1 / 0.4 = 0.25) goes
    # 0.4 -> 0.35 -> 0.3125 -> 0.284: released at the third step, by hand, committed at the next (as after
    # any hold: the descent resumes, then commits)
    for k, expect in ((1, 0.35), (2, 0.3125)):
        m.step(3.1 + 0.1 * k, tilted(low, (1.0, 0, 0), 0.2), target(3.1 + 0.1 * k), None)
        assert m.tilt_lp_rad == pytest.approx(expect) and not m.committed and m.descent_hold
    m.step(3.4, tilted(low, (1.0, 0, 0), 0.2), target(3.4), None)
    assert m.tilt_lp_rad == pytest.approx(0.284375) and not m.descent_hold
    m.step(3.5, tilted(low, (1.0, 0, 0), 0.2), target(3.5), None)
    assert m.committed
    # no lull for land_tilt_wait_s: go-around (not the 3 s hold timeout)
    m = at_mode(Mode.LAND, cfg)
    m.step(3.0, tilted(low, (1.0, 0, 0), 0.4), target(3.0), None)
    assert m.descent_hold
    t_end = 3.0 + cfg.land_tilt_wait_s
    assert (
        m.step(3.0 + cfg.land_hold_timeout_s + 1.0, tilted(low, (1.0, 0, 0), 0.4), target(7.0), None).mode
        is Mode.LAND
    )
    assert m.step(t_end - 0.1, tilted(low, (1.0, 0, 0), 0.4), target(t_end - 0.1), None).mode is Mode.LAND
    status = m.step(t_end + 0.1, tilted(low, (1.0, 0, 0), 0.4), target(t_end + 0.1), None)
    assert status.mode is Mode.GO_AROUND and status.reason == "no lull in the tilt"
    # off by default: the same lean commits at once
    m = at_mode(Mode.LAND)
    m.step(3.0, tilted(low, (1.0, 0, 0), 0.4), target(3.0), None)
    assert m.committed
    with pytest.raises(ValueError, match="land_commit_max_tilt_rad"):
        MissionConfig(land_commit_max_tilt_rad=2.0)


def test_the_lull_gate_waits_out_an_unsteady_lean_only_and_pauses_a_committed_descent() -> None:
    cfg = dataclasses.replace(CFG, land_commit_max_tilt_rad=0.3, land_tilt_min_spread_rad=0.05)
    low = (5.0, 0, PAD_Z + cfg.land_commit_height_m - 0.05)
    # a steady lean of 0.4 rad (a fast deck in calm air): the spread is 0, the commit is not held
    m = at_mode(Mode.LAND, cfg)
    for k in range(5):
        m.step(3.0 + 0.1 * k, tilted(low, (1.0, 0, 0), 0.4), target(3.0 + 0.1 * k), None)
    assert m.tilt_sd_rad == 0.0 and m.committed
    # the same level swinging by +-0.2 rad every 0.1 s (gusts): held
    m = at_mode(Mode.LAND, cfg)
    high = (5.0, 0, PAD_Z + cfg.land_commit_height_m + 0.5)
    for k in range(30):
        m.step(
            3.0 + 0.1 * k,
            tilted(high, (1.0, 0, 0), 0.4 + (0.2 if k % 2 else -0.2)),
            target(3.0 + 0.1 * k),
            None,
        )
    assert m.tilt_sd_rad > 0.1 and not m.descent_hold  # above the commit height nothing waits
    m.step(6.0, tilted(low, (1.0, 0, 0), 0.6), target(6.0), None)
    assert m.descent_hold and not m.committed
    # committed in a lull, a gust pauses the descent while the body is above half the commit height,
    # and no lower
    m = at_mode(Mode.LAND, cfg)
    m.step(3.0, tilted(low, (1.0, 0, 0), 0.1), target(3.0), None)
    assert m.committed
    m._tilt_var = 0.01  # an unsteady lean (spread 0.1 rad) ...
    m.step(3.1, tilted(low, (1.0, 0, 0), 1.0), target(3.1), None)  # ... and a gust: 0.1 -> 0.325 rad
    assert m.committed and m.descent_hold and m.mode is Mode.LAND
    lower = (5.0, 0, PAD_Z + 0.4 * cfg.land_commit_height_m)
    m.step(3.2, tilted(lower, (1.0, 0, 0), 1.0), target(3.2), None)
    assert m.committed and not m.descent_hold


def test_the_turn_gate_waits_for_a_hard_turn_to_end_and_pauses_a_committed_descent() -> None:
    """Worked by hand: the limit is 1.5 m/s^2; a platform at 3 m/s turning at 0.75 rad/s (a tractor's
    4 m U-turn) accelerates sideways at 2.25 m/s^2, so the descent holds at the commit height; once the
    estimate drives straight (0.3 m/s^2 of noise) it commits. A 10 m circle at 2 m/s (0.4) commits at
    once."""
    cfg = dataclasses.replace(CFG, land_commit_max_platform_accel_mps2=1.5)
    low = (5.0, 0, PAD_Z + cfg.land_commit_height_m - 0.05)
    u_turn, straight, circle = (0.0, 2.25, 0.0), (0.0, 0.3, 0.0), (-0.4, 0.0, 0.0)
    m = at_mode(Mode.LAND, cfg)
    assert (
        m.step(3.0, ego(p=low, v=(3.0, 0, 0)), target(3.0, v=(3.0, 0, 0), a=u_turn), None).mode is Mode.LAND
    )
    assert m.descent_hold and not m.committed
    assert m.events[-1].kind == "descent_hold" and "platform turning at 2.25 m/s^2" in m.events[-1].reason
    m.step(3.1, ego(p=low, v=(3.0, 0, 0)), target(3.1, v=(3.0, 0, 0), a=straight), None)
    assert not m.descent_hold  # released ...
    m.step(3.2, ego(p=low, v=(3.0, 0, 0)), target(3.2, v=(3.0, 0, 0), a=straight), None)
    assert m.committed  # ... and committed at the next step, as after any hold
    m = at_mode(Mode.LAND, cfg)
    m.step(3.0, ego(p=low, v=(2.0, 0, 0)), target(3.0, v=(2.0, 0, 0), a=circle), None)
    assert m.committed
    # a turn that starts after the commit pauses the descent above half the commit height only
    m.step(3.1, ego(p=low, v=(2.0, 0, 0)), target(3.1, v=(2.0, 0, 0), a=u_turn), None)
    assert m.committed and m.descent_hold and m.mode is Mode.LAND
    lower = (5.0, 0, PAD_Z + 0.4 * cfg.land_commit_height_m)
    m.step(3.2, ego(p=lower, v=(2.0, 0, 0)), target(3.2, v=(2.0, 0, 0), a=u_turn), None)
    assert m.committed and not m.descent_hold
    # a turn that lasts land_tilt_wait_s: go-around, with its own reason
    m = at_mode(Mode.LAND, cfg)
    m.step(3.0, ego(p=low, v=(3.0, 0, 0)), target(3.0, v=(3.0, 0, 0), a=u_turn), None)
    t_end = 3.0 + cfg.land_tilt_wait_s
    assert (
        m.step(
            t_end - 0.1, ego(p=low, v=(3.0, 0, 0)), target(t_end - 0.1, v=(3.0, 0, 0), a=u_turn), None
        ).mode
        is Mode.LAND
    )
    status = m.step(
        t_end + 0.1, ego(p=low, v=(3.0, 0, 0)), target(t_end + 0.1, v=(3.0, 0, 0), a=u_turn), None
    )
    assert status.mode is Mode.GO_AROUND and status.reason == "the platform kept turning hard"
    # a non-finite acceleration shuts the gate (the prediction is not to be flown on)
    m = at_mode(Mode.LAND, cfg)
    m.step(3.0, ego(p=low, v=(3.0, 0, 0)), target(3.0, v=(3.0, 0, 0), a=(np.nan, 0.0, 0.0)), None)
    assert m.descent_hold and not m.committed
    # off by default: the U-turn commits at once
    m = at_mode(Mode.LAND)
    m.step(3.0, ego(p=low, v=(3.0, 0, 0)), target(3.0, v=(3.0, 0, 0), a=u_turn), None)
    assert m.committed
    with pytest.raises(ValueError, match="land_commit_max_platform_accel_mps2"):
        MissionConfig(land_commit_max_platform_accel_mps2=-1.0)


def test_a_steady_lean_above_the_ceiling_still_holds_the_commit() -> None:
    """With a spread limit, a steady lean commits (waiting would change nothing) only below
    land_steady_tilt_max_rad: 0.40 rad steady commits under a 0.42 ceiling, 0.45 rad steady waits."""
    cfg = dataclasses.replace(
        CFG, land_commit_max_tilt_rad=0.3, land_tilt_min_spread_rad=0.05, land_steady_tilt_max_rad=0.42
    )
    low = (5.0, 0, PAD_Z + cfg.land_commit_height_m - 0.05)
    for tilt, held in ((0.40, False), (0.45, True)):
        m = at_mode(Mode.LAND, cfg)
        for k in range(5):
            m.step(3.0 + 0.1 * k, tilted(low, (1.0, 0, 0), tilt), target(3.0 + 0.1 * k), None)
            if m.committed:
                break
        assert m.tilt_sd_rad == 0.0
        assert (m.descent_hold and not m.committed) if held else m.committed, tilt
    with pytest.raises(ValueError, match="land_steady_tilt_max_rad"):
        MissionConfig(land_steady_tilt_max_rad=1.6)


def test_sinking_through_the_commit_height_during_a_hold_does_not_commit() -> None:
    """A vehicle that lags its held reference and sinks below the commit height while a gate is marginal
    (the platform braked) is not committed: the gates still apply, and a bad one goes around."""
    m = at_mode(Mode.LAND)
    high = PAD_Z + CFG.land_commit_height_m + 0.1
    marginal_v = (1.0 + CFG.land_hold_rel_speed_mps + 0.1, 0, 0)
    assert m.step(3.0, ego(p=(5.0, 0, high), v=marginal_v), target(3.0), None).mode is Mode.LAND
    assert m.descent_hold
    low = PAD_Z + CFG.land_commit_height_m - 0.1
    assert m.step(3.1, ego(p=(5.0, 0, low), v=marginal_v), target(3.1), None).mode is Mode.LAND
    assert not m.committed and m.descent_hold
    bad_v = (1.0 + CFG.land_abort_rel_speed_mps + 0.1, 0, 0)
    status = m.step(3.2, ego(p=(5.0, 0, low), v=bad_v), target(3.2), None)
    assert status.mode is Mode.GO_AROUND and status.reason == "relative velocity too large during the descent"
    # entered with every gate good, the commit holds whatever the gates say afterwards
    m = at_mode(Mode.LAND)
    assert m.step(3.0, ego(p=(5.0, 0, low), v=(1.0, 0, 0)), target(3.0), None).mode is Mode.LAND
    assert m.committed
    assert m.step(3.1, ego(p=(5.0, 0, low), v=bad_v), target(3.1), None).mode is Mode.LAND


def test_a_committed_descent_without_touchdown_goes_around() -> None:
    """Below the commit height the descent flies on the prediction; when no touchdown comes (the platform
    drove off, the vehicle hovers beside it at the descent's floor) it goes around after the timeout."""
    m = at_mode(Mode.LAND)
    timeout = m.commit_timeout_s()
    assert timeout == pytest.approx(2.0 * CFG.land_commit_height_m / CFG.land_speed_mps + 3.0)
    low = ego(p=(5.0, 0, PAD_Z - 0.3), v=(1.0, 0, 0))
    assert m.step(3.0, low, target(3.0), None).mode is Mode.LAND and m.committed
    assert m.step(3.0 + timeout - 0.1, low, target(3.0 + timeout - 0.1, age=5.0), None).mode is Mode.LAND
    status = m.step(3.0 + timeout + 0.1, low, target(3.0 + timeout + 0.1, age=5.0), None)
    assert status.mode is Mode.GO_AROUND and status.reason == "no touchdown after the commit height"
    assert m.events[-1].kind == "go_around" and not m.committed
    assert Mission(MissionConfig(land_commit_timeout_s=2.5)).commit_timeout_s() == 2.5


def test_a_platform_speed_change_under_a_committed_descent_goes_around() -> None:
    """Committed at 1 m/s, the platform estimate then says the platform brakes: above a quarter of the
    commit height the descent goes around; lower down it continues (the feet are nearly on the deck)."""
    m = at_mode(Mode.LAND)
    z = PAD_Z + CFG.land_commit_height_m - 0.05
    assert m.step(3.0, ego(p=(5.0, 0, z), v=(1.0, 0, 0)), target(3.0), None).mode is Mode.LAND
    assert m.committed
    slower = (1.0 - CFG.land_commit_speed_change_mps + 0.1, 0, 0)
    assert m.step(3.1, ego(p=(5.0, 0, z), v=(1.0, 0, 0)), target(3.1, v=slower), None).mode is Mode.LAND
    braking = (1.0 - CFG.land_commit_speed_change_mps - 0.1, 0, 0)
    status = m.step(3.2, ego(p=(5.0, 0, z), v=(1.0, 0, 0)), target(3.2, v=braking), None)
    assert status.mode is Mode.GO_AROUND and status.reason == "platform speed changed after the commit"
    # a turn changes the velocity's direction, not the speed: no go-around
    m = at_mode(Mode.LAND)
    m.step(3.0, ego(p=(5.0, 0, z), v=(1.0, 0, 0)), target(3.0), None)
    assert m.step(3.5, ego(p=(5.0, 0, z)), target(3.5, v=(0.0, 1.0, 0)), None).mode is Mode.LAND
    # nearly down: the descent continues
    m = at_mode(Mode.LAND)
    m.step(3.0, ego(p=(5.0, 0, z), v=(1.0, 0, 0)), target(3.0), None)
    low = PAD_Z + 0.2 * CFG.land_commit_height_m
    assert m.step(3.5, ego(p=(5.0, 0, low)), target(3.5, v=braking), None).mode is Mode.LAND


def test_a_committed_descent_over_the_ground_beside_the_deck_goes_around() -> None:
    height = CFG.land_commit_height_m - 0.2  # body over the estimated deck, committed
    low = ego(p=(5.0, 0, PAD_Z + height), v=(1.0, 0, -0.4))
    over_deck, beside = height - 0.1, height + PAD_Z - 0.1  # the range from feet 0.1 m below the body
    assert CFG.land_commit_ground_margin_m == 0.2  # on by default
    cfg = CFG
    m = at_mode(Mode.LAND, cfg)
    assert m.step(3.0, low, target(3.0), over_deck).mode is Mode.LAND
    assert m.step(3.1, low, target(3.1), None).mode is Mode.LAND  # no reading: no evidence
    status = m.step(3.2, low, target(3.2), beside)
    assert status.mode is Mode.GO_AROUND and status.reason == "ground below the committed descent"
    # off with None; and above the commit height the descent's gates decide, not the range
    m = at_mode(Mode.LAND, dataclasses.replace(CFG, land_commit_ground_margin_m=None))
    assert m.step(3.0, low, target(3.0), beside).mode is Mode.LAND
    m = at_mode(Mode.LAND, cfg)
    high = ego(p=(5.0, 0, PAD_Z + CFG.land_commit_height_m + 0.5), v=(1.0, 0, -0.4))
    assert m.step(3.0, high, target(3.0), CFG.land_commit_height_m + 0.5 + PAD_Z).mode is Mode.LAND


def test_a_committed_descent_over_a_deck_that_leaves_the_estimate_goes_around() -> None:
    """The optical-flow module measures the deck's velocity under the feet; when it leaves the platform
    estimate's (1 m/s along x here) by more than the limit, as under a brake, a committed descent goes
    around at any height. Within the limit, in any direction, without a sample, or above the commit
    height (not committed): the descent goes on."""
    limit = CFG.land_commit_deck_velocity_error_mps
    assert limit == 0.5  # on by default
    low = ego(p=(5.0, 0, PAD_Z + 0.1), v=(1.0, 0, -0.4))  # 10 cm over the deck: under every other gate
    commit = ego(p=(5.0, 0, PAD_Z + CFG.land_commit_height_m - 0.1), v=(1.0, 0, -0.4))
    m = at_mode(Mode.LAND)
    m.step(3.0, commit, target(3.0), None)
    near = np.array([1.0 - 0.3 * limit, 0.9 * limit])  # |(-0.15, 0.45)| = 0.47 from the estimate's (1, 0)
    assert m.step(3.1, low, target(3.1), None, deck_velocity_W=near).mode is Mode.LAND
    assert m.step(3.12, low, target(3.12), None, deck_velocity_W=None).mode is Mode.LAND
    braked = np.array([1.0 - limit - 0.05, 0.0])
    status = m.step(3.14, low, target(3.14), None, deck_velocity_W=braked)
    assert status.mode is Mode.GO_AROUND
    assert status.reason == "the deck left the estimate under the committed descent (optical flow)"
    # the same measured velocity against an estimate that agrees with it: no go-around
    m = at_mode(Mode.LAND)
    m.step(3.0, commit, target(3.0, v=(braked[0], 0.0, 0.0)), None)
    assert (
        m.step(3.1, low, target(3.1, v=(braked[0], 0.0, 0.0)), None, deck_velocity_W=braked).mode is Mode.LAND
    )
    # off with None
    m = at_mode(Mode.LAND, dataclasses.replace(CFG, land_commit_deck_velocity_error_mps=None))
    m.step(3.0, commit, target(3.0), None)
    assert m.step(3.1, low, target(3.1), None, deck_velocity_W=np.zeros(2)).mode is Mode.LAND
    # not committed (above the commit height): the descent's own gates decide
    m = at_mode(Mode.LAND)
    high = ego(p=(5.0, 0, PAD_Z + CFG.land_commit_height_m + 0.5), v=(1.0, 0, -0.4))
    assert m.step(3.0, high, target(3.0), None, deck_velocity_W=np.zeros(2)).mode is Mode.LAND


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
    status = m.step(7.1, above, target(7.1), None)
    assert status.mode is Mode.ABORT and status.reason == "too many go-arounds"
    assert "retry_limit" in kinds(m)
    assert m.step(50.0, above, target(50.0), None).mode is Mode.ABORT  # final


def test_go_around_without_an_estimate_waits_for_the_exploration_altitude() -> None:
    m = at_mode(Mode.GO_AROUND)
    assert m.step(4.0, ego(p=(5, 0, 5.0)), None, None).mode is Mode.GO_AROUND
    assert m.step(5.0, ego(p=(5, 0, CFG.explore_altitude_m)), None, None).mode is Mode.TRACK


@pytest.mark.parametrize("mode", [Mode.EXPLORE, Mode.TRACK, Mode.LAND, Mode.GO_AROUND, Mode.SEARCH])
def test_time_budget_aborts(mode: Mode) -> None:
    m = at_search() if mode is Mode.SEARCH else at_mode(mode)
    late = CFG.time_budget_s + 1.0
    e = ego(p=(5.0, 0.0, 3.0), v=(1.0, 0, 0))
    status = m.step(late, e, target(late, age=0.0 if mode is not Mode.SEARCH else 50.0), None)
    if mode is Mode.LAND:  # a descent goes around first; at the tracking height, the abort
        assert status.mode is Mode.GO_AROUND and status.reason == "time budget spent"
        status = m.step(late + 0.1, e, target(late + 0.1), None)
    assert status.mode is Mode.ABORT and status.reason == "time budget spent"
    assert m.abort_reason == "time budget spent"


@pytest.mark.parametrize("cause", ["retry limit", "time budget"])
def test_a_limit_reached_low_in_a_descent_aborts_once_the_go_around_has_climbed(cause: str) -> None:
    """Past the retry limit or the time budget, a go-around from the committed descent still climbs to
    the tracking height before the final action starts (which brakes to a hover point: started
    centimetres over a moving deck, it met the deck)."""
    cfg = dataclasses.replace(CFG, max_go_arounds=0) if cause == "retry limit" else CFG
    m = at_mode(Mode.LAND, cfg)
    t = CFG.time_budget_s + 1.0 if cause == "time budget" else 3.0
    low = ego(p=(5.0, 0.0, PAD_Z + 0.3), v=(1.0, 0.0, -0.4))
    # the retry limit: the deck under the feet leaves the estimate in the committed descent (optical flow)
    first = m.step(t, low, target(t), None, deck_velocity_W=np.array([3.0, 0.0]))
    assert first.mode is Mode.GO_AROUND
    for k, z in enumerate((0.25, 1.0, 2.0)):  # climbing, still below the tracking height
        tk = t + 0.1 * (k + 1)
        climbing = ego(p=(5.0, 0.0, PAD_Z + z), v=(1.0, 0.0, 0.5))
        assert m.step(tk, climbing, target(tk), None).mode is Mode.GO_AROUND
    assert m.abort_reason is None and "retry_limit" not in kinds(m)
    top = t + 1.0
    status = m.step(top, ego(p=(5.0, 0.0, PAD_Z + CFG.track_height_m)), target(top), None)
    expected = "too many go-arounds" if cause == "retry limit" else "time budget spent"
    assert status.mode is Mode.ABORT and status.reason == expected and m.abort_reason == expected
    assert ("retry_limit" in kinds(m)) is (cause == "retry limit")


def test_without_an_estimate_a_go_around_past_the_limit_aborts_at_once() -> None:
    m = at_mode(Mode.GO_AROUND, dataclasses.replace(CFG, max_go_arounds=0))
    status = m.step(4.0, ego(p=(5.0, 0.0, PAD_Z + 0.3)), None, None)
    assert status.mode is Mode.ABORT and status.reason == "too many go-arounds"


def test_final_action_hover_climbs_holds_and_completes() -> None:
    m = at_mode(Mode.TRACK, MissionConfig(time_budget_s=10.0, explore_altitude_m=12.0))
    m.step(11.0, ego(p=(5, 0, 3.0)), target(11.0), None)
    assert m.mode is Mode.ABORT and m.abort_phase == "climb"
    np.testing.assert_allclose(m.abort_goal_W, [5, 0, 12.0])
    m.step(15.0, ego(p=(5, 0, 12.0)), None, None)
    assert m.abort_phase == "hold" and not m.final_action_complete
    m.step(16.0, ego(p=(5, 0, 12.0)), None, None)
    m.step(16.0 + m.config.abort_hover_s, ego(p=(5, 0, 12.0)), None, None)
    assert m.final_action_complete and m.mode is Mode.ABORT
    assert kinds(m)[-1] == "final_action_complete"


def test_final_action_return_flies_home_then_lands() -> None:
    cfg = MissionConfig(time_budget_s=10.0, final_action="return")
    m = at_mode(Mode.TRACK, cfg)
    m.step(11.0, ego(p=(5, 0, 3.0)), target(11.0), None)
    assert m.abort_phase == "transit"
    np.testing.assert_allclose(m.abort_goal_W, [0, 0, 12.0])
    m.step(12.0, ego(p=(2, 0, 12.0), v=(2, 0, 0)), None, None)
    assert m.abort_phase == "transit"
    m.step(20.0, ego(p=(0.1, 0, 12.0)), None, None)
    assert m.abort_phase == "descend" and m.abort_goal_W[2] == pytest.approx(0.1)  # the take-off height
    m.step(30.0, ego(p=(0.1, 0, 0.1)), None, None)
    assert not m.final_action_complete
    m.step(31.0, ego(p=(0.1, 0, 0.1)), None, None, touchdown=True)
    assert m.final_action_complete and m.mode is Mode.ABORT


def test_final_action_land_in_place_descends_at_once() -> None:
    m = at_mode(Mode.TRACK, MissionConfig(time_budget_s=10.0, final_action="land_in_place"))
    m.step(11.0, ego(p=(7, 1, 3.0)), target(11.0), None)
    assert m.abort_phase == "descend"
    np.testing.assert_allclose(m.abort_goal_W[:2], [7, 1])
    m.step(20.0, ego(p=(7, 1, 0.1)), None, None, touchdown=True)
    assert m.final_action_complete


def test_every_listed_transition_is_reachable_and_only_those_happen() -> None:
    """Replays the scenarios above and checks that the transitions they took, with their events, are
    exactly the table."""
    seen: set[tuple[Mode, Mode, str]] = set()
    scenarios = [
        test_idle_to_takeoff_records_the_takeoff_point,
        test_takeoff_waits_for_the_hover_point,
        test_takeoff_goes_straight_to_track_when_target_seen,
        test_takeoff_tracks_a_target_seen_during_the_climb_once_above_the_tracking_height,
        test_takeoff_timeout_aborts_with_the_final_action,
        test_explore_to_track_on_detection_only_when_fresh,
        test_track_to_land_needs_position_velocity_and_dwell,
        test_track_to_land_needs_every_descent_gate,
        test_track_coasts_on_the_prediction_then_searches_and_reacquires,
        test_coast_then_sighting_records_reacquisition_without_a_search,
        test_search_times_out_into_exploration,
        test_too_many_target_losses_abort,
        test_land_to_landed_on_the_onboard_touchdown,
        test_land_without_estimate_goes_around,
        test_a_marginal_gate_holds_the_descent_then_goes_around,
        test_the_lull_gate_holds_the_commit_until_the_tilt_drops_then_goes_around,
        test_the_turn_gate_waits_for_a_hard_turn_to_end_and_pauses_a_committed_descent,
        test_the_lull_gate_waits_out_an_unsteady_lean_only_and_pauses_a_committed_descent,
        test_sinking_through_the_commit_height_during_a_hold_does_not_commit,
        test_a_committed_descent_without_touchdown_goes_around,
        test_a_platform_speed_change_under_a_committed_descent_goes_around,
        test_a_committed_descent_over_the_ground_beside_the_deck_goes_around,
        test_a_committed_descent_over_a_deck_that_leaves_the_estimate_goes_around,
        test_go_around_returns_to_track_at_height_and_aborts_after_too_many,
        test_go_around_without_an_estimate_waits_for_the_exploration_altitude,
        test_final_action_hover_climbs_holds_and_completes,
        test_final_action_return_flies_home_then_lands,
        test_final_action_land_in_place_descends_at_once,
        quiet_gate.test_the_mission_goes_around_when_the_window_closes_before_contact,
        quiet_gate.test_the_mission_goes_around_when_no_window_comes,
    ]
    calls = [(fn, ()) for fn in scenarios]
    calls += [
        (test_time_budget_aborts, (mode,))
        for mode in (Mode.EXPLORE, Mode.TRACK, Mode.LAND, Mode.GO_AROUND, Mode.SEARCH)
    ]
    for args in test_land_gates_go_around_above_the_commit_height_only.pytestmark[0].args[1]:  # type: ignore[attr-defined]
        calls.append((test_land_gates_go_around_above_the_commit_height_only, tuple(args)))
    original = Mission._go
    record: list[tuple[Mode, Mode, str]] = []

    def spy(self: Mission, t: float, mode: Mode, reason: str) -> None:
        record.append((self.mode, mode, reason))
        original(self, t, mode, reason)

    Mission._go = spy  # type: ignore[method-assign]
    try:
        for fn, args in calls:
            fn(*args)  # type: ignore[operator]
    finally:
        Mission._go = original  # type: ignore[method-assign]
    seen.update(record)
    assert seen == set(TRANSITIONS)


def test_bad_config_raises() -> None:
    with pytest.raises(ValueError, match="land_speed_mps"):
        MissionConfig(land_speed_mps=0.0)
    with pytest.raises(ValueError, match="max_go_arounds"):
        MissionConfig(max_go_arounds=-1)
    with pytest.raises(ValueError, match="final_action"):
        MissionConfig(final_action="explode")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="takeoff_timeout_s"):
        MissionConfig(takeoff_timeout_s=0.0)
