"""Closed loop, the ``alight`` preset (issue 16): this project's own composition lands with vision (the
rendered camera, the tag detector, PnP) on a circle, on a fast straight-line platform with its telemetry,
and in paper 004's strongest gusts; and the envelope campaign flies no seed that these regression
missions use."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import pytest

from alight.evaluation.runner import run_mission
from alight.scenario import scenario_from_dict

ROOT = Path(__file__).resolve().parents[2]
TELEMETRY = {"rate_hz": 10, "noise_m": 0.5, "bias_m": 1.0, "latency_s": 0.2, "dropout_prob": 0.05}

# (what, scenario keys, seed): seeds picked once and frozen
CONDITIONS: list[tuple[str, dict[str, Any], int]] = [
    ("circle 2 m/s", {"platform": {"path": "circle", "speed_mps": 2.0}}, 1),
    (
        "straight 9 m/s with telemetry",
        {"platform": {"path": "straight", "speed_mps": 9.0, "telemetry": TELEMETRY}},
        2,
    ),
    (
        "gusts 7.76 N, straight 1.5 m/s",
        {"platform": {"path": "straight", "speed_mps": 1.5}, "wind": {"model": "gust", "gust_power_N": 7.76}},
        3,
    ),
]
BRAKE = {
    "path": "straight",
    "speed_mps": 6.0,
    "telemetry": TELEMETRY,
    "speed_profile": {"brake_stop": {"t_s": 12.0, "decel_mps2": 6.0, "wait_s": 3.0, "accel_mps2": 2.0}},
}
BRAKE_SEED = 998340792  # the envelope's brake on a held-out seed set (campaign seed 3000), replicate 21
CI_SEEDS = {1, 2, 3, 4, 5, 11, 12, 576602530, BRAKE_SEED}
"""Seeds the closed-loop regression missions of tests/integration fly."""


@pytest.mark.parametrize(("what", "keys", "seed"), CONDITIONS, ids=[c[0] for c in CONDITIONS])
def test_alight_lands_with_vision(what: str, keys: dict[str, Any], seed: int) -> None:
    s = scenario_from_dict({"preset": "alight", "seed": seed, "duration_s": 90, **keys})
    r = run_mission(s, record=False).result
    assert r["outcome"] == "landed", (what, r["outcome_reason"], r["abort_reason"])
    assert r["touchdown_error_m"] < 0.15, what
    assert r["detections"] > 0, what  # it flew on its camera, not on ground truth


def test_optical_flow_catches_a_deck_that_brakes_under_the_committed_descent() -> None:
    """The envelope's brake (6 m/s, 6 m/s^2) under the committed descent: without an optical-flow module
    the feet meet a deck that has slowed (crashed); with one, the deck is measured leaving the estimate
    0.1 s into the brake, the vehicle goes around and lands on the next approach; with the module's
    samples lost across the brake (a flow fault), it crashes as without one.

    The brake is placed 0.4 s before the undisturbed mission's first contact, so that it falls under the
    committed descent whatever the approach's timing (a fixed brake time tested the approach's timing
    too: 0.4 s earlier landings put a brake at 12 s after the contact)."""
    base: dict[str, Any] = {"preset": "alight", "seed": BRAKE_SEED, "duration_s": 120, "platform": BRAKE}
    late = copy.deepcopy(base)
    late["platform"]["speed_profile"]["brake_stop"]["t_s"] = 100.0  # after the landing: undisturbed
    undisturbed = run_mission(scenario_from_dict(late), record=False).result
    assert undisturbed["outcome"] == "landed", undisturbed["outcome_reason"]
    t_brake = float(undisturbed["time_first_contact_s"]) - 0.4
    base["platform"] = copy.deepcopy(BRAKE)
    base["platform"]["speed_profile"]["brake_stop"]["t_s"] = t_brake
    without = run_mission(scenario_from_dict(base), record=False).result
    assert without["outcome"] == "crashed", without["outcome_reason"]
    flown = run_mission(scenario_from_dict({**base, "optical_flow": {}}), record=False).result
    assert flown["outcome"] == "landed", (flown["outcome_reason"], flown["abort_reason"])
    slips = [e for e in flown["failsafe_events"] if e["reason"].startswith("the deck left the estimate")]
    assert len(slips) == 1 and t_brake < slips[0]["t"] < t_brake + 0.3, (t_brake, slips)
    assert flown["touchdown_error_m"] < 0.15
    # a module that sees nothing across the brake (faults.flow_dropouts: a featureless deck) leaves the
    # gate silent: the descent meets the brake as without a module
    blind = {**base, "optical_flow": {}, "faults": {"flow_dropouts": [[t_brake - 0.5, t_brake + 2.0]]}}
    dark = run_mission(scenario_from_dict(blind), record=False).result
    assert not [e for e in dark["failsafe_events"] if e["reason"].startswith("the deck left the estimate")]
    assert dark["outcome"] == "crashed", dark["outcome_reason"]
    assert dark["time_first_contact_s"] == without["time_first_contact_s"]


def test_the_envelope_campaign_flies_no_seed_of_the_regression_missions() -> None:
    from alight.campaign.spec import load_campaign

    campaign = load_campaign(ROOT / "examples" / "campaigns" / "envelope.yaml")
    seeds = {m.seed for m in campaign.missions}
    assert len(seeds) == 11 * 20 and not seeds & CI_SEEDS  # every preset flies the same seeds
    assert {m.preset for m in campaign.missions} == {"alight", "falanga2017", "kim_kaist", "zamanakos_sdu"}
