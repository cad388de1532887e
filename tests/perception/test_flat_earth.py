"""Flat-earth geolocation (paper 003 eq. 5-9): closed-form nadir cases, round trips through each camera
model's project, misses, and the first-order covariance against Monte Carlo."""

from __future__ import annotations

import math

import numpy as np
import pytest

from alight.cameras.omni import OmniCamera
from alight.cameras.pinhole import CameraMount, PinholeCamera, camera_pose_W
from alight.estimation.kim_ukf import rotation_zyx
from alight.perception import Geolocator
from alight.perception.flat_earth import FlatEarthGeolocator, flat_earth_jacobians, ground_intersection
from alight.types import Observation, rot_z

MOUNT = CameraMount.downward()
PINHOLE = PinholeCamera(640, 480, np.array([[400.0, 0, 319.5], [0, 400.0, 239.5], [0, 0, 1]]))
# the fisheye of testdata/real/fisheye_ocamcalib/calib_results_0.txt (ss, centre, affine)
FISHEYE = OmniCamera(
    width=1600,
    height=1600,
    ss=np.array([-4.714441e02, 0.0, 7.356108e-04, -3.773045e-07, 5.800006e-10]),
    xc=794.308657,
    yc=798.175741,
    c=1.000305,
    d=-0.000277,
    e=-0.000925,
    rho_max=800.0,
)


def obs(px: np.ndarray, t: float = 1.0) -> Observation:
    return Observation(t=t, kind="blob", quality=1.0, pixels=np.atleast_2d(px))


def cameras() -> list[object]:
    cams: list[object] = [PINHOLE, PinholeCamera.default_downward(), FISHEYE]
    try:
        from alight.cameras.omni import OmniCamera

        cams.append(
            OmniCamera(width=1600, height=1600, ss=FISHEYE.ss, xc=FISHEYE.xc, yc=FISHEYE.yc, c=FISHEYE.c,
                       d=FISHEYE.d, e=FISHEYE.e)
        )  # fmt: skip
    except ImportError:  # pragma: no cover - the omnidirectional model is written in parallel
        pass
    return cams


def test_satisfies_the_geolocator_protocol() -> None:
    assert isinstance(FlatEarthGeolocator(PINHOLE, MOUNT), Geolocator)


@pytest.mark.parametrize("yaw", [0.0, 0.3, -2.0])
def test_nadir_camera_on_a_level_vehicle_is_pixel_offset_times_height_over_f(yaw: float) -> None:
    """Level vehicle, downward camera: a pixel (du, dv) from the principal point is (du, dv) H / f in the
    camera's x, y, which the mount puts at (-dv, -du) H / f in the body's x, y."""
    H, deck = 7.5, 0.6
    geo = FlatEarthGeolocator(PINHOLE, MOUNT, deck_height_m=deck, sigma_height_m=0.0)
    p_WB = np.array([3.0, -2.0, deck + H])
    for du, dv in ((0.0, 0.0), (40.0, 0.0), (0.0, -25.0), (-100.0, 60.0)):
        m = geo.locate(obs(np.array([319.5 + du, 239.5 + dv])), p_WB, rot_z(yaw))
        assert m is not None and m.t == 1.0
        expected = p_WB + rot_z(yaw) @ np.array([-dv * H / 400.0, -du * H / 400.0, -H])
        assert np.allclose(m.p_WP, expected, atol=1e-12)
        assert m.p_WP[2] == pytest.approx(deck)


@pytest.mark.parametrize("k", range(len(cameras())))
def test_round_trip_through_project(k: int) -> None:
    """A ground point projected by the camera model and geolocated from that pixel comes back, for tilted
    poses and any of the camera models."""
    cam = cameras()[k]
    rng = np.random.default_rng(k)
    geo = FlatEarthGeolocator(cam, MOUNT, deck_height_m=0.4)
    n_ok = 0
    for _ in range(60):
        R_WB = rotation_zyx(np.array([rng.uniform(-0.3, 0.3), rng.uniform(-0.3, 0.3), rng.uniform(-3, 3)]))
        p_WB = np.array([rng.uniform(-5, 5), rng.uniform(-5, 5), rng.uniform(2, 20)])
        p_T = np.r_[p_WB[:2] + rng.uniform(-1.2, 1.2, 2) * (p_WB[2] - 0.4), 0.4]
        p_WC, R_WC = camera_pose_W(p_WB, R_WB, MOUNT)
        px = cam.project((R_WC.T @ (p_T - p_WC))[None])[0]  # type: ignore[attr-defined]
        if not (np.isfinite(px).all() and 0 <= px[0] < cam.width and 0 <= px[1] < cam.height):  # type: ignore[attr-defined]
            continue
        m = geo.locate(obs(px), p_WB, R_WB)
        if m is None:  # beyond the 85 deg limit
            assert math.degrees(math.acos((p_WC[2] - 0.4) / np.linalg.norm(p_T - p_WC))) > 84.9
            continue
        n_ok += 1
        assert np.allclose(m.p_WP, p_T, atol=1e-8 * np.linalg.norm(p_T - p_WC))
        assert np.allclose(m.cov_p_WP, m.cov_p_WP.T) and np.linalg.eigvalsh(m.cov_p_WP).min() > 0
    assert n_ok > 20


def test_rays_that_miss_the_plane_give_none() -> None:
    geo = FlatEarthGeolocator(FISHEYE, MOUNT, deck_height_m=0.0)
    level = np.eye(3)
    p = np.array([0.0, 0.0, 10.0])
    # a fisheye pixel 93 deg off axis points above the horizon of a level downward camera
    rho = 800.0
    px_up = np.array([FISHEYE.yc + rho, FISHEYE.xc])
    assert geo.locate(obs(px_up), p, level) is None
    # 86 deg: below the horizon but beyond max_nadir_angle (85 deg)
    ray = np.array([math.sin(math.radians(86)), 0.0, math.cos(math.radians(86))])
    assert geo.locate(obs(FISHEYE.project(ray[None])[0]), p, level) is None
    ray84 = np.array([math.sin(math.radians(84)), 0.0, math.cos(math.radians(84))])
    assert geo.locate(obs(FISHEYE.project(ray84[None])[0]), p, level) is not None
    # upside down, below the deck, no pixel, outside the image circle
    flipped = rotation_zyx(np.array([math.pi, 0.0, 0.0]))
    assert geo.locate(obs(np.array([FISHEYE.yc, FISHEYE.xc])), p, flipped) is None
    assert geo.locate(obs(np.array([FISHEYE.yc, FISHEYE.xc])), np.array([0.0, 0.0, -1.0]), level) is None
    assert geo.locate(Observation(t=0.0, kind="blob", quality=1.0), p, level) is None
    assert geo.locate(obs(np.array([FISHEYE.yc + 900.0, FISHEYE.xc])), p, level) is None
    assert ground_intersection(np.array([1.0, 0.0, 0.0]), 5.0) is None
    with pytest.raises(ValueError):
        geo.locate(obs(np.array([1.0, 1.0])), np.array([0.0, math.nan, 1.0]), level)


def test_several_pixels_use_their_mean() -> None:
    geo = FlatEarthGeolocator(PINHOLE, MOUNT)
    p, R = np.array([0.0, 0.0, 5.0]), np.eye(3)
    two = geo.locate(obs(np.array([[300.0, 200.0], [340.0, 260.0]])), p, R)
    one = geo.locate(obs(np.array([320.0, 230.0])), p, R)
    assert two is not None and one is not None and np.allclose(two.p_WP, one.p_WP)


def test_jacobians_against_finite_differences() -> None:
    d = np.array([0.3, -0.2, -0.9])
    H = 6.0
    J_d, J_att, J_H = flat_earth_jacobians(d, H)
    h = 1e-6
    for k in range(3):
        e = np.zeros(3)
        e[k] = h
        num_d = (ground_intersection(d + e, H) - ground_intersection(d - e, H)) / (2 * h)
        assert np.allclose(J_d[:, k], num_d, atol=1e-6)
        num_a = (ground_intersection(d + np.cross(e, d), H) - ground_intersection(d - np.cross(e, d), H)) / (
            2 * h
        )
        assert np.allclose(J_att[:, k], num_a, atol=1e-6)
    num_H = (ground_intersection(d, H + h) - ground_intersection(d, H - h)) / (2 * h)
    assert np.allclose(J_H, num_H, atol=1e-7)


def _exp_so3(w: np.ndarray) -> np.ndarray:
    th = np.linalg.norm(w)
    if th < 1e-15:
        return np.eye(3)
    k = w / th
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(th) * K + (1 - math.cos(th)) * (K @ K)


@pytest.mark.parametrize("cam", [PINHOLE, FISHEYE], ids=["pinhole", "fisheye"])
def test_covariance_matches_monte_carlo(cam: object) -> None:
    """Pixel, attitude, height and ego-position noise drawn around a tilted, oblique view: the sample
    covariance of the geolocated point, whitened by the predicted one, is the identity (first order)."""
    sig_px, sig_att, sig_H, sig_pos = 2.0, 0.01, 0.1, 0.05
    deck = 0.5
    geo = FlatEarthGeolocator(
        cam, MOUNT, deck_height_m=deck, sigma_px=sig_px, sigma_att_rad=sig_att, sigma_height_m=sig_H,
        sigma_ego_pos_m=sig_pos,
    )  # fmt: skip
    R_WB = rotation_zyx(np.array([0.12, -0.08, 0.7]))
    p_WB = np.array([1.0, 2.0, 10.5])
    p_T = np.array([4.0, 5.5, deck])
    p_WC, R_WC = camera_pose_W(p_WB, R_WB, MOUNT)
    px = cam.project((R_WC.T @ (p_T - p_WC))[None])[0]  # type: ignore[attr-defined]
    m0 = geo.locate(obs(px), p_WB, R_WB)
    assert m0 is not None and np.allclose(m0.p_WP, p_T, atol=1e-9)
    rng = np.random.default_rng(0)
    N = 4000
    err = np.empty((N, 3))
    for i in range(N):
        geo.deck_height_m = deck + rng.normal(0, sig_H)  # the error of H under the vehicle
        R_meas = _exp_so3(rng.normal(0, sig_att, 3)) @ R_WB
        p_meas = p_WB + np.r_[rng.normal(0, sig_pos, 2), 0.0]
        m = geo.locate(obs(px + rng.normal(0, sig_px, 2)), p_meas, R_meas)
        assert m is not None
        err[i] = m.p_WP - p_T
    C = np.cov(err.T)

    def whitened_deviation(cov: np.ndarray) -> float:
        L = np.linalg.cholesky(cov)
        return float(np.abs(np.linalg.solve(L, np.linalg.solve(L, C).T) - np.eye(3)).max())  # L^-1 C L^-T

    assert whitened_deviation(m0.cov_p_WP) < 0.1  # sampling error of a 4000-sample covariance: ~0.03
    assert np.abs(err.mean(axis=0)).max() < 4 * np.sqrt(np.diag(m0.cov_p_WP) / N).max() + 1e-3
    # every term matters here: the covariance without any one of them fails the same check
    geo.deck_height_m = deck
    full = dict(sigma_px=sig_px, sigma_att_rad=sig_att, sigma_height_m=sig_H, sigma_ego_pos_m=sig_pos)
    for name in full:
        g = FlatEarthGeolocator(cam, MOUNT, deck_height_m=deck, **{**full, name: 0.0})
        m = g.locate(obs(px), p_WB, R_WB)
        assert m is not None and whitened_deviation(m.cov_p_WP) > 0.1, name


def test_parameters_are_validated() -> None:
    with pytest.raises(ValueError):
        FlatEarthGeolocator(object(), MOUNT)
    with pytest.raises(ValueError):
        FlatEarthGeolocator(PINHOLE, MOUNT, sigma_px=-1.0)
    with pytest.raises(ValueError):
        FlatEarthGeolocator(PINHOLE, MOUNT, max_nadir_angle_rad=2.0)
    with pytest.raises(ValueError):
        FlatEarthGeolocator(PINHOLE, MOUNT, deck_height_m=math.inf)
