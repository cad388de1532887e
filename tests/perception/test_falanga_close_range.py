"""The close-range stage of the Falanga tag detector (our extension of paper 000's Alg. 1): the cross alone
when the white square no longer fits in the view, on rendered frames 0.4-1.2 m above the pad, negatives,
and its kernels."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
from perception_scenes import Scene, render_scene, tilt

from alight.cameras import CameraMount, PinholeCamera
from alight.pads import AprilTagPad, FalangaTag
from alight.perception import falanga_close as fc
from alight.perception.falanga_close import CloseRangeConfig, CloseRangeCrossDetector
from alight.perception.falanga_tag import FalangaDetectorConfig, FalangaTagDetector
from alight.perception.geolocation import PnpGeolocator, wrap_yaw
from alight.sim.render import RenderOptions
from alight.types import rot_z

TAG = FalangaTag.default()
CAM = PinholeCamera.default_downward()
GEO = PnpGeolocator(CAM, CameraMount.downward(), yaw_fold=4)
P_WP = np.array([0.0, 0.0, 0.5])
GROUNDS = ("grass", "asphalt", "concrete")


@pytest.fixture(scope="module")
def det() -> FalangaTagDetector:
    return FalangaTagDetector(TAG)


def project_P(sc: Scene, pts_P: np.ndarray) -> np.ndarray:
    return CAM.project((sc.R_CP @ np.asarray(pts_P).T).T + sc.p_CP)


def in_view(px: np.ndarray, margin: float) -> bool:
    return bool(
        np.isfinite(px).all()
        and (px >= margin).all()
        and (px[:, 0] <= CAM.width - 1 - margin).all()
        and (px[:, 1] <= CAM.height - 1 - margin).all()
    )


def close_scenes(
    rng: np.random.Generator, n: int, height_m: float, *, whole_cross: bool = False, **kw: object
) -> list[Scene]:
    """``n`` frames with the camera ``height_m`` above the pad plane, up to 15 deg of tilt, offsets up to
    0.3 m, any headings, with the cross's inner corners (or, with ``whole_cross``, all 12 corners of the
    cross) at least 20 px inside the image and the white square NOT entirely in view."""
    out: list[Scene] = []
    t = math.radians(15.0)
    while len(out) < n:
        R_WB = tilt(rng.uniform(-t, t), rng.uniform(-t, t), rng.uniform(-math.pi, math.pi))
        off = rng.uniform(-0.3, 0.3, 2)
        sc = render_scene(
            TAG,
            np.array([off[0], off[1], P_WP[2] + height_m]),
            R_WB,
            P_WP,
            rng.uniform(-math.pi, math.pi),
            ground=GROUNDS[len(out) % 3],
            **kw,  # type: ignore[arg-type]
        )
        feats = np.concatenate([TAG.cross_inner_corners_P(), TAG.cross_outer_corners_P()])
        if not in_view(project_P(sc, feats if whole_cross else feats[:4]), 20.0):
            continue
        if in_view(project_P(sc, TAG.quad_corners_P()), 0.0):
            continue
        out.append(sc)
    return out


def assert_labels_are_a_symmetry(obs, sc: Scene) -> None:  # type: ignore[no-untyped-def]
    """The detected pixels are the true images of ``R_z(k pi/2) points_P`` for one k: the labels are right
    up to the tag's 4-fold symmetry, so PnP sees a consistent tag."""
    errs = []
    for k in range(4):
        px = project_P(sc, (rot_z(k * math.pi / 2) @ obs.points_P.T).T)
        errs.append(float(np.abs(px - obs.pixels).max()))
    assert min(errs) < 1.0, errs
    assert sorted(errs)[1] > 10.0  # the other labellings are far off: the test can tell them apart


# ------------------------------------------------------------------------------------------ detection


@pytest.mark.parametrize("height_m", [0.4, 0.8, 1.2])
def test_detected_below_the_quad_range_with_the_centre_within_3_cm(
    det: FalangaTagDetector, height_m: float
) -> None:
    """Alg. 1 alone is blind here (the white square is cut by the image); the close-range stage finds the
    cross in every frame and PnP puts the pad centre within 3 cm (median well under 5 mm), the yaw right
    modulo 90 deg."""
    errors = []
    for sc in close_scenes(np.random.default_rng(int(10 * height_m)), 6, height_m):
        obs = det.detect(sc.image, 2.5)
        assert len(obs) == 1
        o = obs[0]
        assert o.kind in ("cross", "cross_close") and o.t == 2.5 and 0.5 <= o.quality <= 1.0
        assert o.points_P is not None and 4 <= o.points_P.shape[0] <= 12
        # the 4 inner corners are always there; every point is a corner of the cross
        corners = np.concatenate([TAG.cross_inner_corners_P(), TAG.cross_outer_corners_P()])
        d = np.linalg.norm(o.points_P[:, None, :] - corners[None, :, :], axis=2)
        assert np.all(d.min(axis=1) < 1e-12)
        assert np.all(d[:, :4].min(axis=0) < 1e-12)
        assert_labels_are_a_symmetry(o, sc)
        m = GEO.locate(o, sc.p_WB, sc.R_WB)
        assert m is not None
        errors.append(float(np.linalg.norm(m.p_WP - P_WP)))
        assert m.yaw is not None and abs(wrap_yaw(m.yaw - sc.yaw, 4)) < math.radians(1.0)
    assert max(errors) < 0.03
    assert float(np.median(errors)) < 0.005


def test_the_whole_cross_gives_all_12_corners(det: FalangaTagDetector) -> None:
    """With the whole cross in view (but not the whole square) the observation is the cross's 12-corner
    outline, kind ``cross``, as Alg. 1's cross."""
    for sc in close_scenes(np.random.default_rng(3), 4, 1.3, whole_cross=True):
        (o,) = det.detect(sc.image, 0.0)
        assert o.kind == "cross" and o.pixels.shape == (12, 2)
        outline = TAG.cross_outline_P()
        assert {tuple(p) for p in o.points_P} == {tuple(p) for p in outline}
        assert_labels_are_a_symmetry(o, sc)


def test_at_0_4_m_only_the_centre_of_the_cross_is_in_view(det: FalangaTagDetector) -> None:
    """The 0.84 m cross cannot fit in a 63 deg vertical field of view 0.4 m above it: kind ``cross_close``."""
    for sc in close_scenes(np.random.default_rng(4), 3, 0.4):
        (o,) = det.detect(sc.image, 0.0)
        assert o.kind == "cross_close" and o.pixels.shape[0] < 12


def test_alg1_alone_is_blind_there() -> None:
    """The gap the stage fills: with ``close_range=False`` (the paper's Alg. 1) nothing is found."""
    alg1 = FalangaTagDetector(TAG, FalangaDetectorConfig(close_range=False))
    for h in (0.4, 0.8, 1.2):
        for sc in close_scenes(np.random.default_rng(5), 2, h):
            assert alg1.detect(sc.image, 0.0) == []


def test_paper_order_kept_when_the_quad_is_found(det: FalangaTagDetector) -> None:
    """The whole square in view: Alg. 1's answer (the ring) comes first, unchanged."""
    sc = render_scene(TAG, np.array([0.1, -0.1, 3.5]), tilt(0.05, -0.05, 0.3), P_WP, 0.7)
    alg1 = FalangaTagDetector(TAG, FalangaDetectorConfig(close_range=False))
    a, b = det.detect(sc.image, 0.0), alg1.detect(sc.image, 0.0)
    assert a[0].kind == "circle" and np.array_equal(a[0].pixels, b[0].pixels)


def test_the_vehicles_shadow_over_the_cross() -> None:
    """A hard shadow (gain 0.45) over the centre of the pad: the white in it stays white for the threshold
    (``dark_fraction`` 0.35), the cross is found."""
    opt = RenderOptions(shadow_polygon_P=((-0.3, -0.3), (0.3, -0.4), (0.35, 0.2), (-0.2, 0.3)))
    det = FalangaTagDetector(TAG)
    for sc in close_scenes(np.random.default_rng(6), 3, 0.8, options=opt):
        (o,) = det.detect(sc.image, 0.0)
        m = GEO.locate(o, sc.p_WB, sc.R_WB)
        assert m is not None and np.linalg.norm(m.p_WP - P_WP) < 0.03


def test_bgr_input_and_determinism(det: FalangaTagDetector) -> None:
    sc = close_scenes(np.random.default_rng(7), 1, 0.8)[0]
    a = det.detect(sc.image, 0.0)
    b = det.detect(cv2.cvtColor(sc.image, cv2.COLOR_GRAY2BGR), 0.0)
    c = det.detect(sc.image.copy(), 0.0)
    assert a and np.array_equal(a[0].pixels, b[0].pixels) and np.array_equal(a[0].pixels, c[0].pixels)


# ------------------------------------------------------------------------------------------ no tag


def test_nothing_on_ground_only_frames_at_low_height(det: FalangaTagDetector) -> None:
    """Ground far from the platform, 0.4-4 m below the camera, tilted: nothing."""
    rng = np.random.default_rng(8)
    for k in range(18):
        sc = render_scene(
            TAG,
            np.array([rng.uniform(25.0, 60.0), rng.uniform(-60.0, -25.0), rng.uniform(0.4, 4.0)]),
            tilt(rng.uniform(-0.3, 0.3), rng.uniform(-0.3, 0.3), rng.uniform(-math.pi, math.pi)),
            P_WP,
            0.0,
            ground=GROUNDS[k % 3],
        )
        assert det.detect(sc.image, 0.0) == []


def test_nothing_on_the_apriltag_pad_at_close_range(det: FalangaTagDetector) -> None:
    """Black squares on white, 0.4-2 m above: no cross."""
    pad = AprilTagPad.default()
    rng = np.random.default_rng(9)
    for k in range(12):
        off = rng.uniform(-0.4, 0.4, 2)
        sc = render_scene(
            pad,
            np.array([off[0], off[1], P_WP[2] + rng.uniform(0.4, 2.0)]),
            tilt(rng.uniform(-0.2, 0.2), rng.uniform(-0.2, 0.2), rng.uniform(-math.pi, math.pi)),
            P_WP,
            rng.uniform(-math.pi, math.pi),
            ground=GROUNDS[k % 3],
        )
        assert det.detect(sc.image, 0.0) == []


def test_nothing_on_synthetic_crosses_with_the_wrong_shape() -> None:
    """A plus with arms as long as they are wide, and a dark-grey cross (not ink on paint): rejected by the
    homography of the 12 corners and by the black/white ratio."""
    stage = CloseRangeCrossDetector(TAG)
    img = np.full((480, 752), 235, np.uint8)
    for dx, dy in ((0, 0), (0, -90), (0, 90), (-90, 0), (90, 0)):  # a centre square and 4 equal arms
        cv2.rectangle(img, (331 + dx, 195 + dy), (420 + dx, 284 + dy), 10, -1)
    assert stage.detect(img, 0.0) is None
    # the true shape seen straight down from 1.2 m (image top = +x: u = cx - s y, v = cy - s x) is found;
    # in dark grey on light grey it is not
    good = np.full((480, 752), 235, np.uint8)
    s = 400.0 / 1.2  # px per m
    xy = TAG.cross_outline_P()[:, :2]
    outline = np.stack([375.5 - s * xy[:, 1], 239.5 - s * xy[:, 0]], axis=1)
    cv2.fillPoly(good, [np.round(outline).astype(np.int32)], 10)
    o = stage.detect(good, 0.0)
    assert o is not None and o.kind == "cross"
    grey = np.where(good < 100, 140, 200).astype(np.uint8)
    assert stage.detect(grey, 0.0) is None


@pytest.mark.parametrize(
    "image",
    [np.zeros((480, 752), np.uint8), np.full((480, 752), 255, np.uint8), np.zeros((20, 20), np.uint8)],
    ids=["black", "white", "tiny"],
)
def test_nothing_on_uniform_images(image: np.ndarray) -> None:
    assert CloseRangeCrossDetector(TAG).detect(image, 0.0) is None


def test_input_and_config_validation() -> None:
    with pytest.raises(ValueError, match="2-D uint8"):
        CloseRangeCrossDetector(TAG).detect(np.zeros((480, 752, 3), np.uint8), 0.0)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="dark_fraction"):
        CloseRangeConfig(dark_fraction=1.5)
    with pytest.raises(ValueError, match="min_turn_deg"):
        CloseRangeConfig(min_turn_deg=150.0)


# ------------------------------------------------------------------------------------------ kernels


def test_dark_run_labelling_matches_opencv() -> None:
    """Areas of the 8-connected dark components equal OpenCV's, and so does the threshold (2nd
    percentile plus 0.35 of the spread to the 98th)."""
    rng = np.random.default_rng(0)
    img = cv2.resize(
        rng.integers(0, 256, (40, 60), dtype=np.uint8), (240, 160), interpolation=cv2.INTER_LINEAR
    )
    n, row, x0, x1, root, area, rpr = fc._dark_runs(img, 10.0, 0.35)
    lo, hi = np.percentile(img[::2, ::2], [2, 98], method="inverted_cdf")
    dark = (img < lo + 0.35 * (hi - lo)).astype(np.uint8)
    n_cv, _, stats, _ = cv2.connectedComponentsWithStats(dark, connectivity=8)
    roots = np.flatnonzero(root == np.arange(n))
    assert sorted(area[roots].tolist()) == sorted(stats[1:, cv2.CC_STAT_AREA].tolist())
    # runs per row (x1000) of one component: its runs over the rows it spans
    r = int(roots[np.argmax(area[roots])])
    mine = root == r
    assert rpr[r] == int(mine.sum()) * 1000 // (int(row[mine].max()) - int(row[mine].min()) + 1)
    assert fc._dark_runs(np.full((50, 50), 90, np.uint8), 10.0, 0.35)[0] == 0  # no contrast, no runs


def test_chamfered_corners_are_merged_and_opposite_turns_kept() -> None:
    """A square whose corners were cut by short edges comes back as the square; a short edge between
    turns of opposite sense (a notch) is kept."""
    sq = np.array([[0, 2], [0, 98], [2, 100], [98, 100], [100, 98], [100, 2], [98, 0], [2, 0]], float)
    V, VB, m = fc._merge_short_edges(sq, np.zeros(8, bool), 5.0)
    got = {tuple(np.round(v, 9)) for v in V[:m]}
    assert m == 4 and got == {(0.0, 0.0), (0.0, 100.0), (100.0, 100.0), (100.0, 0.0)}
    notch = np.array([[0, 0], [0, 100], [48, 100], [50, 96], [52, 100], [100, 100], [100, 0]], float)
    _, _, m2 = fc._merge_short_edges(notch, np.zeros(7, bool), 5.0)
    assert m2 == 7


def test_cross_corners_on_an_exact_outline() -> None:
    """The outline of the cross under a homography: the 4 inner and 8 outer corners come back, labelled
    as the outline's order up to a rotation of the labels by a multiple of 90 deg."""
    H = np.array([[180.0, 25.0, 190.0], [-20.0, 170.0, 120.0], [0.05, -0.08, 1.0]])
    H[:, 1] *= -1.0  # a camera looking down: the image of the pad is mirrored (negative shoelace area)
    q = TAG.cross_outline_P()[:, :2] @ H[:2, :2].T + H[:2, 2]
    w = TAG.cross_outline_P()[:, :2] @ H[2, :2] + H[2, 2]
    outline = q / w[:, None]
    ok, inner, outer, has = fc._cross_corners(
        outline, 376, 240, 3.0, math.cos(math.radians(140)), math.cos(0.7)
    )
    assert ok and has.all()
    inner_true = outline[[1, 4, 7, 10]]
    outer_true = outline[[0, 2, 3, 5, 6, 8, 9, 11]]
    matches = [
        np.allclose(inner, np.roll(inner_true, -k, axis=0))
        and np.allclose(outer, np.roll(outer_true, -2 * k, axis=0))
        for k in range(4)
    ]
    assert sum(matches) == 1
    # the inner corner nearest the image's top-left gets the label (+w/2, +w/2)
    c = inner.mean(axis=0)
    assert int(np.argmax(-(inner - c).sum(axis=1))) == 0


def test_the_range_finder_gates_the_close_range_stage() -> None:
    """``set_range``: the stage runs below ``close_range_max_range_m`` (5 m) and without a valid reading,
    and is skipped above it; Alg. 1's quad stage is never gated."""
    det = FalangaTagDetector(TAG)
    (sc,) = close_scenes(np.random.default_rng(11), 1, 0.8)
    for reading in (None, 0.7, 5.0, math.nan, -1.0):
        det.set_range(reading)
        (o,) = det.detect(sc.image, 0.0)
        assert o.kind.startswith("cross")
    det.set_range(5.01)
    assert det.detect(sc.image, 0.0) == []
    far = render_scene(TAG, np.array([0.1, -0.1, 3.5]), tilt(0.05, -0.05, 0.3), P_WP, 0.7)
    det.set_range(12.0)
    assert det.detect(far.image, 0.0)[0].kind == "circle"
    with pytest.raises(ValueError, match="close_range_max_range_m"):
        FalangaDetectorConfig(close_range_max_range_m=0.0)
