"""The take-off climb: its peak speed and acceleration, and the scenario key that sets it on every preset."""

from __future__ import annotations

import math

import numpy as np
import pytest
from preset_flight import pipeline_taking_off

from alight.airframe import DEFAULT_AIRFRAME
from alight.airframes import load_airframe
from alight.mission.guidance import _rest_to_rest
from alight.mission.presets import PRESETS, build_preset
from alight.scenario import scenario_from_dict

_ZERO = np.zeros(3)


def _peaks(traj) -> tuple[float, float]:  # type: ignore[no-untyped-def]
    ts = np.linspace(traj.t0, traj.t_end, 2001)
    v = max(float(np.linalg.norm(traj.sample(t)[1])) for t in ts)
    a = max(float(np.linalg.norm(traj.sample(t)[2])) for t in ts)
    return v, a


def test_a_rest_to_rest_climb_peaks_at_its_speed_when_speed_binds() -> None:
    # 12 m at 5 m/s peak: T = 1.875 * 12 / 5 = 4.5 s; peak acceleration 10/sqrt(3) * 12 / 4.5^2 = 3.42
    traj = _rest_to_rest(0.0, _ZERO, _ZERO, np.array([0.0, 0.0, 12.0]), 5.0, 4.17)
    assert traj.T == pytest.approx(4.5)
    v, a = _peaks(traj)
    assert v == pytest.approx(5.0, rel=1e-3)
    assert a == pytest.approx(10.0 / math.sqrt(3.0) * 12.0 / 4.5**2, rel=1e-3)


def test_a_rest_to_rest_climb_peaks_at_its_acceleration_when_that_binds() -> None:
    # 12 m at up to 20 m/s but 2 m/s^2: T = sqrt(10/sqrt(3) * 12 / 2) = 5.886 s, the speed 3.82 m/s
    traj = _rest_to_rest(0.0, _ZERO, _ZERO, np.array([0.0, 0.0, 12.0]), 20.0, 2.0)
    assert traj.T == pytest.approx(math.sqrt(10.0 / math.sqrt(3.0) * 6.0))
    v, a = _peaks(traj)
    assert a == pytest.approx(2.0, rel=1e-3)
    assert v == pytest.approx(1.875 * 12.0 / traj.T, rel=1e-3)


@pytest.mark.parametrize("preset", sorted(PRESETS))
def test_the_climb_speed_key_acts_on_every_preset(preset: str) -> None:
    def climb_time(extra: dict) -> float:
        traj = pipeline_taking_off(preset, extra).guidance._traj
        assert traj is not None
        return float(traj.T)

    slow, fast = climb_time({"takeoff_climb_speed_mps": 1.0}), climb_time({"takeoff_climb_speed_mps": 4.0})
    assert fast < slow / 3.5
    assert climb_time({}) == pytest.approx(
        climb_time({"takeoff_climb_speed_mps": 5.0 if preset == "alight" else 2.0})
    )


def test_the_climb_acceleration_comes_from_the_airframe() -> None:
    heavy = load_airframe("matrice100")
    s = scenario_from_dict({"preset": "alight", "seed": 1})
    for frame in (DEFAULT_AIRFRAME, heavy):
        g = build_preset(s, frame, np.random.default_rng(0)).pipeline.guidance
        assert g.config.max_climb_accel_mps2 == pytest.approx(0.5 * (frame.thrust_to_weight - 1.0) * 9.81)
