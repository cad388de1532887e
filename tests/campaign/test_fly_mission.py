"""The campaign's own mission function: one flight, recorded; a failure's files written from that flight."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from PIL import Image

from alight.campaign.engines import fly_mission
from alight.evaluation.runner import run_mission
from alight.scenario import scenario_from_dict

_TIMINGS = {"wall_time_s", "block_time_s", "cpu_time_s", "energy_compute_measured_J"}

# falanga2017 with the pad parked ahead of the take-off point: it sees the pad at about 3 s and cannot
# land in 6 s, so the mission times out.
SHORT = {
    "preset": "falanga2017",
    "seed": 3,
    "duration_s": 6.0,
    "platform": {"path": "straight", "speed_mps": 0.0, "start_xy": [1.2, 0.0], "heading_rad": 0.0},
}


def test_a_failure_writes_its_files_from_the_one_flight(tmp_path: Path) -> None:
    s = scenario_from_dict(SHORT)
    result = fly_mission(s, tmp_path)
    assert result["outcome"] == "timeout"
    assert "reflight" not in result
    # the recorded flight is the flight a plain run_mission flies
    plain = run_mission(s, record=True).result
    assert {k: v for k, v in result.items() if k not in _TIMINGS} == {
        k: v for k, v in plain.items() if k not in _TIMINGS
    }
    names = {p.name for p in tmp_path.iterdir()}
    assert {"result.json", "log.npz", "report.html", "replay.gif", "scenario.yaml"} <= names
    written = json.loads((tmp_path / "result.json").read_text())
    assert written["outcome"] == "timeout" and written["seed"] == 3
    with np.load(tmp_path / "log.npz") as log:
        assert log["t"][-1] > 5.5
    with Image.open(tmp_path / "replay.gif") as gif:
        assert gif.n_frames > 40  # 6 s at 10 frames per second of playback
        # the camera panel beside the top view (the top view alone is 520 x 480)
        assert gif.size == (860, 430)


def test_a_landing_writes_nothing(tmp_path: Path) -> None:
    circle = {"path": "circle", "speed_mps": 1.0}
    s = scenario_from_dict({"preset": "groundtruth", "seed": 1, "duration_s": 60.0, "platform": circle})
    result = fly_mission(s, tmp_path)
    assert result["outcome"] == "landed"
    assert list(tmp_path.iterdir()) == []
