"""Pinhole camera model, calibration loading and the camera mount."""

from __future__ import annotations

import math
import os
from pathlib import Path

import cv2
import numpy as np
import pytest

from alight.cameras import CameraModel, CameraMount, PinholeCamera, camera_pose_W, load_camera
from alight.errors import InputError
from alight.types import rot_z

_TESTDATA = Path(
    os.environ.get(
        "ALIGHT_TESTDATA", Path(__file__).resolve().parents[2] / ".." / "shared" / "testdata" / "real"
    )
)
_CHARUCO_DIR = _TESTDATA / "aruco_charuco_real_photos"


def _needs_testdata() -> None:
    if not _CHARUCO_DIR.is_dir():
        pytest.skip(f"real test data not found at {_CHARUCO_DIR} (set ALIGHT_TESTDATA)")


def _K(f: float, cx: float, cy: float, fy: float | None = None, skew: float = 0.0) -> np.ndarray:
    return np.array([[f, skew, cx], [0.0, f if fy is None else fy, cy], [0.0, 0.0, 1.0]])


# cameras with every supported coefficient count, incl. the rational and thin-prism models
_CAMERAS = {
    "default": PinholeCamera.default_downward(),
    "none": PinholeCamera(640, 480, _K(500.0, 319.5, 239.5)),
    "k1k2p1p2": PinholeCamera(640, 480, _K(450.0, 322.0, 241.0, 452.0), np.array([-0.2, 0.05, 1e-3, -2e-3])),
    "strong5": PinholeCamera(  # the ChArUco tutorial calibration, copied here so the test needs no file
        640,
        480,
        _K(452.51072219637672, 317.70297317353277, 277.75155919135995, 456.76707935146891),
        np.array(
            [
                0.12136925618707872,
                -1.0854664722560681,
                1.1786843796668460e-04,
                -4.6240686046485508e-04,
                2.9542589406810080,
            ]
        ),
    ),
    "rational8": PinholeCamera(
        800, 600, _K(420.0, 401.0, 297.0), np.array([0.5, 0.1, 5e-4, 1e-4, 0.0, 0.8, 0.15, 0.0])
    ),
    "prism12": PinholeCamera(
        640,
        400,
        _K(380.0, 320.5, 199.0),
        np.array([-0.1, 0.02, 1e-4, -1e-4, 0.0, 0.0, 0.0, 0.0, 1e-3, -2e-4, 5e-4, 1e-4]),
    ),
}


def _pixel_grid(cam: PinholeCamera, step: int = 4) -> np.ndarray:
    v, u = np.mgrid[-0.5 : cam.height : step, -0.5 : cam.width : step]
    return np.stack([u.ravel(), v.ravel()], axis=1)


@pytest.mark.parametrize("name", sorted(_CAMERAS))
def test_unproject_project_round_trip_over_the_image(name: str) -> None:
    cam = _CAMERAS[name]
    assert isinstance(cam, CameraModel)
    uv = _pixel_grid(cam)
    rays = cam.unproject(uv)
    assert np.isfinite(rays).all()
    np.testing.assert_allclose(np.linalg.norm(rays, axis=1), 1.0, atol=1e-12)
    assert np.all(rays[:, 2] > 0)
    for depth in (0.3, 7.0):  # any point along the ray projects to the same pixel
        back = cam.project(rays * depth)
        assert np.max(np.abs(back - uv)) < 1e-6


@pytest.mark.parametrize("name", sorted(_CAMERAS))
def test_project_matches_opencv(name: str) -> None:
    cam = _CAMERAS[name]
    rng = np.random.default_rng(3)
    rays = cam.unproject(rng.uniform([0, 0], [cam.width - 1, cam.height - 1], size=(200, 2)))
    pts = rays * rng.uniform(0.5, 20.0, size=(200, 1))
    ref, _ = cv2.projectPoints(pts, np.zeros(3), np.zeros(3), cam.K, cam.dist if cam.dist.size else None)
    np.testing.assert_allclose(cam.project(pts), ref.reshape(-1, 2), atol=1e-6)


@pytest.mark.parametrize("name", sorted(_CAMERAS))
def test_principal_point_is_the_optical_axis(name: str) -> None:
    cam = _CAMERAS[name]
    cx, cy = cam.K[0, 2], cam.K[1, 2]
    # tangential and thin-prism terms are zero at r = 0, so the axis maps to the principal point exactly
    np.testing.assert_allclose(cam.project(np.array([[0.0, 0.0, 3.0]])), [[cx, cy]], atol=1e-12)
    np.testing.assert_allclose(cam.unproject(np.array([[cx, cy]])), [[0.0, 0.0, 1.0]], atol=1e-12)


def test_points_behind_or_on_the_camera_plane_are_nan() -> None:
    cam = _CAMERAS["default"]
    pts = np.array([[0.1, 0.2, -1.0], [0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.1, 0.1, 2.0], [np.nan, 0, 1]])
    uv = cam.project(pts)
    assert np.isnan(uv[[0, 1, 2, 4]]).all()
    assert np.isfinite(uv[3]).all()


def test_no_image_beyond_the_monotonic_radius() -> None:
    # x (1 - 0.5 x^2) peaks at r = sqrt(2/3): beyond, a polynomial lens folds back into the image
    cam = PinholeCamera(640, 480, _K(200.0, 319.5, 239.5), np.array([-0.5, 0.0, 0.0, 0.0]))
    assert cam.r_max == pytest.approx(math.sqrt(2 / 3), abs=2e-3)
    assert np.isnan(cam.project(np.array([[1.0, 0.0, 1.0]]))).all()  # r = 1 > r_max
    assert np.isfinite(cam.project(np.array([[0.7, 0.0, 1.0]]))).all()
    r_d_max = math.sqrt(2 / 3) * (1 - 0.5 * 2 / 3)  # the largest distorted radius: 0.544
    uv = np.array([[319.5 + 200.0 * (r_d_max + 0.05), 239.5], [319.5 + 200.0 * (r_d_max - 0.05), 239.5]])
    rays = cam.unproject(uv)
    assert np.isnan(rays[0]).all() and np.isfinite(rays[1]).all()


def test_fov_closed_form_without_distortion() -> None:
    cam = PinholeCamera(752, 480, _K(400.0, 375.5, 239.5))
    h, v = cam.fov_rad()
    assert h == pytest.approx(2 * math.atan(376 / 400.0), abs=1e-12)
    assert v == pytest.approx(2 * math.atan(240 / 400.0), abs=1e-12)
    hd, vd = PinholeCamera.default_downward().fov_rad()  # barrel distortion widens the view
    assert math.degrees(hd) == pytest.approx(90.7, abs=0.1) and hd > h


@pytest.mark.parametrize(
    "kwargs",
    [
        {"K": np.eye(3) * np.array([1, 1, 2])},
        {"K": _K(-1.0, 1.0, 1.0)},
        {"K": _K(500.0, 320.0, 240.0, skew=0.5)},  # OpenCV's model has no skew
        {"dist": np.zeros(6)},
        {"dist": np.array([np.nan, 0, 0, 0])},
        {"width": 0},
        {"width": 10.5},
    ],
)
def test_camera_rejects_bad_parameters(kwargs: dict) -> None:
    args = {"width": 640, "height": 480, "K": _K(500.0, 320.0, 240.0), "dist": np.zeros(5)} | kwargs
    with pytest.raises(ValueError):
        PinholeCamera(**args)


def test_opencv_yaml_round_trip(tmp_path: Path) -> None:
    cam = _CAMERAS["rational8"]
    path = tmp_path / "cam.yaml"
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    fs.write("image_width", cam.width)
    fs.write("image_height", cam.height)
    fs.write("camera_matrix", cam.K)
    fs.write("distortion_coefficients", cam.dist.reshape(1, -1))
    fs.release()
    back = load_camera(path)
    assert isinstance(back, PinholeCamera)
    assert (back.width, back.height) == (cam.width, cam.height)
    np.testing.assert_array_equal(back.K, cam.K)
    np.testing.assert_array_equal(back.dist, cam.dist)


def test_real_calibration_files() -> None:
    _needs_testdata()
    cam = load_camera(_CHARUCO_DIR / "tutorial_camera_charuco.yml")
    assert isinstance(cam, PinholeCamera)
    assert (cam.width, cam.height) == (640, 480)
    np.testing.assert_allclose(cam.K[0], [452.51072219637672, 0.0, 317.70297317353277])
    np.testing.assert_allclose(cam.dist[[0, 4]], [0.12136925618707872, 2.9542589406810080])
    # this file stores no image size: it must be supplied
    with pytest.raises(InputError, match="image_width"):
        PinholeCamera.from_opencv_yaml(_CHARUCO_DIR / "tutorial_camera_params.yml")
    cam2 = PinholeCamera.from_opencv_yaml(_CHARUCO_DIR / "tutorial_camera_params.yml", width=640, height=480)
    np.testing.assert_allclose(cam2.K[:2, 2], [324.099, 260.908])
    np.testing.assert_allclose(cam2.dist, [0.0995485, -0.206384, 0.00754589, 0.00336531, 0.0])
    uv = _pixel_grid(cam2, 8)
    assert np.max(np.abs(cam2.project(cam2.unproject(uv) * 2.0) - uv)) < 1e-6


def test_load_camera_errors(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="not found"):
        load_camera(tmp_path / "missing.yaml")
    (tmp_path / "calib.ini").write_text("x")
    with pytest.raises(InputError, match="unknown camera calibration type"):
        load_camera(tmp_path / "calib.ini")
    (tmp_path / "empty.yaml").write_text("%YAML:1.0\n---\nimage_width: 10\nimage_height: 10\n")
    with pytest.raises(InputError, match="camera_matrix"):
        load_camera(tmp_path / "empty.yaml")


def test_downward_mount_image_top_is_the_vehicle_front() -> None:
    cam = PinholeCamera.default_downward()
    mount = CameraMount.downward(np.array([0.05, 0.0, -0.08]))
    yaw = 0.7
    p_WB = np.array([3.0, -2.0, 10.0])
    R_WB = rot_z(yaw)
    p_WC, R_WC = camera_pose_W(p_WB, R_WB, mount)
    np.testing.assert_allclose(p_WC, p_WB + R_WB @ np.array([0.05, 0.0, -0.08]))
    np.testing.assert_allclose(R_WC[:, 2], [0, 0, -1], atol=1e-15)  # optical axis down
    fwd_W, left_W = R_WB[:2, 0], R_WB[:2, 1]
    ground = np.array([[*(p_WC[:2] + 2.0 * fwd_W), 0.0], [*(p_WC[:2] + 2.0 * left_W), 0.0], [*p_WC[:2], 0.0]])
    uv = cam.project((ground - p_WC) @ R_WC)  # rows: R_WC^T (p - p_WC)
    cx, cy = cam.K[0, 2], cam.K[1, 2]
    np.testing.assert_allclose(uv[2], [cx, cy], atol=1e-9)  # nadir at the principal point
    assert uv[0, 1] < cy - 50 and abs(uv[0, 0] - cx) < 1e-9  # front -> image top
    assert uv[1, 0] < cx - 50 and abs(uv[1, 1] - cy) < 1e-9  # left -> image left


def test_mount_rejects_non_rotations() -> None:
    with pytest.raises(ValueError):
        CameraMount(np.diag([1.0, 1.0, -1.0]))
    with pytest.raises(ValueError):
        CameraMount(np.eye(3), np.array([0.0, np.inf, 0.0]))


def test_corrupt_calibration_file_is_an_input_error(tmp_path) -> None:  # type: ignore[no-untyped-def]
    from alight.errors import InputError

    bad = tmp_path / "bad.yml"
    bad.write_text("not: [yaml\n")
    with pytest.raises(InputError, match="not a readable OpenCV calibration file"):
        PinholeCamera.from_opencv_yaml(bad)
