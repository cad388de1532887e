"""The optical-flow module's model against cases worked by hand, and its inversion on board
(``alight.estimation.optical_flow``) as a round trip."""

from __future__ import annotations

import math

import numpy as np
import pytest

from alight.errors import ConfigError
from alight.estimation.optical_flow import horizontal_slip_W, module_velocity_W
from alight.scenario import scenario_from_dict
from alight.sim.sensors import OpticalFlowConfig, OpticalFlowSensor

LEVEL = np.array([0.0, 0.0, 0.0, 1.0])
DECK_FAR = (np.array([100.0, 100.0, 0.5]), np.zeros(3), 0.0, 0.0)  # a deck nowhere near: ground below
PAD = 1.0


def _sensor(noise: float = 0.0, origin: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> OpticalFlowSensor:
    cfg = OpticalFlowConfig(noise_rad_s=noise, range_noise_m=0.0, origin_B=origin)
    return OpticalFlowSensor(cfg, np.random.default_rng(1))


def _q(axis: tuple[float, float, float], angle: float) -> np.ndarray:
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    return np.array([*(a * math.sin(angle / 2)), math.cos(angle / 2)])


def test_level_flight_over_the_ground_is_minus_velocity_over_height() -> None:
    s = _sensor()
    x = (np.array([0.0, 0.0, 2.0]), np.array([1.0, -0.5, 0.0]), LEVEL, np.zeros(3))
    sample = s.measure_at(0.0, x, DECK_FAR, PAD)
    assert sample is not None
    assert sample.distance_m == pytest.approx(2.0)
    np.testing.assert_allclose(sample.flow_B_rad_s, [-0.5, 0.25], atol=1e-12)


def test_rotation_alone_reads_the_body_rates() -> None:
    """Hovering and rolling/pitching: flow_x = w_y, flow_y = -w_x (sensor at the body origin); from the
    feet 0.1 m below it the sensor also moves, by w x r."""
    x = (np.array([0.0, 0.0, 2.0]), np.zeros(3), LEVEL, np.array([0.3, -0.2, 0.7]))
    sample = _sensor().measure_at(0.0, x, DECK_FAR, PAD)
    assert sample is not None
    np.testing.assert_allclose(sample.flow_B_rad_s, [-0.2, -0.3], atol=1e-12)
    feet = _sensor(origin=(0.0, 0.0, -0.1)).measure_at(0.0, x, DECK_FAR, PAD)
    assert feet is not None
    # the feet move at w x (0, 0, -0.1) = (0.1 * 0.2, 0.1 * 0.3, 0) = (0.02, 0.03, 0) in B, 1.9 m up
    np.testing.assert_allclose(feet.flow_B_rad_s, [-0.02 / 1.9 - 0.2, -0.03 / 1.9 - 0.3], atol=1e-12)


def test_over_the_deck_it_measures_the_velocity_relative_to_the_deck() -> None:
    deck_v = np.array([6.0, 0.0, 0.0])
    deck = (np.array([0.0, 0.0, 0.5]), deck_v, 0.0, 0.0)
    matched = (np.array([0.0, 0.0, 1.5]), deck_v.copy(), LEVEL, np.zeros(3))
    sample = _sensor().measure_at(0.0, matched, deck, PAD)
    assert sample is not None and sample.distance_m == pytest.approx(1.0)
    np.testing.assert_allclose(sample.flow_B_rad_s, [0.0, 0.0], atol=1e-12)
    # the deck brakes to 5 m/s under a vehicle still at 6: 1 m/s forward over the deck, 1 m below
    braked = (deck[0], np.array([5.0, 0.0, 0.0]), 0.0, 0.0)
    sample = _sensor().measure_at(0.0, matched, braked, PAD)
    assert sample is not None
    np.testing.assert_allclose(sample.flow_B_rad_s, [-1.0, 0.0], atol=1e-12)
    # a turning deck (yaw rate 0.5 rad/s), the vehicle 0.2 m to the deck's left of its centre: that deck
    # point moves at 0.5 x 0.2 = 0.1 m/s backwards (-x)
    turning = (deck[0], np.zeros(3), 0.0, 0.5)
    beside = (np.array([0.0, 0.2, 1.5]), np.zeros(3), LEVEL, np.zeros(3))
    sample = _sensor().measure_at(0.0, beside, turning, PAD)
    assert sample is not None
    np.testing.assert_allclose(sample.flow_B_rad_s, [-0.1, 0.0], atol=1e-12)


def test_out_of_range_gives_no_sample_and_the_noise_stays_in_step() -> None:
    a, b = _sensor(noise=0.05), _sensor(noise=0.05)
    high = (np.array([0.0, 0.0, 10.0]), np.zeros(3), LEVEL, np.zeros(3))
    near = (np.array([0.0, 0.0, 0.05]), np.zeros(3), LEVEL, np.zeros(3))
    ok = (np.array([0.0, 0.0, 2.0]), np.zeros(3), LEVEL, np.zeros(3))
    assert a.measure_at(0.0, high, DECK_FAR, PAD) is None  # beyond its 4 m
    assert a.measure_at(0.0, near, DECK_FAR, PAD) is None  # closer than its 8 cm
    b.measure_at(0.0, ok, DECK_FAR, PAD)
    b.measure_at(0.0, ok, DECK_FAR, PAD)
    sa, sb = a.measure_at(1.0, ok, DECK_FAR, PAD), b.measure_at(1.0, ok, DECK_FAR, PAD)
    assert sa is not None and sb is not None
    np.testing.assert_array_equal(sa.flow_B_rad_s, sb.flow_B_rad_s)


@pytest.mark.parametrize("seed", range(5))
def test_the_onboard_inversion_recovers_the_slip_of_a_tilted_turning_vehicle(seed: int) -> None:
    """Round trip: the module's sample of a tilted, rotating vehicle descending over a moving deck, then
    :func:`horizontal_slip_W` with the true rates and descent rate, gives the feet's true horizontal
    velocity relative to the deck."""
    rng = np.random.default_rng(seed)
    origin = np.array([0.0, 0.0, -0.1])
    q = _q(tuple(rng.normal(size=3)), rng.uniform(0.05, 0.4))
    w = rng.normal(0.0, 0.5, 3)
    v_WB = np.array([6.0, 0.0, -0.6]) + rng.normal(0.0, 0.5, 3)
    deck = (np.array([0.0, 0.0, 0.5]), np.array([5.5, 0.3, 0.0]), 0.2, 0.0)
    p_WB = np.array([0.05, -0.05, 1.2])
    sample = _sensor(origin=tuple(origin)).measure_at(0.0, (p_WB, v_WB, q, w), deck, PAD)
    assert sample is not None
    from alight.types import quat_to_rotmat

    R = quat_to_rotmat(q)
    v_feet_W = v_WB + R @ np.cross(w, origin)
    truth = v_feet_W - deck[1]
    slip = horizontal_slip_W(sample.flow_B_rad_s, sample.distance_m, w, q, float(truth[2]))
    assert slip is not None
    np.testing.assert_allclose(slip, truth[:2], atol=1e-9)


def test_the_inversion_refuses_what_it_cannot_read() -> None:
    level = np.zeros(3)
    assert horizontal_slip_W(np.array([math.nan, 0.0]), 1.0, level, LEVEL, 0.0) is None
    assert horizontal_slip_W(np.array([0.1, 0.0]), 0.0, level, LEVEL, 0.0) is None
    assert horizontal_slip_W(np.array([0.1, 0.0]), 1.0, level, _q((1, 0, 0), math.radians(70)), 0.0) is None


def test_the_scenario_key_is_checked() -> None:
    assert scenario_from_dict({"optical_flow": {}}).optical_flow is not None
    assert scenario_from_dict({}).optical_flow is None  # off by default
    with pytest.raises(ConfigError, match="rate_hz must divide 200"):
        scenario_from_dict({"optical_flow": {"rate_hz": 60}})
    with pytest.raises(ConfigError, match="max_range_m"):
        scenario_from_dict({"optical_flow": {"min_range_m": 5.0}})
    # a flow fault needs a module to act on: refused in one line without one
    for fault in ({"flow_dropout_prob": 0.5}, {"flow_dropouts": [[1.0, 2.0]]}):
        with pytest.raises(ConfigError, match="no optical-flow module") as err:
            scenario_from_dict({"faults": fault})
        assert "\n" not in str(err.value)
        assert scenario_from_dict({"faults": fault, "optical_flow": {}}).faults.acts_on_flow()


def test_a_point_at_the_feet_moves_with_the_lever_arm() -> None:
    # level, pitching at 1 rad/s (w = (0, 1, 0)): a point 0.1 m under the origin moves w x r =
    # (1 * -0.1, 0, 0): 0.1 m/s backwards
    v = module_velocity_W(np.array([2.0, 0.0, 0.0]), LEVEL, np.array([0.0, 1.0, 0.0]), (0.0, 0.0, -0.1))
    np.testing.assert_allclose(v, [1.9, 0.0, 0.0], atol=1e-15)
    # yawed 90 deg, rolling at 1 rad/s: w x r = (0, 0.1, 0) in B is (-0.1, 0, 0) in W
    yawed = _q((0.0, 0.0, 1.0), math.pi / 2)
    v = module_velocity_W(np.zeros(3), yawed, np.array([1.0, 0.0, 0.0]), (0.0, 0.0, -0.1))
    np.testing.assert_allclose(v, [-0.1, 0.0, 0.0], atol=1e-15)
    assert module_velocity_W(np.array([1.0, 2.0, 3.0]), yawed, np.ones(3), (0.0, 0.0, 0.0)) == (1.0, 2.0, 3.0)


@pytest.mark.parametrize("origin", [(0.0, 0.0, -0.15), (0.12, -0.06, -0.05)])
@pytest.mark.parametrize("seed", range(5))
def test_the_deck_velocity_under_the_feet_is_recovered_with_the_lever_arm(
    seed: int, origin: tuple[float, float, float]
) -> None:
    """Round trip as the pipeline reads a sample (``Pipeline.on_flow``): the module's velocity from the
    body's state and its mount (at the feet, or off the centre), less the inverted slip, is the deck's
    true velocity; without the lever arm it is off by R (w x r)."""
    rng = np.random.default_rng(100 + seed)
    q = _q(tuple(rng.normal(size=3)), rng.uniform(0.05, 0.4))
    w = rng.normal(0.0, 0.8, 3)
    v_WB = np.array([6.0, 0.0, -0.6]) + rng.normal(0.0, 0.5, 3)
    deck_v = np.array([5.5, 0.3, 0.0])
    deck = (np.array([0.0, 0.0, 0.5]), deck_v, 0.2, 0.0)
    sample = _sensor(origin=origin).measure_at(0.0, (np.array([0.05, -0.05, 1.2]), v_WB, q, w), deck, PAD)
    assert sample is not None
    v_S = np.array(module_velocity_W(v_WB, q, w, origin))
    slip = horizontal_slip_W(sample.flow_B_rad_s, sample.distance_m, w, q, float(v_S[2] - deck_v[2]))
    assert slip is not None
    np.testing.assert_allclose(v_S[:2] - slip, deck_v[:2], atol=1e-9)
    lever = np.linalg.norm((v_S - v_WB)[:2])
    assert lever > 0.005  # the case has a lever arm to miss (0.15 m x ~0.8 rad/s)


def _world_and_pipeline_mounts(optical_flow: dict[str, object]) -> tuple[object, object]:
    from alight.airframes import load_airframe
    from alight.mission.presets import build_preset
    from alight.sim.world import SEED_PIPELINE, World, mission_seeds

    s = scenario_from_dict({"optical_flow": optical_flow})
    airframe = load_airframe(s.airframe)
    seeds = mission_seeds(s.seed)
    preset = build_preset(s, airframe, np.random.default_rng(seeds[SEED_PIPELINE]))
    world = World(s, airframe, preset, seeds)
    assert world.optical_flow is not None
    return world.optical_flow.config.origin_B, preset.pipeline.flow_origin_B


def test_the_modules_mount_is_one_setting_for_the_simulated_module_and_the_pipeline() -> None:
    """``optical_flow.position_B_m`` places the simulated module and tells the pipeline the same lever
    arm; unset, both are at the feet; below the feet it is refused in one line."""
    from alight.airframes import load_airframe

    feet = load_airframe("f450").feet_B
    assert _world_and_pipeline_mounts({}) == (feet, feet)
    off = (0.12, -0.06, -0.05)
    assert _world_and_pipeline_mounts({"position_B_m": list(off)}) == (off, off)
    with pytest.raises(ConfigError, match=r"optical_flow.position_B_m: z = -0.3 m puts the sensor") as err:
        _world_and_pipeline_mounts({"position_B_m": [0.0, 0.0, -0.3]})
    assert "\n" not in str(err.value)
    with pytest.raises(ConfigError, match=r"optical_flow.position_B_m.0: .* less than or equal to 2"):
        scenario_from_dict({"optical_flow": {"position_B_m": [3.0, 0.0, 0.0]}})
