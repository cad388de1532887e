"""tools/paper_table.py on a small synthetic campaign output: counts, the Wilson interval against its
closed form, the labels from the flown scenario and the endings of the missions that did not land."""

from __future__ import annotations

import json
import math
from pathlib import Path
from types import ModuleType

import pytest
from tool_loader import load_tool

ROOT = Path(__file__).resolve().parents[2]


def _tool() -> ModuleType:
    return load_tool("paper_table")


def _wilson(k: int, n: int, z: float = 1.959963984540054) -> tuple[float, float]:
    """Wilson (1927), written out: (p + z^2/2n -+ z sqrt(p(1-p)/n + z^2/4n^2)) / (1 + z^2/n)."""
    p = k / n
    centre = p + z * z / (2 * n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    return (centre - half) / (1 + z * z / n), (centre + half) / (1 + z * z / n)


def _scenario(speed: float, wind: str = "none") -> dict[str, object]:
    return {
        "platform": {"path": "straight", "speed_mps": speed},
        "wind": {"model": wind, "gust_power_N": 7.76},
        "search_area": {"x_min": -62.0, "x_max": 462.0, "y_min": -20.0, "y_max": 20.0},
    }


def _campaign(tmp_path: Path) -> Path:
    """Cell c000: 17 of 20 landed (2 time-outs without a detection, 1 abort); cell c001: 20 of 20."""
    rows = ["mission_id,condition_id,preset,replicate,seed,platform.speed_mps,outcome,success,mission_dir"]
    for cid, speed, wind, bad in (("c000", 4.2, "none", {3: "timeout", 7: "timeout", 11: "aborted"}),
                                  ("c001", 1.5, "gust", {})):  # fmt: skip
        for r in range(20):
            mid = f"{cid}-falanga2017-r{r:03d}"
            outcome = bad.get(r, "landed")
            landed = int(outcome == "landed")
            rows.append(f"{mid},{cid},falanga2017,{r},{1000 + r},{speed},{outcome},{landed},missions/{mid}")
            result = {"outcome": outcome, "scenario": _scenario(speed, wind), "final_mode": "explore",
                      "detections": 0 if outcome == "timeout" else 40,
                      "abort_reason": "target lost" if outcome == "aborted" else None}  # fmt: skip
            (tmp_path / "missions" / mid).mkdir(parents=True)
            (tmp_path / "missions" / mid / "result.json").write_text(json.dumps(result), encoding="utf-8")
    (tmp_path / "results.csv").write_text("\n".join(rows) + "\n", encoding="utf-8")
    lock = {"campaign": "synthetic", "campaign_seed": 41}
    (tmp_path / "campaign.lock.json").write_text(json.dumps(lock), encoding="utf-8")
    return tmp_path


def test_counts_wilson_interval_labels_and_endings(tmp_path: Path) -> None:
    tool = _tool()
    rows = tool.cell_rows(_campaign(tmp_path))
    assert [(r["condition"], r["landed"], r["n"]) for r in rows] == [("c000", 17, 20), ("c001", 20, 20)]
    for row in rows:
        lo, hi = _wilson(row["landed"], row["n"])
        assert row["ci"][0] == pytest.approx(lo, abs=1e-12)
        assert row["ci"][1] == pytest.approx(hi, abs=1e-12)
    # 20/20: the upper bound is 1 and the lower one n / (n + z^2) exactly
    assert rows[1]["ci"][1] == pytest.approx(1.0, abs=1e-12)
    assert rows[1]["ci"][0] == pytest.approx(20 / (20 + 1.959963984540054**2), abs=1e-12)
    assert rows[0]["label"] == "straight 4.2 m/s, area 40 x 524 m"
    assert rows[1]["label"] == "straight 1.5 m/s, gusts 7.76 N, area 40 x 524 m"
    assert rows[0]["endings"] == {"timeout in explore, 0 detections": 2, "aborted: target lost": 1}


def test_rendered_table_marks_the_bar_and_writes_the_file(tmp_path: Path) -> None:
    tool = _tool()
    run = _campaign(tmp_path / "run")
    out = tmp_path / "paper_conditions.md"
    assert tool.main([str(run), "--out", str(out)]) == 0
    text = out.read_text(encoding="utf-8")
    assert "| `falanga2017` | straight 4.2 m/s, area 40 x 524 m | 17/20 | 85 % | 64-95 % | **no** |" in text
    assert "| 20/20 | 100 % | 84-100 % | yes |" in text
    assert "campaign seed 41, " in text
    assert "--note" not in text
    assert tool.main([str(run), "--note", "Measured: why.", "--out", str(out)]) == 0
    text = out.read_text(encoding="utf-8")
    assert "--note TEXT ...  (one per paragraph after this introduction)" in text
    assert "\n\nMeasured: why.\n\n## " in text


def test_bad_arguments_are_refused_with_a_message(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    tool = _tool()
    assert tool.main([]) == 2
    assert tool.main([str(tmp_path)]) == 2
    assert "no such file" in capsys.readouterr().err


def test_labels_name_a_circle_centre_and_the_heading_to_the_gust() -> None:
    tool = _tool()
    circle = {"platform": {"path": "circle", "speed_mps": 4.2, "start_xy": [10.0, 0.0], "heading_rad": 0.0,
                           "circle_radius_m": 10.0}}  # fmt: skip
    assert tool.cell_label(circle) == "circle 4.2 m/s, centre (10, 10) m"
    # the model's default circle (start (10, 0) heading +y) is centred on the take-off point
    circle["platform"]["heading_rad"] = math.pi / 2
    assert tool.cell_label(circle) == "circle 4.2 m/s, centre (0, 0) m"
    # paper 004's force is -(0.8, 0.2) power: the wind comes from atan2(0.2, 0.8) = 14.04 deg
    from_deg = math.degrees(math.atan2(0.2, 0.8))
    for heading_deg, way, off_deg in ((0, "upwind", from_deg), (90, "across the wind", 90 - from_deg),
                                      (180, "downwind", 180 - from_deg)):  # fmt: skip
        s = _scenario(1.5, "gust")
        s["platform"]["heading_rad"] = math.radians(heading_deg)  # type: ignore[index]
        wind = f"gusts 7.76 N, heading {heading_deg} deg ({way}, {off_deg:.0f} deg off upwind)"
        assert tool.cell_label(s) == f"straight 1.5 m/s, {wind}, area 40 x 524 m"
