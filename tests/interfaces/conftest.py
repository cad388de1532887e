"""A short falanga2017 flight with its camera frames, flown once for the replay and export tests."""

from __future__ import annotations

import importlib.util
import sys
from dataclasses import dataclass, field
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import pytest

from alight.evaluation.runner import MissionRun, run_mission
from alight.scenario import Scenario, scenario_from_dict

FLIGHT = {
    "preset": "falanga2017",
    "seed": 3,
    "duration_s": 16.0,
    # the platform starts in view of the climbing vehicle, so the detector has work from the start
    "platform": {"path": "straight", "speed_mps": 0.5, "start_xy": [2.0, 1.0], "heading_rad": 0.0},
    "camera": {"ground": "grass", "noise_dn": 2.0},
    "perception": {"rate_hz": 20, "latency_s": 0.1},
}


@dataclass
class Flight:
    scenario: Scenario
    run: MissionRun
    frames: list[tuple[float, np.ndarray, list[Any]]] = field(default_factory=list)

    @property
    def log(self) -> dict[str, np.ndarray]:
        assert self.run.log is not None
        return self.run.log


@pytest.fixture(scope="session")
def vision_flight() -> Flight:
    scenario = scenario_from_dict(FLIGHT)
    frames: list[tuple[float, np.ndarray, list[Any]]] = []

    def sink(t: float, image: np.ndarray, observations: list[Any]) -> None:
        frames.append((t, image.copy(), list(observations)))

    run = run_mission(scenario, frame_sink=sink)
    return Flight(scenario, run, frames)


FUZZ = Path(__file__).resolve().parents[2] / "benchmarks" / "fuzz_logs.py"


@pytest.fixture(scope="session")
def fuzz_logs() -> ModuleType:
    """benchmarks/fuzz_logs.py: the fuzzer, and the generated flights it damages."""
    spec = importlib.util.spec_from_file_location("fuzz_logs", FUZZ)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules["fuzz_logs"] = mod
    spec.loader.exec_module(mod)
    return mod
