"""Which presets a warm-up flies for scenarios that change their preset's blocks (issue 18, item 3): a
campaign's block set is a label, not a preset; its sandboxes warm up the presets that fly its blocks."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

import alight.campaign.run as campaign_run
from alight.campaign.spec import campaign_from_dict, load_campaign
from alight.compile.warmup import presets_to_warm_up

ROOT = Path(__file__).parents[1]


def test_a_preset_alone_is_warmed_up_as_itself() -> None:
    assert presets_to_warm_up([{"preset": "falanga2017"}]) == ("falanga2017",)
    assert presets_to_warm_up([{"preset": "kim_kaist"}, {"preset": "kim_kaist", "seed": 3}]) == ("kim_kaist",)


def test_a_changed_block_brings_a_preset_that_flies_it() -> None:
    # falanga2017 with paper 003's UKF: kim_kaist is the preset whose flight calls the UKF's kernels
    ukf = {"preset": "falanga2017", "blocks": {"platform_estimator": "kim_ukf"}}
    assert presets_to_warm_up([ukf]) == ("falanga2017", "kim_kaist")
    # paper 004's geolocator and filter come with zamanakos_sdu, once
    sdu = {"preset": "falanga2017", "blocks": {"geolocator": "homography", "platform_estimator": "sdu_kf"}}
    assert presets_to_warm_up([sdu]) == ("falanga2017", "zamanakos_sdu")


def test_a_block_that_a_chosen_preset_flies_adds_nothing() -> None:
    ukf = {"preset": "falanga2017", "blocks": {"platform_estimator": "kim_ukf"}}
    assert presets_to_warm_up([{"preset": "kim_kaist"}, ukf]) == ("kim_kaist", "falanga2017")
    # a parameter of the preset's own block is the same block
    gain = {"preset": "falanga2017", "blocks": {"controller": {"integral_gain": 1.0}}}
    assert presets_to_warm_up([gain]) == ("falanga2017",)


def test_a_block_no_preset_flies_is_left_to_its_missions() -> None:
    # OpenCV's ArUco detector on an AprilTag pad: no preset has them (and they have no numba kernels)
    tag = {"preset": "falanga2017", "blocks": {"pad": "apriltag", "detector": "aruco"}}
    assert presets_to_warm_up([tag]) == ("falanga2017",)


def test_a_scenario_that_does_not_validate_is_left_out() -> None:
    assert presets_to_warm_up([{"preset": "no_such_preset"}, {"preset": "groundtruth"}]) == ("groundtruth",)
    assert presets_to_warm_up([{"preset": "falanga2017", "blocks": {"detector": "nope"}}]) == ()


def test_blocks_yaml_warms_up_presets_not_its_labels() -> None:
    campaign = load_campaign(ROOT / "examples" / "campaigns" / "blocks.yaml")
    assert all("-" in label for label in campaign.presets)  # every label is a composition, none a preset
    chosen = presets_to_warm_up(m.scenario for m in campaign.missions)
    assert chosen[0] == "falanga2017"  # the compositions' own preset first
    assert set(chosen) == {"falanga2017", "kim_kaist", "zamanakos_sdu", "groundtruth"}


def test_a_campaigns_sandboxes_are_given_presets(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """run_campaign hands its engine the presets that cover its block sets (before, the labels: the
    sandbox's warm-up failed on the first one, 'unknown preset', and warmed up nothing)."""
    seen: list[tuple[str, ...]] = []

    class Stop(Exception):
        pass

    def make_engine(engine: str, *, warmup: tuple[str, ...] = (), **_: Any) -> Any:
        seen.append(tuple(warmup))
        raise Stop

    monkeypatch.setattr(campaign_run, "make_engine", make_engine)
    campaign = campaign_from_dict(
        {
            "name": "mixed",
            "presets": [
                "groundtruth",
                {"name": "tag-ukf", "preset": "falanga2017", "blocks": {"platform_estimator": "kim_ukf"}},
            ],
        }
    )
    with pytest.raises(Stop):
        campaign_run.run_campaign(campaign, tmp_path / "out", report=False)
    assert seen == [("groundtruth", "falanga2017", "kim_kaist")]
