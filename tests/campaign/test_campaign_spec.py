"""Campaign files: expansion (grid, explicit conditions, sampling), the seed tree, and one-line errors."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from alight.campaign.seeds import mission_seed, sample_rng
from alight.campaign.spec import campaign_from_dict, load_campaign
from alight.errors import ConfigError
from alight.scenario import Scenario

ROOT = Path(__file__).resolve().parents[2]


def _campaign(**over: object) -> dict:
    data: dict = {
        "name": "t",
        "base": {"duration_s": 30.0, "platform": {"path": "straight"}},
        "presets": ["groundtruth", "falanga2017"],
        "seeds_per_condition": 2,
        "seed": 7,
    }
    data.update(over)
    return data


def _error(data: dict) -> str:
    with pytest.raises(ConfigError) as info:
        campaign_from_dict(data, "c.yaml")
    text = str(info.value)
    assert "\n" not in text and text.startswith("c.yaml")
    return text


def test_grid_is_the_cartesian_product_in_order() -> None:
    c = campaign_from_dict(
        _campaign(grid={"platform.path": ["straight", "circle"], "platform.speed_mps": [1.0, 2.0, 3.0]})
    )
    assert [cond.condition_id for cond in c.conditions] == [f"c{i:03d}" for i in range(6)]
    assert [tuple(cond.params.values()) for cond in c.conditions] == [
        ("straight", 1.0), ("straight", 2.0), ("straight", 3.0),
        ("circle", 1.0), ("circle", 2.0), ("circle", 3.0),
    ]  # fmt: skip
    assert len(c.missions) == 6 * 2 * 2
    # condition by condition, replicate by replicate, preset by preset
    assert [m.mission_id for m in c.missions[:4]] == [
        "c000-groundtruth-r000", "c000-falanga2017-r000", "c000-groundtruth-r001", "c000-falanga2017-r001",
    ]  # fmt: skip
    for m in c.missions:
        s = Scenario.model_validate(m.scenario)
        assert (s.preset, s.seed) == (m.preset, m.seed)
        assert s.platform.path == m.params["platform.path"]
        assert s.platform.speed_mps == m.params["platform.speed_mps"]
        assert s.duration_s == 30.0


def test_presets_share_the_seed_of_a_condition_and_replicate() -> None:
    c = campaign_from_dict(_campaign(grid={"platform.speed_mps": [1.0, 2.0]}, seeds_per_condition=3))
    seeds: dict[tuple[str, int], set[int]] = {}
    for m in c.missions:
        seeds.setdefault((m.condition_id, m.replicate), set()).add(m.seed)
    assert all(len(s) == 1 for s in seeds.values())  # the same draw for every preset
    distinct = {next(iter(s)) for s in seeds.values()}
    assert len(distinct) == len(seeds)  # and different draws for different conditions / replicates


def test_settings_in_same_seeds_across_are_flown_on_the_same_seeds() -> None:
    grid = {"platform.speed_mps": [1.0, 2.0], "controller.l1_adaptive": [True, False]}
    c = campaign_from_dict(
        _campaign(grid=grid, seeds_per_condition=2, same_seeds_across=["controller.l1_adaptive"])
    )
    by_speed: dict[tuple[float, int], set[int]] = {}
    for m in c.missions:
        by_speed.setdefault((m.params["platform.speed_mps"], m.replicate), set()).add(m.seed)
    assert all(len(s) == 1 for s in by_speed.values())  # L1 on and off: the same draws
    assert len({next(iter(s)) for s in by_speed.values()}) == 4  # speeds and replicates still differ
    plain = campaign_from_dict(_campaign(grid=grid, seeds_per_condition=2))
    assert len({m.seed for m in plain.missions}) == 8
    with pytest.raises(ConfigError, match="same_seeds_across"):
        campaign_from_dict(_campaign(grid=grid, same_seeds_across=["wind.model"]))


def test_mission_seed_is_the_spawn_tree() -> None:
    missions_branch, sample_branch = np.random.SeedSequence(7).spawn(2)
    for c, cond in enumerate(missions_branch.spawn(3)):
        for r, child in enumerate(cond.spawn(4)):
            assert mission_seed(7, c, r) == int(child.generate_state(1, np.uint32)[0])
    expected = np.random.default_rng(sample_branch).random(3)
    np.testing.assert_array_equal(sample_rng(7).random(3), expected)


def test_explicit_conditions_follow_the_grid_and_fill_in_base_values() -> None:
    c = campaign_from_dict(
        _campaign(
            grid={"platform.speed_mps": [1.0, 2.0]},
            conditions=[{"platform.speed_mps": 1.5, "wind.model": "gust", "wind.gust_power_N": 3.45}],
        )
    )
    assert c.swept_parameters == ["platform.speed_mps", "wind.model", "wind.gust_power_N"]
    assert [cond.params for cond in c.conditions] == [
        {"platform.speed_mps": 1.0, "wind.model": "none", "wind.gust_power_N": 7.0},
        {"platform.speed_mps": 2.0, "wind.model": "none", "wind.gust_power_N": 7.0},
        {"platform.speed_mps": 1.5, "wind.model": "gust", "wind.gust_power_N": 3.45},
    ]


def test_sampled_conditions_are_reproducible_and_in_range() -> None:
    sample = {
        "n": 50,
        "platform.speed_mps": {"dist": "uniform", "low": 0.5, "high": 3.0},
        "perception.noise_m": {"dist": "loguniform", "low": 0.01, "high": 0.2},
        "platform.path": {"dist": "choice", "values": ["straight", "circle"], "p": [0.25, 0.75]},
        "perception.latency_s": {"dist": "normal", "mean": 0.1, "std": 0.001},
    }
    a = campaign_from_dict(_campaign(sample=sample, seeds_per_condition=1))
    b = campaign_from_dict(_campaign(sample=sample, seeds_per_condition=1))
    other = campaign_from_dict(_campaign(sample=sample, seeds_per_condition=1, seed=8))
    assert [x.params for x in a.conditions] == [x.params for x in b.conditions]
    assert [x.params for x in a.conditions] != [x.params for x in other.conditions]
    speeds = np.array([x.params["platform.speed_mps"] for x in a.conditions])
    noise = np.array([x.params["perception.noise_m"] for x in a.conditions])
    assert len(a.conditions) == 50 and np.all((speeds >= 0.5) & (speeds < 3.0))
    assert np.all((noise >= 0.01) & (noise < 0.2))
    assert {x.params["platform.path"] for x in a.conditions} == {"straight", "circle"}


def test_sampling_crosses_the_grid() -> None:
    c = campaign_from_dict(
        _campaign(
            grid={"platform.path": ["straight", "circle"]},
            sample={"n": 3, "platform.speed_mps": {"dist": "uniform", "low": 1.0, "high": 2.0}},
            seeds_per_condition=1,
        )
    )
    assert [x.params["platform.path"] for x in c.conditions] == ["straight"] * 3 + ["circle"] * 3
    assert len({x.params["platform.speed_mps"] for x in c.conditions}) == 6


def test_base_file_relative_to_the_campaign_and_duration_override(tmp_path: Path) -> None:
    (tmp_path / "scen").mkdir()
    (tmp_path / "scen" / "base.yaml").write_text("preset: groundtruth\nseed: 99\nduration_s: 50\n")
    (tmp_path / "camp.yaml").write_text(
        yaml.safe_dump({"name": "x", "base": "scen/base.yaml", "duration_s": 12.5, "seeds_per_condition": 2})
    )
    c = load_campaign(tmp_path / "camp.yaml")
    assert c.presets == ["groundtruth"] and len(c.missions) == 2
    assert all(m.scenario["duration_s"] == 12.5 and m.seed != 99 for m in c.missions)
    assert c.text is not None and "scen/base.yaml" in c.text


SPEED = "platform.speed_mps"
UNIFORM = {"dist": "uniform", "low": 1, "high": 2}
BAD_VALUES = [
    ({"gird": {SPEED: [1.0]}}, "gird: Extra inputs are not permitted"),
    (
        {"grid": {"platform.sped_mps": [1.0]}},
        "'platform.sped_mps' is not a scenario key ('sped_mps' not in platform",
    ),
    ({"grid": {"platfrom.speed_mps": [1.0]}}, "'platfrom' not in the scenario: airframe, blocks, camera"),
    ({"grid": {"platform.speed_mps.x": [1.0]}}, "'x' not in platform.speed_mps"),
    ({"grid": {SPEED: []}}, "grid.platform.speed_mps: List should have at least 1 item"),
    ({"grid": {"seed": [1, 2]}}, "'seed' cannot be swept"),
    ({"conditions": [{"wind.modle": "gust"}]}, "conditions[0]: 'wind.modle' is not a scenario key"),
    (
        {"grid": {SPEED: [1.0, -1.0]}},
        "condition c001 (platform.speed_mps=-1.0), preset groundtruth: "
        "platform.speed_mps: Input should be greater than or equal to 0, got -1.0",
    ),
    ({"conditions": [{"platform.path": "zigzag"}]}, 'condition c000 (platform.path="zigzag")'),
    ({"presets": ["groundtruth", "nosuch"]}, "presets: unknown preset 'nosuch'"),
    ({"seeds_per_condition": 0}, "seeds_per_condition: Input should be greater than or equal to 1, got 0"),
    ({"name": "a/b"}, "name: String should match pattern"),
    ({"base": {"platform": {"speed": 1}}}, "c.yaml: base: platform.speed: Extra inputs are not permitted"),
    ({"sample": {SPEED: UNIFORM}}, "sample.n: the number of draws"),
    ({"sample": {"n": 2, SPEED: {"dist": "gauss"}}}, "sample.platform.speed_mps: "),
    ({"sample": {"n": 2, SPEED: {**UNIFORM, "low": 3}}}, "needs high > low"),
    ({"grid": {SPEED: [1.0]}, "conditions": [{SPEED: 1.0}]}, "c001 (platform.speed_mps=1.0) repeats c000"),
    ({"grid": {"wind": [{"model": "none"}], "wind.model": ["gust"]}}, "'wind' and 'wind.model' overlap"),
]


@pytest.mark.parametrize(("over", "expected"), BAD_VALUES)
def test_errors_are_one_line(over: dict, expected: str) -> None:
    assert expected in _error(_campaign(**over))


def test_file_errors_are_one_line(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="no such campaign file"):
        load_campaign(tmp_path / "none.yaml")
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: x\ngrid: {a: [1\n")
    with pytest.raises(ConfigError, match=r"not valid YAML \(line"):
        load_campaign(bad)
    missing_base = tmp_path / "mb.yaml"
    missing_base.write_text("name: x\nbase: nothere.yaml\n")
    with pytest.raises(ConfigError, match="nothere.yaml: no such scenario file"):
        load_campaign(missing_base)
    for path in (bad, missing_base):
        with pytest.raises(ConfigError) as info:
            load_campaign(path)
        assert "\n" not in str(info.value)


def test_examples_expand() -> None:
    smoke = load_campaign(ROOT / "examples" / "campaigns" / "smoke.yaml")
    assert len(smoke.missions) == 8 and smoke.presets == ["groundtruth", "falanga2017"]
    assert all(m.scenario["duration_s"] <= 60 for m in smoke.missions)

    paper = load_campaign(ROOT / "examples" / "campaigns" / "paper_conditions.yaml")
    presets = ["groundtruth", "falanga2017", "kim_kaist", "zamanakos_sdu"]
    assert paper.spec.seeds_per_condition == 20 and paper.presets == presets
    conds = [c.params for c in paper.conditions]
    for path in ("straight", "circle", "figure8"):
        for speed in (1.0, 2.0, 3.0, 4.2):
            assert any(
                c["platform.path"] == path and c["platform.speed_mps"] == speed and c["wind.model"] == "none"
                for c in conds
            )
    for speed in (1.2, 1.5):
        assert any(c["platform.path"] == "straight" and c["platform.speed_mps"] == speed for c in conds)
    gusts = sorted(c["wind.gust_power_N"] for c in conds if c["wind.model"] == "gust")
    assert gusts == [3.45, 7.76]
    assert all(math.isclose(m.scenario["perception"]["rate_hz"], 20.0) for m in paper.missions)
    assert len(paper.missions) == len(conds) * 4 * 20


def test_the_sdu_conditions_fly_the_12_mps_gust_force() -> None:
    # Issue 6's table is calm against paper 004's 12 m/s gusts: 7.76 N as the model's power_init, not the
    # 7.0 N default of the model (an earlier version of the file flew 7.0 N while calling it 12 m/s).
    sdu = load_campaign(ROOT / "examples" / "campaigns" / "zamanakos_sdu_conditions.yaml")
    assert sdu.spec.seeds_per_condition == 20 and sdu.presets == ["zamanakos_sdu"]
    winds = {(m.scenario["platform"]["path"], m.scenario["wind"]["model"]) for m in sdu.missions}
    assert winds == {("straight", "none"), ("straight", "gust"), ("tractor", "none"), ("tractor", "gust")}
    gusty = [m for m in sdu.missions if m.scenario["wind"]["model"] == "gust"]
    assert len(gusty) == 40
    assert all(math.isclose(m.scenario["wind"]["gust_power_N"], 7.76) for m in gusty)
    assert all(math.isclose(m.scenario["platform"]["speed_mps"], 1.5) for m in sdu.missions)


def test_the_falanga2017_conditions_are_paper_000s() -> None:
    # Issue 3's closed-loop table: straight 1.2 m/s, circle 2 m/s, figure-8 4.2 m/s, 20 seeds each, the
    # vision preset and its ground-truth ablation on the same seeds.
    fal = load_campaign(ROOT / "examples" / "campaigns" / "falanga2017_conditions.yaml")
    assert fal.spec.seeds_per_condition == 20 and fal.presets == ["falanga2017", "groundtruth"]
    flown = {(m.scenario["platform"]["path"], m.scenario["platform"]["speed_mps"]) for m in fal.missions}
    assert flown == {("straight", 1.2), ("circle", 2.0), ("figure8", 4.2)}
    assert len(fal.missions) == 3 * 2 * 20
    assert all(m.scenario["wind"]["model"] == "none" for m in fal.missions)
    seeds = {p: sorted(m.seed for m in fal.missions if m.preset == p) for p in fal.presets}
    assert seeds["falanga2017"] == seeds["groundtruth"]


def test_the_falanga2017_gusts_pair_the_integral_on_the_same_seeds() -> None:
    gusts = load_campaign(ROOT / "examples" / "campaigns" / "falanga2017_gusts.yaml")
    assert gusts.presets == ["falanga2017", "groundtruth"] and len(gusts.missions) == 2 * 2 * 2 * 20
    forces = {m.scenario["wind"]["gust_power_N"] for m in gusts.missions}
    assert forces == {3.45, 7.76} and all(m.scenario["wind"]["model"] == "gust" for m in gusts.missions)
    by_gain: dict[float, list[tuple[str, float, int]]] = {}
    for m in gusts.missions:
        key = (m.preset, m.scenario["wind"]["gust_power_N"], m.replicate)
        by_gain.setdefault(m.scenario["controller"]["integral_gain"], []).append((*key, m.seed))
    assert sorted(by_gain) == [0.0, 2.0]
    assert sorted(by_gain[0.0]) == sorted(by_gain[2.0])  # the same seeds with and without the integral
