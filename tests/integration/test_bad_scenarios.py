"""Bad scenario files through the real CLI entry point: each gives exit status 2 and one line on stderr
that names the file and what is wrong, for ``alight fly`` and for ``alight campaign`` (as the campaign's
base). Nothing is flown: every case is refused while the file is read."""

from __future__ import annotations

from pathlib import Path

import pytest

from alight.cli import main

G = "preset: groundtruth\n"

# (id, file text, a piece of the message)
BAD: list[tuple[str, str | bytes, str]] = [
    ("empty", "", "empty"),
    ("comments_only", "# nothing here\n", "empty"),
    ("blank_lines", "\n\n   \n", "empty"),
    ("duplicate_top_key", G + "preset: kim_kaist\n", "given twice"),
    ("duplicate_flow_key", G + "platform: {speed_mps: 1, speed_mps: 2}\n", "given twice"),
    ("duplicate_block_key", G + "platform:\n  path: circle\n  path: straight\n", "given twice"),
    ("speed_1e9", G + "platform: {speed_mps: 1.0e9}\n", "platform.speed_mps"),
    ("speed_negative", G + "platform: {speed_mps: -1}\n", "platform.speed_mps"),
    ("wind_1e6", G + "wind: {model: steady, velocity_mps: [1.0e6, 0, 0]}\n", "wind.velocity_mps"),
    ("wind_nan", G + "wind: {model: steady, velocity_mps: [.nan, 0, 0]}\n", "wind.velocity_mps"),
    ("wind_two_axes", G + "wind: {model: steady, velocity_mps: [1, 0]}\n", "wind.velocity_mps"),
    ("wind_model", G + "wind: {model: tornado}\n", "wind.model"),
    ("gust_1e6", G + "wind: {model: gust, gust_power_N: 1.0e6}\n", "wind.gust_power_N"),
    ("altitude_1e6", G + "mission: {explore_altitude_m: 1.0e6}\n", "mission.explore_altitude_m"),
    ("takeoff_altitude_1e6", G + "mission: {takeoff_altitude_m: 1.0e6}\n", "mission.takeoff_altitude_m"),
    ("track_height_0", G + "mission: {track_height_m: 0}\n", "mission.track_height_m"),
    ("go_arounds_1e9", G + "mission: {max_go_arounds: 1000000000}\n", "mission.max_go_arounds"),
    ("lost_timeout_1e9", G + "mission: {lost_timeout_s: 1.0e9}\n", "mission.lost_timeout_s"),
    ("time_budget_1e9", G + "mission: {time_budget_s: 1.0e9}\n", "mission.time_budget_s"),
    ("land_speed_1e3", G + "mission: {land_speed_mps: 1000}\n", "mission.land_speed_mps"),
    ("search_pattern", G + "mission: {search_pattern: zigzag}\n", "mission.search_pattern"),
    ("latency_1e6", G + "perception: {latency_s: 1.0e6}\n", "perception.latency_s"),
    ("perception_rate_0", G + "perception: {rate_hz: 0}\n", "perception.rate_hz"),
    ("perception_rate_1e9", G + "perception: {rate_hz: 1.0e9}\n", "perception.rate_hz"),
    ("dropout_2", G + "perception: {dropout_prob: 2}\n", "perception.dropout_prob"),
    ("fov_1e6", G + "perception: {fov_deg: [1.0e6, 60]}\n", "perception.fov_deg"),
    ("noise_negative", G + "perception: {noise_m: -1}\n", "perception.noise_m"),
    ("mitigation", G + "perception: {mitigation: magic}\n", "perception.mitigation"),
    ("duration_1e9", G + "duration_s: 1.0e9\n", "duration_s"),
    ("duration_0", G + "duration_s: 0\n", "duration_s"),
    ("duration_negative", G + "duration_s: -5\n", "duration_s"),
    ("duration_nan", G + "duration_s: .nan\n", "duration_s"),
    ("duration_inf", G + "duration_s: .inf\n", "duration_s"),
    ("duration_text", G + "duration_s: long\n", "duration_s"),
    ("seed_negative", G + "seed: -1\n", "seed"),
    ("seed_huge", G + "seed: 100000000000000000000000000000\n", "seed"),
    ("seed_text", G + "seed: abc\n", "seed"),
    ("seed_true", G + "seed: true\n", "seed: Value error, an integer, not a boolean"),
    ("seed_false", G + "seed: false\n", "an integer, not a boolean"),
    ("go_arounds_true", G + "mission: {max_go_arounds: true}\n", "mission.max_go_arounds"),
    ("duration_1e-9", G + "duration_s: 1.0e-9\n", "duration_s: Input should be greater than or equal to 1"),
    ("duration_half_second", G + "duration_s: 0.5\n", "duration_s"),
    ("pad_1e-9", G + "platform: {pad_size_m: 1.0e-9}\n", "platform.pad_size_m"),
    ("pad_narrower_than_gear", G + "platform: {pad_size_m: 0.3}\n", "no wider than the landing gear"),
    ("pad_vs_wide_gear", G + "contact: {gear_half_width_m: 1.0}\n", "no wider than the landing gear"),
    ("perception_rate_1e-9", G + "perception: {rate_hz: 1.0e-9}\n", "perception.rate_hz"),
    ("telemetry_rate_1e-9", G + "platform: {telemetry: {rate_hz: 1.0e-9}}\n", "platform.telemetry.rate_hz"),
    ("preset_unknown", "preset: nope\n", "unknown preset"),
    ("preset_number", "preset: [1]\n", "preset"),
    ("unknown_key", G + "platfrom: {}\n", "platfrom"),
    ("unknown_nested_key", G + "platform: {sped_mps: 2}\n", "platform.sped_mps"),
    ("top_level_list", "- a list\n", "expected a mapping"),
    ("top_level_number", "42\n", "expected a mapping"),
    ("top_level_text", "hello\n", "expected a mapping"),
    ("unclosed_flow", "preset: [unclosed\n", "not valid YAML"),
    ("tab_indent", "platform:\n\tpath: circle\n", "not valid YAML"),
    ("not_utf8", b"preset: groundtruth\nname: \xff\xfe\n", "not valid YAML"),
    ("nul_bytes", "preset: groundtruth\x00\n", "not valid YAML"),
    ("path_unknown", G + "platform: {path: zigzag}\n", "platform.path"),
    ("platform_list", G + "platform: [1, 2]\n", "platform"),
    ("pad_size_0", G + "platform: {pad_size_m: 0}\n", "platform.pad_size_m"),
    ("pad_size_1e6", G + "platform: {pad_size_m: 1.0e6}\n", "platform.pad_size_m"),
    ("circle_radius_1e9", G + "platform: {circle_radius_m: 1.0e9}\n", "platform.circle_radius_m"),
    ("start_xy_three", G + "platform: {start_xy: [1, 2, 3]}\n", "platform.start_xy"),
    ("start_xy_1e12", G + "platform: {start_xy: [1.0e12, 0]}\n", "platform.start_xy"),
    ("heading_inf", G + "platform: {heading_rad: .inf}\n", "platform.heading_rad"),
    ("camera_noise_1e6", G + "camera: {noise_dn: 1.0e6}\n", "camera.noise_dn"),
    ("camera_gamma_0", G + "camera: {gamma: 0}\n", "camera.gamma"),
    ("camera_exposure_1e6", G + "camera: {exposure_s: 1.0e6}\n", "camera.exposure_s"),
    ("brightness_drift_1", G + "camera: {brightness_drift: 1}\n", "camera.brightness_drift"),
    ("distractors_1e6", G + "camera: {distractors: {count: 1000000}}\n", "camera.distractors.count"),
    (
        "distractor_colour",
        G + "camera: {distractors: {color_bgr: [300, 0, 0]}}\n",
        "camera.distractors.color_bgr",
    ),
    ("blackout_reversed", G + "faults: {blackouts: [[5, 1]]}\n", "blackout"),
    ("blackout_not_list", G + "faults: {blackouts: 5}\n", "faults.blackouts"),
    ("search_area_inverted", G + "search_area: {x_min: 5, x_max: -5}\n", "search_area"),
    ("search_area_1e12", G + "search_area: {x_max: 1.0e12}\n", "search_area.x_max"),
    ("candidates_0", G + "planner: {n_candidates: 0}\n", "planner.n_candidates"),
    ("horizons_inverted", G + "planner: {horizon_min_s: 3, horizon_max_s: 1}\n", "horizon"),
    ("planner_rate_1e9", G + "planner: {rate_hz: 1.0e9}\n", "planner.rate_hz"),
    (
        "bandwidth_1e6",
        G + "controller: {position_bandwidth_rad_s: 1.0e6}\n",
        "controller.position_bandwidth_rad_s",
    ),
    ("tilt_1e3", G + "contact: {max_tilt_deg: 1000}\n", "contact.max_tilt_deg"),
    (
        "contact_vertical_1e-9",
        G + "contact: {max_vertical_speed_mps: 1.0e-9}\n",
        "contact.max_vertical_speed_mps: Input should be greater than or equal to 0.05",
    ),
    (
        "contact_horizontal_0.01",
        G + "contact: {max_horizontal_speed_mps: 0.01}\n",
        "contact.max_horizontal_speed_mps: Input should be greater than or equal to 0.05",
    ),
    ("accel_noise_1e9", G + "estimator: {accel_noise: 1.0e9}\n", "estimator.accel_noise"),
]


def _write(tmp_path: Path, text: str | bytes) -> Path:
    path = tmp_path / "bad.yaml"
    if isinstance(text, bytes):
        path.write_bytes(text)
    else:
        path.write_text(text, encoding="utf-8")
    return path


def _one_line(capsys: pytest.CaptureFixture[str], message: str) -> str:
    captured = capsys.readouterr()
    err = captured.err.strip()
    assert len(err.splitlines()) == 1, err
    assert message in err and "bad.yaml" in err, err
    assert "Traceback" not in captured.err + captured.out
    return err


def test_there_are_at_least_55_cases() -> None:
    assert len(BAD) >= 55 and len({case[0] for case in BAD}) == len(BAD)


@pytest.mark.parametrize(("text", "message"), [c[1:] for c in BAD], ids=[c[0] for c in BAD])
def test_fly_refuses_with_one_line_and_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], text: str | bytes, message: str
) -> None:
    scenario = _write(tmp_path, text)
    assert main(["fly", str(scenario), "--out", str(tmp_path / "out")]) == 2
    _one_line(capsys, message)
    assert not (tmp_path / "out" / "result.json").exists()


@pytest.mark.parametrize(("text", "message"), [c[1:] for c in BAD], ids=[c[0] for c in BAD])
def test_campaign_refuses_a_bad_base_with_one_line_and_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], text: str | bytes, message: str
) -> None:
    _write(tmp_path, text)
    campaign = tmp_path / "campaign.yaml"
    campaign.write_text("name: bad\nbase: bad.yaml\n", encoding="utf-8")
    assert main(["campaign", str(campaign), "--out", str(tmp_path / "out"), "--no-progress"]) == 2
    _one_line(capsys, message)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("", "empty"),
        ("name: c\nname: d\n", "given twice"),
        ("name: c\nseeds_per_condition: 1000000000\n", "more than the 100,000"),
        ("name: c\nbase: {duration_s: 1.0e9}\n", "duration_s"),
        ("name: c\ngrid: {platform.speed_mps: [1, 1.0e9]}\n", "platform.speed_mps"),
    ],
    ids=["empty", "duplicate_key", "too_many_missions", "bad_inline_base", "bad_grid_value"],
)
def test_bad_campaign_files_give_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], text: str, message: str
) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(text, encoding="utf-8")
    assert main(["campaign", str(path), "--out", str(tmp_path / "out"), "--no-progress"]) == 2
    _one_line(capsys, message)


@pytest.mark.parametrize(
    "text",
    ["not,a,campaign\n1,2,3\n", "", "mission_id,outcome\nm1\n", "\xff\xfe"],
    ids=["foreign_csv", "empty", "short_row", "not_utf8"],
)
def test_report_on_a_damaged_results_csv_never_raises(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], text: str
) -> None:
    # the report reads what it can (a foreign CSV gives an empty report); what it cannot is one line
    (tmp_path / "results.csv").write_bytes(text.encode("utf-8", "surrogateescape") if text else b"")
    status = main(["report", str(tmp_path)])
    captured = capsys.readouterr()
    assert status in (0, 2) and "Traceback" not in captured.err
    assert len(captured.err.strip().splitlines()) == (1 if status == 2 else 0), captured.err
