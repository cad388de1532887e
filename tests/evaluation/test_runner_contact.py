"""The runner's contact bookkeeping with the onboard touchdown: nothing outside the pipeline stops the
motors, a lift-off after the first contact is counted, and the outcome waits for the vehicle to settle."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

import alight
from alight.evaluation.runner import run_mission
from alight.mission.touchdown_detector import TouchdownDetector, TouchdownState
from alight.scenario import scenario_from_dict
from alight.types import Command

SRC = Path(alight.__file__).parent
BASE = {
    "preset": "groundtruth",
    "seed": 1,
    "duration_s": 60.0,
    "platform": {"path": "straight", "speed_mps": 1.2, "start_xy": [-6.0, 2.0], "heading_rad": 0.0},
}


def test_nothing_in_the_simulator_or_the_runner_switches_the_motors_off() -> None:
    # the only writer of the motors' state into the physics is the pipeline's command
    for package in ("sim", "evaluation"):
        for path in (SRC / package).rglob("*.py"):
            text = path.read_text()
            assert not re.search(r"motors_on\s*=\s*False", text), path
            assert "IN_MOTORS_ON] = 0" not in text, path
    # the world writes what it is commanded, and the runner commands only what the pipeline says
    world = (SRC / "sim" / "world.py").read_text()
    assert world.count("inputs[IN_MOTORS_ON] =") == 1
    assert "inputs[IN_MOTORS_ON] = 1.0 if motors_on else 0.0" in world
    runner = (SRC / "evaluation" / "runner.py").read_text()
    assert runner.count("world.set_command(") == 1
    assert "world.set_command(self.thrust_N, self.w_cmd, not cmd.motors_off)" in runner


@pytest.mark.slow
def test_thrust_kept_after_contact_lifts_off_and_the_bounce_is_counted(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A faulty touchdown: on the first ground contact the vehicle commands 1.3 hover thrust for 0.4 s
    (as a vehicle without a land detector would keep flying its descent reference) and lifts off."""
    original = TouchdownDetector.command
    kick: dict[str, float] = {}

    def faulty(self: TouchdownDetector, t: float, ego, target, range_raw_m, cmd: Command) -> Command:  # type: ignore[no-untyped-def]
        if self.state is TouchdownState.GROUND_CONTACT and "t" not in kick:
            kick["t"] = t
        if "t" in kick and t - kick["t"] < 0.4:
            self.reset()
            return Command(t, 1.3 * 9.81, cmd.w_WB_B_cmd)
        return original(self, t, ego, target, range_raw_m, cmd)

    monkeypatch.setattr(TouchdownDetector, "command", faulty)
    r = run_mission(scenario_from_dict(BASE), record=False).result
    assert "t" in kick
    assert r["bounces"] >= 1
    assert r["time_first_contact_s"] < kick["t"] < r["time_touchdown_onboard_s"]
    assert r["outcome"] in ("landed", "crashed")  # judged after it came down again and settled


@pytest.mark.slow
def test_the_outcome_waits_for_the_settling_time() -> None:
    r = run_mission(scenario_from_dict({**BASE, "contact": {"settle_s": 3.5}}), record=False).result
    assert r["outcome"] == "landed" and r["outcome_reason"] == ""
    assert r["simulated_time_s"] == pytest.approx(r["time_motors_off_s"] + 3.5, abs=0.01)
