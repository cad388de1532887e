"""Detector fuzz harness (issue 39): corrupt and adversarial images into every registered image detector.

    PYTHONPATH=src python benchmarks/fuzz_detectors.py [--n 1800] [--seed 0] [--limit-s 10]
        [--testdata ../shared/testdata/real] [--only NAME ...]

prints a JSON summary. Every detector of ``alight.perception.DETECTORS`` that reads an image (at its block
defaults on its pad's default layout, as ``alight detect`` builds it) gets the same ``--n`` images:

- garbage that is not an image: random bytes, None, a string, a ragged list, 0-size, 1-D, 4-D,
  (3, H, W), 2, 4 (BGRA), 5 or 7 channels, a 1 x 20,000 strip, complex, object, int64, bool, float16;
- images with no target: NaN and inf float images, float images out of [0, 1], 16-bit and 12-bit noise,
  all black, all white, uniform grey and colours, a saturated red half (left, right, top, bottom) or
  quarter, a red stripe, a red border, red and grey gradients (horizontal, vertical, radial), noise
  (grey, colour, reddish, salt and pepper), checkerboards and stripes;
- the real photos of ``../shared/testdata/real`` corrupted: the file cut short or with flipped bytes and
  then decoded, channels swapped, cropped, scaled down, noised, inverted, tinted red, 16-bit. A damaged
  file is decoded as alight's readers decode it (``--decoder alight``, the default:
  :func:`alight.perception.image_decode.decode_image_bytes`, which refuses a JPEG that libjpeg flags;
  those count as ``decode_refused`` and reach no detector), or as a lenient driver would
  (``--decoder opencv``: ``cv2.imdecode``, which hands on the partial image).

Counted per detector: ``crashes`` (an exception other than the documented
:class:`~alight.errors.ImageError`), ``hangs`` (a call over the limit, SIGALRM), ``refused``
(``ImageError``), ``malformed`` (an observation with a non-finite pixel or a quality outside [0, 1]) and
``false_detections``: any observation on an image with no target. The real photos hold real targets of
some detectors (:data:`PHOTO_TARGETS`: tag36h11 markers, which ``aruco`` and ``apriltag`` read, an
n-fold marker, and red objects, which paper 003's colour filter is meant to find): on those, that
detector's observations are counted as ``photo_targets_seen``, not
as false. Real targets must still be found: ``targets`` rendered frames of the detector's own pad
(through the simulator's renderer and the default downward camera, 2.5-5 m, nadir to 0.15 rad) and the
clean photos with its markers, ``targets_missed`` of them not detected. The first image of each kind per
detector has ``WARMUP_LIMIT_S`` (numba compiles a kernel for each new array type). The test
``tests/perception/test_fuzz_detectors.py`` runs a short version.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import signal
import sys
import time
from collections.abc import Callable, Iterator
from functools import partial
from pathlib import Path
from typing import Any

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from robustness_harness import _call as watchdog_call  # noqa: E402  (the harnesses' watchdog)
from robustness_harness import _on_alarm  # noqa: E402

from alight.blockspec import NoContext
from alight.cameras import CameraMount, PinholeCamera, camera_pose_W
from alight.errors import ImageError
from alight.pads import PADS
from alight.perception import DETECTORS
from alight.perception.detect_cli import detector_names, make_detector
from alight.perception.image_decode import decode_image_bytes
from alight.sim.render import Renderer, RenderOptions
from alight.sim.textures import make_ground_texture
from alight.types import rot_z

ROOT = Path(__file__).resolve().parents[1]
WARMUP_LIMIT_S = 600.0
"""The limit of a detector's first call on each kind of image (numba compiles for new array types)."""
H, W = 120, 160
"""The synthetic images' size (px): OpenCV's ArUco search costs seconds on a noise frame of 752 x 480."""

PHOTO_TARGETS = {
    "33369213973_9d9bb4cc96_c": ("aruco", "apriltag"),
    "34085369442_304b6bafd9_c": ("aruco", "apriltag"),
    "34139872896_defdb2f8d9_c": ("aruco", "apriltag"),
    "img0": ("aruco", "apriltag"),
    "diamondmarkers": ("red",),
    "gboriginal": ("red",),
    "singlemarkersoriginal": ("red",),
    "hubsanwithmarker": ("red", "nfold", "sdu"),
    "sample": ("red",),
}
"""The photos' real targets: tag36h11 markers (the AprilTag pad's family) in the AprilTag photos and the
fisheye corridor (``img0``), MarkerLocator's n-fold marker on the drone in ``hubsanwithmarker``, and red
objects (what paper 003's colour filter finds by design) in five photos. A detector named here may see
something on that photo."""
MUST_FIND = {"33369213973_9d9bb4cc96_c", "34085369442_304b6bafd9_c", "34139872896_defdb2f8d9_c", "img0"}
"""Clean photos whose tag36h11 markers ``aruco`` and ``apriltag`` must find."""


def _call(fn: Callable[[], Any], limit_s: float) -> tuple[str, Any]:
    """The harnesses' one watchdog, with this boundary's documented refusal (ImageError)."""
    return watchdog_call(fn, limit_s, (ImageError,))


# ---- images with no target -------------------------------------------------------------------------------


def _red(shape: tuple[int, int]) -> Any:
    img = np.zeros((*shape, 3), np.uint8)
    img[..., 2] = 255
    return img


def _half(where: str, rng: np.random.Generator) -> Any:
    img = np.full((H, W, 3), int(rng.integers(0, 256)), np.uint8)
    red = np.array([0, 0, 255], np.uint8)
    sl = {
        "left": np.s_[:, : W // 2], "right": np.s_[:, W // 2 :], "top": np.s_[: H // 2],
        "bottom": np.s_[H // 2 :],
        "quarter": np.s_[: H // 2, : W // 2], "stripe": np.s_[H // 2 - 6 : H // 2 + 6],
    }[where]  # fmt: skip
    img[sl] = red
    return img


def _gradient(kind: str, red: bool) -> Any:
    y, x = np.mgrid[0:H, 0:W].astype(np.float64)
    g = {
        "h": x / (W - 1),
        "v": y / (H - 1),
        "radial": 1.0 - np.hypot(x - W / 2, y - H / 2) / math.hypot(W, H) * 2,
    }
    ramp = np.clip(g[kind] * 255.0, 0, 255).astype(np.uint8)
    if not red:
        return ramp
    return np.dstack([np.zeros_like(ramp), np.zeros_like(ramp), ramp])


def _border(rng: np.random.Generator) -> Any:
    img = np.full((H, W, 3), int(rng.integers(0, 256)), np.uint8)
    img[:4], img[-4:], img[:, :4], img[:, -4:] = (0, 0, 255), (0, 0, 255), (0, 0, 255), (0, 0, 255)
    return img


def _checker(n: int) -> Any:
    y, x = np.mgrid[0:H, 0:W]
    return (((x // n) + (y // n)) % 2 * 255).astype(np.uint8)


def synthetic_kinds(rng: np.random.Generator) -> list[tuple[str, Callable[[], Any]]]:
    """The images with no target: ``(kind, make)``."""
    u8 = partial(rng.integers, 0, 256, dtype=np.uint8)
    kinds: list[tuple[str, Callable[[], Any]]] = [
        ("random_bytes", lambda: rng.integers(0, 256, int(rng.integers(1, 5000)), dtype=np.uint8).tobytes()),
        ("none", lambda: None), ("string", lambda: "frame.png"), ("ragged", lambda: [[1, 2, 3], [4]]),
        ("empty", lambda: np.zeros((0, 0), np.uint8)), ("1d", lambda: u8(H * W)),
        ("4d", lambda: u8((4, H, W, 3))), ("chw", lambda: u8((3, H, W))), ("two_ch", lambda: u8((H, W, 2))),
        ("bgra", lambda: u8((H, W, 4))), ("five_ch", lambda: u8((H, W, 5))),
        ("seven_ch", lambda: u8((H, W, 7))),
        ("strip", lambda: u8((1, 20000, 3))), ("complex", lambda: rng.random((H, W)) + 1j),
        ("object", lambda: np.full((H, W), None, dtype=object)),
        ("int64", lambda: rng.integers(-9, 9, (H, W))), ("bool", lambda: rng.random((H, W, 3)) < 0.5),
        ("float16", lambda: rng.random((H, W, 3)).astype(np.float16)),
        ("nan", lambda: np.full((H, W, 3), np.nan, np.float32)),
        ("nan_part", lambda: np.where(rng.random((H, W)) < 0.3, np.nan, rng.random((H, W)))),
        ("inf", lambda: np.where(rng.random((H, W, 3)) < 0.3, np.inf, 0.5)),
        ("float_out_of_range", lambda: rng.normal(0, 1e6, (H, W, 3))),
        ("float_noise", lambda: rng.random((H, W, 3)).astype(np.float32)),
        ("uint16_noise", lambda: rng.integers(0, 65536, (H, W), dtype=np.uint16)),
        ("12bit_noise", lambda: rng.integers(0, 4096, (H, W, 3), dtype=np.uint16)),
        ("black", lambda: np.zeros((H, W, 3), np.uint8)), ("white", lambda: np.full((H, W), 255, np.uint8)),
        ("white_bgr", lambda: np.full((H, W, 3), 255, np.uint8)),
        ("grey", lambda: np.full((H, W), int(rng.integers(0, 256)), np.uint8)),
        ("uniform_colour", lambda: np.broadcast_to(u8(3), (H, W, 3)).copy()),
        ("all_red", lambda: _red((H, W))), ("all_red_dark", lambda: _red((H, W)) // 3),
        *[(f"red_{w}", partial(_half, w, rng)) for w in ("left", "right", "top", "bottom", "quarter")],
        ("red_stripe", partial(_half, "stripe", rng)),
        ("red_border", lambda: _border(rng)),
        *[(f"grad_{k}", partial(_gradient, k, False)) for k in ("h", "v", "radial")],
        *[(f"red_grad_{k}", partial(_gradient, k, True)) for k in ("h", "v", "radial")],
        ("noise_grey", lambda: u8((H, W))), ("noise_bgr", lambda: u8((H, W, 3))),
        ("noise_reddish", lambda: np.dstack([u8((H, W)), u8((H, W)), 200 + u8((H, W)) % 56])),
        ("salt_pepper", lambda: ((rng.random((H, W)) < 0.5) * 255).astype(np.uint8)),
        ("checker_8", lambda: _checker(8)), ("checker_20", lambda: _checker(20)),
        ("stripes", lambda: np.tile(((np.arange(W) // 6) % 2 * 255).astype(np.uint8), (H, 1))),
    ]  # fmt: skip
    return kinds


# ---- real photos, corrupted ------------------------------------------------------------------------------


def load_photos(testdata: Path) -> dict[str, tuple[bytes, Any]]:
    """``name -> (file bytes, decoded image)`` of the photos under ``testdata`` (empty when absent)."""
    out = {}
    for p in sorted([*testdata.glob("*/*.jpg"), *testdata.glob("*/*.png")]):
        data = p.read_bytes()
        out[p.stem] = (data, cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED))
    return out


class Refused:
    """A damaged file that the decoder refused: no frame reaches a detector (counted ``decode_refused``)."""

    def __init__(self, reason: str) -> None:
        self.reason = reason


DECODERS = ("alight", "opencv")
"""``alight``: :func:`alight.perception.image_decode.decode_image_bytes`, the reader of ``alight detect``
and of the replay's compressed frames (a JPEG that libjpeg flags as damaged is refused); ``opencv``:
``cv2.imdecode``, a lenient driver that hands on what libjpeg could make of the damaged data."""


def _decode(data: bytes, decoder: str = "alight") -> Any:
    """What the decoder hands on for a damaged file: the image, the partial image (``opencv``), a
    :class:`Refused` (``alight``), or None (libjpeg's and libpng's complaints on stderr are silenced)."""
    if not data:
        return None
    sys.stderr.flush()
    saved = os.dup(2)
    with open(os.devnull, "wb") as null:
        os.dup2(null.fileno(), 2)
        try:
            if decoder == "opencv":
                return cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
            img, reason = decode_image_bytes(data)
            return img if img is not None else Refused(reason or "refused")
        finally:
            os.dup2(saved, 2)
            os.close(saved)


def _small(img: Any, side: int = 480) -> Any:
    s = side / max(img.shape[:2])
    return img if s >= 1.0 else cv2.resize(img, None, fx=s, fy=s, interpolation=cv2.INTER_AREA)


def corrupt_photo(how: str, data: bytes, img: Any, rng: np.random.Generator, decoder: str = "alight") -> Any:
    """One damage to a real photo (file bytes ``data``, decoded ``img``), at most 480 px on its long side
    (the cost of the marker detectors grows with the area)."""
    if how == "truncated":
        return _decode(data[: int(rng.integers(0, len(data)))], decoder)
    if how == "flipped_bytes":
        b = bytearray(data)
        for i in rng.integers(100, len(b), size=int(rng.integers(1, 40))):
            b[int(i)] = int(rng.integers(0, 256))
        return _decode(bytes(b), decoder)
    small = _small(img)
    if how == "channels_swapped":
        return np.ascontiguousarray(small[..., ::-1])
    if how == "cropped":
        h, w = small.shape[:2]
        y, x = int(rng.integers(0, h // 2)), int(rng.integers(0, w // 2))
        return small[y : y + int(rng.integers(8, h - y + 1)), x : x + int(rng.integers(8, w - x + 1))]
    if how == "scaled_down":
        f = float(rng.uniform(0.05, 0.5))
        return cv2.resize(small, None, fx=f, fy=f, interpolation=cv2.INTER_AREA)
    if how == "noised":
        return np.clip(small + rng.normal(0, 40, small.shape), 0, 255).astype(np.uint8)
    if how == "inverted":
        return 255 - small
    if how == "red_tint":
        out = small.astype(np.float64)
        out[..., 2] = np.minimum(255.0, out[..., 2] * 1.8 + 60.0)
        return out.astype(np.uint8)
    if how == "16bit":
        return small.astype(np.uint16) * 257
    if how == "grey":
        return cv2.cvtColor(small, cv2.COLOR_BGR2GRAY)
    raise ValueError(how)


PHOTO_CORRUPTIONS = [
    "truncated", "flipped_bytes", "channels_swapped", "cropped", "scaled_down", "noised", "inverted",
    "red_tint", "16bit", "grey",
]  # fmt: skip


def images(
    n: int, seed: int, photos: dict[str, tuple[bytes, Any]], decoder: str = "alight"
) -> Iterator[tuple[str, str | None, Any]]:
    """``n`` images ``(kind, photo name or None, image)``: every kind in turn first, then at random (a
    quarter of them corrupted photos when there are photos)."""
    rng = np.random.default_rng(seed)
    synth = synthetic_kinds(rng)
    names = sorted(photos)
    order = [("synthetic", k) for k in range(len(synth))]
    order += [("photo", k) for k in range(len(PHOTO_CORRUPTIONS))] if names else []
    for i in range(n):
        if i < len(order):
            which, k = order[i]
        elif names and rng.random() < 0.25:
            which, k = "photo", int(rng.integers(len(PHOTO_CORRUPTIONS)))
        else:
            which, k = "synthetic", int(rng.integers(len(synth)))
        if which == "synthetic":
            kind, make = synth[k]
            yield kind, None, make()
        else:
            name = names[int(rng.integers(len(names)))]
            how = PHOTO_CORRUPTIONS[k]
            yield f"photo_{how}", name, corrupt_photo(how, *photos[name], rng, decoder)


# ---- real targets --------------------------------------------------------------------------------------


def pad_of(name: str) -> Any:
    """The pad ``make_detector(name)`` reads (its default layout)."""
    spec = PADS[DETECTORS[name].needs["pad"][0]]
    return spec.build(spec.default_params(), NoContext())


def target_frames(name: str, n: int, seed: int) -> list[Any]:
    """``n`` rendered frames of the detector's pad fully in view: the default downward camera 2.5-5 m above
    it, tilted up to 0.15 rad, the pad at a random heading, on grass."""
    rng = np.random.default_rng(seed)
    pad = pad_of(name)
    cam = PinholeCamera.default_downward()
    colour = DETECTORS[name].needs.get("camera.color", (False,))[0] is True
    r = Renderer(cam, make_ground_texture("grass", rng, size_px=512), pad, RenderOptions(color=colour), rng)
    mount = CameraMount.downward()
    frames: list[Any] = []
    while len(frames) < n:
        z = float(rng.uniform(2.5, 5.0))
        roll, pitch = rng.uniform(-0.15, 0.15, 2)
        cr, sr, cp, sp = math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch)
        R_WB = rot_z(float(rng.uniform(-math.pi, math.pi))) @ np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
        R_WB = R_WB @ np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
        p_WB = np.array([*rng.uniform(-0.15, 0.15, 2) * z, z + 0.5])
        p_WC, R_WC = camera_pose_W(p_WB, R_WB, mount)
        p_WP, yaw = np.array([0.0, 0.0, 0.5]), float(rng.uniform(-math.pi, math.pi))
        corners_W = (rot_z(yaw) @ pad.quad_corners_P().T).T + p_WP
        px = cam.project((R_WC.T @ (corners_W - p_WC).T).T)
        inside = np.isfinite(px).all() and (px > 8).all() and (px[:, 0] < cam.width - 9).all()
        if inside and (px[:, 1] < cam.height - 9).all():
            frames.append(r.render(p_WC, R_WC, (p_WP, yaw)))
    return frames


# ---- the run ---------------------------------------------------------------------------------------------


def _well_formed(obs: Any) -> bool:
    try:
        return all(np.isfinite(o.pixels).all() and 0.0 <= o.quality <= 1.0 for o in obs)
    except (AttributeError, TypeError):
        return False


class Counts:
    def __init__(self) -> None:
        self.c = {
            "images": 0, "decode_refused": 0, "crashes": 0, "hangs": 0, "refused": 0, "malformed": 0,
            "false_detections": 0,
            "photo_targets_seen": 0, "targets": 0, "targets_missed": 0,
        }  # fmt: skip
        self.examples: list[str] = []

    def fail(self, what: str, detail: str) -> None:
        self.c[what] += 1
        self.examples.append(f"{what}:{detail[:100]}")


def run_detector(
    name: str,
    n: int,
    seed: int,
    limit_s: float,
    photos: dict[str, tuple[bytes, Any]],
    n_targets: int,
    decoder: str = "alight",
) -> dict[str, Any]:
    det = make_detector(name)
    counts = Counts()
    seen: set[str] = set()
    t0 = time.perf_counter()
    for frame in target_frames(name, n_targets, seed):
        status, obs = _call(partial(det.detect, frame, 1.0), WARMUP_LIMIT_S if not seen else limit_s)
        seen.add("target")
        counts.c["targets"] += 1
        if status != "ok" or not obs:
            counts.fail("targets_missed", f"render:{status}")
    for stem in sorted(MUST_FIND & set(photos)) if name in ("aruco", "apriltag") else ():
        status, obs = _call(partial(det.detect, photos[stem][1], 1.0), WARMUP_LIMIT_S)
        counts.c["targets"] += 1
        if status != "ok" or not obs:
            counts.fail("targets_missed", f"photo:{stem}:{status}")
    for kind, photo, image in images(n, seed, photos, decoder):
        counts.c["images"] += 1
        if isinstance(image, Refused):
            counts.c["decode_refused"] += 1
            continue
        status, obs = _call(partial(det.detect, image, 2.0), limit_s if kind in seen else WARMUP_LIMIT_S)
        seen.add(kind)
        where = f"{kind}:{photo}" if photo else kind
        if status in ("crash", "hang"):
            counts.fail("crashes" if status == "crash" else "hangs", f"{where}:{type(obs).__name__}:{obs}")
        elif status == "refused":
            counts.c["refused"] += 1
        elif obs and not _well_formed(obs):
            counts.fail("malformed", where)
        elif obs and photo is not None and name in PHOTO_TARGETS.get(photo, ()):
            counts.c["photo_targets_seen"] += 1
        elif obs:
            counts.fail("false_detections", where)
    return {**counts.c, "wall_s": round(time.perf_counter() - t0, 1), "examples": counts.examples[:8]}


def run(
    n: int = 1800,
    seed: int = 0,
    limit_s: float = 10.0,
    testdata: Path | None = None,
    only: list[str] | None = None,
    n_targets: int = 10,
    decoder: str = "alight",
) -> dict[str, Any]:
    """The whole harness; the JSON summary as a dict (``decoder``: one of :data:`DECODERS`)."""
    if decoder not in DECODERS:
        raise ValueError(f"decoder must be one of {DECODERS}, got {decoder!r}")
    signal.signal(signal.SIGALRM, _on_alarm)
    cv2.setNumThreads(1)
    photos = load_photos(testdata if testdata is not None else ROOT.parent / "shared" / "testdata" / "real")
    t0 = time.perf_counter()
    names = [d for d in detector_names() if only is None or d in only]
    per = {name: run_detector(name, n, seed, limit_s, photos, n_targets, decoder) for name in names}
    keys = ("crashes", "hangs", "malformed", "false_detections", "targets_missed")
    totals = {k: sum(int(b[k]) for b in per.values()) for k in keys}
    return {
        "images_per_detector": n,
        "photos": len(photos),
        "decoder": decoder,
        "seed": seed,
        "per_call_limit_s": limit_s,
        "detectors": per,
        "totals": totals,
        "wall_s": round(time.perf_counter() - t0, 1),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=1800, help="images per detector")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--limit-s", type=float, default=10.0, help="watchdog per call (s)")
    parser.add_argument("--targets", type=int, default=10, help="rendered target frames per detector")
    parser.add_argument(
        "--testdata", type=Path, default=None, help="the real photos (../shared/testdata/real)"
    )
    parser.add_argument("--only", nargs="*", default=None, help="these detectors only")
    parser.add_argument(
        "--decoder", choices=DECODERS, default="alight", help="how the damaged files are decoded"
    )
    args = parser.parse_args(argv)
    summary = run(args.n, args.seed, args.limit_s, args.testdata, args.only, args.targets, args.decoder)
    print(json.dumps(summary, indent=2))
    return 0 if not any(summary["totals"].values()) else 1


if __name__ == "__main__":
    sys.exit(main())
