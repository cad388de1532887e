"""Each failsafe in one closed-loop seeded mission with its outcome asserted (groundtruth preset: the
platform drives straight past the take-off point, found during the climb; faults.blackouts remove the
detections at chosen times of that timeline: TRACK from ~4 s, LAND from ~7.8 s, contact at ~14 s)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from alight.evaluation.runner import run_mission
from alight.scenario import scenario_from_dict


def _fly(record: bool = False, **over: Any) -> tuple[dict[str, Any], dict[str, np.ndarray] | None]:
    base: dict[str, Any] = {
        "preset": "groundtruth",
        "seed": 1,
        "duration_s": 90.0,
        "platform": {"path": "straight", "speed_mps": 1.2, "start_xy": [-6.0, 2.0], "heading_rad": 0.0},
    }
    for key, value in over.items():
        base[key] = {**base.get(key, {}), **value} if isinstance(value, dict) else value
    run = run_mission(scenario_from_dict(base), record=record)
    return run.result, run.log


def _kinds(r: dict[str, Any]) -> list[str]:
    return [e["kind"] for e in r["failsafe_events"]]


def _modes(r: dict[str, Any]) -> list[str]:
    return [h["mode"] for h in r["mode_history"]]


@pytest.mark.slow
def test_nominal_mission_lands_on_board_without_failsafes() -> None:
    r, _ = _fly()
    assert r["outcome"] == "landed" and r["bounces"] == 0 and r["failsafe_events"] == []
    # the land detector stops the motors within a second of the first contact; the outcome is judged
    # settle_s (2 s) later
    assert r["time_first_contact_s"] < r["time_touchdown_onboard_s"] < r["time_first_contact_s"] + 1.5
    assert r["simulated_time_s"] == pytest.approx(r["time_motors_off_s"] + 2.0, abs=0.01)


@pytest.mark.slow
def test_lost_target_coasts_then_searches_around_the_prediction_and_reacquires() -> None:
    r, log = _fly(record=True, faults={"blackouts": [[5.0, 12.0]]})
    assert r["outcome"] == "landed", r["mode_history"]
    assert _kinds(r)[:3] == ["coast", "search", "reacquired"]
    assert _modes(r)[:5] == ["takeoff", "track", "search", "track", "land"]
    assert log is not None
    search = log["mode"] == "search"
    assert search.any()
    # the search is centred on the predicted platform, which moves on: the vehicle stays near the true
    # platform throughout, not around where it lost it
    d = np.hypot(*(log["p_WB"][search, 0:2] - log["p_WP"][search, 0:2]).T)
    assert np.max(d) < 6.0
    pred = log["p_WP_est"][search, 0:2]
    assert np.hypot(*(pred[-1] - pred[0])) > 3.0  # the prediction it circles moved on with the platform
    assert np.max(np.hypot(*(log["p_WB"][search, 0:2] - pred).T)) < 6.0


@pytest.mark.slow
def test_a_short_gap_during_the_descent_holds_it_then_lands() -> None:
    r, _ = _fly(faults={"blackouts": [[9.0, 9.8]]})
    assert r["outcome"] == "landed", r["mode_history"]
    assert "descent_hold" in _kinds(r) and r["go_arounds"] == 0


@pytest.mark.slow
def test_a_long_gap_during_the_descent_goes_around_relative_to_the_platform_then_lands() -> None:
    r, _ = _fly(faults={"blackouts": [[9.0, 11.0]]})
    assert r["outcome"] == "landed", r["mode_history"]
    assert r["go_arounds"] == 1 and "go_around" in _kinds(r)
    assert _modes(r)[2:6] == ["land", "go_around", "track", "land"]


@pytest.mark.slow
def test_go_around_limit_aborts_and_returns_home_to_land() -> None:
    r, _ = _fly(faults={"blackouts": [[9.0, 11.0]]}, mission={"max_go_arounds": 0, "final_action": "return"})
    assert r["abort_reason"] == "too many go-arounds"
    assert r["outcome"] == "aborted", (r["mode_history"], r["failsafe_events"], r["outcome_reason"])
    assert "retry_limit" in _kinds(r) and _kinds(r)[-1] == "final_action_complete"
    assert r["success"] is False


@pytest.mark.slow
def test_takeoff_timeout_aborts_and_lands_in_place() -> None:
    r, _ = _fly(mission={"takeoff_timeout_s": 3.0, "final_action": "land_in_place"})
    assert r["abort_reason"] == "take-off timeout"
    assert r["outcome"] == "aborted", (r["mode_history"], r["failsafe_events"], r["outcome_reason"])
    assert _kinds(r)[0] == "takeoff_timeout" and _kinds(r)[-1] == "final_action_complete"


@pytest.mark.slow
def test_time_budget_aborts_and_hovers() -> None:
    r, _ = _fly(mission={"time_budget_s": 6.0})
    assert r["abort_reason"] == "time budget spent"
    assert r["outcome"] == "aborted" and r["time_first_contact_s"] is None
    assert _kinds(r)[-1] == "final_action_complete"
    assert math.isfinite(r["simulated_time_s"]) and r["simulated_time_s"] < 30.0


@pytest.mark.slow
def test_target_loss_limit_aborts_and_hovers() -> None:
    r, _ = _fly(faults={"blackouts": [[5.0, 40.0]]}, mission={"max_target_losses": 0})
    assert r["abort_reason"] == "too many target losses"
    assert r["outcome"] == "aborted", (r["mode_history"], r["failsafe_events"])
    assert _kinds(r)[:2] == ["coast", "retry_limit"] and _kinds(r)[-1] == "final_action_complete"
    assert _modes(r) == ["takeoff", "track", "abort"]
