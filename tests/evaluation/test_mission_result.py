"""MissionResult is the one list of the results.csv result columns; every mission directory has a
scenario.yaml that flies the mission again."""

from __future__ import annotations

import json
import re
from pathlib import Path

import yaml

from alight.campaign.store import NUMERIC_COLUMNS, RESULT_COLUMNS, write_mission_dir
from alight.cli import main
from alight.evaluation.result import SCENARIO_YAML, MissionResult
from alight.scenario import load_scenario, scenario_from_dict

ROOT = Path(__file__).resolve().parents[2]


def test_results_csv_columns_come_from_mission_result() -> None:
    assert RESULT_COLUMNS == (*MissionResult.columns(), "mission_dir", "error")
    assert set(NUMERIC_COLUMNS) <= set(MissionResult.columns())


def test_docs_campaigns_lists_the_mission_result_columns_in_order() -> None:
    text = (ROOT / "docs" / "campaigns.md").read_text(encoding="utf-8")
    para = text[text.index("`results.csv` columns, in order") :]
    para = para[: para.index("Missing values")]
    tokens = re.findall(r"`([^`]*)`", para, re.S)
    documented = [n.strip() for tok in tokens for n in tok.replace("\n", " ").split(",")]
    wanted = ["mission_id", "condition_id", "preset", "replicate", "seed", *RESULT_COLUMNS]
    assert [c for c in documented if c in wanted] == wanted


def _fly(tmp_path: Path, name: str, scenario: Path) -> dict[str, object]:
    out = tmp_path / name
    assert main(["fly", str(scenario), "--out", str(out)]) == 0
    result: dict[str, object] = json.loads((out / "result.json").read_text(encoding="utf-8"))
    return result


def test_a_mission_directory_flies_again_from_its_scenario_yaml(tmp_path: Path) -> None:
    src = tmp_path / "s.yaml"
    src.write_text(
        yaml.safe_dump(
            {"preset": "groundtruth", "seed": 3, "duration_s": 25.0, "platform": {"path": "circle"}}
        ),
        encoding="utf-8",
    )
    first = _fly(tmp_path, "a", src)
    again = _fly(tmp_path, "b", tmp_path / "a" / SCENARIO_YAML)
    a, b = MissionResult.from_result(first), MissionResult.from_result(again)
    for column in MissionResult.columns():
        if column.endswith("_time_s") and column != "simulated_time_s":
            continue  # wall clocks
        assert a.row()[column] == b.row()[column], column
    assert load_scenario(tmp_path / "b" / SCENARIO_YAML) == load_scenario(tmp_path / "a" / SCENARIO_YAML)


def test_a_campaign_mission_directory_has_its_scenario(tmp_path: Path) -> None:
    scenario = scenario_from_dict({"preset": "falanga2017", "seed": 7, "blocks": {"detector": "falanga"}})
    result = {"scenario": scenario.model_dump(mode="json"), "outcome": "timeout", "success": False}
    rel = write_mission_dir(tmp_path, "c000-falanga2017-r000", result)
    assert load_scenario(tmp_path / rel / SCENARIO_YAML) == scenario
