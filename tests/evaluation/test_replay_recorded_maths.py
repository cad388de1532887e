"""The maths behind a recorded flight's report: Euler angles and attitude differences against closed
forms, the held reference, and the frame sampler's bounds."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from alight.evaluation.recorded_flight import (
    CameraFrame,
    FrameSampler,
    PoseTrack,
    attitude_angle,
    difference,
    euler_rpy,
    frames_to_show,
    held_at,
    rms,
)


def _axis_quat(axis: int, angle: float) -> np.ndarray:
    q = np.zeros(4)
    q[axis] = math.sin(angle / 2)
    q[3] = math.cos(angle / 2)
    return q


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_euler_of_a_rotation_about_one_axis_is_that_angle(axis: int) -> None:
    """A rotation by a about B's x is roll a, about y pitch a (nose down in FLU), about z yaw a."""
    for a in (-1.2, -0.3, 0.0, 0.4, 1.1):
        rpy = euler_rpy(_axis_quat(axis, a)[None, :])[0]
        expected = np.zeros(3)
        expected[axis] = a
        assert rpy == pytest.approx(expected, abs=1e-12)


def test_pitch_about_the_left_axis_puts_the_nose_down() -> None:
    nose_W = quat_rotate(_axis_quat(1, 0.3), np.array([1.0, 0.0, 0.0]))
    assert nose_W[2] < 0  # positive pitch about y (left) turns x (forward) down


def quat_rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    return np.asarray(Rotation.from_quat(q).apply(v))


def test_euler_round_trip_and_missing_rows() -> None:
    rng = np.random.default_rng(1)
    rpy = np.column_stack(
        [rng.uniform(-1, 1, 50), rng.uniform(-1.2, 1.2, 50), rng.uniform(-math.pi + 0.01, math.pi - 0.01, 50)]
    )
    q = Rotation.from_euler("ZYX", rpy[:, ::-1]).as_quat()
    q[3] = np.nan
    out = euler_rpy(q)
    assert np.isnan(out[3]).all()
    keep = np.arange(50) != 3
    assert out[keep] == pytest.approx(rpy[keep], abs=1e-9)


def test_attitude_angle_closed_form() -> None:
    a, b = 0.3, -0.9
    qa = np.array([_axis_quat(2, a), _axis_quat(0, 0.5)])
    qb = np.array([_axis_quat(2, b), -_axis_quat(0, 0.5)])  # -q is the same attitude
    assert attitude_angle(qa, qb) == pytest.approx([abs(a - b), 0.0], abs=1e-7)
    assert np.isnan(attitude_angle(qa[:1], np.full((1, 4), np.nan)))[0]


def test_held_at_is_the_sample_handed_over_before_the_row() -> None:
    t_src = np.array([0.0, 0.02, 0.04])
    v = np.array([[1.0], [2.0], [3.0]])
    # a row at a sample's own stamp still has the previous one (the sample arrives after that tick)
    out = held_at(t_src, v, np.array([-0.01, 0.0, 0.01, 0.02, 0.03, 0.5]))
    assert np.isnan(out[:2, 0]).all()
    assert out[2:, 0].tolist() == [1.0, 1.0, 2.0, 3.0]
    assert np.isnan(held_at(np.zeros(0), np.zeros((0, 3)), np.array([1.0]))).all()


def test_difference_against_a_track_with_a_known_offset() -> None:
    t_src = np.arange(0, 2.0, 0.01) + 0.005
    n = t_src.size
    p = np.column_stack([t_src, np.zeros(n), np.ones(n)])
    q = np.tile(_axis_quat(2, 0.2), (n, 1))
    track = PoseTrack(t_src, p, q, np.tile([1.0, 0, 0], (n, 1)))
    t = np.arange(0.02, 1.9, 0.02)
    p_est = held_at(t_src, p, t) + [0.0, 0.3, 0.4]
    v_est = np.tile([1.0, 0, 0], (t.size, 1))
    q_est = np.tile(_axis_quat(2, 0.2 + 0.05), (t.size, 1))
    s = difference(t, p_est, v_est, q_est, track).summary()
    assert s["position_rms_m"] == pytest.approx(0.5)
    assert s["velocity_rms_mps"] == pytest.approx(0.0)
    assert s["attitude_rms_deg"] == pytest.approx(math.degrees(0.05), rel=1e-6)
    assert rms(np.array([np.nan])) is None


def _frame(t: float) -> CameraFrame:
    return CameraFrame(t, np.zeros((2, 2), np.uint8), [])


def test_frame_sampler_keeps_a_bounded_evenly_spaced_subset() -> None:
    made: list[int] = []
    s = FrameSampler(3)
    for i in range(1000):

        def make(i: int = i) -> CameraFrame:
            made.append(i)
            return _frame(float(i))

        s.offer(make)
    kept = [int(f.t) for f in s.items]
    assert len(kept) <= 6 and kept[0] == 0
    steps = np.diff(kept)
    assert (steps == steps[0]).all() and steps[0] == s.stride  # evenly spaced
    assert len(made) < 30  # frames off the stride are never made (no copies of every frame)
    shown = s.spread(3)
    assert [f.t for f in shown] == sorted(f.t for f in shown) and len(shown) == 3


def test_frames_with_detections_come_first() -> None:
    with_det, without = FrameSampler(2), FrameSampler(2)
    for i in range(3):
        with_det.offer(lambda i=i: _frame(10.0 + i))
    for i in range(10):
        without.offer(lambda i=i: _frame(float(i)))
    shown = frames_to_show(with_det, without, n=5)
    assert len(shown) == 5 and sum(f.t >= 10 for f in shown) == 3
    assert [f.t for f in shown] == sorted(f.t for f in shown)


def test_a_long_series_is_drawn_as_an_envelope_that_keeps_its_spikes() -> None:
    """Beyond MAX_POINTS samples (a 20 min ULog's IMU) a series is drawn per bin: its min-max band keeps
    a one-sample spike that decimation would drop, and the mean line has one point per bin."""
    from alight.evaluation.plots import new_figure
    from alight.evaluation.recorded_plots import MAX_POINTS, _series

    n = 5 * MAX_POINTS + 7
    t = np.arange(n) * 0.005
    y = np.sin(t)
    y[73_457] = 40.0  # one spike, off any regular stride
    ax = new_figure(4, 3).add_subplot()
    _series(ax, t, y, color="tab:red", lw=0.8)
    (line,) = ax.get_lines()
    assert len(line.get_xdata()) == MAX_POINTS // 2
    band = ax.collections[0].get_paths()[0].vertices
    assert band[:, 1].max() == pytest.approx(40.0)
    assert band[:, 1].min() == pytest.approx(-1.0, abs=1e-6)
    # a short series is drawn as it is
    ax2 = new_figure(4, 3).add_subplot()
    _series(ax2, t[:100], y[:100], color="k")
    assert np.array_equal(ax2.get_lines()[0].get_ydata(), y[:100]) and not ax2.collections
