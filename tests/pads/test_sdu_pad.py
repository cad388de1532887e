"""Paper 004's landing marker (SduPad): the texture shows what the geometry says, in the pad convention."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from alight.pads import PadDesign
from alight.pads.sdu_pad import SduPad
from alight.perception.nfold import NFoldConfig, NFoldDetector


def _to_px(H: np.ndarray, pts_P: np.ndarray) -> np.ndarray:
    q = np.c_[pts_P[:, :2], np.ones(len(pts_P))] @ H.T
    return q[:, :2] / q[:, 2:]


@pytest.mark.parametrize("px_per_m", [37.3, 100.0, 211.7])
def test_pad_design_contract(px_per_m: float) -> None:
    pad = SduPad.default()
    assert isinstance(pad, PadDesign)
    tex = pad.texture(px_per_m)
    n = round(pad.size_m * px_per_m)
    assert tex.shape == (n, n) and tex.dtype == np.uint8
    H = pad.texture_homography_P_to_px(px_per_m)
    np.testing.assert_allclose(
        _to_px(H, pad.quad_corners_P()), [[-0.5, -0.5], [-0.5, n - 0.5], [n - 0.5, n - 0.5], [n - 0.5, -0.5]]
    )
    hash(pad)  # the renderer caches textures by pad


def test_default_scales_every_length() -> None:
    a, b = SduPad.default(1.5), SduPad.default(3.0)
    assert a == SduPad()
    for f in ("nfold_radius_m", "aruco_size_m", "aruco_offset_m"):
        assert getattr(b, f) == pytest.approx(2 * getattr(a, f))
    assert a.size_m == 1.5 and a.nfold_order == 4 and a.aruco_dictionary == "DICT_4X4_50"


def test_geometry_in_P() -> None:
    pad = SduPad.default()
    np.testing.assert_array_equal(pad.nfold_center_P, [0.0, 0.0, 0.0])
    assert pad.marker_ids == pad.aruco_ids == (1, 2, 3)
    expected_centres = {1: (0.55, 0.55), 2: (-0.55, 0.55), 3: (-0.55, -0.55)}
    for mid, (cx, cy) in expected_centres.items():
        np.testing.assert_allclose(pad.marker_offset_P(mid), [cx, cy, 0.0])
        c = pad.marker_corners_P(mid)
        np.testing.assert_allclose(c.mean(axis=0), [cx, cy, 0.0])
        # OpenCV's order: (+x,+y), (+x,-y), (-x,-y), (-x,+y) of the marker: clockwise seen from above
        signs = np.sign(c[:, :2] - [cx, cy])
        np.testing.assert_array_equal(signs, [[1, 1], [1, -1], [-1, -1], [-1, 1]])
        side = np.linalg.norm(np.diff(np.r_[c, c[:1]], axis=0), axis=1)
        np.testing.assert_allclose(side, pad.aruco_size_m)
    with pytest.raises(ValueError):
        pad.marker_corners_P(0)


def test_aruco_markers_read_back_from_the_texture_at_their_corners() -> None:
    pad = SduPad.default()
    px_per_m = 300.0
    tex = pad.texture(px_per_m)
    img = cv2.copyMakeBorder(tex, 40, 40, 40, 40, cv2.BORDER_CONSTANT, value=128)
    params = cv2.aruco.DetectorParameters()
    params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    det = cv2.aruco.ArucoDetector(cv2.aruco.getPredefinedDictionary(pad.aruco_dictionary_id), params)
    corners, ids, _ = det.detectMarkers(img)
    assert ids is not None and sorted(ids.ravel().tolist()) == [1, 2, 3]
    H = pad.texture_homography_P_to_px(px_per_m)
    for c, mid in zip(corners, ids.ravel(), strict=True):
        expected = _to_px(H, pad.marker_corners_P(int(mid))) + 40
        assert np.abs(c.reshape(4, 2) - expected).max() < 0.6  # the corner order is the pad's too


def test_black_area_of_the_nfold_disc_is_half_the_disc() -> None:
    """n black wedges of pi/n each cover half of the disc (one wedge fewer for the oriented variant):
    a check of the edge-coverage anti-aliasing against the closed-form area."""
    for oriented in (False, True):
        pad = SduPad(nfold_oriented=oriented)
        px_per_m = 400.0
        tex = pad.texture(px_per_m).astype(np.float64)
        s = tex.shape[0] / pad.size_m
        n = tex.shape[0]
        c = (n - 1) / 2
        vv, uu = np.mgrid[0:n, 0:n]
        # a circle between the disc and the ArUco markers' inner corners
        r_mid = 0.5 * (pad.nfold_radius_m + math.sqrt(2) * (pad.aruco_offset_m - pad.aruco_size_m / 2))
        inside = np.hypot(uu - c, vv - c) < s * r_mid
        black_px = float(((255.0 - tex) / 255.0)[inside].sum())
        legs = pad.nfold_order - (1 if oriented else 0)
        expected = legs / (2 * pad.nfold_order) * math.pi * (s * pad.nfold_radius_m) ** 2
        assert black_px == pytest.approx(expected, rel=2e-3)


def test_texture_colour_matches_nfold_is_black_P() -> None:
    for pad in (SduPad(), SduPad(nfold_oriented=True), SduPad(nfold_order=5)):
        px_per_m = 200.0
        tex = pad.texture(px_per_m)
        n = tex.shape[0]
        s = n / pad.size_m
        v, u = np.mgrid[0:n, 0:n]
        x = pad.size_m / 2 - (v + 0.5) / s
        y = pad.size_m / 2 - (u + 0.5) / s
        black = pad.nfold_is_black_P(x, y)
        # away from the wedge edges (more than a pixel from every edge) the texture is pure black / white
        r = np.hypot(x, y)
        psi = np.arctan2(y, x)
        k = pad.nfold_order
        m = np.remainder(psi - math.pi / (2 * k), math.pi / k)  # wedge edges at pi/(2k) + j pi/k
        d_edge = np.minimum(m, math.pi / k - m)
        edge_dist = np.minimum(r * np.sin(d_edge), np.abs(r - pad.nfold_radius_m)) * s
        clear = (edge_dist > 1.5) & (r < pad.nfold_radius_m + 0.1)
        assert clear.sum() > 1000
        assert np.all(tex[clear & black] == 0) and np.all(tex[clear & ~black] == 255)


@pytest.mark.parametrize("order,oriented", [(4, False), (5, False), (4, True)])
def test_nfold_detector_finds_the_tip_and_heading_in_the_texture(order: int, oriented: bool) -> None:
    """Tip at the texture centre; the wedge along +x (image up, angle -pi/2) fixes the orientation:
    modulo 2 pi / n for a plain marker, exactly for the oriented one (its missing leg points along +x)."""
    pad = SduPad(nfold_order=order, nfold_oriented=oriented)
    tex = pad.texture(100.0)  # 150 x 150 px
    det = NFoldDetector(NFoldConfig(order=order, oriented=oriented, kernel_sizes=(21, 31)))
    res = det.detect_result(tex)
    assert res is not None and res.quality >= 0.9
    c = (tex.shape[0] - 1) / 2
    assert math.hypot(res.x - c, res.y - c) < 0.1
    period = 2 * math.pi if oriented else 2 * math.pi / order
    assert abs(math.remainder(res.theta - (-math.pi / 2), period)) < math.radians(1.0)


@pytest.mark.parametrize(
    "kw",
    [
        {"size_m": 0.0},
        {"nfold_order": 1},
        {"aruco_ids": (1, 1, 2)},
        {"aruco_ids": (1, 2, 99)},  # DICT_4X4_50 has ids 0..49
        {"aruco_dictionary": "DICT_NOPE"},
        {"aruco_offset_m": 0.7},  # quiet zone outside the pad
        {"aruco_offset_m": 0.45},  # quiet zone over the n-fold disc
        {"nfold_radius_m": 0.8},
    ],
)
def test_invalid_layouts_raise(kw: dict[str, object]) -> None:
    with pytest.raises(ValueError):
        SduPad(**kw)  # type: ignore[arg-type]


def test_dictionary_name_without_prefix_is_accepted() -> None:
    pad = SduPad(aruco_dictionary="4X4_50")
    assert pad.aruco_dictionary == "DICT_4X4_50" and pad.aruco_dictionary_id == cv2.aruco.DICT_4X4_50
    assert pad.aruco_cells == 6
