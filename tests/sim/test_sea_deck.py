"""The pad's kinematics on a moving deck (alight.sim.sea.deck): exact velocity, acceleration, angular
velocity and acceleration against finite differences, the ZYX attitude, a still sea, a platform path."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from alight.sim.platform import Platform, PlatformConfig
from alight.sim.sea import DeckMotion, SeaConfig, VesselPath, synthesise
from alight.sim.sea.deck import PadKinematics
from alight.sim.sea.vessel import load_vessel

H = 1e-4  # finite-difference step (s)


def _weaving_path(t: np.ndarray) -> VesselPath:
    # every input term nonzero: a forward run with a sideways weave and a heading that swings
    t = np.asarray(t, dtype=np.float64)
    om, b = 0.3, 0.25
    p = np.stack([6.0 * t, 4.0 * np.sin(om * t), 0.5 + 0.0 * t], axis=1)
    v = np.stack([6.0 + 0.0 * t, 4.0 * om * np.cos(om * t), 0.0 * t], axis=1)
    a = np.stack([0.0 * t, -4.0 * om**2 * np.sin(om * t), 0.0 * t], axis=1)
    yaw = 0.7 + b * np.sin(om * t)
    return VesselPath(p, v, a, yaw, b * om * np.cos(om * t), -b * om**2 * np.sin(om * t))


def _deck(vessel: str = "patrol_boat", hs: float = 4.0, mu_deg: float = 150.0, seed: int = 3) -> DeckMotion:
    waves = synthesise(hs, 9.7, np.random.default_rng(seed), n=200)
    return DeckMotion(waves, load_vessel(vessel), 6.0, math.radians(mu_deg), (-6.0, 1.5, 2.0))


def _fd(f, t: np.ndarray) -> tuple[PadKinematics, PadKinematics, PadKinematics]:
    return f(t), f(t + H), f(t - H)


def _rel(x: np.ndarray, y: np.ndarray) -> float:
    return float(np.abs(x - y).max() / np.abs(y).max())


@pytest.mark.parametrize("vessel", ["small_usv", "patrol_boat", "frigate"])
def test_velocity_and_acceleration_match_finite_differences(vessel):
    deck = _deck(vessel)
    t = np.linspace(100.0, 400.0, 1501)
    k, kp, km = _fd(lambda tt: deck.pad(tt, _weaving_path(tt)), t)
    v_fd = (kp.p_WP - km.p_WP) / (2 * H)
    a_fd = (kp.v_WP - km.v_WP) / (2 * H)
    assert _rel(v_fd, k.v_WP) < 1e-6
    assert _rel(a_fd, k.a_WP) < 1e-6
    # the check can fail: without the w x r terms the velocity and acceleration are visibly wrong
    r_W = k.R_WP @ deck.r_B
    wxr = np.cross(k.w_WP_W, r_W)
    assert _rel(v_fd, k.v_WP - wxr) > 1e-2
    assert _rel(a_fd, k.a_WP - np.cross(k.dw_WP_W, r_W) - np.cross(k.w_WP_W, wxr)) > 1e-2


def test_angular_velocity_and_acceleration_match_finite_differences_of_r():
    deck = _deck("small_usv", hs=1.0, mu_deg=120.0)
    t = np.linspace(50.0, 200.0, 751)
    k, kp, km = _fd(lambda tt: deck.pad(tt, _weaving_path(tt)), t)
    r_dot = (kp.R_WP - km.R_WP) / (2 * H)
    skew = r_dot @ np.transpose(k.R_WP, (0, 2, 1))  # [w]x = R' R^T
    w_fd = np.stack([skew[:, 2, 1], skew[:, 0, 2], skew[:, 1, 0]], axis=1)
    assert _rel(w_fd, k.w_WP_W) < 1e-6
    assert _rel((kp.w_WP_W - km.w_WP_W) / (2 * H), k.dw_WP_W) < 1e-6
    # the body-axes rate is R^T w
    np.testing.assert_allclose(k.w_WP_P, np.einsum("nji,nj->ni", k.R_WP, k.w_WP_W), atol=1e-15)


def test_attitude_is_zyx_of_heading_plus_yaw_pitch_roll():
    deck = _deck("small_usv", hs=2.0, mu_deg=60.0)
    t = np.linspace(0.0, 60.0, 301)
    path = _weaving_path(t)
    k = deck.pad(t, path)
    q, _, _ = deck.axes(t)
    euler = np.stack([path.yaw + q[:, 5], q[:, 4], q[:, 3]], axis=1)
    np.testing.assert_allclose(k.R_WP, Rotation.from_euler("ZYX", euler).as_matrix(), atol=1e-14)
    # FLU signs: positive roll lifts the port side, positive pitch puts the bow down
    assert k.tilt_rad.max() > math.radians(2.0)
    np.testing.assert_allclose(k.normal_W, k.R_WP[:, :, 2])


def test_small_angle_pad_height_and_the_full_formula_agree_at_small_tilt():
    # sheet sec. 4: z_pad ~ z_c + heave + r_z + r_y roll - r_x pitch for small angles
    deck = _deck("frigate", hs=0.88, mu_deg=180.0)
    r = deck.r_B
    t = np.linspace(0.0, 300.0, 601)
    path = VesselPath.straight(t, 6.0, 0.4)
    k = deck.pad(t, path)
    q, _, _ = deck.axes(t)
    z_lin = q[:, 2] + r[2] + r[1] * q[:, 3] - r[0] * q[:, 4]
    tilt = k.tilt_rad.max()
    assert tilt < math.radians(1.0)
    assert np.abs(k.p_WP[:, 2] - z_lin).max() < 2.0 * np.linalg.norm(r) * tilt**2


def test_still_sea_carries_the_pad_rigidly_along_the_path():
    config = SeaConfig(sea_state=0, vessel="frigate")
    deck = DeckMotion.from_config(config, np.random.default_rng(0), 7.0)
    plat = Platform(PlatformConfig(path="circle", speed_mps=7.0, circle_radius_m=300.0, pad_height_m=0.0))
    t = np.linspace(0.0, 200.0, 401)
    states = plat.states(t)
    k = deck.pad(t, VesselPath.from_states(states))
    r = np.array(load_vessel("frigate").pad_offset_m)
    c, s = np.cos(states.yaw), np.sin(states.yaw)
    r_W = np.stack([c * r[0] - s * r[1], s * r[0] + c * r[1], np.full(t.size, r[2])], axis=1)
    np.testing.assert_allclose(k.p_WP, states.p_WP + r_W, atol=1e-9)
    np.testing.assert_allclose(k.tilt_rad, 0.0, atol=1e-12)
    # a rigid body turning at yaw_rate: the pad's velocity has the w x r term of the turn
    w = np.zeros((t.size, 3))
    w[:, 2] = states.yaw_rate
    np.testing.assert_allclose(k.v_WP, states.v_WP + np.cross(w, r_W), atol=1e-9)


def test_on_a_platform_path_the_kinematics_match_finite_differences():
    config = SeaConfig(sea_state=4, vessel="patrol_boat", wave_direction_deg=120.0)
    deck = DeckMotion.from_config(config, np.random.default_rng(11), 5.0)
    plat = Platform(PlatformConfig(path="circle", speed_mps=5.0, circle_radius_m=80.0, pad_height_m=0.0))

    def kin(tt: np.ndarray) -> PadKinematics:
        return deck.pad(tt, VesselPath.from_states(plat.states(tt)))

    t = np.linspace(10.0, 110.0, 501)
    k, kp, km = _fd(kin, t)
    assert _rel((kp.p_WP - km.p_WP) / (2 * H), k.v_WP) < 1e-6
    assert _rel((kp.v_WP - km.v_WP) / (2 * H), k.a_WP) < 1e-6


def test_one_platform_state_gives_the_same_pad_as_the_vectorised_call():
    config = SeaConfig(sea_state=4, vessel="small_usv", wave_direction_deg=135.0)
    deck = DeckMotion.from_config(config, np.random.default_rng(2), 1.5)
    plat = Platform(PlatformConfig(path="figure8", speed_mps=1.5, pad_height_m=0.0))
    t = np.array([0.0, 3.3, 17.9])
    many = deck.pad(t, VesselPath.from_states(plat.states(t)))
    for i, ti in enumerate(t):
        one = deck.pad(np.array([ti]), VesselPath.from_truth(plat.state(float(ti))))
        for field in ("p_WP", "R_WP", "v_WP", "a_WP", "w_WP_W", "dw_WP_W"):
            np.testing.assert_allclose(getattr(one, field)[0], getattr(many, field)[i], rtol=0, atol=1e-12)


def test_same_seed_same_deck_and_a_scalar_time_works():
    config = SeaConfig(sea_state=3, vessel="small_usv", wave_direction_deg=90.0)
    t = np.linspace(0.0, 20.0, 41)
    path = VesselPath.straight(t, 2.0, 0.0)
    a = DeckMotion.from_config(config, np.random.default_rng(9), 2.0).pad(t, path)
    b = DeckMotion.from_config(config, np.random.default_rng(9), 2.0).pad(t, path)
    c = DeckMotion.from_config(config, np.random.default_rng(10), 2.0).pad(t, path)
    np.testing.assert_array_equal(a.p_WP, b.p_WP)
    np.testing.assert_array_equal(a.R_WP, b.R_WP)
    assert not np.array_equal(a.p_WP, c.p_WP)
    deck = DeckMotion.from_config(config, np.random.default_rng(9), 2.0)
    one = deck.pad(np.array(3.5), VesselPath.straight(np.array([3.5]), 2.0, 0.0))
    assert one.p_WP.shape == (1, 3) and one.R_WP.shape == (1, 3, 3)
    np.testing.assert_array_equal(one.p_WP[0], a.p_WP[7])
    with pytest.raises(ValueError, match="states for"):
        deck.pad(t, VesselPath.straight(t[:3], 2.0, 0.0))
    with pytest.raises(ValueError, match="finite"):
        deck.pad(np.array([math.nan]), VesselPath.straight(np.zeros(1), 2.0, 0.0))
