"""Fault models (``alight.sim.faults``) on their own: each fault does what it says to the data it is given,
draws its random numbers from its own stream, and leaves data alone when it is not configured."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from alight.errors import ConfigError
from alight.scenario import FaultSpec
from alight.sim.faults import Faults
from alight.sim.sensors import Imu, ImuConfig
from alight.types import EgoState, Observation


def _faults(camera: bool = True, perception_latency_s: float = 0.1, seed: int = 7, **spec: Any) -> Faults:
    return Faults(
        FaultSpec.model_validate(spec),
        np.random.SeedSequence(seed),
        camera=camera,
        latency_s=perception_latency_s,
    )


def _image(seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).integers(30, 200, (48, 64), dtype=np.uint8)


def test_no_faults_pass_every_message_through_unchanged() -> None:
    f = _faults()
    img = _image()
    assert f.frame(0.1, img) is img
    obs = [Observation(t=0.1, kind="truth", quality=1.0, p_CP=np.array([0.0, 0.0, 5.0]))]
    assert _faults(camera=False).frame(0.1, obs) is obs
    assert f.delivery_time(0.3) == 0.3 + 0.1
    assert f.range(1.0, 2.5) == 2.5
    odo = EgoState(
        t=1.0, p_WB=np.ones(3), v_WB=np.zeros(3), q_WB=np.array([0, 0, 0, 1.0]), w_WB_B=np.zeros(3)
    )
    assert f.odometry(odo) is odo
    assert f.before_imu_batch(1, 5, Imu(ImuConfig(), np.random.default_rng(0))) == 5


def test_dropout_loses_frames_and_blackout_delivers_dark_frames() -> None:
    f = _faults(dropout_prob=1.0)
    assert all(f.frame(0.05 * i, _image(i)) is None for i in range(20))
    f = _faults(dropout_prob=0.3)
    lost = sum(f.frame(0.05 * i, _image(i)) is None for i in range(2000))
    assert 500 < lost < 700  # binomial(2000, 0.3): 600 +- 20
    f = _faults(blackouts=[[1.0, 2.0]])
    lit = f.frame(0.5, _image())
    assert isinstance(lit, np.ndarray) and lit.max() > 0
    dark = f.frame(1.5, _image())
    assert isinstance(dark, np.ndarray) and dark.shape == (48, 64) and dark.max() == 0


def test_perception_dropout_prob_acts_on_camera_frames_too() -> None:
    f = Faults(FaultSpec(), np.random.SeedSequence(1), camera=True, latency_s=0.1, extra_dropout_prob=1.0)
    assert f.frame(0.0, _image()) is None


@pytest.mark.parametrize(
    "kind",
    [
        {"noise": {"prob": 1.0, "sigma_dn": 40.0}},
        {"occlusion": {"prob": 1.0}},
        {"exposure": {"prob": 1.0, "gain": 4.0}},
        {"stripes": {"prob": 1.0}},
    ],
    ids=lambda k: next(iter(k)),
)
def test_each_corruption_changes_the_frame_without_touching_the_original(kind: dict[str, Any]) -> None:
    f = _faults(corruption=kind)
    img = _image()
    before = img.copy()
    out = f.frame(0.0, img)
    assert isinstance(out, np.ndarray) and out.shape == img.shape and out.dtype == np.uint8
    assert np.array_equal(img, before)  # the rendered frame is not modified in place
    changed = out != img
    name = next(iter(kind))
    if name == "noise":
        assert changed.mean() > 0.9
    elif name == "exposure":
        assert out.mean() > 2.0 * img.mean()
    elif name == "occlusion":
        rows, cols = np.nonzero(out == 20)
        assert rows.size >= (0.2 * 48) * (0.2 * 64)  # a rectangle of at least half the size fraction
        assert np.all(out[rows.min() : rows.max() + 1, cols.min() : cols.max() + 1] == 20)
    else:  # stripes: whole rows or whole columns
        assert changed.any(axis=1).all() or changed.any(axis=0).all()


def test_noise_burst_lasts_its_frames() -> None:
    f = _faults(corruption={"noise": {"prob": 0.02, "frames": 4}})
    noisy = [not np.array_equal(np.asarray(f.frame(0.05 * i, _image(i))), _image(i)) for i in range(3000)]
    runs: list[int] = []
    n = 0
    for x in [*noisy, False]:
        if x:
            n += 1
        elif n:
            runs.append(n)
            n = 0
    assert runs and all(r % 4 == 0 for r in runs)  # back-to-back bursts join


def test_frozen_frame_is_the_previous_frame_again() -> None:
    f = _faults(corruption={"frozen": {"prob": 1.0}})
    first = f.frame(0.0, _image(0))
    second = f.frame(0.05, _image(1))
    assert isinstance(first, np.ndarray) and np.array_equal(first, _image(0))  # nothing to repeat yet
    assert isinstance(second, np.ndarray) and np.array_equal(second, first)
    # The ground-truth sensor: the previous report again, with the new capture time.
    g = _faults(camera=False, corruption={"frozen": {"prob": 1.0}})
    obs = [Observation(t=0.0, kind="truth", quality=1.0, p_CP=np.array([0.1, 0.2, 5.0]))]
    g.frame(0.0, obs)
    again = g.frame(0.05, [])
    assert isinstance(again, list) and len(again) == 1
    assert again[0].t == 0.05 and np.array_equal(again[0].p_CP, obs[0].p_CP)  # type: ignore[arg-type]


def test_image_corruptions_are_refused_without_a_camera() -> None:
    f = _faults(camera=False, corruption={"stripes": {"prob": 0.1}})
    with pytest.raises(ConfigError, match=r"faults.corruption needs a camera preset.*stripes"):
        f.check_preset("groundtruth", uses_camera=False)
    _faults(camera=False, corruption={"frozen": {"prob": 0.1}}).check_preset("groundtruth", False)
    f.check_preset("falanga2017", uses_camera=True)


def test_latency_jitter_is_bounded_and_delivery_keeps_capture_order() -> None:
    f = _faults(perception_latency_s=0.2, latency_s=0.05, latency_jitter_s=0.05)
    caps = np.arange(400) * 0.05
    dels = np.array([f.delivery_time(float(t)) for t in caps])
    lat = dels - caps
    assert np.all(np.diff(dels) >= 0.0)  # in order
    assert lat.min() >= 0.25 - 0.05 - 1e-12 and lat.max() <= 0.25 + 0.05 + 1e-9
    assert abs(lat.mean() - 0.25) < 0.01 and lat.std() > 0.02  # uniform +-50 ms: std 29 ms
    # A jitter larger than the frame period: a late frame holds back the next ones, never overtaken.
    g = _faults(perception_latency_s=0.0, latency_s=0.2, latency_jitter_s=0.2)
    d = [g.delivery_time(0.02 * i) for i in range(500)]
    assert all(b >= a for a, b in zip(d, d[1:], strict=False))


def test_range_dropouts_and_spurious_returns() -> None:
    f = _faults(range_dropout_prob=1.0)
    assert all(f.range(0.01 * i, 3.0) == math.inf for i in range(50))
    f = _faults(range_dropouts=[[1.0, 2.0]])
    assert f.range(0.5, 3.0) == 3.0 and f.range(1.5, 3.0) == math.inf and f.range(2.5, 3.0) == 3.0
    f = _faults(range_spurious_prob=1.0)
    r = np.array([f.range(0.01 * i, 3.0) for i in range(2000)])
    assert r.min() >= 0.0 and r.max() <= 14.0 and r.std() > 3.0  # uniform on [0, 14]: std 4.0


def test_flow_dropouts_withhold_samples_and_draw_from_their_own_stream() -> None:
    assert all(_faults().flow_delivered(0.02 * i) for i in range(100))  # no fault: no draw, all delivered
    assert not any(_faults(flow_dropout_prob=1.0).flow_delivered(0.02 * i) for i in range(100))
    f = _faults(flow_dropouts=[[1.0, 2.0]])
    assert [f.flow_delivered(t) for t in (0.5, 1.0, 1.5, 2.0, 2.5)] == [True, False, False, False, True]
    # a 30 % dropout: about 30 % lost, the same samples on every run, and the other streams unchanged
    runs = [_faults(flow_dropout_prob=0.3, range_dropout_prob=0.5) for _ in range(2)]
    kept = [np.array([f.flow_delivered(0.02 * i) for i in range(5000)]) for f in runs]
    assert np.array_equal(kept[0], kept[1]) and abs(kept[0].mean() - 0.7) < 0.02
    ranges = [_faults(range_dropout_prob=0.5, **extra) for extra in ({}, {"flow_dropout_prob": 0.3})]
    for f in ranges[1:]:
        for i in range(50):
            f.flow_delivered(0.02 * i)
    assert [ranges[0].range(0.01 * i, 3.0) for i in range(200)] == [
        ranges[1].range(0.01 * i, 3.0) for i in range(200)
    ]


def test_odometry_jump_shifts_later_positions_and_dropouts_withhold_messages() -> None:
    f = _faults(odometry_jumps=[{"t_s": 2.0, "offset_m": [0.5, 0.0, 0.0]}], odometry_dropouts=[[5.0, 6.0]])

    def odo(t: float) -> EgoState:
        return EgoState(
            t=t,
            p_WB=np.array([1.0, 2.0, 3.0]),
            v_WB=np.ones(3),
            q_WB=np.array([0, 0, 0, 1.0]),
            w_WB_B=np.zeros(3),
        )

    a, b = f.odometry(odo(1.9)), f.odometry(odo(2.0))
    assert a is not None and b is not None
    assert np.allclose(a.p_WB, [1, 2, 3]) and np.allclose(b.p_WB, [1.5, 2, 3]) and np.allclose(b.v_WB, 1.0)
    assert f.odometry(odo(5.5)) is None
    later = f.odometry(odo(7.0))
    assert later is not None and np.allclose(later.p_WB, [1.5, 2, 3])  # the VIO stays re-localised


def test_imu_bias_step_lands_on_the_first_sample_at_its_time() -> None:
    dt = 0.005
    f = Faults(
        FaultSpec.model_validate(
            {
                "accel_bias_steps": [{"t_s": 0.1, "delta": [0.2, 0, 0]}],
                "gyro_bias_steps": [{"t_s": 0.1, "delta": [0, 0, 0.01]}],
            }
        ),
        np.random.SeedSequence(0),
        camera=True,
        latency_s=0.0,
        tick_dt=dt,
    )
    imu = Imu(ImuConfig(accel_bias_random_walk=0.0, gyro_bias_random_walk=0.0), np.random.default_rng(3))
    b0 = np.concatenate([imu.accel_bias, imu.gyro_bias])
    assert f.before_imu_batch(16, 5, imu) == 4  # the batch 16..20 is cut at tick 20 (t = 0.1 s)
    assert np.array_equal(np.concatenate([imu.accel_bias, imu.gyro_bias]), b0)
    assert f.before_imu_batch(20, 5, imu) == 5
    step = np.concatenate([imu.accel_bias, imu.gyro_bias]) - b0
    assert np.allclose(step, [0.2, 0, 0, 0, 0, 0.01])


def test_fault_streams_are_independent() -> None:
    # Adding a corruption does not change which frames the dropout loses (one stream per fault).
    a = _faults(dropout_prob=0.5)
    b = _faults(dropout_prob=0.5, corruption={"stripes": {"prob": 0.5}, "noise": {"prob": 0.3}})
    lost_a = [a.frame(0.05 * i, _image()) is None for i in range(300)]
    lost_b = [b.frame(0.05 * i, _image()) is None for i in range(300)]
    assert lost_a == lost_b
