"""The fault campaign file: every class at the level issue 15 asks for, every preset, 50 paired seeds."""

from __future__ import annotations

import importlib.util
import math
from pathlib import Path

from alight.campaign import load_campaign
from alight.scenario import FaultSpec

ROOT = Path(__file__).resolve().parents[2]


def test_fault_campaign_has_every_class_on_every_preset_with_paired_seeds() -> None:
    c = load_campaign(ROOT / "examples" / "campaigns" / "faults.yaml")
    assert c.presets == ["groundtruth", "falanga2017", "kim_kaist", "zamanakos_sdu"]
    assert c.spec.seeds_per_condition == 50 and len(c.missions) == 50 * 4 * len(c.conditions)
    seeds = {
        cond.condition_id: {m.seed for m in c.missions if m.condition_id == cond.condition_id}
        for cond in c.conditions
    }
    assert len({frozenset(s) for s in seeds.values()}) == 1  # the same platforms and noise for every class

    scenarios = {
        m.condition_id: m.scenario for m in c.missions if m.preset == "falanga2017" and m.replicate == 0
    }
    faults = [scenarios[cond.condition_id]["faults"] for cond in c.conditions]
    latency = [
        s["perception"]["latency_s"] + f["latency_s"] for s, f in zip(scenarios.values(), faults, strict=True)
    ]

    def has(pred: object) -> bool:
        return any(pred(f) for f in faults)  # type: ignore[operator]

    assert has(lambda f: f["dropout_prob"] == 0.2)
    assert any(
        math.isclose(lat, 0.25)
        for lat, f in zip(latency, faults, strict=True)
        if f["latency_jitter_s"] == 0.05
    )
    jumps = [j for f in faults for j in f["odometry_jumps"]]
    assert all(math.isclose(math.hypot(*j["offset_m"]), 0.5) for j in jumps)
    assert {j["announced"] for j in jumps} == {True, False}  # with and without the VIO's reset counter
    assert has(lambda f: any(math.isclose(math.hypot(*b["delta"]), 0.2) for b in f["accel_bias_steps"]))
    assert has(lambda f: f["gyro_bias_steps"]) and has(lambda f: f["blackouts"])
    assert has(lambda f: f["odometry_dropouts"]) and has(lambda f: f["range_dropout_prob"] > 0)
    assert has(lambda f: f["range_spurious_prob"] > 0)
    assert has(lambda f: all(f["corruption"][k]["prob"] > 0 for k in f["corruption"]))
    assert any(s["platform"]["speed_profile"] for s in scenarios.values())
    assert faults[0] == FaultSpec().model_dump(mode="json")  # c000: no fault, the reference


def test_fault_table_names_each_class() -> None:
    spec = importlib.util.spec_from_file_location(
        "fault_table", ROOT / "examples" / "campaigns" / "fault_table.py"
    )
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    c = load_campaign(ROOT / "examples" / "campaigns" / "faults.yaml")
    names = [module.class_name(cond.params) for cond in c.conditions]
    assert names[0] == "none" and len(set(names)) == len(names)
    assert "corruption" in names and "speed_profile.brake_stop" in names and "dropout_prob" in names
    assert "odometry_jumps" in names and "odometry_jumps.unannounced" in names
