"""A campaign's sandboxes warm up what its missions fly: a composition of blocks is warmed up as its preset
with its blocks, not refused as an unknown preset (which left its kernels to compile on the missions'
clocks)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from alight.campaign.run import warmup_flights
from alight.campaign.spec import campaign_from_dict, load_campaign
from alight.errors import ConfigError
from alight.scenario import scenario_from_dict
from alight.warmup import WarmupFlight, warm_up, warmup_scenario

ROOT = Path(__file__).resolve().parents[2]


def test_a_composition_is_warmed_up_as_its_preset_with_its_blocks() -> None:
    campaign = load_campaign(ROOT / "examples" / "campaigns" / "blocks_acceptance.yaml")
    flights = warmup_flights(campaign)
    assert len(flights) == len(campaign.presets)  # one flight per label, each a different composition
    for label, flight in zip(campaign.presets, flights, strict=True):
        first = next(m for m in campaign.missions if m.preset == label)
        assert flight.preset == first.scenario["preset"]
        blocks = json.loads(flight.blocks_json)
        assert blocks == {k: v for k, v in first.scenario["blocks"].items() if v is not None}
        assert blocks  # a composition sets blocks
        # the flight is a scenario the simulator accepts, with those blocks
        flown = scenario_from_dict(warmup_scenario(flight.preset, blocks), "warm-up")
        assert flown.blocks.model_dump(exclude_none=True) == blocks
    # only the labels asked for (the views' second flights warm up the presets they fly)
    assert warmup_flights(campaign, {campaign.presets[1]}) == (flights[1],)


def test_a_named_preset_is_warmed_up_as_itself() -> None:
    campaign = campaign_from_dict(
        {"name": "two", "presets": ["groundtruth", "falanga2017"], "seeds_per_condition": 1, "seed": 1}
    )
    flights = warmup_flights(campaign)
    assert flights == (WarmupFlight("groundtruth"), WarmupFlight("falanga2017"))
    assert [f.label for f in flights] == ["groundtruth", "falanga2017"]


def test_a_label_that_is_no_preset_is_still_refused_in_one_line() -> None:
    # what the sandbox's warm-up did with a composition's label before: its error, not a flight
    with pytest.raises(ConfigError, match="unknown preset 'apriltag-aruco-pnp-ekf'"):
        warm_up(["apriltag-aruco-pnp-ekf"], compile_first=False)
