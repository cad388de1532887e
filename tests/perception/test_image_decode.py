"""Encoded bytes to an image (perception/image_decode.py): a damaged JPEG is refused with libjpeg's reason,
a good one gives OpenCV's pixels, and both readers (``alight detect``, the replay's compressed frames)
use it."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from alight.perception.detect_cli import read_image
from alight.perception.image_decode import decode_image_bytes

JPEGS = [
    "aruco_charuco_real_photos/img_01.jpg",  # 4:2:0
    "apriltag_real_photos/34139872896_defdb2f8d9_c.jpg",  # 4:4:4
]


def _flipped(data: bytes, seed: int) -> bytes:
    """A few bytes of the entropy-coded data changed, as a flaky link or card does."""
    rng = np.random.default_rng(seed)
    b = bytearray(data)
    for i in rng.integers(len(b) // 4, len(b) - 2, size=20):
        b[int(i)] = int(rng.integers(0, 256))
    return bytes(b)


@pytest.mark.parametrize("name", JPEGS)
def test_a_good_jpeg_gives_opencvs_pixels(real_dir: Path, name: str) -> None:
    data = (real_dir / name).read_bytes()
    img, reason = decode_image_bytes(data)
    assert reason is None and img is not None
    np.testing.assert_array_equal(img, cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED))


def test_a_grey_jpeg_is_grey() -> None:
    grey = np.tile(np.arange(64, dtype=np.uint8) * 4, (48, 1))
    ok, enc = cv2.imencode(".jpg", grey)
    img, reason = decode_image_bytes(enc.tobytes())
    assert ok and reason is None and img is not None and img.shape == (48, 64)
    np.testing.assert_array_equal(img, cv2.imdecode(enc, cv2.IMREAD_UNCHANGED))


@pytest.mark.parametrize("name", JPEGS)
def test_a_damaged_jpeg_is_refused_with_libjpegs_reason(real_dir: Path, name: str) -> None:
    data = (real_dir / name).read_bytes()
    refused = 0
    for seed in range(10):
        bad = _flipped(data, seed)
        lenient = cv2.imdecode(np.frombuffer(bad, np.uint8), cv2.IMREAD_UNCHANGED)
        img, reason = decode_image_bytes(bad)
        if img is None:
            assert reason is not None and reason.startswith("damaged JPEG: ") and "\n" not in reason
            refused += 1
        # OpenCV hands on an image for (nearly) every one of them
        assert lenient is not None
    assert refused >= 8
    for cut in (len(data) // 3, len(data) - 10):
        img, reason = decode_image_bytes(data[:cut])
        assert img is None and reason is not None and reason.startswith("damaged JPEG")


def test_other_formats_and_garbage() -> None:
    bgr = np.random.default_rng(0).integers(0, 256, (6, 5, 3), dtype=np.uint8)
    ok, png = cv2.imencode(".png", bgr)
    img, reason = decode_image_bytes(png.tobytes())
    assert ok and reason is None and np.array_equal(img, bgr)
    assert decode_image_bytes(png.tobytes()[:-30])[0] is None  # libpng refuses a cut file itself
    for data in (b"", b"hello", b"\xff\xd8\xff" + bytes(40)):
        img, reason = decode_image_bytes(data)
        assert img is None and reason is not None and "\n" not in reason


def test_alight_detect_reads_through_it(tmp_path: Path, real_dir: Path) -> None:
    bad = tmp_path / "bad.jpg"
    bad.write_bytes(_flipped((real_dir / JPEGS[0]).read_bytes(), 0))
    img, reason = read_image(str(bad))
    assert img is None and reason is not None and reason.startswith("damaged JPEG")
