"""Platform paths: exact speed, non-holonomic heading, consistent derivatives, closure, determinism."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.special import ellipk, ellipkinc

from alight.sim.platform import (
    PATH_KINDS,
    Platform,
    PlatformConfig,
    ellipf_m1,
    pad_contains,
    pad_corners,
)

SPEED = 3.0


def _platform(kind: str, seed: int = 0, **kw) -> Platform:
    return Platform(PlatformConfig(path=kind, speed_mps=SPEED, **kw), np.random.default_rng(seed))


def _unwrap_diff(yaw):
    return np.diff(np.unwrap(yaw))


def test_elliptic_integral_matches_scipy():
    u = np.linspace(-9.0, 9.0, 101)
    np.testing.assert_allclose([ellipf_m1(x) for x in u], ellipkinc(u, -1.0), rtol=1e-14, atol=1e-14)


@pytest.mark.parametrize("kind", PATH_KINDS)
def test_speed_heading_and_derivatives_are_consistent(kind):
    pl = _platform(kind)
    h = 1e-3
    ts = np.arange(0.0, 120.0, h)
    st = pl.states(ts)
    assert np.all(st.p_WP[:, 2] == pl.config.pad_height_m)
    # speed: the analytic one is exactly the set speed, finite differences agree (chords are shorter
    # than arcs by (kappa v h)^2 / 24 < 1e-8 relative)
    np.testing.assert_allclose(np.linalg.norm(st.v_WP, axis=1), SPEED, rtol=1e-14)
    fd_speed = np.linalg.norm(np.diff(st.p_WP, axis=0), axis=1) / h
    np.testing.assert_allclose(fd_speed, SPEED, rtol=1e-7)
    # non-holonomic: the velocity points along the heading
    np.testing.assert_allclose(st.v_WP[:, 0], SPEED * np.cos(st.yaw), atol=1e-12)
    np.testing.assert_allclose(st.v_WP[:, 1], SPEED * np.sin(st.yaw), atol=1e-12)
    # the chord's direction is the mean heading, off the mid-point heading only where the curvature
    # steps (arc joins), so compare where it does not
    fd_v = np.diff(st.p_WP, axis=0) / h
    mid_yaw = st.yaw[:-1] + 0.5 * _unwrap_diff(st.yaw)
    smooth = np.abs(np.diff(st.yaw_rate)) < 1e-3
    assert smooth.mean() > 0.95
    np.testing.assert_allclose(fd_v[smooth, 0], SPEED * np.cos(mid_yaw[smooth]), atol=1e-6)
    np.testing.assert_allclose(fd_v[smooth, 1], SPEED * np.sin(mid_yaw[smooth]), atol=1e-6)
    # the acceleration integrates to the velocity change, and the heading rate to the heading change
    # (trapezoid rule over 1 s windows; where the curvature steps, the rule errs by up to half the step
    # times h, so h/2 times the total variation is allowed on top: a loose but rigorous bound, the
    # smooth paths get a pointwise test below)
    k = round(1.0 / h)
    jump_a = np.linalg.norm(np.diff(st.a_WP, axis=0), axis=1)
    jump_r = np.abs(np.diff(st.yaw_rate))
    for i in range(0, len(ts) - k, 997):
        sl = slice(i, i + k + 1)
        dv = np.trapezoid(st.a_WP[sl], dx=h, axis=0)
        tol = 1e-6 + 0.5 * h * jump_a[i : i + k].sum()
        np.testing.assert_allclose(dv, st.v_WP[i + k] - st.v_WP[i], rtol=0, atol=tol)
        dyaw = np.trapezoid(st.yaw_rate[sl], dx=h)
        tol = 1e-7 + 0.5 * h * jump_r[i : i + k].sum()
        assert dyaw == pytest.approx(np.unwrap(st.yaw[sl])[-1] - st.yaw[i], rel=0, abs=tol)
    # the acceleration is centripetal: perpendicular to the velocity
    np.testing.assert_allclose(np.einsum("ij,ij->i", st.a_WP, st.v_WP), 0.0, atol=1e-12)


@pytest.mark.parametrize("kind", ["circle", "figure8"])
def test_acceleration_is_the_derivative_of_velocity_on_smooth_paths(kind):
    pl = _platform(kind)
    h = 1e-4
    ts = np.linspace(0.0, 40.0, 400)
    a = pl.states(ts).a_WP
    fd = (pl.states(ts + h).v_WP - pl.states(ts - h).v_WP) / (2 * h)
    np.testing.assert_allclose(fd, a, atol=1e-6)


def test_state_and_states_agree():
    for kind in PATH_KINDS:
        pl = _platform(kind)
        ts = np.array([0.0, 3.3, 17.9, 101.2])
        st = pl.states(ts)
        for i, t in enumerate(ts):
            one = pl.state(float(t))
            np.testing.assert_allclose(one.p_WP, st.p_WP[i], atol=1e-12)
            np.testing.assert_allclose(one.a_WP, st.a_WP[i], atol=1e-12)
            assert one.yaw == pytest.approx(st.yaw[i], abs=1e-12)
            assert st.at(i).yaw_rate == one.yaw_rate


def test_every_path_starts_at_the_configured_pose():
    for kind in PATH_KINDS:
        pl = _platform(kind, start_xy_m=(-3.0, 4.0), start_heading=0.8)
        s0 = pl.state(0.0)
        np.testing.assert_allclose(s0.p_WP[:2], [-3.0, 4.0], atol=1e-12)
        assert s0.yaw == pytest.approx(0.8, abs=1e-12)


def test_circle_is_closed_and_centred_on_take_off_point_by_default():
    pl = _platform("circle")
    st = pl.states(np.linspace(0.0, 50.0, 1001))
    np.testing.assert_allclose(np.linalg.norm(st.p_WP[:, :2], axis=1), 10.0, atol=1e-10)
    assert pl.period_m == pytest.approx(2 * math.pi * 10.0)
    T = pl.period_m / SPEED
    np.testing.assert_allclose(pl.state(T).p_WP, pl.state(0.0).p_WP, atol=1e-10)
    np.testing.assert_allclose(st.yaw_rate, SPEED / 10.0)  # left turn
    right = _platform("circle", turn_left=False)
    assert right.state(1.0).yaw_rate == pytest.approx(-SPEED / 10.0)


def test_figure8_is_a_closed_lemniscate_through_its_start():
    pl = _platform("figure8")
    a = 15.0
    assert pl.period_m == pytest.approx(4 * a * ellipk(-1.0), rel=1e-14)  # 78.66 m around
    T = pl.period_m / SPEED
    s0 = pl.state(0.0)
    np.testing.assert_allclose(pl.state(T).p_WP, s0.p_WP, atol=1e-9)
    assert pl.state(T).yaw == pytest.approx(s0.yaw, abs=1e-9)
    # halfway round it crosses its start at right angles
    half = pl.state(0.5 * T)
    np.testing.assert_allclose(half.p_WP, s0.p_WP, atol=1e-9)
    assert abs(math.cos(half.yaw - s0.yaw)) < 1e-9
    # the tips are a from the crossing (30 m tip to tip), curvature 3 r / a^2 at distance r
    st = pl.states(np.linspace(0.0, T, 20001))
    r = np.linalg.norm(st.p_WP[:, :2] - s0.p_WP[:2], axis=1)
    assert r.max() == pytest.approx(a, abs=1e-6)
    np.testing.assert_allclose(np.abs(st.yaw_rate) / SPEED, 3 * r / a**2, atol=1e-9)
    # the two lobes turn opposite ways
    assert st.yaw_rate.max() > 0 > st.yaw_rate.min()


def test_tractor_rows_and_u_turns():
    L, R = 30.0, 4.0
    pl = _platform("tractor", start_xy_m=(0.0, 0.0), start_heading=0.0)
    row = pl.state(L / SPEED)
    np.testing.assert_allclose(row.p_WP[:2], [L, 0.0], atol=1e-12)
    turned = pl.state((L + math.pi * R) / SPEED)
    np.testing.assert_allclose(turned.p_WP[:2], [L, 2 * R], atol=1e-12)
    assert math.cos(turned.yaw) == pytest.approx(-1.0)  # reversed
    second = pl.state((2 * L + math.pi * R) / SPEED)
    np.testing.assert_allclose(second.p_WP[:2], [0.0, 2 * R], atol=1e-12)
    after = pl.state((2 * L + 2 * math.pi * R) / SPEED)
    np.testing.assert_allclose(after.p_WP[:2], [0.0, 4 * R], atol=1e-12)
    assert math.cos(after.yaw) == pytest.approx(1.0)
    # three periods on, rows keep stacking 4 R apart
    far = pl.state((3 * (2 * L + 2 * math.pi * R) + 10.0) / SPEED)
    np.testing.assert_allclose(far.p_WP[:2], [10.0, 12 * R], atol=1e-9)
    # U-turn curvature is 1 / R, the rows straight
    assert pl.state((L + 1.0) / SPEED).yaw_rate == pytest.approx(SPEED / R)
    assert pl.state((2 * L + math.pi * R + 1.0) / SPEED).yaw_rate == pytest.approx(-SPEED / R)
    assert pl.state(1.0).yaw_rate == 0.0


def test_straight_path():
    pl = _platform("straight", start_xy_m=(1.0, 2.0), start_heading=-0.5)
    st = pl.state(7.0)
    np.testing.assert_allclose(st.p_WP[:2], [1 + 21 * math.cos(-0.5), 2 + 21 * math.sin(-0.5)], atol=1e-12)
    np.testing.assert_allclose(st.a_WP, 0.0)


def test_random_path_bounded_curvature_and_determinism():
    pl = _platform("random", seed=11)
    ts = np.arange(0.0, 400.0, 0.05)
    st = pl.states(ts)
    kappa = st.yaw_rate / SPEED
    assert np.abs(kappa).max() <= 0.15
    assert np.abs(kappa).max() > 0.05  # it does turn
    assert np.sign(kappa).min() < 0 < np.sign(kappa).max()
    again = _platform("random", seed=11).states(ts)
    np.testing.assert_array_equal(again.p_WP, st.p_WP)
    other = _platform("random", seed=12).states(ts)
    assert np.abs(other.p_WP - st.p_WP).max() > 1.0
    # beyond the drawn length it goes straight on
    short = Platform(
        PlatformConfig(path="random", speed_mps=SPEED, random_length_m=100.0), np.random.default_rng(1)
    )
    assert short.state(200.0).yaw_rate == 0.0
    with pytest.raises(ValueError):
        Platform(PlatformConfig(path="random"))


def test_pad_geometry():
    p = np.array([2.0, -1.0, 0.5])
    yaw = math.radians(30.0)
    corners = pad_corners(p, yaw, 1.5)
    np.testing.assert_allclose(corners.mean(axis=0), p)
    np.testing.assert_allclose(np.linalg.norm(corners[:, :2] - p[:2], axis=1), 0.75 * math.sqrt(2))
    np.testing.assert_allclose(np.linalg.norm(corners[1] - corners[0]), 1.5)
    # the first corner is (+x, +y) of the pad frame
    d = corners[0, :2] - p[:2]
    local = np.array(
        [math.cos(yaw) * d[0] + math.sin(yaw) * d[1], -math.sin(yaw) * d[0] + math.cos(yaw) * d[1]]
    )
    np.testing.assert_allclose(local, [0.75, 0.75], atol=1e-12)
    assert pad_contains(p[:2], p, yaw, 1.5)
    # a point 0.7 m along the pad's x axis: inside, but not inside the pad shrunk by 0.2 m
    q = p[:2] + 0.7 * np.array([math.cos(yaw), math.sin(yaw)])
    assert pad_contains(q, p, yaw, 1.5) and not pad_contains(q, p, yaw, 1.5, 0.2)
    # 0.7 m along W x at 45 deg heading is 0.495 m along each pad axis
    q45 = p[:2] + np.array([0.7, 0.0])
    assert pad_contains(q45, p, math.pi / 4, 1.5, 0.2)
    assert not pad_contains(p[:2] + np.array([0.76, 0.0]), p, 0.0, 1.5)
    many = pad_contains(np.array([p[:2], p[:2] + 5.0]), p, yaw, 1.5)
    np.testing.assert_array_equal(many, [True, False])
    pl = _platform("circle")
    assert pl.contains(pl.state(3.0).p_WP[:2], 3.0, 0.2)
    np.testing.assert_allclose(pl.pad_corners_W(3.0).mean(axis=0), pl.state(3.0).p_WP)


def test_config_validation():
    with pytest.raises(ValueError):
        PlatformConfig(path="spiral")  # type: ignore[arg-type]
    with pytest.raises(ValueError):
        PlatformConfig(speed_mps=-1.0)
    with pytest.raises(ValueError):
        PlatformConfig(circle_radius_m=0.0)
