"""The campaign's own mission functions: one flight, recorded; a failure's files written from that flight,
its views (figures, report.html, replay.gif) only by the views function."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from PIL import Image

from alight.campaign.engines import CLOCK_FIELDS, fly_mission, fly_mission_views
from alight.evaluation.runner import run_mission
from alight.scenario import scenario_from_dict

# falanga2017 with the pad parked ahead of the take-off point: it sees the pad at about 3 s and cannot
# land in 6 s, so the mission times out.
SHORT = {
    "preset": "falanga2017",
    "seed": 3,
    "duration_s": 6.0,
    "platform": {"path": "straight", "speed_mps": 0.0, "start_xy": [1.2, 0.0], "heading_rad": 0.0},
}


def _without_clocks(result: dict) -> dict:
    return {k: v for k, v in result.items() if k not in CLOCK_FIELDS}


def test_a_failure_writes_its_log_and_its_views_are_drawn_from_the_same_flight(tmp_path: Path) -> None:
    s = scenario_from_dict(SHORT)
    sweep, views = tmp_path / "sweep", tmp_path / "views"
    sweep.mkdir()
    views.mkdir()
    result = fly_mission(s, sweep)
    assert result["outcome"] == "timeout"
    # the recorded flight is the flight a plain run_mission flies, and the one the views function flies
    plain = run_mission(s, record=True).result
    assert _without_clocks(result) == _without_clocks(plain)
    assert _without_clocks(fly_mission_views(s, views)) == _without_clocks(plain)
    # two flights differ in their clocks only: CLOCK_FIELDS lists them all
    assert {k for k in result if result[k] != plain[k]} <= CLOCK_FIELDS

    names = {p.name for p in sweep.iterdir()}
    assert {"result.json", "log.npz", "log.csv", "log_detections.csv", "scenario.yaml"} == names
    assert {p.name for p in views.iterdir()} >= names | {"report.html", "replay.gif"}
    with np.load(sweep / "log.npz") as a, np.load(views / "log.npz") as b:
        assert a["t"][-1] > 5.5
        assert set(a.files) == set(b.files)
        for key in a.files:
            np.testing.assert_array_equal(a[key], b[key], err_msg=key)
    written = json.loads((sweep / "result.json").read_text())
    assert written["outcome"] == "timeout" and written["seed"] == 3
    with Image.open(views / "replay.gif") as gif:
        assert gif.n_frames > 40  # 6 s at 10 frames per second of playback
        # the camera panel beside the top view (the top view alone is 520 x 480)
        assert gif.size == (860, 430)


def test_a_landing_writes_nothing(tmp_path: Path) -> None:
    circle = {"path": "circle", "speed_mps": 1.0}
    s = scenario_from_dict({"preset": "groundtruth", "seed": 1, "duration_s": 60.0, "platform": circle})
    result = fly_mission_views(s, tmp_path)
    assert result["outcome"] == "landed"
    assert list(tmp_path.iterdir()) == []
