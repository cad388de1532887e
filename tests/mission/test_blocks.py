"""Blocks by name: the registry, the presets as data, the one-line refusals and the campaign block sets."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from alight.airframe import DEFAULT_AIRFRAME
from alight.cli import main
from alight.mission.blocks import BLOCKS, STAGES, preset_data, preset_names, resolve_blocks
from alight.mission.presets import build_preset
from alight.scenario import scenario_from_dict

# (scenario, the key the one-line error must name)
WRONG: list[tuple[dict[str, Any], str]] = [
    ({"preset": "falanga2017", "blocks": {"camera": "stereo"}}, "blocks.camera"),
    ({"preset": "falanga2017", "blocks": {"pad": "checkerboard"}}, "blocks.pad"),
    ({"preset": "falanga2017", "blocks": {"detector": "yolo"}}, "blocks.detector"),
    ({"preset": "falanga2017", "blocks": {"geolocator": "lidar"}}, "blocks.geolocator"),
    ({"preset": "falanga2017", "blocks": {"platform_estimator": "particle"}}, "blocks.platform_estimator"),
    ({"preset": "falanga2017", "blocks": {"controller": "pid"}}, "blocks.controller"),
    ({"preset": "falanga2017", "blocks": {"planner": "rrt"}}, "blocks.planner"),
    ({"preset": "falanga2017", "blocks": {"detector": 3}}, "blocks.detector"),
    ({"preset": "falanga2017", "blocks": {"detector": {"name": 3}}}, "blocks.detector"),
    ({"preset": "falanga2017", "blocks": {"detector": "red"}}, "blocks.detector"),
    ({"preset": "falanga2017", "blocks": {"detector": "aruco"}}, "blocks.detector"),
    ({"preset": "falanga2017", "blocks": {"detector": "sdu"}}, "blocks.detector"),
    ({"preset": "falanga2017", "blocks": {"pad": "apriltag"}}, "blocks.detector"),
    ({"preset": "kim_kaist", "camera": {"color": False}}, "blocks.detector"),
    ({"preset": "kim_kaist", "blocks": {"geolocator": "pnp"}}, "blocks.geolocator"),
    ({"preset": "kim_kaist", "blocks": {"geolocator": "homography"}}, "blocks.geolocator"),
    ({"preset": "falanga2017", "blocks": {"camera": "fisheye"}}, "blocks.geolocator"),
    ({"preset": "falanga2017", "blocks": {"geolocator": "direct"}}, "blocks.geolocator"),
    ({"preset": "groundtruth", "blocks": {"geolocator": "pnp"}}, "blocks.geolocator"),
    ({"preset": "groundtruth", "blocks": {"platform_estimator": "kim_ukf"}}, "blocks.platform_estimator"),
    ({"preset": "zamanakos_sdu", "blocks": {"geolocator": "pnp"}}, "blocks.geolocator"),
    ({"preset": "kim_kaist", "estimator": {"use_turn_rate": False}}, "estimator.use_turn_rate"),
    ({"preset": "zamanakos_sdu", "estimator": {"heading_noise": 0.2}}, "estimator.heading_noise"),
    ({"preset": "zamanakos_sdu", "controller": {"position_bandwidth_rad_s": 1.0}}, "controller"),
    ({"preset": "falanga2017", "controller": {"integral_gain": 100.0}}, "controller"),
    (
        {"preset": "falanga2017", "blocks": {"detector": {"name": "falanga", "bogus": 1}}},
        "blocks.detector.bogus",
    ),
    ({"preset": "falanga2017", "blocks": {"detector": {"min_pattern_corr": "high"}}}, "blocks.detector"),
    (
        {"preset": "falanga2017", "blocks": {"planner": {"horizon_max_s": "long"}}},
        "blocks.planner.horizon_max_s",
    ),
    (
        {"preset": "falanga2017", "blocks": {"planner": {"horizon_min_s": 4.0, "horizon_max_s": 2.0}}},
        "blocks.planner",
    ),
    ({"preset": "falanga2017", "blocks": {"planner": {"end_acceleration": "zero"}}}, "blocks.planner"),
    ({"preset": "falanga2017", "blocks": {"planner": {"n_candidates": 0}}}, "blocks.planner"),
    ({"preset": "falanga2017", "blocks": {"geolocator": {"sigma_px": -1.0}}}, "blocks.geolocator"),
    ({"preset": "falanga2017", "blocks": {"geolocator": {"yaw_folds": 4}}}, "blocks.geolocator.yaw_folds"),
    (
        {"preset": "falanga2017", "blocks": {"platform_estimator": {"gate_probability": 1.5}}},
        "blocks.platform_estimator",
    ),
    (
        {"preset": "kim_kaist", "blocks": {"platform_estimator": {"sigma_points": "julier"}}},
        "blocks.platform_estimator",
    ),
    (
        {"preset": "kim_kaist", "blocks": {"platform_estimator": {"turn": {"cutoff": 1}}}},
        "blocks.platform_estimator.turn",
    ),
    ({"preset": "kim_kaist", "blocks": {"camera": {"fov_deg": 400.0}}}, "blocks.camera"),
    (
        {"preset": "kim_kaist", "blocks": {"camera": {"calibration": "/no/such/calib_results.txt"}}},
        "blocks.camera",
    ),
    ({"preset": "falanga2017", "camera": {"calibration": "/no/such/camera.yaml"}}, "blocks.camera"),
    ({"preset": "falanga2017", "blocks": {"pad": {"size_m": -1.0}}}, "blocks.pad"),
    (
        {"preset": "falanga2017", "blocks": {"controller": {"position_bandwidth_rad_s": float("nan")}}},
        "blocks.controller",
    ),
    ({"preset": "zamanakos_sdu", "blocks": {"detector": {"qos": "yes"}}}, "blocks.detector.qos"),
    ({"preset": "falanga2017", "blocks": {"camera": 1.5}}, "blocks.camera"),
    ({"preset": "falanga2017", "blocks": {"lens": "pinhole"}}, "blocks.lens"),
    ({"preset": "paper000"}, "preset"),
]


def _write(tmp_path: Path, data: dict[str, Any], name: str = "s.yaml") -> Path:
    p = tmp_path / name
    p.write_text(yaml.safe_dump(data), encoding="utf-8")
    return p


def test_there_are_at_least_30_wrong_choices() -> None:
    assert len(WRONG) >= 30


@pytest.mark.parametrize(("data", "key"), WRONG, ids=[f"{i:02d}-{k}" for i, (_, k) in enumerate(WRONG)])
def test_a_wrong_block_choice_is_one_line_and_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], data: dict[str, Any], key: str
) -> None:
    path = _write(tmp_path, data)
    # --print-config: a choice wrongly accepted returns 0 at once instead of flying a mission
    assert main(["fly", str(path), "--print-config"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("alight fly: "), err
    assert f"{key}" in err, err
    assert "Traceback" not in err


def test_every_packaged_preset_names_a_known_block_for_every_stage() -> None:
    assert set(preset_names()) == {"alight", "falanga2017", "groundtruth", "kim_kaist", "zamanakos_sdu"}
    for name in preset_names():
        blocks = preset_data(name)["blocks"]
        assert set(blocks) == set(STAGES), name
        eff = resolve_blocks(scenario_from_dict({"preset": name}))
        for stage in STAGES:
            assert eff[stage].name in BLOCKS[stage]


def _flown(scenario: dict[str, Any]) -> Any:
    """The pipeline the scenario flies (its mission config and guidance config)."""
    s = scenario_from_dict(scenario)
    p = build_preset(s, DEFAULT_AIRFRAME, np.random.default_rng(0)).pipeline
    return p.mission.config, p.guidance.config


def test_a_presets_mission_section_sets_the_mission_defaults_and_the_scenario_overrides_them() -> None:
    # the alight preset carries the opt-in mission keys as its defaults
    m, g = _flown({"preset": "alight"})
    assert (g.intercept, g.adaptive_horizon, g.no_feasible) == (True, True, "extend")
    assert g.max_platform_speed_mps == preset_data("alight")["mission"]["max_platform_speed_mps"]
    assert m.touchdown.level_to == "steady" and m.touchdown.max_vertical_speed_mps == 0.5
    # a scenario's key wins over the preset's, key by key (the touchdown section too)
    m, g = _flown(
        {
            "preset": "alight",
            "mission": {"intercept": False, "no_feasible": "keep", "touchdown": {"level_to": "vertical"}},
        }
    )
    assert (g.intercept, g.adaptive_horizon, g.no_feasible) == (False, True, "keep")
    assert m.touchdown.level_to == "vertical" and m.touchdown.max_vertical_speed_mps == 0.5
    # the paper presets set none of them: the blocks' defaults, as before
    for name in ("falanga2017", "groundtruth", "kim_kaist", "zamanakos_sdu"):
        m, g = _flown({"preset": name})
        assert (g.intercept, g.adaptive_horizon, g.no_feasible) == (False, False, "keep"), name
        assert g.max_platform_speed_mps is None and m.touchdown.level_to == "vertical", name
    assert _flown({"preset": "kim_kaist"})[0].land_speed_mps == 0.1


@pytest.mark.parametrize(
    ("mission", "key"),
    [
        ({"aim_camera": False}, "mission.aim_camera"),  # a key whose scenario default is not None
        ({"bogus": 1}, "mission.bogus"),
        ({"no_feasible": "retry"}, "mission.no_feasible"),
        ({"touchdown": {"level_to": "sideways"}}, "mission.touchdown.level_to"),
        ({"coverage_fov_deg": "wide"}, "mission.coverage_fov_deg"),
    ],
)
def test_a_bad_preset_mission_section_is_refused_naming_the_key(
    monkeypatch: pytest.MonkeyPatch, mission: dict[str, Any], key: str
) -> None:
    from alight.mission import blocks
    from alight.scenario import preset_mission_defaults

    monkeypatch.setattr(blocks, "preset_data", lambda name: {"blocks": {}, "mission": mission})
    with pytest.raises(ValueError, match=rf"^preset broken: {key}"):
        preset_mission_defaults.__wrapped__("broken")


def test_scenario_blocks_override_the_presets_and_keep_their_parameters() -> None:
    s = scenario_from_dict({"preset": "falanga2017", "blocks": {"geolocator": {"sigma_px": 2.0}}})
    g = resolve_blocks(s)["geolocator"]
    assert g.name == "pnp" and g.params.sigma_px == 2.0 and g.params.yaw_fold == 4  # the preset's
    s = scenario_from_dict({"preset": "falanga2017", "blocks": {"geolocator": "flat_earth"}})
    g = resolve_blocks(s)["geolocator"]
    assert g.name == "flat_earth" and g.params.deck_height_m == s.platform.pad_height_m
    s = scenario_from_dict({"preset": "kim_kaist", "controller": {"l1_adaptive": False}})
    assert resolve_blocks(s)["controller"].name == "faessler"


def test_the_estimator_section_acts_on_every_estimator_that_has_the_key() -> None:
    ekf = resolve_blocks(scenario_from_dict({"preset": "falanga2017", "estimator": {"accel_noise": 0.3}}))
    ukf = resolve_blocks(scenario_from_dict({"preset": "kim_kaist", "estimator": {"accel_noise": 0.3}}))
    assert ekf["platform_estimator"].params.accel_noise == 0.3
    assert ukf["platform_estimator"].params.accel_noise == 0.3
    # and the defaults missions fly are the block's
    base = resolve_blocks(scenario_from_dict({"preset": "falanga2017"}))["platform_estimator"].params
    assert base.use_turn_rate is True and base.accel_noise == 0.1 and base.init_max_span == 4.0
    planner = resolve_blocks(scenario_from_dict({"preset": "falanga2017"}))["planner"].params
    assert planner.horizon_max_s == 3.0


def test_kim_ukf_flies_behind_a_pinhole_camera_through_its_projection() -> None:
    s = scenario_from_dict({"preset": "falanga2017", "blocks": {"platform_estimator": "kim_ukf"}})
    preset = build_preset(s, DEFAULT_AIRFRAME, np.random.default_rng(0))
    ukf = preset.pipeline.platform_estimator
    assert ukf.config.measurement_model == "camera"  # type: ignore[attr-defined]
    assert ukf.camera is preset.camera  # type: ignore[attr-defined]
    kim = build_preset(
        scenario_from_dict({"preset": "kim_kaist"}), DEFAULT_AIRFRAME, np.random.default_rng(0)
    )
    assert kim.pipeline.platform_estimator.config.measurement_model == "quartic"  # type: ignore[attr-defined]


def test_print_config_prints_the_effective_blocks(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _write(tmp_path, {"preset": "zamanakos_sdu", "blocks": {"controller": {"integral_gain": 1.0}}})
    assert main(["fly", str(path), "--print-config"]) == 0
    out = yaml.safe_load(capsys.readouterr().out)
    assert out["blocks"]["controller"] == {
        "name": "faessler",
        "position_bandwidth_rad_s": 3.0,
        "integral_gain": 1.0,
        "integral_limit_mps2": 6.0,
    }
    assert out["blocks"]["detector"]["name"] == "sdu" and out["blocks"]["detector"]["qos"] is True


def test_alight_blocks_lists_every_block_with_its_parameters(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["blocks"]) == 0
    out = capsys.readouterr().out
    for stage in STAGES:
        assert f"{stage}:" in out
        for name in BLOCKS[stage]:
            assert f"  {name}: " in out
    assert "horizon_max_s = 3.0" in out and "works with: pad in ['red_target']" in out


def test_a_campaign_sweeps_blocks_and_named_block_sets(tmp_path: Path) -> None:
    from alight.campaign.spec import load_campaign

    path = _write(
        tmp_path,
        {
            "name": "blocks_sweep",
            "base": {"preset": "falanga2017"},
            "presets": [
                "falanga2017",
                {"name": "apriltag_pnp", "blocks": {"pad": "apriltag", "detector": "aruco"}},
            ],
            "grid": {"blocks.planner": [{"horizon_max_s": 3.0}, {"horizon_max_s": 4.0}]},
        },
        "c.yaml",
    )
    c = load_campaign(path)
    assert c.presets == ["falanga2017", "apriltag_pnp"]
    by_id = {m.mission_id: m for m in c.missions}
    plain, aruco = by_id["c001-falanga2017-r000"], by_id["c001-apriltag_pnp-r000"]
    assert plain.scenario["blocks"]["detector"] is None and aruco.scenario["blocks"]["detector"] == "aruco"
    assert aruco.scenario["preset"] == "falanga2017" and aruco.seed == plain.seed  # paired, like presets
    assert aruco.scenario["blocks"]["planner"] == {"horizon_max_s": 4.0}
    bad = _write(
        tmp_path, {"name": "bad", "presets": [{"name": "x", "blocks": {"detector": "red"}}]}, "b.yaml"
    )
    from alight.errors import ConfigError

    with pytest.raises(ConfigError, match=r"preset x: blocks.detector: detector 'red' needs pad"):
        load_campaign(bad)


def test_the_pad_centre_pixel_of_pad_points_is_their_homography_image_of_the_centre() -> None:
    from alight.perception.geolocation import pad_centre_pixel
    from alight.types import Observation

    P = np.array([[0.5, 0.5, 0], [-0.5, 0.5, 0], [-0.5, -0.5, 0], [0.5, -0.5, 0], [0.2, 0.1, 0]])
    H = np.array([[300.0, 20, 370], [-10, 310, 240], [0.01, 0.02, 1]])
    q = (H @ np.c_[P[:, :2], np.ones(5)].T).T
    obs = Observation(0.0, "quad", 1.0, q[:, :2] / q[:, 2:], P)
    np.testing.assert_allclose(pad_centre_pixel(obs), H[:2, 2] / H[2, 2], atol=1e-9)
    assert np.array_equal(pad_centre_pixel(Observation(0.0, "blob", 1.0, [[3.0, 4.0]])), [3.0, 4.0])
