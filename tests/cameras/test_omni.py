"""Omnidirectional camera (Scaramuzza / OCamCalib model): file format, round trips, axis convention,
paper 003's root selection, the synthetic fisheye, and two AprilTags on a real 186 deg fisheye image."""

from __future__ import annotations

import dataclasses
import math
import os
from pathlib import Path

import cv2
import numpy as np
import pytest

from alight.cameras import CameraModel, OmniCamera, PinholeCamera, load_camera, solve_rho
from alight.cameras.omni import fit_invpol, solve_rho_jit, valid_radius
from alight.errors import InputError
from alight.numerics.poly import positive_real_roots

_TESTDATA = Path(
    os.environ.get(
        "ALIGHT_TESTDATA", Path(__file__).resolve().parents[2] / ".." / "shared" / "testdata" / "real"
    )
)
_FISHEYE_DIR = _TESTDATA / "fisheye_ocamcalib"
_FILE0 = _FISHEYE_DIR / "calib_results_0.txt"
_PREM = _FISHEYE_DIR / "calib_results_omni_1024x768_premnirmal.txt"
_CIRCLE0_PX = 808.0
"""The image circle of img0.jpg measured on its diagonals (reference sheet §5: 802-818 px)."""


def _needs_testdata() -> None:
    if not _FISHEYE_DIR.is_dir():
        pytest.skip(f"real fisheye test data not found at {_FISHEYE_DIR} (set ALIGHT_TESTDATA)")


def _real(name: str, **kw: object) -> OmniCamera:
    _needs_testdata()
    path = {"file0": _FILE0, "premnirmal": _PREM}[name]
    if name == "file0":
        kw.setdefault("rho_max", _CIRCLE0_PX)
    return OmniCamera.from_ocamcalib(path, **kw)  # type: ignore[arg-type]


def _grid(cam: OmniCamera, step: float) -> np.ndarray:
    v, u = np.mgrid[0 : cam.height : step, 0 : cam.width : step]
    return np.stack([u.ravel(), v.ravel()], axis=1).astype(np.float64)


def _angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle between rows (rad), accurate for tiny angles."""
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=1), np.sum(a * b, axis=1))


def _rays_in_cone(half_angle: float, n: int, rng: np.random.Generator) -> np.ndarray:
    """Unit rays in C uniform on the sphere cap within ``half_angle`` of +z."""
    cz = rng.uniform(math.cos(half_angle), 1.0, n)
    phi = rng.uniform(-math.pi, math.pi, n)
    s = np.sqrt(1 - cz**2)
    return np.stack([s * np.cos(phi), s * np.sin(phi), cz], axis=1)


# ------------------------------------------------------------------------------------ file format


def test_reads_both_real_calibration_files() -> None:
    cam = _real("file0", rho_max=None)
    assert isinstance(cam, CameraModel)
    assert (cam.width, cam.height) == (1600, 1600)
    np.testing.assert_array_equal(cam.ss, [-4.714441e02, 0.0, 7.356108e-04, -3.773045e-07, 5.800006e-10])
    assert cam.invpol is not None and cam.invpol.size == 10
    assert cam.invpol[0] == 772.405470 and cam.invpol[-1] == 2.968883
    assert (cam.xc, cam.yc) == (794.308657, 798.175741)
    assert (cam.c, cam.d, cam.e) == (1.000305, -0.000277, -0.000925)
    prem = load_camera(_PREM)
    assert isinstance(prem, OmniCamera)
    # "height width" in the file: 768 1024
    assert (prem.width, prem.height) == (1024, 768)
    assert prem.invpol is not None and prem.invpol.size == 33 and prem.invpol[-1] == 13963.695510
    assert (prem.xc, prem.yc) == (382.828814, 456.345673)
    # default circle: the half-diagonal on which the toolbox fits invpol (sheet §5: theta_max there)
    assert prem.rho_max == 640.0
    assert prem.theta_max == pytest.approx(0.8022, abs=1e-4)
    assert cam.theta_max == pytest.approx(0.6578, abs=1e-4)


def _write(tmp_path: Path, text: str | bytes) -> Path:
    p = tmp_path / "calib_results.txt"
    if isinstance(text, bytes):
        p.write_bytes(text)
    else:
        p.write_text(text)
    return p


_GOOD = [
    "#polynomial coefficients for the DIRECT mapping function",
    "",
    "5 -4.714441e+02 0.000000e+00 7.356108e-04 -3.773045e-07 5.800006e-10 ",
    "",
    "#polynomial coefficients for the inverse mapping function",
    "",
    "10 772.405470 504.754051 7.034666 45.327180 54.651570 0.458049 -7.873745 15.588713 13.743404 2.968883 ",
    "",
    '#center: "row" and "column", starting from 0 (C convention)',
    "",
    "794.308657 798.175741",
    "",
    '#affine parameters "c", "d", "e"',
    "",
    "1.000305 -0.000277 -0.000925",
    "",
    '#image size: "height" and "width"',
    "",
    "1600 1600",
    "",
]


def _edit(line: int, new: str | None) -> str:
    lines = list(_GOOD)
    if new is None:
        del lines[line - 1]
    else:
        lines[line - 1] = new
    return "\n".join(lines)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("", "expected 5 data lines"),
        (_edit(19, None), "expected 5 data lines"),
        (
            _edit(3, "5 -4.714441e+02 0.0 7.356108e-04 -3.773045e-07"),
            "line 3: ss .* declares 5 coefficients but has 4",
        ),
        (_edit(7, "11 772.4 504.7"), "line 7: invpol .* declares 11 coefficients but has 2"),
        (_edit(11, "794.308657 nan"), "line 11: non-finite value 'nan'"),
        (_edit(15, "1.000305 -0.000277 abc"), "line 15: not a number: 'abc'"),
        (_edit(11, "794.3 798.1 1.0"), "line 11: centre needs 2 values, found 3"),
        (_edit(19, "1600.5 1600"), "line 19: image size must be positive integers"),
        (_edit(3, "5 4.714441e+02 0.0 7.356108e-04 -3.773045e-07 5.800006e-10"), "a0 must be negative"),
        (_edit(15, "0.0 1.0 1.0"), "c - d e must be positive"),
        (_edit(7, "3 500.0 300.0 1.0"), "invpol does not invert ss"),
        (b"\xff\xfe\x00garbage", "not a readable OCamCalib text file"),
    ],
)
def test_malformed_files_give_one_line_input_errors(tmp_path: Path, text: str | bytes, message: str) -> None:
    path = _write(tmp_path, text)
    with pytest.raises(InputError, match=message) as info:
        load_camera(path)
    msg = str(info.value)
    assert msg.startswith(str(path)) and "\n" not in msg


def test_written_file_reads_back_and_missing_file(tmp_path: Path) -> None:
    cam = load_camera(_write(tmp_path, "\n".join(_GOOD)))
    assert isinstance(cam, OmniCamera) and cam.invpol is not None and cam.invpol.size == 10
    with pytest.raises(InputError, match="not found"):
        OmniCamera.from_ocamcalib(tmp_path / "missing.txt")


def test_constructor_validation() -> None:
    ss = np.array([-300.0, 0.0, 1e-3])
    with pytest.raises(ValueError, match="a0"):
        OmniCamera(width=640, height=480, ss=-ss, xc=239.5, yc=319.5)
    with pytest.raises(ValueError, match="finite"):
        OmniCamera(width=640, height=480, ss=np.array([-300.0, np.nan]), xc=239.5, yc=319.5)
    # f = -300 + 1e-2 rho^2: rho f' - f = 300 + 1e-2 rho^2 > 0 always; a cubic that folds back:
    fold = np.array([-300.0, 0.0, 0.0, 1e-6])  # rho f' - f = 300 + 2e-6 rho^3 ... monotonic too
    assert valid_radius(fold, 1000.0) == 1000.0
    folding = np.array([-300.0, 0.0, 2e-3, -2e-6])  # rho f' - f = 300 + 2e-3 rho^2 - 4e-6 rho^3
    r_fold = valid_radius(folding, 2000.0)
    rho = np.linspace(0, 2000, 200001)
    g = 300 + 2e-3 * rho**2 - 4e-6 * rho**3
    assert r_fold == pytest.approx(rho[np.argmax(g <= 0)], abs=0.3)
    with pytest.raises(ValueError, match="elevation stops increasing"):
        OmniCamera(width=2000, height=2000, ss=folding, xc=999.5, yc=999.5, rho_max=r_fold + 5)
    ok = OmniCamera(width=2000, height=2000, ss=folding, xc=999.5, yc=999.5, rho_max=0.75 * r_fold)
    assert ok.invpol_max_err_px < 0.01
    with pytest.raises(ValueError, match="newton_steps"):
        OmniCamera(width=640, height=480, ss=ss, xc=239.5, yc=319.5, newton_steps=-1)


# ------------------------------------------------------------------------------------ round trips


@pytest.mark.parametrize(("name", "step"), [("file0", 4.0), ("premnirmal", 2.0)])
def test_pixel_ray_pixel_round_trip_over_the_image_circle(name: str, step: float) -> None:
    """Every frame pixel inside the image circle (file 0: rho <= 808 px, 188 deg; premnirmal: the
    half-diagonal, 272 deg) -> unproject -> project at two depths -> the same pixel to < 0.01 px."""
    cam = _real(name)
    uv = _grid(cam, step)
    rays = cam.unproject(uv)
    inside = np.isfinite(rays[:, 0])
    np.testing.assert_array_equal(inside, cam.ideal_radius(uv) <= cam.rho_max)
    assert inside.sum() > 0.75 * len(uv)
    np.testing.assert_allclose(np.linalg.norm(rays[inside], axis=1), 1.0, atol=1e-12)
    for depth in (0.05, 30.0):
        err = np.linalg.norm(cam.project(rays[inside] * depth) - uv[inside], axis=1)
        assert err.max() < 0.01
    # the toolbox's world2cam alone (no Newton polish): the sheet's 0.0041 px (file 0); for premnirmal
    # the 6-decimal print of its 33-term invpol costs up to ~0.6 px near the axis (sheet §5)
    raw = dataclasses.replace(cam, newton_steps=0)
    err = np.linalg.norm(raw.project(rays[inside]) - uv[inside], axis=1)
    near_axis = cam.ideal_radius(uv[inside]) <= 40
    if name == "file0":
        assert err.max() < 0.005
    else:
        assert 0.3 < err[near_axis].max() < 1.0
        inscribed = cam.ideal_radius(uv[inside]) <= cam.xc
        assert err[~near_axis & inscribed].max() < 0.003


@pytest.mark.parametrize("name", ["file0", "premnirmal"])
def test_ray_pixel_ray_angle_round_trip(name: str) -> None:
    """20,000 random rays uniform in the circle's cone -> project -> unproject: the same ray to 1e-9 rad."""
    cam = _real(name)
    rays = _rays_in_cone(cam.circle_fov_rad / 2, 20000, np.random.default_rng(3))
    uv = cam.project(rays * 4.0)
    assert np.isfinite(uv).all()
    assert _angle(cam.unproject(uv), rays).max() < 1e-9


@pytest.mark.parametrize("name", ["file0", "premnirmal"])
def test_project_agrees_with_paper_root_selection(name: str) -> None:
    """project (invpol + Newton) equals project_exact (eq. 24 roots, positive real root in the circle) to
    1e-6 px; the file's invpol alone is within the sheet's 0.015 px (file 0) / 0.63 px (premnirmal)."""
    cam = _real(name)
    rays = _rays_in_cone(cam.circle_fov_rad / 2, 3000, np.random.default_rng(4))
    exact = cam.project_exact(rays)
    assert np.isfinite(exact).all()
    assert np.abs(cam.project(rays) - exact).max() < 1e-6
    bound = 0.016 if name == "file0" else 0.65
    assert cam.invpol_max_err_px < bound
    assert (
        np.linalg.norm(dataclasses.replace(cam, newton_steps=0).project(rays) - exact, axis=1).max() < bound
    )


@pytest.mark.parametrize("name", ["file0", "premnirmal"])
def test_field_of_view_edge(name: str) -> None:
    """Rays exactly at the circle's half angle land on the circle (ideal radius rho_max); 1e-7 rad beyond
    they have no image; the axis, straight back, zero and non-finite vectors are handled."""
    cam = _real(name)
    assert cam.rho_max is not None
    half = cam.circle_fov_rad / 2
    assert half == pytest.approx(cam.theta_max + math.pi / 2, abs=1e-12)
    phi = np.linspace(-math.pi, math.pi, 37)
    for a, finite in ((half, True), (half + 1e-7, False)):
        rays = np.stack(
            [math.sin(a) * np.cos(phi), math.sin(a) * np.sin(phi), np.full_like(phi, math.cos(a))], 1
        )
        for proj in (cam.project, cam.project_exact):
            uv = proj(rays)
            assert np.isfinite(uv).all() == finite and np.isnan(uv).all() != finite
            if finite:
                np.testing.assert_allclose(cam.ideal_radius(uv), cam.rho_max, atol=1e-6)
    uv = cam.project(np.array([[0.0, 0.0, 2.0], [0.0, 0.0, -1.0], [0.0, 0.0, 0.0], [np.nan, 0.0, 1.0]]))
    np.testing.assert_array_equal(uv[0], [cam.yc, cam.xc])
    assert np.isnan(uv[1:]).all()
    np.testing.assert_allclose(cam.unproject(np.array([[cam.yc, cam.xc]])), [[0.0, 0.0, 1.0]], atol=1e-15)
    # just outside the circle along the row through the centre: no ray
    det = cam.c - cam.d * cam.e
    du = (cam.rho_max + 1e-6) * det / math.hypot(cam.c, cam.d)  # ideal rho = rho_max + 1e-6 at dv = 0
    assert np.isnan(cam.unproject(np.array([[cam.yc + du, cam.xc]]))).all()


# ------------------------------------------------------------------------------------ axis convention


def _ocam_native_cam2world(cam: OmniCamera, row: np.ndarray, col: np.ndarray) -> np.ndarray:
    """The toolbox's cam2world in its own frame and (row, col) pixels, written from the sheet's §2."""
    dr, dc = row - cam.xc, col - cam.yc
    det = cam.c - cam.d * cam.e
    x = (dr - cam.d * dc) / det
    y = (cam.c * dc - cam.e * dr) / det
    z = np.polynomial.polynomial.polyval(np.hypot(x, y), cam.ss)
    p = np.stack([x, y, z], axis=1)
    return p / np.linalg.norm(p, axis=1, keepdims=True)


def _ocam_native_world2cam(cam: OmniCamera, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The toolbox's world2cam (sheet §3) in its frame: returns (row, col)."""
    r = np.hypot(p[:, 0], p[:, 1])
    rho = np.polynomial.polynomial.polyval(np.arctan(p[:, 2] / r), cam.invpol)
    xs, ys = rho * p[:, 0] / r, rho * p[:, 1] / r
    return cam.c * xs + cam.d * ys + cam.xc, cam.e * xs + ys + cam.yc


@pytest.mark.parametrize("name", ["file0", "premnirmal"])
def test_matches_the_toolbox_in_its_own_frame_through_M(name: str) -> None:
    """Our (u, v) / OpenCV-frame formulas equal the toolbox's (row, col) / OCam-frame ones with
    u = col, v = row and p_C = M p_OCam, M = [[0,1,0],[1,0,0],[0,0,-1]] (det +1)."""
    cam = _real(name)
    M = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
    assert np.linalg.det(M) == 1.0
    uv = _grid(cam, 16.0)
    uv = uv[cam.ideal_radius(uv) <= cam.rho_max]
    ocam = _ocam_native_cam2world(cam, row=uv[:, 1], col=uv[:, 0])
    np.testing.assert_allclose(cam.unproject(uv), ocam @ M.T, atol=1e-13)
    row, col = _ocam_native_world2cam(cam, ocam * 3.0)
    raw = dataclasses.replace(cam, newton_steps=0)
    np.testing.assert_allclose(raw.project(ocam @ M.T * 3.0), np.stack([col, row], axis=1), atol=1e-9)


def test_axis_directions() -> None:
    """A point to the right (x_C > 0) appears right of the centre (u > yc), one below (y_C > 0) below it."""
    cam = _real("file0")
    uv = cam.project(np.array([[1.0, 0.0, 1.0], [0.0, 1.0, 1.0], [1.0, 0.0, -0.01]]))
    assert uv[0, 0] - cam.yc > 300 and abs(uv[0, 1] - cam.xc) < 1.0
    assert uv[1, 1] - cam.xc > 300 and abs(uv[1, 0] - cam.yc) < 1.0
    # 90.6 deg off axis, still inside the 188 deg circle
    assert cam.ideal_radius(uv[2:])[0] > cam.invpol[0]  # type: ignore[index]


# ------------------------------------------------------------------------------------ paper 003 eq. 24


def test_solve_rho_root_selection() -> None:
    """Eq. 24 with two positive real roots (100 and 300 px): f(rho) - K rho = 30000 - 400 rho + rho^2 for
    ss = (30000, -390, 1), K = 10. The smallest without a previous radius, the nearest with one, none
    beyond rho_max; a negative or complex root never counts."""
    ss = np.array([30000.0, -390.0, 1.0])
    assert solve_rho(ss, 10.0) == pytest.approx(100.0, abs=1e-9)
    assert solve_rho(ss, 10.0, rho_prev=280.0) == pytest.approx(300.0, abs=1e-9)
    assert solve_rho(ss, 10.0, rho_prev=190.0) == pytest.approx(100.0, abs=1e-9)
    assert solve_rho(ss, 10.0, rho_max=200.0) == pytest.approx(100.0, abs=1e-9)
    assert math.isnan(solve_rho(ss, 10.0, rho_max=50.0))  # type: ignore[arg-type]
    # roots -100 and 300 (negative dropped); then a complex pair only
    assert solve_rho(np.array([-30000.0, -190.0, 1.0]), 10.0) == pytest.approx(300.0, abs=1e-9)
    assert math.isnan(solve_rho(np.array([30000.0, 10.0, 1.0]), 10.0))  # type: ignore[arg-type]
    assert solve_rho(ss, -math.inf) == 0.0
    # vectorised, and the numba form is the same function
    np.testing.assert_allclose(solve_rho(ss, np.array([10.0, 10.0])), [100.0, 100.0])
    assert solve_rho_jit(ss, 10.0, 280.0, math.inf) == pytest.approx(300.0, abs=1e-9)


def test_positive_real_roots_match_numpy_roots() -> None:
    """The root isolation behind solve_rho finds exactly the positive real roots that np.roots (companion
    matrix eigenvalues) finds, on 1000 random polynomials of degree 1-6 with coefficients spread over six
    orders of magnitude."""
    rng = np.random.default_rng(7)
    for _ in range(1000):
        n = int(rng.integers(1, 7))
        p = rng.normal(size=n + 1) * 10.0 ** rng.uniform(-3, 3, n + 1)
        r = np.roots(p[::-1])
        ref = np.sort(r[(np.abs(r.imag) <= 1e-9 * np.maximum(1, np.abs(r.real))) & (r.real > 0)].real)
        out = np.empty(n + 1)
        m = positive_real_roots(p, 1 + np.max(np.abs(p[:-1] / p[-1])), out)
        assert m == ref.size
        np.testing.assert_allclose(out[:m], ref, rtol=1e-7, atol=1e-9)
        if m:  # and solve_rho picks the smallest
            K = 0.0
            # the same roots (the search interval differs: Fujiwara's bound there, Cauchy's here)
            assert solve_rho_jit(p, K, math.nan, math.inf) == pytest.approx(out[0], rel=1e-12)


def test_solve_rho_near_the_axis_and_on_the_real_quartic() -> None:
    """On file 0's quartic, the selected root satisfies eq. 24 to 1e-9 relative at every elevation from
    1e-8 rad off axis to the circle's edge, and near the axis rho ~ -a0 tan(angle) (f ~ a0 there)."""
    cam = _real("file0")
    for off in (1e-8, 1e-5, 1e-2, 0.5, 1.2, cam.circle_fov_rad / 2):
        K = -1.0 / math.tan(off)  # z_OCam / r for a ray `off` from the axis (-z_OCam)
        rho = solve_rho(cam.ss, K, rho_max=cam.rho_max)  # type: ignore[arg-type]
        assert isinstance(rho, float) and 0 < rho <= cam.rho_max  # type: ignore[operator]
        resid = np.polynomial.polynomial.polyval(rho, cam.ss) - K * rho
        assert abs(resid) <= 1e-9 * abs(K * rho) + 1e-9
        assert cam.off_axis_angle(rho) == pytest.approx(off, rel=1e-9)
    assert solve_rho(cam.ss, -1.0 / math.tan(1e-8)) == pytest.approx(-cam.ss[0] * 1e-8, rel=1e-6)


# ------------------------------------------------------------------------------------ synthetic camera


@pytest.mark.parametrize(("W", "H", "fov"), [(752, 480, 185.0), (640, 480, 190.0), (752, 480, 180.0)])
def test_synthetic_fisheye(W: int, H: int, fov: float) -> None:
    """The synthetic fisheye: the circle spans fov_deg, is inscribed in the frame (so both fields of view
    equal it), holds pi r^2 pixels, and its fitted invpol is within the toolbox's 0.01 px."""
    cam = OmniCamera.synthetic(W, H, fov_deg=fov)
    assert (cam.width, cam.height, cam.rho_max) == (W, H, H / 2)
    assert cam.ss[1] == 0.0 and cam.ss[0] < 0
    assert math.degrees(cam.circle_fov_rad) == pytest.approx(fov, abs=1e-9)
    h, v = cam.fov_rad()
    assert math.degrees(h) == pytest.approx(fov, abs=1e-9) and math.degrees(v) == pytest.approx(fov, abs=1e-9)
    assert cam.invpol_max_err_px < 0.01
    mask = cam.valid_mask()
    assert mask.shape == (H, W) and not mask[0, 0] and mask[H // 2, W // 2]
    assert mask.sum() == pytest.approx(math.pi * (H / 2) ** 2, rel=2e-3)
    uv = _grid(cam, 1.0)
    rays = cam.unproject(uv)
    np.testing.assert_array_equal(np.isfinite(rays[:, 0]), mask.ravel())
    m = mask.ravel()
    assert np.abs(cam.project(rays[m]) - uv[m]).max() < 1e-6
    # roughly equidistant: the off-axis angle grows ~linearly with rho (within 3 % of the edge's rate)
    alpha = _angle(rays[m], np.array([[0.0, 0.0, 1.0]]))
    rho = cam.ideal_radius(uv[m])
    k = math.radians(fov) / 2 / cam.rho_max  # type: ignore[operator]
    assert np.abs(alpha - k * rho).max() < 0.03 * math.radians(fov) / 2


def test_fit_invpol_matches_the_toolbox_fit() -> None:
    """Refitting file 0's ss over the toolbox's range (the half-diagonal) meets the 0.01 px criterion with
    about the file's 10 terms (the sheet: re-running the toolbox's fit reproduces its 10 terms)."""
    cam = _real("file0", rho_max=None)
    inv = fit_invpol(cam.ss, cam.rho_max)  # type: ignore[arg-type]
    assert 8 <= inv.size <= 12
    refit = dataclasses.replace(cam, invpol=None)
    assert refit.invpol_max_err_px < 0.01


def test_fov_of_the_real_camera_clipped_by_the_frame() -> None:
    """file 0: the 1600 px frame clips the 188 deg circle on all four sides (the centre is 794 px from the
    top), so the horizontal and vertical fields of view are ~186 deg (sheet: rho 800 px = 93.1 deg)."""
    cam = _real("file0")
    h, v = cam.fov_rad()
    assert math.degrees(cam.circle_fov_rad) == pytest.approx(188.07, abs=0.01)
    assert 185.5 < math.degrees(h) < 187.0 and 185.5 < math.degrees(v) < 187.0
    assert cam.off_axis_angle(800.0) == pytest.approx(math.radians(93.13), abs=math.radians(0.01))
    mask = cam.valid_mask()
    H, W = mask.shape
    assert mask[0, W // 2] and mask[H - 1, W // 2] and mask[H // 2, 0] and mask[H // 2, W - 1]
    assert not (mask[0, 0] or mask[0, W - 1] or mask[H - 1, 0] or mask[H - 1, W - 1])


# ------------------------------------------------------------------------------------ real image


def _tag_fit(rays: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pose of a unit square (ArUco corner order, z out of the printed face) from its 4 corner rays:
    IPPE on the normalised coordinates (x/z, y/z) of the rays (all have z > 0 here)."""
    obj = np.array([[-0.5, 0.5, 0.0], [0.5, 0.5, 0.0], [0.5, -0.5, 0.0], [-0.5, -0.5, 0.0]])
    assert np.all(rays[:, 2] > 0)
    ok, rvec, tvec = cv2.solvePnP(
        obj, rays[:, :2] / rays[:, 2:], np.eye(3), None, flags=cv2.SOLVEPNP_IPPE_SQUARE
    )
    assert ok
    R = cv2.Rodrigues(rvec)[0]
    return R, (R @ obj.T).T + tvec.ravel()


def test_two_apriltags_on_the_real_fisheye_image() -> None:
    """img0.jpg (1600 x 1600, 186 deg) has AprilTag 36h11 ids 1 and 2 lying on the corridor floor, 70-77
    deg off axis. Detected by OpenCV ArUco on the raw image (subpixel corners), their corners are
    unprojected with the file-0 model and a unit square is fitted to each tag's 4 rays (IPPE on x/z, y/z).
    What must then hold if the model (and its axis convention) is right:

    1. each fitted square reprojects through the model within 1.5 px of the detected corners;
    2. both lie on one floor: their normals are within 8 deg (sheet: 4.9), their plane distances agree
       within 3 % (equal-size tags; sheet 1.003), and the normal is "up" in the camera, |n . -y_C| > 0.99
       (the camera is held level; sheet: 3.5 deg tilt);
    3. both printed faces point at the camera (n . p < 0), and both tags are below the horizon (y_C > 0).

    Controls that must fail with the same corners: a pinhole with the same centre and f = -a0 (normals
    ~69 deg apart, larger square residuals), and the mirrored axes (x and y not swapped back, det -1):
    both faces point away from the camera."""
    cam = _real("file0")
    img = cv2.imread(str(_FISHEYE_DIR / "img0.jpg"), cv2.IMREAD_GRAYSCALE)
    assert img is not None and img.shape == (cam.height, cam.width)
    params = cv2.aruco.DetectorParameters()
    params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    detector = cv2.aruco.ArucoDetector(
        cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_APRILTAG_36h11), params
    )
    corners, ids, _ = detector.detectMarkers(img)
    assert ids is not None and sorted(ids.ravel().tolist()) == [1, 2]
    tags = [c.reshape(4, 2).astype(np.float64) for c in corners]

    f = -cam.ss[0]

    def pin_unproject(uv: np.ndarray) -> np.ndarray:
        r = np.stack([uv[:, 0] - cam.yc, uv[:, 1] - cam.xc, np.full(len(uv), f)], axis=1)
        return r / np.linalg.norm(r, axis=1, keepdims=True)

    def pin_project(P: np.ndarray) -> np.ndarray:
        return np.stack([cam.yc + f * P[:, 0] / P[:, 2], cam.xc + f * P[:, 1] / P[:, 2]], axis=1)

    def fits(unproject, project):  # type: ignore[no-untyped-def]
        out = []
        for uv in tags:
            R, P = _tag_fit(unproject(uv))
            n, centre = R[:, 2], P.mean(axis=0)
            out.append((n, centre, float(-(n @ centre)), float(np.abs(project(P) - uv).max())))
        return out

    omni = fits(cam.unproject, cam.project)
    (n1, c1, d1, e1), (n2, c2, d2, e2) = omni
    assert max(e1, e2) < 1.5
    assert math.degrees(math.acos(min(1.0, n1 @ n2))) < 8.0
    assert abs(d1 / d2 - 1) < 0.03
    assert -n1[1] > 0.99 and -n2[1] > 0.99
    assert d1 > 0 and d2 > 0  # faces towards the camera
    for c in (c1, c2):
        ray = c / np.linalg.norm(c)
        assert ray[1] > 0.5 and 65 < math.degrees(math.acos(ray[2])) < 80

    pin = fits(pin_unproject, pin_project)
    assert math.degrees(math.acos(min(1.0, pin[0][0] @ pin[1][0]))) > 30.0
    assert all(p[3] > o[3] for p, o in zip(pin, omni, strict=True))

    mirror = fits(lambda uv: cam.unproject(uv)[:, [1, 0, 2]], lambda P: cam.project(P[:, [1, 0, 2]]))
    assert all(m[2] < 0 for m in mirror)  # faces away: the mirrored model is rejected


# ------------------------------------------------------------------------------------ misc


def test_loader_dispatch_and_protocol() -> None:
    cam = OmniCamera.synthetic()
    assert isinstance(cam, CameraModel)
    assert not isinstance(cam, PinholeCamera)
    with pytest.raises(dataclasses.FrozenInstanceError):
        cam.xc = 1.0  # type: ignore[misc]
    with pytest.raises(ValueError, match=r"\(N, 3\)"):
        cam.project(np.zeros((3, 2)))
    with pytest.raises(ValueError, match=r"\(N, 2\)"):
        cam.unproject(np.zeros(2))
    assert cam.project(np.zeros((0, 3))).shape == (0, 2) and cam.unproject(np.zeros((0, 2))).shape == (0, 3)
    # same parameters, same model: the renderer keys its ray cache on the init fields
    again = OmniCamera.synthetic()
    for f in dataclasses.fields(cam):
        a, b = getattr(cam, f.name), getattr(again, f.name)
        assert np.array_equal(a, b)
