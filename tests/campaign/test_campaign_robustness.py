"""Campaign files that cannot blow up: expansion is counted before it is made and capped, ``--limit``
expands only what it flies (grid points and sampled draws), and a damaged results.csv cell damages its
row, which is named and left out, never a traceback."""

from __future__ import annotations

import os
from pathlib import Path

import campaign_fakes
import pytest
import yaml

from alight.campaign import campaign_from_dict, run_campaign
from alight.campaign.results import COLUMN, read_cell
from alight.campaign.spec import MAX_MISSIONS, CampaignSpec, count_missions, load_campaign
from alight.campaign.store import read_rows
from alight.cli import MISSION_FN_ENV, main
from alight.errors import ConfigError


def _spec(**over: object) -> dict:
    data: dict = {"name": "robust", "base": {"duration_s": 10.0}, "presets": ["groundtruth", "falanga2017"]}
    data.update(over)
    return data


@pytest.mark.parametrize(
    ("over", "expected"),
    [
        ({}, 2),
        (
            {
                "seeds_per_condition": 3,
                "grid": {"platform.speed_mps": [1.0, 2.0], "wind.gust_power_N": [1, 2, 3]},
            },
            36,
        ),
        ({"grid": {"platform.speed_mps": [1.0]}, "conditions": [{"platform.speed_mps": 2.0}]}, 4),
        ({"sample": {"n": 5, "platform.speed_mps": {"dist": "uniform", "low": 1, "high": 2}}}, 10),
    ],
)
def test_count_matches_the_expansion(over: dict, expected: int) -> None:
    spec = CampaignSpec.model_validate(_spec(**over))
    assert count_missions(spec) == expected == len(campaign_from_dict(_spec(**over)).missions)


@pytest.mark.parametrize(
    "over",
    [
        {"seeds_per_condition": 1_000_000_000},
        {
            "grid": {
                f"platform.{k}": list(range(1, 60)) for k in ("speed_mps", "pad_size_m", "circle_radius_m")
            }
        },
        {"seeds_per_condition": MAX_MISSIONS // 2 + 1},
    ],
    ids=["1e9_seeds", "huge_grid", "just_over"],
)
def test_a_campaign_above_the_cap_is_refused_before_expanding(over: dict) -> None:
    with pytest.raises(ConfigError, match="more than the 100,000 one campaign may hold"):
        campaign_from_dict(_spec(**over))


def test_limit_expands_only_the_first_missions_of_a_huge_campaign(tmp_path: Path) -> None:
    path = tmp_path / "huge.yaml"
    path.write_text(yaml.safe_dump(_spec(seeds_per_condition=10**9, grid={"platform.speed_mps": [1.0, 2.0]})))
    c = load_campaign(path, limit=5)
    assert [m.mission_id for m in c.missions] == [
        "c000-groundtruth-r000",
        "c000-falanga2017-r000",
        "c000-groundtruth-r001",
        "c000-falanga2017-r001",
        "c000-groundtruth-r002",
    ]
    # the same missions, with the same seeds, as the head of the full expansion of a smaller campaign
    small = campaign_from_dict(_spec(seeds_per_condition=3, grid={"platform.speed_mps": [1.0, 2.0]}))
    assert [(m.mission_id, m.seed) for m in c.missions] == [
        (m.mission_id, m.seed) for m in small.missions[:5]
    ]


def test_cli_refuses_a_huge_campaign_with_one_line_and_flies_its_head_with_limit(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "huge.yaml"
    path.write_text(yaml.safe_dump(_spec(seeds_per_condition=10**9)))
    assert main(["campaign", str(path), "--out", str(tmp_path / "o"), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "2,000,000,000 missions" in err and "huge.yaml" in err
    monkeypatch.setenv(MISSION_FN_ENV, "campaign_fakes:instant")
    # the engine's worker processes import the fake by name
    here = str(Path(__file__).resolve().parent)
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join(p for p in (here, os.environ.get("PYTHONPATH")) if p))
    out = tmp_path / "o2"
    assert (
        main(["campaign", str(path), "--out", str(out), "--workers", "1", "--limit", "3", "--no-progress"])
        == 0
    )
    assert len(read_rows(out / "results.csv")) == 3


@pytest.mark.parametrize("text", ["abc", "1e", "--", "None", "nan", "inf", "-1", "1e308", "1" * 10**6])
def test_a_numeric_cell_that_is_not_a_plausible_number_is_damage(text: str) -> None:
    value, problem = read_cell(COLUMN["wall_time_s"], text)
    assert value is None and problem is not None and problem.startswith("wall_time_s: ")
    assert len(problem) < 200  # a 1 MB cell is named by its head and its length
    assert read_cell(COLUMN["wall_time_s"], "") == (None, None)  # empty: no value, no damage
    assert read_cell(COLUMN["wall_time_s"], "2.5") == (2.5, None)


def test_damaged_cells_do_not_stop_the_report_or_the_resume(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    campaign = campaign_from_dict(_spec(seeds_per_condition=2))
    run_campaign(campaign, tmp_path, workers=1, limit=3, mission_fn=campaign_fakes.instant, report=False)
    results = tmp_path / "results.csv"
    lines = results.read_text(encoding="utf-8").splitlines()
    header = lines[0].split(",")
    damaged = []
    for line in lines[1:]:
        cells = line.split(",")
        for column in ("touchdown_error_m", "wall_time_s", "simulated_time_s", "time_to_land_s"):
            if column in header:
                cells[header.index(column)] = "garbage"
        damaged.append(",".join(cells))
    results.write_text("\n".join([lines[0], *damaged]) + "\n", encoding="utf-8")
    capsys.readouterr()
    assert main(["report", str(tmp_path)]) == 0, capsys.readouterr().err
    # resume: the finished rows stay as they are, the rest is flown
    run_campaign(campaign, tmp_path, workers=1, mission_fn=campaign_fakes.instant, report=False)
    after = results.read_text(encoding="utf-8").splitlines()
    assert after[: 1 + len(damaged)] == [lines[0], *damaged]
    assert len(after) == 1 + len(campaign.missions)


def _sampled(n: int) -> dict:
    return _spec(sample={"n": n, "platform.speed_mps": {"dist": "uniform", "low": 1.0, "high": 2.0}})


def test_limit_draws_only_the_first_conditions_of_a_billion_draws(tmp_path: Path) -> None:
    """``sample.n: 1e9`` with a limit draws the few conditions it flies (it once drew all 1e9 first:
    3.2 GB, then a MemoryError), and they are the full expansion's first draws."""
    import time
    import tracemalloc

    path = tmp_path / "billion.yaml"
    path.write_text(yaml.safe_dump(_sampled(10**9)))
    tracemalloc.start()
    t0 = time.monotonic()
    try:
        c = load_campaign(path, limit=5)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert time.monotonic() - t0 < 20.0 and peak < 50e6
    assert [m.mission_id for m in c.missions] == [
        "c000-groundtruth-r000",
        "c000-falanga2017-r000",
        "c001-groundtruth-r000",
        "c001-falanga2017-r000",
        "c002-groundtruth-r000",
    ]
    assert [cond.condition_id for cond in c.conditions] == ["c000", "c001", "c002"]
    small = campaign_from_dict(_sampled(4))
    assert [(m.mission_id, m.seed, m.params) for m in c.missions] == [
        (m.mission_id, m.seed, m.params) for m in small.missions[:5]
    ]
    with pytest.raises(ConfigError, match="2,000,000,000 missions, more than") as info:
        load_campaign(path)
    assert "\n" not in str(info.value)


def test_cli_flies_one_mission_of_a_billion_draws_and_refuses_them_all(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "billion.yaml"
    path.write_text(yaml.safe_dump({**_sampled(10**9), "presets": ["groundtruth"]}))
    assert main(["campaign", str(path), "--out", str(tmp_path / "all"), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "1,000,000,000 missions" in err
    monkeypatch.setenv(MISSION_FN_ENV, "campaign_fakes:instant")
    here = str(Path(__file__).resolve().parent)
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join(p for p in (here, os.environ.get("PYTHONPATH")) if p))
    out = tmp_path / "one"
    args = ["campaign", str(path), "--out", str(out), "--workers", "1", "--limit", "1", "--no-progress"]
    assert main(args) == 0
    assert [r["mission_id"] for r in read_rows(out / "results.csv")] == ["c000-groundtruth-r000"]
