"""Paper 003's colour filter (Alg. 1 and 2) and red-target detector: the vectorised filter against the
pseudo-code pixel by pixel, the centroid of a disc, lighting tolerances from the thresholds' closed form,
bad images, the false-lock mitigations, and real photos."""

from __future__ import annotations

import math
from fractions import Fraction
from pathlib import Path

import cv2
import numpy as np
import pytest

from alight.errors import ImageError
from alight.perception import Detector
from alight.perception.color_filter import (
    BlobObservation,
    RedTargetDetector,
    RedTargetDetectorConfig,
    alg1_table,
    color_filter,
    temp_table,
)

TARGET_BGR = (40, 40, 200)  # the red of alight.pads.RedTarget
GREY_BGR = (150, 150, 150)


def reference_filter(img: np.ndarray, K: float, C: float, ratio: float) -> np.ndarray:
    """Alg. 1 and 2 literally, pixel by pixel, in exact arithmetic on the parameters as written
    (saturating subtraction of 0/1 images)."""
    Kf, Cf, q = Fraction(repr(K)), Fraction(repr(C)), Fraction(repr(ratio))

    def alg1(i1: int, i2: int, i3: int) -> int:
        return 1 if i1 >= Kf * (i2 + i3) + Cf else 0

    out = np.zeros(img.shape[:2], np.uint8)
    for i in range(img.shape[0]):
        for j in range(img.shape[1]):
            b, g, r = (int(v) for v in img[i, j])
            rr, gg, bb = alg1(r, g, b), alg1(g, b, r), alg1(b, r, g)
            temp = 1 if q * r < g else 0
            out[i, j] = 255 * max(0, max(0, max(0, rr - gg) - bb) - temp)
    return out


@pytest.mark.parametrize(
    ("K", "C", "ratio"),
    [(0.8, 20.0, 0.6), (1.0, 0.0, 0.6), (0.5, 10.5, 0.75), (0.0, 100.0, 0.6), (1.3, -5.0, 0.2)],
)
def test_vectorised_filter_is_the_pseudo_code(K: float, C: float, ratio: float) -> None:
    rng = np.random.default_rng(0)
    img = rng.integers(0, 256, (48, 64, 3), dtype=np.uint8)
    # plus pixels on the boundaries of Alg. 1 (I1 = K (I2 + I3) + C when that is an integer) and of the
    # 0.6 test (G = 0.6 R), where a floating-point product could tip either way
    for k in range(200):
        g, b = int(rng.integers(0, 128)), int(rng.integers(0, 128))
        r = Fraction(repr(K)) * (g + b) + Fraction(repr(C))
        if r.denominator == 1 and 0 <= r <= 255:
            img[k % 48, k // 48] = (b, g, int(r))
        rr = int(rng.integers(0, 256))
        gg = Fraction(repr(ratio)) * rr
        if gg.denominator == 1 and gg <= 255:
            img[47 - k % 48, 63 - k // 48] = (int(rng.integers(0, 50)), int(gg), rr)
    ours = color_filter(img, K, C, ratio)
    assert ours.dtype == np.uint8 and ours.shape == img.shape[:2]
    assert np.array_equal(ours, reference_filter(img, K, C, ratio))
    assert 0 < np.count_nonzero(ours) < ours.size or K == 0.0


def test_filter_on_every_byte_triple_and_on_views() -> None:
    """The one-pass kernel on all 2^24 (B, G, R) triples against the whole-image formulation of Alg. 1 and
    2 with numpy (an independent evaluation of the same tables), and on non-contiguous views."""
    T1, T2 = alg1_table(0.8, 20.0), temp_table(0.6)
    v = np.arange(256, dtype=np.int32)
    b, g, r = (a.ravel() for a in np.meshgrid(v, v, v, indexing="ij"))
    img = np.stack([b, g, r], axis=-1).astype(np.uint8).reshape(4096, 4096, 3)
    expected = (g + b < T1[r]) & ~(b + r < T1[g]) & ~(r + g < T1[b]) & ~(g > T2[r])
    assert np.array_equal(color_filter(img, tables=(T1, T2)).ravel() > 0, expected)
    view = img[::7, ::-3]  # strided and reversed
    assert np.array_equal(color_filter(view), color_filter(np.ascontiguousarray(view)))


@pytest.mark.parametrize(
    "bad", [np.zeros((8, 8), np.uint8), np.zeros((8, 8, 4), np.uint8), np.zeros((8, 8, 3))]
)
def test_filter_refuses_what_is_not_bgr_u8(bad: np.ndarray) -> None:
    with pytest.raises(ValueError, match="BGR uint8"):
        color_filter(bad)


def test_tables_encode_the_inequalities() -> None:
    T = alg1_table(0.8, 20.0)
    assert T[19] == 0  # 19 >= 0.8 s + 20 for no s
    assert T[20] == 1  # only s = 0
    assert T[60] == 51  # 60 >= 0.8 s + 20 <=> s <= 50 (a tie at s = 50 counts)
    assert T[255] == 294  # s <= 293.75
    G = temp_table(0.6)
    assert G[200] == 120 and G[201] == 120 and G[255] == 153


def test_default_thresholds_sort_colours_as_documented() -> None:
    """K_I = 0.8, C_I = 20: saturated reds down to a quarter exposure pass, and a red-orange with
    G < 0.6 R; neutral, skin, brown, orange, pink, green and blue do not (the module docstring's claims).
    Colours are (B, G, R)."""
    reds = [(10, 10, 64), (40, 40, 200), (0, 0, 255), (60, 50, 150), (30, 60, 170), (30, 140, 240)]
    others = [
        (128, 128, 128), (255, 255, 255), (0, 0, 0), (120, 150, 200), (50, 80, 120), (0, 165, 255),
        (180, 130, 230), (50, 200, 50), (200, 60, 40), (20, 20, 45),
    ]  # fmt: skip
    img = np.array([reds + others], dtype=np.uint8)
    m = color_filter(img)[0] > 0
    assert m[: len(reds)].all() and not m[len(reds) :].any()


def disc_image(cx: float, cy: float, r: float, size: tuple[int, int] = (480, 640)) -> np.ndarray:
    """A red disc on grey with the edge anti-aliased as alight.pads.RedTarget draws it."""
    y, x = np.mgrid[0 : size[0], 0 : size[1]].astype(float)
    w = np.clip(0.5 - (np.hypot(x - cx, y - cy) - r), 0.0, 1.0)[..., None]
    fg, bg = np.array(TARGET_BGR, float), np.array(GREY_BGR, float)
    return np.rint(bg + w * (fg - bg)).astype(np.uint8)


@pytest.mark.parametrize(("r_lo", "r_hi", "tol"), [(20.0, 60.0, 0.1), (5.0, 20.0, 0.25)])
def test_disc_centroid_is_sub_pixel(r_lo: float, r_hi: float, tol: float) -> None:
    det = RedTargetDetector()
    rng = np.random.default_rng(1)
    for _ in range(25):
        cx, cy, r = rng.uniform(80, 560), rng.uniform(80, 400), rng.uniform(r_lo, r_hi)
        obs = det.detect(disc_image(cx, cy, r), 2.5)
        assert len(obs) == 1
        o = obs[0]
        assert isinstance(o, BlobObservation) and o.kind == "blob" and o.t == 2.5
        assert o.pixels.shape == (1, 2)
        assert np.hypot(*(o.pixels[0] - (cx, cy))) < tol
        assert o.area_px == pytest.approx(math.pi * r * r, rel=0.07)
        assert 0.9 < o.quality <= 1.0 and o.aspect < 1.15


def scaled(img: np.ndarray, gains_bgr: tuple[float, float, float]) -> np.ndarray:
    return np.clip(np.rint(img * np.array(gains_bgr)), 0, 255).astype(np.uint8)


def test_lighting_tolerance_follows_the_thresholds() -> None:
    """The target (B, G, R) = (40, 40, 200) under an exposure gain g passes Alg. 1 while
    200 g >= 0.8 (80 g) + 20, i.e. g >= 20 / 136, and while the saturated red still dominates,
    255 >= 0.8 (80 g) + 20, i.e. g <= 235 / 64. A red channel gain w (white balance) needs
    200 w >= 84; a green gain turns it off once 40 g > 0.6 * 200 (Alg. 2's test); a blue gain once
    200 < 0.8 (40 + 40 b) + 20."""
    det = RedTargetDetector()
    base = disc_image(320, 240, 40)
    found = lambda g: bool(det.detect(scaled(base, g), 0.0))  # noqa: E731
    g_lo, g_hi = 20 / 136, 235 / 64
    assert found((1.1 * g_lo,) * 3) and not found((0.9 * g_lo,) * 3)
    assert found((0.95 * g_hi,) * 3) and not found((1.05 * g_hi,) * 3)
    w = 84 / 200
    assert found((1, 1, 1.05 * w)) and not found((1, 1, 0.95 * w))
    assert found((1, 119 / 40, 1)) and not found((1, 121 / 40, 1))  # G = 119 passes, 121 does not
    b = 4.625
    assert found((0.97 * b, 1, 1)) and not found((1.03 * b, 1, 1))


@pytest.mark.parametrize(
    "image",
    [
        np.full((480, 640), 128, np.uint8),
        np.full((480, 640, 3), 128, np.uint8),
        np.zeros((0, 0, 3), np.uint8),
        np.zeros((1, 1, 3), np.uint8),
        np.zeros((480, 640, 3), np.float32),
        np.zeros((480, 640, 2), np.uint8),
        None,
        [[1, 2, 3], [4]],
        "image.png",
    ],
    ids=["grey", "grey_bgr", "empty", "tiny", "float", "two_channels", "none", "list", "str"],
)
def test_bad_or_empty_images_give_nothing(image: object) -> None:
    for mitigation in ("none", "gate+shape"):
        assert RedTargetDetector(RedTargetDetectorConfig(mitigation=mitigation)).detect(image, 0.0) == []


@pytest.mark.parametrize(
    "image", [np.full((480, 640), 128, np.uint8), np.full((48, 64, 1), 9, np.uint16), [[1, 2, 3]]]
)
def test_grey_images_have_no_colour_to_find(image: object) -> None:
    assert RedTargetDetector.needs_colour
    assert RedTargetDetector().detect(image, 0.0) == []


def test_a_uniformly_red_frame_and_noise_are_not_targets() -> None:
    det = RedTargetDetector()
    red = np.zeros((480, 640, 3), np.uint8)
    red[..., 2] = 200
    assert det.detect(red, 0.0) == []  # the paper's rule reported it with quality 1.0
    rng = np.random.default_rng(7)
    for _ in range(10):
        noise = rng.integers(0, 256, (480, 640, 3), dtype=np.uint8)
        noise[..., 2] = np.maximum(noise[..., 2], 200)  # reddish noise: speckle clusters of 100+ px
        assert det.detect(noise, 0.0) == []
    # ... while a target cut by the frame's edge (close range) or in a corner is still found
    for centre, r in [((0, 240), 60), ((0, 0), 150), ((320, 240), 300)]:
        img = np.full((480, 640, 3), 90, np.uint8)
        cv2.circle(img, centre, r, (20, 20, 200), -1)
        assert len(det.detect(img, 0.0)) == 1, (centre, r)


def test_sixteen_bit_and_float_colour_images_are_converted() -> None:
    det = RedTargetDetector()
    img = disc_image(300, 200, 30)
    ref = det.detect(img, 0.0)
    assert len(ref) == 1
    for other in (img.astype(np.uint16) * 257, img.astype(np.uint16) * 16, img.astype(np.float32) / 255.0):
        obs = det.detect(other, 0.0)
        assert len(obs) == 1 and np.allclose(obs[0].pixels, ref[0].pixels, atol=0.5)


@pytest.mark.parametrize("t", [math.nan, math.inf, "soon", None])
def test_capture_time_must_be_finite(t: object) -> None:
    with pytest.raises(ImageError, match="capture time"):
        RedTargetDetector().detect(disc_image(300, 200, 30), t)  # type: ignore[arg-type]


def test_alpha_channel_and_non_contiguous_views_are_read() -> None:
    det = RedTargetDetector()
    img = disc_image(300, 200, 30)
    bgra = np.dstack([img, np.full(img.shape[:2], 255, np.uint8)])
    big = np.zeros((960, 1280, 3), np.uint8)
    big[::2, ::2] = img
    for im in (bgra, big[::2, ::2]):
        o = det.detect(im, 0.0)
        assert len(o) == 1 and np.hypot(*(o[0].pixels[0] - (300, 200))) < 0.1


def cluttered_scene() -> tuple[np.ndarray, dict[str, tuple[float, float]]]:
    """The target disc (r = 25 px), a bigger red rectangle (80 x 26), a red ring (non-convex), a speck."""
    img = disc_image(150, 300, 25)
    cv2.rectangle(img, (380, 60), (460, 86), TARGET_BGR, -1)
    cv2.ellipse(img, (500, 350), (45, 45), 0, 30, 330, TARGET_BGR, 9)
    cv2.circle(img, (600, 30), 1, TARGET_BGR, -1)
    return img, {"disc": (150, 300), "rect": (420, 73), "ring": (500, 350)}


def nearest(obs: list, where: dict[str, tuple[float, float]]) -> str:
    assert len(obs) == 1
    p = obs[0].pixels[0]
    return min(where, key=lambda k: np.hypot(p[0] - where[k][0], p[1] - where[k][1]))


def test_paper_mode_takes_the_biggest_red_contour() -> None:
    img, where = cluttered_scene()
    det = RedTargetDetector()
    blobs = det.candidates(img)
    assert len(blobs) == 3  # the speck is below min_area_px
    assert nearest(det.detect(img, 0.0), where) == "ring"  # the biggest: a false lock


def test_shape_mitigation_keeps_the_disc() -> None:
    img, where = cluttered_scene()
    det = RedTargetDetector(RedTargetDetectorConfig(mitigation="shape", max_fill=0.9))
    assert nearest(det.detect(img, 0.0), where) == "disc"
    # with rectangles allowed (max_fill 1), the rectangle is the biggest convex candidate
    det = RedTargetDetector(RedTargetDetectorConfig(mitigation="shape"))
    assert nearest(det.detect(img, 0.0), where) == "rect"


def test_gate_mitigation_follows_the_prediction() -> None:
    img, where = cluttered_scene()
    det = RedTargetDetector(RedTargetDetectorConfig(mitigation="gate"))
    assert nearest(det.detect(img, 0.0), where) == "ring"  # no prediction: the biggest
    det.set_prediction(np.array([160.0, 290.0]), 40.0)
    assert nearest(det.detect(img, 0.0), where) == "disc"
    det.set_prediction(np.array([300.0, 200.0]), 40.0)
    assert det.detect(img, 0.0) == []  # nothing within the gate: no false lock
    det.set_prediction(np.array([300.0, 200.0]), 200.0)
    assert nearest(det.detect(img, 0.0), where) == "rect"
    det.set_prediction(None)
    assert det.prediction is None
    with pytest.raises(ValueError):
        det.set_prediction(np.array([math.nan, 1.0]), 10.0)
    with pytest.raises(ValueError):
        det.set_prediction(np.array([1.0, 1.0]), -1.0)


def test_gate_plus_shape_skips_a_nearer_false_target() -> None:
    img, where = cluttered_scene()
    det = RedTargetDetector(RedTargetDetectorConfig(mitigation="gate+shape", max_fill=0.9))
    det.set_prediction(np.array([420.0, 200.0]), 400.0)  # nearer the rectangle and the ring
    assert nearest(det.detect(img, 0.0), where) == "disc"


def test_satisfies_the_detector_protocol_and_validates_its_config() -> None:
    assert isinstance(RedTargetDetector(), Detector)
    for bad in (
        {"mitigation": "both"}, {"K_I": -1.0}, {"C_I": math.nan}, {"green_ratio": -0.1},
        {"open_px": 1.5}, {"max_area_frac": 0.0}, {"max_aspect": 0.5}, {"min_fill": 0.9, "max_fill": 0.8},
        {"gate_radius_px": 0.0},
    ):  # fmt: skip
        with pytest.raises(ValueError):
            RedTargetDetectorConfig(**bad)


def test_opening_removes_speckle() -> None:
    img = disc_image(320, 240, 30)
    rng = np.random.default_rng(2)
    for y, x in zip(rng.integers(0, 478, 100), rng.integers(0, 638, 100), strict=True):
        img[y : y + 2, x : x + 2] = TARGET_BGR  # 2 x 2 red specks (a single pixel has no contour area)
    plain = RedTargetDetector(RedTargetDetectorConfig(min_area_px=0.0)).candidates(img)
    opened = RedTargetDetector(RedTargetDetectorConfig(min_area_px=0.0, open_px=3)).candidates(img)
    assert len(opened) == 1 < len(plain)


# --------------------------------------------------------------------------------------------------
# Real photos
# --------------------------------------------------------------------------------------------------


def test_real_photo_red_leds_are_found_and_markers_ignored(real_dir: Path) -> None:
    """The only real photo with red objects: the Hubsan quadrotor's two red LEDs (nfold_marker_real_photo,
    3264 x 2448; the glows around (610, 683) and (663, 1609) px, read off the photo). Both are the two
    biggest red contours; nothing red on the two black-and-white n-fold markers (MANIFEST: marker tips at
    about (931, 1071) and (2274, 1265))."""
    img = cv2.imread(str(real_dir / "nfold_marker_real_photo" / "hubsanwithmarker.jpg"))
    assert img is not None
    det = RedTargetDetector()
    blobs = det.candidates(img)
    leds = np.array([[610.0, 683.0], [663.0, 1609.0]])
    top2 = np.array([b.centroid for b in blobs[:2]])
    d = np.linalg.norm(top2[:, None, :] - leds[None, :, :], axis=2)
    assert d.min(axis=0).max() < 60  # each LED glow is one of the two biggest contours
    for marker in ((931.0, 1071.0), (2274.0, 1265.0)):
        assert all(np.hypot(*(b.centroid - marker)) > 250 for b in blobs)
    (o,) = det.detect(img, 0.0)
    assert np.linalg.norm(leds - o.pixels[0], axis=1).min() < 60


@pytest.mark.parametrize(
    "name",
    [
        "aruco_charuco_real_photos/img_00.jpg",
        "aruco_charuco_real_photos/chocclusion_original.jpg",
        "fisheye_ocamcalib/img0.jpg",
        "apriltag_real_photos/33369213973_9d9bb4cc96_c.jpg",
        "apriltag_real_photos/34139872896_defdb2f8d9_c.jpg",
    ],
)
def test_real_photos_without_red_give_nothing(real_dir: Path, name: str) -> None:
    img = cv2.imread(str(real_dir / name))
    assert img is not None
    assert RedTargetDetector().detect(img, 0.0) == []


def test_circularity_above_a_squares_tells_the_disc_from_bigger_red_boxes() -> None:
    import cv2

    img = np.full((240, 320, 3), (60, 120, 60), np.uint8)
    cv2.circle(img, (80, 120), 10, (40, 40, 200), -1, lineType=cv2.LINE_AA)  # the target: a disc
    cv2.rectangle(img, (180, 100), (207, 127), (40, 40, 200), -1)  # a bigger red square
    cv2.rectangle(img, (230, 30), (279, 54), (40, 40, 200), -1)  # a bigger red 2:1 box
    plain = RedTargetDetector(RedTargetDetectorConfig(mitigation="none")).detect(img, 0.0)
    assert plain and abs(plain[0].pixels[0][0] - 80) > 50  # the biggest red contour is a box
    shape = RedTargetDetector(RedTargetDetectorConfig(mitigation="shape", min_circularity=0.8))
    found = shape.detect(img, 0.0)
    assert found and np.hypot(*(found[0].pixels[0] - (80, 120))) < 1.0


# ---- a tint or a gradient is not a disc cut by the border (issue 39, point 4) ----------------------------


def _grey(h: int = 480, w: int = 640) -> np.ndarray:
    return np.full((h, w, 3), GREY_BGR, np.uint8)


def _tints() -> dict[str, np.ndarray]:
    """Frames with red over a region bounded by straight lines or iso-lines: no disc anywhere."""
    out = {}
    for name, sl in [
        ("right half", np.s_[:, 320:]),
        ("left half", np.s_[:, :320]),
        ("top half", np.s_[:240]),
    ]:
        img = _grey()
        img[sl] = (0, 0, 255)
        out[name] = img
    corner = _grey()
    corner[:240, :320] = (0, 0, 255)
    out["corner quadrant"] = corner
    yy, xx = np.mgrid[:480, :640]
    tilted = _grey()
    tilted[(xx - 320) * math.cos(0.5) + (yy - 240) * math.sin(0.5) > 0] = (30, 30, 220)
    out["tilted half"] = tilted
    vertical, horizontal = np.zeros((480, 640, 3), np.uint8), np.zeros((480, 640, 3), np.uint8)
    vertical[..., :2], horizontal[..., :2] = 30, 30
    vertical[..., 2] = np.linspace(0, 255, 480).astype(np.uint8)[:, None]
    horizontal[..., 2] = np.linspace(255, 0, 640).astype(np.uint8)[None, :]
    out["vertical gradient"], out["horizontal gradient"] = vertical, horizontal
    stripes = _grey()
    stripes[(xx // 40) % 2 == 0] = (30, 30, 220)
    out["stripes"] = stripes
    full = np.zeros((480, 640, 3), np.uint8)
    full[..., 2] = 255
    out["full frame"] = full
    return out


@pytest.mark.parametrize("mitigation", ["none", "shape", "gate", "gate+shape"])
@pytest.mark.parametrize("name", list(_tints()))
def test_a_tint_or_gradient_is_not_the_target(name: str, mitigation: str) -> None:
    img = _tints()[name]
    assert np.count_nonzero(color_filter(img)) > 0.1 * img.shape[0] * img.shape[1]  # red is there
    assert RedTargetDetector(RedTargetDetectorConfig(mitigation=mitigation)).detect(img, 0.0) == []
    # the rim check is what rejects the half frames and gradients (the paper's rule took them)
    if name != "full frame":
        off = RedTargetDetectorConfig(mitigation="none", min_arc_sagitta_frac=0.0)
        assert len(RedTargetDetector(off).detect(img, 0.0)) == 1


def _cut_disc(side: str, offset: float, along: float, r: int) -> tuple[np.ndarray, tuple[float, float]]:
    """A red disc of radius ``r`` (px) whose centre lies ``offset * r`` inside the ``side`` border (negative:
    outside the frame), at ``along`` of the way along that border; and its true centre."""
    h, w = 480, 640
    cx, cy = {
        "left": (offset * r, along * h),
        "right": (w - 1 - offset * r, along * h),
        "top": (along * w, offset * r),
        "bottom": (along * w, h - 1 - offset * r),
    }[side]
    img = _grey()
    cv2.circle(img, (round(cx), round(cy)), r, TARGET_BGR, -1, cv2.LINE_AA)
    return img, (cx, cy)


@pytest.mark.parametrize("side", ["left", "right", "top", "bottom"])
@pytest.mark.parametrize(
    ("r", "offset"), [(40, 0.0), (40, 0.5), (100, -0.3), (150, 0.0), (150, 0.6), (300, 0.2)]
)
@pytest.mark.parametrize("along", [0.3, 0.5])
def test_a_disc_cut_by_each_border_is_still_found(side: str, r: int, offset: float, along: float) -> None:
    img, _ = _cut_disc(side, offset, along, r)
    obs = RedTargetDetector().detect(img, 0.0)
    assert len(obs) == 1
    assert obs[0].area_px == pytest.approx(np.count_nonzero(color_filter(img)), rel=0.02)


@pytest.mark.parametrize(
    ("centre", "r"),
    [((-700, 240), 1000), ((320, -900), 1200), ((-400, -300), 900), ((1100, 240), 800), ((-2300, 240), 2500)],
)
def test_the_last_metre_a_disc_filling_most_of_the_view(centre: tuple[int, int], r: int) -> None:
    """The pad from close by: a disc larger than the frame, cut by one, two or three borders; the rim in
    view is an arc even for a radius of 2,500 px (sagitta 11.5 px over the frame's height)."""
    img = _grey()
    cv2.circle(img, centre, r, TARGET_BGR, -1, cv2.LINE_AA)
    frac = np.count_nonzero(color_filter(img)) / (480 * 640)
    assert 0.3 < frac < 0.999
    assert len(RedTargetDetector().detect(img, 0.0)) == 1


@pytest.mark.parametrize("aspect", [1.5, 2.5, 3.8])
@pytest.mark.parametrize("angle_deg", [0, 30, 60, 90])
def test_an_oblique_disc_an_ellipse_cut_by_the_border_is_found(aspect: float, angle_deg: int) -> None:
    img = _grey()
    cv2.ellipse(img, (40, 240), (150, round(150 / aspect)), angle_deg, 0, 360, TARGET_BGR, -1, cv2.LINE_AA)
    assert len(RedTargetDetector().detect(img, 0.0)) == 1


def test_rim_is_arc_on_closed_forms() -> None:
    """An arc of a circle passes from either side's blob only when the blob is the disc; a straight line,
    an L and a ragged line do not."""
    from alight.perception.color_filter import rim_is_arc

    phi = np.linspace(-0.6, 0.6, 400)
    arc = np.column_stack([500 * np.cos(phi), 500 * np.sin(phi)])  # a disc of radius 500 around 0
    assert rim_is_arc(arc, np.array([300.0, 0.0]), 0.02)
    assert not rim_is_arc(arc, np.array([700.0, 0.0]), 0.02)  # the blob outside the circle
    line = np.column_stack([np.zeros(400), np.linspace(0, 479, 400)])
    assert not rim_is_arc(line, np.array([-100.0, 240.0]), 0.02)
    corner = np.vstack(
        [
            np.column_stack([np.zeros(200), np.linspace(0, 200, 200)]),
            np.column_stack([np.linspace(0, 200, 200), np.full(200, 200.0)]),
        ]
    )
    assert not rim_is_arc(corner, np.array([100.0, 100.0]), 0.02)
    ragged = line + np.column_stack([np.random.default_rng(3).normal(0, 4, 400), np.zeros(400)])
    assert not rim_is_arc(ragged, np.array([-100.0, 240.0]), 0.02)
