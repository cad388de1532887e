"""Paper 004's landing-marker detector: n-fold + ArUco fused into one landing-marker pixel, on rendered
frames, with partial views, an outlier, odd inputs and the real photos."""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np
import pytest
from perception_scenes import Scene, render_scene, tilt

from alight.cameras import PinholeCamera
from alight.pads.sdu_pad import SduPad
from alight.perception.nfold import NFoldConfig
from alight.perception.sdu_marker import SduMarkerDetector
from alight.sim.render import RenderOptions

CAM = PinholeCamera.default_downward()
PAD = SduPad.default()
OPT = RenderOptions(noise_sigma_dn=2.0)


def _project(sc: Scene, pts_P: np.ndarray) -> np.ndarray:
    return CAM.project((sc.R_CP @ np.atleast_2d(pts_P).T).T + sc.p_CP)


def _truth(sc: Scene) -> tuple[np.ndarray, float]:
    """The pad centre's pixel and the image angle of the pad's +x axis there."""
    c = _project(sc, np.zeros(3))[0]
    ax = _project(sc, np.array([0.01, 0.0, 0.0]))[0] - c
    return c, math.atan2(ax[1], ax[0])


def _scene(rng: np.random.Generator, z_range: tuple[float, float], spread: float = 0.3) -> Scene:
    z = rng.uniform(*z_range)
    R_WB = tilt(rng.uniform(-0.25, 0.25), rng.uniform(-0.25, 0.25), rng.uniform(-math.pi, math.pi))
    p_WB = np.array([rng.uniform(-spread, spread) * z, rng.uniform(-spread, spread) * z, z + 0.5])
    return render_scene(
        PAD, p_WB, R_WB, np.array([0.0, 0.0, 0.5]), rng.uniform(-math.pi, math.pi), options=OPT
    )


def _all_in_view(px: np.ndarray, margin: float = 3.0) -> bool:
    return bool(
        np.isfinite(px).all()
        and (px > margin).all()
        and (px[:, 0] < CAM.width - 1 - margin).all()
        and (px[:, 1] < CAM.height - 1 - margin).all()
    )


def _paint(img: np.ndarray, poly_px: np.ndarray, value: int = 128) -> np.ndarray:
    out = img.copy()
    cv2.fillPoly(out, [np.round(poly_px * 16).astype(np.int32)], value, cv2.LINE_8, 4)
    return out


def _disc_polygon(sc: Scene, radius_m: float) -> np.ndarray:
    a = np.linspace(0, 2 * np.pi, 48, endpoint=False)
    return _project(sc, np.c_[radius_m * np.cos(a), radius_m * np.sin(a), np.zeros(48)])


def test_full_view_fuses_nfold_and_aruco() -> None:
    """Pad fully in view from 1.5-4 m: every source found; the fused pixel within 0.3 px of the projected
    pad centre (the tip dominates the weights), the pad's heading within 2 deg; the observation's rows
    are the fused pixel, the tip and the used markers' corners."""
    rng = np.random.default_rng(1)
    det = SduMarkerDetector(PAD)
    done = 0
    while done < 8:
        sc = _scene(rng, (1.5, 4.0))
        if not _all_in_view(_project(sc, PAD.quad_corners_P())):
            continue
        done += 1
        c, yaw = _truth(sc)
        d = det.detect_detailed(sc.image, 1.25)
        assert d is not None
        assert [s.kind for s in d.sources] == ["nfold", "aruco:1", "aruco:2", "aruco:3"]
        assert all(s.used for s in d.sources)
        assert np.linalg.norm(d.pixel - c) < 0.3
        assert d.yaw_CP is not None and abs(math.remainder(d.yaw_CP - yaw, 2 * math.pi)) < math.radians(2)
        for s in d.sources[1:]:  # each ArUco marker alone: a few pixels (extrapolated 2.6 sides away)
            assert np.linalg.norm(s.pixel - c) < 10.0
            assert s.yaw_CP is not None and abs(math.remainder(s.yaw_CP - yaw, 2 * math.pi)) < math.radians(5)
        (obs,) = det.detect(sc.image, 1.25)
        assert obs.kind == "sdu" and obs.t == 1.25 and obs.quality == pytest.approx(d.quality)
        assert obs.pixels.shape == (1 + 1 + 12, 2) and obs.points_P is not None
        np.testing.assert_allclose(obs.pixels[0], d.pixel)
        np.testing.assert_array_equal(obs.points_P[:2], np.zeros((2, 3)))
        np.testing.assert_array_equal(obs.points_P[2:6], PAD.marker_corners_P(1))
        # the measured rows are where the camera puts their pad points (corners to ~1 px)
        truth = _project(sc, obs.points_P)
        assert np.abs(obs.pixels[1:] - truth[1:]).max() < 1.5
        assert obs.yaw_CP == d.yaw_CP


def test_nfold_covered_leaves_the_aruco_markers() -> None:
    """The n-fold disc painted over: the landing-marker pixel from the ArUco markers alone, within a few
    pixels (their homographies extrapolate 2.6 marker sides)."""
    rng = np.random.default_rng(2)
    det = SduMarkerDetector(PAD)
    done = 0
    while done < 6:
        sc = _scene(rng, (1.5, 3.5))
        if not _all_in_view(_project(sc, PAD.quad_corners_P())):
            continue
        done += 1
        img = _paint(sc.image, _disc_polygon(sc, PAD.nfold_radius_m + 0.02))
        c, yaw = _truth(sc)
        d = det.detect_detailed(img, 0.0)
        assert d is not None and d.nfold is None
        assert {s.kind for s in d.sources} == {"aruco:1", "aruco:2", "aruco:3"}
        assert np.linalg.norm(d.pixel - c) < 4.0
        assert d.yaw_CP is not None and abs(math.remainder(d.yaw_CP - yaw, 2 * math.pi)) < math.radians(3)
        (obs,) = det.detect(img, 0.0)
        assert obs.pixels.shape == (1 + 12, 2)


def test_pad_centre_out_of_view_from_one_aruco_marker() -> None:
    """Close to the pad, over a corner: the centre is outside the image and only some ArUco markers are
    seen; the fused pixel (outside the image) still lands within 2 px of the pad centre's projection when
    the detector knows the camera (lens distortion; without it 16-39 px here)."""
    rng = np.random.default_rng(3)
    det = SduMarkerDetector(PAD, camera=CAM)
    done = 0
    while done < 5:
        z = rng.uniform(0.6, 1.0)
        mid = int(rng.choice(PAD.aruco_ids))
        cx, cy, _ = PAD.marker_center_and_size_P(mid)
        p_WB = np.array([cx * 1.2 + rng.uniform(-0.05, 0.05), cy * 1.2 + rng.uniform(-0.05, 0.05), z + 0.5])
        sc = render_scene(
            PAD,
            p_WB,
            tilt(0.0, 0.0, rng.uniform(-math.pi, math.pi)),
            np.array([0.0, 0.0, 0.5]),
            0.0,
            options=OPT,
        )
        c, _ = _truth(sc)
        if 0 <= c[0] < CAM.width and 0 <= c[1] < CAM.height:
            continue
        if not _all_in_view(_project(sc, PAD.marker_corners_P(mid))):
            continue
        done += 1
        d = det.detect_detailed(sc.image, 0.0)
        assert d is not None and d.nfold is None and f"aruco:{mid}" in {s.kind for s in d.sources}
        assert np.linalg.norm(d.pixel - c) < 2.0


def test_aruco_covered_leaves_the_nfold_marker() -> None:
    """ArUco markers painted over: the tip alone, and no heading (a plain marker gives it mod pi/2)."""
    rng = np.random.default_rng(4)
    det = SduMarkerDetector(PAD)
    done = 0
    while done < 4:
        sc = _scene(rng, (2.0, 8.0))
        if not _all_in_view(_project(sc, PAD.quad_corners_P())):
            continue
        done += 1
        img = sc.image
        for mid in PAD.aruco_ids:
            cx, cy, a = PAD.marker_center_and_size_P(mid)
            h = 0.7 * a
            img = _paint(
                img,
                _project(
                    sc,
                    np.array(
                        [[cx + h, cy + h, 0], [cx + h, cy - h, 0], [cx - h, cy - h, 0], [cx - h, cy + h, 0]]
                    ),
                ),
                255,
            )
        c, _ = _truth(sc)
        d = det.detect_detailed(img, 0.0)
        assert d is not None and [s.kind for s in d.sources] == ["nfold"]
        assert np.linalg.norm(d.pixel - c) < 0.3 and d.yaw_CP is None
        (obs,) = det.detect(img, 0.0)
        assert obs.pixels.shape == (2, 2) and obs.yaw_CP is None


def test_oriented_pad_gives_the_heading_from_the_nfold_marker_alone() -> None:
    pad = SduPad(nfold_oriented=True)
    det = SduMarkerDetector(pad)
    sc = render_scene(
        pad, np.array([0.3, -0.2, 6.5]), tilt(0.05, -0.1, 0.4), np.array([0.0, 0.0, 0.5]), 1.1, options=OPT
    )
    c, yaw = _truth(sc)
    d = det.detect_detailed(sc.image, 0.0)
    assert d is not None and d.sources[0].kind == "nfold"
    assert np.linalg.norm(d.pixel - c) < 0.5
    assert d.yaw_CP is not None and abs(math.remainder(d.yaw_CP - yaw, 2 * math.pi)) < math.radians(3)


def test_a_stronger_nfold_marker_elsewhere_is_gated_out() -> None:
    """A second, larger, higher-contrast 4-fold marker beside the pad wins the n-fold search; the ArUco
    markers disagree with it, so the gate drops it and the fused pixel comes from them."""
    from test_nfold import draw_marker

    rng = np.random.default_rng(5)
    det = SduMarkerDetector(PAD)
    while True:
        sc = _scene(rng, (2.0, 3.0), spread=0.1)
        if _all_in_view(_project(sc, PAD.quad_corners_P())):
            break
    c, _ = _truth(sc)
    img = sc.image.copy()
    # the decoy in the image corner farthest from the pad
    fx = 60 if c[0] > CAM.width / 2 else CAM.width - 61
    fy = 60 if c[1] > CAM.height / 2 else CAM.height - 61
    patch = draw_marker((121, 121), 60.3, 60.6, 4, 0.4, 58, lo=0.0, hi=255.0, bg=255.0)
    img[fy - 60 : fy + 61, fx - 60 : fx + 61] = patch
    d = det.detect_detailed(img, 0.0)
    assert d is not None and d.nfold is not None
    assert math.hypot(d.nfold.x - fx, d.nfold.y - fy) < 2.0  # the decoy won the n-fold search
    nf = [s for s in d.sources if s.kind == "nfold"][0]
    assert not nf.used and sum(s.used for s in d.sources) == 3
    assert np.linalg.norm(d.pixel - c) < 4.0


def test_nothing_on_odd_inputs_and_square_marker_photos(real_dir: Path) -> None:
    det = SduMarkerDetector()
    rng = np.random.default_rng(0)
    for img in (
        np.zeros((0, 0), np.uint8),
        np.zeros((3, 3), np.uint8),
        np.full((480, 752), 200, np.uint8),
        rng.integers(0, 256, (480, 752), dtype=np.uint8),
        np.full((64, 64), np.nan),
        None,
    ):
        assert det.detect(img, 0.0) == []
    for name in ("aruco_charuco_real_photos/img_01.jpg", "apriltag_real_photos/33369213973_9d9bb4cc96_c.jpg"):
        assert det.detect(cv2.imread(str(real_dir / name)), 0.0) == []


def test_mismatched_configuration_raises() -> None:
    with pytest.raises(ValueError):
        SduMarkerDetector(PAD, NFoldConfig(order=5))
    with pytest.raises(ValueError):
        SduMarkerDetector(PAD, NFoldConfig(order=4, oriented=True))
    with pytest.raises(ValueError):
        SduMarkerDetector(PAD, nfold_sigma_px=0.0)
    with pytest.raises(ValueError):
        SduMarkerDetector(PAD, gate_frac=-1.0)


def test_a_lone_small_aruco_marker_does_not_gate_out_a_good_tip() -> None:
    from alight.perception.sdu_marker import SduSource

    det = SduMarkerDetector(SduPad.default(1.5))
    square = np.array([[0.0, 0.0], [12.0, 0.0], [12.0, 12.0], [0.0, 12.0]])  # a 12 px marker
    tip = SduSource("nfold", np.array([100.0, 100.0]), 0.3, None, 0.95, square[:1], np.zeros((1, 3)), True)
    lone = SduSource("aruco:1", np.array([108.0, 104.0]), 4.0, None, 0.4, square, np.zeros((4, 3)), True)
    kept = det._gate([tip, lone])
    assert all(s.used for s in kept)  # 8.9 px apart, within 3 sigma of the lone marker's 4 px
    far = SduSource("aruco:1", np.array([125.0, 100.0]), 4.0, None, 0.4, square, np.zeros((4, 3)), True)
    assert not det._gate([tip, far])[0].used  # 25 px: beyond both gates, the decoded marker wins
