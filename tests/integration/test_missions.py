"""Closed-loop regression missions: seeded scenarios with asserted outcomes (a few per condition; the
20-seed tables are measured with the batch commands in the issue notes, not in CI)."""

from __future__ import annotations

import json
import math

import pytest

from alight.cli import main
from alight.evaluation.runner import run_mission
from alight.mission.pipeline import BLOCKS
from alight.scenario import scenario_from_dict

REQUIRED_RESULT_FIELDS = {
    "scenario",
    "seed",
    "preset",
    "outcome",
    "success",
    "touchdown_error_m",
    "touchdown_rel_speed_mps",
    "time_first_detection_s",
    "time_to_land_s",
    "energy_flight_J",
    "energy_compute_J",
    "detections",
    "platform_estimate_rmse_m",
    "wall_time_s",
    "alight_version",
    "time_first_contact_s",
    "time_touchdown_onboard_s",
    "bounces",
    "failsafe_events",
    "abort_reason",
}

# (path, speed, seed): the paper-000 conditions, seeds picked once at random and frozen.
CONDITIONS = [
    ("straight", 1.2, 1),
    ("straight", 1.2, 2),
    ("circle", 2.0, 3),
    ("circle", 2.0, 5),
    ("figure8", 4.2, 2),
    ("figure8", 4.2, 5),
]


@pytest.mark.slow
@pytest.mark.parametrize(("path", "speed", "seed"), CONDITIONS)
def test_groundtruth_mission_lands(path: str, speed: float, seed: int) -> None:
    s = scenario_from_dict(
        {"preset": "groundtruth", "seed": seed, "platform": {"path": path, "speed_mps": speed}}
    )
    run = run_mission(s, record=False)
    r = run.result
    assert r["outcome"] == "landed", r["mode_history"]
    assert r["touchdown_error_m"] < 0.3
    assert r["touchdown_rel_vertical_speed_mps"] <= 1.0
    assert r["time_first_detection_s"] < r["time_landing_start_s"] < r["time_to_land_s"]
    modes = [h["mode"] for h in r["mode_history"]]
    assert modes[0] == "takeoff" and modes[-1] == "landed" and "land" in modes


# falanga2017 end to end (rendered camera, tag detector, PnP): one seed per paper condition.
VISION_CONDITIONS = [("straight", 1.2, 1), ("circle", 2.0, 2), ("figure8", 4.2, 3)]


@pytest.mark.slow
@pytest.mark.parametrize(("path", "speed", "seed"), VISION_CONDITIONS)
def test_falanga2017_mission_lands_on_vision_alone(path: str, speed: float, seed: int) -> None:
    s = scenario_from_dict(
        {"preset": "falanga2017", "seed": seed, "platform": {"path": path, "speed_mps": speed}}
    )
    r = run_mission(s, record=False).result
    assert r["outcome"] == "landed", r["mode_history"]
    assert r["touchdown_error_m"] < 0.2
    assert r["detections"] > 50  # measurements came from the rendered images, through PnP
    assert r["time_first_detection_s"] < r["time_landing_start_s"] < r["time_to_land_s"]
    # every block was charged its compute, and together they took less than the mission (which also
    # rendered the images and stepped the physics)
    blocks = r["block_time_s"]
    assert set(blocks) == set(BLOCKS) and all(v > 0 for v in blocks.values()), blocks
    assert sum(blocks.values()) < r["wall_time_s"]


# kim_kaist (paper 003) end to end: rendered colour fisheye, colour filter, pixels into the UKF, L1
# augmentation, the -0.1 m/s descent; in the gust model, as issue 5's table.
@pytest.mark.slow
@pytest.mark.parametrize(("speed", "seed"), [(1.0, 1), (2.0, 3), (3.0, 2)])
def test_kim_kaist_mission_lands_in_gusts(speed: float, seed: int) -> None:
    s = scenario_from_dict(
        {
            "preset": "kim_kaist",
            "seed": seed,
            "duration_s": 90.0,
            "platform": {"path": "straight", "speed_mps": speed},
            "wind": {"model": "gust"},
        }
    )
    r = run_mission(s, record=False).result
    assert r["outcome"] == "landed", r["mode_history"]
    assert r["touchdown_error_m"] < 0.3
    assert r["detections"] > 100 and r["false_detections"] == 0 and not r["false_lock"]
    # the paper's ramp: at 0.1 m/s the descent from the tracking height takes over 15 s
    assert r["time_to_land_s"] - r["time_landing_start_s"] > 15.0


# zamanakos_sdu (paper 004) end to end: n-fold + ArUco marker, homography, delay-compensated KF, QoS.
@pytest.mark.slow
@pytest.mark.parametrize(
    ("path", "wind", "seed"),
    [("straight", "none", 2), ("straight", "gust", 2), ("tractor", "none", 4), ("tractor", "gust", 1)],
)
def test_zamanakos_sdu_mission_lands(path: str, wind: str, seed: int) -> None:
    s = scenario_from_dict(
        {
            "preset": "zamanakos_sdu",
            "seed": seed,
            "duration_s": 90.0,
            "platform": {"path": path, "speed_mps": 1.5},
            "wind": {"model": wind, "gust_power_N": 7.76},
        }
    )
    r = run_mission(s, record=False).result
    assert r["outcome"] == "landed", r["mode_history"]
    assert r["touchdown_error_m"] < 0.3
    assert r["detections"] > 50 and r["false_detections"] == 0
    assert r["energy_compute_J"] > 0 and r["frames_processed"] < r["simulated_time_s"] * 20.0


@pytest.mark.slow
def test_aiming_the_camera_finds_a_platform_passing_upwind_in_gusts() -> None:
    # A seed of the sdu straight-line gust campaign: the platform passes 5 m upwind of the take-off point
    # while the vehicle climbs into the 7.76 N gusts, tilted ~30 deg. Flying the body on the pattern, the
    # camera looks ~6 m downwind and never sees it; aimed, the camera covers the take-off area.
    base = {
        "preset": "zamanakos_sdu",
        "seed": 576602530,
        "duration_s": 60.0,
        "platform": {"path": "straight", "speed_mps": 1.5},
        "wind": {"model": "gust", "gust_power_N": 7.76},
    }
    aimed = run_mission(scenario_from_dict(base), record=False).result
    assert aimed["outcome"] == "landed", aimed["mode_history"]
    assert aimed["time_first_detection_s"] < 15.0 and aimed["touchdown_error_m"] < 0.3
    body = run_mission(scenario_from_dict({**base, "mission": {"aim_camera": False}}), record=False).result
    assert body["outcome"] == "timeout" and body["detections"] == 0


@pytest.mark.slow
def test_kim_kaist_shape_mitigation_keeps_off_red_boxes() -> None:
    # Red 1.5 x 0.75 m boxes on the ground: the plain colour filter locks onto one of them (the
    # campaign measured 20/20 false locks); the shape mitigation lands on the target.
    s = scenario_from_dict(
        {
            "preset": "kim_kaist",
            "seed": 1,
            "duration_s": 60.0,
            "platform": {"path": "straight", "speed_mps": 2.0},
            "perception": {"mitigation": "gate+shape"},
            "camera": {"distractors": {"count": 8, "size_m": 1.5, "shape": "rect", "aspect": 2.0}},
        }
    )
    r = run_mission(s, record=False).result
    assert r["outcome"] == "landed" and not r["false_lock"] and r["false_detections"] == 0


@pytest.mark.slow
def test_phase_adaptive_quality_costs_less_compute_than_the_highest() -> None:
    base = {
        "preset": "zamanakos_sdu",
        "seed": 2,
        "duration_s": 60.0,
        "platform": {"path": "straight", "speed_mps": 1.5},
        "perception": {"rate_hz": 30.0},
    }
    phase = run_mission(scenario_from_dict({**base, "energy": {"qos": "phase"}}), record=False).result
    fixed = run_mission(scenario_from_dict({**base, "energy": {"qos": "fixed"}}), record=False).result
    assert phase["outcome"] == fixed["outcome"] == "landed"
    assert phase["energy_compute_J"] < 0.7 * fixed["energy_compute_J"]


@pytest.mark.slow
def test_same_seed_same_mission_and_seeds_differ() -> None:
    base = {"preset": "groundtruth", "duration_s": 30.0, "platform": {"path": "circle", "speed_mps": 2.0}}
    a = run_mission(scenario_from_dict({**base, "seed": 11}), record=True)
    b = run_mission(scenario_from_dict({**base, "seed": 11}), record=True)
    c = run_mission(scenario_from_dict({**base, "seed": 12}), record=True)
    assert a.log is not None and b.log is not None and c.log is not None
    for key in ("p_WB", "p_WP", "p_WP_est", "thrust_N"):
        assert (a.log[key] == b.log[key])[~_nan(a.log[key])].all()
    assert a.result["mode_history"] == b.result["mode_history"]
    assert not (a.log["p_WP"][: len(c.log["p_WP"])] == c.log["p_WP"][: len(a.log["p_WP"])]).all()


def _nan(x):  # type: ignore[no-untyped-def]
    import numpy as np

    return np.isnan(x)


@pytest.mark.slow
def test_blackout_of_perception_never_lands() -> None:
    s = scenario_from_dict(
        {
            "preset": "groundtruth",
            "seed": 1,
            "duration_s": 20.0,
            "platform": {"path": "straight", "speed_mps": 1.2},
            "faults": {"blackouts": [[0.0, 1000.0]]},
        }
    )
    r = run_mission(s, record=False).result
    assert r["outcome"] == "timeout"
    assert r["time_first_detection_s"] is None and r["detections"] == 0
    assert r["touchdown_error_m"] is None


@pytest.mark.slow
def test_cli_fly_writes_result_log_and_report(tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    scenario = tmp_path / "s.yaml"
    scenario.write_text("preset: groundtruth\nseed: 3\nplatform: {path: circle, speed_mps: 2.0}\n")
    out = tmp_path / "run"
    assert main(["fly", str(scenario), "--out", str(out)]) == 0
    result = json.loads((out / "result.json").read_text())
    assert REQUIRED_RESULT_FIELDS <= result.keys()
    assert result["outcome"] == "landed" and result["success"] is True
    assert result["energy_flight_J"] > 0 and math.isfinite(result["energy_flight_J"])
    for name in ("log.npz", "log.csv", "report.html", "top_view.png", "time_series.png"):
        assert (out / name).stat().st_size > 0, name
    assert "landed" in (out / "report.html").read_text()
    assert "landed" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("preset: nope\n", "unknown preset"),
        ("preset: groundtruth\nplatform: {speed_mps: -1}\n", "platform.speed_mps"),
        ("preset: groundtruth\nplatfrom: {}\n", "platfrom"),
        ("preset: [unclosed\n", "not valid YAML"),
        ("- a list\n", "expected a mapping"),
        ("preset: groundtruth\nfaults: {blackouts: [[5, 1]]}\n", "blackout"),
        ("preset: groundtruth\nwind: {model: steady, velocity_mps: [.nan, 0, 0]}\n", "wind.velocity_mps"),
        ("preset: groundtruth\nplatform: {heading_rad: .inf}\n", "platform.heading_rad"),
    ],
)
def test_bad_scenario_gives_one_line_and_exit_2(tmp_path, capsys, text: str, message: str) -> None:  # type: ignore[no-untyped-def]
    scenario = tmp_path / "bad.yaml"
    scenario.write_text(text)
    assert main(["fly", str(scenario), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and message in err and "bad.yaml" in err


def test_missing_scenario_file(tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    assert main(["fly", str(tmp_path / "none.yaml"), "--out", str(tmp_path / "o")]) == 2
    assert "no such scenario file" in capsys.readouterr().err


def test_three_line_scenario_has_defaults() -> None:
    s = scenario_from_dict(
        {"preset": "groundtruth", "seed": 4, "platform": {"path": "figure8", "speed_mps": 4.2}}
    )
    assert s.perception.rate_hz == 20 and s.perception.latency_s == 0.1 and s.platform.pad_size_m == 1.5


def test_every_example_scenario_validates() -> None:
    from pathlib import Path

    from alight.mission.presets import PRESETS
    from alight.scenario import load_scenario

    examples = sorted((Path(__file__).resolve().parents[2] / "examples").glob("*.yaml"))
    assert len(examples) >= 6
    assert {"alight", "groundtruth", "falanga2017", "kim_kaist", "zamanakos_sdu"} <= set(PRESETS)
    for path in examples:
        s = load_scenario(path)
        assert s.preset in PRESETS, path


# A 2 m/s circle for the two presets whose papers' estimators are constant velocity: predicted along
# the tangent, the planner's targets lay outside the circle and the vehicle orbited ~0.8 m outside the
# platform, never landing (every such mission timed out in the paper_conditions campaign). The turn rate
# of alight.estimation.turn_rate puts the predictions on the turn.
@pytest.mark.slow
@pytest.mark.parametrize("preset", ["kim_kaist", "zamanakos_sdu"])
def test_constant_velocity_papers_land_on_a_circle(preset: str) -> None:
    s = scenario_from_dict(
        {"preset": preset, "seed": 3, "duration_s": 60.0, "platform": {"path": "circle", "speed_mps": 2.0}}
    )
    r = run_mission(s, record=False).result
    assert r["outcome"] == "landed", r["mode_history"]
    assert r["touchdown_error_m"] < 0.4
