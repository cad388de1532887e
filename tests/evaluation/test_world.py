"""The one simulated world (``sim/world.py``) that ``run_mission`` and ``alight sitl`` step."""

from __future__ import annotations

import numpy as np

from alight.evaluation.result import MissionResult
from alight.evaluation.runner import run_mission, world_for_scenario
from alight.scenario import Scenario
from alight.sim.quadrotor import SL_P
from alight.sim.world import TICK_DT, mission_seeds

BASE = {"preset": "groundtruth", "seed": 5, "duration_s": 3.0}


def test_verdict_is_in_every_result_and_covers_the_judged_columns() -> None:
    s = Scenario.model_validate(BASE)
    verdict = world_for_scenario(s).verdict()
    result = run_mission(s, record=False).result
    assert set(verdict) <= set(result)
    judged = {"outcome", "success", "touchdown_error_m", "touchdown_rel_speed_mps", "time_to_land_s"}
    assert judged <= set(verdict) and judged <= set(MissionResult.columns())


def test_seed_children_are_independent_of_their_number() -> None:
    # adding a component at the end leaves the others' random numbers as they were
    a = mission_seeds(7)
    b = np.random.SeedSequence(7).spawn(9)
    for x, y in zip(a[:9], b, strict=True):
        assert np.array_equal(np.random.default_rng(x).random(4), np.random.default_rng(y).random(4))


def test_world_stands_still_without_a_command_and_times_out() -> None:
    """Nothing in the world starts or stops the motors: left alone, the vehicle stands where it was put,
    the ticks advance at the IMU period, and the mission ends as a timeout."""
    world = world_for_scenario(Scenario.model_validate(BASE))
    p0 = world.x[SL_P].copy()
    while not world.done:
        imu = world.step()
    assert world.k == world.n_ticks and abs(world.t - world.n_ticks * TICK_DT) < 1e-12
    assert np.allclose(world.x[SL_P], p0, atol=1e-3) and not world.airborne
    assert abs(float(np.linalg.norm(imu[0:3])) - 9.81) < 0.5  # the feet hold the weight
    v = world.verdict()
    assert v["outcome"] == "timeout" and v["touchdown_error_m"] is None
