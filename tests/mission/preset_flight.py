"""Shared by the tests that check a mission key on every preset: a preset's pipeline, built from a
scenario with the given ``mission:`` keys, its ego estimate at rest at the origin, and taken into the
take-off (its first step)."""

from __future__ import annotations

from typing import Any

import numpy as np

from alight.airframe import DEFAULT_AIRFRAME
from alight.mission.pipeline import Pipeline
from alight.mission.presets import build_preset
from alight.scenario import scenario_from_dict


def pipeline_taking_off(preset: str, mission: dict[str, Any]) -> Pipeline:
    s = scenario_from_dict({"preset": preset, "seed": 1, "mission": mission})
    pipeline = build_preset(s, DEFAULT_AIRFRAME, np.random.default_rng(0)).pipeline
    pipeline.ego_estimator.initialize(0.0, np.zeros(3), np.zeros(3), np.array([0, 0, 0, 1.0]))
    pipeline.step(0.0)  # enters the take-off
    return pipeline
