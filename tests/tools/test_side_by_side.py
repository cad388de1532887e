"""tools/side_by_side.py on two small synthetic runs of one campaign: the counts and Wilson interval per
condition and run, the median error of the landed missions, the others' endings, and a condition that
one run did not fly."""

from __future__ import annotations

from pathlib import Path
from types import ModuleType
from typing import Any

from tool_loader import load_tool

from alight.campaign import campaign_from_dict, run_campaign, wilson95

ROOT = Path(__file__).resolve().parents[2]


def _tool() -> ModuleType:
    return load_tool("side_by_side")


def lands_below_2_mps(scenario: Any, out_dir: Path) -> dict[str, Any]:
    """Landed 0.1 m from the centre on the slow platform, a timeout on the fast one."""
    landed = scenario.platform.speed_mps < 2.0
    return {"outcome": "landed" if landed else "timeout", "success": landed, "seed": scenario.seed,
            "preset": scenario.preset, "touchdown_error_m": 0.1 if landed else None,
            "touchdown_rel_horizontal_speed_mps": 0.05 if landed else None}  # fmt: skip


def _campaign(conditions: list[dict[str, Any]]) -> Any:
    return campaign_from_dict({"name": "sbs", "base": {"duration_s": 10.0}, "presets": ["groundtruth"],
                               "seeds_per_condition": 4, "seed": 9, "conditions": conditions})  # fmt: skip


def test_side_by_side_counts_each_condition_of_each_run(tmp_path: Path) -> None:
    slow = {"name": "slow", "platform.speed_mps": 1.0}
    fast = {"name": "fast", "platform.speed_mps": 3.0}
    run_campaign(
        _campaign([slow, fast]), tmp_path / "a", workers=1, mission_fn=lands_below_2_mps, report=False
    )
    run_campaign(_campaign([slow]), tmp_path / "b", workers=1, mission_fn=lands_below_2_mps, report=False)
    text = _tool().table([(tmp_path / "a", "A"), (tmp_path / "b", "B")])
    lines = text.splitlines()
    assert lines[0].startswith("| condition | A: landed") and "| B: landed" in lines[0]
    lo, hi = wilson95(4, 4) or (0.0, 0.0)
    slow_row = next(line for line in lines if line.startswith("| slow |"))
    fast_row = next(line for line in lines if line.startswith("| fast |"))
    assert slow_row.count(f"4/4 ({100 * lo:.0f}-{100 * hi:.0f} %) | 0.10 | 0.05 | -") == 2
    lo0, hi0 = wilson95(0, 4) or (0.0, 0.0)
    assert f"0/4 ({100 * lo0:.0f}-{100 * hi0:.0f} %) | - | - | 4 timeout" in fast_row
    assert fast_row.endswith("| - | - | - | - |")  # B did not fly it
